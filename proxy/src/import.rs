//! Bringing a model back (issue 39, `docs/model-format.md`): `POST /v1/sessions/{session}/import`
//! takes a GLB that penmesh exported (`format=glb`) and re-creates each of its strokes in the
//! session through the writer, as a duplicate is written (`crate::placement::duplicate`):
//! the same simplified samples, exactly (they become the stroke's drawn samples, all kept: no
//! simplification runs again), its brush and its node's matrix as its placement. The importer
//! (the participant of `x-penmesh-key`) is every new stroke's drawer; the original author,
//! stroke id and time are kept beside it (`stroke_imports`), since an import cannot act as
//! another participant.
//!
//! **All or nothing**: every check runs and every mesh is built before anything is written,
//! then every stroke is written in one request to the writer, which commits it in one
//! transaction. The meshes (built as `crate::mesh_build` builds them for the page) are stored
//! after that commit, each as an upload is (`http::store_mesh`); the session's mesh quota is
//! checked for all of them before the strokes are written. Once the strokes are committed the
//! import is answered 201 even if a mesh then fails to be stored (the stroke stays meshless);
//! meshes not stored by half the request timeout are stored after the answer, so that a
//! committed import is answered as such, not 408. Others in the session see the strokes arrive
//! live, as any new stroke.
//!
//! **A retry imports once**: with an `Idempotency-Key` header the new strokes' ids are derived
//! from the session, the importer and the key, the first one claimed in the strokes'
//! transaction; the same import sent again (after a lost answer or a 408) finds them stored
//! and is answered as the first was, nothing stored twice.

use std::collections::HashMap;
use std::time::Duration;

use axum::Json;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode, header};
use penmesh::protocol::{Imported, ImportedStroke, MAX_NAME_CHARS, check_text, quantize_sample};
use penmesh::{
    AcutsParams, GlbMeta, GlbOptions, ImportedFrom, Kept, OutlineOptions, Placement, ReadStroke,
    SceneError, StrokeExtras,
};
use uuid::Uuid;

use crate::events::{EventKind, SessionEvent};
use crate::http::{AppError, ErrorBody, authorize_session, store_mesh};
use crate::mesh_build::PROXY_UPLOADER;
use crate::query::Query;
use crate::state::AppState;
use crate::store::{WriteError, WriteOp, now_ms};

/// Most strokes one import re-creates.
pub const MAX_IMPORT_STROKES: usize = 5_000;
/// The header that makes an import's retry find the first one (`docs/protocol.md`).
pub const IDEMPOTENCY_HEADER: &str = "idempotency-key";
/// Longest `Idempotency-Key` (characters).
const MAX_IDEMPOTENCY_KEY_CHARS: usize = 200;

/// The `Idempotency-Key` of a request, if any: 1 to 200 visible ASCII characters.
fn idempotency_key(headers: &HeaderMap) -> Result<Option<&str>, AppError> {
    let Some(value) = headers.get(IDEMPOTENCY_HEADER) else { return Ok(None) };
    let key = value.to_str().ok().filter(|k| {
        (1..=MAX_IDEMPOTENCY_KEY_CHARS).contains(&k.len())
            && k.bytes().all(|b| b.is_ascii_graphic())
    });
    key.map(Some).ok_or_else(|| {
        AppError::BadRequest(format!(
            "{IDEMPOTENCY_HEADER} is 1 to {MAX_IDEMPOTENCY_KEY_CHARS} visible ASCII characters"
        ))
    })
}

/// The id of the `index`th stroke of an import by `importer` in `session` with the
/// idempotency key `key`: a UUID of version 8 (custom), the first 16 bytes of SHA-256 over a
/// label and all of them, so that the same import sent again has the same ids, and no other.
fn derived_id(session: Uuid, importer: Uuid, key: &str, index: usize) -> Uuid {
    use sha2::Digest;
    let digest = sha2::Sha256::new_with_prefix(b"penmesh import\0")
        .chain_update(session.as_bytes())
        .chain_update(importer.as_bytes())
        .chain_update((key.len() as u64).to_le_bytes())
        .chain_update(key.as_bytes())
        .chain_update((index as u64).to_le_bytes())
        .finalize();
    let mut bytes = [0u8; 16];
    bytes.copy_from_slice(&digest[..16]);
    uuid::Builder::from_custom_bytes(bytes).into_uuid()
}
/// The device an imported stroke is stored with.
pub const IMPORT_DEVICE: &str = "import";

