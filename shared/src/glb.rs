//! Binary glTF 2.0 (GLB) export of stroke meshes (LRPDP step 7).
//!
//! One glTF mesh and one node per stroke, all in one scene; each mesh has one triangle primitive
//! with `POSITION`, `NORMAL` and indices accessors (all with `min` and `max`), and carries the
//! stroke's [`GlbMeta`] (id, author, brush) in `extras`, as does its node. Indices are `u16`
//! when the stroke has at most 65,535 vertices (so no index is the primitive-restart value),
//! `u32` otherwise. The JSON chunk is padded to 4 bytes with spaces, the binary chunk with zeros.
//!
//! With [`GlbOptions::quantize`], the file uses `KHR_mesh_quantization` (declared in
//! `extensionsUsed` and `extensionsRequired`): positions are unnormalised `u16` in the stroke's
//! bounding box, mapped back by the node's `translation` and `scale` (error at most half a step,
//! `extent / 65535 / 2` per axis), and normals are normalised `i8`; each vertex element is
//! padded to 4 bytes as glTF requires. A reader without that extension must refuse the file
//! (the `gltf` crate's validating loader does).
//!
//! A stroke with an empty mesh still gets a node with its metadata, but no mesh.

use gltf_json as json;
use json::validation::{Checked::Valid, USize64};
use serde::{Deserialize, Serialize};

use crate::mesh::StrokeMesh;
use crate::model::Brush;

/// The extension name for quantised attributes.
pub const KHR_MESH_QUANTIZATION: &str = "KHR_mesh_quantization";

const GLB_MAGIC: &[u8; 4] = b"glTF";
const GLB_VERSION: u32 = 2;
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// What a stroke's mesh carries in `extras`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GlbMeta {
    pub stroke: uuid::Uuid,
    pub author: String,
    pub brush: Brush,
}

/// How the GLB is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GlbOptions {
    /// Write `KHR_mesh_quantization` attributes (about a third smaller). Off by default.
    pub quantize: bool,
}

impl GlbOptions {
    pub fn quantize(mut self, quantize: bool) -> GlbOptions {
        self.quantize = quantize;
        self
    }
}

/// One stroke to export.
#[derive(Debug, Clone, Copy)]
pub struct GlbStroke<'a> {
    pub mesh: &'a StrokeMesh,
    pub meta: &'a GlbMeta,
}

/// A GLB file of one stroke.
pub fn stroke_glb(mesh: &StrokeMesh, meta: &GlbMeta, options: &GlbOptions) -> Vec<u8> {
    strokes_glb(&[GlbStroke { mesh, meta }], options)
}

