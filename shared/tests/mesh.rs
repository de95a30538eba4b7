//! The LRPDP solid and its GLB: closed, outward, unit normals on awkward strokes; the GLB read
//! back with the `gltf` crate; the PLY point cloud; and a property test over random strokes.

use penmesh::{
    Brush, CloudOptions, GlbMeta, GlbOptions, GlbStroke, KHR_MESH_QUANTIZATION, MeshStats,
    OutlineOptions, Sample, SolidOptions, StrokeMesh, mesh_defect, outline, point_cloud,
    point_cloud_ply, signed_volume, solid_mesh, stroke_glb, stroke_mesh, strokes_glb,
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
    let big = Brush { size: 30.0, pressure_response: 1.0, min_radius: 0.25 };
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
    // 4N + 2M vertices and 8N - 4 + 4M triangles, M = cap points of both ends.
    let stroke = wave(100);
    let out = outline(&stroke, &Brush::default(), &OutlineOptions::default());
    let mesh = solid_mesh(&out, &SolidOptions::default());
    let n = out.n_samples();
    let m = out.start_cap.len() + out.end_cap.len();
    assert_eq!(n, 100);
    assert_eq!(mesh.stats(), MeshStats { vertices: 4 * n + 2 * m, triangles: 8 * n - 4 + 4 * m });
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

/// Decodes a VEC3 accessor to floats, undoing normalisation (not the node transform).
fn read_vec3(gltf: &gltf::Gltf, accessor: &gltf::Accessor) -> Vec<[f32; 3]> {
    let blob = gltf.blob.as_deref().unwrap();
    let view = accessor.view().unwrap();
    let component = accessor.data_type();
    let size = component.size();
    let stride = view.stride().unwrap_or(3 * size);
    let start = view.offset() + accessor.offset();
    let normalized = accessor.normalized();
    let decode = |at: usize| -> f32 {
        let b = &blob[at..at + size];
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
        .map(|i| std::array::from_fn(|axis| decode(start + i * stride + axis * size)))
        .collect()
}

fn read_indices(gltf: &gltf::Gltf, accessor: &gltf::Accessor) -> Vec<u32> {
    let blob = gltf.blob.as_deref().unwrap();
    let view = accessor.view().unwrap();
    let start = view.offset() + accessor.offset();
    let size = accessor.data_type().size();
    (0..accessor.count())
        .map(|i| {
            let b = &blob[start + i * size..start + (i + 1) * size];
            match size {
                2 => u32::from(u16::from_le_bytes(b.try_into().unwrap())),
                _ => u32::from_le_bytes(b.try_into().unwrap()),
            }
        })
        .collect()
}

/// The mesh of node `node_idx` as decoded from the GLB, with the node's transform applied.
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
    let extras = mesh.extras().as_ref().unwrap();
    let meta: GlbMeta = serde_json::from_str(extras.get()).unwrap();
    (StrokeMesh { positions, normals, indices }, meta)
}

fn wave_mesh(n: usize) -> StrokeMesh {
    stroke_mesh(&wave(n), &Brush::default(), &OutlineOptions::default(), &SolidOptions::default())
}

#[test]
fn plain_glb_loads_with_gltf_and_round_trips_exactly() {
    // The validating gltf loader accepts the file; mesh, counts and extras come back unchanged.
    let mesh = wave_mesh(300);
    let glb = stroke_glb(&mesh, &meta("ada"), &GlbOptions::default());
    let gltf = gltf::Gltf::from_slice(&glb).unwrap();
    assert!(gltf.extensions_required().next().is_none());
    assert_eq!(gltf.meshes().count(), 1);
    let (back, back_meta) = decoded_mesh(&gltf, 0);
    assert_eq!(back_meta, meta("ada"));
    assert_eq!(back.stats(), mesh.stats());
    assert_eq!(back, mesh);
    let positions = gltf.meshes().next().unwrap().primitives().next().unwrap();
    let positions = positions.get(&gltf::Semantic::Positions).unwrap();
    let (lo, hi) = mesh.bounds().unwrap();
    assert_eq!(positions.min().unwrap(), serde_json::json!(lo));
    assert_eq!(positions.max().unwrap(), serde_json::json!(hi));
    // u16 indices: 2 bytes each.
    assert_eq!(
        gltf.meshes().next().unwrap().primitives().next().unwrap().indices().unwrap().size(),
        2
    );
}

#[test]
fn quantized_glb_is_smaller_and_within_one_quantization_step() {
    // KHR_mesh_quantization is declared; positions come back within half a step, normals within 1/127.
    let mesh = wave_mesh(300);
    let plain = stroke_glb(&mesh, &meta("ada"), &GlbOptions::default());
    let glb = stroke_glb(&mesh, &meta("ada"), &GlbOptions::default().quantize(true));
    assert!(glb.len() < plain.len() * 3 / 4, "{} vs {}", glb.len(), plain.len());

    // The validating loader refuses it only because it does not know the required extension.
    match gltf::Gltf::from_slice(&glb) {
        Err(gltf::Error::Validation(errors)) => {
            assert_eq!(errors.len(), 1, "{errors:?}");
            assert_eq!(errors[0].1, gltf::json::validation::Error::Unsupported);
        }
        other => panic!("expected an unsupported-extension error, got {:?}", other.map(|_| ())),
    }
    let gltf = gltf::Gltf::from_slice_without_validation(&glb).unwrap();
    let used: Vec<&str> = gltf.extensions_used().collect();
    let required: Vec<&str> = gltf.extensions_required().collect();
    assert_eq!((used, required), (vec![KHR_MESH_QUANTIZATION], vec![KHR_MESH_QUANTIZATION]));

    let (back, back_meta) = decoded_mesh(&gltf, 0);
    assert_eq!(back_meta, meta("ada"));
    assert_eq!(back.indices, mesh.indices);
    let (lo, hi) = mesh.bounds().unwrap();
    for (got, want) in back.positions.iter().zip(&mesh.positions) {
        for axis in 0..3 {
            let step = (hi[axis] - lo[axis]) / 65535.0;
            let error = (got[axis] - want[axis]).abs();
            assert!(error <= 0.5 * step + 1e-4, "axis {axis}: error {error}, step {step}");
        }
    }
    for (got, want) in back.normals.iter().zip(&mesh.normals) {
        for axis in 0..3 {
            assert!((got[axis] - want[axis]).abs() <= 0.5 / 127.0 + 1e-6);
        }
    }
    // The quantised mesh is still closed and outward.
    assert_eq!(mesh_defect(&back), Ok(()));
    assert!(signed_volume(&back) > 0.0);
}

#[test]
fn several_strokes_give_one_mesh_and_node_each() {
    // Two strokes and an empty one: three nodes, two meshes, counts and extras per stroke.
    let a = wave_mesh(20);
    let b = stroke_mesh(
        &tight_circle(30, 1.0),
        &Brush::default(),
        &OutlineOptions::default(),
        &SolidOptions::default(),
    );
    let empty = StrokeMesh::default();
    let (meta_a, meta_b, meta_empty) = (meta("a"), meta("b"), meta("nobody"));
    let glb = strokes_glb(
        &[
            GlbStroke { mesh: &a, meta: &meta_a },
            GlbStroke { mesh: &empty, meta: &meta_empty },
            GlbStroke { mesh: &b, meta: &meta_b },
        ],
        &GlbOptions::default(),
    );
    let gltf = gltf::Gltf::from_slice(&glb).unwrap();
    assert_eq!((gltf.nodes().count(), gltf.meshes().count()), (3, 2));
    assert_eq!(gltf.scenes().next().unwrap().nodes().count(), 3);
    assert!(gltf.nodes().nth(1).unwrap().mesh().is_none());
    let (back_a, got_a) = decoded_mesh(&gltf, 0);
    let (back_b, got_b) = decoded_mesh(&gltf, 2);
    assert_eq!((back_a.stats(), got_a.author.as_str()), (a.stats(), "a"));
    assert_eq!((back_b.stats(), got_b.author.as_str()), (b.stats(), "b"));
}

#[test]
fn big_meshes_switch_to_u32_indices() {
    // Past 65,535 vertices the indices are u32 and still read back.
    let mesh = wave_mesh(17_000);
    assert!(mesh.stats().vertices > 65_535);
    let gltf =
        gltf::Gltf::from_slice(&stroke_glb(&mesh, &meta("ada"), &GlbOptions::default())).unwrap();
    let primitive = gltf.meshes().next().unwrap().primitives().next().unwrap();
    assert_eq!(primitive.indices().unwrap().size(), 4);
    assert_eq!(read_indices(&gltf, &primitive.indices().unwrap()), mesh.indices);
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
        Brush { size, pressure_response, min_radius }
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
        for quantize in [false, true] {
            let glb = stroke_glb(&mesh, &meta("p"), &GlbOptions::default().quantize(quantize));
            prop_assert!(gltf::Gltf::from_slice_without_validation(&glb).is_ok());
        }
    }
}
