//! Placing a stroke in the session's 3D space (protocol version 5, `spec/system.md` "The model
//! in 3D"): the one rule the WebSocket (`SetPlacement`) and HTTP (`PUT
//! /v1/strokes/{id}/placement`) follow, the history of a stroke's placements, and duplicates.
//!
//! - **Who**: only the stroke's drawer, as for taking it back ([`crate::removal`]).
//! - **What**: a finished stroke (one being drawn is placed by its `stroke_begin`).
//! - **Nothing is overwritten**: each placement is a row of its own with who and when
//!   ([`WriteOp::Place`]); the current one is the latest, and undo sets the one before again.
//! - **A mesh never moves, its node does**: a placement is a matrix, never mesh bytes.
//! - Every connection of the session hears of it once it is committed (`PeerPlacement`; the
//!   writer publishes the event with the commit: `NOTIFY` across replicas). A version-4
//!   connection is not told: it sees every stroke in its own plane's coordinates.

use std::time::Duration;

use axum::Json;
use axum::body::Body;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode};
use penmesh::Placement;
use penmesh::protocol::{
    DuplicateRequest, Duplicated, ErrorCode, ParticipantId, PlacementChange, PlacementHistory,
    StrokeId, StrokeStatus,
};
use uuid::Uuid;

use crate::change_history::{HistoryPage, PLACEMENTS, read_page};
use crate::events::{EventKind, SessionEvent};
use crate::http::{
    AppError, ErrorBody, SMALL_BODY_BYTES, authorized_stroke, owned_stroke, small_body,
};
use crate::query::Query;
use crate::removal::Refused;
use crate::state::AppState;
use crate::store::{StrokeRow, WriteError, WriteOp, now_ms};

/// Checks that `by` may place `row` (a stroke of its session).
pub fn check(row: &StrokeRow, by: ParticipantId) -> Result<(), Refused> {
    if row.participant != by {
        return Err(Refused {
            code: ErrorCode::NotOwner,
            message: format!(
                "stroke {} was drawn by another participant: only its drawer may place it",
                row.id
            ),
        });
    }
    if row.status != StrokeStatus::Done {
        return Err(Refused {
            code: ErrorCode::StrokeOpen,
            message: format!(
                "stroke {} is {}: only a finished stroke can be placed anew (a stroke being \
                 drawn has the placement of its stroke_begin)",
                row.id,
                row.status.as_str()
            ),
        });
    }
    Ok(())
}

/// The write and the event of placing the stroke `(session, drawer, stroke)` at `placement`
/// (`cause`: `begin`, `set` or `duplicate`), by its drawer, on connection `origin` of this
/// replica, if any.
pub fn request(
    (session, participant, stroke): (uuid::Uuid, ParticipantId, StrokeId),
    placement: Placement,
    cause: &'static str,
    origin: Option<u64>,
) -> (WriteOp, SessionEvent) {
    let kind = EventKind::Placed { participant, stroke, placement, id: 0 };
    let event = match origin {
        Some(connection) => SessionEvent::from_connection(connection, session, kind),
        None => SessionEvent::new(session, kind),
    };
    let op = WriteOp::Place { stroke, placement, by: participant, at: now_ms(), cause };
    (op, event)
}

fn write_error(err: WriteError) -> AppError {
    match err {
        WriteError::Closed => AppError::ShuttingDown,
        WriteError::Refused(why) | WriteError::Quota(why) => AppError::Conflict(why),
        err => AppError::Internal(err.into()),
    }
}

/// The drawer of the new strokes that `what` (a duplicate, an import) makes: the participant
/// of the request's `x-penmesh-key`; 403 when it is missing (as on every route that needs a
/// key: the request does not say who it speaks for), 400 when it is malformed.
pub(crate) fn new_drawer(
    session: uuid::Uuid,
    headers: &axum::http::HeaderMap,
    what: &str,
) -> Result<ParticipantId, AppError> {
    crate::identity::request_participant(session, headers).map_err(|err| match err {
        crate::identity::KeyError::Missing => AppError::Forbidden(format!(
            "{what} needs a drawer: send your participant key (your hello.key) in the {} header",
            penmesh::protocol::KEY_HEADER
        )),
        crate::identity::KeyError::Malformed(why) => AppError::BadRequest(why),
    })
}