/// A GLB file of several strokes, one mesh and node each, in order.
///
/// The document is planned first (views, accessors, bounds), so the file is allocated once at
/// its exact size and the attributes are written straight into it.
pub fn strokes_glb(strokes: &[GlbStroke<'_>], options: &GlbOptions) -> Vec<u8> {
    let mut writer = DocumentWriter::default();
    if options.quantize {
        writer.root.extensions_used.push(KHR_MESH_QUANTIZATION.to_owned());
        writer.root.extensions_required.push(KHR_MESH_QUANTIZATION.to_owned());
    }
    let mut nodes = Vec::with_capacity(strokes.len());
    for stroke in strokes {
        nodes.push(writer.add_stroke(stroke, options));
    }
    writer.root.push(json::Scene { extensions: None, extras: None, name: None, nodes });
    writer.root.scene = Some(json::Index::new(0));
    writer.finish()
}

/// The bytes of one buffer view, written when the file is assembled.
enum Payload<'a> {
    /// `f32` VEC3, tightly packed.
    Floats(&'a [[f32; 3]]),
    /// `u16` VEC3 steps from `lo`, padded to 8 bytes.
    QuantizedPositions {
        positions: &'a [[f32; 3]],
        lo: [f32; 3],
        inv_step: [f32; 3],
    },
    /// Normalised `i8` VEC3, padded to 4 bytes.
    QuantizedNormals(&'a [[f32; 3]]),
    Indices16(&'a [u32]),
    Indices32(&'a [u32]),
}

impl Payload<'_> {
    fn byte_length(&self) -> usize {
        match self {
            Payload::Floats(values) => 12 * values.len(),
            Payload::QuantizedPositions { positions, .. } => 8 * positions.len(),
            Payload::QuantizedNormals(normals) => 4 * normals.len(),
            Payload::Indices16(indices) => 2 * indices.len(),
            Payload::Indices32(indices) => 4 * indices.len(),
        }
    }

    /// Writes into `out`, which is `byte_length()` zeroed bytes.
    fn write(&self, out: &mut [u8]) {
        match self {
            Payload::Floats(values) => {
                for (bytes, v) in out.chunks_exact_mut(4).zip(values.as_flattened()) {
                    bytes.copy_from_slice(&v.to_le_bytes());
                }
            }
            Payload::QuantizedPositions { positions, lo, inv_step } => {
                for (bytes, p) in out.chunks_exact_mut(8).zip(*positions) {
                    for axis in 0..3 {
                        let q = quantize_position(p[axis], lo[axis], inv_step[axis]);
                        bytes[2 * axis..2 * axis + 2].copy_from_slice(&q.to_le_bytes());
                    }
                }
            }
            Payload::QuantizedNormals(normals) => {
                for (bytes, n) in out.chunks_exact_mut(4).zip(*normals) {
                    for axis in 0..3 {
                        bytes[axis] = quantize_normal(n[axis]).to_le_bytes()[0];
                    }
                }
            }
            Payload::Indices16(indices) => {
                for (bytes, &i) in out.chunks_exact_mut(2).zip(*indices) {
                    bytes.copy_from_slice(&(i as u16).to_le_bytes());
                }
            }
            Payload::Indices32(indices) => {
                for (bytes, i) in out.chunks_exact_mut(4).zip(*indices) {
                    bytes.copy_from_slice(&i.to_le_bytes());
                }
            }
        }
    }
}

/// Steps of `inv_step⁻¹` from `lo`, rounded half up (the value is not negative); `as`
/// saturates, so NaN and out-of-range values cannot panic.
fn quantize_position(value: f32, lo: f32, inv_step: f32) -> u16 {
    ((value - lo) * inv_step + 0.5) as u16
}

/// A normalised `i8`, rounded half away from zero (`as` truncates towards zero).
fn quantize_normal(value: f32) -> i8 {
    (value * 127.0 + 0.5f32.copysign(value)).clamp(-127.0, 127.0) as i8
}

#[derive(Default)]
struct DocumentWriter<'a> {
    root: json::Root,
    /// Each view's payload and its offset in the binary chunk.
    payloads: Vec<(usize, Payload<'a>)>,
    bin_length: usize,
}

impl<'a> DocumentWriter<'a> {
    fn add_stroke(
        &mut self,
        stroke: &GlbStroke<'a>,
        options: &GlbOptions,
    ) -> json::Index<json::Node> {
        let meta = serde_json::value::to_raw_value(stroke.meta).ok();
        let name = Some(stroke.meta.stroke.to_string());
        let mut node =
            json::Node { extras: meta.clone(), name: name.clone(), ..Default::default() };
        let mesh: &'a StrokeMesh = stroke.mesh;
        if let Some((lo, hi)) = mesh.bounds().filter(|_| !mesh.is_empty()) {
            let (positions, normals) = if options.quantize {
                let step: [f32; 3] = std::array::from_fn(|axis| {
                    let step = (hi[axis] - lo[axis]) / f32::from(u16::MAX);
                    if step > 0.0 && step.is_finite() { step } else { 1.0 }
                });
                node.translation = Some(lo);
                node.scale = Some(step);
                (self.quantized_positions(mesh, lo, hi, step), self.quantized_normals(mesh))
            } else {
                let (normals_lo, normals_hi) = component_bounds(&mesh.normals);
                let positions = self.accessor(
                    Payload::Floats(&mesh.positions),
                    None,
                    json::buffer::Target::ArrayBuffer,
                    json::accessor::ComponentType::F32,
                    json::accessor::Type::Vec3,
                    false,
                    (json::Value::from(lo.to_vec()), json::Value::from(hi.to_vec())),
                );
                let normals = self.accessor(
                    Payload::Floats(&mesh.normals),
                    None,
                    json::buffer::Target::ArrayBuffer,
                    json::accessor::ComponentType::F32,
                    json::accessor::Type::Vec3,
                    false,
                    (
                        json::Value::from(normals_lo.to_vec()),
                        json::Value::from(normals_hi.to_vec()),
                    ),
                );
                (positions, normals)
            };
            let indices = self.indices(mesh);
            let primitive = json::mesh::Primitive {
                attributes: [
                    (Valid(json::mesh::Semantic::Positions), positions),
                    (Valid(json::mesh::Semantic::Normals), normals),
                ]
                .into(),
                extensions: None,
                extras: None,
                indices: Some(indices),
                material: None,
                mode: Valid(json::mesh::Mode::Triangles),
                targets: None,
            };
            node.mesh = Some(self.root.push(json::Mesh {
                extensions: None,
                extras: meta,
                name,
                primitives: vec![primitive],
                weights: None,
            }));
        }
        self.root.push(node)
    }

    /// Plans a buffer view (4-byte aligned) for `payload` and an accessor reading all of it.
    #[allow(clippy::too_many_arguments)]
    fn accessor(
        &mut self,
        payload: Payload<'a>,
        stride: Option<usize>,
        target: json::buffer::Target,
        component: json::accessor::ComponentType,
        type_: json::accessor::Type,
        normalized: bool,
        (min, max): (json::Value, json::Value),
    ) -> json::Index<json::Accessor> {
        let offset = self.bin_length;
        let length = payload.byte_length();
        let count = match &payload {
            Payload::Floats(values) => values.len(),
            Payload::QuantizedPositions { positions, .. } => positions.len(),
            Payload::QuantizedNormals(normals) => normals.len(),
            Payload::Indices16(indices) | Payload::Indices32(indices) => indices.len(),
        };
        self.bin_length = (offset + length).next_multiple_of(4);
        self.payloads.push((offset, payload));
        let view = self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(length),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: stride.map(json::buffer::Stride),
            name: None,
            target: Some(Valid(target)),
            extensions: None,
            extras: None,
        });
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: Some(USize64(0)),
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: None,
            extras: None,
            type_: Valid(type_),
            min: Some(min),
            max: Some(max),
            name: None,
            normalized,
            sparse: None,
        })
    }

    /// Positions as `u16` steps of `step` across the bounding box `lo..hi`. Quantisation is
    /// monotonic, so the bounds in steps are the quantised bounds.
    fn quantized_positions(
        &mut self,
        mesh: &'a StrokeMesh,
        lo: [f32; 3],
        hi: [f32; 3],
        step: [f32; 3],
    ) -> json::Index<json::Accessor> {
        let inv_step = step.map(|step| 1.0 / step);
        let q_lo: [u16; 3] = std::array::from_fn(|a| quantize_position(lo[a], lo[a], inv_step[a]));
        let q_hi: [u16; 3] = std::array::from_fn(|a| quantize_position(hi[a], lo[a], inv_step[a]));
        self.accessor(
            Payload::QuantizedPositions { positions: &mesh.positions, lo, inv_step },
            Some(8),
            json::buffer::Target::ArrayBuffer,
            json::accessor::ComponentType::U16,
            json::accessor::Type::Vec3,
            false,
            (json::Value::from(q_lo.to_vec()), json::Value::from(q_hi.to_vec())),
        )
    }

    fn quantized_normals(&mut self, mesh: &'a StrokeMesh) -> json::Index<json::Accessor> {
        let (lo, hi) = component_bounds(&mesh.normals);
        let (q_lo, q_hi) = (lo.map(quantize_normal), hi.map(quantize_normal));
        self.accessor(
            Payload::QuantizedNormals(&mesh.normals),
            Some(4),
            json::buffer::Target::ArrayBuffer,
            json::accessor::ComponentType::I8,
            json::accessor::Type::Vec3,
            true,
            (json::Value::from(q_lo.to_vec()), json::Value::from(q_hi.to_vec())),
        )
    }

    fn indices(&mut self, mesh: &'a StrokeMesh) -> json::Index<json::Accessor> {
        let lo = mesh.indices.iter().copied().min().unwrap_or(0);
        let hi = mesh.indices.iter().copied().max().unwrap_or(0);
        let (payload, component) = if mesh.positions.len() <= usize::from(u16::MAX) {
            (Payload::Indices16(&mesh.indices), json::accessor::ComponentType::U16)
        } else {
            (Payload::Indices32(&mesh.indices), json::accessor::ComponentType::U32)
        };
        self.accessor(
            payload,
            None,
            json::buffer::Target::ElementArrayBuffer,
            component,
            json::accessor::Type::Scalar,
            false,
            (json::Value::from(vec![lo]), json::Value::from(vec![hi])),
        )
    }

    fn finish(mut self) -> Vec<u8> {
        let bin_length = self.bin_length;
        if bin_length > 0 {
            self.root.push(json::Buffer {
                byte_length: USize64::from(bin_length),
                name: None,
                uri: None,
                extensions: None,
                extras: None,
            });
        }
        self.root.asset.generator = Some(format!("penmesh {}", env!("CARGO_PKG_VERSION")));
        // Serialising the document cannot fail: every map key is a string and every value is
        // plain data (non-finite floats become `null`).
        let mut json_bytes =
            json::serialize::to_vec(&self.root).expect("a glTF document always serialises");
        while json_bytes.len() % 4 != 0 {
            json_bytes.push(b' ');
        }
        let bin_chunk = if bin_length == 0 { 0 } else { 8 + bin_length };
        let total = 12 + 8 + json_bytes.len() + bin_chunk;
        let mut glb = Vec::with_capacity(total);
        glb.extend_from_slice(GLB_MAGIC);
        glb.extend_from_slice(&GLB_VERSION.to_le_bytes());
        glb.extend_from_slice(&(total as u32).to_le_bytes());
        glb.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
        glb.extend_from_slice(&CHUNK_JSON.to_le_bytes());
        glb.extend_from_slice(&json_bytes);
        if bin_length > 0 {
            glb.extend_from_slice(&(bin_length as u32).to_le_bytes());
            glb.extend_from_slice(&CHUNK_BIN.to_le_bytes());
            let bin_start = glb.len();
            // Zeroed, so the padding between views is zero as GLB requires.
            glb.resize(total, 0);
            for (offset, payload) in &self.payloads {
                let at = bin_start + offset;
                payload.write(&mut glb[at..at + payload.byte_length()]);
            }
        }
        glb
    }
}

