//! LRPDP mesh path for a 1,000-sample stroke: outline, solid mesh and GLB (plain and
//! `KHR_mesh_quantization`), timed separately and end to end. Targets: < 100 µs end to end and
//! a small GLB. Sizes are printed before the timings, for the raw stroke and for its ACUTS
//! simplification (the stroke LRPDP is meant to receive).
//!
//! Run: `cargo bench -p penmesh --bench mesh -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

#[path = "support/cpu_time.rs"]
mod cpu_time;

use cpu_time::ThreadCpuTime;
use criterion::{Criterion, criterion_group, criterion_main};
use penmesh::{
    AcutsParams, Brush, GlbMeta, GlbOptions, OutlineOptions, Sample, SolidOptions, outline,
    simplify, solid_mesh, stroke_glb, stroke_mesh,
};

const N_SAMPLES: usize = 1_000;

/// A deterministic smooth stroke: a wandering curve about 1.5 px between samples, with pressure
/// rising and falling, as a pen at 120 Hz would give after resampling.
fn smooth_stroke(n: usize) -> Vec<Sample> {
    (0..n)
        .map(|i| {
            let s = i as f64;
            let x = 1.5 * s + 12.0 * (s * 0.021).sin();
            let y = 60.0 * (s * 0.013).sin() + 9.0 * (s * 0.047).cos();
            let p = 0.55 + 0.35 * (s * 0.009).sin() * (s * 0.031).cos();
            Sample::new(x, y, s * 8.3, p)
        })
        .collect()
}

fn meta() -> GlbMeta {
    GlbMeta {
        stroke: uuid::Uuid::from_u128(0x1000),
        author: "bench".to_owned(),
        brush: Brush::default(),
    }
}

fn report_sizes(label: &str, stroke: &[Sample]) {
    let (brush, meta) = (Brush::default(), meta());
    let mesh = stroke_mesh(stroke, &brush, &OutlineOptions::default(), &SolidOptions::default());
    let stats = mesh.stats();
    let plain = stroke_glb(&mesh, &meta, &GlbOptions::default()).len();
    let quantized = stroke_glb(&mesh, &meta, &GlbOptions::default().quantize(true)).len();
    println!(
        "{label}: {} samples -> {} vertices, {} triangles; GLB {plain} B plain, {quantized} B \
         quantised",
        stroke.len(),
        stats.vertices,
        stats.triangles,
    );
}

fn bench_mesh(c: &mut Criterion<ThreadCpuTime>) {
    let stroke = smooth_stroke(N_SAMPLES);
    let kept = simplify(&stroke, &AcutsParams::default());
    let simplified: Vec<Sample> = kept.iter().map(|&i| stroke[i]).collect();
    report_sizes("raw stroke", &stroke);
    report_sizes("ACUTS-simplified stroke", &simplified);

    let brush = Brush::default();
    let outline_options = OutlineOptions::default();
    let solid_options = SolidOptions::default();
    let meta = meta();
    let plain = GlbOptions::default();
    let quantized = GlbOptions::default().quantize(true);

    let mut group = c.benchmark_group("lrpdp_1000");
    group.bench_function("outline", |b| {
        b.iter(|| outline(black_box(&stroke), &brush, &outline_options))
    });
    let out = outline(&stroke, &brush, &outline_options);
    group.bench_function("solid_mesh", |b| b.iter(|| solid_mesh(black_box(&out), &solid_options)));
    let mesh = solid_mesh(&out, &solid_options);
    group.bench_function("glb_plain", |b| b.iter(|| stroke_glb(black_box(&mesh), &meta, &plain)));
    group.bench_function("glb_quantized", |b| {
        b.iter(|| stroke_glb(black_box(&mesh), &meta, &quantized))
    });
    for (name, options) in [("end_to_end_plain", plain), ("end_to_end_quantized", quantized)] {
        group.bench_function(name, |b| {
            b.iter(|| {
                let mesh =
                    stroke_mesh(black_box(&stroke), &brush, &outline_options, &solid_options);
                stroke_glb(&mesh, &meta, &options)
            })
        });
    }
    group.bench_function("end_to_end_plain_acuts_simplified", |b| {
        b.iter(|| {
            let mesh =
                stroke_mesh(black_box(&simplified), &brush, &outline_options, &solid_options);
            stroke_glb(&mesh, &meta, &plain)
        })
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().with_measurement(ThreadCpuTime);
    targets = bench_mesh
}
criterion_main!(benches);
