//! The one path from a stroke to its GLB, which the native client, the proxy's mesh build and
//! `penmesh-lab eval` share: the outline (the smooth centreline checked against the drawn samples
//! when they are known, [`fitted_outline`]; [`outline`] of the retained samples when they are
//! not), the direct solid ([`solid_mesh`], default options), the GLB ([`stroke_glb`]).

use crate::glb::{GlbMeta, GlbOptions, stroke_glb};
use crate::lrpdp::{KeptError, Outline, OutlineOptions, fitted_outline, outline};
use crate::mesh::{SolidOptions, StrokeMesh, solid_mesh};
use crate::model::Sample;

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

fn mesh_outline(outline: Outline, meta: &GlbMeta, glb_options: &GlbOptions) -> MeshedStroke {
    let mesh = solid_mesh(&outline, &SolidOptions::default());
    let glb = stroke_glb(&mesh, meta, glb_options);
    MeshedStroke { outline, mesh, glb }
}
