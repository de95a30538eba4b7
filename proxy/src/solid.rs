//! What a stroke becomes (issue 51, `spec/system.md` "Solids: what a stroke becomes"; protocol
//! 6): its solid set by its drawer over the WebSocket (`SetSolid`, `ws/solids.rs`; a stroke
//! begun as one, `StrokeBegin.solid`) or HTTP (`PUT /v1/strokes/{id}/solid`), and its history
//! (`GET /v1/strokes/{id}/solids`), under the rule placements follow:
//!
//! - **Who**: only the stroke's drawer (its `x-penmesh-key`), checked before the body is read.
//! - **What**: a finished stroke; a `filled` solid only of a closed stroke (the refusal says
//!   how far apart its ends are).
//! - **Nothing is overwritten**: each solid is a row of its own with who and when
//!   ([`WriteOp::SetSolid`]); the current one is the latest, and undo sets the one before.
//! - **Nothing half-made**: the new mesh is built first (refused there if the stroke cannot be
//!   that solid), then the solid is committed and told to the session (`PeerSolid`; a
//!   connection of protocol 5 or 4 is not told), then the mesh stored and announced
//!   (`peer_mesh`), as the proxy's mesh build stores one. The solid's kind and depth are what
//!   is stored and told; the mesh is made from the stroke's samples where meshes are made.

use axum::Json;
use axum::body::Body;
use axum::extract::{Path, State};
use axum::http::HeaderMap;
use penmesh::Solid;
use penmesh::protocol::{
    ErrorCode, ParticipantId, SolidChange, SolidHistory, StrokeId, StrokeStatus,
};

use crate::change_history::{HistoryPage, SOLIDS, read_page};
use crate::events::{EventKind, SessionEvent};
use crate::http::{AppError, ErrorBody, MeshInfo, authorized_stroke, owned_stroke};
use crate::mesh_build::{built_glb, store_built};
use crate::query::Query;
use crate::removal::Refused;
use crate::state::AppState;
use crate::store::{StrokeRow, WriteError, WriteOp, now_ms};

/// Checks that `by` may set the solid of `row` (a stroke of its session).
pub fn check(row: &StrokeRow, by: ParticipantId) -> Result<(), Refused> {
    if row.participant != by {
        return Err(Refused {
            code: ErrorCode::NotOwner,
            message: format!(
                "stroke {} was drawn by another participant: only its drawer may set its solid",
                row.id
            ),
        });
    }
    if row.status != StrokeStatus::Done {
        return Err(Refused {
            code: ErrorCode::StrokeOpen,
            message: format!(
                "stroke {} is {}: only a finished stroke's solid can be set (a stroke being \
                 drawn has the solid of its stroke_begin)",
                row.id,
                row.status.as_str()
            ),
        });
    }
    Ok(())
}

/// The write and the event of setting the solid of the stroke `(session, drawer, stroke)`
/// (`cause`: `begin`, `set`, `duplicate` or `import`), on connection `origin` of this replica,
/// if any.
pub fn request(
    (session, participant, stroke): (uuid::Uuid, ParticipantId, StrokeId),
    solid: Solid,
    cause: &'static str,
    origin: Option<u64>,
) -> (WriteOp, SessionEvent) {
    let kind = EventKind::Solid { participant, stroke, solid };
    let event = match origin {
        Some(connection) => SessionEvent::from_connection(connection, session, kind),
        None => SessionEvent::new(session, kind),
    };
    let op = WriteOp::SetSolid { stroke, solid, by: participant, at: now_ms(), cause };
    (op, event)
}

/// The largest body a solid is sent in: `{"kind": "filled", "depth": 48.0}` is 33 bytes.
const MAX_SOLID_BODY: usize = 1024;

/// A solid body, `{"kind": "line"|"filled"|"hole", "depth": px|null}`: 400 naming what is
/// wrong.
fn solid_body(body: &[u8]) -> Result<Solid, AppError> {
    serde_json::from_slice(body).map_err(|e| {
        AppError::BadRequest(format!(
            "the body is not a solid {{\"kind\": \"line\" | \"filled\" | \"hole\", \"depth\": px \
             or null (only for a line)}}: {e}"
        ))
    })
}

