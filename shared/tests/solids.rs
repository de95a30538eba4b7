//! What a stroke becomes (issue 51): a `line` with a depth, a `filled` plate and a `hole`, built
//! from the stroke's outline: closed and outward, their volume the region's area times the
//! depth, the fill rule (non-zero) on a figure eight and a loop drawn twice round, an open
//! stroke refused, and the plate's GLB light on the recorded strokes.

use penmesh::data_sets::{DATA_SETS, px_per_unit};
use penmesh::{
    AcutsParams, Brush, DEFAULT_RESAMPLE_DISTANCE, GeneratorParams, GlbMeta, GlbOptions, Outline,
    OutlineOptions, Polygon, PrismVertices, Sample, Shape, Solid, SolidError, SolidKind,
    StrokeMesh, acuts, filled_region, generate_stroke, ink_region, mesh_defect, mesh_drawn_solid,
    outline, region_area, signed_volume, solid_of_outline, solid_region,
};

fn samples(points: impl IntoIterator<Item = (f64, f64)>) -> Vec<Sample> {
    points
        .into_iter()
        .enumerate()
        .map(|(i, (x, y))| Sample::new(x, y, 8.0 * i as f64, 0.5))
        .collect()
}

/// `turns` times round a circle of radius `radius` about (200, 200).
fn circle(radius: f64, turns: f64) -> Vec<Sample> {
    let n = (120.0 * turns) as usize;
    samples((0..=n).map(|i| {
        let a = turns * std::f64::consts::TAU * i as f64 / n as f64;
        (200.0 + radius * a.cos(), 200.0 + radius * a.sin())
    }))
}

/// A figure eight (a lemniscate of Gerono) of half-width `size`, lobes left and right of
/// (200, 200), back where it began.
fn figure_eight(size: f64) -> Vec<Sample> {
    let n = 240;
    samples((0..=n).map(|i| {
        let t = std::f64::consts::TAU * i as f64 / n as f64;
        (200.0 + size * t.cos(), 200.0 + size * t.sin() * t.cos())
    }))
}

fn stroke_outline(samples: &[Sample]) -> Outline {
    outline(samples, &Brush::default(), &OutlineOptions::default())
}

fn solid(kind: SolidKind, depth: f64) -> Solid {
    Solid::new(kind, Some(depth)).unwrap()
}

/// Whether `point` lies in the region (non-zero winding over every contour).
fn covers(region: &[Polygon], point: [f64; 2]) -> bool {
    let mut winding = 0i32;
    for contour in region.iter().flatten() {
        for i in 0..contour.len() {
            let (a, b) = (contour[i], contour[(i + 1) % contour.len()]);
            let side = (b[0] - a[0]) * (point[1] - a[1]) - (point[0] - a[0]) * (b[1] - a[1]);
            if a[1] <= point[1] && b[1] > point[1] && side > 0.0 {
                winding += 1;
            } else if a[1] > point[1] && b[1] <= point[1] && side < 0.0 {
                winding -= 1;
            }
        }
    }
    winding != 0
}

fn check_closed(mesh: &StrokeMesh, what: &str) {
    mesh_defect(mesh).unwrap_or_else(|e| panic!("{what}: {e:?}"));
}

