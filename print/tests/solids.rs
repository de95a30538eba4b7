//! Solids in the print (issue 51), through PrusaSlicer's command line: a keychain (a rounded
//! plate filled 3 mm deep, three letters raised 2 mm on it, a small circle as a hole near one
//! edge) is one manifold part with a through-hole, of the volume its areas and depths say, and
//! slices; a cookie cutter (a closed contour as a wall 15 mm tall on a filled 1 mm flange)
//! slices; a print of nothing but holes is refused by name.

use std::path::Path;
use std::process::Command;

use penmesh::{
    Brush, OutlineOptions, Sample, Solid, SolidKind, filled_region, fitted_outline, ink_region,
    region_area,
};
use penmesh_print::{
    IDENTITY, PrintError, PrintMesh, PrintOptions, PrintStroke, print_mesh, write_stl,
};

/// Size 20 at pressure 0.5: a radius of 10 px, above the print's thickness floor.
fn brush() -> Brush {
    Brush { size: 20.0, pressure_response: 1.0, min_radius: 0.25, color: None }
}

/// A stroke through `points` (every sample kept) at pressure 0.5, as `solid`, on the plane
/// `lifted` px above the board.
fn stroke(points: Vec<[f64; 2]>, solid: Solid, lifted: f64) -> PrintStroke {
    let raw: Vec<Sample> = (points.iter().enumerate())
        .map(|(i, p)| Sample::new(p[0], p[1], 8.0 * i as f64, 0.5))
        .collect();
    let mut placement = IDENTITY;
    placement[14] = lifted;
    PrintStroke { kept: (0..raw.len()).collect(), raw, brush: brush(), placement, solid }
}

/// The points of a polyline, one every `step` px along it.
fn along(corners: &[[f64; 2]], step: f64) -> Vec<[f64; 2]> {
    let mut out = vec![corners[0]];
    for w in corners.windows(2) {
        let (a, b) = (w[0], w[1]);
        let n = ((b[0] - a[0]).hypot(b[1] - a[1]) / step).ceil().max(1.0) as usize;
        out.extend((1..=n).map(|i| {
            let f = i as f64 / n as f64;
            [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])]
        }));
    }
    out
}

/// A closed rounded rectangle from (0, 0) to (w, h), corner radius `r`, ending where it began.
fn rounded_rectangle(w: f64, h: f64, r: f64) -> Vec<[f64; 2]> {
    let mut out = Vec::new();
    let corners = [[w - r, r, -90.0], [w - r, h - r, 0.0], [r, h - r, 90.0], [r, r, 180.0]];
    for [cx, cy, start] in corners {
        for i in 0..=12 {
            let a = (start + 90.0 * f64::from(i) / 12.0_f64).to_radians();
            out.push([cx + r * a.cos(), cy + r * a.sin()]);
        }
    }
    out.push(out[0]);
    out
}

fn circle(centre: [f64; 2], r: f64) -> Vec<[f64; 2]> {
    (0..=48)
        .map(|i| {
            let a = std::f64::consts::TAU * f64::from(i) / 48.0;
            [centre[0] + r * a.cos(), centre[1] + r * a.sin()]
        })
        .collect()
}

fn solid(kind: SolidKind, depth: f64) -> Solid {
    Solid::new(kind, Some(depth)).unwrap()
}

/// The region a stroke's solid covers, px² (the outline as the print's stroke mesh has it).
fn area(s: &PrintStroke) -> f64 {
    let outline = fitted_outline(&s.raw, &s.kept, &s.brush, &OutlineOptions::default()).unwrap();
    match s.solid.kind() {
        SolidKind::Line => region_area(&ink_region(&outline)),
        _ => region_area(&filled_region(&outline).unwrap()),
    }
}

fn slicer() -> Command {
    let mut command = Command::new("prusa-slicer");
    command.arg("--loglevel").arg("1");
    command
}

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

/// Writes the STL, checks PrusaSlicer reads one manifold part, and slices it.
fn slices_as_one_part(mesh: &PrintMesh, name: &str) -> Vec<(String, String)> {
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join(format!("{name}.stl"));
    std::fs::write(&stl, write_stl(mesh)).unwrap();
    let info = slicer_info(&stl);
    assert_eq!(info_value(&info, "manifold"), "yes", "{name}: {info:?}");
    assert_eq!(info_value(&info, "number_of_parts"), "1", "{name}: {info:?}");
    let gcode = dir.path().join(format!("{name}.gcode"));
    let out =
        slicer().arg("--export-gcode").arg(&stl).arg("--output").arg(&gcode).output().unwrap();
    assert!(out.status.success(), "slicing {name}: {}", String::from_utf8_lossy(&out.stderr));
    let text = std::fs::read_to_string(&gcode).unwrap();
    assert!(
        text.lines().filter(|l| l.starts_with("G1 ")).count() > 100,
        "{name}: too little G-code"
    );
    info
}

/// The Euler characteristic `V - E + F` of the mesh's indexed surface: 2 for a closed body
/// without a hole through it, 0 for one with one through-hole.
fn euler_characteristic(mesh: &PrintMesh) -> i64 {
    let faces = (mesh.indices.len() / 3) as i64;
    mesh.positions.len() as i64 - faces * 3 / 2 + faces
}

