//! HTTP handlers, the bearer-token check, and the one [`AppError`] every handler returns.
//!
//! Sessions are private: a missing or wrong token gets 401 whether or not the session exists.
//! Strokes are found by id and must belong to the token's session (404 otherwise). What only a
//! stroke's drawer may do (store or build its mesh) also needs the drawer's participant key in
//! the `x-penmesh-key` header (403 otherwise; see `crate::identity`).

use axum::Json;
use std::net::SocketAddr;

use anyhow::Context;
use axum::body::{Body, Bytes};
use futures_util::StreamExt;
use tokio::sync::OwnedSemaphorePermit;

use axum::extract::{ConnectInfo, Path, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use penmesh::protocol::{
    KEY_HEADER, ParticipantId, PointBatch, Retained, ServerMessage, encode_server,
};
use rand::RngCore;
use uuid::Uuid;

pub(crate) use penmesh::protocol::{
    ErrorBody, MeshInfo, NewSession, StrokeInfo, StrokeList, StrokeSamples,
};

use crate::events::{EventKind, SessionEvent};
use crate::identity::{KeyError, request_participant};
use crate::query::Query;
use crate::state::{AppState, LARGE_BODY_BYTES};
use crate::store::{
    MeshRow, RawPiece, RawSamples, StrokeRow, WriteError, WriteOp, hash_token, now_ms,
};

/// Every failure a handler can answer with.
#[derive(Debug, thiserror::Error)]
pub enum AppError {
    #[error("missing or wrong session token")]
    Unauthorized,
    /// The token is right, but the request is not the stroke's drawer's.
    #[error("{0}")]
    Forbidden(String),
    #[error("{0}")]
    NotFound(String),
    #[error("{0}")]
    BadRequest(String),
    #[error("{0}")]
    Conflict(String),
    #[error("{0}")]
    TooLarge(String),
    /// A storage quota would be passed (the message names it).
    #[error("{0}")]
    QuotaExceeded(String),
    #[error("the proxy is shutting down")]
    ShuttingDown,
    /// A rate limit (`crate::rate`): the message names it; the client may try again after
    /// `wait`.
    #[error("{message}")]
    TooManyRequests { wait: std::time::Duration, message: String },
    /// This replica is at a limit (e.g. `max_connections`): try again later or elsewhere.
    #[error("{0}")]
    Busy(String),
    /// Not answered within the request timeout (a route that keeps its own: the export).
    #[error("{0}")]
    TimedOut(String),
    #[error("internal error")]
    Internal(#[from] anyhow::Error),
}

impl AppError {
    /// The same error again, for each request answered with one outcome (an export's waiters,
    /// `crate::flight`); an internal error keeps its cause as text.
    pub fn again(&self) -> AppError {
        match self {
            AppError::Unauthorized => AppError::Unauthorized,
            AppError::Forbidden(m) => AppError::Forbidden(m.clone()),
            AppError::NotFound(m) => AppError::NotFound(m.clone()),
            AppError::BadRequest(m) => AppError::BadRequest(m.clone()),
            AppError::Conflict(m) => AppError::Conflict(m.clone()),
            AppError::TooLarge(m) => AppError::TooLarge(m.clone()),
            AppError::QuotaExceeded(m) => AppError::QuotaExceeded(m.clone()),
            AppError::ShuttingDown => AppError::ShuttingDown,
            AppError::TooManyRequests { wait, message } => {
                AppError::TooManyRequests { wait: *wait, message: message.clone() }
            }
            AppError::Busy(m) => AppError::Busy(m.clone()),
            AppError::TimedOut(m) => AppError::TimedOut(m.clone()),
            AppError::Internal(err) => AppError::Internal(anyhow::anyhow!("{err:#}")),
        }
    }
}

impl IntoResponse for AppError {
    fn into_response(self) -> Response {
        let (status, code) = match &self {
            AppError::Unauthorized => (StatusCode::UNAUTHORIZED, "unauthorized"),
            AppError::Forbidden(_) => (StatusCode::FORBIDDEN, "forbidden"),
            AppError::NotFound(_) => (StatusCode::NOT_FOUND, "not_found"),
            AppError::BadRequest(_) => (StatusCode::BAD_REQUEST, "bad_request"),
            AppError::Conflict(_) => (StatusCode::CONFLICT, "conflict"),
            AppError::TooLarge(_) => (StatusCode::PAYLOAD_TOO_LARGE, "too_large"),
            AppError::QuotaExceeded(_) => (StatusCode::PAYLOAD_TOO_LARGE, "quota_exceeded"),
            AppError::ShuttingDown => (StatusCode::SERVICE_UNAVAILABLE, "shutting_down"),
            AppError::Busy(_) => (StatusCode::SERVICE_UNAVAILABLE, "busy"),
            AppError::TimedOut(_) => (StatusCode::REQUEST_TIMEOUT, "timeout"),
            AppError::TooManyRequests { .. } => {
                (StatusCode::TOO_MANY_REQUESTS, "too_many_requests")
            }
            AppError::Internal(err) => {
                tracing::error!(error = ?err, "request failed");
                (StatusCode::INTERNAL_SERVER_ERROR, "internal")
            }
        };
        metrics::counter!("penmesh_http_errors_total", "code" => code).increment(1);
        let body = ErrorBody { error: code.into(), message: self.to_string() };
        let mut response = (status, Json(body)).into_response();
        if let AppError::TooManyRequests { wait, .. } = &self {
            let seconds = crate::rate::retry_after_secs(*wait);
            response.headers_mut().insert(header::RETRY_AFTER, HeaderValue::from(seconds));
        }
        if let AppError::Busy(_) = &self {
            response.headers_mut().insert(header::RETRY_AFTER, HeaderValue::from(1));
        }
        if status == StatusCode::UNAUTHORIZED {
            response
                .headers_mut()
                .insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer"));
        }
        response
    }
}

/// The bearer token of a request: `Authorization: Bearer …`, else `other` (the token a
/// browser offers as a WebSocket subprotocol). Never the query string: URLs reach logs.
pub fn request_token<'a>(headers: &'a HeaderMap, other: Option<&'a str>) -> Option<&'a str> {
    headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer ").or_else(|| v.strip_prefix("bearer ")))
        .map(str::trim)
        .or(other)
        .filter(|t| !t.is_empty())
}

/// The session the request's token opens.
pub async fn token_session(
    state: &AppState,
    headers: &HeaderMap,
    subprotocol: Option<&str>,
) -> Result<Uuid, AppError> {
    let token = request_token(headers, subprotocol).ok_or(AppError::Unauthorized)?;
    state.store.session_for_token_hash(&hash_token(token)).await?.ok_or(AppError::Unauthorized)
}

/// Checks that the request's token opens the session named in the path.
pub async fn authorize_session(
    state: &AppState,
    headers: &HeaderMap,
    subprotocol: Option<&str>,
    session: &str,
) -> Result<Uuid, AppError> {
    let session = Uuid::parse_str(session).map_err(|_| AppError::Unauthorized)?;
    let of_token = token_session(state, headers, subprotocol).await?;
    if of_token == session { Ok(session) } else { Err(AppError::Unauthorized) }
}

/// The stroke `id` of the token's session.
pub(crate) async fn authorized_stroke(
    state: &AppState,
    headers: &HeaderMap,
    id: &str,
) -> Result<StrokeRow, AppError> {
    let session = token_session(state, headers, None).await?;
    let not_found = || AppError::NotFound(format!("no stroke {id} in this session"));
    let id = Uuid::parse_str(id).map_err(|_| not_found())?;
    let row = state.store.stroke(id).await?.ok_or_else(not_found)?;
    if row.session_id == session { Ok(row) } else { Err(not_found()) }
}

/// The stroke `id` of the token's session when the request speaks for its drawer (the
/// participant of its `x-penmesh-key`), and that participant; before any body is read.
/// `action` names what only the drawer may do, for the refusal ("store or build its mesh").
pub(crate) async fn owned_stroke(
    state: &AppState,
    headers: &HeaderMap,
    id: &str,
    action: &str,
) -> Result<(StrokeRow, ParticipantId), AppError> {
    let row = authorized_stroke(state, headers, id).await?;
    let participant = match request_participant(row.session_id, headers) {
        Ok(participant) => participant,
        Err(KeyError::Missing) => {
            return Err(AppError::Forbidden(format!(
                "only the drawer of stroke {} may {action}: send its participant key (its \
                 hello.key) in the {KEY_HEADER} header",
                row.id
            )));
        }
        Err(KeyError::Malformed(why)) => return Err(AppError::BadRequest(why)),
    };
    if participant != row.participant {
        return Err(AppError::Forbidden(format!(
            "stroke {} was drawn by another participant: only its drawer may {action}",
            row.id
        )));
    }
    Ok((row, participant))
}

/// Most bytes of a small JSON body (a placement: 16 numbers; a duplicate's request: a
/// placement and an id), however its numbers are written.
pub(crate) const SMALL_BODY_BYTES: usize = 16 * 1024;

/// A small body read whole, at most `limit` bytes (413 past it, told by `Content-Length` before
/// anything is read): for the routes that read it only once the request is authorised.
pub(crate) async fn small_body(
    headers: &HeaderMap,
    body: Body,
    limit: usize,
) -> Result<Bytes, AppError> {
    let too_large =
        || AppError::TooLarge(format!("the body is larger than this route takes: {limit} bytes"));
    let length: Option<u64> =
        headers.get(header::CONTENT_LENGTH).and_then(|v| v.to_str().ok()?.parse().ok());
    if length.is_some_and(|n| n > limit as u64) {
        return Err(too_large());
    }
    axum::body::to_bytes(body, limit).await.map_err(|err| {
        if std::error::Error::source(&err)
            .is_some_and(|e| e.is::<http_body_util::LengthLimitError>())
        {
            too_large()
        } else {
            AppError::BadRequest(format!("cannot read the body: {err}"))
        }
    })
}

fn wants_binary(headers: &HeaderMap) -> bool {
    headers
        .get(header::ACCEPT)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.contains("application/octet-stream"))
}

/// Creates a session and its token.
#[utoipa::path(post, path = "/v1/sessions", tag = "sessions",
    responses((status = 201, description = "Session created", body = NewSession),
              (status = 429, description = "Too many sessions from this address (`Retry-After`)",
               body = ErrorBody)))]
