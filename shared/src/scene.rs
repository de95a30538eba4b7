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

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value, json};
use uuid::Uuid;

use crate::model::{Brush, Sample};
use crate::placement::IDENTITY_MATRIX;

/// The version of the layout of [`StrokeExtras`]; a reader refuses another.
pub const SCENE_FORMAT_VERSION: u32 = 1;
/// The key of a stroke node's `extras` that holds its [`StrokeExtras`].
pub const EXTRAS_KEY: &str = "penmesh";
/// The key of the root node's `extras` that says how the scene is scaled ([`SceneExtras`]).
pub const SCENE_EXTRAS_KEY: &str = "penmesh_scene";

const GLB_MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;
const MESHOPT: &str = "EXT_meshopt_compression";

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

fn transform_point(m: &[f64; 16], p: [f64; 3]) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (row, value) in out.iter_mut().enumerate() {
        *value = m[row] * p[0] + m[4 + row] * p[1] + m[8 + row] * p[2] + m[12 + row];
    }
    out
}

/// A box as its low and high corners.
type Bounds = ([f64; 3], [f64; 3]);

fn grow(bounds: &mut Option<Bounds>, p: [f64; 3]) {
    let (lo, hi) = bounds.get_or_insert((p, p));
    for axis in 0..3 {
        lo[axis] = lo[axis].min(p[axis]);
        hi[axis] = hi[axis].max(p[axis]);
    }
}

fn corners((lo, hi): Bounds) -> impl Iterator<Item = [f64; 3]> {
    (0..8).map(move |i| {
        [
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        ]
    })
}

/// A node's local transform, column-major: its `matrix`, or its translation, rotation and
/// scale composed (`T · R · S`), or the identity.
fn node_matrix(node: &Value, index: usize) -> Result<[f64; 16], SceneError> {
    let bad = |why: String| SceneError::BadTransform { node: index, why };
    let numbers = |key: &str, n: usize| -> Result<Option<Vec<f64>>, SceneError> {
        match node.get(key) {
            None => Ok(None),
            Some(Value::Array(items)) if items.len() == n => items
                .iter()
                .map(|v| v.as_f64().ok_or_else(|| bad(format!("{key} holds {v}, not a number"))))
                .collect::<Result<Vec<_>, _>>()
                .map(Some),
            Some(other) => Err(bad(format!("{key} is {other}, not {n} numbers"))),
        }
    };
    if let Some(m) = numbers("matrix", 16)? {
        return Ok(m.try_into().expect("16 numbers"));
    }
    let t = numbers("translation", 3)?.unwrap_or_else(|| vec![0.0; 3]);
    let r = numbers("rotation", 4)?.unwrap_or_else(|| vec![0.0, 0.0, 0.0, 1.0]);
    let s = numbers("scale", 3)?.unwrap_or_else(|| vec![1.0; 3]);
    let (x, y, z, w) = (r[0], r[1], r[2], r[3]);
    let rotation = [
        1.0 - 2.0 * (y * y + z * z),
        2.0 * (x * y + z * w),
        2.0 * (x * z - y * w),
        2.0 * (x * y - z * w),
        1.0 - 2.0 * (x * x + z * z),
        2.0 * (y * z + x * w),
        2.0 * (x * z + y * w),
        2.0 * (y * z - x * w),
        1.0 - 2.0 * (x * x + y * y),
    ];
    let mut m = IDENTITY_MATRIX;
    for col in 0..3 {
        for row in 0..3 {
            m[4 * col + row] = rotation[3 * col + row] * s[col];
        }
        m[12 + col] = t[col];
    }
    Ok(m)
}

