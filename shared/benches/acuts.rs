//! ACUTS stage 1 + 2 together ([`penmesh::acuts`] with the default parameters), on strokes of
//! 1,000 to 1,000,000 samples: a pen-like curvy stroke and a straight line. Throughput is in
//! input samples per second; the target is at least 50 million per second on one core. The
//! paper's table 3 setting (`paper-*`) and the defaults before the pressure interpolation test
//! (`former-*`) run in the same process for comparison.
//! The kept counts are printed before the timings.
//!
//! Run: `cargo bench -p penmesh --bench acuts -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

#[path = "support/cpu_time.rs"]
mod cpu_time;

use cpu_time::ThreadCpuTime;
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use penmesh::{
    AcutsParams, DEFAULT_RESAMPLE_DISTANCE, PAPER_RESAMPLE_DISTANCE, PressureGate, Sample, acuts,
};
use rand::rngs::StdRng;
use rand::{Rng as _, SeedableRng};

const SIZES: [usize; 4] = [1_000, 10_000, 100_000, 1_000_000];

/// A seeded generator, so every run uses the same strokes.
type Rng = StdRng;

/// A uniform value in `[lo, hi)` (`lo` when the range is empty).
fn range(rng: &mut Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

/// A pen-like stroke: a smooth random walk 1-3 px per sample whose curvature drifts and now and
/// then jumps (a new letter stroke), with a slight hand tremor, samples 8 ms apart and pressure
/// drifting between 0.1 and 1.
fn curvy_stroke(n: usize) -> Vec<Sample> {
    let mut rng = Rng::seed_from_u64(0x5eed_ac75_5eed_0001);
    let (mut x, mut y, mut heading, mut curvature, mut p) = (0.0, 0.0, 0.0_f64, 0.0, 0.5);
    (0..n)
        .map(|i| {
            curvature = f64::clamp(curvature + range(&mut rng, -0.01, 0.01), -0.3, 0.3);
            if rng.random::<f64>() < 0.005 {
                curvature = range(&mut rng, -0.3, 0.3);
            }
            heading += curvature;
            let step = range(&mut rng, 1.0, 3.0);
            x += heading.cos() * step + range(&mut rng, -0.05, 0.05);
            y += heading.sin() * step + range(&mut rng, -0.05, 0.05);
            p = f64::clamp(p + range(&mut rng, -0.01, 0.01), 0.1, 1.0);
            Sample::new(x, y, i as f64 * 8.0, p)
        })
        .collect()
}

/// A straight diagonal line, 1.68 px per sample, constant pressure: the case that is O(n²) for a
/// naive stage 2.
fn straight_line(n: usize) -> Vec<Sample> {
    (0..n).map(|i| Sample::new(1.5 * i as f64, 0.75 * i as f64, i as f64 * 8.0, 0.5)).collect()
}

/// Makes a stroke of `n` samples.
type Generator = fn(usize) -> Vec<Sample>;

/// The paper's table 3 setting, measured beside the defaults in the same run.
const PAPER: (f64, AcutsParams) = (PAPER_RESAMPLE_DISTANCE, AcutsParams::paper());
/// The defaults before the pressure interpolation test (2026-11-22): `l_eps` 0.2, `d_d` 1.54,
/// 45° near the anchor too, variance gate 0.01; also measured in the same run.
const FORMER: (f64, AcutsParams) = (
    0.2,
    AcutsParams {
        tolerance: 1.54,
        angle_deg: 45.0,
        angle_near_anchor: true,
        pressure: PressureGate::Variance(0.01),
    },
);

fn bench_acuts(c: &mut Criterion<ThreadCpuTime>) {
    let settings = [
        ("", (DEFAULT_RESAMPLE_DISTANCE, AcutsParams::default())),
        ("former-", FORMER),
        ("paper-", PAPER),
    ];
    let strokes: [(&str, Generator); 2] = [("curvy", curvy_stroke), ("straight", straight_line)];
    for ((setting, (resample_distance, params)), (name, generate)) in
        settings.into_iter().flat_map(|s| strokes.map(|g| (s, g)))
    {
        let name = format!("{setting}{name}");
        let mut group = c.benchmark_group(format!("acuts/{name}"));
        for n in SIZES {
            let samples = generate(n);
            let out = acuts(&samples, resample_distance, &params);
            eprintln!(
                "acuts/{name}/{n}: stage 1 keeps {}, stage 2 keeps {} ({:.1} % of the input)",
                out.resampled.len(),
                out.kept.len(),
                100.0 * out.kept.len() as f64 / n as f64
            );
            group.throughput(Throughput::Elements(n as u64));
            group.bench_with_input(BenchmarkId::from_parameter(n), &samples, |b, samples| {
                b.iter(|| acuts(black_box(samples), resample_distance, &params))
            });
        }
        group.finish();
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().with_measurement(ThreadCpuTime);
    targets = bench_acuts
}
criterion_main!(benches);