pub async fn create_session(
    State(state): State<AppState>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    headers: HeaderMap,
) -> Result<(StatusCode, Json<NewSession>), AppError> {
    state.session_limiter.check(peer, &headers)?;
    let mut bytes = [0u8; 32];
    rand::rng().fill_bytes(&mut bytes);
    let token = hex::encode(bytes);
    let session = Uuid::new_v4();
    state.store.create_session(session, &hash_token(&token)).await?;
    metrics::counter!("penmesh_sessions_total").increment(1);
    Ok((StatusCode::CREATED, Json(NewSession { session, token })))
}

impl From<StrokeRow> for StrokeInfo {
    fn from(row: StrokeRow) -> StrokeInfo {
        StrokeInfo {
            id: row.id,
            session: row.session_id,
            participant: row.participant,
            status: row.status,
            n_points: row.n_points,
            n_retained: row.n_retained,
            brush: row.brush,
            params: row.params,
            device: row.device,
            has_mesh: row.has_mesh,
            created_at: row.created_at,
            updated_at: row.updated_at,
            removed: row.removed,
            placement: row.placement,
            duplicate_of: row.duplicate_of,
            solid: row.solid,
        }
    }
}

/// `?include=removed` of the strokes list.
#[derive(Debug, serde::Deserialize, utoipa::IntoParams)]
pub struct ListQuery {
    /// `removed`: also the strokes taken back, each with who took it back and when.
    include: Option<String>,
}

