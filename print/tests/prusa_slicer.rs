//! The print through PrusaSlicer's command line (Debian's `prusa-slicer`, installed by
//! scripts/test.sh): `--info` reports the mesh manifold with the volume we computed, and
//! `--export-gcode` slices it; overlapping strokes count once; the longest side is `size_mm`; a
//! hairline stroke comes out at least `min_thickness_mm` thick.

use std::path::Path;
use std::process::Command;

use penmesh::{Brush, Sample, Solid};
use penmesh_print::{
    IDENTITY, PrintError, PrintMesh, PrintOptions, PrintStroke, print_mesh, write_3mf, write_stl,
};

/// A straight stroke from `a` to `b` at pressure `p`, every sample kept.
fn line(a: [f64; 2], b: [f64; 2], p: f64, brush: Brush) -> PrintStroke {
    let n = 20;
    let raw: Vec<Sample> = (0..n)
        .map(|i| {
            let f = i as f64 / (n - 1) as f64;
            Sample::new(a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), i as f64 * 7.0, p)
        })
        .collect();
    PrintStroke { kept: (0..n).collect(), raw, brush, placement: IDENTITY, solid: Solid::ROD }
}

fn brush() -> Brush {
    Brush { size: 20.0, pressure_response: 1.0, min_radius: 0.25, color: None }
}

fn print(strokes: &[PrintStroke], options: &PrintOptions) -> PrintMesh {
    print_mesh(strokes, options, &mut |_, _| {}).unwrap()
}

/// PrusaSlicer's `--info` of a file, as `key = value` lines.
fn slicer_info(file: &Path) -> Vec<(String, String)> {
    let out = slicer().arg("--info").arg(file).output().expect("prusa-slicer runs");
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "prusa-slicer --info {}: {text}", file.display());
    text.lines()
        .filter_map(|l| l.split_once(" = "))
        .map(|(k, v)| (k.trim().to_owned(), v.trim().to_owned()))
        .collect()
}

fn info_value<'a>(info: &'a [(String, String)], key: &str) -> &'a str {
    info.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str()).unwrap_or_else(|| {
        panic!("prusa-slicer --info has no {key}: {info:?}");
    })
}

fn slicer() -> Command {
    let mut command = Command::new("prusa-slicer");
    // Headless: no display is needed for --info and --export-gcode; keep its logging quiet.
    command.arg("--loglevel").arg("1");
    command
}

/// The print's body: three strokes crossing one another and one apart.
fn crossing_board() -> Vec<PrintStroke> {
    vec![
        line([0.0, 0.0], [300.0, 0.0], 0.6, brush()),
        line([0.0, -60.0], [300.0, 60.0], 0.8, brush()),
        line([150.0, -100.0], [150.0, 100.0], 0.5, brush()),
        line([0.0, 200.0], [200.0, 200.0], 0.7, brush()),
    ]
}

#[test]
fn the_print_is_one_manifold_that_prusaslicer_slices_in_stl_and_3mf() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = print(&crossing_board(), &PrintOptions::default());
    let ours = mesh.volume();
    let stl = dir.path().join("board.stl");
    let threemf = dir.path().join("board.3mf");
    std::fs::write(&stl, write_stl(&mesh)).unwrap();
    std::fs::write(&threemf, write_3mf(&mesh).unwrap()).unwrap();
    for file in [&stl, &threemf] {
        let info = slicer_info(file);
        assert_eq!(info_value(&info, "manifold"), "yes", "{}: {info:?}", file.display());
        let volume: f64 = info_value(&info, "volume").parse().unwrap();
        assert!((volume - ours).abs() < 1e-3 * ours, "{}: {volume} vs ours {ours}", file.display());
        // Two bodies: the three crossing strokes are one, the one apart another.
        assert_eq!(info_value(&info, "number_of_parts"), "2", "{}: {info:?}", file.display());
        let gcode = dir.path().join("out.gcode");
        let out =
            slicer().arg("--export-gcode").arg(file).arg("--output").arg(&gcode).output().unwrap();
        assert!(
            out.status.success(),
            "slicing {}: {}",
            file.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        let text = std::fs::read_to_string(&gcode).unwrap();
        assert!(
            text.lines().filter(|l| l.starts_with("G1 ")).count() > 100,
            "{}: too little G-code",
            file.display()
        );
    }
}

/// Writes `mesh` as STL in `dir` and returns PrusaSlicer's `--info` of it.
fn stl_info(dir: &Path, name: &str, mesh: &PrintMesh) -> Vec<(String, String)> {
    let file = dir.join(name);
    std::fs::write(&file, write_stl(mesh)).unwrap();
    slicer_info(&file)
}

