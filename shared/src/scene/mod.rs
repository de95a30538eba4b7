//! The session as one glTF scene (issue 39, `docs/model-format.md`): a GLB with a node per
//! stroke whose `matrix` is its placement, whose mesh is the stroke's stored GLB merged in as
//! it is (compressed, quantised: no geometry is made again), and whose `extras.penmesh` holds
//! its pen data ([`StrokeExtras`]), under one root node that turns the session's axes and
//! pixels into glTF's (Y up, metres) so the scene has the print's real size. [`read_scene`]
//! reads such a file back for an import.
//!
//! The stored meshes are merged at the JSON level: their buffer views, accessors, meshes and
//! materials are appended with their indices shifted, their binary chunks concatenated into
//! one, and the fallback buffers of `EXT_meshopt_compression` into one. Whatever extensions
//! they use or require are declared. A stored mesh with textures, images, skins, animations or
//! cameras, or with data outside the GLB (a `uri`), is refused: penmesh never writes them.
//!
//! Pure: bytes in, bytes out.
//!
//! [`write`] makes the scene, [`read`] reads one back, [`container`] is the GLB both speak.

mod container;
mod read;
mod write;

pub use read::read_scene;
pub use write::scene_glb;

use serde::{Deserialize, Serialize};
use uuid::Uuid;

use crate::model::{Brush, Sample};

/// The version of the layout of [`StrokeExtras`]; a reader refuses another.
pub const SCENE_FORMAT_VERSION: u32 = 1;
/// The key of a stroke node's `extras` that holds its [`StrokeExtras`].
pub const EXTRAS_KEY: &str = "penmesh";
/// The key of the root node's `extras` that says how the scene is scaled ([`SceneExtras`]).
pub const SCENE_EXTRAS_KEY: &str = "penmesh_scene";
/// A stroke's pen data, as its node's `extras.penmesh` holds it (`docs/model-format.schema.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StrokeExtras {
    /// [`SCENE_FORMAT_VERSION`].
    pub format: u32,
    /// The stroke's id in the session it was exported from.
    pub stroke: Uuid,
    /// Its drawer: the participant id and the name shown for it.
    pub author: Author,
    /// When it was drawn (its begin), milliseconds since the Unix epoch.
    pub drawn_at: i64,
    pub brush: Brush,
    /// The simplified samples, `[x, y, t, p]` each, exactly as stored (x, y in px of the
    /// stroke's plane, t in ms from its first sample, p in [0, 1]).
    pub samples: Vec<Sample>,
    /// The stroke it is a duplicate of, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub duplicate_of: Option<Uuid>,
    /// For a stroke that was imported: where it came from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imported_from: Option<ImportedFrom>,
    /// What the stroke becomes (issue 51): its kind and depth; left out for the rod (the
    /// default), so a scene of rods is written as before.
    #[serde(default, skip_serializing_if = "crate::solid::Solid::is_rod")]
    pub solid: crate::solid::Solid,
}

/// Who drew a stroke.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Author {
    pub participant: Uuid,
    pub name: String,
}

/// What an imported stroke keeps of the stroke it was made from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImportedFrom {
    /// The stroke's id in the file it was imported from.
    pub stroke: Uuid,
    /// Its author there.
    pub author: Author,
    /// When it was drawn, ms since the Unix epoch.
    pub drawn_at: i64,
    /// When it was imported, ms since the Unix epoch.
    pub imported_at: i64,
}

/// The root node's `extras.penmesh_scene`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneExtras {
    pub format: u32,
    /// The scene's longest side, in millimetres.
    pub size_mm: f64,
    /// Metres per unit of the session (px).
    pub metres_per_unit: f64,
}

/// One stroke of a scene.
#[derive(Debug, Clone)]
pub struct SceneStroke<'a> {
    pub extras: &'a StrokeExtras,
    /// Its placement, column-major.
    pub placement: [f64; 16],
    /// Its mesh: an index into [`SceneInput::meshes`] (a duplicate names its source's), or
    /// none for a stroke without one.
    pub mesh: Option<usize>,
}

/// What [`scene_glb`] writes.
#[derive(Debug, Clone)]
pub struct SceneInput<'a> {
    /// The stored GLBs, each once.
    pub meshes: Vec<&'a [u8]>,
    pub strokes: Vec<SceneStroke<'a>>,
    /// The scene's longest side, in millimetres.
    pub size_mm: f64,
}

/// A stroke read back from a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadStroke {
    /// The node it was read from.
    pub node: usize,
    pub extras: StrokeExtras,
    /// Its node's transform, column-major: its placement.
    pub placement: [f64; 16],
}

/// Why a scene cannot be written or read; each names what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SceneError {
    #[error("the file is truncated: {0}")]
    Truncated(String),
    #[error("not a GLB (binary glTF 2.0): {0}")]
    NotGlb(String),
    #[error(
        "no penmesh strokes in the file: no node has extras.{EXTRAS_KEY} (export the model from \
         penmesh as GLB)"
    )]
    NoStrokes,
    #[error("node {node}{name}: extras.{EXTRAS_KEY} is not penmesh's stroke data: {why}")]
    BadExtras { node: usize, name: String, why: String },
    #[error("node {node}: {why}")]
    BadTransform { node: usize, why: String },
    #[error("the stored mesh of stroke {stroke}: {why}")]
    BadMesh { stroke: Uuid, why: String },
}

/// Column-major 4×4 product `a · b`.
pub fn mat_mul(a: &[f64; 16], b: &[f64; 16]) -> [f64; 16] {
    let mut out = [0.0; 16];
    for col in 0..4 {
        for row in 0..4 {
            out[4 * col + row] = (0..4).map(|k| a[4 * k + row] * b[4 * col + k]).sum();
        }
    }
    out
}
/// A short, readable name for a stroke: its author and the last 8 hex digits of its id (the
/// first ones of a UUID v7 are its time, the same for strokes drawn together).
pub fn stroke_label(extras: &StrokeExtras) -> String {
    let hex = extras.stroke.simple().to_string();
    let short = &hex[hex.len() - 8..];
    let author = extras.author.name.trim();
    if author.is_empty() {
        format!("stroke {short}")
    } else {
        format!("stroke {short} by {author}")
    }
}

#[cfg(test)]
mod tests;