/// The strokes of a session, oldest first; those taken back (undo, the eraser) only with
/// `?include=removed`.
#[utoipa::path(get, path = "/v1/sessions/{session}/strokes", tag = "strokes",
    params(("session" = Uuid, Path), ListQuery), security(("bearer" = [])),
    responses((status = 200, body = StrokeList), (status = 400, body = ErrorBody),
        (status = 401, body = ErrorBody)))]
pub async fn list_strokes(
    State(state): State<AppState>,
    Path(session): Path<String>,
    Query(query): Query<ListQuery>,
    headers: HeaderMap,
) -> Result<Json<StrokeList>, AppError> {
    let session = authorize_session(&state, &headers, None, &session).await?;
    let include_removed = match query.include.as_deref() {
        None => false,
        Some("removed") => true,
        Some(other) => {
            return Err(AppError::BadRequest(format!(
                "include={other:?}: the one thing a strokes list can include is `removed`"
            )));
        }
    };
    let rows = state.store.list_strokes(session, include_removed).await?;
    Ok(Json(StrokeList { strokes: rows.into_iter().map(StrokeInfo::from).collect() }))
}

/// The permit to handle a body of about `bytes` ([`AppState::large_body`]), or 503 `busy`.
fn large_body(state: &AppState, bytes: u64) -> Result<Option<OwnedSemaphorePermit>, AppError> {
    state.large_body(bytes).ok_or_else(|| {
        AppError::Busy(format!(
            "{} bodies over {LARGE_BODY_BYTES} bytes are being sent or received, the limit; \
             try again shortly",
            state.config.max_large_bodies
        ))
    })
}

