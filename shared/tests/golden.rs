//! Golden tests: ACUTS and the mesh on the paper's four classic contours (and a scribble), at the
//! paper's 300 px/s on a 150 Hz tablet, compared with the values recorded in
//! `tests/golden/classic_shapes.txt`.
//!
//! A change that moves any count or metric fails here and shows the difference. When the change
//! is intended, regenerate the file with `UPDATE_GOLDEN=1 cargo test -p penmesh --test golden`
//! and commit it with the change, so the review sees the new numbers.

use std::fmt::Write;

use penmesh::{
    AcutsParams, Brush, DEFAULT_RESAMPLE_DISTANCE, GeneratorParams, GlbMeta, GlbOptions,
    OutlineOptions, Shape, SolidOptions, acuts, generate_stroke, simplification_metrics,
    stroke_glb, stroke_mesh,
};

const GOLDEN_PATH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/classic_shapes.txt");

/// One line of the golden file for a shape: counts, metrics (6 decimals) and mesh sizes.
fn golden_line(shape: Shape) -> String {
    let stroke = generate_stroke(&GeneratorParams { shape, seed: 1, ..GeneratorParams::default() })
        .expect("the generator's defaults are valid");
    let samples = stroke.samples();
    let output = acuts(samples, DEFAULT_RESAMPLE_DISTANCE, &AcutsParams::default());
    let m = simplification_metrics(samples, &output.kept).expect("ACUTS keeps valid indices");
    let simplified: Vec<_> = output.kept.iter().map(|&i| samples[i]).collect();
    let mesh = stroke_mesh(
        &simplified,
        &Brush::default(),
        &OutlineOptions::default(),
        &SolidOptions::default(),
    );
    let meta =
        GlbMeta { stroke: uuid::Uuid::nil(), author: "golden".into(), brush: Brush::default() };
    let glb = stroke_glb(&mesh, &meta, &GlbOptions::default());
    let stats = mesh.stats();
    format!(
        "{shape} n={} resampled={} kept={} cr={:.6} e_max={:.6} e_l={:.6} sed={:.6} vertices={} triangles={} glb_bytes={}",
        samples.len(),
        output.resampled.len(),
        output.kept.len(),
        m.cr,
        m.e_max,
        m.e_l,
        m.sed,
        stats.vertices,
        stats.triangles,
        glb.len()
    )
}

#[test]
fn classic_shapes_match_the_recorded_counts_and_metrics() {
    let mut actual = String::new();
    for shape in Shape::ALL {
        writeln!(actual, "{}", golden_line(shape)).unwrap();
    }
    if std::env::var_os("UPDATE_GOLDEN").is_some() {
        std::fs::write(GOLDEN_PATH, &actual).expect("write the golden file");
        return;
    }
    let expected = std::fs::read_to_string(GOLDEN_PATH)
        .expect("tests/golden/classic_shapes.txt exists (UPDATE_GOLDEN=1 makes it)");
    for (line_no, (want, got)) in expected.lines().zip(actual.lines()).enumerate() {
        assert_eq!(got, want, "line {} of the golden file differs", line_no + 1);
    }
    assert_eq!(
        actual.lines().count(),
        expected.lines().count(),
        "the golden file has other shapes"
    );
}

#[test]
fn every_shape_keeps_its_ends_and_stays_within_the_guaranteed_bound() {
    // The guaranteed bound against the unresampled stroke: tolerance plus resample distance.
    let params = AcutsParams::default();
    for shape in Shape::ALL {
        for seed in 0..5 {
            let stroke =
                generate_stroke(&GeneratorParams { shape, seed, ..GeneratorParams::default() })
                    .unwrap();
            let samples = stroke.samples();
            let output = acuts(samples, DEFAULT_RESAMPLE_DISTANCE, &params);
            assert_eq!(output.kept.first(), Some(&0), "{shape} seed {seed}");
            assert_eq!(output.kept.last(), Some(&(samples.len() - 1)), "{shape} seed {seed}");
            let m = simplification_metrics(samples, &output.kept).unwrap();
            let bound = params.tolerance + DEFAULT_RESAMPLE_DISTANCE;
            assert!(m.e_max <= bound + 1e-9, "{shape} seed {seed}: e_max {} > {bound}", m.e_max);
        }
    }
}
