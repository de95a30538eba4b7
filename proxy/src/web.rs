//! The browser page (`client/web/`), built by `build.rs` and embedded in the binary, served at
//! `/` (a new session) and `/s/{session}` (a session; its token stays in the URL fragment, which
//! browsers never send, so it reaches no access log). The page's WebSocket offers the token as
//! the subprotocol `penmesh.token.TOKEN` next to [`SUBPROTOCOL`], which the proxy selects.

use axum::Router;
use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;

use penmesh::protocol::{POSITION_STEP, PRESSURE_STEP, PROTOCOL_VERSION, TIME_STEP};

use crate::state::AppState;

/// The subprotocol the proxy selects when a client offers it.
pub const SUBPROTOCOL: &str = "penmesh";
/// Prefix of the subprotocol that carries a browser's session token.
const TOKEN_PREFIX: &str = "penmesh.token.";

const INDEX_HTML: &str = include_str!(concat!(env!("OUT_DIR"), "/web/index.html"));
const APP_JS: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/web/app.js"));
const APP_JS_GZ: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/web/app.js.gz"));

pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/", get(index))
        .route("/s/{session}", get(index))
        .route("/web/app.js", get(app_js))
}

/// The session token offered as a `Sec-WebSocket-Protocol` entry, if any.
pub fn subprotocol_token(headers: &HeaderMap) -> Option<&str> {
    headers
        .get_all(header::SEC_WEBSOCKET_PROTOCOL)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .find_map(|p| p.trim().strip_prefix(TOKEN_PREFIX))
        .filter(|t| !t.is_empty())
}

async fn index(State(state): State<AppState>) -> Response {
    // The page speaks the protocol version and snaps to the grid of this binary: one place for
    // those facts. It also gets this proxy's ACUTS defaults, to ask a tighter pressure
    // tolerance for a wide brush (docs/web.md, "The mesh and the ink").
    let grid = format!("{POSITION_STEP} {TIME_STEP} {PRESSURE_STEP}");
    let c = &state.config;
    let params = format!("{} {} {}", c.tolerance, c.angle_deg, c.pressure_tolerance);
    let html = INDEX_HTML
        .replace("__PENMESH_PROTOCOL__", &PROTOCOL_VERSION.to_string())
        .replace("__PENMESH_GRID__", &grid)
        .replace("__PENMESH_PARAMS__", &params);
    (
        [
            (header::CONTENT_TYPE, "text/html; charset=utf-8"),
            (header::CACHE_CONTROL, "no-cache"),
            // The token lives in the fragment: never let it leave in a Referer.
            (header::REFERRER_POLICY, "no-referrer"),
        ],
        html,
    )
        .into_response()
}

/// Whether the request's `Accept-Encoding` names gzip.
pub(crate) fn accepts_gzip(headers: &HeaderMap) -> bool {
    headers
        .get(header::ACCEPT_ENCODING)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.split(',').any(|e| e.trim().starts_with("gzip")))
}

async fn app_js(headers: HeaderMap) -> Response {
    let gzip = accepts_gzip(&headers);
    let mut response = if gzip { APP_JS_GZ.into_response() } else { APP_JS.into_response() };
    let h = response.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static("text/javascript; charset=utf-8"));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    h.insert(header::VARY, HeaderValue::from_static("accept-encoding"));
    if gzip {
        h.insert(header::CONTENT_ENCODING, HeaderValue::from_static("gzip"));
    }
    response
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_token_is_read_from_the_offered_subprotocols() {
        let mut headers = HeaderMap::new();
        headers.insert(
            header::SEC_WEBSOCKET_PROTOCOL,
            HeaderValue::from_static("penmesh, penmesh.token.abc123"),
        );
        assert_eq!(subprotocol_token(&headers), Some("abc123"));
        headers.insert(header::SEC_WEBSOCKET_PROTOCOL, HeaderValue::from_static("penmesh"));
        assert_eq!(subprotocol_token(&headers), None);
    }
}