#[test]
fn overlapping_strokes_count_once_where_concatenated_shells_count_twice() {
    let dir = tempfile::tempdir().unwrap();
    let stroke = line([0.0, 0.0], [300.0, 40.0], 0.7, brush());
    let single = print(std::slice::from_ref(&stroke), &PrintOptions::default());
    // The same stroke twice has the same bounds, so the same scale: its union is the one stroke.
    let doubled = print(&[stroke.clone(), stroke.clone()], &PrintOptions::default());
    let info = stl_info(dir.path(), "doubled.stl", &doubled);
    assert_eq!(info_value(&info, "manifold"), "yes");
    assert_eq!(info_value(&info, "number_of_parts").trim(), "1", "{info:?}");
    let (one, two) = (single.volume(), doubled.volume());
    assert!((two - one).abs() < 1e-3 * one, "union {two} mm³ vs the stroke alone {one} mm³");
    // The control: the two shells side by side (today's page export) count the volume twice.
    let offset = single.positions.len() as u32;
    let concatenated = PrintMesh {
        positions: [single.positions.clone(), single.positions.clone()].concat(),
        indices: single
            .indices
            .iter()
            .copied()
            .chain(single.indices.iter().map(|i| i + offset))
            .collect(),
    };
    let info = stl_info(dir.path(), "concatenated.stl", &concatenated);
    assert_eq!(info_value(&info, "number_of_parts").trim(), "2", "{info:?}");
    let slicer_volume: f64 = info_value(&info, "volume").parse().unwrap();
    assert!((slicer_volume - 2.0 * one).abs() < 1e-3 * one, "{slicer_volume} vs 2 × {one}");
    // Crossing strokes: the union is one body, with less volume than its strokes apart.
    let crossing = [stroke.clone(), line([150.0, -80.0], [150.0, 120.0], 0.7, brush())];
    let united = print(&crossing, &PrintOptions::default());
    let info = stl_info(dir.path(), "crossing.stl", &united);
    assert_eq!(info_value(&info, "manifold"), "yes");
    assert_eq!(info_value(&info, "number_of_parts").trim(), "1", "{info:?}");
}

#[test]
fn the_longest_side_is_size_mm_read_back_by_an_independent_stl_reader() {
    let dir = tempfile::tempdir().unwrap();
    let options = PrintOptions { size_mm: 42.5, ..PrintOptions::default() };
    let mesh = print(&crossing_board(), &options);
    let bytes = write_stl(&mesh);
    let read = stl_io::read_stl(&mut std::io::Cursor::new(&bytes)).unwrap();
    assert_eq!(read.faces.len(), mesh.indices.len() / 3);
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for v in &read.vertices {
        for axis in 0..3 {
            lo[axis] = lo[axis].min(v[axis]);
            hi[axis] = hi[axis].max(v[axis]);
        }
    }
    let longest = (0..3).map(|a| hi[a] - lo[a]).fold(0.0f32, f32::max);
    assert!((f64::from(longest) - 42.5).abs() < 1e-4, "longest side {longest} mm");
    let info = stl_info(dir.path(), "sized.stl", &mesh);
    let slicer_longest = ["size_x", "size_y", "size_z"]
        .iter()
        .map(|k| info_value(&info, k).parse::<f64>().unwrap())
        .fold(0.0, f64::max);
    assert!((slicer_longest - 42.5).abs() < 1e-4, "prusa-slicer: {slicer_longest} mm");
}

/// The bounds of the vertices of `mesh` whose Y (mm) is below `y_mm` (toward the bed's front:
/// further down the page).
fn bounds_below(mesh: &PrintMesh, y_mm: f32) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in mesh.positions.iter().filter(|p| p[1] < y_mm) {
        for axis in 0..3 {
            lo[axis] = lo[axis].min(p[axis]);
            hi[axis] = hi[axis].max(p[axis]);
        }
    }
    (lo, hi)
}

/// A bold stroke along y = 0 and a hairline (radius 0.01 px) along y = 400.
fn bold_and_hairline(hairline_placement: [f64; 16]) -> Vec<PrintStroke> {
    let hair = Brush { size: 1.0, pressure_response: 1.0, min_radius: 0.01, color: None };
    let mut hairline = line([0.0, 400.0], [200.0, 400.0], 0.01, hair);
    hairline.placement = hairline_placement;
    vec![line([0.0, 0.0], [400.0, 0.0], 0.9, brush()), hairline]
}

