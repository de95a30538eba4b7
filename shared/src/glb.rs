//! Binary glTF 2.0 (GLB) export of stroke meshes (LRPDP step 7).
//!
//! One glTF mesh and one node per stroke, all in one scene; each mesh has one triangle primitive
//! with `POSITION` (with `min` and `max`, as glTF requires) and `NORMAL` accessors, interleaved
//! in one buffer view (the position, then the normal), and an indices accessor; the node
//! carries the stroke's [`GlbMeta`] (id, author, brush) in `extras` and its id as `name`.
//! Indices are `u16` when the stroke has at most 65,535 vertices (so no index is the
//! primitive-restart value), `u32` otherwise. The JSON chunk is padded to 4 bytes with spaces,
//! the binary chunk with zeros. A stroke with an empty mesh still gets a node with its
//! metadata, but no mesh. The JSON is most of a small file (about 1.4 KB with the metadata),
//! so it holds nothing a reader does not need.
//!
//! Three encodings ([`GlbEncoding`]):
//! - **Meshopt** (the default): the quantised attributes below, each buffer view compressed with
//!   `EXT_meshopt_compression` (meshoptimizer's codecs through the `meshopt` crate): the
//!   attributes with the vertex codec's version 0 (the header byte `0xa0` the extension
//!   specifies), the indices with the triangle codec. The views lie in a second buffer with no
//!   data, marked `fallback`, so the extension is required as well as used: a reader must
//!   decode (three.js: `GLTFLoader.setMeshoptDecoder(MeshoptDecoder)`). The triangles are first
//!   put in meshoptimizer's vertex cache order and the vertices numbered in the order the
//!   triangles first use them, which is what the codecs compress best: the same mesh, numbered
//!   differently from [`StrokeMesh`].
//! - **Quantized**: `KHR_mesh_quantization` alone (used and required): positions are unsigned
//!   `u16` steps of one grid for all three axes, [`POSITION_STEP`] px unless the stroke's
//!   largest extent needs a coarser one (`extent / 65535`), mapped back by the node's
//!   `translation` (the bounding box's low corner) and uniform `scale` (the step): so a vertex
//!   is within half a step of where it was on each axis (`1/32` px at the default), and the
//!   normals, which a non-uniform scale would skew, keep their directions. Normals are
//!   normalised `i8` (within `0.5 / 127` per component); each is padded to 4 bytes as glTF
//!   requires, 12 bytes a vertex.
//! - **Plain**: `f32` positions and normals, for tools that read neither extension.
//!
//! The `gltf` crate's validating loader refuses both extensions as unsupported;
//! `penmesh-proxy` accepts exactly these two (`proxy/src/glb.rs`).

use gltf_json as json;
use json::validation::{Checked::Valid, USize64};
use serde::{Deserialize, Serialize};

use crate::mesh::StrokeMesh;
use crate::model::Brush;

/// The extension name for quantised attributes.
pub const KHR_MESH_QUANTIZATION: &str = "KHR_mesh_quantization";
/// The extension name for meshoptimizer-compressed buffer views.
pub const EXT_MESHOPT_COMPRESSION: &str = "EXT_meshopt_compression";
/// The grid step of quantised positions, px: a sixteenth of a pixel, the grid the pen's samples
/// are on (`protocol::POSITION_STEP`), so no vertex moves by more than 1/32 px, invisible at
/// 1 px per unit, while the codec sees small deltas (a grid of 1/64 px cost 2 to 4 % more bytes
/// on `../shared/data`).
pub const POSITION_STEP: f32 = 1.0 / 16.0;

pub(crate) const GLB_MAGIC: &[u8; 4] = b"glTF";
const GLB_VERSION: u32 = 2;
pub(crate) const CHUNK_JSON: u32 = 0x4E4F_534A;
pub(crate) const CHUNK_BIN: u32 = 0x004E_4942;
/// The vertex codec version `EXT_meshopt_compression` specifies (header byte `0xa0`); version
/// 1 belongs to the later `KHR_meshopt_compression`.
const MESHOPT_VERTEX_VERSION: i32 = 0;
/// meshoptimizer's default compression level (it only matters from version 1 on).
const MESHOPT_LEVEL: i32 = 2;

/// What a stroke's mesh carries in `extras`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GlbMeta {
    pub stroke: uuid::Uuid,
    pub author: String,
    pub brush: Brush,
}

/// How the attributes and indices are stored (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GlbEncoding {
    /// `f32` attributes: any glTF reader.
    Plain,
    /// `KHR_mesh_quantization`.
    Quantized,
    /// `KHR_mesh_quantization` and `EXT_meshopt_compression`: the lightest, the default.
    #[default]
    Meshopt,
}

