//! `GET /v1/sessions/{session}/meshes`: every stored mesh of a session in one response (a mesh
//! bundle, `penmesh::protocol::encode_mesh_bundle`), so a page opens a session with one
//! request instead of one per mesh. The ETag is a hash of the body: a client that sends it back
//! in `If-None-Match` gets 304 while the session's meshes are the same. Gzipped for a client
//! that accepts it: plain GLBs (float positions and normals) shrink to about half
//! (`docs/performance.md`).

use std::io::Write;

use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use penmesh::protocol::{MESH_BUNDLE_CONTENT_TYPE, encode_mesh_bundle, encode_placed_mesh_bundle};
use sha2::Digest;

use crate::http::{AppError, ErrorBody, authorize_session};
use crate::state::AppState;
use crate::web::accepts_gzip;

/// Every stored mesh of the session with its stroke and drawer, in the order the strokes were
/// begun, as one `application/vnd.penmesh.mesh-bundle` body: `PMB1`, a u32 count, then per
/// mesh the stroke id and the participant id (16 bytes each), a u32 length and the GLB (u32
/// little-endian). Cacheable: `ETag`, and 304 on a matching `If-None-Match`. Gzipped
/// (`Content-Encoding: gzip`) when `Accept-Encoding` names gzip.
///
/// With `?placements=true` (protocol 5), the `PMB2` layout: each mesh's header also holds its
/// stroke's current placement, 16 `f64` (`penmesh::protocol::encode_placed_mesh_bundle`).
#[utoipa::path(get, path = "/v1/sessions/{session}/meshes", tag = "meshes",
    params(("session" = Uuid, Path),
        ("placements" = Option<bool>, Query, description = "true: the PMB2 layout, each mesh with its stroke's placement"),
        ("if-none-match" = Option<String>, Header, description = "the ETag of a bundle the client holds")),
    security(("bearer" = [])),
    responses(
        (status = 200, content_type = "application/vnd.penmesh.mesh-bundle", body = Vec<u8>,
         headers(("etag" = String, description = "a hash of the body"))),
        (status = 304, description = "the client's bundle is current"),
        (status = 401, body = ErrorBody)))]
pub async fn session_meshes(
    State(state): State<AppState>,
    Path(session): Path<String>,
    Query(layout): Query<BundleLayout>,
    headers: HeaderMap,
) -> Result<Response, AppError> {
    let session = authorize_session(&state, &headers, None, &session).await?;
    let body = if layout.placements {
        encode_placed_mesh_bundle(&state.store.session_placed_meshes(session).await?)
    } else {
        encode_mesh_bundle(&state.store.session_meshes(session).await?)
    };
    let gzip = accepts_gzip(&headers);
    // Each encoding is its own representation, with its own tag.
    let hash = hex::encode(&sha2::Sha256::digest(&body)[..16]);
    let etag = format!("\"{hash}{}\"", if gzip { "-gzip" } else { "" });
    let etag = HeaderValue::from_str(&etag).map_err(anyhow::Error::from)?;
    let cache = [
        (header::ETAG, etag.clone()),
        // Private (it needs the token) and revalidated on every use: a new mesh changes it.
        (header::CACHE_CONTROL, HeaderValue::from_static("private, no-cache")),
        (header::VARY, HeaderValue::from_static("accept-encoding")),
    ];
    if matches_any(&headers, &etag) {
        return Ok((StatusCode::NOT_MODIFIED, cache).into_response());
    }
    let content_type = (header::CONTENT_TYPE, HeaderValue::from_static(MESH_BUNDLE_CONTENT_TYPE));
    if !gzip {
        return Ok((cache, [content_type], body).into_response());
    }
    // The fastest level: most of what gzip saves here, for a fraction of the time of the default.
    let gzipped = tokio::task::spawn_blocking(move || {
        let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        encoder.write_all(&body)?;
        encoder.finish()
    })
    .await
    .map_err(anyhow::Error::from)?
    .map_err(anyhow::Error::from)?;
    let encoding = (header::CONTENT_ENCODING, HeaderValue::from_static("gzip"));
    Ok((cache, [content_type, encoding], gzipped).into_response())
}

/// `?placements=true`: the `PMB2` layout.
#[derive(Debug, Default, serde::Deserialize)]
pub struct BundleLayout {
    #[serde(default)]
    placements: bool,
}

/// Whether `If-None-Match` names `etag` (or is `*`), by the weak comparison RFC 9110 asks of it.
fn matches_any(headers: &HeaderMap, etag: &HeaderValue) -> bool {
    let opaque = |tag: &str| tag.trim().trim_start_matches("W/").to_owned();
    let ours = opaque(etag.to_str().unwrap_or_default());
    headers
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .any(|tag| tag.trim() == "*" || opaque(tag) == ours)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn if_none_match_is_compared_weakly_over_its_list() {
        let etag = HeaderValue::from_static("\"abc\"");
        let check = |value: &'static str| {
            let mut headers = HeaderMap::new();
            headers.insert(header::IF_NONE_MATCH, HeaderValue::from_static(value));
            matches_any(&headers, &etag)
        };
        assert!(check("\"abc\""));
        assert!(check("W/\"abc\""));
        assert!(check("\"x\", \"abc\""));
        assert!(check("*"));
        assert!(!check("\"abd\""));
        assert!(!check("abc"));
        assert!(!matches_any(&HeaderMap::new(), &etag));
    }
}