/// About how many bytes a sample takes in a JSON body (`[x, y, t, p]` with their digits).
const JSON_BYTES_PER_SAMPLE: u64 = 48;

/// Samples handed to the socket at once by a streamed body: about 200 KB of JSON.
const SAMPLES_PER_PIECE: usize = 4096;

/// A body of `bytes` handed out in pieces, holding `permit` until the last one is taken: a
/// large body's permit is held while most of it is written, not only while it is made.
fn held_body(bytes: Bytes, permit: Option<OwnedSemaphorePermit>) -> Body {
    const PIECE: usize = 256 * 1024;
    let pieces = (0..bytes.len().div_ceil(PIECE)).map(move |i| {
        Ok::<_, std::io::Error>(bytes.slice(i * PIECE..((i + 1) * PIECE).min(bytes.len())))
    });
    Body::from_stream(futures_util::stream::iter(pieces).map(move |piece| {
        let _held = &permit;
        piece
    }))
}

/// A stroke's samples as the body of a response: JSON ([`StrokeSamples`]) or, on `Accept:
/// application/octet-stream`, the wire codec's `Retained` message carrying every sample, the
/// metadata in headers. The JSON of `samples` is written piece by piece as they are decoded,
/// never whole; the binary form is made whole (the codec predicts each sample from the ones
/// before it, and it takes a few bytes a sample). `permit` is held until the body is sent.
async fn samples_response(
    headers: &HeaderMap,
    stroke: StrokeInfo,
    indices: Option<Vec<u64>>,
    samples: RawSamples,
    permit: Option<OwnedSemaphorePermit>,
) -> Result<Response, AppError> {
    if !wants_binary(headers) {
        return Ok(json_samples_body(stroke, indices, samples, permit)?.into_response());
    }
    let id = stroke.id;
    let samples = tokio::task::spawn_blocking(move || samples.collect_all())
        .await
        .map_err(anyhow::Error::from)??;
    let msg =
        ServerMessage::Retained(Retained { stroke: id, first: 0, points: PointBatch(samples) });
    let body = held_body(Bytes::from(encode_server(&msg)), permit);
    let mut response = ([(header::CONTENT_TYPE, "application/octet-stream")], body).into_response();
    let h = response.headers_mut();
    for (name, value) in [
        ("x-penmesh-status", stroke.status.as_str().to_string()),
        ("x-penmesh-n-points", stroke.n_points.to_string()),
        ("x-penmesh-n-retained", stroke.n_retained.to_string()),
    ] {
        if let Ok(value) = HeaderValue::from_str(&value) {
            h.insert(name, value);
        }
    }
    Ok(response)
}

