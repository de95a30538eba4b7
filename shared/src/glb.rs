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
pub fn strokes_glb(strokes: &[GlbStroke<'_>], options: &GlbOptions) -> Vec<u8> {
    let mut writer = DocumentWriter::default();
    if options.quantize {
        writer.root.extensions_used.push(KHR_MESH_QUANTIZATION.to_owned());
        writer.root.extensions_required.push(KHR_MESH_QUANTIZATION.to_owned());
    }
    // Room for the largest layout (float attributes, u32 indices), so the buffer never moves.
    let bin_capacity: usize =
        strokes.iter().map(|s| 24 * s.mesh.positions.len() + 4 * s.mesh.indices.len() + 12).sum();
    writer.bin.reserve(bin_capacity);
    let mut nodes = Vec::with_capacity(strokes.len());
    for stroke in strokes {
        nodes.push(writer.add_stroke(stroke, options));
    }
    writer.root.push(json::Scene { extensions: None, extras: None, name: None, nodes });
    writer.root.scene = Some(json::Index::new(0));
    writer.finish()
}

#[derive(Default)]
struct DocumentWriter {
    root: json::Root,
    bin: Vec<u8>,
}

impl DocumentWriter {
    fn add_stroke(
        &mut self,
        stroke: &GlbStroke<'_>,
        options: &GlbOptions,
    ) -> json::Index<json::Node> {
        let meta = serde_json::value::to_raw_value(stroke.meta).ok();
        let name = Some(stroke.meta.stroke.to_string());
        let mut node =
            json::Node { extras: meta.clone(), name: name.clone(), ..Default::default() };
        let mesh = stroke.mesh;
        if let Some((lo, hi)) = mesh.bounds().filter(|_| !mesh.is_empty()) {
            let (positions, normals) = if options.quantize {
                let (positions, translation, scale) = self.quantized_positions(mesh, lo, hi);
                node.translation = Some(translation);
                node.scale = Some(scale);
                (positions, self.quantized_normals(mesh))
            } else {
                let (normals_lo, normals_hi) = component_bounds(&mesh.normals);
                (
                    self.float_vec3(&mesh.positions, lo, hi),
                    self.float_vec3(&mesh.normals, normals_lo, normals_hi),
                )
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

    /// Appends a buffer view (4-byte aligned) filled by `write`, and returns its index.
    fn view(
        &mut self,
        stride: Option<usize>,
        target: json::buffer::Target,
        write: impl FnOnce(&mut Vec<u8>),
    ) -> json::Index<json::buffer::View> {
        let offset = self.bin.len();
        write(&mut self.bin);
        let length = self.bin.len() - offset;
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
        self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(length),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: stride.map(json::buffer::Stride),
            name: None,
            target: Some(Valid(target)),
            extensions: None,
            extras: None,
        })
    }

    #[allow(clippy::too_many_arguments)]
    fn accessor(
        &mut self,
        view: json::Index<json::buffer::View>,
        count: usize,
        component: json::accessor::ComponentType,
        type_: json::accessor::Type,
        normalized: bool,
        min: json::Value,
        max: json::Value,
    ) -> json::Index<json::Accessor> {
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

    /// A float VEC3 attribute with the given per-axis bounds.
    fn float_vec3(
        &mut self,
        values: &[[f32; 3]],
        lo: [f32; 3],
        hi: [f32; 3],
    ) -> json::Index<json::Accessor> {
        let view = self.view(None, json::buffer::Target::ArrayBuffer, |bin| {
            bin.reserve(12 * values.len());
            for v in values.iter().flatten() {
                bin.extend_from_slice(&v.to_le_bytes());
            }
        });
        self.accessor(
            view,
            values.len(),
            json::accessor::ComponentType::F32,
            json::accessor::Type::Vec3,
            false,
            json::Value::from(lo.to_vec()),
            json::Value::from(hi.to_vec()),
        )
    }

    /// Positions as `u16` steps across the bounding box; returns the node's translation and scale.
    fn quantized_positions(
        &mut self,
        mesh: &StrokeMesh,
        lo: [f32; 3],
        hi: [f32; 3],
    ) -> (json::Index<json::Accessor>, [f32; 3], [f32; 3]) {
        let scale: [f32; 3] = std::array::from_fn(|axis| {
            let step = (hi[axis] - lo[axis]) / f32::from(u16::MAX);
            if step > 0.0 && step.is_finite() { step } else { 1.0 }
        });
        let inv_scale = scale.map(|step| 1.0 / step);
        let mut q_lo = [u16::MAX; 3];
        let mut q_hi = [0u16; 3];
        let view = self.view(Some(8), json::buffer::Target::ArrayBuffer, |bin| {
            bin.reserve(8 * mesh.positions.len());
            for p in &mesh.positions {
                let q: [u16; 3] = std::array::from_fn(|axis| {
                    // Rounds half up (the value is not negative); `as` saturates, so NaN and
                    // out-of-range values cannot panic.
                    ((p[axis] - lo[axis]) * inv_scale[axis] + 0.5) as u16
                });
                for axis in 0..3 {
                    q_lo[axis] = q_lo[axis].min(q[axis]);
                    q_hi[axis] = q_hi[axis].max(q[axis]);
                }
                let [x, y, z] = q.map(u16::to_le_bytes);
                bin.extend_from_slice(&[x[0], x[1], y[0], y[1], z[0], z[1], 0, 0]);
            }
        });
        let accessor = self.accessor(
            view,
            mesh.positions.len(),
            json::accessor::ComponentType::U16,
            json::accessor::Type::Vec3,
            false,
            json::Value::from(q_lo.to_vec()),
            json::Value::from(q_hi.to_vec()),
        );
        (accessor, lo, scale)
    }

    fn quantized_normals(&mut self, mesh: &StrokeMesh) -> json::Index<json::Accessor> {
        let mut q_lo = [i8::MAX; 3];
        let mut q_hi = [i8::MIN; 3];
        let view = self.view(Some(4), json::buffer::Target::ArrayBuffer, |bin| {
            bin.reserve(4 * mesh.normals.len());
            for n in &mesh.normals {
                let q: [i8; 3] = std::array::from_fn(|axis| {
                    // Rounds half away from zero; `as` truncates towards zero and saturates.
                    (n[axis] * 127.0 + 0.5f32.copysign(n[axis])).clamp(-127.0, 127.0) as i8
                });
                for axis in 0..3 {
                    q_lo[axis] = q_lo[axis].min(q[axis]);
                    q_hi[axis] = q_hi[axis].max(q[axis]);
                }
                let [x, y, z] = q.map(|v| v.to_le_bytes()[0]);
                bin.extend_from_slice(&[x, y, z, 0]);
            }
        });
        self.accessor(
            view,
            mesh.normals.len(),
            json::accessor::ComponentType::I8,
            json::accessor::Type::Vec3,
            true,
            json::Value::from(q_lo.to_vec()),
            json::Value::from(q_hi.to_vec()),
        )
    }

    fn indices(&mut self, mesh: &StrokeMesh) -> json::Index<json::Accessor> {
        let narrow = mesh.positions.len() <= usize::from(u16::MAX);
        let view = self.view(None, json::buffer::Target::ElementArrayBuffer, |bin| {
            if narrow {
                bin.reserve(2 * mesh.indices.len());
                for &i in &mesh.indices {
                    bin.extend_from_slice(&(i as u16).to_le_bytes());
                }
            } else {
                bin.reserve(4 * mesh.indices.len());
                for &i in &mesh.indices {
                    bin.extend_from_slice(&i.to_le_bytes());
                }
            }
        });
        let component = if narrow {
            json::accessor::ComponentType::U16
        } else {
            json::accessor::ComponentType::U32
        };
        let lo = mesh.indices.iter().copied().min().unwrap_or(0);
        let hi = mesh.indices.iter().copied().max().unwrap_or(0);
        self.accessor(
            view,
            mesh.indices.len(),
            component,
            json::accessor::Type::Scalar,
            false,
            json::Value::from(vec![lo]),
            json::Value::from(vec![hi]),
        )
    }

    fn finish(mut self) -> Vec<u8> {
        if !self.bin.is_empty() {
            self.root.push(json::Buffer {
                byte_length: USize64::from(self.bin.len()),
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
        let bin_chunk = if self.bin.is_empty() { 0 } else { 8 + self.bin.len() };
        let total = 12 + 8 + json_bytes.len() + bin_chunk;
        let mut glb = Vec::with_capacity(total);
        glb.extend_from_slice(GLB_MAGIC);
        glb.extend_from_slice(&GLB_VERSION.to_le_bytes());
        glb.extend_from_slice(&(total as u32).to_le_bytes());
        glb.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
        glb.extend_from_slice(&CHUNK_JSON.to_le_bytes());
        glb.extend_from_slice(&json_bytes);
        if !self.bin.is_empty() {
            glb.extend_from_slice(&(self.bin.len() as u32).to_le_bytes());
            glb.extend_from_slice(&CHUNK_BIN.to_le_bytes());
            glb.extend_from_slice(&self.bin);
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