/// A placement body, `{"matrix": [16 numbers]}`: 400 naming what is wrong.
fn placement_body(body: &[u8]) -> Result<Placement, AppError> {
    serde_json::from_slice(body).map_err(|e| {
        AppError::BadRequest(format!(
            "the body is not a placement {{\"matrix\": [16 numbers, column-major]}}: {e}"
        ))
    })
}

/// Places a finished stroke anew (move, turn, scale, mirror; undo puts the previous placement
/// back): a new entry of its placement history, told to every connection of the session
/// (`peer_placement`). Only its drawer may (its participant key in `x-penmesh-key`).
#[utoipa::path(put, path = "/v1/strokes/{id}/placement", tag = "strokes",
    params(("id" = Uuid, Path),
        ("x-penmesh-key" = String, Header, description = "the drawer's participant key (its hello.key)")),
    request_body(content = Placement, description = "a similarity transform, glTF node.matrix order \
        (column-major); finite, last row 0 0 0 1, scale within [1/1000, 1000]"),
    security(("bearer" = [])),
    responses((status = 204, description = "placed (committed, and told to the session)"),
        (status = 400, description = "not a placement (naming what is wrong), or a malformed key", body = ErrorBody),
        (status = 401, body = ErrorBody),
        (status = 403, description = "not the stroke's drawer, or no key", body = ErrorBody),
        (status = 404, description = "no such stroke in this session", body = ErrorBody),
        (status = 409, description = "the stroke is still being drawn", body = ErrorBody),
        (status = 413, description = "a body over 16 KiB", body = ErrorBody),
        (status = 429, description = "past the participant's rate of moves (`--move-rate-per-second` after `--move-burst`), with `Retry-After`", body = ErrorBody)))]
pub async fn put_placement(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    body: Body,
) -> Result<StatusCode, AppError> {
    // The token, the stroke and its drawer first: a stranger's body is never read.
    let (row, by) = owned_stroke(&state, &headers, &id, "place it").await?;
    state.rates.moves.take(&by, 1)?;
    let body = small_body(&headers, body, SMALL_BODY_BYTES).await?;
    let placement = placement_body(&body)?;
    check(&row, by).map_err(|refused| AppError::Conflict(refused.message))?;
    let (op, event) = request((row.session_id, row.participant, row.id), placement, "set", None);
    state.writer.write_with(vec![op], vec![event]).await.map_err(write_error)?;
    metrics::counter!("penmesh_strokes_total", "event" => "placed").increment(1);
    Ok(StatusCode::NO_CONTENT)
}

/// Every placement the stroke had, oldest first (the last is its current one), a page at a
/// time (`crate::change_history`): each with who set it, when, and why (`begin`, `set`,
/// `duplicate`). A stroke begun without one starts at the identity, listed with its drawer and
/// its begin time. `next`, when present, is the `from` of the next page.
#[utoipa::path(get, path = "/v1/strokes/{id}/placements", tag = "strokes",
    params(("id" = Uuid, Path), HistoryPage),
    security(("bearer" = [])),
    responses((status = 200, body = PlacementHistory),
        (status = 400, description = "a limit of 0, or a from or limit that is not a number", body = ErrorBody),
        (status = 401, body = ErrorBody),
        (status = 404, description = "no such stroke in this session", body = ErrorBody),
        (status = 503, description = "busy: as many histories as allowed are being read", body = ErrorBody)))]