/// The JSON of [`StrokeSamples`], byte for byte as serde writes it, streamed: the head, then
/// the samples [`SAMPLES_PER_PIECE`] at a time as each stored piece is decoded (on the
/// blocking pool), then the end. A stored piece that cannot be read ends the body with an
/// error, so the client sees a broken body, never a short one.
fn json_samples_body(
    stroke: StrokeInfo,
    indices: Option<Vec<u64>>,
    samples: RawSamples,
    permit: Option<OwnedSemaphorePermit>,
) -> anyhow::Result<Body> {
    let id = stroke.id;
    let head = serde_json::to_string(&StrokeSamples { stroke, indices, samples: Vec::new() })?;
    // `samples` is the last field: the head is everything before its empty list closes.
    let head = head.strip_suffix("]}").context("the samples close the JSON")?.to_string();
    struct Sending {
        samples: Option<RawSamples>,
        piece: Option<(RawPiece, usize)>,
        first: bool,
        _permit: Option<OwnedSemaphorePermit>,
    }
    let start = Sending { samples: Some(samples), piece: None, first: true, _permit: permit };
    let pieces = futures_util::stream::try_unfold(start, move |mut sending| async move {
        loop {
            if let Some((piece, at)) = sending.piece.take() {
                let end = (at + SAMPLES_PER_PIECE).min(piece.len());
                let mut json = Vec::with_capacity((end - at) * JSON_BYTES_PER_SAMPLE as usize);
                for sample in &piece[at..end] {
                    if !std::mem::take(&mut sending.first) {
                        json.push(b',');
                    }
                    serde_json::to_writer(&mut json, sample).map_err(std::io::Error::other)?;
                }
                if end < piece.len() {
                    sending.piece = Some((piece, end));
                }
                return Ok(Some((Bytes::from(json), sending)));
            }
            let Some(mut samples) = sending.samples.take() else { return Ok(None) };
            let (samples, next) = tokio::task::spawn_blocking(move || {
                let next = samples.next();
                (samples, next)
            })
            .await
            .map_err(std::io::Error::other)?;
            match next {
                Some(Ok(piece)) => {
                    sending.samples = Some(samples);
                    sending.piece = Some((piece, 0));
                }
                Some(Err(err)) => {
                    tracing::error!(error = %err, stroke = %id, "a stored piece of a stroke being sent is unreadable");
                    return Err(std::io::Error::other(format!("stroke {id} cannot be read")));
                }
                None => return Ok(Some((Bytes::from_static(b"]}"), sending))),
            }
        }
    });
    let head = futures_util::stream::once(async move { Ok(Bytes::from(head)) });
    Ok(Body::from_stream(head.chain(pieces)))
}

/// The simplified stroke (once the stroke is done). JSON, or the wire codec's `Retained`
/// message on `Accept: application/octet-stream`.
#[utoipa::path(get, path = "/v1/strokes/{id}/simplified", tag = "strokes",
    params(("id" = Uuid, Path)), security(("bearer" = [])),
    responses((status = 200, body = StrokeSamples), (status = 401, body = ErrorBody),
        (status = 404, body = ErrorBody), (status = 409, description = "stroke not done", body = ErrorBody),
        (status = 503, description = "too many large bodies at once (`Retry-After`)", body = ErrorBody)))]
pub async fn simplified(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, AppError> {
    let row = authorized_stroke(&state, &headers, &id).await?;
    // The samples and, in JSON, about 8 bytes of index each.
    let permit = large_body(&state, row.n_retained * (JSON_BYTES_PER_SAMPLE + 8))?;
    let Some(simplified) = state.store.simplified(row.id).await? else {
        return Err(AppError::Conflict(format!(
            "stroke {} is {}: it has no simplified form until it is done",
            row.id,
            row.status.as_str()
        )));
    };
    let samples = RawSamples::from(simplified.samples);
    samples_response(&headers, row.into(), Some(simplified.indices), samples, permit).await
}

/// Every committed sample of a stroke as the client sent it (after the client's own
/// resampling, if it resamples), put on the codec's grid: the input of the simplification.
#[utoipa::path(get, path = "/v1/strokes/{id}/raw", tag = "strokes",
    params(("id" = Uuid, Path)), security(("bearer" = [])),
    responses((status = 200, body = StrokeSamples), (status = 401, body = ErrorBody), (status = 404, body = ErrorBody),
        (status = 503, description = "too many large bodies at once (`Retry-After`)", body = ErrorBody)))]