/// Per-axis minimum and maximum of a list of 3-vectors (zeros for an empty list).
fn component_bounds(values: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let Some(&first) = values.first() else {
        return ([0.0; 3], [0.0; 3]);
    };
    values.iter().fold((first, first), |(lo, hi), v| {
        (std::array::from_fn(|i| lo[i].min(v[i])), std::array::from_fn(|i| hi[i].max(v[i])))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{OutlineOptions, Sample, SolidOptions, stroke_mesh};

    fn meta() -> GlbMeta {
        GlbMeta { stroke: uuid::Uuid::nil(), author: "ada".into(), brush: Brush::default() }
    }

    #[test]
    fn header_and_chunks_are_well_formed_and_padded() {
        // GLB header length matches, both chunks are 4-byte multiples with the right types.
        let samples = [Sample::new(0.0, 0.0, 0.0, 0.5), Sample::new(5.0, 1.0, 1.0, 0.7)];
        let mesh = stroke_mesh(
            &samples,
            &Brush::default(),
            &OutlineOptions::default(),
            &SolidOptions::default(),
        );
        for quantize in [false, true] {
            let glb = stroke_glb(&mesh, &meta(), &GlbOptions::default().quantize(quantize));
            let word = |at: usize| u32::from_le_bytes(glb[at..at + 4].try_into().unwrap());
            assert_eq!(&glb[..4], b"glTF");
            assert_eq!(word(4), 2);
            assert_eq!(word(8) as usize, glb.len());
            let json_len = word(12) as usize;
            assert_eq!((json_len % 4, word(16)), (0, CHUNK_JSON));
            let bin_at = 20 + json_len;
            assert_eq!((word(bin_at) % 4, word(bin_at + 4)), (0, CHUNK_BIN));
            assert_eq!(bin_at + 8 + word(bin_at) as usize, glb.len());
        }
    }

    #[test]
    fn empty_mesh_gives_a_node_without_mesh_or_buffer() {
        // An empty stroke still exports its metadata, with no binary chunk.
        let glb = stroke_glb(&StrokeMesh::default(), &meta(), &GlbOptions::default());
        let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        assert_eq!(glb.len(), 20 + json_len);
        let doc: serde_json::Value = serde_json::from_slice(&glb[20..]).unwrap();
        assert_eq!(doc["nodes"][0]["extras"]["author"], "ada");
        assert!(doc.get("meshes").is_none() && doc.get("buffers").is_none());
    }
}
