//! The LRPDP solid and its GLB: closed, outward, unit normals on awkward strokes; the GLB read
//! back with the `gltf` crate; the PLY point cloud; and a property test over random strokes.

use penmesh::{
    Brush, CloudOptions, DEFAULT_THICKNESS, EXT_MESHOPT_COMPRESSION, GlbEncoding, GlbMeta,
    GlbOptions, GlbStroke, KHR_MESH_QUANTIZATION, MAX_MERGED_PIECES, MAX_MERGED_TURN_DEG,
    MeshStats, OutlineOptions, PIXEL_TOLERANCE, POSITION_STEP, Sample, SolidOptions, StrokeMesh,
    mesh_defect, outline, point_cloud, point_cloud_ply, signed_volume, solid_mesh, stroke_glb,
    stroke_mesh, strokes_glb, visible_centres,
};
use proptest::prelude::*;

// ---------------------------------------------------------------- strokes

fn samples(points: &[(f64, f64, f64)]) -> Vec<Sample> {
    points.iter().enumerate().map(|(i, &(x, y, p))| Sample::new(x, y, i as f64, p)).collect()
}

/// A smooth wave with varying pressure.
fn wave(n: usize) -> Vec<Sample> {
    (0..n)
        .map(|i| {
            let s = i as f64;
            Sample::new(s * 1.5, 20.0 * (s * 0.05).sin(), s * 8.0, 0.5 + 0.4 * (s * 0.03).cos())
        })
        .collect()
}

/// A circle of radius 1 px, far tighter than the brush radius: the outline overlaps itself.
fn tight_circle(n: usize, turns: f64) -> Vec<Sample> {
    (0..n)
        .map(|i| {
            let a = turns * std::f64::consts::TAU * i as f64 / n as f64;
            Sample::new(a.cos(), a.sin(), i as f64, 1.0)
        })
        .collect()
}

/// Named strokes that have broken stroke meshers before.
fn awkward_strokes() -> Vec<(&'static str, Vec<Sample>)> {
    vec![
        ("one sample", samples(&[(3.0, 4.0, 0.6)])),
        ("two samples", samples(&[(0.0, 0.0, 0.3), (10.0, 5.0, 0.9)])),
        ("two samples very close", samples(&[(0.0, 0.0, 1.0), (1e-6, 0.0, 1.0)])),
        ("cusp", samples(&[(0.0, 0.0, 1.0), (10.0, 0.0, 1.0), (0.0, 0.0, 1.0)])),
        (
            "back and forth",
            samples(&[
                (0.0, 0.0, 1.0),
                (10.0, 0.0, 0.2),
                (0.0, 0.0, 1.0),
                (10.0, 0.0, 0.2),
                (0.0, 0.0, 1.0),
            ]),
        ),
        (
            "repeated points",
            samples(&[
                (0.0, 0.0, 0.5),
                (0.0, 0.0, 0.9),
                (0.0, 0.0, 0.1),
                (5.0, 1.0, 0.5),
                (5.0, 1.0, 0.5),
                (9.0, -2.0, 0.7),
                (9.0, -2.0, 0.7),
            ]),
        ),
        ("all at one point", samples(&[(2.0, 2.0, 0.5), (2.0, 2.0, 0.8), (2.0, 2.0, 0.1)])),
        ("zero pressure", wave(40).into_iter().map(|s| Sample { p: 0.0, ..s }).collect()),
        ("tight circle", tight_circle(40, 1.0)),
        ("tight spiral of three turns", tight_circle(90, 3.0)),
        (
            "sharp zigzag shorter than the radius",
            (0..30).map(|i| Sample::new(i as f64, (i % 2) as f64 * 3.0, i as f64, 1.0)).collect(),
        ),
        ("smooth wave", wave(200)),
    ]
}

fn brushes() -> Vec<(&'static str, Brush, OutlineOptions)> {
    let big = Brush { size: 30.0, pressure_response: 1.0, min_radius: 0.25, color: None };
    vec![
        ("default", Brush::default(), OutlineOptions::default()),
        ("default with miter", Brush::default(), OutlineOptions::default().miter(true)),
        ("big", big, OutlineOptions::default()),
        ("big with miter", big, OutlineOptions::default().miter(true)),
    ]
}