pub async fn raw(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, AppError> {
    let row = authorized_stroke(&state, &headers, &id).await?;
    let permit = large_body(&state, row.n_points * JSON_BYTES_PER_SAMPLE)?;
    let samples = state.store.raw(row.id).await?;
    samples_response(&headers, row.into(), None, samples, permit).await
}

/// What only a stroke's drawer may do with its mesh, as the refusals say it.
pub(crate) const STORE_MESH: &str = "store or build its mesh";

/// Stores the stroke's mesh (a GLB body, `model/gltf-binary`, a mesh of the stroke's solid),
/// replacing any earlier one; only the stroke's drawer may (its participant key in
/// `x-penmesh-key`). A duplicate gets a mesh of its own; duplicates of the stroke that share
/// its mesh and are another solid keep the one they showed. Vertex and triangle counts
/// are read from the GLB's accessors. The uploader stored is the drawer's participant id. The
/// GLB may require `KHR_mesh_quantization` and `EXT_meshopt_compression` (what penmesh writes)
/// and no other extension; a compressed view must decode to what it claims.
#[utoipa::path(put, path = "/v1/strokes/{id}/mesh", tag = "meshes",
    params(("id" = Uuid, Path),
        ("x-penmesh-key" = String, Header, description = "the drawer's participant key (its hello.key)")),
    security(("bearer" = [])),
    request_body(content = Vec<u8>, content_type = "model/gltf-binary"),
    responses((status = 200, body = MeshInfo), (status = 400, body = ErrorBody), (status = 401, body = ErrorBody),
        (status = 403, description = "not the stroke's drawer", body = ErrorBody),
        (status = 404, body = ErrorBody), (status = 409, body = ErrorBody),
        (status = 413, description = "body too large (`too_large`), or the session's meshes would pass its quota (`quota_exceeded`)", body = ErrorBody),
        (status = 503, description = "too many large bodies at once (`Retry-After`)", body = ErrorBody)))]
pub async fn put_mesh(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    body: axum::body::Body,
) -> Result<Json<MeshInfo>, AppError> {
    // The token, the stroke and its drawer first: a stranger's upload is refused before its
    // body is read.
    let (row, participant) = owned_stroke(&state, &headers, &id, STORE_MESH).await?;
    let limit = state.config.max_body_bytes;
    // As large as it says, or as the limit when it does not say.
    let length = headers.get(header::CONTENT_LENGTH).and_then(|v| v.to_str().ok()?.parse().ok());
    let _permit = large_body(&state, length.unwrap_or(limit as u64).min(limit as u64))?;
    let body = axum::body::to_bytes(body, limit).await.map_err(|err| {
        if std::error::Error::source(&err)
            .is_some_and(|e| e.is::<http_body_util::LengthLimitError>())
        {
            AppError::TooLarge(format!("the body is larger than the limit of {limit} bytes"))
        } else {
            AppError::BadRequest(format!("cannot read the body: {err}"))
        }
    })?;
    if row.status != penmesh::protocol::StrokeStatus::Done {
        return Err(AppError::Conflict(format!(
            "stroke {} is {}: a mesh can be stored once it is done",
            row.id,
            row.status.as_str()
        )));
    }
    let counts = crate::glb::inspect(&body, limit)
        .map_err(|e| AppError::BadRequest(format!("not a valid GLB: {e}")))?;
    // An upload is taken to be of the stroke's solid when it was asked.
    let (solid, glb) = (row.solid, body.to_vec());
    store_mesh(&state, &row, solid, glb, counts, Some(participant.to_string())).await.map(Json)
}