/// Sets what a finished stroke becomes (undo sets the previous solid back): a new entry of its
/// solid history, then its mesh built anew from its samples, stored and told to the session
/// (`peer_mesh`). Only its drawer may (its participant key in `x-penmesh-key`).
#[utoipa::path(put, path = "/v1/strokes/{id}/solid", tag = "strokes",
    params(("id" = Uuid, Path),
        ("x-penmesh-key" = String, Header, description = "the drawer's participant key (its hello.key)")),
    request_body(content = Solid, description = "the kind (line, filled, hole) and the depth in px \
        of the stroke's plane (null only for a line: the pressure-width rod); a depth within \
        [0.125, 10000]"),
    security(("bearer" = [])),
    responses((status = 200, description = "set (committed), and the stroke's new mesh stored and told to the session", body = MeshInfo),
        (status = 400, description = "not a solid (naming what is wrong), or a malformed key", body = ErrorBody),
        (status = 401, body = ErrorBody),
        (status = 403, description = "not the stroke's drawer", body = ErrorBody),
        (status = 404, description = "no such stroke in this session", body = ErrorBody),
        (status = 409, description = "the stroke is still being drawn, or cannot be that solid (an open stroke filled)", body = ErrorBody),
        (status = 429, description = "past the participant's rate of solid changes (`--solid-rate-per-second` after `--solid-burst`), with `Retry-After`", body = ErrorBody)))]
pub async fn put_solid(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    body: Body,
) -> Result<Json<MeshInfo>, AppError> {
    let (row, by) = owned_stroke(&state, &headers, &id, "set its solid").await?;
    state.rates.solids.take(&by, 1)?;
    let body = axum::body::to_bytes(body, MAX_SOLID_BODY).await.map_err(|e| {
        AppError::BadRequest(format!(
            "the body is not a solid of at most {MAX_SOLID_BODY} bytes: {e}"
        ))
    })?;
    let solid = solid_body(&body)?;
    check(&row, row.participant).map_err(|refused| AppError::Conflict(refused.message))?;
    let glb = built_glb(&state, &row, solid).await?;
    let (op, event) = request((row.session_id, row.participant, row.id), solid, "set", None);
    state.writer.write_with(vec![op], vec![event]).await.map_err(|err| match err {
        WriteError::Closed => AppError::ShuttingDown,
        WriteError::Refused(why) | WriteError::Quota(why) => AppError::Conflict(why),
        err => AppError::Internal(err.into()),
    })?;
    metrics::counter!("penmesh_strokes_total", "event" => "solid").increment(1);
    store_solid_mesh(&state, &row, solid, glb).await.map(Json)
}

/// How many times a solid's mesh is built again for a solid committed meanwhile.
const MAX_REBUILDS: usize = 8;

/// Stores `glb`, the mesh built for `solid`, as the stroke's; then, while the stroke's stored
/// solid is another (a change committed while this one was building or storing), builds and
/// stores that one's. Two changes at once could otherwise leave the first one's mesh stored
/// last: whichever request stores last checks afterwards, so the mesh that stays is the one of
/// the solid stored then (a later change stores after its own commit).
pub(crate) async fn store_solid_mesh(
    state: &AppState,
    row: &StrokeRow,
    mut solid: Solid,
    mut glb: Vec<u8>,
) -> Result<MeshInfo, AppError> {
    let mut rebuilds = 0;
    loop {
        let stored = store_built(state, row, solid, glb).await?;
        let current = state.store.stroke(row.id).await?.map(|r| r.solid);
        match current {
            Some(current) if current != solid && rebuilds < MAX_REBUILDS => {
                rebuilds += 1;
                solid = current;
                glb = built_glb(state, row, solid).await?;
            }
            _ => return Ok(stored),
        }
    }
}

/// Every solid the stroke had, oldest first (the last is its current one), a page at a time
/// (`crate::change_history`): each with who set it, when, and why (`begin`, `set`,
/// `duplicate`, `import`). A stroke begun without one starts as the rod, listed with its
/// drawer and its begin time. `next`, when present, is the `from` of the next page.
#[utoipa::path(get, path = "/v1/strokes/{id}/solids", tag = "strokes",
    params(("id" = Uuid, Path), HistoryPage),
    security(("bearer" = [])),
    responses((status = 200, body = SolidHistory),
        (status = 400, description = "a limit of 0, or a from or limit that is not a number", body = ErrorBody),
        (status = 401, body = ErrorBody),
        (status = 404, description = "no such stroke in this session", body = ErrorBody),
        (status = 503, description = "busy: as many histories as allowed are being read", body = ErrorBody)))]
pub async fn solids(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Query(page): Query<HistoryPage>,
    headers: HeaderMap,
) -> Result<Json<SolidHistory>, AppError> {
    let row = authorized_stroke(&state, &headers, &id).await?;
    let page = read_page(&state, &row, &SOLIDS, &page).await?;
    let begin = page.begin.then(|| SolidChange {
        solid: Solid::ROD,
        by: row.participant,
        at: row.created_at,
        cause: "begin".into(),
    });
    let stored = page.changes.into_iter().map(|c| {
        Ok(SolidChange { solid: Solid::from_bytes(&c.stored)?, by: c.by, at: c.at, cause: c.cause })
    });
    let solids = begin.into_iter().map(Ok).chain(stored).collect::<anyhow::Result<Vec<_>>>()?;
    Ok(Json(SolidHistory { stroke: row.id, solids, next: page.next }))
}
