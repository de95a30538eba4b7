//! `GET /v1/sessions/{session}/meshes`: every stored mesh of a session in one response (a mesh
//! bundle, `penmesh::protocol::encode_mesh_bundle`), so a page opens a session with one
//! request instead of one per mesh. Gzipped for a client that accepts it: plain GLBs (float
//! positions and normals) shrink to about half (`docs/performance.md`).
//!
//! What the bundle holds is read first without the meshes ([`BundleEntry`]: stroke, drawer,
//! size, when stored, counts). The ETag is a hash of that, so a client that sends it back in
//! `If-None-Match` gets 304 with no mesh hashed or held. A 200 takes a large-body permit (waiting up to
//! [`PERMIT_WAIT`] for one) and streams the meshes, read about [`PIECE_BYTES`] at a time and
//! gzipped as they go: a request holds a piece, never the whole bundle (`docs/reliability.md`).

use std::io::Write;
use std::time::Duration;

use axum::body::{Body, Bytes};
use axum::extract::{Path, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use flate2::write::GzEncoder;
use penmesh::protocol::{MESH_BUNDLE_CONTENT_TYPE, mesh_bundle_head, push_bundled_mesh};
use sha2::Digest;
use tokio::sync::OwnedSemaphorePermit;

use crate::http::{AppError, ErrorBody, authorize_session};
use crate::query::Query;
use crate::state::{AppState, LARGE_BODY_BYTES};
use crate::store::BundleEntry;
use crate::web::accepts_gzip;

/// Meshes read from storage at once for a bundle: about this many bytes (a larger mesh alone).
const PIECE_BYTES: u64 = 1 << 20;

/// How long a bundle waits for a large-body permit before 503 `busy`, at most: a class that
/// opens one board at once takes turns.
const PERMIT_WAIT: Duration = Duration::from_secs(10);

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
         headers(("etag" = String, description = "a hash of what the bundle holds: each mesh's stroke, drawer, size, counts and time stored"))),
        (status = 304, description = "the client's bundle is current"),
        (status = 401, body = ErrorBody),
        (status = 503, description = "too many large bodies at once (`Retry-After`)", body = ErrorBody)))]