/// Who imports.
#[derive(Debug, serde::Deserialize, utoipa::IntoParams)]
pub struct ImportQuery {
    /// The importer's display name, shown as the drawer's where the importer never joined the
    /// session live (as `hello.name`; cleaned the same way).
    name: Option<String>,
}

/// A stroke of the file, checked, and its mesh built.
struct Checked {
    read: ReadStroke,
    placement: Placement,
    glb: Vec<u8>,
    counts: crate::glb::MeshCounts,
}

fn scene_error(err: SceneError) -> AppError {
    AppError::BadRequest(format!("cannot import the file: {err}"))
}

/// Latest a file may say a stroke was drawn or imported, past now: clocks differ, by less.
const CLOCK_SKEW_MS: i64 = 24 * 60 * 60 * 1000;

/// Checks where a stroke of the file says it comes from: its id (not the nil UUID), not its
/// own duplicate, its author's name (as any name: at most 200 characters, no NUL; cleaned when
/// stored), its times (from the Unix epoch to now). `bad` names the stroke.
fn check_origin(extras: &StrokeExtras, bad: &dyn Fn(String) -> AppError) -> Result<(), AppError> {
    if extras.stroke.is_nil() {
        return Err(bad("its id is the nil UUID".into()));
    }
    if extras.duplicate_of == Some(extras.stroke) {
        return Err(bad("it names itself as the stroke it duplicates".into()));
    }
    let latest = now_ms() + CLOCK_SKEW_MS;
    let mut authors = vec![("its author's name", &extras.author.name)];
    let mut times = vec![("drawn_at", extras.drawn_at)];
    if let Some(from) = &extras.imported_from {
        if from.stroke.is_nil() {
            return Err(bad("its imported_from.stroke is the nil UUID".into()));
        }
        authors.push(("its imported_from.author's name", &from.author.name));
        times.extend([
            ("imported_from.drawn_at", from.drawn_at),
            ("imported_from.imported_at", from.imported_at),
        ]);
    }
    for (what, name) in authors {
        check_text(name, MAX_NAME_CHARS).map_err(|why| bad(format!("{what} {why}")))?;
    }
    for (what, at) in times {
        if !(0..=latest).contains(&at) {
            return Err(bad(format!(
                "{what} = {at} is not a time from the Unix epoch to now (ms)"
            )));
        }
    }
    Ok(())
}

/// Checks one stroke read from the file: where it comes from, its placement, brush and
/// samples, each refusal naming the stroke (its id in the file and its node).
fn check(read: &ReadStroke, max_samples: usize) -> Result<Placement, AppError> {
    let what = format!("stroke {} (node {})", read.extras.stroke, read.node);
    let bad = |why: String| AppError::BadRequest(format!("cannot import {what}: {why}"));
    check_origin(&read.extras, &bad)?;
    let placement =
        Placement::new(read.placement).map_err(|e| bad(format!("its node's matrix: {e}")))?;
    read.extras.brush.validate().map_err(|e| bad(format!("its brush: {e}")))?;
    let samples = &read.extras.samples;
    if samples.is_empty() {
        return Err(bad("it has no samples".into()));
    }
    if samples.len() > max_samples {
        return Err(bad(format!(
            "{} samples, a stroke holds at most {max_samples}",
            samples.len()
        )));
    }
    penmesh::validate_samples(samples, None, 0).map_err(|e| bad(e.to_string()))?;
    // Stored samples are on the codec's grid; one off it would not be stored exactly.
    if let Some((index, s)) = samples.iter().enumerate().find(|(_, s)| quantize_sample(s) != **s) {
        return Err(bad(format!(
            "sample {index} ({}, {}, {}, {}) is not on penmesh's grid (x and y in 1/16 px, t in \
             1/8 ms, p in 1/1024): it was not exported by penmesh",
            s.x, s.y, s.t, s.p
        )));
    }
    Ok(placement)
}