fn meta(author: &str) -> GlbMeta {
    GlbMeta {
        stroke: uuid::Uuid::from_u128(0xfeed),
        author: author.into(),
        brush: Brush::default(),
    }
}

/// Asserts the solid's guarantees: closed, consistently wound, outward, unit normals.
fn assert_sound(mesh: &StrokeMesh, what: &str) {
    assert_eq!(mesh_defect(mesh), Ok(()), "{what}: not closed");
    let volume = signed_volume(mesh);
    assert!(volume > 0.0, "{what}: signed volume {volume}");
    for (vertex, n) in mesh.normals.iter().enumerate() {
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-5, "{what}: normal {vertex} has length {len}");
    }
    assert!(mesh.positions.iter().flatten().all(|v| v.is_finite()), "{what}: non-finite");
}

// ---------------------------------------------------------------- the solid

#[test]
fn awkward_strokes_give_closed_outward_solids_with_unit_normals() {
    // Cusps, repeats, 1 and 2 samples, overlapping curves, zero pressure, with and without miter.
    for (stroke_name, stroke) in awkward_strokes() {
        for (brush_name, brush, options) in brushes() {
            let mesh = stroke_mesh(&stroke, &brush, &options, &SolidOptions::default());
            assert_sound(&mesh, &format!("{stroke_name} / {brush_name}"));
        }
    }
}

#[test]
fn thickness_option_scales_depth_and_volume() {
    // A thicker solid is deeper in z by the same factor and still closed and outward.
    let stroke = wave(50);
    let thin = stroke_mesh(
        &stroke,
        &Brush::default(),
        &OutlineOptions::default(),
        &SolidOptions::default().thickness(0.25),
    );
    let thick = stroke_mesh(
        &stroke,
        &Brush::default(),
        &OutlineOptions::default(),
        &SolidOptions::default().thickness(1.0),
    );
    assert_sound(&thin, "thin");
    assert_sound(&thick, "thick");
    let depth = |m: &StrokeMesh| m.bounds().map(|(lo, hi)| hi[2] - lo[2]).unwrap();
    assert!((depth(&thick) / depth(&thin) - 4.0).abs() < 1e-4);
    assert!((signed_volume(&thick) / signed_volume(&thin) - 4.0).abs() < 1e-3);
}

#[test]
fn counts_follow_the_formula() {
    // 4N + 2M vertices and 8N - 4 + 4M triangles, N = kept centreline points (all of them with
    // a zero tolerance), M = cap points of both ends.
    let stroke = wave(100);
    let out = outline(&stroke, &Brush::default(), &OutlineOptions::default());
    let m = out.start_cap.len() + out.end_cap.len();
    for tolerance in [0.0, PIXEL_TOLERANCE] {
        let options = SolidOptions::default().tolerance(tolerance);
        let mesh = solid_mesh(&out, &options);
        let n = visible_centres(&out, tolerance, options.thickness).len();
        assert_eq!(n == out.n_samples(), tolerance == 0.0, "{n} of {}", out.n_samples());
        let expected = MeshStats { vertices: 4 * n + 2 * m, triangles: 8 * n - 4 + 4 * m };
        assert_eq!(mesh.stats(), expected);
    }
}

