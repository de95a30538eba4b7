use super::container::parse_glb;
use super::*;
use crate::placement::IDENTITY_MATRIX;
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
        solid: crate::solid::Solid::ROD,
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
    let mut b = extras(vec![Sample::new(5.0, 5.0, 0.0, 0.5), Sample::new(5.0, 60.0, 8.0, 0.5)]);
    // A solid (issue 51) comes back exactly too.
    b.solid = crate::solid::Solid::new(crate::solid::SolidKind::Hole, Some(0.1 + 0.2)).unwrap();
    let mirror = [-1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 3.5, -0.0, 7.0, 1.0];
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
    // Written a stroke at a time, the JSON is what one tree of the whole document writes.
    let (json, _) = parse_glb(&glb).unwrap();
    let whole = serde_json::to_vec(&json).unwrap();
    let length = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    assert_eq!(
        String::from_utf8_lossy(&glb[20..20 + length]).trim_end(),
        String::from_utf8_lossy(&whole)
    );
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
