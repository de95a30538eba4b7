//! A session's model taken out (issue 39): `GET /v1/sessions/{session}/export` answers the
//! print, the union of its strokes' solids as one STL or 3MF file made by `penmesh-print` from
//! the stored drawn samples, kept indices, brushes and placements (`docs/print.md`), or the
//! scene, one GLB of its stored meshes and pen data (`crate::scene`, `docs/model-format.md`).
//! A bounded job like a mesh build: at most [`MAX_PRINTS`] prints and, apart, [`MAX_SCENES`]
//! scenes at once on a replica (the next is answered 503 `busy`), at most
//! [`MAX_EXPORT_STROKES`] strokes, the CPU work on the blocking pool.
//!
//! The work runs on a task of its own (`crate::flight`), which the request waits for: a print
//! goes on while someone waits for it or within a request timeout of its 408, is kept once
//! made, and the same request again (the same model) is answered from it or waits for that
//! same work (`crate::kept_prints`). A print nobody wants any more stops at its next step.

use std::collections::{HashMap, HashSet};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, header};
use axum::response::{IntoResponse, Response};
use base64::Engine as _;
use penmesh::protocol::StrokeStatus;
use penmesh_print::{PrintOptions, PrintStroke};
use serde_json::json;
use tokio::time::Instant;
use uuid::Uuid;

use crate::flight::{Flight, Outcome, Progress, Waiter};
use crate::http::{AppError, authorize_session};
use crate::kept_prints::{Joined, KEPT_FOR, PrintKey};
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
        (status = 408, description = "not ready within the request timeout: a print goes on and is kept, so the same request again is answered with it (docs/reliability.md)", body = crate::http::ErrorBody),
        (status = 409, description = "nothing done to export", body = crate::http::ErrorBody),
        (status = 413, description = "too many strokes", body = crate::http::ErrorBody),
        (status = 503, description = "busy: another print (or, for a scene, as many scenes as allowed) is being made", body = crate::http::ErrorBody)))]
