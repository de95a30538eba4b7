//! The print's orientation (docs/print.md, "Orientation"): an "F" drawn on the board reads as an
//! F from above on the bed (its top at the back, +Y; its arms to the right, +X), a stroke on a
//! standing plane stands up (+Z), the solid stays outward and PrusaSlicer finds it manifold.
//! The browser test client/web/test/orientation.mjs checks the same against the page and the GLB.

use std::process::Command;

use penmesh::{Brush, Sample, Solid};
use penmesh_print::{IDENTITY, PrintMesh, PrintOptions, PrintStroke, print_mesh, write_stl};

/// The page's "Front" plane (client/web/src/placement.js FRONT): standing on the board along x.
const FRONT: [f64; 16] =
    [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];

fn line(a: [f64; 2], b: [f64; 2], placement: [f64; 16]) -> PrintStroke {
    let n = 20;
    let raw: Vec<Sample> = (0..n)
        .map(|i| {
            let f = i as f64 / (n - 1) as f64;
            Sample::new(a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), i as f64 * 7.0, 0.6)
        })
        .collect();
    let brush = Brush { size: 16.0, pressure_response: 1.0, min_radius: 0.25, color: None };
    PrintStroke { kept: (0..n).collect(), raw, brush, placement, solid: Solid::ROD }
}

/// An "F" in page pixels (y down): the stem at x = 0, the top arm at y = 0, the middle arm
/// shorter, at y = 150.
fn letter_f() -> Vec<PrintStroke> {
    vec![
        line([0.0, 0.0], [0.0, 300.0], IDENTITY),
        line([0.0, 0.0], [200.0, 0.0], IDENTITY),
        line([0.0, 150.0], [120.0, 150.0], IDENTITY),
    ]
}

/// The X range (mm) of the vertices whose Y lies in `[y0, y1]`.
fn x_range(mesh: &PrintMesh, y0: f32, y1: f32) -> (f32, f32) {
    mesh.positions
        .iter()
        .filter(|p| p[1] >= y0 && p[1] <= y1)
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| (lo.min(p[0]), hi.max(p[0])))
}

#[test]
fn an_f_on_the_board_reads_as_an_f_from_above_the_bed() {
    let mesh = print_mesh(&letter_f(), &PrintOptions::default(), &mut |_, _| {}).unwrap();
    let (lo, hi) = mesh.bounds();
    let (width, depth) = (hi[0] - lo[0], hi[1] - lo[1]);
    assert!(depth > width, "the F is taller ({depth} mm) than wide ({width} mm) on the bed");
    // The back tenth of the bed (+Y) holds the top arm: wide. The front tenth, the stem's foot:
    // narrow, at the left (-X).
    let back = x_range(&mesh, (hi[1] - 0.1 * depth) as f32, hi[1] as f32);
    let front = x_range(&mesh, lo[1] as f32, (lo[1] + 0.1 * depth) as f32);
    assert!(back.1 - back.0 > 0.6 * width as f32, "the top arm at the back: {back:?}");
    assert!(front.1 - front.0 < 0.2 * width as f32, "only the stem at the front: {front:?}");
    assert!(front.1 < (lo[0] + 0.2 * width) as f32, "the stem at the left: {front:?}");
    assert!(mesh.volume() > 0.0, "the solid is wound outward");
}

#[test]
fn a_stroke_on_a_standing_plane_stands_up_on_the_bed() {
    // The F on the board and, beside it, a stroke on the Front plane from its foot up (FRONT
    // takes its plane's y to the session's z, out of the board).
    let mut strokes = letter_f();
    strokes.push(line([300.0, 0.0], [300.0, 200.0], FRONT));
    let mesh = print_mesh(&strokes, &PrintOptions::default(), &mut |_, _| {}).unwrap();
    let (lo, hi) = mesh.bounds();
    // Everything stands on the bed (z = 0 is the lowest corner); the standing stroke reaches up.
    let tall: Vec<_> = mesh.positions.iter().filter(|p| f64::from(p[2]) > lo[2] + 10.0).collect();
    assert!(hi[2] - lo[2] > 40.0, "the standing stroke is {} mm high", hi[2] - lo[2]);
    assert!(
        tall.iter().all(|p| f64::from(p[0]) > lo[0] + 0.5 * (hi[0] - lo[0])),
        "only the standing stroke, right of the F, rises"
    );
    assert!(mesh.volume() > 0.0, "the solid is wound outward");
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("f.stl");
    std::fs::write(&file, write_stl(&mesh)).unwrap();
    let out = Command::new("prusa-slicer")
        .args(["--loglevel", "1", "--info"])
        .arg(&file)
        .output()
        .expect("prusa-slicer runs");
    let info = String::from_utf8_lossy(&out.stdout);
    assert!(info.lines().any(|l| l.trim() == "manifold = yes"), "{info}");
}