/// Checks the rule of the centreline points the solid keeps (`visible_centres`, the module docs
/// of `mesh.rs`) against its statement: the ends kept; every left-out point's rim vertices
/// (x, y and height) within the tolerance of the edges replacing them; at most 45° of turning
/// and 16 pieces per edge; and no edge could have gone one point further.
fn assert_vertex_rule(out: &penmesh::Outline, tolerance: f64, thickness: f64) {
    use glam::DVec3;
    let keep = visible_centres(out, tolerance, thickness);
    let n = out.n_samples();
    if n == 0 {
        assert!(keep.is_empty());
        return;
    }
    assert_eq!((keep[0], *keep.last().unwrap()), (0, n - 1));
    let rim = |side: &[glam::DVec2], k: usize| side[k].extend(thickness * out.radii[k]);
    let distance = |q: DVec3, a: DVec3, b: DVec3| {
        let t = ((q - a).dot(b - a) / (b - a).length_squared().max(1e-300)).clamp(0.0, 1.0);
        q.distance(a + t * (b - a))
    };
    let turning = |from: usize, to: usize| -> f64 {
        penmesh::centreline::polyline_turns(&out.centres[from..=to]).iter().sum()
    };
    let fits = |from: usize, to: usize| {
        to - from <= MAX_MERGED_PIECES
            && turning(from, to) <= MAX_MERGED_TURN_DEG.to_radians() + 1e-12
            && [&out.upper, &out.lower].into_iter().all(|side| {
                (from + 1..to).all(|k| {
                    distance(rim(side, k), rim(side, from), rim(side, to)) <= tolerance + 1e-12
                })
            })
    };
    for pair in keep.windows(2) {
        let (from, to) = (pair[0], pair[1]);
        assert!(from < to);
        assert!(to == from + 1 || fits(from, to), "edge {from} -> {to} breaks the rule");
        if to < n - 1 {
            assert!(!fits(from, to + 1), "edge {from} -> {to} could reach {}", to + 1);
        }
    }
}

#[test]
fn the_solid_keeps_the_fewest_centreline_points_no_pixel_would_miss() {
    // The wave's smooth centreline: the rule holds and leaves points out; with a zero
    // tolerance every point stays.
    let out = outline(&wave(200), &Brush::default(), &OutlineOptions::default());
    assert_vertex_rule(&out, PIXEL_TOLERANCE, DEFAULT_THICKNESS);
    let kept = visible_centres(&out, PIXEL_TOLERANCE, DEFAULT_THICKNESS).len();
    assert!(kept < out.n_samples() * 2 / 3, "{kept} of {}", out.n_samples());
    assert_eq!(visible_centres(&out, 0.0, DEFAULT_THICKNESS).len(), out.n_samples());
}

#[test]
fn vertex_normals_face_the_same_way_as_their_triangles_on_smooth_strokes() {
    // On a stroke without self-overlap, every vertex normal points out of each of its triangles.
    let mesh = stroke_mesh(
        &wave(200),
        &Brush::default(),
        &OutlineOptions::default(),
        &SolidOptions::default(),
    );
    let p = |i: u32| glam::Vec3::from(mesh.positions[i as usize]);
    for [a, b, c] in mesh.triangles() {
        let face = (p(b) - p(a)).cross(p(c) - p(a));
        if face.length() < 1e-4 {
            continue;
        }
        for v in [a, b, c] {
            let n = glam::Vec3::from(mesh.normals[v as usize]);
            assert!(n.dot(face.normalize()) > 0.0, "triangle {a} {b} {c}, vertex {v}");
        }
    }
}

// ---------------------------------------------------------------- GLB read back

const ENCODINGS: [GlbEncoding; 3] =
    [GlbEncoding::Plain, GlbEncoding::Quantized, GlbEncoding::Meshopt];

fn glb_of(mesh: &StrokeMesh, encoding: GlbEncoding) -> Vec<u8> {
    stroke_glb(mesh, &meta("ada"), &GlbOptions::default().encoding(encoding))
}

/// Loads a GLB as a reader that knows the extensions penmesh writes would: the `gltf` crate's
/// validating loader refuses exactly those two as unsupported, and nothing else.
fn load(glb: &[u8]) -> gltf::Gltf {
    match gltf::Gltf::from_slice(glb) {
        Ok(gltf) => gltf,
        Err(gltf::Error::Validation(errors)) => {
            let required: Vec<String> = gltf::Gltf::from_slice_without_validation(glb)
                .unwrap()
                .extensions_required()
                .map(str::to_owned)
                .collect();
            assert_eq!(errors.len(), required.len(), "{errors:?}");
            for (path, error) in &errors {
                assert_eq!(*error, gltf::json::validation::Error::Unsupported, "{path}");
                assert!(path.as_str().starts_with("extensionsRequired"), "{path}");
            }
            gltf::Gltf::from_slice_without_validation(glb).unwrap()
        }
        Err(other) => panic!("not a GLB: {other}"),
    }
}