/// How the GLB is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GlbOptions {
    pub encoding: GlbEncoding,
}

impl GlbOptions {
    pub fn encoding(mut self, encoding: GlbEncoding) -> GlbOptions {
        self.encoding = encoding;
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
/// The document is planned first (views, accessors, bounds), with each view's bytes encoded as
/// it is planned, then the file is assembled at its exact size.
pub fn strokes_glb(strokes: &[GlbStroke<'_>], options: &GlbOptions) -> Vec<u8> {
    let mut writer = DocumentWriter { encoding: options.encoding, ..Default::default() };
    let extensions: &[&str] = match options.encoding {
        GlbEncoding::Plain => &[],
        GlbEncoding::Quantized => &[KHR_MESH_QUANTIZATION],
        GlbEncoding::Meshopt => &[KHR_MESH_QUANTIZATION, EXT_MESHOPT_COMPRESSION],
    };
    for name in extensions {
        writer.root.extensions_used.push((*name).to_owned());
        writer.root.extensions_required.push((*name).to_owned());
    }
    let mut nodes = Vec::with_capacity(strokes.len());
    for stroke in strokes {
        nodes.push(writer.add_stroke(stroke));
    }
    writer.root.push(json::Scene { extensions: None, extras: None, name: None, nodes });
    writer.root.scene = Some(json::Index::new(0));
    writer.finish()
}

/// The quantisation grid of a mesh's positions: one step for all three axes, from the low
/// corner of its bounding box.
fn position_grid(lo: [f32; 3], hi: [f32; 3]) -> f32 {
    let extent = (0..3).map(|axis| hi[axis] - lo[axis]).fold(0.0f32, f32::max);
    let step = (extent / f32::from(u16::MAX)).max(POSITION_STEP);
    if step.is_finite() { step } else { 1.0 }
}

/// Steps of `step` from `lo`, rounded half up (the value is not negative); `as` saturates, so
/// NaN and out-of-range values cannot panic.
fn quantize_position(value: f32, lo: f32, step: f32) -> u16 {
    ((value - lo) / step + 0.5) as u16
}

/// A normalised `i8`, rounded half away from zero (`as` truncates towards zero).
fn quantize_normal(value: f32) -> i8 {
    (value * 127.0 + 0.5f32.copysign(value)).clamp(-127.0, 127.0) as i8
}

/// A mesh's vertices as one interleaved buffer view: the position, then the normal.
struct Vertices {
    bytes: Vec<u8>,
    /// Bytes per vertex.
    stride: usize,
    /// Where the normal starts in a vertex.
    normal_offset: usize,
    /// The position accessor's `min` and `max` (in steps, when quantised).
    position_bounds: (json::Value, json::Value),
}

/// `f32` positions and normals, 24 bytes a vertex.
fn plain_vertices(mesh: &StrokeMesh, lo: [f32; 3], hi: [f32; 3]) -> Vertices {
    let mut bytes = Vec::with_capacity(24 * mesh.positions.len());
    for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
        bytes.extend(p.iter().chain(n).flat_map(|v| v.to_le_bytes()));
    }
    let bounds = (json::Value::from(lo.to_vec()), json::Value::from(hi.to_vec()));
    Vertices { bytes, stride: 24, normal_offset: 12, position_bounds: bounds }
}

/// Bytes of a quantised vertex.
const QUANTIZED_STRIDE: usize = 12;

/// `u16` position steps of `step` from `lo` (padded to 8 bytes), then the normal as
/// normalised `i8` (padded to 4): [`QUANTIZED_STRIDE`] bytes a vertex.
fn quantized_vertices(mesh: &StrokeMesh, lo: [f32; 3], step: f32) -> Vertices {
    let mut bytes = vec![0; QUANTIZED_STRIDE * mesh.positions.len()];
    let (mut q_lo, mut q_hi) = ([u16::MAX; 3], [0; 3]);
    for ((out, p), n) in
        bytes.chunks_exact_mut(QUANTIZED_STRIDE).zip(&mesh.positions).zip(&mesh.normals)
    {
        for axis in 0..3 {
            let q = quantize_position(p[axis], lo[axis], step);
            (q_lo[axis], q_hi[axis]) = (q_lo[axis].min(q), q_hi[axis].max(q));
            out[2 * axis..2 * axis + 2].copy_from_slice(&q.to_le_bytes());
            out[8 + axis] = quantize_normal(n[axis]).to_le_bytes()[0];
        }
    }
    let bounds = (json::Value::from(q_lo.to_vec()), json::Value::from(q_hi.to_vec()));
    Vertices { bytes, stride: QUANTIZED_STRIDE, normal_offset: 8, position_bounds: bounds }
}

/// Whether `indices` are whole triangles of `n_vertices` vertices: what meshoptimizer's
/// functions need (they read out of bounds otherwise). A [`StrokeMesh`] from
/// [`crate::solid_mesh`] always is; one that is not is written unreordered, its indices
/// uncompressed.
fn whole_triangles(indices: &[u32], n_vertices: usize) -> bool {
    indices.len() % 3 == 0 && indices.iter().all(|&i| (i as usize) < n_vertices)
}

/// The mesh renumbered for meshoptimizer's codecs: triangles in its vertex cache order, then
/// vertices in the order the triangles first use them (any vertex no triangle uses last).
fn codec_order(mesh: &StrokeMesh) -> StrokeMesh {
    let n_vertices = mesh.positions.len().min(mesh.normals.len());
    if !whole_triangles(&mesh.indices, n_vertices) {
        return mesh.clone();
    }
    let mut indices = meshopt::optimize_vertex_cache(&mesh.indices, n_vertices);
    let mut new_index = vec![u32::MAX; n_vertices];
    let mut order = Vec::with_capacity(n_vertices);
    for index in &mut indices {
        let slot = &mut new_index[*index as usize];
        if *slot == u32::MAX {
            *slot = order.len() as u32;
            order.push(*index as usize);
        }
        *index = *slot;
    }
    order.extend((0..n_vertices).filter(|&v| new_index[v] == u32::MAX));
    StrokeMesh {
        positions: order.iter().map(|&v| mesh.positions[v]).collect(),
        normals: order.iter().map(|&v| mesh.normals[v]).collect(),
        indices,
    }
}

/// What one buffer view holds.
enum ViewData<'a> {
    /// Interleaved vertices of `stride` bytes.
    Vertices { bytes: &'a [u8], stride: usize },
    /// Triangle list indices, written as `u16` or `u32` (`size` 2 or 4).
    Triangles { indices: &'a [u32], size: usize, n_vertices: usize },
}

#[derive(Default)]
struct DocumentWriter {
    encoding: GlbEncoding,
    root: json::Root,
    /// The binary chunk: the views (compressed, with `Meshopt`), each at a 4-byte aligned
    /// offset.
    bin: Vec<u8>,
    /// With `Meshopt`: the length of the fallback buffer the views decode into.
    fallback_length: usize,
}

impl DocumentWriter {
    fn add_stroke(&mut self, stroke: &GlbStroke<'_>) -> json::Index<json::Node> {
        let meta = serde_json::value::to_raw_value(stroke.meta).ok();
        let name = Some(stroke.meta.stroke.to_string());
        let mut node = json::Node { extras: meta, name, ..Default::default() };
        let reordered;
        let mesh = if self.encoding == GlbEncoding::Meshopt {
            reordered = codec_order(stroke.mesh);
            &reordered
        } else {
            stroke.mesh
        };
        let Some((lo, hi)) = mesh.bounds().filter(|_| !mesh.is_empty()) else {
            return self.root.push(node);
        };
        let vertices = match self.encoding {
            GlbEncoding::Plain => plain_vertices(mesh, lo, hi),
            GlbEncoding::Quantized | GlbEncoding::Meshopt => {
                let step = position_grid(lo, hi);
                node.translation = Some(lo);
                node.scale = Some([step; 3]);
                quantized_vertices(mesh, lo, step)
            }
        };
        let (position_type, normal_type) = match self.encoding {
            GlbEncoding::Plain => {
                (json::accessor::ComponentType::F32, json::accessor::ComponentType::F32)
            }
            _ => (json::accessor::ComponentType::U16, json::accessor::ComponentType::I8),
        };
        // Both lists are as long in a sound mesh; the vertices written are the pairs.
        let n_vertices = mesh.positions.len().min(mesh.normals.len());
        let view =
            self.view(ViewData::Vertices { bytes: &vertices.bytes, stride: vertices.stride });
        let (min, max) = vertices.position_bounds;
        let positions =
            self.accessor(view, 0, position_type, json::accessor::Type::Vec3, n_vertices);
        let normals = self.accessor(
            view,
            vertices.normal_offset,
            normal_type,
            json::accessor::Type::Vec3,
            n_vertices,
        );
        let position_accessor = &mut self.root.accessors[positions.value()];
        (position_accessor.min, position_accessor.max) = (Some(min), Some(max));
        self.root.accessors[normals.value()].normalized = self.encoding != GlbEncoding::Plain;
        let (size, index_type) = if n_vertices <= usize::from(u16::MAX) {
            (2, json::accessor::ComponentType::U16)
        } else {
            (4, json::accessor::ComponentType::U32)
        };
        let view = self.view(ViewData::Triangles { indices: &mesh.indices, size, n_vertices });
        let indices =
            self.accessor(view, 0, index_type, json::accessor::Type::Scalar, mesh.indices.len());
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
            extras: None,
            name: None,
            primitives: vec![primitive],
            weights: None,
        }));
        self.root.push(node)
    }

