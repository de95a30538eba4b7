//! A session's model taken out (issue 39): `GET /v1/sessions/{session}/export` answers the
//! print, the union of its strokes' solids as one STL or 3MF file made by `penmesh-print` from
//! the stored drawn samples, kept indices, brushes and placements (`docs/print.md`), or the
//! scene, one GLB of its stored meshes and pen data (`crate::scene`, `docs/model-format.md`).
//! A bounded job like a mesh build: at most [`MAX_PRINTS`] prints and, apart, [`MAX_SCENES`]
//! scenes at once on a replica (the next is answered 503 `busy`), at most
//! [`MAX_EXPORT_STROKES`] strokes, the CPU work on the blocking pool.

use std::collections::{HashMap, HashSet};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, header};
use axum::response::{IntoResponse, Response};
use base64::Engine as _;
use penmesh::protocol::StrokeStatus;
use penmesh_print::{PrintOptions, PrintStroke};
use serde_json::json;
use uuid::Uuid;

use crate::http::{AppError, authorize_session};
use crate::query::Query;
use crate::state::AppState;
use crate::store::StrokeRow;

/// Prints made at once on one replica: each keeps the cores busy for seconds.
pub const MAX_PRINTS: usize = 1;
/// Scenes made at once on one replica, a bound apart from the prints': each takes a fraction of
/// a second but holds its strokes' meshes in memory (at most
/// [`crate::scene::MAX_SCENE_MESH_BYTES`]).
pub const MAX_SCENES: usize = 2;
/// Most strokes in one print.
pub const MAX_EXPORT_STROKES: usize = 5_000;
/// Strokes whose samples are read per query (bound parameters: SQLite allows 32,766).
const STROKES_PER_READ: usize = 500;

/// What to export.
#[derive(Debug, serde::Deserialize, utoipa::IntoParams)]
pub struct ExportQuery {
    /// `glb` (the scene), `stl` or `3mf` (the print).
    format: String,
    /// Stroke ids, comma-separated: only these (each done and in the session); all the
    /// session's done strokes when absent.
    strokes: Option<String>,
    /// The model's longest side in millimetres (default 100).
    size_mm: Option<f64>,
    /// Every part at least this thick, in millimetres (default 0.8).
    min_thickness_mm: Option<f64>,
}

/// The model of a session's done strokes (or of `strokes`): the scene as GLB (a node per
/// stroke with its placement, stored mesh and pen data in `extras`, in metres, the longest
/// side `size_mm`), or the print, one closed manifold in millimetres, as binary STL or 3MF.
#[utoipa::path(get, path = "/v1/sessions/{session}/export", tag = "export",
    params(("session" = Uuid, Path), ExportQuery,
        ("accept" = Option<String>, Header, description = "`application/x-ndjson` to be told the progress: then the answer is a JSON object a line, `{\"progress\": {\"stage\", \"done\", \"total\"}}` while the export is made, last `{\"file\": {\"content_type\", \"name\", \"bytes\", \"base64\"}}` or `{\"error\": {\"status\", \"code\", \"message\"}}` (docs/protocol.md)")),
    security(("bearer" = [])),
    responses((status = 200, description = "the GLB (model/gltf-binary), STL (model/stl) or 3MF (model/3mf) file; asked with `Accept: application/x-ndjson`, the progress lines and the file in the last (application/x-ndjson)"),
        (status = 400, body = crate::http::ErrorBody), (status = 401, body = crate::http::ErrorBody),
        (status = 404, description = "a chosen stroke is not in the session", body = crate::http::ErrorBody),
        (status = 409, description = "nothing done to export", body = crate::http::ErrorBody),
        (status = 413, description = "too many strokes", body = crate::http::ErrorBody),
        (status = 503, description = "busy: another print (or, for a scene, as many scenes as allowed) is being made", body = crate::http::ErrorBody)))]
