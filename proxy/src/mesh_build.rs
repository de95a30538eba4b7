//! The mesh of a thin client's stroke, built by the proxy: a browser cannot run LRPDP (no
//! WebAssembly build here, and no second LRPDP in JavaScript), so it asks the proxy, which runs
//! the same `penmesh` calls as the native client (`client/src/reconstruct.rs`) and stores and
//! announces the result exactly like an uploaded mesh (`http::store_mesh`). The mesh is the
//! stroke's solid (`penmesh::Solid`: the rod by default, a wall, a plate or a hole), made from
//! the same samples.

use axum::Json;
use axum::extract::{Path, State};
use axum::http::HeaderMap;
use penmesh::{GlbMeta, GlbOptions, OutlineOptions, Solid};

use crate::http::{AppError, MeshInfo, STORE_MESH, owned_stroke, store_mesh};
use crate::state::AppState;
use crate::store::StrokeRow;

/// What the proxy names as the uploader of the meshes it builds.
pub const PROXY_UPLOADER: &str = "penmesh-proxy";

/// Builds, stores and announces the mesh of a done stroke from its simplified samples; only
/// the stroke's drawer may ask (its participant key in `x-penmesh-key`). A stroke that already
/// has a mesh keeps it (the call is idempotent, so a page that reloads may ask again).
#[utoipa::path(post, path = "/v1/strokes/{id}/mesh/build", tag = "meshes",
    params(("id" = Uuid, Path),
        ("x-penmesh-key" = String, Header, description = "the drawer's participant key (its hello.key)")),
    security(("bearer" = [])),
    responses((status = 200, body = MeshInfo), (status = 400, body = crate::http::ErrorBody),
        (status = 401, body = crate::http::ErrorBody),
        (status = 403, description = "not the stroke's drawer", body = crate::http::ErrorBody),
        (status = 404, body = crate::http::ErrorBody),
        (status = 409, description = "stroke not done, or its stored samples make no mesh", body = crate::http::ErrorBody)))]
pub async fn build_mesh(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Json<MeshInfo>, AppError> {
    let (row, _) = owned_stroke(&state, &headers, &id, STORE_MESH).await?;
    if row.has_mesh {
        let mesh = state.store.mesh(row.id).await?;
        if let Some(mesh) = mesh {
            return Ok(Json(MeshInfo {
                stroke: row.id,
                bytes: mesh.glb.len() as u64,
                vertices: mesh.vertices,
                triangles: mesh.triangles,
                uploader: mesh.uploader,
            }));
        }
    }
    let glb = built_glb(&state, &row, row.solid).await?;
    store_built(&state, &row, row.solid, glb).await.map(Json)
}

/// The GLB of `row`'s stroke as `solid`, from its stored samples: 409 when the stroke is not
/// done, its samples make no mesh, or it cannot be that solid (an open stroke filled).
pub(crate) async fn built_glb(
    state: &AppState,
    row: &StrokeRow,
    solid: Solid,
) -> Result<Vec<u8>, AppError> {
    let Some(simplified) = state.store.simplified(row.id).await? else {
        return Err(AppError::Conflict(format!(
            "stroke {} is {}: its mesh can be built once it is done",
            row.id,
            row.status.as_str()
        )));
    };
    // The samples the proxy received: the smooth centreline is checked against them, as the
    // native client checks it against what it drew.
    let raw = state.store.raw_samples(row.id).await?;
    // Samples stored before they were bounded (`penmesh::MAX_COORDINATE`) make no mesh: said,
    // not a failure of the proxy.
    if let Err(err) = penmesh::validate_samples(&raw, None, 0) {
        return Err(AppError::Conflict(format!("stroke {} cannot have a mesh: {err}", row.id)));
    }
    let kept: Vec<usize> = simplified.indices.iter().map(|&i| i as usize).collect();
    let meta = GlbMeta { stroke: row.id, author: PROXY_UPLOADER.into(), brush: row.brush };
    // LRPDP is CPU work of a few milliseconds: keep it off the connection threads.
    tokio::task::spawn_blocking(move || {
        penmesh::mesh_drawn_solid(
            &raw,
            &kept,
            &meta,
            &solid,
            &OutlineOptions::default(),
            &GlbOptions::default(),
        )
        .map(|meshed| meshed.glb)
        .map_err(|e| match e {
            penmesh::MeshError::Solid(why) => {
                AppError::Conflict(format!("stroke {} cannot be {solid}: {why}", meta.stroke))
            }
            e => AppError::Internal(anyhow::anyhow!("stored stroke {}: {e}", meta.stroke)),
        })
    })
    .await
    .map_err(anyhow::Error::from)?
}

/// Stores and announces a GLB the proxy built for `row`'s stroke as `solid`.
pub(crate) async fn store_built(
    state: &AppState,
    row: &StrokeRow,
    solid: Solid,
    glb: Vec<u8>,
) -> Result<MeshInfo, AppError> {
    let counts = crate::glb::inspect(&glb, state.config.max_body_bytes)
        .map_err(|e| anyhow::anyhow!("the proxy built an invalid GLB for {}: {e}", row.id))?;
    store_mesh(state, row, solid, glb, counts, Some(PROXY_UPLOADER.into())).await
}