/// A GLB's JSON document and its binary chunk (empty when it has none).
fn parse_glb(bytes: &[u8]) -> Result<(Value, &[u8]), SceneError> {
    let word = |at: usize| {
        bytes.get(at..at + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
    };
    if bytes.len() < 12 {
        return Err(SceneError::Truncated(format!(
            "{} bytes, less than a GLB's 12-byte header",
            bytes.len()
        )));
    }
    if &bytes[0..4] != GLB_MAGIC {
        return Err(SceneError::NotGlb("it does not start with 'glTF'".into()));
    }
    if word(4) != Some(2) {
        return Err(SceneError::NotGlb(format!("version {:?}, not 2", word(4).unwrap_or(0))));
    }
    let declared = word(8).unwrap_or(0);
    if declared > bytes.len() {
        return Err(SceneError::Truncated(format!(
            "its header says {declared} bytes, the file has {}",
            bytes.len()
        )));
    }
    if declared < bytes.len() {
        return Err(SceneError::NotGlb(format!(
            "its header says {declared} bytes, the file has {} (bytes after its end)",
            bytes.len()
        )));
    }
    let chunk = |at: usize, kind: u32, what: &str| -> Result<Option<&[u8]>, SceneError> {
        if at == bytes.len() {
            return Ok(None);
        }
        let (Some(length), Some(found)) = (word(at), word(at + 4)) else {
            return Err(SceneError::Truncated(format!("the {what} chunk's header is cut off")));
        };
        if found != kind as usize {
            return Err(SceneError::NotGlb(format!("the {what} chunk has type {found:#x}")));
        }
        let body = bytes.get(at + 8..at + 8 + length).ok_or_else(|| {
            SceneError::Truncated(format!(
                "the {what} chunk says {length} bytes, {} are left",
                bytes.len().saturating_sub(at + 8)
            ))
        })?;
        Ok(Some(body))
    };
    let json_chunk = chunk(12, CHUNK_JSON, "JSON")?
        .ok_or_else(|| SceneError::Truncated("it has no JSON chunk".into()))?;
    let bin = chunk(12 + 8 + json_chunk.len(), CHUNK_BIN, "BIN")?.unwrap_or_default();
    let json: Value = serde_json::from_slice(json_chunk)
        .map_err(|e| SceneError::NotGlb(format!("its JSON chunk is not JSON: {e}")))?;
    if !json.is_object() {
        return Err(SceneError::NotGlb("its JSON chunk is not a glTF object".into()));
    }
    Ok((json, bin))
}

/// Reads every stroke of a scene [`scene_glb`] wrote (or another tool edited): each node with
/// `extras.penmesh`, in node order, with its node's own transform as its placement.
pub fn read_scene(bytes: &[u8]) -> Result<Vec<ReadStroke>, SceneError> {
    let (json, _) = parse_glb(bytes)?;
    let nodes = json.get("nodes").and_then(Value::as_array).map(Vec::as_slice).unwrap_or(&[]);
    let mut strokes = Vec::new();
    for (index, node) in nodes.iter().enumerate() {
        let Some(data) = node.get("extras").and_then(|e| e.get(EXTRAS_KEY)) else {
            continue;
        };
        let bad = |why: String| SceneError::BadExtras {
            node: index,
            name: node
                .get("name")
                .and_then(Value::as_str)
                .map(|n| format!(" ({n:?})"))
                .unwrap_or_default(),
            why,
        };
        let format = data.get("format").and_then(Value::as_u64);
        if format != Some(u64::from(SCENE_FORMAT_VERSION)) {
            return Err(bad(format!(
                "format {}, this penmesh reads format {SCENE_FORMAT_VERSION}",
                data.get("format").map(Value::to_string).unwrap_or_else(|| "missing".into())
            )));
        }
        let extras: StrokeExtras =
            serde_json::from_value(data.clone()).map_err(|e| bad(e.to_string()))?;
        strokes.push(ReadStroke { node: index, extras, placement: node_matrix(node, index)? });
    }
    if strokes.is_empty() {
        return Err(SceneError::NoStrokes);
    }
    Ok(strokes)
}

/// Converts an sRGB channel to linear, as glTF's `baseColorFactor` wants.
fn srgb_to_linear(channel: u32) -> f64 {
    let c = f64::from(channel & 0xff) / 255.0;
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
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

/// The stored mesh merged into the scene: the templates of its scene's root nodes (their
/// `mesh` already shifted) and its bounds in its own coordinates.
struct MergedMesh {
    roots: Vec<Value>,
    bounds: Option<Bounds>,
    /// The meshes (scene indices) it added, for their materials.
    meshes: Vec<usize>,
}

#[derive(Default)]
struct Merger {
    nodes: Vec<Value>,
    meshes: Vec<Value>,
    materials: Vec<Value>,
    accessors: Vec<Value>,
    views: Vec<Value>,
    used: Vec<String>,
    required: Vec<String>,
    bin: Vec<u8>,
    fallback_length: usize,
}

fn shift(value: &mut Value, key: &str, by: usize) {
    if let Some(v) = value.get_mut(key)
        && let Some(i) = v.as_u64()
    {
        *v = json!(i as usize + by);
    }
}

fn add_to(value: &mut Value, key: &str, by: usize) {
    let now = value.get(key).and_then(Value::as_u64).unwrap_or(0) as usize;
    value[key] = json!(now + by);
}

fn declare(list: &mut Vec<String>, names: Option<&Value>) {
    for name in names.and_then(Value::as_array).into_iter().flatten().filter_map(Value::as_str) {
        if !list.iter().any(|n| n == name) {
            list.push(name.to_owned());
        }
    }
}

impl Merger {
    fn merge(&mut self, stroke: Uuid, glb: &[u8]) -> Result<MergedMesh, SceneError> {
        let bad = |why: String| SceneError::BadMesh { stroke, why };
        let (json, bin) = parse_glb(glb).map_err(|e| bad(e.to_string()))?;
        for key in ["textures", "images", "samplers", "skins", "animations", "cameras"] {
            if json.get(key).and_then(Value::as_array).is_some_and(|a| !a.is_empty()) {
                return Err(bad(format!("it has {key}, which penmesh never writes")));
            }
        }
        let list = |key: &str| json.get(key).and_then(Value::as_array).cloned().unwrap_or_default();
        // Where each of its buffers goes: (0, offset in the BIN) or (1, offset in the
        // fallback buffer).
        let bin_at = self.bin.len();
        self.bin.extend_from_slice(bin);
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        let mut buffers = Vec::new();
        for (index, buffer) in list("buffers").iter().enumerate() {
            if buffer.get("uri").is_some() {
                return Err(bad(format!("buffer {index} is outside the GLB (a uri)")));
            }
            let fallback = buffer
                .pointer(&format!("/extensions/{MESHOPT}/fallback"))
                .and_then(Value::as_bool)
                .unwrap_or(false);
            let length = buffer.get("byteLength").and_then(Value::as_u64).unwrap_or(0) as usize;
            if fallback {
                buffers.push((1, self.fallback_length));
                self.fallback_length = (self.fallback_length + length).next_multiple_of(4);
            } else if index == 0 && length <= bin.len() {
                buffers.push((0, bin_at));
            } else {
                return Err(bad(format!("buffer {index} is neither the GLB's BIN nor a fallback")));
            }
        }
        let place = |index: Option<u64>| -> Result<(usize, usize), SceneError> {
            index
                .and_then(|i| buffers.get(i as usize).copied())
                .ok_or_else(|| bad(format!("a buffer view names buffer {index:?}")))
        };
        let view_base = self.views.len();
        for mut view in list("bufferViews") {
            let (buffer, at) = place(view.get("buffer").and_then(Value::as_u64))?;
            view["buffer"] = json!(buffer);
            add_to(&mut view, "byteOffset", at);
            if let Some(ext) = view.pointer_mut(&format!("/extensions/{MESHOPT}")) {
                let (buffer, at) = place(ext.get("buffer").and_then(Value::as_u64))?;
                ext["buffer"] = json!(buffer);
                add_to(ext, "byteOffset", at);
            }
            self.views.push(view);
        }
        let accessor_base = self.accessors.len();
        let accessors = list("accessors");
        for mut accessor in accessors.iter().cloned() {
            shift(&mut accessor, "bufferView", view_base);
            if let Some(sparse) = accessor.get_mut("sparse") {
                for part in ["indices", "values"] {
                    if let Some(p) = sparse.get_mut(part) {
                        shift(p, "bufferView", view_base);
                    }
                }
            }
            self.accessors.push(accessor);
        }
        let material_base = self.materials.len();
        self.materials.extend(list("materials"));
        let mesh_base = self.meshes.len();
        let meshes = list("meshes");
        for mut mesh in meshes.iter().cloned() {
            for primitive in
                mesh.get_mut("primitives").and_then(Value::as_array_mut).into_iter().flatten()
            {
                if let Some(attributes) =
                    primitive.get_mut("attributes").and_then(Value::as_object_mut)
                {
                    for value in attributes.values_mut() {
                        if let Some(i) = value.as_u64() {
                            *value = json!(i as usize + accessor_base);
                        }
                    }
                }
                shift(primitive, "indices", accessor_base);
                shift(primitive, "material", material_base);
                for target in
                    primitive.get_mut("targets").and_then(Value::as_array_mut).into_iter().flatten()
                {
                    for value in target.as_object_mut().into_iter().flat_map(|t| t.values_mut()) {
                        if let Some(i) = value.as_u64() {
                            *value = json!(i as usize + accessor_base);
                        }
                    }
                }
            }
            self.meshes.push(mesh);
        }
        declare(&mut self.used, json.get("extensionsUsed"));
        declare(&mut self.required, json.get("extensionsRequired"));
        // Its scene's nodes as templates; bounds from each mesh's POSITION min and max.
        let nodes = list("nodes");
        let scene = json.get("scene").and_then(Value::as_u64).unwrap_or(0) as usize;
        let roots: Vec<usize> = json
            .pointer(&format!("/scenes/{scene}/nodes"))
            .and_then(Value::as_array)
            .map(|a| a.iter().filter_map(|v| v.as_u64().map(|i| i as usize)).collect())
            .unwrap_or_else(|| (0..nodes.len()).collect());
        let mut bounds = None;
        let mut templates = Vec::new();
        for root in roots {
            templates.push(
                self.template(
                    &nodes,
                    root,
                    &IDENTITY_MATRIX,
                    (&meshes, &accessors, mesh_base),
                    &mut bounds,
                    0,
                )
                .map_err(&bad)?,
            );
        }
        Ok(MergedMesh {
            roots: templates,
            bounds,
            meshes: (mesh_base..self.meshes.len()).collect(),
        })
    }

    /// Node `index` of a stored GLB as a template (mesh shifted, children nested, no name or
    /// extras: the stroke node has them), growing `bounds` by its mesh's.
    fn template(
        &self,
        nodes: &[Value],
        index: usize,
        parent: &[f64; 16],
        (meshes, accessors, mesh_base): (&[Value], &[Value], usize),
        bounds: &mut Option<Bounds>,
        depth: usize,
    ) -> Result<Value, String> {
        let node = nodes.get(index).ok_or_else(|| format!("its scene names node {index}"))?;
        if depth > 32 {
            return Err("its nodes nest too deep".into());
        }
        let here = mat_mul(parent, &node_matrix(node, index).map_err(|e| e.to_string())?);
        let mut out = Map::new();
        for key in ["matrix", "translation", "rotation", "scale"] {
            if let Some(v) = node.get(key) {
                out.insert(key.into(), v.clone());
            }
        }
        if let Some(mesh) = node.get("mesh").and_then(Value::as_u64) {
            out.insert("mesh".into(), json!(mesh as usize + mesh_base));
            let primitives = meshes
                .get(mesh as usize)
                .and_then(|m| m.get("primitives"))
                .and_then(Value::as_array)
                .ok_or_else(|| format!("node {index} names mesh {mesh}, which it lacks"))?;
            for primitive in primitives {
                let Some(accessor) = primitive
                    .pointer("/attributes/POSITION")
                    .and_then(Value::as_u64)
                    .and_then(|a| accessors.get(a as usize))
                else {
                    continue;
                };
                let (Some(min), Some(max)) =
                    (position_bound(accessor, "min"), position_bound(accessor, "max"))
                else {
                    return Err("a POSITION accessor has no min and max".into());
                };
                for corner in corners((min, max)) {
                    grow(bounds, transform_point(&here, corner));
                }
            }
        }
        let children = node.get("children").and_then(Value::as_array).cloned().unwrap_or_default();
        if !children.is_empty() {
            let nested = children
                .iter()
                .map(|c| {
                    let c = c.as_u64().ok_or("a child is not a node index")? as usize;
                    self.template(
                        nodes,
                        c,
                        &here,
                        (meshes, accessors, mesh_base),
                        bounds,
                        depth + 1,
                    )
                })
                .collect::<Result<Vec<_>, String>>()?;
            out.insert("children".into(), Value::Array(nested));
        }
        Ok(Value::Object(out))
    }

    /// Adds a template's node (and its nested children) to the scene; returns its index.
    fn instantiate(&mut self, template: &Value, name: &str) -> usize {
        let mut node = template.clone();
        let children = node.as_object_mut().and_then(|n| n.remove("children"));
        node["name"] = json!(format!("{name} mesh"));
        let index = self.nodes.len();
        self.nodes.push(node);
        if let Some(Value::Array(children)) = children {
            let indices: Vec<usize> = children.iter().map(|c| self.instantiate(c, name)).collect();
            self.nodes[index]["children"] = json!(indices);
        }
        index
    }
}

/// A POSITION accessor's `min` or `max`, as the values it decodes to (a normalised integer
/// accessor's stored steps divided out).
fn position_bound(accessor: &Value, key: &str) -> Option<[f64; 3]> {
    let values = accessor.get(key)?.as_array()?;
    let mut out = [0.0; 3];
    for (slot, value) in out.iter_mut().zip(values) {
        *slot = value.as_f64()?;
    }
    if accessor.get("normalized").and_then(Value::as_bool) == Some(true) {
        let divisor = match accessor.get("componentType").and_then(Value::as_u64) {
            Some(5120) => 127.0,
            Some(5121) => 255.0,
            Some(5122) => 32767.0,
            Some(5123) => 65535.0,
            _ => 1.0,
        };
        for v in &mut out {
            *v = (*v / divisor).max(-1.0);
        }
    }
    Some(out)
}

/// The axes change of the root: penmesh's x right, y down the page, z out of it, to glTF's
/// Y up, as the page shows the board (lying on the ground, seen from above).
const AXES: [f64; 16] =
    [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];

/// The scene as one GLB: a root node (axes to glTF's, px to metres so the longest side is
/// `size_mm` mm, lowest corner at the origin) with a node per stroke in order.
pub fn scene_glb(input: &SceneInput<'_>) -> Result<Vec<u8>, SceneError> {
    let mut merger = Merger::default();
    let mut merged = Vec::with_capacity(input.meshes.len());
    for (index, glb) in input.meshes.iter().enumerate() {
        // The stroke that owns the mesh names it in errors.
        let owner = input
            .strokes
            .iter()
            .find(|s| s.mesh == Some(index))
            .map(|s| s.extras.stroke)
            .unwrap_or_default();
        merged.push(merger.merge(owner, glb)?);
    }
    // A material per mesh, named after the first stroke that shows it, in its brush's colour.
    let mut named = vec![false; merged.len()];
    for stroke in &input.strokes {
        let Some(mesh) = stroke.mesh.filter(|&m| m < merged.len()) else { continue };
        if std::mem::replace(&mut named[mesh], true) {
            continue;
        }
        let rgb = stroke.extras.brush.color.unwrap_or(0x40_40_40);
        let material = merger.materials.len();
        merger.materials.push(json!({
            "name": stroke_label(stroke.extras),
            "pbrMetallicRoughness": {
                "baseColorFactor": [srgb_to_linear(rgb >> 16), srgb_to_linear(rgb >> 8), srgb_to_linear(rgb), 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.8,
            },
            "doubleSided": true,
        }));
        for &m in &merged[mesh].meshes {
            merger.meshes[m]["name"] = json!(stroke_label(stroke.extras));
            for primitive in merger.meshes[m]
                .get_mut("primitives")
                .and_then(Value::as_array_mut)
                .into_iter()
                .flatten()
            {
                if primitive.get("material").is_none() {
                    primitive["material"] = json!(material);
                }
            }
        }
    }
    // The scene's bounds in session units: every placed mesh, and every placed sample.
    let mut bounds = None;
    for stroke in &input.strokes {
        if let Some(b) = stroke.mesh.and_then(|m| merged.get(m)).and_then(|m| m.bounds) {
            for corner in corners(b) {
                grow(&mut bounds, transform_point(&stroke.placement, corner));
            }
        }
        for s in &stroke.extras.samples {
            grow(&mut bounds, transform_point(&stroke.placement, [s.x, s.y, 0.0]));
        }
    }
    let mut stroke_nodes = Vec::with_capacity(input.strokes.len());
    for stroke in &input.strokes {
        let label = stroke_label(stroke.extras);
        let children: Vec<usize> = match stroke.mesh.and_then(|m| merged.get(m)) {
            Some(mesh) => {
                mesh.roots.clone().iter().map(|t| merger.instantiate(t, &label)).collect()
            }
            None => Vec::new(),
        };
        let mut node = json!({
            "name": label,
            "extras": { EXTRAS_KEY: stroke.extras },
        });
        if stroke.placement.map(f64::to_bits) != IDENTITY_MATRIX.map(f64::to_bits) {
            node["matrix"] = json!(stroke.placement.to_vec());
        }
        if !children.is_empty() {
            node["children"] = json!(children);
        }
        stroke_nodes.push(merger.nodes.len());
        merger.nodes.push(node);
    }
    // The root: axes, then px to metres, then the lowest corner to the origin.
    let longest = bounds
        .map(|b: Bounds| {
            corners(b)
                .map(|c| transform_point(&AXES, c))
                .fold(None, |mut acc, p| {
                    grow(&mut acc, p);
                    acc
                })
                .map(|(lo, hi)| (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max))
                .unwrap_or(0.0)
        })
        .unwrap_or(0.0);
    let metres_per_unit =
        if longest > 0.0 && longest.is_finite() { input.size_mm / 1000.0 / longest } else { 1e-3 };
    let mut root = AXES;
    for v in &mut root[..12] {
        *v *= metres_per_unit;
    }
    if let Some(b) = bounds {
        let mut low = None;
        for c in corners(b) {
            grow(&mut low, transform_point(&root, c));
        }
        if let Some((lo, _)) = low {
            for axis in 0..3 {
                root[12 + axis] = -lo[axis];
            }
        }
    }
    let scene_extras =
        SceneExtras { format: SCENE_FORMAT_VERSION, size_mm: input.size_mm, metres_per_unit };
    let root_index = merger.nodes.len();
    merger.nodes.push(json!({
        "name": "penmesh session",
        "matrix": root.to_vec(),
        "children": stroke_nodes,
        "extras": { SCENE_EXTRAS_KEY: scene_extras },
    }));
    let mut doc = json!({
        "asset": { "version": "2.0", "generator": format!("penmesh {}", env!("CARGO_PKG_VERSION")) },
        "scene": 0,
        "scenes": [{ "name": "penmesh session", "nodes": [root_index] }],
        "nodes": merger.nodes,
    });
    let mut put = |key: &str, list: Vec<Value>| {
        if !list.is_empty() {
            doc[key] = Value::Array(list);
        }
    };
    put("meshes", merger.meshes);
    put("materials", merger.materials);
    put("accessors", merger.accessors);
    put("bufferViews", merger.views);
    let mut buffers = Vec::new();
    if !merger.bin.is_empty() {
        buffers.push(json!({ "byteLength": merger.bin.len() }));
    }
    if merger.fallback_length > 0 {
        if buffers.is_empty() {
            return Err(SceneError::BadMesh {
                stroke: Uuid::nil(),
                why: "a fallback buffer without a BIN chunk".into(),
            });
        }
        buffers.push(json!({
            "byteLength": merger.fallback_length,
            "extensions": { MESHOPT: { "fallback": true } },
        }));
    }
    put("buffers", buffers);
    if !merger.used.is_empty() {
        doc["extensionsUsed"] = json!(merger.used);
    }
    if !merger.required.is_empty() {
        doc["extensionsRequired"] = json!(merger.required);
    }
    let mut json_bytes = serde_json::to_vec(&doc).expect("a JSON value serialises");
    json_bytes.resize(json_bytes.len().next_multiple_of(4), b' ');
    let bin_chunk = if merger.bin.is_empty() { 0 } else { 8 + merger.bin.len() };
    let total = 12 + 8 + json_bytes.len() + bin_chunk;
    let mut glb = Vec::with_capacity(total);
    glb.extend_from_slice(GLB_MAGIC);
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(total as u32).to_le_bytes());
    glb.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    glb.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    glb.extend_from_slice(&json_bytes);
    if !merger.bin.is_empty() {
        glb.extend_from_slice(&(merger.bin.len() as u32).to_le_bytes());
        glb.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        glb.extend_from_slice(&merger.bin);
    }
    Ok(glb)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{GlbMeta, GlbOptions, OutlineOptions, SolidOptions, stroke_glb, stroke_mesh};

    fn extras(samples: Vec<Sample>) -> StrokeExtras {
        StrokeExtras {
            format: SCENE_FORMAT_VERSION,
            stroke: Uuid::new_v4(),
            author: Author { participant: Uuid::new_v4(), name: "Ada".into() },
            drawn_at: 1_800_000_000_000,
            brush: Brush { color: Some(0xff8000), ..Brush::default() },
            samples,
            duplicate_of: None,
            imported_from: None,
        }
    }

    fn glb_of(extras: &StrokeExtras) -> Vec<u8> {
        let mesh = stroke_mesh(
            &extras.samples,
            &extras.brush,
            &OutlineOptions::default(),
            &SolidOptions::default(),
        );
        let meta = GlbMeta { stroke: extras.stroke, author: "x".into(), brush: extras.brush };
        stroke_glb(&mesh, &meta, &GlbOptions::default())
    }

    #[test]
    fn a_scene_reads_back_its_strokes_and_placements_exactly() {
        // Samples off any short decimal, a mirror placement: both come back bit for bit.
        let a = extras(vec![
            Sample::new(0.0625, 1.0 / 3.0, 0.0, 0.1),
            Sample::new(40.5, 10.0, 12.125, 0.7),
        ]);
        let b = extras(vec![Sample::new(5.0, 5.0, 0.0, 0.5), Sample::new(5.0, 60.0, 8.0, 0.5)]);
        let mirror =
            [-1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 3.5, -0.0, 7.0, 1.0];
        let meshes = [glb_of(&a), glb_of(&b)];
        let input = SceneInput {
            meshes: meshes.iter().map(Vec::as_slice).collect(),
            strokes: vec![
                SceneStroke { extras: &a, placement: IDENTITY_MATRIX, mesh: Some(0) },
                SceneStroke { extras: &b, placement: mirror, mesh: Some(1) },
                // A duplicate shows its source's mesh.
                SceneStroke { extras: &b, placement: IDENTITY_MATRIX, mesh: Some(1) },
            ],
            size_mm: 100.0,
        };
        let glb = scene_glb(&input).unwrap();
        let back = read_scene(&glb).unwrap();
        assert_eq!(back.len(), 3);
        assert_eq!(back[0].extras, a);
        assert_eq!(back[1].extras, b);
        assert_eq!(back[1].placement.map(f64::to_bits), mirror.map(f64::to_bits));
        assert_eq!(back[2].placement, IDENTITY_MATRIX);
        // The gltf crate reads the merged document (its validation knows neither extension,
        // so it is read without it).
        let gltf = gltf::Gltf::from_slice_without_validation(&glb).unwrap();
        assert_eq!(gltf.meshes().count(), 2);
        assert_eq!(gltf.materials().count(), 2);
    }

    #[test]
    fn the_root_scales_the_longest_side_to_size_mm() {
        // A stroke 100 px long and 1 px wide: its longest side, meshes and all, is about
        // 100 px, so 50 mm makes about 0.5 mm a px.
        let a = extras(vec![Sample::new(0.0, 0.0, 0.0, 0.5), Sample::new(100.0, 0.0, 1.0, 0.5)]);
        let meshes = [glb_of(&a)];
        let input = SceneInput {
            meshes: meshes.iter().map(Vec::as_slice).collect(),
            strokes: vec![SceneStroke { extras: &a, placement: IDENTITY_MATRIX, mesh: Some(0) }],
            size_mm: 50.0,
        };
        let (json, _) = parse_glb(&scene_glb(&input).unwrap()).unwrap();
        let root = json["nodes"].as_array().unwrap().last().unwrap();
        let per_unit = root["extras"][SCENE_EXTRAS_KEY]["metres_per_unit"].as_f64().unwrap();
        let longest = 50.0 / 1000.0 / per_unit;
        assert!((100.0..110.0).contains(&longest), "{longest}");
    }

    #[test]
    fn bad_files_are_refused_naming_what_is_wrong() {
        let a = extras(vec![Sample::new(0.0, 0.0, 0.0, 0.5), Sample::new(10.0, 0.0, 1.0, 0.5)]);
        let meshes = [glb_of(&a)];
        let input = SceneInput {
            meshes: meshes.iter().map(Vec::as_slice).collect(),
            strokes: vec![SceneStroke { extras: &a, placement: IDENTITY_MATRIX, mesh: Some(0) }],
            size_mm: 100.0,
        };
        let glb = scene_glb(&input).unwrap();
        let cut = read_scene(&glb[..glb.len() - 10]).unwrap_err();
        assert!(matches!(cut, SceneError::Truncated(_)), "{cut}");
        assert!(cut.to_string().contains("truncated"), "{cut}");
        // A stored stroke GLB has no penmesh extras.
        assert_eq!(read_scene(&meshes[0]).unwrap_err(), SceneError::NoStrokes);
        assert!(matches!(read_scene(b"not a glb at all").unwrap_err(), SceneError::NotGlb(_)));
    }
}