pub async fn export_print(
    State(state): State<AppState>,
    Path(session): Path<String>,
    Query(query): Query<ExportQuery>,
    headers: HeaderMap,
) -> Result<Response, AppError> {
    let session = authorize_session(&state, &headers, None, &session).await?;
    let (content_type, extension) = match query.format.as_str() {
        "stl" => ("model/stl", "stl"),
        "3mf" => ("model/3mf", "3mf"),
        "glb" => ("model/gltf-binary", "glb"),
        other => {
            return Err(AppError::BadRequest(format!(
                "format={other:?}: a model is exported as `glb` (the scene), `stl` or `3mf` (the \
                 print)"
            )));
        }
    };
    let options = PrintOptions {
        size_mm: query.size_mm.unwrap_or(penmesh_print::DEFAULT_SIZE_MM),
        min_thickness_mm: query.min_thickness_mm.unwrap_or(penmesh_print::DEFAULT_MIN_THICKNESS_MM),
    };
    options.validate().map_err(|e| AppError::BadRequest(e.to_string()))?;
    let rows = chosen_rows(&state, session, query.strokes.as_deref()).await?;
    let scene = extension == "glb";
    let Some(permit) = state.export_permit(scene) else {
        let (limit, what) = if scene { (MAX_SCENES, "scene") } else { (MAX_PRINTS, "print") };
        return Err(AppError::Busy(format!(
            "{limit} {what}(s) are being made, the limit; try again shortly"
        )));
    };
    let name = format!("penmesh-{session}.{extension}");
    let cancel = Cancel::default();
    let job = Job { state, session, rows, options, extension, permit, cancel: cancel.clone() };
    if wants_progress(&headers) {
        return Ok(progress_stream(job, content_type, name, cancel));
    }
    // Dropped with this request (answered, timed out, or its client gone): the work stops.
    let _stop = cancel.on_drop();
    let file = job.file(Box::new(|_, _, _| {})).await?;
    let disposition = format!("attachment; filename=\"{name}\"");
    Ok((
        [
            (header::CONTENT_TYPE, content_type.to_string()),
            (header::CONTENT_DISPOSITION, disposition),
        ],
        file,
    )
        .into_response())
}

/// The media type a client asks with `Accept` to be told the export's progress.
pub const PROGRESS_TYPE: &str = "application/x-ndjson";
/// Most progress lines a second.
const PROGRESS_LINES_PER_SECOND: u32 = 10;

/// Whether the request's `Accept` names [`PROGRESS_TYPE`].
fn wants_progress(headers: &HeaderMap) -> bool {
    headers
        .get_all(header::ACCEPT)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .any(|t| t.split(';').next().is_some_and(|t| t.trim() == PROGRESS_TYPE))
}

/// Where an export is: its `stage` (`reading`, `solids`, `union`), `done` of `total`.
type Report = Box<dyn FnMut(&'static str, usize, usize) + Send>;

/// Whether anyone still waits for an export: set once nobody does (its request dropped,
/// answered or timed out; a progress body dropped), and then the print's work stops at its
/// next step.
#[derive(Debug, Clone, Default)]
pub(crate) struct Cancel(Arc<AtomicBool>);

/// Sets its [`Cancel`] when dropped.
pub(crate) struct CancelOnDrop(Cancel);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        (self.0).0.store(true, Ordering::Relaxed);
    }
}

impl Cancel {
    fn on_drop(&self) -> CancelOnDrop {
        CancelOnDrop(self.clone())
    }

