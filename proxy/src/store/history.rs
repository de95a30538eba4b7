//! A session's history, what a newcomer is owed: who is present, then every stroke as events,
//! an unfinished one with what ACUTS retains of it (kept by an earlier history, or replayed).

use std::collections::{HashMap, HashSet};

use anyhow::Context;
use penmesh::Sample;
use penmesh::protocol::StrokeStatus;
use sqlx::{AnyConnection, Row};
use uuid::Uuid;

use super::{
    LONG_STROKE_SAMPLES, STROKE_SELECT, Store, StrokeRow, WriteOp, decode_samples, end_with_log,
    log, parse_uuid, stroke_from_row,
};
use crate::events::{EventKind, SessionEvent};

/// What a newcomer to a session is owed ([`Store::session_history`]).
#[derive(Debug, Clone, Default)]
pub struct SessionHistory {
    /// The session's events, in order, without the unreadable strokes.
    pub events: Vec<SessionEvent>,
    /// The strokes that could not be read (`None`: not even its id), and why.
    pub unreadable: Vec<(Option<Uuid>, String)>,
    /// What the long unfinished strokes it replayed retain, for the caller to keep
    /// ([`WriteOp::KeepRetained`]), so that the next history reads it instead.
    pub keep: Vec<WriteOp>,
    /// The strokes taken back, left out of `events`, as `Removed` events: a client resynced
    /// after a gap is told of those it has shown.
    pub removed: Vec<SessionEvent>,
    /// The placements that are current and exactly the board (the identity), left out of
    /// `events` (every stroke's default needs no message), as `Placed` events: a connection
    /// records their ids, so that an older placement arriving after the history is not told,
    /// and tells a client that was told an older placement before a gap.
    pub on_board: Vec<SessionEvent>,
}

impl Store {
    /// What a newcomer to `session` is owed: the participants present, then every stroke
    /// (finished ones with their simplified samples and mesh, open ones with the samples
    /// retained from what is committed so far), as events in order.
    /// A stroke that cannot be read is left out and named in `unreadable`; it does not hide
    /// the others.
    ///
    /// What an unfinished stroke retains is read where a history before kept it for as many
    /// samples as are stored (an interrupted stroke, or one not drawn since), else rebuilt by
    /// replaying its samples: a short stroke on the spot, a long one ([`LONG_STROKE_SAMPLES`])
    /// through [`Store::replay`] after the connection is given back, and what it retains goes
    /// into `keep`.
    ///
    /// It reads through one pooled connection, taken once and given back before a long
    /// replay: a reader that holds a connection while it waits for a second one deadlocks the
    /// pool when as many newcomers arrive at once as the pool has connections (issue 25's join
    /// storm). Its queries are a fixed few, whatever the number of strokes.
    pub async fn session_history(&self, session: Uuid) -> anyhow::Result<SessionHistory> {
        let mut conn = self.pool.acquire().await?;
        let mut history = SessionHistory::default();
        let present = sqlx::query(
            "SELECT connection, participant, name FROM participants \
             WHERE session_id = $1 AND left_at IS NULL ORDER BY joined_at, connection",
        )
        .bind(session.to_string())
        .fetch_all(&mut *conn)
        .await?;
        for row in present {
            history.events.push(SessionEvent::new(
                session,
                EventKind::Joined {
                    participant: parse_uuid(&row.try_get::<String, _>("participant")?)?,
                    connection: parse_uuid(&row.try_get::<String, _>("connection")?)?,
                    name: row.try_get("name")?,
                },
            ));
        }
        let strokes = sqlx::query(&format!(
            "{STROKE_SELECT} WHERE s.session_id = $1 AND s.removed_at IS NULL \
             ORDER BY s.created_at, s.id"
        ))
        .bind(session.to_string())
        .fetch_all(&mut *conn)
        .await?;
        let removed = sqlx::query(
            "SELECT id, participant, removed_by FROM strokes \
             WHERE session_id = $1 AND removed_at IS NOT NULL ORDER BY removed_at, id",
        )
        .bind(session.to_string())
        .fetch_all(&mut *conn)
        .await?;
        for row in removed {
            let participant = parse_uuid(&row.try_get::<String, _>("participant")?)?;
            let by = row.try_get::<Option<String>, _>("removed_by")?;
            history.removed.push(SessionEvent::new(
                session,
                EventKind::Removed {
                    participant,
                    stroke: parse_uuid(&row.try_get::<String, _>("id")?)?,
                    by: by.as_deref().map(parse_uuid).transpose()?.unwrap_or(participant),
                },
            ));
        }
        let meshes = sqlx::query(
            "SELECT s.id AS stroke_id, m.created_at FROM strokes s \
             JOIN meshes m ON m.stroke_id = COALESCE(s.mesh_of, s.id) WHERE s.session_id = $1",
        )
        .bind(session.to_string())
        .fetch_all(&mut *conn)
        .await?;
        let mut mesh_at = HashMap::new();
        for row in meshes {
            let stroke = parse_uuid(&row.try_get::<String, _>("stroke_id")?)?;
            mesh_at.insert(stroke, row.try_get::<i64, _>("created_at")?);
        }
        // The log, once, for the strokes in progress (a stroke whose row cannot be read is
        // reported below).
        let open: HashSet<Uuid> = strokes
            .iter()
            .filter_map(|r| stroke_from_row(r).ok())
            .filter(|r| r.status != StrokeStatus::Done)
            .map(|r| r.id)
            .collect();
        let log = if open.is_empty() {
            log::StrokeEntries::new()
        } else {
            log::read_log(&mut conn, Some(&open), None).await?
        };
        let simplified = simplified_rows(&mut conn, session).await?;
        let unreadable = |row: &sqlx::any::AnyRow, err: anyhow::Error| {
            let id = row.try_get::<String, _>("id").ok().and_then(|id| id.parse().ok());
            tracing::error!(error = %err, stroke = ?id, "a stroke of a session's history is unreadable");
            (id, format!("{err:#}"))
        };
        // Each readable stroke and what it retains (`None`: a long replay, below).
        let mut parts: Vec<(StrokeRow, Option<Vec<Sample>>)> = Vec::with_capacity(strokes.len());
        for row in &strokes {
            match self.stroke_points(&mut conn, row, &log, &simplified).await {
                Ok(part) => parts.push(part),
                Err(err) => history.unreadable.push(unreadable(row, err)),
            }
        }
        drop(conn);
        // The placements of the strokes off the board come after every stroke: each reaches
        // the client as one `PeerPlacement`, after the stroke it places (`PeerStrokes` is the
        // same in both protocol versions; a version-4 client is not sent them).
        let mut placed = Vec::new();
        let mut solids = Vec::new();
        for (row, points) in parts {
            if !row.solid.is_rod() {
                solids.push(solid_event(session, &row));
            }
            if let Some(id) = row.placement_id {
                let placed_event = SessionEvent::new(
                    session,
                    EventKind::Placed {
                        participant: row.participant,
                        stroke: row.id,
                        placement: row.placement,
                        id,
                    },
                );
                if row.placement.is_identity() {
                    history.on_board.push(placed_event);
                } else {
                    placed.push(placed_event);
                }
            }
            let points = match points {
                Some(points) => points,
                None => match self.replay(row.id, row.params, row.n_points).await {
                    Ok(state) => {
                        let kept = state.kept().to_vec();
                        let points = kept.iter().map(|k| k.sample).collect();
                        let upto = state.next_seq();
                        history.keep.push(WriteOp::KeepRetained { stroke: row.id, upto, kept });
                        points
                    }
                    Err(err) => {
                        tracing::error!(error = %err, stroke = %row.id, "a stroke of a session's history is unreadable");
                        history.unreadable.push((Some(row.id), format!("{err:#}")));
                        continue;
                    }
                },
            };
            history.events.extend(stroke_events(session, &row, points, &mesh_at));
        }
        history.events.extend(placed);
        // Their solids after them (a version-6 client's `HistoryStroke` carries them where the
        // stroke is sent whole; otherwise a `PeerSolid` each, which older clients are not sent).
        history.events.extend(solids);
        Ok(history)
    }

