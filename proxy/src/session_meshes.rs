//! `GET /v1/sessions/{session}/meshes`: every stored mesh of a session in one response (a mesh
//! bundle, `penmesh::protocol::encode_mesh_bundle` and its later layouts), so a page opens a
//! session with one request instead of one per mesh. Gzipped for a client that accepts it: plain
//! GLBs (float positions and normals) shrink to about half (`docs/performance-log.md`, "A busy
//! board").
//!
//! What the bundle holds is read first without the meshes ([`BundleEntry`]: stroke, drawer,
//! the stroke whose mesh it shows, size, when stored, counts, placement, solid). The ETag is a
//! hash of that, so a client that sends it back in `If-None-Match` gets 304 with no mesh hashed
//! or held. A 200 takes a large-body permit (waiting up to [`PERMIT_WAIT`] for one) and streams
//! the meshes a piece at a time (`bundle_body.rs`): a request holds a piece, never the whole
//! bundle (`docs/reliability.md`).

use std::time::Duration;

use axum::extract::{Path, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use penmesh::protocol::MESH_BUNDLE_CONTENT_TYPE;
use sha2::Digest;

use crate::bundle_body::{Layout, bundle_body, plan};
use crate::http::{AppError, ErrorBody, authorize_session};
use crate::query::Query;
use crate::state::{AppState, LARGE_BODY_BYTES};
use crate::store::BundleEntry;
use crate::web::accepts_gzip;

/// How long a bundle waits for a large-body permit before 503 `busy`, at most: a class that
/// opens one board at once takes turns.
const PERMIT_WAIT: Duration = Duration::from_secs(10);

/// Every stored mesh of the session with its stroke and drawer, in the order the strokes were
/// begun, as one `application/vnd.penmesh.mesh-bundle` body: `PMB1`, a u32 count, then per
/// mesh the stroke id and the participant id (16 bytes each), a u32 length and the GLB (u32
/// little-endian). Cacheable: `ETag`, and 304 on a matching `If-None-Match`. Gzipped
/// (`Content-Encoding: gzip`) when `Accept-Encoding` names gzip.
///
/// With `?placements=true` or `?layout=PMB2` (protocol 5), the `PMB2` layout: each mesh's
/// header also holds its stroke's current placement, 16 `f64`
/// (`penmesh::protocol::encode_placed_mesh_bundle`). With `?layout=PMB3` (protocol 6), each
/// distinct mesh once, then per stroke its ids, placement, solid and the index of its mesh
/// (`penmesh::protocol::encode_mesh_table_bundle`): a duplicate's shared mesh is not repeated.
#[utoipa::path(get, path = "/v1/sessions/{session}/meshes", tag = "meshes",
    params(("session" = Uuid, Path), BundleQuery,
        ("if-none-match" = Option<String>, Header, description = "the ETag of a bundle the client holds")),
    security(("bearer" = [])),
    responses(
        (status = 200, content_type = "application/vnd.penmesh.mesh-bundle", body = Vec<u8>,
         headers(("etag" = String, description = "a hash of what the bundle holds: each mesh's stroke, drawer, size, counts and time stored (and in PMB2 and PMB3 each stroke's placement, in PMB3 its solid and which strokes share a mesh)"))),
        (status = 304, description = "the client's bundle is current"),
        (status = 400, description = "a layout there is none of, or `placements=true` with a layout other than PMB2", body = ErrorBody),
        (status = 401, body = ErrorBody),
        (status = 503, description = "too many large bodies at once (`Retry-After`)", body = ErrorBody)))]
pub async fn session_meshes(
    State(state): State<AppState>,
    Path(session): Path<String>,
    Query(query): Query<BundleQuery>,
    headers: HeaderMap,
) -> Result<Response, AppError> {
    let layout = query.layout()?;
    let session = authorize_session(&state, &headers, None, &session).await?;
    let entries = state.store.session_bundle_entries(session).await?;
    let gzip = accepts_gzip(&headers);
    // Each layout and encoding is its own representation, with its own tag.
    let etag = format!(
        "\"{}{}{}\"",
        bundle_tag(&entries, layout),
        match layout {
            Layout::Pmb1 => "",
            Layout::Pmb2 => "-pmb2",
            Layout::Pmb3 => "-pmb3",
        },
        if gzip { "-gzip" } else { "" }
    );
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
    let plan = plan(entries, layout);
    let wait = PERMIT_WAIT.min(Duration::from_secs(state.config.request_timeout_secs) / 2);
    let permit = state.large_body_within(plan.bytes, wait).await.ok_or_else(|| {
        AppError::Busy(format!(
            "{} bodies over {LARGE_BODY_BYTES} bytes are being sent or received, the limit; \
             try again shortly",
            state.config.max_large_bodies
        ))
    })?;
    let content_type = (header::CONTENT_TYPE, HeaderValue::from_static(MESH_BUNDLE_CONTENT_TYPE));
    let body = bundle_body(state, plan, gzip, permit);
    if !gzip {
        // No length: a mesh replaced while it is sent goes at its new size.
        return Ok((cache, [content_type], body).into_response());
    }
    let encoding = (header::CONTENT_ENCODING, HeaderValue::from_static("gzip"));
    Ok((cache, [content_type, encoding], body).into_response())
}

/// The bundle's tag: a hash of what it holds, mesh by mesh. A mesh replaced changes its time
/// stored (and most likely its size and counts); a stroke taken back or brought back, or a
/// mesh added, changes the list; from `PMB2` on, a stroke moved changes its placement; in
/// `PMB3`, a solid changed, or a mesh shared by other strokes, changes the table.
fn bundle_tag(entries: &[BundleEntry], layout: Layout) -> String {
    let mut hash = sha2::Sha256::new();
    hash.update((entries.len() as u64).to_le_bytes());
    for e in entries {
        hash.update(e.stroke.as_bytes());
        hash.update(e.participant.as_bytes());
        for n in [e.bytes as i64, e.created_at, e.vertices, e.triangles] {
            hash.update(n.to_le_bytes());
        }
        if layout != Layout::Pmb1 {
            hash.update(e.placement.to_bytes());
        }
        if layout == Layout::Pmb3 {
            hash.update(e.solid.to_bytes());
            hash.update(e.mesh_stroke.as_bytes());
        }
    }
    hex::encode(&hash.finalize()[..16])
}

/// The bundle's layout: `?layout=PMB1|PMB2|PMB3`, or `?placements=true` (`PMB2`, as the pages
/// of protocol 5 ask); `PMB1` when neither is given.
#[derive(Debug, Default, serde::Deserialize, utoipa::IntoParams)]
#[into_params(parameter_in = Query)]
pub struct BundleQuery {
    /// `true`: the `PMB2` layout (what `layout=PMB2` asks), each mesh with its stroke's placement.
    #[serde(default)]
    placements: bool,
    /// `PMB1`, `PMB2` or `PMB3` (each distinct mesh once, then every stroke with its placement,
    /// solid and the index of its mesh).
    #[param(inline)]
    layout: Option<Layout>,
}

impl BundleQuery {
    fn layout(&self) -> Result<Layout, AppError> {
        match (self.placements, self.layout) {
            (false, layout) => Ok(layout.unwrap_or(Layout::Pmb1)),
            (true, None | Some(Layout::Pmb2)) => Ok(Layout::Pmb2),
            (true, Some(layout)) => Err(AppError::BadRequest(format!(
                "placements=true asks for the PMB2 layout, and layout={} for another: ask for one",
                layout.name()
            ))),
        }
    }
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
