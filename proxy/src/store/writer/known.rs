//! What the writer knows of a stroke ([`Known`]: where its stored samples end, which are only in
//! the log), and reading it from the database when it does not know (a stroke another writer
//! began, or after a failed transaction: [`recover`]).

use std::collections::{HashMap, HashSet};
use std::time::Instant;

use penmesh::Sample;
use sqlx::{AnyConnection, Row};
use uuid::Uuid;

use crate::store::log::{self, Piece};

/// What the writer knows of a stroke, as committed.
#[derive(Debug, Clone, Default)]
pub(super) struct Known {
    /// `stroke_chunks` holds the samples `0..chunk_end`.
    pub(super) chunk_end: u64,
    /// The samples after `chunk_end`, stored only in the log.
    pub(super) pending: Vec<Sample>,
    /// The oldest of this writer's records holding some of `pending`, if any.
    pub(super) first_record: Option<i64>,
    /// Since when `pending` is not empty.
    pub(super) since: Option<Instant>,
}

impl Known {
    pub(super) fn end(&self) -> u64 {
        self.chunk_end + self.pending.len() as u64
    }
}

/// Where `stroke_chunks` holds the samples of `stroke` up to (its rows are contiguous from 0;
/// rows may overlap where two writers moved the same samples).
pub(super) async fn chunk_end(conn: &mut AnyConnection, stroke: Uuid) -> anyhow::Result<u64> {
    let rows = sqlx::query("SELECT seq, n FROM stroke_chunks WHERE stroke_id = $1 ORDER BY seq")
        .bind(stroke.to_string())
        .fetch_all(&mut *conn)
        .await?;
    let mut end = 0u64;
    for row in rows {
        let (seq, n) = (row.try_get::<i64, _>("seq")? as u64, row.try_get::<i64, _>("n")? as u64);
        anyhow::ensure!(seq <= end, "stroke {stroke}: chunk at seq {seq} follows {end} samples");
        end = end.max(seq + n);
    }
    Ok(end)
}

/// What is stored of `stroke`, read from the database: its chunks' end and the samples after
/// it in the log (any writer's); `None` when it has no row.
pub(super) async fn load_stroke(
    conn: &mut AnyConnection,
    stroke: Uuid,
    writer: i64,
) -> anyhow::Result<Option<Known>> {
    if !log::stroke_exists(conn, stroke).await? {
        return Ok(None);
    }
    let chunk_end = chunk_end(conn, stroke).await?;
    let wanted = HashSet::from([stroke]);
    let entries =
        log::read_log(conn, Some(&wanted), None).await?.remove(&stroke).unwrap_or_default();
    known_from(stroke, chunk_end, entries, writer).map(Some)
}

/// A stroke's state from its chunks' end and its log entries (id and writer of the record).
pub(super) fn known_from(
    stroke: Uuid,
    chunk_end: u64,
    entries: Vec<(i64, i64, log::Entry)>,
    writer: i64,
) -> anyhow::Result<Known> {
    let beyond = |(_, _, e): &&(i64, i64, log::Entry)| e.seq + e.samples.len() as u64 > chunk_end;
    let first_record =
        entries.iter().filter(beyond).filter(|(_, w, _)| *w == writer).map(|(id, _, _)| *id).min();
    let pieces = entries.into_iter().map(|(_, _, e)| Piece { seq: e.seq, samples: e.samples });
    let pending = log::assemble_from(stroke, chunk_end, pieces.collect())?;
    let since = (!pending.is_empty()).then(Instant::now);
    Ok(Known { chunk_end, pending, first_record, since })
}

/// After a failed transaction: every stroke with samples in this writer's records, as stored.
/// Samples that cannot be moved into `stroke_chunks` (a stroke with no row, samples that do
/// not decode or do not fit together) are set aside (`log::set_aside`) and forgotten, so that
/// one bad stroke does not fail every transaction after it.
pub(super) async fn recover(
    conn: &mut AnyConnection,
    writer: i64,
) -> anyhow::Result<HashMap<Uuid, Known>> {
    let mut strokes = HashMap::new();
    for (stroke, entries) in log::read_log_to_move(conn, Some(writer)).await? {
        let mut records: Vec<i64> = entries.iter().map(|(id, _, _)| *id).collect();
        records.dedup();
        let known = if log::stroke_exists(conn, stroke).await? {
            chunk_end(conn, stroke).await.and_then(|end| known_from(stroke, end, entries, writer))
        } else {
            Err(anyhow::anyhow!("stroke {stroke} has no row"))
        };
        match known {
            Ok(known) => {
                strokes.insert(stroke, known);
            }
            Err(err) if log::is_database_error(&err) => return Err(err),
            Err(err) => log::set_aside(conn, &records, Some(stroke), &format!("{err:#}")).await?,
        }
    }
    Ok(strokes)
}