/// The bytes of a buffer view as a reader sees them: from the BIN chunk, or decoded with
/// meshoptimizer's decoders when the view is compressed with `EXT_meshopt_compression`.
fn view_bytes(gltf: &gltf::Gltf, view: &gltf::buffer::View) -> Vec<u8> {
    let blob = gltf.blob.as_deref().unwrap();
    let Some(ext) = view.extension_value(EXT_MESHOPT_COMPRESSION) else {
        return blob[view.offset()..view.offset() + view.length()].to_vec();
    };
    let number = |key: &str| ext[key].as_u64().unwrap() as usize;
    let (offset, length) = (number("byteOffset"), number("byteLength"));
    let (stride, count) = (number("byteStride"), number("count"));
    assert_eq!(number("buffer"), 0, "compressed data in the BIN chunk");
    assert_eq!(stride * count, view.length(), "the view is what the extension decodes to");
    let data = &blob[offset..offset + length];
    let bytes = match ext["mode"].as_str().unwrap() {
        "ATTRIBUTES" => {
            assert_eq!((stride, data[0]), (12, 0xa0), "quantised vertices, vertex codec 0");
            meshopt::decode_vertex_buffer::<[u8; 12]>(data, count).unwrap().concat()
        }
        "TRIANGLES" => {
            assert_eq!(data[0], 0xe1, "the triangle codec's header");
            match stride {
                2 => meshopt::decode_index_buffer::<u16>(data, count)
                    .unwrap()
                    .iter()
                    .flat_map(|i| i.to_le_bytes())
                    .collect(),
                _ => meshopt::decode_index_buffer::<u32>(data, count)
                    .unwrap()
                    .iter()
                    .flat_map(|i| i.to_le_bytes())
                    .collect(),
            }
        }
        mode => panic!("unexpected mode {mode}"),
    };
    assert_eq!(bytes.len(), view.length());
    bytes
}

/// Decodes a VEC3 accessor to floats, undoing normalisation (not the node transform).
fn read_vec3(gltf: &gltf::Gltf, accessor: &gltf::Accessor) -> Vec<[f32; 3]> {
    let view = accessor.view().unwrap();
    let bytes = view_bytes(gltf, &view);
    let component = accessor.data_type();
    let size = component.size();
    let stride = view.stride().unwrap_or(3 * size);
    let normalized = accessor.normalized();
    let decode = |at: usize| -> f32 {
        let b = &bytes[at..at + size];
        match component {
            gltf::accessor::DataType::F32 => f32::from_le_bytes(b.try_into().unwrap()),
            gltf::accessor::DataType::U16 => {
                let v = f32::from(u16::from_le_bytes(b.try_into().unwrap()));
                if normalized { v / 65535.0 } else { v }
            }
            gltf::accessor::DataType::I8 => {
                let v = f32::from(b[0] as i8);
                if normalized { (v / 127.0).max(-1.0) } else { v }
            }
            other => panic!("unexpected component type {other:?}"),
        }
    };
    (0..accessor.count())
        .map(|i| std::array::from_fn(|axis| decode(accessor.offset() + i * stride + axis * size)))
        .collect()
}

fn read_indices(gltf: &gltf::Gltf, accessor: &gltf::Accessor) -> Vec<u32> {
    let bytes = view_bytes(gltf, &accessor.view().unwrap());
    let size = accessor.data_type().size();
    bytes[accessor.offset()..]
        .chunks_exact(size)
        .take(accessor.count())
        .map(|b| match size {
            2 => u32::from(u16::from_le_bytes(b.try_into().unwrap())),
            _ => u32::from_le_bytes(b.try_into().unwrap()),
        })
        .collect()
}

/// The mesh of node `node_idx` as decoded from the GLB, with the node's transform applied, and
/// the node's metadata.
fn decoded_mesh(gltf: &gltf::Gltf, node_idx: usize) -> (StrokeMesh, GlbMeta) {
    let node = gltf.nodes().nth(node_idx).unwrap();
    let mesh = node.mesh().unwrap();
    let primitive = mesh.primitives().next().unwrap();
    assert_eq!(primitive.mode(), gltf::mesh::Mode::Triangles);
    let (translation, _, scale) = node.transform().decomposed();
    let positions = read_vec3(gltf, &primitive.get(&gltf::Semantic::Positions).unwrap())
        .into_iter()
        .map(|q| std::array::from_fn(|axis| translation[axis] + scale[axis] * q[axis]))
        .collect();
    let normals = read_vec3(gltf, &primitive.get(&gltf::Semantic::Normals).unwrap());
    let indices = read_indices(gltf, &primitive.indices().unwrap());
    let extras = node.extras().as_ref().unwrap();
    let meta: GlbMeta = serde_json::from_str(extras.get()).unwrap();
    (StrokeMesh { positions, normals, indices }, meta)
}

