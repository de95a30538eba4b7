//! HTTP handlers, the bearer-token check, and the one [`AppError`] every handler returns.
//!
//! Sessions are private: a missing or wrong token gets 401 whether or not the session exists.
//! Strokes are found by id and must belong to the token's session (404 otherwise). What only a
//! stroke's drawer may do (store or build its mesh) also needs the drawer's participant key in
//! the `x-penmesh-key` header (403 otherwise; see `crate::identity`).

use axum::Json;
use std::net::SocketAddr;

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

use crate::fanout::{EventKind, SessionEvent};
use crate::identity::{KeyError, request_participant};
use crate::state::AppState;
use crate::store::{Backend, MeshRow, StrokeRow, hash_token, now_ms};

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
    #[error("the proxy is shutting down")]
    ShuttingDown,
    /// A rate limit: the client may try again after this long.
    #[error("too many requests from this address; try again in {} s", .0.as_secs())]
    TooManyRequests(std::time::Duration),
    /// This replica is at a limit (e.g. `max_connections`): try again later or elsewhere.
    #[error("{0}")]
    Busy(String),
    #[error("internal error")]
    Internal(#[from] anyhow::Error),
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
            AppError::ShuttingDown => (StatusCode::SERVICE_UNAVAILABLE, "shutting_down"),
            AppError::Busy(_) => (StatusCode::SERVICE_UNAVAILABLE, "busy"),
            AppError::TooManyRequests(_) => (StatusCode::TOO_MANY_REQUESTS, "too_many_requests"),
            AppError::Internal(err) => {
                tracing::error!(error = ?err, "request failed");
                (StatusCode::INTERNAL_SERVER_ERROR, "internal")
            }
        };
        metrics::counter!("penmesh_http_errors_total", "code" => code).increment(1);
        let body = ErrorBody { error: code.into(), message: self.to_string() };
        let mut response = (status, Json(body)).into_response();
        if let AppError::TooManyRequests(wait) = &self {
            response.headers_mut().insert(header::RETRY_AFTER, HeaderValue::from(wait.as_secs()));
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
pub(crate) async fn owned_stroke(
    state: &AppState,
    headers: &HeaderMap,
    id: &str,
) -> Result<(StrokeRow, ParticipantId), AppError> {
    let row = authorized_stroke(state, headers, id).await?;
    let participant = match request_participant(row.session_id, headers) {
        Ok(participant) => participant,
        Err(KeyError::Missing) => {
            return Err(AppError::Forbidden(format!(
                "only the drawer of stroke {} may store or build its mesh: send its participant \
                 key (its hello.key) in the {KEY_HEADER} header",
                row.id
            )));
        }
        Err(KeyError::Malformed(why)) => return Err(AppError::BadRequest(why)),
    };
    if participant != row.participant {
        return Err(AppError::Forbidden(format!(
            "stroke {} was drawn by another participant: only its drawer may store or build its \
             mesh",
            row.id
        )));
    }
    Ok((row, participant))
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
    state.session_limiter.check(peer, &headers).map_err(AppError::TooManyRequests)?;
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
        }
    }
}

/// The strokes of a session, oldest first.
#[utoipa::path(get, path = "/v1/sessions/{session}/strokes", tag = "strokes",
    params(("session" = Uuid, Path)), security(("bearer" = [])),
    responses((status = 200, body = StrokeList), (status = 401, body = ErrorBody)))]
pub async fn list_strokes(
    State(state): State<AppState>,
    Path(session): Path<String>,
    headers: HeaderMap,
) -> Result<Json<StrokeList>, AppError> {
    let session = authorize_session(&state, &headers, None, &session).await?;
    let rows = state.store.list_strokes(session).await?;
    Ok(Json(StrokeList { strokes: rows.into_iter().map(StrokeInfo::from).collect() }))
}

fn samples_response(headers: &HeaderMap, body: StrokeSamples) -> Response {
    if !wants_binary(headers) {
        return Json(body).into_response();
    }
    // The binary form is the wire codec's `Retained` message carrying every sample; the
    // metadata travels in headers.
    let msg = ServerMessage::Retained(Retained {
        stroke: body.stroke.id,
        first: 0,
        points: PointBatch(body.samples),
    });
    let mut response =
        ([(header::CONTENT_TYPE, "application/octet-stream")], encode_server(&msg)).into_response();
    let h = response.headers_mut();
    for (name, value) in [
        ("x-penmesh-status", body.stroke.status.as_str().to_string()),
        ("x-penmesh-n-points", body.stroke.n_points.to_string()),
        ("x-penmesh-n-retained", body.stroke.n_retained.to_string()),
    ] {
        if let Ok(value) = HeaderValue::from_str(&value) {
            h.insert(name, value);
        }
    }
    response
}

