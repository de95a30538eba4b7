//! The baseline simplifiers against brute-force checks of their own guarantees.

use penmesh::baselines::{
    Bqs, DouglasPeucker, Dpts, OpeningWindow, Optimal, OptimalPressure, PressureWindow, Simplify,
    SquishE, Visvalingam, VwStop,
};
use penmesh::{AcutsParams, PressureGate, Sample, e_max, p_max};
use proptest::prelude::*;

/// Rounding slack of the geometric tests.
fn slack(tolerance: f64) -> f64 {
    tolerance * 1e-9 + 1e-9
}

/// The fewest samples keeping both bounds, by trying every subset with both ends (n <= 12).
fn brute_force_min_with_pressure(samples: &[Sample], tolerance: f64, pressure: f64) -> usize {
    let n = samples.len();
    if n <= 2 {
        return n;
    }
    let inner = n - 2;
    (0..1_u32 << inner)
        .filter_map(|mask| {
            let mut kept = vec![0];
            kept.extend((0..inner).filter(|b| mask >> b & 1 == 1).map(|b| b + 1));
            kept.push(n - 1);
            (e_max(samples, &kept) <= tolerance && p_max(samples, &kept) <= pressure)
                .then_some(kept.len())
        })
        .min()
        .unwrap()
}

/// Kept indices are strictly increasing, in range, with both ends.
fn assert_well_formed(samples: &[Sample], kept: &[usize], name: &str) {
    let n = samples.len();
    if n == 0 {
        assert!(kept.is_empty(), "{name}");
        return;
    }
    assert_eq!(kept.first(), Some(&0), "{name}: {kept:?}");
    assert_eq!(kept.last(), Some(&(n - 1)), "{name}: {kept:?}");
    assert!(kept.windows(2).all(|w| w[0] < w[1]), "{name}: {kept:?}");
}

/// The fewest samples, by trying every subset with both ends (n <= 12).
fn brute_force_min(samples: &[Sample], tolerance: f64) -> usize {
    brute_force_min_with_pressure(samples, tolerance, f64::INFINITY)
}

/// A pen-like stroke: a random walk with steps of up to `step` in each axis, 10 ms apart, some
/// repeated positions and timestamps.
fn stroke(max_len: usize, step: f64) -> impl Strategy<Value = Vec<Sample>> {
    prop::collection::vec((-step..step, -step..step, 0..3_u8, 0.0..1.0_f64), 0..max_len).prop_map(
        |steps| {
            let (mut x, mut y, mut t) = (0.0, 0.0, 0.0);
            steps
                .into_iter()
                .map(|(dx, dy, kind, p)| {
                    if kind != 0 {
                        x += dx;
                        y += dy;
                    }
                    if kind != 1 {
                        t += 10.0;
                    }
                    Sample::new(x, y, t, p)
                })
                .collect()
        },
    )
}