/// The triangles as vertex triples (position and normal bits), each turned so that its
/// smallest vertex comes first (the winding kept), sorted: the mesh whatever its numbering.
fn canonical_triangles(mesh: &StrokeMesh) -> Vec<[[u32; 6]; 3]> {
    let vertex = |i: u32| -> [u32; 6] {
        let (p, n) = (mesh.positions[i as usize], mesh.normals[i as usize]);
        [p[0], p[1], p[2], n[0], n[1], n[2]].map(f32::to_bits)
    };
    let mut triangles: Vec<[[u32; 6]; 3]> = mesh
        .triangles()
        .map(|t| {
            let v = t.map(vertex);
            let first = (0..3).min_by_key(|&k| v[k]).unwrap();
            [v[first], v[(first + 1) % 3], v[(first + 2) % 3]]
        })
        .collect();
    triangles.sort_unstable();
    triangles
}

fn wave_mesh(n: usize) -> StrokeMesh {
    stroke_mesh(&wave(n), &Brush::default(), &OutlineOptions::default(), &SolidOptions::default())
}

#[test]
fn plain_glb_loads_with_gltf_and_round_trips_exactly() {
    // The validating gltf loader accepts the file; mesh, counts and extras come back unchanged.
    let mesh = wave_mesh(300);
    let glb = glb_of(&mesh, GlbEncoding::Plain);
    let gltf = gltf::Gltf::from_slice(&glb).unwrap();
    assert!(gltf.extensions_used().next().is_none());
    assert_eq!(gltf.meshes().count(), 1);
    let (back, back_meta) = decoded_mesh(&gltf, 0);
    assert_eq!(back_meta, meta("ada"));
    assert_eq!(back, mesh);
    let primitive = gltf.meshes().next().unwrap().primitives().next().unwrap();
    let positions = primitive.get(&gltf::Semantic::Positions).unwrap();
    let (lo, hi) = mesh.bounds().unwrap();
    assert_eq!(positions.min().unwrap(), serde_json::json!(lo));
    assert_eq!(positions.max().unwrap(), serde_json::json!(hi));
    // u16 indices: 2 bytes each.
    assert_eq!(primitive.indices().unwrap().size(), 2);
}

#[test]
fn quantized_glb_is_within_half_a_grid_step_and_declares_the_extension() {
    // KHR_mesh_quantization alone: positions come back within half of the uniform grid step
    // (1/32 px), normals within 0.5/127 per component, indices unchanged.
    let mesh = wave_mesh(300);
    let glb = glb_of(&mesh, GlbEncoding::Quantized);
    assert!(glb.len() < glb_of(&mesh, GlbEncoding::Plain).len() * 3 / 4);
    let gltf = load(&glb);
    let used: Vec<&str> = gltf.extensions_used().collect();
    let required: Vec<&str> = gltf.extensions_required().collect();
    assert_eq!((used, required), (vec![KHR_MESH_QUANTIZATION], vec![KHR_MESH_QUANTIZATION]));
    let (_, _, scale) = gltf.nodes().next().unwrap().transform().decomposed();
    assert_eq!(scale, [POSITION_STEP; 3]);

    let (back, back_meta) = decoded_mesh(&gltf, 0);
    assert_eq!(back_meta, meta("ada"));
    assert_eq!(back.indices, mesh.indices);
    assert_within_quantization(&back, &mesh);
}

/// Positions within half a grid step (and the rounding of the translation), normals within
/// half a step of a normalised `i8`; the mesh still closed and outward.
fn assert_within_quantization(back: &StrokeMesh, mesh: &StrokeMesh) {
    assert_eq!(back.stats(), mesh.stats());
    for (got, want) in back.positions.iter().zip(&mesh.positions) {
        for axis in 0..3 {
            let error = (got[axis] - want[axis]).abs();
            assert!(error <= 0.5 * POSITION_STEP + 1e-4, "axis {axis}: error {error}");
        }
    }
    for (got, want) in back.normals.iter().zip(&mesh.normals) {
        for axis in 0..3 {
            assert!((got[axis] - want[axis]).abs() <= 0.5 / 127.0 + 1e-6);
        }
    }
    assert_eq!(mesh_defect(back), Ok(()));
    assert!(signed_volume(back) > 0.0);
}