/// Stores a done stroke's checked GLB, a mesh of `solid`, and tells the session's peers
/// (`PeerMesh`): the one path of an uploaded mesh and of one the proxy built
/// (`crate::mesh_build`). The duplicates that shared the stroke's mesh and are another solid
/// keep the one they showed (`store/writer/sharing.rs`).
pub(crate) async fn store_mesh(
    state: &AppState,
    row: &StrokeRow,
    solid: penmesh::Solid,
    glb: Vec<u8>,
    counts: crate::glb::MeshCounts,
    uploader: Option<String>,
) -> Result<MeshInfo, AppError> {
    let bytes = glb.len() as u64;
    let mesh = MeshRow {
        glb,
        vertices: counts.vertices,
        triangles: counts.triangles,
        uploader: uploader.clone(),
        created_at: now_ms(),
    };
    // Peers hear of the mesh once it is stored (the writer publishes the event with the
    // commit, after the stroke's end). Through the group commit like every write: a mesh never
    // holds the database's write lock on its own.
    let event = SessionEvent::new(
        row.session_id,
        EventKind::Mesh {
            participant: row.participant,
            stroke: row.id,
            created_at: mesh.created_at,
        },
    );
    let (quota, mesh_at) = (state.config.max_session_mesh_bytes, mesh.created_at);
    let op = WriteOp::PutMesh { stroke: row.id, session: row.session_id, mesh, solid, quota };
    state.writer.write_with(vec![op], vec![event]).await.map_err(|err| match err {
        WriteError::Quota(why) => AppError::QuotaExceeded(why),
        err => AppError::Internal(err.into()),
    })?;
    metrics::counter!("penmesh_meshes_total").increment(1);
    if let Err(err) = tell_sharers(state, row, mesh_at).await {
        tracing::warn!(stroke = %row.id, error = %err, "telling a stored mesh's sharers");
    }
    Ok(MeshInfo {
        stroke: row.id,
        bytes,
        vertices: counts.vertices,
        triangles: counts.triangles,
        uploader,
    })
}

/// Tells the session that the duplicates still sharing `row`'s mesh row (those of its solid)
/// show its new mesh too, stored at `created_at`: a `peer_mesh` each, so that a page fetches
/// it. A page fetches a stroke's current mesh, so one told never shows a wrong one; the
/// stored mesh does not depend on it (a failure is only logged).
async fn tell_sharers(state: &AppState, row: &StrokeRow, created_at: i64) -> anyhow::Result<()> {
    let sharers = state.store.mesh_sharers(row.id).await?;
    if sharers.is_empty() {
        return Ok(());
    }
    let events = sharers
        .into_iter()
        .map(|(stroke, participant)| {
            let kind = EventKind::Mesh { participant, stroke, created_at };
            SessionEvent::new(row.session_id, kind)
        })
        .collect();
    Ok(state.writer.write_with(Vec::new(), events).await?)
}

/// The stroke's mesh as `model/gltf-binary`, as stored: from penmesh, quantised and compressed
/// with `EXT_meshopt_compression` unless its uploader chose otherwise (three.js reads it with
/// `GLTFLoader.setMeshoptDecoder(MeshoptDecoder)`).
#[utoipa::path(get, path = "/v1/strokes/{id}/mesh", tag = "meshes",
    params(("id" = Uuid, Path)), security(("bearer" = [])),
    responses((status = 200, content_type = "model/gltf-binary", body = Vec<u8>), (status = 401, body = ErrorBody),
        (status = 404, body = ErrorBody),
        (status = 503, description = "too many large bodies at once (`Retry-After`)", body = ErrorBody)))]
pub async fn get_mesh(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, AppError> {
    let row = authorized_stroke(&state, &headers, &id).await?;
    let no_mesh = || AppError::NotFound(format!("stroke {} has no mesh", row.id));
    let bytes = state.store.mesh_bytes(row.id).await?.ok_or_else(no_mesh)?;
    let permit = large_body(&state, bytes)?;
    let mesh = state.store.mesh(row.id).await?.ok_or_else(no_mesh)?;
    let body = held_body(Bytes::from(mesh.glb), permit);
    let mut response = ([(header::CONTENT_TYPE, "model/gltf-binary")], body).into_response();
    let h = response.headers_mut();
    h.insert("x-penmesh-vertices", HeaderValue::from(mesh.vertices));
    h.insert("x-penmesh-triangles", HeaderValue::from(mesh.triangles));
    Ok(response)
}

/// Liveness: the process answers.
#[utoipa::path(get, path = "/healthz", tag = "operations", responses((status = 200, description = "alive")))]
pub async fn healthz() -> &'static str {
    "ok"
}