#[test]
fn a_closed_circle_fills_into_a_plate_of_its_area_times_the_depth() {
    let outline = stroke_outline(&circle(60.0, 1.0));
    let radius = outline.radii[0];
    let region = filled_region(&outline).unwrap();
    assert_eq!(region.len(), 1, "one plate");
    assert_eq!(region[0].len(), 1, "no hole in it");
    let want = std::f64::consts::PI * (60.0 + radius).powi(2);
    let area = region_area(&region);
    assert!((area - want).abs() < 0.01 * want, "area {area} px², a disc of {want}");
    assert!(covers(&region, [200.0, 200.0]));

    let mesh =
        solid_of_outline(&outline, &solid(SolidKind::Filled, 24.0), PrismVertices::Shared).unwrap();
    check_closed(&mesh, "the plate");
    let volume = signed_volume(&mesh);
    assert!((volume - 24.0 * area).abs() < 1e-3 * volume, "volume {volume}, {}", 24.0 * area);
    let (lo, hi) = mesh.bounds().unwrap();
    assert_eq!((lo[2], hi[2]), (0.0, 24.0), "the plate stands on its plane");

    // The same stroke as a line: a ring, its inside empty.
    let ring = ink_region(&outline);
    assert!(!covers(&ring, [200.0, 200.0]));
    assert!(covers(&ring, [260.0, 200.0]));
    let wall =
        solid_of_outline(&outline, &solid(SolidKind::Line, 300.0), PrismVertices::Shared).unwrap();
    check_closed(&wall, "the wall");
    let ring_area = region_area(&ring);
    let want = std::f64::consts::PI * ((60.0 + radius).powi(2) - (60.0 - radius).powi(2));
    assert!((ring_area - want).abs() < 0.02 * want, "ring {ring_area} px², want {want}");
    assert!((signed_volume(&wall) - 300.0 * ring_area).abs() < 1e-3 * 300.0 * ring_area);
}

#[test]
fn a_figure_eight_fills_both_lobes_by_the_non_zero_rule() {
    let outline = stroke_outline(&figure_eight(80.0));
    let region = filled_region(&outline).unwrap();
    // Both lobes (winding +1 and -1) are filled, and so is the crossing.
    for point in [[150.0, 200.0], [250.0, 200.0], [200.0, 200.0]] {
        assert!(covers(&region, point), "{point:?} filled");
    }
    assert!(!covers(&region, [200.0, 260.0]), "above the crossing is outside");
    let mesh =
        solid_of_outline(&outline, &solid(SolidKind::Filled, 10.0), PrismVertices::Shared).unwrap();
    check_closed(&mesh, "the figure eight");
    // A lemniscate of Gerono of half-width a encloses 4 a² / 3 (both lobes).
    let lobes = 4.0 * 80.0 * 80.0 / 3.0;
    let area = region_area(&region);
    assert!(area > lobes && area < 1.3 * lobes, "area {area}, lobes {lobes}");
    assert!((signed_volume(&mesh) - 10.0 * area).abs() < 1e-3 * 10.0 * area);
}

#[test]
fn a_loop_drawn_twice_round_fills_its_middle_as_non_zero_says() {
    // Twice round a circle, the second time a little wider (ending within a width of where it
    // began): the middle winds twice, where even-odd would leave it empty.
    let mut points: Vec<(f64, f64)> = Vec::new();
    for i in 0..=240 {
        let a = std::f64::consts::TAU * i as f64 / 120.0;
        let r = 50.0 + 6.0 * (i as f64 / 240.0);
        points.push((200.0 + r * a.cos(), 200.0 + r * a.sin()));
    }
    let outline = stroke_outline(&samples(points));
    let region = filled_region(&outline).unwrap();
    assert!(covers(&region, [200.0, 200.0]), "the middle, wound twice, is filled");
    assert!(covers(&region, [200.0 + 40.0, 200.0]));
    assert_eq!(region.len(), 1);
    assert_eq!(region[0].len(), 1, "no hole");
}

#[test]
fn an_open_stroke_cannot_be_filled_and_its_hole_is_its_line() {
    let open = stroke_outline(&circle(60.0, 0.75));
    let error = filled_region(&open).unwrap_err();
    let SolidError::Open { gap, allowed } = error else { panic!("{error:?}") };
    assert!((gap - 60.0 * 2f64.sqrt()).abs() < 1.0, "gap {gap}");
    assert!(allowed < gap);
    let message = error.to_string();
    assert!(message.contains("an open stroke cannot be filled"), "{message}");
    assert!(solid_of_outline(&open, &solid(SolidKind::Filled, 5.0), PrismVertices::Flat).is_err());
    // A hole of an open stroke is its ink: a groove, not a disc.
    let hole = solid_region(&open, SolidKind::Hole).unwrap();
    assert_eq!(hole, ink_region(&open));
    // Ends a width apart count as closed.
    let nearly = stroke_outline(&circle(60.0, 0.99));
    assert!(filled_region(&nearly).is_ok());
}