#[test]
fn meshopt_glb_decodes_to_the_quantized_mesh() {
    // EXT_meshopt_compression over KHR_mesh_quantization, both used and required, every view
    // compressed (vertex codec 0, triangle codec) in a fallback buffer; decoded with
    // meshoptimizer's decoders it is the quantised mesh, renumbered, and is far smaller.
    let mesh = wave_mesh(300);
    let glb = glb_of(&mesh, GlbEncoding::Meshopt);
    let quantized = glb_of(&mesh, GlbEncoding::Quantized);
    assert!(glb.len() < quantized.len() * 2 / 3, "{} vs {}", glb.len(), quantized.len());
    let gltf = load(&glb);
    let both = vec![KHR_MESH_QUANTIZATION, EXT_MESHOPT_COMPRESSION];
    assert_eq!(gltf.extensions_used().collect::<Vec<_>>(), both);
    assert_eq!(gltf.extensions_required().collect::<Vec<_>>(), both);
    let fallback = gltf.buffers().nth(1).unwrap();
    assert_eq!(fallback.extension_value(EXT_MESHOPT_COMPRESSION).unwrap()["fallback"], true);
    assert!(
        gltf.views().all(
            |v| v.buffer().index() == 1 && v.extension_value(EXT_MESHOPT_COMPRESSION).is_some()
        )
    );

    let (back, back_meta) = decoded_mesh(&gltf, 0);
    assert_eq!(back_meta, meta("ada"));
    let (plain_back, _) = decoded_mesh(&load(&quantized), 0);
    assert_eq!(canonical_triangles(&back), canonical_triangles(&plain_back));
    assert_eq!(back.stats(), mesh.stats());
    assert_eq!(mesh_defect(&back), Ok(()));
    assert!(signed_volume(&back) > 0.0);
}

#[test]
fn several_strokes_give_one_mesh_and_node_each() {
    // Two strokes and an empty one: three nodes, two meshes, counts and extras per stroke, in
    // every encoding.
    let a = wave_mesh(20);
    let b = stroke_mesh(
        &tight_circle(30, 1.0),
        &Brush::default(),
        &OutlineOptions::default(),
        &SolidOptions::default(),
    );
    let empty = StrokeMesh::default();
    let (meta_a, meta_b, meta_empty) = (meta("a"), meta("b"), meta("nobody"));
    for encoding in ENCODINGS {
        let glb = strokes_glb(
            &[
                GlbStroke { mesh: &a, meta: &meta_a },
                GlbStroke { mesh: &empty, meta: &meta_empty },
                GlbStroke { mesh: &b, meta: &meta_b },
            ],
            &GlbOptions::default().encoding(encoding),
        );
        let gltf = load(&glb);
        assert_eq!((gltf.nodes().count(), gltf.meshes().count()), (3, 2));
        assert_eq!(gltf.scenes().next().unwrap().nodes().count(), 3);
        assert!(gltf.nodes().nth(1).unwrap().mesh().is_none());
        let (back_a, got_a) = decoded_mesh(&gltf, 0);
        let (back_b, got_b) = decoded_mesh(&gltf, 2);
        assert_eq!((back_a.stats(), got_a.author.as_str()), (a.stats(), "a"));
        assert_eq!((back_b.stats(), got_b.author.as_str()), (b.stats(), "b"));
        assert_eq!((mesh_defect(&back_a), mesh_defect(&back_b)), (Ok(()), Ok(())));
    }
}