/// Re-creates the strokes of a penmesh GLB (`export?format=glb`) in the session: the same
/// simplified samples (exact), brushes and placements, drawn by the participant of
/// `x-penmesh-key`, the original author kept. All or nothing: a file that is not a penmesh
/// scene, truncated, too large, or with one bad stroke stores nothing.
#[utoipa::path(post, path = "/v1/sessions/{session}/import", tag = "export",
    params(("session" = Uuid, Path), ImportQuery,
        ("x-penmesh-key" = String, Header, description = "the importer's participant key (its hello.key)")),
    request_body(content = Vec<u8>, content_type = "model/gltf-binary",
        description = "a GLB exported by penmesh (`GET /v1/sessions/{id}/export?format=glb`)"),
    security(("bearer" = [])),
    responses((status = 201, description = "the strokes re-created, in the file's order", body = Imported),
        (status = 400, description = "not a penmesh GLB, truncated, or a bad stroke (naming it and what is wrong); nothing stored", body = ErrorBody),
        (status = 401, body = ErrorBody),
        (status = 413, description = "the file, its strokes or the session's mesh quota is too large; nothing stored", body = ErrorBody),
        (status = 503, description = "busy: too many large bodies at once", body = ErrorBody)))]
pub async fn import_scene(
    State(state): State<AppState>,
    Path(session): Path<String>,
    Query(query): Query<ImportQuery>,
    headers: HeaderMap,
    body: axum::body::Body,
) -> Result<(StatusCode, Json<Imported>), AppError> {
    let started = tokio::time::Instant::now();
    let session = authorize_session(&state, &headers, None, &session).await?;
    let by = crate::placement::new_drawer(session, &headers, "an import")?;
    let retry_key = idempotency_key(&headers)?;
    let importer_name = match query.name.as_deref() {
        None => String::new(),
        Some(name) => crate::identity::clean_name(name).ok_or_else(|| {
            AppError::BadRequest(format!("name={name:?} is not a name that can be shown"))
        })?,
    };
    let limit = state.config.max_body_bytes;
    let length = headers.get(header::CONTENT_LENGTH).and_then(|v| v.to_str().ok()?.parse().ok());
    if let Some(length) = length.filter(|&l: &u64| l > limit as u64) {
        return Err(AppError::TooLarge(format!(
            "the file is {length} bytes, an import takes at most {limit} (--max-body-bytes)"
        )));
    }
    let _permit =
        state.large_body(length.unwrap_or(limit as u64).min(limit as u64)).ok_or_else(|| {
            AppError::Busy(
                "too many large bodies are being sent or received; try again shortly".into(),
            )
        })?;
    let body = axum::body::to_bytes(body, limit).await.map_err(|err| {
        if std::error::Error::source(&err)
            .is_some_and(|e| e.is::<http_body_util::LengthLimitError>())
        {
            AppError::TooLarge(format!(
                "the file is larger than the limit of {limit} bytes (--max-body-bytes)"
            ))
        } else {
            AppError::BadRequest(format!("cannot read the body: {err}"))
        }
    })?;
    let strokes = penmesh::read_scene(&body).map_err(scene_error)?;
    if strokes.len() > MAX_IMPORT_STROKES {
        return Err(AppError::TooLarge(format!(
            "{} strokes in the file, an import takes at most {MAX_IMPORT_STROKES}",
            strokes.len()
        )));
    }
    let max_samples = state.config.max_stroke_retained;
    let mut placements = Vec::with_capacity(strokes.len());
    for read in &strokes {
        placements.push(check(read, max_samples)?);
    }
    // The new strokes' ids, chosen now so their meshes carry them, in increasing order: they
    // are begun at the same moment, and a session lists its strokes by (begun, id), so the
    // session (and its next export) keeps the file's order. A retry's ids are derived from its
    // key, so it gets the same set (sorted the same way).
    let mut ids: Vec<Uuid> = match retry_key {
        Some(key) => (0..strokes.len()).map(|i| derived_id(session, by, key, i)).collect(),
        None => strokes.iter().map(|_| Uuid::new_v4()).collect(),
    };
    ids.sort_unstable();
    // The same import, committed before: answered as it was.
    let first = ids.first().copied();
    if let (Some(_), Some(first)) = (retry_key, first)
        && state.store.stroke(first).await?.is_some()
    {
        return Ok(already_imported(&ids, &strokes));
    }
    let max_decoded = limit;
    let checked = tokio::task::spawn_blocking(move || {
        strokes
            .into_iter()
            .zip(placements)
            .zip(&ids)
            .map(|((read, placement), &id)| {
                let samples = &read.extras.samples;
                let kept: Vec<usize> = (0..samples.len()).collect();
                let meta =
                    GlbMeta { stroke: id, author: PROXY_UPLOADER.into(), brush: read.extras.brush };
                let meshed = penmesh::mesh_drawn_solid(
                    samples,
                    &kept,
                    &meta,
                    &read.extras.solid,
                    &OutlineOptions::default(),
                    &GlbOptions::default(),
                )
                .map_err(|e| {
                    AppError::BadRequest(format!(
                        "cannot import stroke {} (node {}): it makes no mesh: {e}",
                        read.extras.stroke, read.node
                    ))
                })?;
                let counts = crate::glb::inspect(&meshed.glb, max_decoded).map_err(|e| {
                    anyhow::anyhow!("the proxy built an invalid GLB for an import: {e}")
                })?;
                Ok((id, Checked { read, placement, glb: meshed.glb, counts }))
            })
            .collect::<Result<Vec<_>, AppError>>()
    })
    .await
    .map_err(anyhow::Error::from)??;
    // The session's mesh quota, for every mesh at once, before anything is written.
    let quota = state.config.max_session_mesh_bytes;
    let stored = state.store.session_mesh_bytes(session).await?;
    let adding: u64 = checked.iter().map(|(_, c)| c.glb.len() as u64).sum();
    if stored + adding > quota {
        return Err(AppError::QuotaExceeded(format!(
            "the imported strokes' meshes ({adding} bytes) would take the session's meshes to \
             {} bytes, past its quota of {quota} (--max-session-mesh-bytes); nothing imported",
            stored + adding
        )));
    }
    let now = now_ms();
    let mut ops = Vec::with_capacity(5 * checked.len() + 2);
    if let (Some(_), Some((first, _))) = (retry_key, checked.first()) {
        // Of the same import sent twice at once, one is written.
        ops.push(WriteOp::Claim { stroke: *first });
    }
    // The session's sample quota, for every stroke at once, checked by the writer.
    let samples = checked.iter().map(|(_, c)| c.read.extras.samples.len() as u64).sum();
    let quota = state.config.max_session_samples;
    ops.push(WriteOp::CountSamples { session, samples, quota });
    let mut events = Vec::with_capacity(4 * checked.len());
    let event = |kind| SessionEvent::new(session, kind);
    for (stroke, c) in &checked {
        let (stroke, extras) = (*stroke, &c.read.extras);
        let kept: Vec<Kept> = extras
            .samples
            .iter()
            .enumerate()
            .map(|(index, &sample)| Kept { index, sample })
            .collect();
        ops.push(WriteOp::BeginStroke {
            stroke,
            session,
            participant: by,
            brush: extras.brush,
            params: AcutsParams::default(),
            device: Some(IMPORT_DEVICE.into()),
        });
        ops.push(WriteOp::Append { stroke, seq: 0, samples: extras.samples.clone() });
        ops.push(WriteOp::Finish { stroke, kept });
        // Where it came from: an imported stroke imported again keeps its first origin.
        let mut from = extras.imported_from.clone().unwrap_or_else(|| ImportedFrom {
            stroke: extras.stroke,
            author: extras.author.clone(),
            drawn_at: extras.drawn_at,
            imported_at: now,
        });
        // Shown as any name is: what would mislead (bidirectional controls, …) removed.
        from.author.name = crate::identity::clean_name(&from.author.name).unwrap_or_default();
        ops.push(WriteOp::MarkImported {
            stroke,
            from: Box::new(from),
            importer_name: importer_name.clone(),
        });
        events.push(event(EventKind::StrokeBegin { participant: by, stroke, brush: extras.brush }));
        events.push(event(EventKind::Retained {
            participant: by,
            stroke,
            first: 0,
            points: extras.samples.clone(),
        }));
        events.push(event(EventKind::StrokeDone {
            participant: by,
            stroke,
            n_retained: extras.samples.len() as u64,
        }));
        if !c.placement.is_identity() {
            let (place, placed) =
                crate::placement::request((session, by, stroke), c.placement, "begin", None);
            ops.push(place);
            events.push(placed);
        }
        // Its solid, as the file has it (checked above: its mesh was made of it).
        if !extras.solid.is_rod() {
            let (set, told) =
                crate::solid::request((session, by, stroke), extras.solid, "import", None);
            ops.push(set);
            events.push(told);
        }
    }
    // A duplicate whose source is in the file too stays its duplicate: the file's ids mapped to
    // the new ones. It keeps its own mesh, built from its own samples (another tool may have
    // changed them). Last, so that every source is written before it is named.
    let new_ids: HashMap<Uuid, Uuid> =
        checked.iter().rev().map(|(stroke, c)| (c.read.extras.stroke, *stroke)).collect();
    for (stroke, c) in &checked {
        if let Some(&source) = c.read.extras.duplicate_of.and_then(|old| new_ids.get(&old)) {
            ops.push(WriteOp::MarkDuplicate { stroke: *stroke, source, shares: None });
        }
    }
    match state.writer.write_with(ops, events).await {
        Ok(()) => {}
        // The same import, committed meanwhile by its twin.
        Err(WriteError::Taken(_)) => {
            let answer = checked.iter().map(|(stroke, c)| (*stroke, c.read.extras.stroke));
            return Ok(imported(answer));
        }
        Err(err) => {
            return Err(match err {
                WriteError::Closed => AppError::ShuttingDown,
                WriteError::Refused(why) => AppError::Conflict(why),
                WriteError::Quota(why) => AppError::QuotaExceeded(why),
                err => AppError::Internal(err.into()),
            });
        }
    }
    metrics::counter!("penmesh_strokes_total", "event" => "imported")
        .increment(checked.len() as u64);
    // The strokes are committed: from here on the import has happened, and the answer says so
    // whatever becomes of the meshes (an error now would have the importer send the file again
    // and import it twice). A mesh that cannot be stored leaves its stroke meshless, which the
    // page builds when it next opens the session (`docs/model-format.md`).
    let answer = imported(checked.iter().map(|(stroke, c)| (*stroke, c.read.extras.stroke)));
    // The meshes: here until half the request timeout, then after the answer, so that the
    // answer comes before the timeout.
    let answer_by = started + Duration::from_secs(state.config.request_timeout_secs) / 2;
    let mut meshes = checked.into_iter().map(|(stroke, c)| (stroke, c.glb, c.counts));
    for (stroke, glb, counts) in meshes.by_ref() {
        store_import_mesh(&state, stroke, glb, counts).await;
        if tokio::time::Instant::now() >= answer_by {
            break;
        }
    }
    let rest: Vec<_> = meshes.collect();
    if !rest.is_empty() {
        tracing::info!(meshes = rest.len(), "an import's last meshes are stored after its answer");
        tokio::spawn(async move {
            for (stroke, glb, counts) in rest {
                store_import_mesh(&state, stroke, glb, counts).await;
            }
        });
    }
    Ok(answer)
}

