//! The one path from a stroke to its GLB, which the native client, the proxy's mesh build and
//! `penmesh-lab eval` share: the outline (the smooth centreline checked against the drawn samples
//! when they are known, [`fitted_outline`]; [`outline`] of the retained samples when they are
//! not), the solid the stroke becomes ([`solid_mesh`], default options, for the rod; a prism of
//! its region for a solid with a depth, `solid.rs`), the GLB ([`stroke_glb`]).

use crate::glb::{GlbMeta, GlbOptions, stroke_glb};
use crate::lrpdp::{KeptError, Outline, OutlineOptions, fitted_outline, outline};
use crate::mesh::{SolidOptions, StrokeMesh, solid_mesh};
use crate::model::Sample;
use crate::prism::{PrismVertices, prism_mesh};
use crate::region::solid_region;
use crate::solid::{Solid, SolidError};

/// A stroke's outline, solid and GLB, as [`mesh_drawn_stroke`] or [`mesh_retained_stroke`]
/// built them.
#[derive(Debug, Clone)]
pub struct MeshedStroke {
    pub outline: Outline,
    pub mesh: StrokeMesh,
    pub glb: Vec<u8>,
}

/// The mesh of a stroke from its drawn samples and the indices ACUTS kept of them (strictly
/// increasing, within `raw`): refused, naming the index, otherwise.
pub fn mesh_drawn_stroke(
    raw: &[Sample],
    kept: &[usize],
    meta: &GlbMeta,
    outline_options: &OutlineOptions,
    glb_options: &GlbOptions,
) -> Result<MeshedStroke, KeptError> {
    let outline = fitted_outline(raw, kept, &meta.brush, outline_options)?;
    Ok(mesh_outline(outline, meta, glb_options))
}

/// The mesh of a stroke from its retained samples alone: where the drawn samples are not known,
/// or for the paper's straight centreline.
pub fn mesh_retained_stroke(
    retained: &[Sample],
    meta: &GlbMeta,
    outline_options: &OutlineOptions,
    glb_options: &GlbOptions,
) -> MeshedStroke {
    mesh_outline(outline(retained, &meta.brush, outline_options), meta, glb_options)
}

/// Why a stroke's mesh cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    #[error(transparent)]
    Kept(#[from] KeptError),
    #[error(transparent)]
    Solid(#[from] SolidError),
}

/// [`mesh_drawn_stroke`] for the stroke's `solid`: refused for an open stroke filled.
pub fn mesh_drawn_solid(
    raw: &[Sample],
    kept: &[usize],
    meta: &GlbMeta,
    solid: &Solid,
    outline_options: &OutlineOptions,
    glb_options: &GlbOptions,
) -> Result<MeshedStroke, MeshError> {
    let outline = fitted_outline(raw, kept, &meta.brush, outline_options)?;
    Ok(mesh_solid_outline(outline, meta, solid, glb_options)?)
}

/// [`mesh_retained_stroke`] for the stroke's `solid`: refused for an open stroke filled.
pub fn mesh_retained_solid(
    retained: &[Sample],
    meta: &GlbMeta,
    solid: &Solid,
    outline_options: &OutlineOptions,
    glb_options: &GlbOptions,
) -> Result<MeshedStroke, SolidError> {
    let outline = outline(retained, &meta.brush, outline_options);
    mesh_solid_outline(outline, meta, solid, glb_options)
}

/// The mesh of a solid made from `outline`: the rod for the default, else the prism of its
/// region (`layout` as [`PrismVertices`] says).
pub fn solid_of_outline(
    outline: &Outline,
    solid: &Solid,
    layout: PrismVertices,
) -> Result<StrokeMesh, SolidError> {
    match solid.depth() {
        None => Ok(solid_mesh(outline, &SolidOptions::default())),
        Some(depth) => Ok(prism_mesh(&solid_region(outline, solid.kind())?, depth, layout)),
    }
}

fn mesh_solid_outline(
    outline: Outline,
    meta: &GlbMeta,
    solid: &Solid,
    glb_options: &GlbOptions,
) -> Result<MeshedStroke, SolidError> {
    let mesh = solid_of_outline(&outline, solid, PrismVertices::Flat)?;
    let glb = stroke_glb(&mesh, meta, glb_options);
    Ok(MeshedStroke { outline, mesh, glb })
}

fn mesh_outline(outline: Outline, meta: &GlbMeta, glb_options: &GlbOptions) -> MeshedStroke {
    mesh_solid_outline(outline, meta, &Solid::ROD, glb_options).expect("the rod is always made")
}