pub async fn placements(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Query(page): Query<HistoryPage>,
    headers: HeaderMap,
) -> Result<Json<PlacementHistory>, AppError> {
    let row = authorized_stroke(&state, &headers, &id).await?;
    let page = read_page(&state, &row, &PLACEMENTS, &page).await?;
    let begin = page.begin.then(|| PlacementChange {
        placement: Placement::IDENTITY,
        by: row.participant,
        at: row.created_at,
        cause: "begin".into(),
    });
    let stored = page.changes.into_iter().map(|c| {
        Ok(PlacementChange {
            placement: Placement::from_bytes(&c.stored)?,
            by: c.by,
            at: c.at,
            cause: c.cause,
        })
    });
    let placements = begin.into_iter().map(Ok).chain(stored).collect::<anyhow::Result<Vec<_>>>()?;
    Ok(Json(PlacementHistory { stroke: row.id, placements, next: page.next }))
}

/// Duplicates made at once on one replica (the next is answered 503 `busy`): each copies up
/// to a whole stroke's samples in the database through the writer.
pub const MAX_DUPLICATES: usize = 2;
/// How long a duplicate waits for its turn before 503 `busy`, at most (half the request
/// timeout at most).
const DUPLICATE_WAIT: Duration = Duration::from_secs(10);

/// Duplicates a finished stroke: a new stroke (its own id; the participant of the
/// `x-penmesh-key` is its drawer; the source recorded as `duplicate_of`) with the same pen data
/// (raw and simplified samples, brush, parameters, solid), at a new placement. Its mesh is
/// the source's, shared, never copied, and stays what it is when the source's changes. The session sees it as any new stroke (its begin, samples,
/// end, mesh and `peer_placement`); a version-4 client sees it in its own plane, on top of its
/// source. Anyone in the session may duplicate any stroke it sees. Of two requests naming the
/// same new id one is made; the same request again (same id, source and drawer) is answered
/// as made, nothing stored twice; any other gets 409.
#[utoipa::path(post, path = "/v1/strokes/{id}/duplicate", tag = "strokes",
    params(("id" = Uuid, Path),
        ("x-penmesh-key" = String, Header, description = "the duplicater's participant key (its hello.key)")),
    request_body = DuplicateRequest,
    security(("bearer" = [])),
    responses((status = 201, description = "the new stroke (or the same request made before)", body = Duplicated),
        (status = 400, description = "not a placement (naming what is wrong), or a malformed key", body = ErrorBody),
        (status = 401, body = ErrorBody),
        (status = 403, description = "no key", body = ErrorBody),
        (status = 404, description = "no such stroke in this session", body = ErrorBody),
        (status = 409, description = "the source is still being drawn or taken back, its solid changed while it was being duplicated, or the new id is taken", body = ErrorBody),
        (status = 413, description = "a body over 16 KiB, or the session's samples would pass its quota (`quota_exceeded`)", body = ErrorBody),
        (status = 429, description = "past the session's rate of duplicated samples told to its watchers (`--duplicate-samples-per-second`), with `Retry-After`", body = ErrorBody),
        (status = 503, description = "busy: as many duplicates as allowed are being made", body = ErrorBody)))]
