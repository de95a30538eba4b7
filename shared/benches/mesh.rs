//! LRPDP mesh path for a 1,000-sample stroke: outline, solid mesh and GLB (plain,
//! `KHR_mesh_quantization`, and meshopt-compressed, the default), timed separately and end to end, with the smooth centreline (the
//! default) and the paper's straight one. Targets: < 100 µs end to end and a GLB of at most
//! 16 KB. Sizes are printed before the timings, for the raw stroke and for its ACUTS
//! simplification (the stroke LRPDP is meant to receive).
//!
//! Besides the generated stroke, the longest stroke of a real recording is measured when it is
//! there: `PENMESH_BENCH_STROKE` (an .hwr, .txt, .csv or .json file; SigComp2011 and SVC2004
//! tablet units are converted to px as `penmesh-lab eval` does), by default the 945-sample stroke of
//! `../shared/data/sigcomp2011_dutch/002_177_02.hwr` next to the checkout.
//!
//! Run: `cargo bench -p penmesh --bench mesh -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;
use std::path::PathBuf;

#[path = "support/cpu_time.rs"]
mod cpu_time;

use cpu_time::ThreadCpuTime;
use criterion::{Criterion, criterion_group, criterion_main};
use penmesh::{
    AcutsParams, Brush, GlbEncoding, GlbMeta, GlbOptions, OutlineOptions, Sample, SolidOptions,
    fitted_outline, outline, simplify, solid_mesh, stroke_glb, stroke_mesh,
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

/// The longest stroke of the real recording, in px, if the file is there.
fn real_stroke() -> Option<(String, Vec<Sample>)> {
    let path = std::env::var_os("PENMESH_BENCH_STROKE")
        .map(PathBuf::from)
        .unwrap_or_else(|| penmesh::data_sets::SIGCOMP2011_DUTCH.dir().join("002_177_02.hwr"));
    let text = std::fs::read_to_string(&path).ok()?;
    let name = path.file_name()?.to_str()?.to_owned();
    let strokes = penmesh::read_strokes(&name, &text).ok()?;
    // Px per tablet unit: SigComp2011 at 5080 lines per inch, SVC2004 at 2540 (see eval).
    let scale = penmesh::data_sets::px_per_unit(&path);
    let longest = strokes.iter().max_by_key(|s| s.len())?;
    let samples =
        longest.samples().iter().map(|s| Sample { x: s.x * scale, y: s.y * scale, ..*s }).collect();
    Some((name, samples))
}

fn meta() -> GlbMeta {
    GlbMeta {
        stroke: uuid::Uuid::from_u128(0x1000),
        author: "bench".to_owned(),
        brush: Brush::default(),
    }
}

fn report_sizes(label: &str, stroke: &[Sample], options: &OutlineOptions) {
    let (brush, meta) = (Brush::default(), meta());
    let out = outline(stroke, &brush, options);
    let mesh = solid_mesh(&out, &SolidOptions::default());
    let stats = mesh.stats();
    let size = |encoding| stroke_glb(&mesh, &meta, &GlbOptions::default().encoding(encoding)).len();
    let plain = size(GlbEncoding::Plain);
    let quantized = size(GlbEncoding::Quantized);
    let meshopt = size(GlbEncoding::Meshopt);
    println!(
        "{label}: {} samples -> {} centreline points, {} vertices, {} triangles; GLB {plain} B \
         plain, {quantized} B quantised, {meshopt} B meshopt",
        stroke.len(),
        out.n_samples(),
        stats.vertices,
        stats.triangles,
    );
}

fn bench_mesh(c: &mut Criterion<ThreadCpuTime>) {
    let stroke = smooth_stroke(N_SAMPLES);
    let kept = simplify(&stroke, &AcutsParams::default());
    let simplified: Vec<Sample> = kept.iter().map(|&i| stroke[i]).collect();
    let smooth = OutlineOptions::default();
    let straight = OutlineOptions::paper();
    for (name, options) in [("smooth", &smooth), ("straight", &straight)] {
        report_sizes(&format!("raw stroke, {name}"), &stroke, options);
        report_sizes(&format!("ACUTS-simplified stroke, {name}"), &simplified, options);
    }

    let brush = Brush::default();
    let solid_options = SolidOptions::default();
    let meta = meta();
    let plain = GlbOptions::default().encoding(GlbEncoding::Plain);
    let quantized = GlbOptions::default().encoding(GlbEncoding::Quantized);
    let meshopt = GlbOptions::default();

    let mut group = c.benchmark_group("lrpdp_1000");
    group.bench_function("outline", |b| b.iter(|| outline(black_box(&stroke), &brush, &smooth)));
    let out = outline(&stroke, &brush, &smooth);
    group.bench_function("solid_mesh", |b| b.iter(|| solid_mesh(black_box(&out), &solid_options)));
    let mesh = solid_mesh(&out, &solid_options);
    group.bench_function("glb_plain", |b| b.iter(|| stroke_glb(black_box(&mesh), &meta, &plain)));
    group.bench_function("glb_quantized", |b| {
        b.iter(|| stroke_glb(black_box(&mesh), &meta, &quantized))
    });
    group.bench_function("glb_meshopt", |b| {
        b.iter(|| stroke_glb(black_box(&mesh), &meta, &meshopt))
    });
    for (name, options) in [
        ("end_to_end_plain", plain),
        ("end_to_end_quantized", quantized),
        ("end_to_end_meshopt", meshopt),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| {
                let mesh = stroke_mesh(black_box(&stroke), &brush, &smooth, &solid_options);
                stroke_glb(&mesh, &meta, &options)
            })
        });
    }
    for (name, options) in [
        ("end_to_end_plain_acuts_simplified", &smooth),
        ("end_to_end_plain_acuts_simplified_straight", &straight),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| {
                let mesh = stroke_mesh(black_box(&simplified), &brush, options, &solid_options);
                stroke_glb(&mesh, &meta, &plain)
            })
        });
    }
    group.finish();

    let Some((name, real)) = real_stroke() else {
        println!("no real stroke (set PENMESH_BENCH_STROKE): the lrpdp_real group is not run");
        return;
    };
    let kept = simplify(&real, &AcutsParams::default());
    let simplified: Vec<Sample> = kept.iter().map(|&i| real[i]).collect();
    for (label, options) in [("smooth", &smooth), ("straight", &straight)] {
        report_sizes(&format!("{name} longest stroke, ACUTS, {label}"), &simplified, options);
    }
    let mut group = c.benchmark_group("lrpdp_real");
    for (label, options) in [("straight", &straight), ("smooth", &smooth)] {
        group.bench_function(format!("end_to_end_plain_acuts_{label}"), |b| {
            b.iter(|| {
                let mesh = stroke_mesh(black_box(&simplified), &brush, options, &solid_options);
                stroke_glb(&mesh, &meta, &plain)
            })
        });
    }
    // What the client, `penmesh mesh` and the proxy run: the smooth centreline checked against
    // the raw samples, the compressed GLB (and the plain one, to compare).
    for (label, options) in [("plain", plain), ("meshopt", meshopt)] {
        group.bench_function(format!("end_to_end_{label}_acuts_smooth_checked"), |b| {
            b.iter(|| {
                let out = fitted_outline(black_box(&real), &kept, &brush, &smooth)
                    .expect("ACUTS keeps increasing indices");
                stroke_glb(&solid_mesh(&out, &solid_options), &meta, &options)
            })
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().with_measurement(ThreadCpuTime);
    targets = bench_mesh
}
criterion_main!(benches);