fn error_bounded() -> Vec<Box<dyn Simplify>> {
    vec![
        Box::new(DouglasPeucker),
        Box::new(Visvalingam { stop: VwStop::ErrorBound }),
        Box::new(OpeningWindow::default()),
        Box::new(OpeningWindow { angle_deg: None }),
        Box::new(SquishE::default()),
        Box::new(Bqs { fast: false }),
        Box::new(Bqs { fast: true }),
        Box::new(Dpts::default()),
        Box::new(Optimal),
        Box::new(PressureWindow { pressure_tolerance: 0.2 }),
        Box::new(OptimalPressure { pressure_tolerance: 0.2 }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    // Every error-bounded baseline keeps each removed sample within the tolerance of its segment,
    // and none keeps fewer samples than the optimum.
    #[test]
    fn error_bounded_baselines_hold_their_bound(samples in stroke(80, 3.0), tolerance in 0.0..4.0_f64) {
        let optimum = Optimal.run(&samples, tolerance).len();
        for algo in error_bounded() {
            let kept = algo.run(&samples, tolerance);
            assert_well_formed(&samples, &kept, algo.name());
            let worst = e_max(&samples, &kept);
            prop_assert!(worst <= tolerance + slack(tolerance), "{}: E_max {worst} > {tolerance}", algo.name());
            prop_assert!(kept.len() >= optimum, "{}: {} < optimum {optimum}", algo.name(), kept.len());
        }
    }

    // Optimal min-# keeps exactly as few samples as an exhaustive search finds.
    #[test]
    fn optimal_is_minimal(samples in stroke(12, 3.0), tolerance in 0.0..3.0_f64) {
        let kept = Optimal.run(&samples, tolerance);
        prop_assert_eq!(kept.len(), brute_force_min(&samples, tolerance));
    }

    // Optimal min-# under both bounds keeps exactly as few samples as an exhaustive search finds.
    #[test]
    fn optimal_with_pressure_is_minimal(
        samples in stroke(12, 3.0),
        tolerance in 0.0..3.0_f64,
        pressure in prop_oneof![Just(0.0), 0.0..0.6_f64],
    ) {
        let kept = OptimalPressure { pressure_tolerance: pressure }.run(&samples, tolerance);
        prop_assert_eq!(kept.len(), brute_force_min_with_pressure(&samples, tolerance, pressure));
    }

    // The pressure-aware baselines hold the pressure bound, and neither they nor ACUTS with the
    // same pressure tolerance (and no stage 1) keep fewer samples than optimal min-# under both.
    #[test]
    fn pressure_bounded_baselines(
        samples in stroke(80, 3.0),
        tolerance in 0.0..4.0_f64,
        pressure in 0.0..0.6_f64,
    ) {
        let optimum = OptimalPressure { pressure_tolerance: pressure }.run(&samples, tolerance);
        prop_assert!(p_max(&samples, &optimum) <= pressure + 1e-9);
        let window = PressureWindow { pressure_tolerance: pressure }.run(&samples, tolerance);
        assert_well_formed(&samples, &window, "window-p");
        prop_assert!(p_max(&samples, &window) <= pressure + 1e-9);
        prop_assert!(e_max(&samples, &window) <= tolerance + slack(tolerance));
        prop_assert!(window.len() >= optimum.len());
        let params = AcutsParams {
            tolerance,
            pressure: PressureGate::Interpolation(pressure),
            ..AcutsParams::default()
        };
        let acuts = penmesh::simplify(&samples, &params);
        prop_assert!(p_max(&samples, &acuts) <= pressure + 1e-9);
        prop_assert!(acuts.len() >= optimum.len(), "acuts {} < optimum {}", acuts.len(), optimum.len());
    }

    // BQS decides exactly as the plain greedy window (its bounds only save work).
    #[test]
    fn bqs_matches_the_greedy_window(samples in stroke(120, 3.0), tolerance in 0.0..4.0_f64) {
        prop_assert_eq!(
            Bqs { fast: false }.run(&samples, tolerance),
            OpeningWindow { angle_deg: None }.run(&samples, tolerance)
        );
    }

    // The window's angle bound holds for every removed sample: angle(a->q, a->e) <= angle.
    #[test]
    fn window_holds_its_angle(samples in stroke(80, 3.0), tolerance in 0.0..4.0_f64, angle in 0.0..90.0_f64) {
        let kept = OpeningWindow { angle_deg: Some(angle) }.run(&samples, tolerance);
        for pair in kept.windows(2) {
            let (a, e) = (samples[pair[0]], samples[pair[1]]);
            for q in &samples[pair[0] + 1..pair[1]] {
                let (u, v) = ((q.x - a.x, q.y - a.y), (e.x - a.x, e.y - a.y));
                if u == (0.0, 0.0) || v == (0.0, 0.0) {
                    continue;
                }
                let between = (u.0 * v.1 - u.1 * v.0).abs().atan2(u.0 * v.0 + u.1 * v.1);
                prop_assert!(between.to_degrees() <= angle + 1e-9);
            }
        }
    }

    // DPTS: every spanned original step of non-zero length points within the angle of its
    // retained segment.
    #[test]
    fn dpts_preserves_directions(samples in stroke(80, 3.0), tolerance in 0.0..4.0_f64, angle in 1.0..89.0_f64) {
        let kept = Dpts { angle_deg: angle }.run(&samples, tolerance);
        for pair in kept.windows(2).filter(|p| p[1] > p[0] + 1) {
            let (a, e) = (samples[pair[0]], samples[pair[1]]);
            let v = (e.x - a.x, e.y - a.y);
            for w in samples[pair[0]..=pair[1]].windows(2) {
                let u = (w[1].x - w[0].x, w[1].y - w[0].y);
                if u == (0.0, 0.0) {
                    continue;
                }
                let between = (u.0 * v.1 - u.1 * v.0).abs().atan2(u.0 * v.0 + u.1 * v.1);
                prop_assert!(between.to_degrees() <= angle + 1e-9);
            }
        }
    }

    // SQUISH-E's error mode bounds the synchronised distance of every removed sample.
    #[test]
    fn squish_e_bounds_sed(samples in stroke(80, 3.0), tolerance in 0.0..4.0_f64) {
        let kept = SquishE { ratio: 1.0 }.run(&samples, tolerance);
        for pair in kept.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            for i in a + 1..b {
                let error = penmesh::baselines::sed(&samples, i, a, b);
                prop_assert!(error <= tolerance + slack(tolerance), "SED {error} > {tolerance}");
            }
        }
    }

    // SQUISH-E's ratio mode keeps at most max(3, ceil(n / ratio)) samples.
    #[test]
    fn squish_e_ratio_mode_count(samples in stroke(300, 3.0), ratio in 1.0..20.0_f64) {
        let kept = SquishE { ratio }.run(&samples, 0.0);
        assert_well_formed(&samples, &kept, "squish-e");
        let bound = ((samples.len() as f64 / ratio).ceil() as usize).max(3).min(samples.len());
        prop_assert!(kept.len() <= bound, "{} > {bound}", kept.len());
    }

    // Visvalingam–Whyatt by count keeps exactly that many samples (at least the two ends).
    #[test]
    fn visvalingam_count(samples in stroke(80, 3.0), count in 0..100_usize) {
        let kept = Visvalingam { stop: VwStop::Count(count) }.run(&samples, 0.0);
        assert_well_formed(&samples, &kept, "vw");
        prop_assert_eq!(kept.len(), count.max(2).min(samples.len()));
    }

    // Visvalingam–Whyatt by area stops with every remaining triangle at least the threshold.
    #[test]
    fn visvalingam_area(samples in stroke(80, 3.0), threshold in 0.0..5.0_f64) {
        let kept = Visvalingam { stop: VwStop::Area(threshold) }.run(&samples, 0.0);
        assert_well_formed(&samples, &kept, "vw");
        for w in kept.windows(3) {
            let (a, b, c) = (samples[w[0]], samples[w[1]], samples[w[2]]);
            let area = ((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)).abs() / 2.0;
            prop_assert!(area >= threshold * (1.0 - 1e-12));
        }
    }
}

// Douglas–Peucker on a known case: the corner is kept, the collinear samples are not.
#[test]
fn douglas_peucker_keeps_the_corner() {
    let samples: Vec<Sample> = [(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (2.0, 1.0), (2.0, 2.0)]
        .iter()
        .enumerate()
        .map(|(i, &(x, y))| Sample::new(x, y, i as f64, 0.5))
        .collect();
    assert_eq!(DouglasPeucker.run(&samples, 0.1), [0, 2, 4]);
    assert_eq!(Optimal.run(&samples, 0.1), [0, 2, 4]);
    // (2, 0) is 1.41 from the chord (0, 0)-(2, 2), but 0.89 from (1, 0)-(2, 2).
    assert_eq!(Optimal.run(&samples, 1.0), [0, 1, 4]);
    assert_eq!(Optimal.run(&samples, 1.5), [0, 4]);
}

// Optimal min-# handles a long stroke (quadratic time, bit-matrix memory) quickly.
#[test]
fn optimal_on_a_long_wiggly_stroke() {
    let samples: Vec<Sample> = (0..3000)
        .map(|i| {
            let s = i as f64 * 0.5;
            Sample::new(s, 3.0 * (s / 20.0).sin(), i as f64 * 10.0, 0.5)
        })
        .collect();
    let kept = Optimal.run(&samples, 0.5);
    assert!(e_max(&samples, &kept) <= 0.5 + 1e-9);
    assert!(kept.len() <= DouglasPeucker.run(&samples, 0.5).len());
}