    /// The events of one finished stroke as a history has them (begin, retained samples, done,
    /// mesh, then its placement and its solid when not the identity and the rod): what a client
    /// that lacks a stroke brought back is sent. `None` when the stroke is not there to send:
    /// unknown, taken back (again), or not finished.
    pub async fn stroke_history(&self, stroke: Uuid) -> anyhow::Result<Option<Vec<SessionEvent>>> {
        let Some(row) = self.stroke(stroke).await? else { return Ok(None) };
        if row.removed.is_some() || row.status != StrokeStatus::Done {
            return Ok(None);
        }
        let points = match self.simplified(stroke).await? {
            Some(simplified) => simplified.samples,
            None => Vec::new(),
        };
        let mesh_at: Option<i64> =
            sqlx::query_scalar("SELECT created_at FROM meshes WHERE stroke_id = $1")
                .bind(stroke.to_string())
                .fetch_optional(&self.pool)
                .await?;
        let mesh_at = mesh_at.map(|at| HashMap::from([(stroke, at)])).unwrap_or_default();
        let mut events = stroke_events(row.session_id, &row, points, &mesh_at);
        if let Some(id) = row.placement_id.filter(|_| !row.placement.is_identity()) {
            let (participant, placement) = (row.participant, row.placement);
            let kind = EventKind::Placed { participant, stroke, placement, id };
            events.push(SessionEvent::new(row.session_id, kind));
        }
        if !row.solid.is_rod() {
            events.push(solid_event(row.session_id, &row));
        }
        Ok(Some(events))
    }

