//! `penmesh draw --solid --depth` (issue 51): a keychain made from the command line (a rounded
//! outline filled 3 mm deep, three letters raised 2 mm on it, a small circle as a hole), exported
//! as STL, is one manifold part with a hole through it for PrusaSlicer, of the volume its areas
//! and depths say, and slices; an open stroke filled and a bad depth are refused by name.

use std::collections::HashMap;
use std::path::Path;
use std::process::Command;

use penmesh::{
    Brush, OutlineOptions, Sample, filled_region, fitted_outline, ink_region, region_area,
};

use crate::helpers::{Proxy, json_of, penmesh, run};

/// Size 20, response 1, at pressure 0.5: 10 px of radius, above the print's thickness floor.
const BRUSH: [&str; 4] = ["--brush-size", "20", "--pressure-response", "1"];

/// The points of a polyline, one every 4 px along it.
fn along(corners: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut out = vec![corners[0]];
    for w in corners.windows(2) {
        let (a, b) = (w[0], w[1]);
        let n = ((b[0] - a[0]).hypot(b[1] - a[1]) / 4.0).ceil().max(1.0) as usize;
        out.extend((1..=n).map(|i| {
            let f = i as f64 / n as f64;
            [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])]
        }));
    }
    out
}

/// A closed rounded rectangle from (0, 0) to (w, h), corner radius `r`.
fn rounded_rectangle(w: f64, h: f64, r: f64) -> Vec<[f64; 2]> {
    let mut out = Vec::new();
    for [cx, cy, start] in [[w - r, r, -90.0], [w - r, h - r, 0.0], [r, h - r, 90.0], [r, r, 180.0]]
    {
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

fn samples(points: &[[f64; 2]]) -> Vec<Sample> {
    points.iter().enumerate().map(|(i, p)| Sample::new(p[0], p[1], 8.0 * i as f64, 0.5)).collect()
}

/// A CSV of `strokes`, one `stroke` number each.
fn write_csv(path: &Path, strokes: &[Vec<[f64; 2]>]) {
    let mut text = String::from("stroke,x,y,t,p\n");
    for (k, points) in strokes.iter().enumerate() {
        for s in samples(points) {
            text.push_str(&format!("{k},{},{},{},{}\n", s.x, s.y, s.t, s.p));
        }
    }
    std::fs::write(path, text).unwrap();
}

/// The area (px²) of a stroke's ink, or of the region it encloses with its ink.
fn area(points: &[[f64; 2]], filled: bool) -> f64 {
    let raw = samples(points);
    let brush = Brush { size: 20.0, pressure_response: 1.0, ..Brush::default() };
    let kept: Vec<usize> = (0..raw.len()).collect();
    let outline = fitted_outline(&raw, &kept, &brush, &OutlineOptions::default()).unwrap();
    if filled {
        region_area(&filled_region(&outline).unwrap())
    } else {
        region_area(&ink_region(&outline))
    }
}

fn slicer() -> Command {
    let mut command = Command::new("prusa-slicer");
    command.arg("--loglevel").arg("1");
    command
}

/// PrusaSlicer's `--info` of a file, by key.
fn slicer_info(file: &Path) -> HashMap<String, String> {
    let out = slicer().arg("--info").arg(file).output().expect("prusa-slicer runs");
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "prusa-slicer --info {}: {text}", file.display());
    text.lines()
        .filter_map(|l| l.split_once(" = "))
        .map(|(k, v)| (k.trim().to_owned(), v.trim().to_owned()))
        .collect()
}

/// The Euler characteristic `V - E + F` of a binary STL's surface, its corners joined within
/// 10⁻⁴ mm (the print gives each vertex its own `f32` position, a step apart): 2 for a body
/// with no hole through it, 0 for one with one.
fn stl_euler_characteristic(bytes: &[u8]) -> i64 {
    let n = u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as usize;
    let mut corners: HashMap<[i64; 3], usize> = HashMap::new();
    let mut edges: HashMap<(usize, usize), usize> = HashMap::new();
    for t in 0..n {
        let at = 84 + 50 * t + 12;
        let mut ids = [0usize; 3];
        for (c, id) in ids.iter_mut().enumerate() {
            let f = |k: usize| {
                let o = at + 12 * c + 4 * k;
                f64::from(f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap()))
            };
            let key = [f(0), f(1), f(2)].map(|v| (v * 1e4).round() as i64);
            let next = corners.len();
            *id = *corners.entry(key).or_insert(next);
        }
        for (a, b) in [(ids[0], ids[1]), (ids[1], ids[2]), (ids[2], ids[0])] {
            *edges.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    assert!(edges.values().all(|&k| k == 2), "every edge joins two triangles");
    corners.len() as i64 - edges.len() as i64 + n as i64
}

#[tokio::test]
async fn a_keychain_drawn_with_penmesh_draw_prints_as_one_part_with_a_through_hole() {
    let dir = tempfile::tempdir().unwrap();
    let proxy = Proxy::start(&dir.path().join("p.db"), 0);
    // 400 x 200 px and its ink: 420 px across, printed 60 mm long: 7 px a millimetre.
    let px_per_mm = 7.0;
    let (plate_depth, letter_depth) = (3.0 * px_per_mm, 2.0 * px_per_mm);
    let plate = rounded_rectangle(400.0, 200.0, 40.0);
    let hole = circle([45.0, 100.0], 15.0);
    let letters = vec![
        along(&[[140.0, 150.0], [140.0, 50.0], [190.0, 50.0]]),
        along(&[[230.0, 150.0], [230.0, 50.0]]),
        along(&[[270.0, 150.0], [305.0, 50.0], [340.0, 150.0]]),
    ];
    let files = ["plate", "hole", "letters"].map(|name| dir.path().join(format!("{name}.csv")));
    write_csv(&files[0], std::slice::from_ref(&plate));
    write_csv(&files[1], std::slice::from_ref(&hole));
    write_csv(&files[2], &letters);
    let draw = |file: &Path, extra: &[String]| {
        let out = run(proxy.draw().args(BRUSH).arg("--input").arg(file).args(extra));
        json_of(&out)
    };
    let depth = |d: f64| ["--depth".to_string(), d.to_string()];
    draw(&files[0], &[&["--solid".into(), "filled".into()][..], &depth(plate_depth)].concat());
    draw(&files[1], &[&["--solid".into(), "hole".into()][..], &depth(plate_depth)].concat());
    // The letters on a plane at the plate's top, sunk 1 px into it so that they join it.
    let lifted = format!("1,0,0,0,0,1,0,0,0,0,1,0,0,0,{},1", plate_depth - 1.0);
    let letters_args =
        [&["--placement".to_string(), lifted][..], &depth(letter_depth + 1.0)].concat();
    draw(&files[2], &letters_args);

    let stl = dir.path().join("keychain.stl");
    let out = run(penmesh()
        .args(["export", "--server", &proxy.url, "--session", &proxy.session])
        .args(["--token", &proxy.token, "--format", "stl", "--size-mm", "60", "--out"])
        .arg(&stl));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    let info = slicer_info(&stl);
    assert_eq!(info["manifold"], "yes", "{info:?}");
    assert_eq!(info["number_of_parts"], "1", "{info:?}");
    let bytes = std::fs::read(&stl).unwrap();
    assert_eq!(stl_euler_characteristic(&bytes), 0, "one hole through one body");
    let size: Vec<f64> = ["size_x", "size_y", "size_z"].map(|k| info[k].parse().unwrap()).to_vec();
    let longest = size[0].max(size[1]).max(size[2]);
    let height = size.iter().copied().fold(f64::INFINITY, f64::min);
    assert!((height - 5.0).abs() < 0.15, "the plate and its letters: {height} mm high, {size:?}");
    let k = longest / 420.0;
    let letters_area: f64 = letters.iter().map(|l| area(l, false)).sum();
    let want_px =
        (area(&plate, true) - area(&hole, true)) * plate_depth + letters_area * letter_depth;
    let want = want_px * k.powi(3);
    let volume: f64 = info["volume"].parse().unwrap();
    assert!((volume - want).abs() < 0.05 * want, "volume {volume} mm³, want {want} mm³");

    let gcode = dir.path().join("keychain.gcode");
    let out =
        slicer().arg("--export-gcode").arg(&stl).arg("--output").arg(&gcode).output().unwrap();
    assert!(out.status.success(), "slicing: {}", String::from_utf8_lossy(&out.stderr));
}

#[tokio::test]
async fn an_open_stroke_filled_and_a_bad_depth_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let proxy = Proxy::start(&dir.path().join("p.db"), 0);
    let file = dir.path().join("open.csv");
    write_csv(&file, &[along(&[[0.0, 0.0], [200.0, 0.0], [200.0, 200.0]])]);
    let out =
        run(proxy.draw().arg("--input").arg(&file).args(["--solid", "filled", "--depth", "10"]));
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("an open stroke cannot be filled"), "{stderr}");

    for (args, says) in [
        (&["--solid", "filled"][..], "a filled solid needs a depth"),
        (&["--depth", "-3"][..], "outside [0.125, 10000] px"),
        (&["--solid", "hole", "--depth", "1e9"][..], "outside [0.125, 10000] px"),
    ] {
        let out = run(proxy.draw().arg("--input").arg(&file).args(args));
        assert!(!out.status.success(), "{args:?}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(says), "{args:?}: {stderr}");
    }
    // Nothing was drawn for the refused flags: only the open stroke, a rod with no mesh.
    let strokes: serde_json::Value = reqwest::Client::new()
        .get(format!("{}/v1/sessions/{}/strokes", proxy.url, proxy.session))
        .bearer_auth(&proxy.token)
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let strokes = strokes["strokes"].as_array().unwrap();
    assert_eq!(strokes.len(), 1, "{strokes:?}");
    assert_eq!(strokes[0]["solid"], serde_json::json!({"kind": "line", "depth": null}));
    assert_eq!(strokes[0]["has_mesh"], false);
}