#[test]
fn a_hairline_stroke_comes_out_at_least_min_thickness_thick() {
    let dir = tempfile::tempdir().unwrap();
    let half = [0.5, 0.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 200.0, 0.0, 1.0];
    for (name, placement) in [("identity", IDENTITY), ("scaled by 0.5", half)] {
        for min_thickness_mm in [0.8, 1.5] {
            let options = PrintOptions { min_thickness_mm, ..PrintOptions::default() };
            let mesh = print(&bold_and_hairline(placement), &options);
            // The hairline's body is the part in front of the middle of the bed (in mm).
            let (lo, hi) = bounds_below(&mesh, 50.0);
            let thickness = hi[2] - lo[2];
            let width = hi[1] - lo[1];
            let floor = min_thickness_mm as f32 - 1e-4;
            assert!(
                thickness >= floor,
                "{name}: hairline {thickness} mm thick < {min_thickness_mm}"
            );
            assert!(width >= floor, "{name}: hairline {width} mm wide < {min_thickness_mm}");
            let info = stl_info(dir.path(), "hairline.stl", &mesh);
            assert_eq!(info_value(&info, "manifold"), "yes");
            assert_eq!(info_value(&info, "number_of_parts").trim(), "2", "{info:?}");
        }
    }
    // The control: with a floor far below it, the hairline is as thin as drawn.
    let options = PrintOptions { min_thickness_mm: 1e-3, ..PrintOptions::default() };
    let mesh = print(&bold_and_hairline(IDENTITY), &options);
    let (lo, hi) = bounds_below(&mesh, 50.0);
    assert!(hi[2] - lo[2] < 0.05, "unfloored hairline {} mm thick", hi[2] - lo[2]);
}