/// The simplified stroke (once the stroke is done). JSON, or the wire codec's `Retained`
/// message on `Accept: application/octet-stream`.
#[utoipa::path(get, path = "/v1/strokes/{id}/simplified", tag = "strokes",
    params(("id" = Uuid, Path)), security(("bearer" = [])),
    responses((status = 200, body = StrokeSamples), (status = 401, body = ErrorBody),
        (status = 404, body = ErrorBody), (status = 409, description = "stroke not done", body = ErrorBody)))]
pub async fn simplified(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, AppError> {
    let row = authorized_stroke(&state, &headers, &id).await?;
    let Some(simplified) = state.store.simplified(row.id).await? else {
        return Err(AppError::Conflict(format!(
            "stroke {} is {}: it has no simplified form until it is done",
            row.id,
            row.status.as_str()
        )));
    };
    let body = StrokeSamples {
        stroke: row.into(),
        indices: Some(simplified.indices),
        samples: simplified.samples,
    };
    Ok(samples_response(&headers, body))
}

/// Every committed raw (resampled) sample of a stroke.
#[utoipa::path(get, path = "/v1/strokes/{id}/raw", tag = "strokes",
    params(("id" = Uuid, Path)), security(("bearer" = [])),
    responses((status = 200, body = StrokeSamples), (status = 401, body = ErrorBody), (status = 404, body = ErrorBody)))]
pub async fn raw(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, AppError> {
    let row = authorized_stroke(&state, &headers, &id).await?;
    let samples = state.store.raw_samples(row.id).await?;
    Ok(samples_response(&headers, StrokeSamples { stroke: row.into(), indices: None, samples }))
}

/// Stores the stroke's mesh (a GLB body, `model/gltf-binary`), replacing any earlier one; only
/// the stroke's drawer may (its participant key in `x-penmesh-key`). Vertex and triangle counts
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
        (status = 404, body = ErrorBody), (status = 409, body = ErrorBody), (status = 413, description = "body too large")))]
pub async fn put_mesh(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    body: axum::body::Body,
) -> Result<Json<MeshInfo>, AppError> {
    // The token, the stroke and its drawer first: a stranger's upload is refused before its
    // body is read.
    let (row, participant) = owned_stroke(&state, &headers, &id).await?;
    let limit = state.config.max_body_bytes;
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
    store_mesh(&state, &row, body.to_vec(), counts, Some(participant.to_string())).await.map(Json)
}

/// Stores a done stroke's checked GLB and tells the session's peers (`PeerMesh`): the one path
/// of an uploaded mesh and of one the proxy built (`crate::mesh_build`).
pub(crate) async fn store_mesh(
    state: &AppState,
    row: &StrokeRow,
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
    // Peers hear of the mesh once it is stored: with PostgreSQL by a notification of the same
    // transaction, with SQLite through the writer, which orders it after the stroke's end.
    let event = SessionEvent::new(
        row.session_id,
        EventKind::Mesh {
            participant: row.participant,
            stroke: row.id,
            created_at: mesh.created_at,
        },
    );
    let postgres = state.store.backend() == Backend::Postgres;
    let notified = if postgres { std::slice::from_ref(&event) } else { &[] };
    state.store.put_mesh(row.id, &mesh, notified).await?;
    if !postgres {
        state.writer.write_with(Vec::new(), vec![event]).await.map_err(anyhow::Error::from)?;
    }
    metrics::counter!("penmesh_meshes_total").increment(1);
    Ok(MeshInfo {
        stroke: row.id,
        bytes,
        vertices: counts.vertices,
        triangles: counts.triangles,
        uploader,
    })
}

/// The stroke's mesh as `model/gltf-binary`, as stored: from penmesh, quantised and compressed
/// with `EXT_meshopt_compression` unless its uploader chose otherwise (three.js reads it with
/// `GLTFLoader.setMeshoptDecoder(MeshoptDecoder)`).
#[utoipa::path(get, path = "/v1/strokes/{id}/mesh", tag = "meshes",
    params(("id" = Uuid, Path)), security(("bearer" = [])),
    responses((status = 200, content_type = "model/gltf-binary", body = Vec<u8>), (status = 401, body = ErrorBody),
        (status = 404, body = ErrorBody)))]
pub async fn get_mesh(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, AppError> {
    let row = authorized_stroke(&state, &headers, &id).await?;
    let mesh = state
        .store
        .mesh(row.id)
        .await?
        .ok_or_else(|| AppError::NotFound(format!("stroke {} has no mesh", row.id)))?;
    let mut response = ([(header::CONTENT_TYPE, "model/gltf-binary")], mesh.glb).into_response();
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
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], state.metrics.render()).into_response()
}