/// How long `/readyz` waits for the database. Probes come every few seconds: without a
/// deadline a hung database would keep every probe (and a pool connection each) waiting for
/// the pool's acquire timeout, and the orchestrator would learn nothing meanwhile.
pub const READY_DB_DEADLINE: std::time::Duration = std::time::Duration::from_secs(1);

/// Readiness: the database answers within [`READY_DB_DEADLINE`].
#[utoipa::path(get, path = "/readyz", tag = "operations",
    responses((status = 200, description = "ready"), (status = 503, description = "database unreachable or slow, or shutting down")))]
pub async fn readyz(State(state): State<AppState>) -> Response {
    if state.shutdown.is_cancelled() {
        return (StatusCode::SERVICE_UNAVAILABLE, "shutting down").into_response();
    }
    match tokio::time::timeout(READY_DB_DEADLINE, state.store.ping()).await {
        Ok(Ok(())) => "ready".into_response(),
        Ok(Err(err)) => {
            tracing::warn!(error = %err, "readiness: database unreachable");
            (StatusCode::SERVICE_UNAVAILABLE, "database unreachable").into_response()
        }
        Err(_) => {
            tracing::warn!(
                deadline_ms = READY_DB_DEADLINE.as_millis() as u64,
                "readiness: database too slow"
            );
            (StatusCode::SERVICE_UNAVAILABLE, "database did not answer in time").into_response()
        }
    }
}

/// Prometheus metrics in the text format.
#[utoipa::path(get, path = "/metrics", tag = "operations", responses((status = 200, description = "Prometheus text")))]
pub async fn metrics(State(state): State<AppState>) -> Response {
    let mut text = state.metrics.render();
    if let Some(stages) = crate::stages::render() {
        text.push_str(&stages);
    }
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text).into_response()
}

#[cfg(test)]
mod tests {
    use super::*;

    // The streamed JSON of a stroke's samples is, byte for byte, what serde writes whole.
    #[tokio::test(flavor = "multi_thread", worker_threads = 1)]
    async fn streamed_samples_are_the_json_serde_writes() {
        let samples: Vec<penmesh::Sample> = (0..SAMPLES_PER_PIECE * 2 + 7)
            .map(|i| penmesh::Sample::new(i as f64 * 0.5, -(i as f64), i as f64 * 8.125, 0.25))
            .collect();
        let (id, session, participant) = (Uuid::new_v4(), Uuid::new_v4(), Uuid::new_v4());
        let stroke = || StrokeInfo {
            id,
            session,
            participant,
            status: penmesh::protocol::StrokeStatus::Done,
            n_points: samples.len() as u64,
            n_retained: 3,
            brush: penmesh::Brush::default(),
            params: penmesh::AcutsParams::default(),
            device: Some("pen \"1\"".into()),
            has_mesh: false,
            created_at: 1,
            updated_at: 2,
            removed: None,
            placement: penmesh::Placement::IDENTITY,
            duplicate_of: None,
            solid: penmesh::Solid::ROD,
        };
        for indices in [None, Some(vec![0, 5, 9])] {
            let whole = StrokeSamples {
                stroke: stroke(),
                indices: indices.clone(),
                samples: samples.clone(),
            };
            let expected = serde_json::to_vec(&whole).unwrap();
            let body = json_samples_body(stroke(), indices, samples.clone().into(), None);
            let streamed = axum::body::to_bytes(body.unwrap(), usize::MAX).await.unwrap();
            assert_eq!(String::from_utf8_lossy(&streamed), String::from_utf8_lossy(&expected));
        }
    }
}
