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

use axum::Json;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode};
use penmesh::Placement;
use penmesh::protocol::{
    DuplicateRequest, Duplicated, ErrorCode, ParticipantId, PlacementChange, PlacementHistory,
    StrokeId, StrokeStatus,
};
use sqlx::Row;
use uuid::Uuid;

use crate::events::{EventKind, SessionEvent};
use crate::http::{AppError, ErrorBody, authorized_stroke, owned_stroke};
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
/// of the request's `x-penmesh-key`; 400 when it is missing or malformed.
pub(crate) fn new_drawer(
    session: uuid::Uuid,
    headers: &axum::http::HeaderMap,
    what: &str,
) -> Result<ParticipantId, AppError> {
    crate::identity::request_participant(session, headers).map_err(|err| match err {
        crate::identity::KeyError::Missing => AppError::BadRequest(format!(
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
        (status = 403, description = "not the stroke's drawer", body = ErrorBody),
        (status = 404, description = "no such stroke in this session", body = ErrorBody),
        (status = 409, description = "the stroke is still being drawn", body = ErrorBody)))]
pub async fn put_placement(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<StatusCode, AppError> {
    let (row, by) = owned_stroke(&state, &headers, &id, "place it").await?;
    let placement = placement_body(&body)?;
    check(&row, by).map_err(|refused| AppError::Conflict(refused.message))?;
    let (op, event) = request((row.session_id, row.participant, row.id), placement, "set", None);
    state.writer.write_with(vec![op], vec![event]).await.map_err(write_error)?;
    metrics::counter!("penmesh_strokes_total", "event" => "placed").increment(1);
    Ok(StatusCode::NO_CONTENT)
}

/// Every placement the stroke had, oldest first (the last is its current one): each with who
/// set it, when, and why (`begin`, `set`, `duplicate`). A stroke begun without one starts at
/// the identity, listed with its drawer and its begin time.
#[utoipa::path(get, path = "/v1/strokes/{id}/placements", tag = "strokes",
    params(("id" = Uuid, Path)),
    security(("bearer" = [])),
    responses((status = 200, body = PlacementHistory),
        (status = 401, body = ErrorBody),
        (status = 404, description = "no such stroke in this session", body = ErrorBody)))]
pub async fn placements(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Json<PlacementHistory>, AppError> {
    let row = authorized_stroke(&state, &headers, &id).await?;
    let rows = sqlx::query(
        "SELECT matrix, set_by, set_at, cause FROM stroke_placements WHERE stroke_id = $1 \
         ORDER BY id",
    )
    .bind(row.id.to_string())
    .fetch_all(state.store.pool())
    .await
    .map_err(anyhow::Error::from)?;
    let mut placements = Vec::with_capacity(rows.len() + 1);
    for r in rows {
        let matrix: Vec<u8> = r.try_get("matrix").map_err(anyhow::Error::from)?;
        let by: String = r.try_get("set_by").map_err(anyhow::Error::from)?;
        placements.push(PlacementChange {
            placement: Placement::from_bytes(&matrix).map_err(anyhow::Error::from)?,
            by: Uuid::parse_str(&by).map_err(anyhow::Error::from)?,
            at: r.try_get("set_at").map_err(anyhow::Error::from)?,
            cause: r.try_get("cause").map_err(anyhow::Error::from)?,
        });
    }
    if placements.first().is_none_or(|p| p.cause == "set") {
        let begin = PlacementChange {
            placement: Placement::IDENTITY,
            by: row.participant,
            at: row.created_at,
            cause: "begin".into(),
        };
        placements.insert(0, begin);
    }
    Ok(Json(PlacementHistory { stroke: row.id, placements }))
}

/// Duplicates a finished stroke: a new stroke (its own id; the participant of the
/// `x-penmesh-key` is its drawer; the source recorded as `duplicate_of`) with the same pen data
/// (raw and simplified samples, brush, parameters), at a new placement. Its mesh is the
/// source's, shared, never copied. The session sees it as any new stroke (its begin, samples,
/// end, mesh and `peer_placement`); a version-4 client sees it in its own plane, on top of its
/// source. Anyone in the session may duplicate any stroke it sees.
#[utoipa::path(post, path = "/v1/strokes/{id}/duplicate", tag = "strokes",
    params(("id" = Uuid, Path),
        ("x-penmesh-key" = String, Header, description = "the duplicater's participant key (its hello.key)")),
    request_body = DuplicateRequest,
    security(("bearer" = [])),
    responses((status = 201, description = "the new stroke", body = Duplicated),
        (status = 400, description = "not a placement (naming what is wrong), or a missing or malformed key", body = ErrorBody),
        (status = 401, body = ErrorBody),
        (status = 404, description = "no such stroke in this session", body = ErrorBody),
        (status = 409, description = "the source is still being drawn or taken back, or the new id is taken", body = ErrorBody)))]
pub async fn duplicate(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<(StatusCode, Json<Duplicated>), AppError> {
    let source = authorized_stroke(&state, &headers, &id).await?;
    let by = new_drawer(source.session_id, &headers, "a duplicate")?;
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
    let stroke = asked.stroke.unwrap_or_else(Uuid::new_v4);
    if state.store.stroke(stroke).await?.is_some() {
        return Err(AppError::Conflict(format!(
            "stroke id {stroke} is taken; choose a new random id"
        )));
    }
    let raw = state.store.raw_samples(source.id).await?;
    let simplified = state.store.simplified(source.id).await?.ok_or_else(|| {
        anyhow::anyhow!("stroke {} is done but has no simplified samples", source.id)
    })?;
    let kept: Vec<penmesh::Kept> = simplified
        .indices
        .iter()
        .zip(&simplified.samples)
        .map(|(&index, &sample)| penmesh::Kept { index: index as usize, sample })
        .collect();
    let mesh_of = mesh_owner(&state, source.id).await?;
    let mesh_at = state.store.mesh(source.id).await?.map(|m| m.created_at);
    let session = source.session_id;
    let n_retained = kept.len() as u64;
    let ops = vec![
        WriteOp::BeginStroke {
            stroke,
            session,
            participant: by,
            brush: source.brush,
            params: source.params,
            device: source.device.clone(),
        },
        WriteOp::Append { stroke, seq: 0, samples: raw },
        WriteOp::Finish { stroke, kept },
        WriteOp::MarkDuplicate { stroke, source: source.id, mesh_of },
    ];
    let (place, placed) = request((session, by, stroke), asked.placement, "duplicate", None);
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
    ops.push(place);
    // It is what its source is (the mesh it shares is that solid's).
    if !source.solid.is_rod() {
        let (set, told) =
            crate::solid::request((session, by, stroke), source.solid, "duplicate", None);
        ops.push(set);
        events.push(told);
    }
    state.writer.write_with(ops, events).await.map_err(write_error)?;
    metrics::counter!("penmesh_strokes_total", "event" => "duplicated").increment(1);
    Ok((StatusCode::CREATED, Json(Duplicated { stroke, source: source.id })))
}

/// The stroke whose mesh row `stroke` shows: its own, or its source's for a duplicate.
async fn mesh_owner(state: &AppState, stroke: Uuid) -> Result<Uuid, AppError> {
    let of: Option<Option<String>> =
        sqlx::query_scalar("SELECT mesh_of FROM strokes WHERE id = $1")
            .bind(stroke.to_string())
            .fetch_optional(state.store.pool())
            .await
            .map_err(anyhow::Error::from)?;
    match of.flatten() {
        Some(id) => Ok(Uuid::parse_str(&id).map_err(anyhow::Error::from)?),
        None => Ok(stroke),
    }
}