#[test]
fn the_rod_is_todays_mesh_and_a_depth_makes_it_a_straight_wall() {
    let samples = circle(40.0, 0.5);
    let outline = stroke_outline(&samples);
    let rod = solid_of_outline(&outline, &Solid::ROD, PrismVertices::Flat).unwrap();
    assert_eq!(rod, penmesh::solid_mesh(&outline, &penmesh::SolidOptions::default()));
    let wall =
        solid_of_outline(&outline, &solid(SolidKind::Line, 50.0), PrismVertices::Flat).unwrap();
    let (lo, hi) = wall.bounds().unwrap();
    assert_eq!((lo[2], hi[2]), (0.0, 50.0));
    // The flat layout is the shared one with the caps' vertices apart: the same solid.
    let shared =
        solid_of_outline(&outline, &solid(SolidKind::Line, 50.0), PrismVertices::Shared).unwrap();
    assert_eq!(wall.indices.len(), shared.indices.len());
    assert!((signed_volume(&wall) - signed_volume(&shared)).abs() < 1e-6 * signed_volume(&shared));
    for (n, p) in wall.normals.iter().zip(&wall.positions) {
        let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((length - 1.0).abs() < 1e-5, "unit normal at {p:?}");
    }
}

/// Every closed stroke of the recorded data sets and generated 400 px contours, filled: closed, its volume its area times its
/// depth, and its GLB at most 8 KB (the goal for a held-out-sized contour).
#[test]
fn recorded_closed_strokes_fill_into_light_closed_plates() {
    let params = AcutsParams::default();
    let mut strokes: Vec<(String, Vec<Sample>)> = Vec::new();
    for set in DATA_SETS {
        for recording in set.read().unwrap() {
            let scale = px_per_unit(&recording.path);
            for (s, stroke) in recording.strokes.iter().enumerate() {
                let raw = stroke
                    .samples()
                    .iter()
                    .map(|q| Sample::new(q.x * scale, q.y * scale, q.t, q.p));
                strokes.push((format!("{} stroke {s}", recording.name()), raw.collect()));
            }
        }
    }
    // Contours the size of a hand-drawn keychain or cookie cutter: 400 px across.
    for shape in [Shape::Figure8, Shape::Chromosome] {
        for seed in 0..4 {
            let params = GeneratorParams { shape, size: 400.0, seed, ..GeneratorParams::default() };
            let stroke = generate_stroke(&params).unwrap();
            strokes.push((format!("{} seed {seed}", shape.name()), stroke.samples().to_vec()));
        }
    }
    let mut sizes = Vec::new();
    for (what, raw) in &strokes {
        {
            {
                let kept = acuts(raw, DEFAULT_RESAMPLE_DISTANCE, &params).kept;
                let meta = GlbMeta {
                    stroke: uuid::Uuid::nil(),
                    author: String::new(),
                    brush: Brush::default(),
                };
                let filled = solid(SolidKind::Filled, 24.0);
                let Ok(meshed) = mesh_drawn_solid(
                    raw,
                    &kept,
                    &meta,
                    &filled,
                    &OutlineOptions::default(),
                    &GlbOptions::default(),
                ) else {
                    continue;
                };
                let shared =
                    solid_of_outline(&meshed.outline, &filled, PrismVertices::Shared).unwrap();
                check_closed(&shared, what);
                let area = region_area(&filled_region(&meshed.outline).unwrap());
                let volume = signed_volume(&shared);
                assert!((volume - 24.0 * area).abs() <= 1e-3 * 24.0 * area, "{what}: {volume}");
                sizes.push((meshed.glb.len(), what.clone()));
            }
        }
    }
    sizes.sort();
    assert!(sizes.len() >= 10, "only {} closed strokes", sizes.len());
    let (largest, which) = sizes.last().unwrap();
    eprintln!(
        "{} closed strokes (recorded, and generated 400 px across) filled: GLB median {} B, largest {largest} B ({which})",
        sizes.len(),
        sizes[sizes.len() / 2].0
    );
    assert!(*largest <= 8 * 1024, "{which}: {largest} B");
}