#[test]
fn big_meshes_switch_to_u32_indices() {
    // Past 65,535 vertices the indices are u32 (and compressed with a 4-byte stride) and still
    // read back.
    let mesh = stroke_mesh(
        &wave(17_000),
        &Brush::default(),
        &OutlineOptions::default(),
        &SolidOptions::default().tolerance(0.0),
    );
    assert!(mesh.stats().vertices > 65_535);
    for encoding in [GlbEncoding::Plain, GlbEncoding::Meshopt] {
        let gltf = load(&glb_of(&mesh, encoding));
        let primitive = gltf.meshes().next().unwrap().primitives().next().unwrap();
        assert_eq!(primitive.indices().unwrap().size(), 4);
        let (back, _) = decoded_mesh(&gltf, 0);
        assert_eq!(back.stats(), mesh.stats());
        if encoding == GlbEncoding::Plain {
            assert_eq!(back.indices, mesh.indices);
        }
    }
}

// ---------------------------------------------------------------- PLY

#[test]
fn ply_header_declares_the_point_count_and_the_body_matches() {
    // Binary little-endian PLY: header names N vertices with 6 floats; body is 24 N bytes.
    let out = outline(&wave(50), &Brush::default(), &OutlineOptions::default());
    let cloud = point_cloud(&out, &CloudOptions::default());
    assert_eq!(cloud.len(), 9 * out.n_closed());
    let ply = point_cloud_ply(&cloud);
    let header_end = ply.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let header = std::str::from_utf8(&ply[..header_end]).unwrap();
    let lines: Vec<&str> = header.lines().collect();
    assert_eq!(lines[0], "ply");
    assert_eq!(lines[1], "format binary_little_endian 1.0");
    assert!(lines.contains(&format!("element vertex {}", cloud.len()).as_str()));
    let properties: Vec<&str> =
        lines.iter().filter_map(|l| l.strip_prefix("property float ")).collect();
    assert_eq!(properties, ["x", "y", "z", "nx", "ny", "nz"]);
    assert_eq!(ply.len() - header_end, 24 * cloud.len());
    // The first record is the first point of the z = 0 layer.
    let first: Vec<f32> = ply[header_end..header_end + 24]
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    let p = cloud.points[0];
    assert_eq!(&first[..3], &[p.x as f32, p.y as f32, p.z as f32]);
}

// ---------------------------------------------------------------- properties

/// Random strokes: positions on a coarse grid (so repeats and exact reversals happen) or free.
fn arb_stroke() -> impl Strategy<Value = Vec<Sample>> {
    let point = prop_oneof![
        (-4i32..4, -4i32..4).prop_map(|(x, y)| (f64::from(x) * 3.0, f64::from(y) * 3.0)),
        (-500.0..500.0f64, -500.0..500.0f64),
    ];
    prop::collection::vec((point, 0.0..=1.0f64), 0..60).prop_map(|points| {
        points
            .into_iter()
            .enumerate()
            .map(|(i, ((x, y), p))| Sample::new(x, y, i as f64, p))
            .collect()
    })
}

fn arb_brush() -> impl Strategy<Value = Brush> {
    (0.0..60.0f64, 0.0..=1.0f64, 0.001..5.0f64).prop_map(|(size, pressure_response, min_radius)| {
        Brush { size, pressure_response, min_radius, color: None }
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    // Any finite stroke gives a closed, outward mesh with unit normals and a loadable GLB.
    #[test]
    fn random_strokes_give_sound_meshes(
        stroke in arb_stroke(),
        brush in arb_brush(),
        miter in any::<bool>(),
        thickness in 0.01..2.0f64,
    ) {
        let options = OutlineOptions::default().miter(miter);
        let mesh = stroke_mesh(&stroke, &brush, &options, &SolidOptions::default().thickness(thickness));
        if stroke.is_empty() {
            prop_assert!(mesh.is_empty());
        } else {
            assert_sound(&mesh, "random stroke");
        }
        assert_vertex_rule(&outline(&stroke, &brush, &options), PIXEL_TOLERANCE, thickness);
        // Every encoding loads; the compressed one decodes to the quantised one.
        let decoded = ENCODINGS.map(|encoding| {
            let gltf = load(&glb_of(&mesh, encoding));
            (!mesh.is_empty()).then(|| decoded_mesh(&gltf, 0).0)
        });
        if let [Some(plain), Some(quantized), Some(compressed)] = &decoded {
            prop_assert_eq!(plain, &mesh);
            prop_assert_eq!(canonical_triangles(compressed), canonical_triangles(quantized));
        }
    }
}