    /// Plans a buffer view holding `data`: in the binary chunk, or, with `Meshopt`, in the
    /// fallback buffer, with its compressed bytes in the binary chunk.
    fn view(&mut self, data: ViewData<'_>) -> json::Index<json::buffer::View> {
        let (length, stride, target) = match data {
            ViewData::Vertices { bytes, stride } => {
                (bytes.len(), Some(stride), json::buffer::Target::ArrayBuffer)
            }
            ViewData::Triangles { indices, size, .. } => {
                (size * indices.len(), None, json::buffer::Target::ElementArrayBuffer)
            }
        };
        let mut view = json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(length),
            byte_offset: None,
            byte_stride: stride.map(json::buffer::Stride),
            name: None,
            target: Some(Valid(target)),
            extensions: None,
            extras: None,
        };
        let compress = match data {
            ViewData::Vertices { .. } => true,
            ViewData::Triangles { indices, n_vertices, .. } => whole_triangles(indices, n_vertices),
        };
        if self.encoding == GlbEncoding::Meshopt && compress {
            let (compressed, element, count, mode) = match data {
                // Only quantised vertices are compressed: `QUANTIZED_STRIDE` bytes each.
                ViewData::Vertices { bytes, stride } => {
                    (meshopt_vertices(bytes), stride, bytes.len() / stride, "ATTRIBUTES")
                }
                ViewData::Triangles { indices, size, n_vertices } => {
                    let encoded = meshopt::encode_index_buffer(indices, n_vertices)
                        .expect("meshopt's index encoder cannot fail");
                    (encoded, size, indices.len(), "TRIANGLES")
                }
            };
            let at = self.append_bin(&compressed);
            let extension = serde_json::json!({
                "buffer": 0,
                "byteOffset": at,
                "byteLength": compressed.len(),
                "byteStride": element,
                "count": count,
                "mode": mode,
            });
            view.buffer = json::Index::new(1);
            view.byte_offset = Some(USize64::from(self.fallback_length));
            view.extensions = Some(json::extensions::buffer::View {
                others: [(EXT_MESHOPT_COMPRESSION.to_owned(), extension)].into_iter().collect(),
            });
            self.fallback_length = (self.fallback_length + length).next_multiple_of(4);
        } else {
            let at = match data {
                ViewData::Vertices { bytes, .. } => self.append_bin(bytes),
                ViewData::Triangles { indices, size, .. } => {
                    self.append_bin(&index_bytes(indices, size))
                }
            };
            view.byte_offset = Some(USize64::from(at));
        }
        self.root.push(view)
    }

    /// An accessor reading `count` elements from `offset` in every stride of `view`.
    fn accessor(
        &mut self,
        view: json::Index<json::buffer::View>,
        offset: usize,
        component: json::accessor::ComponentType,
        type_: json::accessor::Type,
        count: usize,
    ) -> json::Index<json::Accessor> {
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: (offset > 0).then(|| USize64::from(offset)),
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: None,
            extras: None,
            type_: Valid(type_),
            min: None,
            max: None,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// Appends `bytes` to the binary chunk, zero-padded to 4 bytes; returns where they start.
    fn append_bin(&mut self, bytes: &[u8]) -> usize {
        let at = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        at
    }

    fn finish(mut self) -> Vec<u8> {
        let bin_length = self.bin.len();
        if bin_length > 0 {
            self.root.push(json::Buffer {
                byte_length: USize64::from(bin_length),
                name: None,
                uri: None,
                extensions: None,
                extras: None,
            });
        }
        if self.fallback_length > 0 {
            let fallback = serde_json::json!({ "fallback": true });
            self.root.push(json::Buffer {
                byte_length: USize64::from(self.fallback_length),
                name: None,
                uri: None,
                extensions: Some(json::extensions::buffer::Buffer {
                    others: [(EXT_MESHOPT_COMPRESSION.to_owned(), fallback)].into_iter().collect(),
                }),
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
            glb.extend_from_slice(&self.bin);
        }
        glb
    }
}

/// Indices as `u16` (`size` 2) or `u32` (4), little-endian.
fn index_bytes(indices: &[u32], size: usize) -> Vec<u8> {
    if size == 2 {
        indices.iter().flat_map(|&i| (i as u16).to_le_bytes()).collect()
    } else {
        indices.iter().flat_map(|i| i.to_le_bytes()).collect()
    }
}

/// Quantised vertices compressed with meshoptimizer's vertex codec, version 0.
fn meshopt_vertices(bytes: &[u8]) -> Vec<u8> {
    let elements: Vec<[u8; QUANTIZED_STRIDE]> = bytes
        .chunks_exact(QUANTIZED_STRIDE)
        .map(|b| b.try_into().expect("whole vertices"))
        .collect();
    meshopt::encode_vertex_buffer_level(&elements, MESHOPT_LEVEL, Some(MESHOPT_VERTEX_VERSION))
        .expect("meshopt's vertex encoder cannot fail")
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
        for encoding in [GlbEncoding::Plain, GlbEncoding::Quantized, GlbEncoding::Meshopt] {
            let glb = stroke_glb(&mesh, &meta(), &GlbOptions::default().encoding(encoding));
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
        // An empty stroke still exports its metadata, with no binary chunk, in every encoding.
        for encoding in [GlbEncoding::Plain, GlbEncoding::Quantized, GlbEncoding::Meshopt] {
            let options = GlbOptions::default().encoding(encoding);
            let glb = stroke_glb(&StrokeMesh::default(), &meta(), &options);
            let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
            assert_eq!(glb.len(), 20 + json_len);
            let doc: serde_json::Value = serde_json::from_slice(&glb[20..]).unwrap();
            assert_eq!(doc["nodes"][0]["extras"]["author"], "ada");
            assert!(doc.get("meshes").is_none() && doc.get("buffers").is_none());
        }
    }

    #[test]
    fn meshes_that_are_not_whole_triangles_are_written_without_reading_out_of_bounds() {
        // meshoptimizer reads past the end of such indices: they are written uncompressed, as
        // given; unused vertices are kept.
        let vertices = |n: usize| (0..n).map(|i| [i as f32, 0.0, 0.0]).collect::<Vec<_>>();
        let normals = |n: usize| vec![[0.0, 0.0, 1.0]; n];
        for (n_vertices, indices) in
            [(4, vec![0, 1, 2, 0, 9, 1]), (4, vec![0, 1, 2, 3]), (5, vec![0, 1, 2])]
        {
            let mesh = StrokeMesh {
                positions: vertices(n_vertices),
                normals: normals(n_vertices),
                indices: indices.clone(),
            };
            let glb = stroke_glb(&mesh, &meta(), &GlbOptions::default());
            let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
            let doc: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
            assert_eq!(doc["accessors"][0]["count"], n_vertices, "{indices:?}");
            assert_eq!(doc["accessors"][2]["count"], indices.len());
            let compressed =
                doc["bufferViews"][1]["extensions"].get(EXT_MESHOPT_COMPRESSION).is_some();
            assert_eq!(compressed, indices.len() == 3, "{indices:?}");
        }
    }

    #[test]
    fn positions_share_one_grid_step_of_a_sixteenth_of_a_pixel() {
        // The node's scale is uniform (a non-uniform one would skew the normals) and is the
        // grid step, unless the stroke is too large for 65,535 of them.
        let line = |length: f64| {
            let samples = [Sample::new(0.0, 0.0, 0.0, 0.5), Sample::new(length, 1.0, 1.0, 0.7)];
            let options = (OutlineOptions::default(), SolidOptions::default());
            stroke_mesh(&samples, &Brush::default(), &options.0, &options.1)
        };
        for length in [100.0, 10_000.0] {
            let mesh = line(length);
            let (lo, hi) = mesh.bounds().unwrap();
            let step = if length < 4000.0 { POSITION_STEP } else { (hi[0] - lo[0]) / 65_535.0 };
            let glb =
                stroke_glb(&mesh, &meta(), &GlbOptions::default().encoding(GlbEncoding::Quantized));
            let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
            let doc: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
            let scale: Vec<f64> = doc["nodes"][0]["scale"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            assert!(
                scale.iter().all(|&s| (s - f64::from(step)).abs() < 1e-6 * f64::from(step)),
                "{scale:?}"
            );
        }
    }
}