    fn is_set(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// The unwinding payload that stops a print's work between two steps (`print_mesh` takes no
/// other way out): caught where the work was spawned, never a panic message.
struct Cancelled;

fn cancelled() -> AppError {
    AppError::Busy("the export was stopped: nobody waits for it any more".into())
}

/// What an export's work on the blocking pool holds while it runs: its permit, so that at most
/// [`MAX_PRINTS`] prints and [`MAX_SCENES`] scenes are being made, whether or not anyone still
/// waits for them; counted in [`AppState::exports_working`] until it ends.
pub(crate) struct Working {
    _permit: tokio::sync::OwnedSemaphorePermit,
    count: Arc<AtomicUsize>,
}

impl Working {
    pub(crate) fn start(state: &AppState, permit: tokio::sync::OwnedSemaphorePermit) -> Working {
        state.exports_working.fetch_add(1, Ordering::Relaxed);
        Working { _permit: permit, count: state.exports_working.clone() }
    }
}

impl Drop for Working {
    fn drop(&mut self) {
        self.count.fetch_sub(1, Ordering::Relaxed);
    }
}

/// One export to make, its checks passed, and its permit.
struct Job {
    state: AppState,
    session: Uuid,
    rows: Vec<StrokeRow>,
    options: PrintOptions,
    extension: &'static str,
    permit: tokio::sync::OwnedSemaphorePermit,
    cancel: Cancel,
}

impl Job {
    async fn file(self, mut report: Report) -> Result<Vec<u8>, AppError> {
        if self.extension == "glb" {
            report("reading", 0, self.rows.len());
            let Job { state, session, rows, options, permit, .. } = self;
            crate::scene::scene_file(&state, session, &rows, options.size_mm, permit).await
        } else {
            print_file(self, report).await
        }
    }
}

/// The answer to an export that asked for its progress: 200 `application/x-ndjson`, a line
/// `{"progress":{"stage","done","total"}}` per step (at most [`PROGRESS_LINES_PER_SECOND`] a
/// second), then one line `{"file":{"content_type","name","bytes","base64"}}`, or
/// `{"error":{"status","code","message"}}` when the export fails once the answer has begun.
/// The job runs on its own task, holding its permit, so it is one request's work on one
/// replica and nothing is kept between requests; once the body is dropped (the client gone),
/// `cancel` stops it.
fn progress_stream(job: Job, content_type: &'static str, name: String, cancel: Cancel) -> Response {
    let (lines, received) = tokio::sync::mpsc::channel::<Bytes>(64);
    let progress = lines.clone();
    let mut last: Option<(&'static str, std::time::Instant)> = None;
    let gap = std::time::Duration::from_secs(1) / PROGRESS_LINES_PER_SECOND;
    let report: Report = Box::new(move |stage, done, total| {
        let due = match last {
            Some((at_stage, at)) => at_stage != stage || done == total || at.elapsed() >= gap,
            None => true,
        };
        if due {
            last = Some((stage, std::time::Instant::now()));
            let line = json!({ "progress": { "stage": stage, "done": done, "total": total } });
            // A full channel (a slow reader) drops the step: the next one says more.
            let _ = progress.try_send(ndjson(&line));
        }
    });
    tokio::spawn(async move {
        let line = match job.file(report).await {
            Ok(file) => json!({ "file": {
                "content_type": content_type,
                "name": name,
                "bytes": file.len(),
                "base64": base64::engine::general_purpose::STANDARD.encode(&file),
            }}),
            Err(err) => error_line(err).await,
        };
        let _ = lines.send(ndjson(&line)).await;
    });
    let stop = cancel.on_drop();
    let body = futures_util::stream::unfold((received, stop), |(mut received, stop)| async move {
        let line = received.recv().await?;
        Some((Ok::<_, std::convert::Infallible>(line), (received, stop)))
    });
    ([(header::CONTENT_TYPE, PROGRESS_TYPE)], axum::body::Body::from_stream(body)).into_response()
}

fn ndjson(line: &serde_json::Value) -> Bytes {
    let mut text = line.to_string();
    text.push('\n');
    Bytes::from(text)
}

/// The error line of a failure after the answer began: the status, code and message the error
/// would have had as its own answer.
async fn error_line(err: AppError) -> serde_json::Value {
    let response = err.into_response();
    let status = response.status().as_u16();
    let body = axum::body::to_bytes(response.into_body(), 64 * 1024).await.unwrap_or_default();
    let body: serde_json::Value = serde_json::from_slice(&body).unwrap_or_default();
    json!({ "error": { "status": status, "code": body["error"], "message": body["message"] } })
}

/// The session's done strokes not taken back, oldest first, or the chosen ones (each done
/// and in the session), at most [`MAX_EXPORT_STROKES`].
async fn chosen_rows(
    state: &AppState,
    session: Uuid,
    strokes: Option<&str>,
) -> Result<Vec<StrokeRow>, AppError> {
    let chosen = strokes.map(parse_ids).transpose()?;
    let rows = state.store.list_strokes(session, false).await?;
    let rows: Vec<_> = match &chosen {
        None => rows.into_iter().filter(|r| r.status == StrokeStatus::Done).collect(),
        Some(ids) => {
            for id in ids {
                match rows.iter().find(|r| r.id == *id) {
                    None => {
                        return Err(AppError::NotFound(format!(
                            "stroke {id} is not a stroke of this session (or was taken back)"
                        )));
                    }
                    Some(r) if r.status != StrokeStatus::Done => {
                        return Err(AppError::Conflict(format!(
                            "stroke {id} is {}: only done strokes are exported",
                            r.status.as_str()
                        )));
                    }
                    Some(_) => {}
                }
            }
            rows.into_iter().filter(|r| ids.contains(&r.id)).collect()
        }
    };
    if rows.is_empty() {
        return Err(AppError::Conflict("the session has no done stroke to export".into()));
    }
    if rows.len() > MAX_EXPORT_STROKES {
        return Err(AppError::TooLarge(format!(
            "{} strokes: an export takes at most {MAX_EXPORT_STROKES}; choose some with `strokes`",
            rows.len()
        )));
    }
    Ok(rows)
}

/// The print of the job's strokes as STL or 3MF, on the blocking pool, which holds the job's
/// permit until the work ends; it stops between two steps once the job is cancelled.
async fn print_file(job: Job, mut report: Report) -> Result<Vec<u8>, AppError> {
    let Job { state, rows, options, extension, permit, cancel, .. } = job;
    let ids: Vec<Uuid> = rows.iter().map(|r| r.id).collect();
    let mut simplified = HashMap::with_capacity(ids.len());
    let mut raw = HashMap::with_capacity(ids.len());
    report("reading", 0, ids.len());
    for chunk in ids.chunks(STROKES_PER_READ) {
        if cancel.is_set() {
            return Err(cancelled());
        }
        simplified.extend(state.store.simplified_many(chunk).await?);
        raw.extend(state.store.done_raw_samples_many(chunk).await?);
        report("reading", raw.len(), ids.len());
    }
    let mut strokes = Vec::with_capacity(rows.len());
    for row in &rows {
        let Some(simplified) = simplified.remove(&row.id) else {
            return Err(AppError::Conflict(format!("stroke {} has no simplified samples", row.id)));
        };
        let raw = raw.remove(&row.id).unwrap_or_default();
        if let Err(err) = penmesh::validate_samples(&raw, None, 0) {
            return Err(AppError::Conflict(format!("stroke {} cannot be printed: {err}", row.id)));
        }
        strokes.push(PrintStroke {
            raw,
            kept: simplified.indices.iter().map(|&i| i as usize).collect(),
            brush: row.brush,
            // Its node's matrix: the print places each solid where the scene shows it.
            placement: *row.placement.matrix(),
            solid: row.solid,
        });
    }
    let working = Working::start(&state, permit);
    let work = tokio::task::spawn_blocking(move || {
        let _working = working;
        // print_mesh's steps: one per stroke's solid, then the unions.
        let n = strokes.len();
        let mesh = penmesh_print::print_mesh(&strokes, &options, &mut |done, _| {
            if cancel.is_set() {
                std::panic::resume_unwind(Box::new(Cancelled));
            }
            if done <= n {
                report("solids", done, n);
            } else {
                report("union", done - n, n - 1);
            }
        })?;
        Ok::<_, penmesh_print::PrintError>(match extension {
            "stl" => Ok(penmesh_print::write_stl(&mesh)),
            _ => penmesh_print::write_3mf(&mesh),
        })
    });
    let file = match work.await {
        Ok(file) => file,
        Err(err) if err.is_panic() => {
            let payload = err.into_panic();
            if payload.is::<Cancelled>() {
                return Err(cancelled());
            }
            return Err(anyhow::anyhow!("the print's work panicked").into());
        }
        Err(err) => return Err(anyhow::Error::from(err).into()),
    };
    let file = file
        .map_err(|e| AppError::Conflict(format!("no print: {e}")))?
        .map_err(anyhow::Error::from)?;
    Ok(file)
}

/// `strokes=id,id,…` as ids, refusing one that is not a UUID by name.
fn parse_ids(text: &str) -> Result<HashSet<Uuid>, AppError> {
    text.split(',')
        .map(|id| {
            Uuid::parse_str(id.trim()).map_err(|_| {
                AppError::BadRequest(format!("strokes: {id:?} is not a stroke id (a UUID)"))
            })
        })
        .collect()
}