/// Stores an imported stroke's mesh built by the proxy; one that cannot be stored leaves its
/// stroke meshless (logged), which the page builds when it next opens the session.
async fn store_import_mesh(
    state: &AppState,
    stroke: Uuid,
    glb: Vec<u8>,
    counts: crate::glb::MeshCounts,
) {
    let stored = async {
        let row = state
            .store
            .stroke(stroke)
            .await?
            .ok_or_else(|| anyhow::anyhow!("imported stroke {stroke} is not stored"))?;
        store_mesh(state, &row, row.solid, glb, counts, Some(PROXY_UPLOADER.into())).await
    };
    if let Err(err) = stored.await {
        tracing::warn!(%stroke, error = %err, "an imported stroke's mesh was not stored");
    }
}

/// The answer to an import: each new stroke and its id in the file, in the file's order.
fn imported(strokes: impl Iterator<Item = (Uuid, Uuid)>) -> (StatusCode, Json<Imported>) {
    let strokes = strokes.map(|(stroke, source)| ImportedStroke { stroke, source }).collect();
    (StatusCode::CREATED, Json(Imported { strokes }))
}

/// The answer to an import committed before (its first id stored): the same as the first's.
fn already_imported(ids: &[Uuid], strokes: &[ReadStroke]) -> (StatusCode, Json<Imported>) {
    imported(ids.iter().copied().zip(strokes.iter().map(|read| read.extras.stroke)))
}