    /// What one stroke of [`Store::session_history`] retains: its simplified samples when it is
    /// done; else what a history kept for as many samples as are stored, or a replay of a short
    /// stroke; `None` for a long one to replay.
    async fn stroke_points(
        &self,
        conn: &mut AnyConnection,
        row: &sqlx::any::AnyRow,
        log: &log::StrokeEntries,
        simplified: &HashMap<Uuid, SimplifiedRow>,
    ) -> anyhow::Result<(StrokeRow, Option<Vec<Sample>>)> {
        let mut row = stroke_from_row(row)?;
        let stroke = row.id;
        if row.status == StrokeStatus::Done {
            let points = match simplified.get(&stroke) {
                Some(found) => decode_samples(found.layout, &found.data)
                    .with_context(|| format!("stroke {stroke}: simplified samples"))?,
                None => Vec::new(),
            };
            return Ok((row, Some(points)));
        }
        row.n_points = end_with_log(row.n_points, stroke, log);
        let kept =
            simplified.get(&stroke).filter(|k| k.upto.is_some_and(|upto| upto >= row.n_points));
        if let Some(SimplifiedRow { layout, data, .. }) = kept {
            let points = decode_samples(*layout, data)
                .with_context(|| format!("stroke {stroke}: the samples it retained"))?;
            return Ok((row, Some(points)));
        }
        if row.n_points >= LONG_STROKE_SAMPLES {
            return Ok((row, None));
        }
        let raw = self.raw_samples_with(conn, stroke, log).await?;
        let kept = crate::ingest::StrokeState::replay(row.params, &raw);
        let points = kept.kept().iter().map(|k| k.sample).collect();
        Ok((row, Some(points)))
    }

    /// The placements of `stroke` with ids after `after` and before `before`, oldest first,
    /// as `(id, placement)`: what a client that holds placement `after` lacks before its own
    /// placement `before` is answered.
    pub async fn placements_between(
        &self,
        stroke: Uuid,
        after: i64,
        before: i64,
    ) -> anyhow::Result<Vec<(i64, penmesh::Placement)>> {
        let rows = sqlx::query(
            "SELECT id, matrix FROM stroke_placements WHERE stroke_id = $1 AND id > $2 \
             AND id < $3 ORDER BY id",
        )
        .bind(stroke.to_string())
        .bind(after)
        .bind(before)
        .fetch_all(self.pool())
        .await?;
        rows.iter()
            .map(|row| {
                let matrix: Vec<u8> = row.try_get("matrix")?;
                let placement =
                    penmesh::Placement::from_bytes(&matrix).context("stored placement")?;
                Ok((row.try_get("id")?, placement))
            })
            .collect()
    }
}

/// The events of one stroke of a session's history, `points` being what it retains.
fn stroke_events(
    session: Uuid,
    row: &StrokeRow,
    points: Vec<Sample>,
    mesh_at: &HashMap<Uuid, i64>,
) -> Vec<SessionEvent> {
    let (participant, stroke) = (row.participant, row.id);
    let mut events = vec![SessionEvent::new(
        session,
        EventKind::StrokeBegin { participant, stroke, brush: row.brush },
    )];
    let done = row.status == StrokeStatus::Done;
    let n_retained = points.len() as u64;
    if !points.is_empty() {
        events.push(SessionEvent::new(
            session,
            EventKind::Retained { participant, stroke, first: 0, points },
        ));
    }
    if done {
        events.push(SessionEvent::new(
            session,
            EventKind::StrokeDone { participant, stroke, n_retained },
        ));
        if let Some(&created_at) = mesh_at.get(&stroke) {
            events.push(SessionEvent::new(
                session,
                EventKind::Mesh { participant, stroke, created_at },
            ));
        }
    }
    events
}

/// A `simplified` row of a session's history ([`simplified_rows`]): a finished stroke's
/// simplified samples, or what a history kept of an unfinished one ([`WriteOp::KeepRetained`]).
struct SimplifiedRow {
    /// For a kept row, how many stored samples it covers.
    upto: Option<u64>,
    layout: i64,
    data: Vec<u8>,
}

/// Every `simplified` row of the session's strokes, in one query.
async fn simplified_rows(
    conn: &mut AnyConnection,
    session: Uuid,
) -> anyhow::Result<HashMap<Uuid, SimplifiedRow>> {
    let rows = sqlx::query(
        "SELECT f.stroke_id, f.upto, f.layout, f.data FROM simplified f \
         JOIN strokes s ON s.id = f.stroke_id WHERE s.session_id = $1",
    )
    .bind(session.to_string())
    .fetch_all(&mut *conn)
    .await?;
    let mut found = HashMap::with_capacity(rows.len());
    for row in rows {
        let stroke = parse_uuid(&row.try_get::<String, _>("stroke_id")?)?;
        let upto = row.try_get::<Option<i64>, _>("upto")?.map(|n| n as u64);
        found.insert(
            stroke,
            SimplifiedRow { upto, layout: row.try_get("layout")?, data: row.try_get("data")? },
        );
    }
    Ok(found)
}

/// The event of a stroke's current solid.
fn solid_event(session: Uuid, row: &StrokeRow) -> SessionEvent {
    let kind = EventKind::Solid { participant: row.participant, stroke: row.id, solid: row.solid };
    SessionEvent::new(session, kind)
}