pub async fn duplicate(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    body: Body,
) -> Result<(StatusCode, Json<Duplicated>), AppError> {
    // The token, the stroke and the key first: a stranger's body is never read.
    let source = authorized_stroke(&state, &headers, &id).await?;
    let by = new_drawer(source.session_id, &headers, "a duplicate")?;
    let body = small_body(&headers, body, SMALL_BODY_BYTES).await?;
    let asked: DuplicateRequest = serde_json::from_slice(&body).map_err(|e| {
        AppError::BadRequest(format!(
            "the body is not {{\"placement\": {{\"matrix\": [16 numbers]}}, \"stroke\"?: id}}: {e}"
        ))
    })?;
    if source.status != StrokeStatus::Done || source.removed.is_some() {
        return Err(AppError::Conflict(format!(
            "stroke {} is {}: only a finished stroke that is not taken back can be duplicated",
            source.id,
            if source.removed.is_some() { "taken back" } else { source.status.as_str() }
        )));
    }
    // Duplicates asked at once (a class copying one stroke) take turns, up to a while.
    let wait = DUPLICATE_WAIT.min(Duration::from_secs(state.config.request_timeout_secs) / 2);
    let _permit = state.duplicate_permit(wait).await.ok_or_else(|| {
        AppError::Busy(format!(
            "{MAX_DUPLICATES} duplicates are being made, the limit, and more wait their turn; \
             try again shortly"
        ))
    })?;
    let stroke = asked.stroke.unwrap_or_else(Uuid::new_v4);
    if let Some(existing) = state.store.stroke(stroke).await? {
        return made_before(&existing, &source, by);
    }
    // Every watcher of the session is sent the copy's retained samples: the session's
    // duplicates may send them no faster than its watchers take them (`crate::rate`).
    state.rates.duplicated.take(&source.session_id, source.n_retained)?;
    // What the session is told: the simplified samples (at most `max_stroke_retained`). The
    // drawn samples are copied in the database, never read here.
    let simplified = state.store.simplified(source.id).await?.ok_or_else(|| {
        anyhow::anyhow!("stroke {} is done but has no simplified samples", source.id)
    })?;
    let mesh_at = state.store.mesh(source.id).await?.map(|m| m.created_at);
    let session = source.session_id;
    let n_retained = simplified.samples.len() as u64;
    let quota = state.config.max_session_samples;
    let (place, placed) = request((session, by, stroke), asked.placement, "duplicate", None);
    let ops = vec![
        WriteOp::Claim { stroke },
        WriteOp::CountSamples { session, samples: source.n_points, quota },
        WriteOp::BeginStroke {
            stroke,
            session,
            participant: by,
            brush: source.brush,
            params: source.params,
            device: source.device.clone(),
        },
        WriteOp::CopySamples { stroke, source: source.id },
        WriteOp::MarkDuplicate { stroke, source: source.id, shares: Some(source.solid) },
        place,
    ];
    let event = |kind| SessionEvent::new(session, kind);
    let mut events = vec![
        event(EventKind::StrokeBegin { participant: by, stroke, brush: source.brush }),
        event(EventKind::Retained {
            participant: by,
            stroke,
            first: 0,
            points: simplified.samples,
        }),
        event(EventKind::StrokeDone { participant: by, stroke, n_retained }),
    ];
    if let Some(created_at) = mesh_at {
        events.push(event(EventKind::Mesh { participant: by, stroke, created_at }));
    }
    events.push(placed);
    let mut ops = ops;
    // It is what its source is (the mesh it shares is that solid's).
    if !source.solid.is_rod() {
        let (set, told) =
            crate::solid::request((session, by, stroke), source.solid, "duplicate", None);
        ops.push(set);
        events.push(told);
    }
    match state.writer.write_with(ops, events).await {
        Ok(()) => {}
        // Another request named the id first: the same one made before, or a conflict.
        Err(WriteError::Taken(why)) => {
            return match state.store.stroke(stroke).await? {
                Some(existing) => made_before(&existing, &source, by),
                None => Err(AppError::Conflict(why)),
            };
        }
        Err(WriteError::Quota(why)) => return Err(AppError::QuotaExceeded(why)),
        Err(err) => return Err(write_error(err)),
    }
    metrics::counter!("penmesh_strokes_total", "event" => "duplicated").increment(1);
    Ok((StatusCode::CREATED, Json(Duplicated { stroke, source: source.id })))
}

/// The answer to a duplicate whose new id is taken by `existing`: the same request made
/// before (a duplicate of `source` by `by`: a retry) is answered as made; anything else is 409.
fn made_before(
    existing: &StrokeRow,
    source: &StrokeRow,
    by: ParticipantId,
) -> Result<(StatusCode, Json<Duplicated>), AppError> {
    if existing.duplicate_of == Some(source.id) && existing.participant == by {
        return Ok((
            StatusCode::CREATED,
            Json(Duplicated { stroke: existing.id, source: source.id }),
        ));
    }
    Err(AppError::Conflict(format!("stroke id {} is taken; choose a new random id", existing.id)))
}
