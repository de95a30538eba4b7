//! Taking a stroke back (undo, the eraser) and bringing it back (redo): the one rule both the
//! WebSocket (`RemoveStroke`, `RestoreStroke`) and HTTP (`DELETE /v1/strokes/{id}`,
//! `POST /v1/strokes/{id}/restore`) follow, and the HTTP handlers.
//!
//! - **Who**: only the stroke's drawer (the participant of its key). A session owner has no
//!   such right: a session has no owner, only a token shared by everyone in it.
//! - **What**: a finished stroke. One still being drawn (open or interrupted) is refused: its
//!   drawer may yet resume it, and its live events would show it again.
//! - **Nothing is lost**: the stroke's row is marked with who and when
//!   ([`WriteOp::SetRemoved`]); its samples, simplified samples and mesh stay stored and
//!   readable through `/v1/strokes/{id}/...`. The session's history, strokes list and mesh
//!   bundle leave it out. The mark is kept as long as the session.
//! - **Idempotent**: taking back a stroke taken back (or bringing back one that is not) changes
//!   nothing and answers the same.
//! - Every connection of the session hears of it once it is committed (the writer publishes
//!   the event with the commit: `NOTIFY` across replicas).

use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode};
use penmesh::protocol::{ErrorCode, ParticipantId, Removal, StrokeStatus};

use crate::events::{EventKind, SessionEvent};
use crate::http::{AppError, ErrorBody, owned_stroke};
use crate::state::AppState;
use crate::store::{StrokeRow, WriteError, WriteOp, now_ms};

/// Why a removal or restore was refused.
#[derive(Debug, Clone, PartialEq)]
pub struct Refused {
    pub code: ErrorCode,
    pub message: String,
}

/// Checks that `by` may take back or bring back `row` (a stroke of its session).
pub fn check(row: &StrokeRow, by: ParticipantId) -> Result<(), Refused> {
    if row.participant != by {
        return Err(Refused {
            code: ErrorCode::NotOwner,
            message: format!(
                "stroke {} was drawn by another participant: only its drawer may take it back or \
                 bring it back",
                row.id
            ),
        });
    }
    if row.status != StrokeStatus::Done {
        return Err(Refused {
            code: ErrorCode::StrokeOpen,
            message: format!(
                "stroke {} is {}: only a finished stroke can be taken back or brought back",
                row.id,
                row.status.as_str()
            ),
        });
    }
    Ok(())
}

/// The write and the event of taking back (`remove`) or bringing back `row`, asked by `by` on
/// connection `origin` of this replica, if any.
pub fn request(
    row: &StrokeRow,
    by: ParticipantId,
    remove: bool,
    origin: Option<u64>,
) -> (WriteOp, SessionEvent) {
    let (participant, stroke) = (row.participant, row.id);
    let (removed, kind) = if remove {
        (Some(Removal { by, at: now_ms() }), EventKind::Removed { participant, stroke, by })
    } else {
        (None, EventKind::Restored { participant, stroke, by })
    };
    let event = match origin {
        Some(connection) => SessionEvent::from_connection(connection, row.session_id, kind),
        None => SessionEvent::new(row.session_id, kind),
    };
    (WriteOp::SetRemoved { stroke, removed }, event)
}

/// Takes back or brings back a stroke over HTTP: 204 once committed.
async fn set_removed(
    state: &AppState,
    headers: &HeaderMap,
    id: &str,
    remove: bool,
) -> Result<StatusCode, AppError> {
    let action = if remove { "take it back" } else { "bring it back" };
    let (row, by) = owned_stroke(state, headers, id, action).await?;
    check(&row, by).map_err(|refused| AppError::Conflict(refused.message))?;
    let (op, event) = request(&row, by, remove, None);
    state.writer.write_with(vec![op], vec![event]).await.map_err(|err| match err {
        WriteError::Closed => AppError::ShuttingDown,
        err => AppError::Internal(err.into()),
    })?;
    let event = if remove { "removed" } else { "restored" };
    metrics::counter!("penmesh_strokes_total", "event" => event).increment(1);
    Ok(StatusCode::NO_CONTENT)
}

/// Takes a finished stroke back (undo, the eraser): the session's history, strokes list and
/// mesh bundle leave it out, and every connection of the session is told (`stroke_removed`).
/// Nothing of it is deleted: its own reads keep working, and `POST …/restore` brings it back.
/// Only its drawer may (its participant key in `x-penmesh-key`). Idempotent.
#[utoipa::path(delete, path = "/v1/strokes/{id}", tag = "strokes",
    params(("id" = Uuid, Path),
        ("x-penmesh-key" = String, Header, description = "the drawer's participant key (its hello.key)")),
    security(("bearer" = [])),
    responses((status = 204, description = "taken back (or already)"),
        (status = 400, description = "a malformed participant key", body = ErrorBody),
        (status = 401, body = ErrorBody),
        (status = 403, description = "not the stroke's drawer", body = ErrorBody),
        (status = 404, description = "no such stroke in this session", body = ErrorBody),
        (status = 409, description = "the stroke is still being drawn", body = ErrorBody)))]
pub async fn remove_stroke(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<StatusCode, AppError> {
    set_removed(&state, &headers, &id, true).await
}

/// Brings a taken-back stroke back (redo): in the history, the strokes list and the mesh
/// bundle again, and every connection of the session is told (`stroke_restored`). Only its
/// drawer may. Idempotent.
#[utoipa::path(post, path = "/v1/strokes/{id}/restore", tag = "strokes",
    params(("id" = Uuid, Path),
        ("x-penmesh-key" = String, Header, description = "the drawer's participant key (its hello.key)")),
    security(("bearer" = [])),
    responses((status = 204, description = "brought back (or was not taken back)"),
        (status = 400, description = "a malformed participant key", body = ErrorBody),
        (status = 401, body = ErrorBody),
        (status = 403, description = "not the stroke's drawer", body = ErrorBody),
        (status = 404, description = "no such stroke in this session", body = ErrorBody),
        (status = 409, description = "the stroke is still being drawn", body = ErrorBody)))]
pub async fn restore_stroke(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<StatusCode, AppError> {
    set_removed(&state, &headers, &id, false).await
}