pub async fn export_print(
    State(state): State<AppState>,
    Path(session): Path<String>,
    Query(query): Query<ExportQuery>,
    headers: HeaderMap,
) -> Result<Response, AppError> {
    // The route keeps its own request timeout (the router's is not on it), so that its 408
    // leaves the print going on for the retry (`Waiter::timed_out`).
    let timeout = Duration::from_secs(state.config.request_timeout_secs);
    let deadline = Instant::now() + timeout;
    let asked = tokio::time::timeout_at(deadline, ask(&state, &session, &query, &headers));
    let (waiter, content_type, name) = asked.await.map_err(|_| timed_out(timeout))??;
    if wants_progress(&headers) {
        return Ok(progress_stream(waiter, content_type, name));
    }
    let file = match tokio::time::timeout_at(deadline, waiter.outcome()).await {
        Ok(outcome) => outcome.map_err(|err| err.again())?,
        Err(_) => {
            waiter.timed_out(timeout);
            return Err(timed_out(timeout));
        }
    };
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

/// The 408 of an export not ready within the request timeout.
fn timed_out(timeout: Duration) -> AppError {
    AppError::TimedOut(format!(
        "the export was not ready within the request timeout ({} s); a print goes on and is \
         kept: the same request again is answered with it",
        timeout.as_secs()
    ))
}

/// The request's checks, then a waiter of its export: the print kept or being made for the
/// same model, or new work on a task of its own; its content type and file name.
async fn ask(
    state: &AppState,
    session: &str,
    query: &ExportQuery,
    headers: &HeaderMap,
) -> Result<(Waiter, &'static str, String), AppError> {
    let session = authorize_session(state, headers, None, session).await?;
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
    let rows = chosen_rows(state, session, query.strokes.as_deref()).await?;
    let name = format!("penmesh-{session}.{extension}");
    let waiter = if extension == "glb" {
        let permit = state.export_permit(true).ok_or_else(|| busy(MAX_SCENES, "scene"))?;
        let (flight, waiter) = Flight::start();
        let state = state.clone();
        tokio::spawn(async move {
            flight.report(Progress { stage: "reading", done: 0, total: rows.len() });
            let file = crate::scene::scene_file(&state, session, &rows, options.size_mm, permit);
            flight.finish(file.await.map(Bytes::from).map_err(Arc::new));
        });
        waiter
    } else {
        let key = PrintKey::of(session, extension, &options, &rows);
        let kept = state.kept_prints.clone();
        match kept.join(key.clone(), || state.export_permit(false)) {
            None => return Err(busy(MAX_PRINTS, "print")),
            Some(Joined::Existing(waiter)) => waiter,
            Some(Joined::Started(flight, waiter, permit)) => {
                let state = state.clone();
                tokio::spawn(async move {
                    let work = Work { rows, options, extension, permit };
                    let file = print_file(&state, work, &flight).await;
                    flight.finish(file.map(Bytes::from).map_err(Arc::new));
                    if kept.finished(&key, &flight) {
                        tokio::time::sleep(KEPT_FOR).await;
                        kept.forget(&key, &flight);
                    }
                });
                waiter
            }
        }
    };
    Ok((waiter, content_type, name))
}

/// The 503 of an export past its replica's bound.
fn busy(limit: usize, what: &str) -> AppError {
    AppError::Busy(format!("{limit} {what}(s) are being made, the limit; try again shortly"))
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

/// Where an export is, told to its flight at most [`PROGRESS_LINES_PER_SECOND`] times a second
/// (and at every new stage, and at a stage's end).
type Report = Box<dyn FnMut(&'static str, usize, usize) + Send>;

fn report_to(flight: Arc<Flight>) -> Report {
    let mut last: Option<(&'static str, std::time::Instant)> = None;
    let gap = Duration::from_secs(1) / PROGRESS_LINES_PER_SECOND;
    Box::new(move |stage, done, total| {
        let due = match last {
            Some((at_stage, at)) => at_stage != stage || done == total || at.elapsed() >= gap,
            None => true,
        };
        if due {
            last = Some((stage, std::time::Instant::now()));
            flight.report(Progress { stage, done, total });
        }
    })
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

/// A print to make, its checks passed, and its permit.
struct Work {
    rows: Vec<StrokeRow>,
    options: PrintOptions,
    extension: &'static str,
    permit: tokio::sync::OwnedSemaphorePermit,
}

/// The answer to an export that asked for its progress: 200 `application/x-ndjson`, a line
/// `{"progress":{"stage","done","total"}}` per step the flight tells, then one line
/// `{"file":{"content_type","name","bytes","base64"}}`, or `{"error":{"status","code",
/// "message"}}` when the export fails once the answer has begun. Once the body is dropped (the
/// client gone), its waiter is, and a print nobody else wants stops.
fn progress_stream(waiter: Waiter, content_type: &'static str, name: String) -> Response {
    let progress = waiter.progress();
    let start = Some((waiter, progress, name));
    let body = futures_util::stream::unfold(start, move |state| async move {
        let (waiter, mut progress, name) = state?;
        // The progress first: every line told before the file.
        tokio::select! {
            biased;
            Progress { stage, done, total } = progress.next() => {
                let line = json!({ "progress": { "stage": stage, "done": done, "total": total } });
                Some((Ok::<_, std::convert::Infallible>(ndjson(&line)), Some((waiter, progress, name))))
            }
            outcome = waiter.outcome() => {
                let line = last_line(outcome, content_type, &name).await;
                Some((Ok(line), None))
            }
        }
    });
    ([(header::CONTENT_TYPE, PROGRESS_TYPE)], axum::body::Body::from_stream(body)).into_response()
}

/// The last line of a progress answer: the file, or the error.
async fn last_line(outcome: Outcome, content_type: &str, name: &str) -> Bytes {
    let line = match outcome {
        Ok(file) => json!({ "file": {
            "content_type": content_type,
            "name": name,
            "bytes": file.len(),
            "base64": base64::engine::general_purpose::STANDARD.encode(&file),
        }}),
        Err(err) => error_line(err.again()).await,
    };
    ndjson(&line)
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
    // A placement stored before translations had a bound reads, but no model holds it.
    for row in &rows {
        if let Err(err) = row.placement.check_translation() {
            return Err(AppError::Conflict(format!(
                "stroke {} cannot be exported: its placement, stored before translations were \
                 bounded, is out of bounds: {err}; move it",
                row.id
            )));
        }
    }
    if rows.len() > MAX_EXPORT_STROKES {
        return Err(AppError::TooLarge(format!(
            "{} strokes: an export takes at most {MAX_EXPORT_STROKES}; choose some with `strokes`",
            rows.len()
        )));
    }
    Ok(rows)
}

/// The print of the work's strokes as STL or 3MF, on the blocking pool, which holds the
/// work's permit until it ends; it stops between two steps once `flight` is not wanted.
async fn print_file(
    state: &AppState,
    work: Work,
    flight: &Arc<Flight>,
) -> Result<Vec<u8>, AppError> {
    let Work { rows, options, extension, permit } = work;
    let mut report = report_to(flight.clone());
    let ids: Vec<Uuid> = rows.iter().map(|r| r.id).collect();
    let mut simplified = HashMap::with_capacity(ids.len());
    let mut raw = HashMap::with_capacity(ids.len());
    report("reading", 0, ids.len());
    for chunk in ids.chunks(STROKES_PER_READ) {
        if !flight.is_wanted() {
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
    let working = Working::start(state, permit);
    let flight = flight.clone();
    let work = tokio::task::spawn_blocking(move || {
        let _working = working;
        // print_mesh's steps: one per stroke's solid, then the unions.
        let n = strokes.len();
        let mesh = penmesh_print::print_mesh(&strokes, &options, &mut |done, _| {
            if !flight.is_wanted() {
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
