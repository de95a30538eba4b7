//! The scene of a session as one GLB (`GET /v1/sessions/{id}/export?format=glb`, issue 39,
//! `docs/model-format.md`): what `penmesh::scene_glb` needs read from the store (each stroke's
//! simplified samples, brush, placement, drawer's name, origin if imported, and its stored
//! mesh, a duplicate's being its source's, read once), then the file made on the blocking pool.

use std::collections::HashMap;

use penmesh::{Author, SCENE_FORMAT_VERSION, SceneInput, SceneStroke, StrokeExtras};
use uuid::Uuid;

use crate::http::AppError;
use crate::state::AppState;
use crate::store::StrokeRow;

/// Most bytes of stored meshes one scene holds: they are all in memory while it is made.
pub const MAX_SCENE_MESH_BYTES: u64 = 256 * 1024 * 1024;
/// Most simplified samples one scene holds: they are all in memory while it is made, as the
/// samples and as their JSON in the file (about 100 bytes a sample in all: `docs/reliability.md`).
pub const MAX_SCENE_SAMPLES: u64 = 1_000_000;
/// Meshes read from the store per query.
const MESHES_PER_READ: usize = 64;
/// Simplified strokes read per query (bound parameters: SQLite allows 32,766).
const SIMPLIFIED_PER_READ: usize = 500;

/// The name shown for `participant`: the latest it went by in the session, else the name its
/// imports gave, else none.
fn author_name(
    participant: Uuid,
    names: &HashMap<Uuid, String>,
    imports: &HashMap<Uuid, crate::store::ImportRow>,
    stroke: Uuid,
) -> String {
    names
        .get(&participant)
        .cloned()
        .or_else(|| imports.get(&stroke).map(|i| i.importer_name.clone()))
        .unwrap_or_default()
}

/// The GLB of `rows` (done strokes of `session`), the longest side `size_mm` mm. `permit` is
/// held until the file is made, on the blocking pool, whether or not anyone still waits.
pub async fn scene_file(
    state: &AppState,
    session: Uuid,
    rows: &[StrokeRow],
    size_mm: f64,
    permit: tokio::sync::OwnedSemaphorePermit,
) -> Result<Vec<u8>, AppError> {
    let started = std::time::Instant::now();
    let samples: u64 = rows.iter().map(|r| r.n_retained).sum();
    if samples > MAX_SCENE_SAMPLES {
        return Err(AppError::TooLarge(format!(
            "the chosen strokes hold {samples} simplified samples, a scene holds at most \
             {MAX_SCENE_SAMPLES}; choose fewer with `strokes`"
        )));
    }
    let names = state.store.participant_names(session).await?;
    let imports = state.store.session_imports(session).await?;
    // Which mesh row each stroke shows, and how large it is.
    let entries = state.store.session_bundle_entries(session).await?;
    let shown: HashMap<Uuid, (Uuid, u64)> =
        entries.iter().map(|e| (e.stroke, (e.mesh_stroke, e.bytes))).collect();
    let mut mesh_order: Vec<Uuid> = Vec::new();
    let mut mesh_index: HashMap<Uuid, usize> = HashMap::new();
    let mut mesh_bytes = 0u64;
    for row in rows {
        if let Some(&(mesh, bytes)) = shown.get(&row.id)
            && !mesh_index.contains_key(&mesh)
        {
            mesh_index.insert(mesh, mesh_order.len());
            mesh_order.push(mesh);
            mesh_bytes += bytes;
        }
    }
    if mesh_bytes > MAX_SCENE_MESH_BYTES {
        return Err(AppError::TooLarge(format!(
            "the chosen strokes' meshes are {mesh_bytes} bytes, a scene holds at most \
             {MAX_SCENE_MESH_BYTES}; choose fewer with `strokes`"
        )));
    }
    let mut glbs: HashMap<Uuid, Vec<u8>> = HashMap::with_capacity(mesh_order.len());
    for chunk in mesh_order.chunks(MESHES_PER_READ) {
        glbs.extend(state.store.mesh_glbs(chunk).await?);
    }
    let ids: Vec<Uuid> = rows.iter().map(|r| r.id).collect();
    let mut simplified = HashMap::with_capacity(ids.len());
    for chunk in ids.chunks(SIMPLIFIED_PER_READ) {
        simplified.extend(state.store.simplified_many(chunk).await?);
    }
    let mut extras = Vec::with_capacity(rows.len());
    for row in rows {
        let Some(simplified) = simplified.remove(&row.id) else {
            return Err(AppError::Conflict(format!("stroke {} has no simplified samples", row.id)));
        };
        extras.push(StrokeExtras {
            format: SCENE_FORMAT_VERSION,
            stroke: row.id,
            author: Author {
                participant: row.participant,
                name: author_name(row.participant, &names, &imports, row.id),
            },
            drawn_at: row.created_at,
            brush: row.brush,
            samples: simplified.samples,
            duplicate_of: row.duplicate_of,
            imported_from: imports.get(&row.id).map(|i| i.from.clone()),
            solid: row.solid,
        });
    }
    let meshes: Vec<Vec<u8>> = mesh_order
        .iter()
        .map(|id| {
            glbs.remove(id).ok_or_else(|| anyhow::anyhow!("the mesh of stroke {id} vanished"))
        })
        .collect::<anyhow::Result<_>>()?;
    let placements: Vec<([f64; 16], Option<usize>)> = rows
        .iter()
        .map(|row| {
            let mesh = shown.get(&row.id).and_then(|(m, _)| mesh_index.get(m).copied());
            (*row.placement.matrix(), mesh)
        })
        .collect();
    let read = started.elapsed();
    let working = crate::export::Working::start(state, permit);
    let file = tokio::task::spawn_blocking(move || {
        let _working = working;
        let input = SceneInput {
            meshes: meshes.iter().map(Vec::as_slice).collect(),
            strokes: extras
                .iter()
                .zip(&placements)
                .map(|(extras, &(placement, mesh))| SceneStroke { extras, placement, mesh })
                .collect(),
            size_mm,
        };
        penmesh::scene_glb(&input)
    })
    .await
    .map_err(anyhow::Error::from)?
    // The stored meshes were checked on upload: one the scene cannot merge is the proxy's fault.
    .map_err(|e| anyhow::anyhow!("no scene: {e}"))?;
    tracing::info!(
        strokes = rows.len(),
        read_ms = read.as_millis() as u64,
        total_ms = started.elapsed().as_millis() as u64,
        bytes = file.len(),
        "scene exported"
    );
    Ok(file)
}
