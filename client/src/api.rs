//! The proxy's `/v1` paths, the one place the client spells them (`docs/protocol.md`, and the
//! OpenAPI document the proxy serves at `/v1/openapi.json`), and the call more than one command
//! makes. The bodies are `penmesh::protocol`'s types, the proxy's own.

use anyhow::Context as _;
use serde::de::DeserializeOwned;
use uuid::Uuid;

/// `POST`: a new session and its token.
pub const SESSIONS: &str = "/v1/sessions";

/// The session's WebSocket.
pub fn session_ws(session: Uuid) -> String {
    format!("{SESSIONS}/{session}/ws")
}

/// `GET`: the session's strokes (`StrokeList`).
pub fn session_strokes(session: Uuid) -> String {
    format!("{SESSIONS}/{session}/strokes")
}

/// `GET`: the session's model (`?format=glb|stl|3mf`).
pub fn session_export(session: Uuid) -> String {
    format!("{SESSIONS}/{session}/export")
}

/// `POST` (with the participant key): a GLB penmesh exported, its strokes re-created.
pub fn session_import(session: Uuid) -> String {
    format!("{SESSIONS}/{session}/import")
}

/// `GET`: a stroke's simplified samples (`StrokeSamples`).
pub fn stroke_simplified(stroke: Uuid) -> String {
    format!("/v1/strokes/{stroke}/simplified")
}

/// `PUT` (with the participant key): what a stroke becomes, `penmesh::Solid`.
pub fn stroke_solid(stroke: Uuid) -> String {
    format!("/v1/strokes/{stroke}/solid")
}

/// `PUT` (with the participant key) and `GET`: a stroke's mesh, a GLB.
pub fn stroke_mesh(stroke: Uuid) -> String {
    format!("/v1/strokes/{stroke}/mesh")
}

/// `POST /v1/sessions` at `base` (`http://HOST:PORT`): a new session, read as `T` (the proxy's
/// `NewSession`, or a reply that adds to it).
pub async fn create_session<T: DeserializeOwned>(
    http: &reqwest::Client,
    base: &str,
) -> anyhow::Result<T> {
    let url = format!("{base}{SESSIONS}");
    http.post(&url)
        .send()
        .await
        .and_then(|r| r.error_for_status())
        .with_context(|| format!("cannot create a session: POST {url}"))?
        .json()
        .await
        .with_context(|| format!("POST {url} answered something else than a session"))
}