pub async fn session_meshes(
    State(state): State<AppState>,
    Path(session): Path<String>,
    Query(layout): Query<BundleLayout>,
    headers: HeaderMap,
) -> Result<Response, AppError> {
    let session = authorize_session(&state, &headers, None, &session).await?;
    let entries = state.store.session_bundle_entries(session).await?;
    let gzip = accepts_gzip(&headers);
    // Each encoding is its own representation, with its own tag.
    let placed = layout.placements;
    let etag = format!(
        "\"{}{}{}\"",
        bundle_tag(&entries, placed),
        if placed { "-pmb2" } else { "" },
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
    let per_mesh = if placed { 164 } else { 36 };
    let size = 8 + entries.iter().map(|e| per_mesh + e.bytes).sum::<u64>();
    let wait = PERMIT_WAIT.min(Duration::from_secs(state.config.request_timeout_secs) / 2);
    let permit = state.large_body_within(size, wait).await.ok_or_else(|| {
        AppError::Busy(format!(
            "{} bodies over {LARGE_BODY_BYTES} bytes are being sent or received, the limit; \
             try again shortly",
            state.config.max_large_bodies
        ))
    })?;
    let content_type = (header::CONTENT_TYPE, HeaderValue::from_static(MESH_BUNDLE_CONTENT_TYPE));
    let body = bundle_body(state, entries, placed, gzip, permit);
    if !gzip {
        // No length: a mesh replaced while it is sent goes at its new size.
        return Ok((cache, [content_type], body).into_response());
    }
    let encoding = (header::CONTENT_ENCODING, HeaderValue::from_static("gzip"));
    Ok((cache, [content_type, encoding], body).into_response())
}

/// The bundle's tag: a hash of what it holds, mesh by mesh. A mesh replaced changes its time
/// stored (and most likely its size and counts); a stroke taken back or brought back, or a
/// mesh added, changes the list; with `placed`, a stroke moved changes its placement.
fn bundle_tag(entries: &[BundleEntry], placed: bool) -> String {
    let mut hash = sha2::Sha256::new();
    hash.update((entries.len() as u64).to_le_bytes());
    for e in entries {
        hash.update(e.stroke.as_bytes());
        hash.update(e.participant.as_bytes());
        for n in [e.bytes as i64, e.created_at, e.vertices, e.triangles] {
            hash.update(n.to_le_bytes());
        }
        if placed {
            hash.update(e.placement.to_bytes());
        }
    }
    hex::encode(&hash.finalize()[..16])
}

/// The bundle of `entries`, streamed: its head, then the meshes read [`PIECE_BYTES`] at a time
/// (each with its size as read, should it have been replaced since the entries were read),
/// gzipped piece by piece on the blocking pool when `gzip`. `permit` is held until the last
/// piece is taken. A mesh that cannot be read ends the body with an error: the client sees a
/// broken body, never a short one.
fn bundle_body(
    state: AppState,
    entries: Vec<BundleEntry>,
    placed: bool,
    gzip: bool,
    permit: Option<OwnedSemaphorePermit>,
) -> Body {
    struct Sending {
        state: AppState,
        head: Option<[u8; 8]>,
        placed: bool,
        entries: std::vec::IntoIter<BundleEntry>,
        gzip: Option<GzEncoder<Vec<u8>>>,
        done: bool,
        _permit: Option<OwnedSemaphorePermit>,
    }
    let start = Sending {
        head: Some(mesh_bundle_head(entries.len(), placed)),
        placed,
        entries: entries.into_iter(),
        state,
        gzip: gzip.then(|| GzEncoder::new(Vec::new(), flate2::Compression::fast())),
        done: false,
        _permit: permit,
    };
    let pieces = futures_util::stream::try_unfold(start, |mut sending| async move {
        if sending.done {
            return Ok::<_, std::io::Error>(None);
        }
        let mut piece = Vec::new();
        if let Some(head) = sending.head.take() {
            piece.extend_from_slice(&head);
        }
        let mut group = Vec::new();
        let mut bytes = 0;
        while bytes < PIECE_BYTES {
            let Some(entry) = sending.entries.next() else { break };
            bytes += entry.bytes;
            group.push(entry);
        }
        let last = group.is_empty() || sending.entries.as_slice().is_empty();
        // A duplicate shows its source's mesh: each mesh row is read once.
        let mut strokes: Vec<_> = group.iter().map(|e| e.mesh_stroke).collect();
        strokes.sort_unstable();
        strokes.dedup();
        let glbs = sending.state.store.mesh_glbs(&strokes).await.map_err(|err| {
            tracing::error!(error = %err, "reading the meshes of a bundle");
            std::io::Error::other("the session's meshes cannot be read")
        })?;
        for entry in &group {
            let glb = glbs.get(&entry.mesh_stroke).ok_or_else(|| {
                std::io::Error::other(format!("the mesh of stroke {} is gone", entry.stroke))
            })?;
            let placement = sending.placed.then_some(&entry.placement);
            push_bundled_mesh(&mut piece, entry.stroke, entry.participant, placement, glb);
        }
        drop(glbs);
        sending.done = last;
        let Some(mut encoder) = sending.gzip.take() else {
            return Ok(Some((Bytes::from(piece), sending)));
        };
        // The fastest level: most of what gzip saves here, for a fraction of the default's time.
        let (encoder, out) = tokio::task::spawn_blocking(move || {
            encoder.write_all(&piece)?;
            if last {
                return Ok::<_, std::io::Error>((None, encoder.finish()?));
            }
            let out = std::mem::take(encoder.get_mut());
            Ok((Some(encoder), out))
        })
        .await
        .map_err(std::io::Error::other)??;
        sending.gzip = encoder;
        Ok(Some((Bytes::from(out), sending)))
    });
    Body::from_stream(pieces)
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