#[test]
fn a_mirrored_stroke_keeps_its_solid_outward() {
    let mirror = [-1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let board = crossing_board();
    let mirrored: Vec<PrintStroke> =
        board.iter().cloned().map(|s| PrintStroke { placement: mirror, ..s }).collect();
    let (plain, flipped) =
        (print(&board, &PrintOptions::default()), print(&mirrored, &PrintOptions::default()));
    // A mirror image has the same volume, outward (positive): the winding was flipped back.
    assert!(flipped.volume() > 0.0);
    assert!((flipped.volume() - plain.volume()).abs() < 1e-3 * plain.volume());
    let dir = tempfile::tempdir().unwrap();
    assert_eq!(info_value(&stl_info(dir.path(), "mirrored.stl", &flipped), "manifold"), "yes");
}

#[test]
fn bad_input_is_refused_naming_what_is_wrong() {
    let board = crossing_board();
    let err = |strokes: &[PrintStroke], options: PrintOptions| {
        print_mesh(strokes, &options, &mut |_, _| {}).unwrap_err()
    };
    assert_eq!(err(&[], PrintOptions::default()), PrintError::NoStrokes);
    let text = err(&board, PrintOptions { size_mm: -1.0, ..PrintOptions::default() }).to_string();
    assert!(text.contains("size_mm = -1"), "{text}");
    let text =
        err(&board, PrintOptions { size_mm: f64::NAN, ..PrintOptions::default() }).to_string();
    assert!(text.contains("size_mm = NaN"), "{text}");
    let text =
        err(&board, PrintOptions { min_thickness_mm: 30.0, ..PrintOptions::default() }).to_string();
    assert!(text.contains("min_thickness_mm = 30"), "{text}");
    let mut bad = board.clone();
    bad[2].placement[5] = f64::INFINITY;
    assert!(
        err(&bad, PrintOptions::default())
            .to_string()
            .starts_with("stroke 2: its placement has a value")
    );
    let mut flat = board.clone();
    flat[1].placement[10] = 0.0;
    assert_eq!(
        err(&flat, PrintOptions::default()),
        PrintError::BadPlacement { index: 1, reason: "is singular" }
    );
    let mut out_of_range = board;
    out_of_range[3].kept.push(99);
    assert!(err(&out_of_range, PrintOptions::default()).to_string().starts_with("stroke 3: "));
}

#[test]
fn progress_counts_every_stroke_and_every_union() {
    let mut seen = Vec::new();
    print_mesh(&crossing_board(), &PrintOptions::default(), &mut |done, total| {
        seen.push((done, total))
    })
    .unwrap();
    assert_eq!(seen, (1..=7).map(|d| (d, 7)).collect::<Vec<_>>());
}

#[test]
fn the_3mf_model_is_in_millimetres_with_every_vertex_and_triangle() {
    let mesh = print(&crossing_board(), &PrintOptions::default());
    let bytes = write_3mf(&mesh).unwrap();
    let mut zip = zip::ZipArchive::new(std::io::Cursor::new(bytes)).unwrap();
    let mut xml = String::new();
    std::io::Read::read_to_string(&mut zip.by_name(penmesh_print::MODEL_PATH).unwrap(), &mut xml)
        .unwrap();
    assert!(xml.contains(r#"<model unit="millimeter""#));
    assert_eq!(xml.matches("<vertex ").count(), mesh.positions.len());
    assert_eq!(xml.matches("<triangle ").count(), mesh.indices.len() / 3);
    assert!(zip.by_name("[Content_Types].xml").is_ok() && zip.by_name("_rels/.rels").is_ok());
}

#[test]
fn strokes_floored_to_one_thickness_still_unite_into_a_manifold_stl() {
    // A floor above every stroke's radius gives them all one thickness: their tops and bottoms
    // are coplanar where they cross, which Manifold's symbolic perturbation resolves.
    let dir = tempfile::tempdir().unwrap();
    let options = PrintOptions { min_thickness_mm: 6.0, ..PrintOptions::default() };
    let mesh = print(&crossing_board(), &options);
    let info = stl_info(dir.path(), "floored.stl", &mesh);
    assert_eq!(info_value(&info, "manifold"), "yes", "{info:?}");
    assert_eq!(info_value(&info, "number_of_parts").trim(), "2", "{info:?}");
    let thickness: f64 = info_value(&info, "size_z").parse().unwrap();
    assert!(thickness >= 6.0 - 1e-4, "{thickness} mm");
}

/// Whether the polyline through `samples` crosses itself (two segments that are not neighbours
/// meet).
fn crosses_itself(samples: &[Sample]) -> bool {
    let points: Vec<glam::DVec2> = samples.iter().map(Sample::pos).collect();
    let orient = |a: glam::DVec2, b: glam::DVec2, c: glam::DVec2| (b - a).perp_dot(c - a);
    let segments: Vec<_> = points.windows(2).map(|w| (w[0], w[1])).collect();
    segments.iter().enumerate().any(|(i, &(p1, p2))| {
        segments.iter().skip(i + 2).any(|&(q1, q2)| {
            orient(q1, q2, p1) * orient(q1, q2, p2) < 0.0
                && orient(p1, p2, q1) * orient(p1, p2, q2) < 0.0
        })
    })
}

/// The strokes of the first `files` SigComp2011 Dutch signatures (real pen data, read in place
/// from ../shared/data), in px, one signature beside the next, simplified by ACUTS.
fn signatures_board(files: usize) -> Vec<PrintStroke> {
    use penmesh::data_sets::SIGCOMP2011_DUTCH;
    let recordings = SIGCOMP2011_DUTCH.read().expect("the SigComp2011 Dutch data set");
    let scale = SIGCOMP2011_DUTCH.px_per_unit;
    let mut strokes = Vec::new();
    for (column, recording) in recordings.iter().take(files).enumerate() {
        let lo = recording
            .strokes
            .iter()
            .flat_map(|s| s.samples())
            .fold(glam::DVec2::INFINITY, |lo, s| lo.min(s.pos()));
        for stroke in &recording.strokes {
            let raw: Vec<Sample> = stroke
                .samples()
                .iter()
                .map(|s| {
                    let p = (s.pos() - lo) * scale + glam::DVec2::new(column as f64 * 600.0, 0.0);
                    Sample::new(p.x, p.y, s.t, s.p)
                })
                .collect();
            let kept = penmesh::acuts(
                &raw,
                penmesh::DEFAULT_RESAMPLE_DISTANCE,
                &penmesh::AcutsParams::default(),
            )
            .kept;
            strokes.push(PrintStroke {
                raw,
                kept,
                brush: Brush::default(),
                placement: IDENTITY,
                solid: Solid::ROD,
            });
        }
    }
    strokes
}

#[test]
fn real_signatures_whose_strokes_cross_themselves_give_a_manifold_stl() {
    let board = signatures_board(3);
    let crossing = board.iter().filter(|s| crosses_itself(&s.raw)).count();
    assert!(crossing >= 3, "only {crossing} of {} strokes cross themselves", board.len());
    let dir = tempfile::tempdir().unwrap();
    let mut seen = Vec::new();
    let mesh = print_mesh(&board, &PrintOptions::default(), &mut |done, total| {
        seen.push((done, total));
    })
    .unwrap();
    // Strokes cut into pieces still report 2n - 1 steps, rising to the end.
    let total = 2 * board.len() - 1;
    assert!(seen.windows(2).all(|w| w[0].0 < w[1].0) && seen.iter().all(|s| s.1 == total));
    assert_eq!(seen.last(), Some(&(total, total)));
    let ours = mesh.volume();
    assert_eq!(mesh.open_edges(), 0);
    let info = stl_info(dir.path(), "signatures.stl", &mesh);
    assert_eq!(info_value(&info, "manifold"), "yes", "{info:?}");
    let volume: f64 = info_value(&info, "volume").parse().unwrap();
    assert!((volume - ours).abs() < 1e-3 * ours, "prusa-slicer {volume} mm³ vs ours {ours} mm³");
}