#[test]
fn a_keychain_is_one_manifold_part_with_a_through_hole_of_the_volume_its_areas_say() {
    let size_mm = 60.0;
    // 400 x 200 px with its ink (10 px): 420 px across is 60 mm, 7 px a millimetre.
    let px_per_mm = 420.0 / size_mm;
    let (plate_depth, letter_depth) = (3.0 * px_per_mm, 2.0 * px_per_mm);
    let plate =
        stroke(rounded_rectangle(400.0, 200.0, 40.0), solid(SolidKind::Filled, plate_depth), 0.0);
    let hole = stroke(circle([45.0, 100.0], 15.0), solid(SolidKind::Hole, plate_depth), 0.0);
    // The letters stand on the plate's top, sunk 1 px into it so that they join it.
    let raised = |points| {
        stroke(along(points, 4.0), solid(SolidKind::Line, letter_depth + 1.0), plate_depth - 1.0)
    };
    let letters = vec![
        raised(&[[140.0, 150.0], [140.0, 50.0], [190.0, 50.0]]),
        raised(&[[230.0, 150.0], [230.0, 50.0]]),
        raised(&[[270.0, 150.0], [305.0, 50.0], [340.0, 150.0]]),
    ];
    let mut strokes = vec![plate.clone(), hole.clone()];
    strokes.extend(letters.iter().cloned());

    let options = PrintOptions { size_mm, ..PrintOptions::default() };
    let mesh = print_mesh(&strokes, &options, &mut |_, _| {}).unwrap();
    let (lo, hi) = mesh.bounds();
    let k = (hi[0] - lo[0]) / 420.0; // mm per px of the print
    assert!((k * px_per_mm - 1.0).abs() < 0.02, "{k} mm per px");
    let letters_area: f64 = letters.iter().map(area).sum();
    let want_px =
        area(&plate) * plate_depth - area(&hole) * plate_depth + letters_area * letter_depth;
    let want = want_px * k.powi(3);
    let volume = mesh.volume();
    assert!((volume - want).abs() < 0.05 * want, "volume {volume} mm³, want {want} mm³");
    let height = hi[2] - lo[2];
    assert!((height - 5.0).abs() < 0.1, "plate and letters {height} mm high");
    assert_eq!(euler_characteristic(&mesh), 0, "one body with one hole through it");
    let info = slices_as_one_part(&mesh, "keychain");
    // The picture in docs/print.md: `PENMESH_KEYCHAIN_STL=/tmp/keychain.stl cargo test -p
    // penmesh-print --test solids keychain`, then `node bench/render-print.mjs`.
    if let Some(path) = std::env::var_os("PENMESH_KEYCHAIN_STL") {
        std::fs::write(path, write_stl(&mesh)).unwrap();
    }
    let slicer_volume: f64 = info_value(&info, "volume").parse().unwrap();
    assert!((slicer_volume - volume).abs() < 1e-3 * volume, "{slicer_volume} vs {volume}");

    // Without the hole: no hole through it, and more volume by the hole's.
    let whole = print_mesh(&[vec![plate], letters].concat(), &options, &mut |_, _| {}).unwrap();
    assert_eq!(euler_characteristic(&whole), 2);
    assert!(whole.volume() > volume + 0.9 * area(&hole) * plate_depth * k.powi(3));
}

#[test]
fn a_cookie_cutter_wall_on_a_filled_flange_slices() {
    let px_per_mm = 440.0 / 80.0;
    let flange =
        stroke(circle([200.0, 200.0], 210.0), solid(SolidKind::Filled, 1.0 * px_per_mm), 0.0);
    let mut contour = along(&[[60.0, 200.0], [200.0, 60.0], [340.0, 200.0], [200.0, 340.0]], 4.0);
    contour.extend(along(&[[200.0, 340.0], [60.0, 200.0]], 4.0));
    let wall = stroke(contour, solid(SolidKind::Line, 15.0 * px_per_mm), 0.0);
    let options = PrintOptions { size_mm: 80.0, ..PrintOptions::default() };
    let mesh = print_mesh(&[flange, wall], &options, &mut |_, _| {}).unwrap();
    let (lo, hi) = mesh.bounds();
    assert!((hi[2] - lo[2] - 15.0).abs() < 0.3, "{} mm tall", hi[2] - lo[2]);
    slices_as_one_part(&mesh, "cookie-cutter");
}

#[test]
fn holes_alone_print_nothing_and_say_so() {
    let hole = stroke(circle([45.0, 100.0], 15.0), solid(SolidKind::Hole, 20.0), 0.0);
    let error = print_mesh(&[hole], &PrintOptions::default(), &mut |_, _| {}).unwrap_err();
    assert_eq!(error, PrintError::OnlyHoles);
    assert!(error.to_string().contains("every stroke is a hole"));
    // An open stroke filled is refused, naming the stroke.
    let open = stroke(
        along(&[[0.0, 0.0], [100.0, 0.0], [100.0, 100.0]], 4.0),
        solid(SolidKind::Filled, 5.0),
        0.0,
    );
    let error = print_mesh(&[open], &PrintOptions::default(), &mut |_, _| {}).unwrap_err();
    assert!(error.to_string().starts_with("stroke 0: an open stroke cannot be filled"), "{error}");
}
