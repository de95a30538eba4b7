//! Writing the scene: the stored meshes merged at the JSON level under one root node, a node
//! per stroke with its placement and pen data.

use serde_json::{Map, Value, json};

use super::container::{node_matrix, parse_glb};
use super::*;
use crate::glb::{CHUNK_BIN, CHUNK_JSON, GLB_MAGIC};
use crate::placement::IDENTITY_MATRIX;

const MESHOPT: &str = "EXT_meshopt_compression";

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

/// Converts an sRGB channel to linear, as glTF's `baseColorFactor` wants.
fn srgb_to_linear(channel: u32) -> f64 {
    let c = f64::from(channel & 0xff) / 255.0;
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
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

/// A member of the scene's document as it is written: its nodes apart, so that each stroke's
/// pen data becomes JSON one stroke at a time, never as a tree of the whole scene's samples
/// (a `Value` takes ten times the bytes of its text).
#[derive(serde::Serialize)]
#[serde(untagged)]
enum Part<'a> {
    Value(Value),
    Nodes(Vec<Node<'a>>),
}

/// A node of the scene: a stroke's is written with its extras added.
enum Node<'a> {
    Plain(Value),
    Stroke { node: Value, extras: &'a StrokeExtras },
}

impl serde::Serialize for Node<'_> {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self {
            Node::Plain(node) => node.serialize(serializer),
            Node::Stroke { node, extras } => {
                // The node as one `Value`, as the whole document once was: the same bytes.
                let mut node = node.clone();
                let extras = serde_json::to_value(extras).map_err(serde::ser::Error::custom)?;
                node["extras"] = json!({ EXTRAS_KEY: extras });
                node.serialize(serializer)
            }
        }
    }
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
        // Its extras are added as it is written ([`Node::Stroke`]), not here.
        let mut node = json!({ "name": label });
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
    // The stroke nodes with their extras, written one at a time.
    let mut nodes: Vec<Node<'_>> = merger.nodes.into_iter().map(Node::Plain).collect();
    for (stroke, &index) in input.strokes.iter().zip(&stroke_nodes) {
        let node = std::mem::replace(&mut nodes[index], Node::Plain(Value::Null));
        if let Node::Plain(node) = node {
            nodes[index] = Node::Stroke { node, extras: stroke.extras };
        }
    }
    let Value::Object(doc) = doc else { unreachable!("the document is an object") };
    let mut parts: std::collections::BTreeMap<String, Part<'_>> =
        doc.into_iter().map(|(key, value)| (key, Part::Value(value))).collect();
    parts.insert("nodes".into(), Part::Nodes(nodes));
    // The header, its lengths set once the JSON is written straight after it.
    let mut glb = Vec::with_capacity(20 + merger.bin.len() + 8);
    glb.extend_from_slice(GLB_MAGIC);
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&[0; 8]);
    glb.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    serde_json::to_writer(&mut glb, &parts).expect("a JSON document serialises");
    glb.resize(glb.len().next_multiple_of(4), b' ');
    let json_length = glb.len() - 20;
    let bin_chunk = if merger.bin.is_empty() { 0 } else { 8 + merger.bin.len() };
    let total = 12 + 8 + json_length + bin_chunk;
    glb[8..12].copy_from_slice(&(total as u32).to_le_bytes());
    glb[12..16].copy_from_slice(&(json_length as u32).to_le_bytes());
    if !merger.bin.is_empty() {
        glb.extend_from_slice(&(merger.bin.len() as u32).to_le_bytes());
        glb.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        glb.extend_from_slice(&merger.bin);
    }
    Ok(glb)
}
