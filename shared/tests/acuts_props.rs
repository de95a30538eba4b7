//! Property tests of ACUTS (stage 1 + 2) against brute-force oracles: the definition of the
//! stage-2 test over every skipped sample (`naive_admits`, O(|R|) per sample) and the guarantee
//! checked segment by segment (`check_guarantee`).
//!
//! Run `cargo test -p penmesh --test acuts_props -- --nocapture` to see the report of how often
//! the O(1) test retains a sample the naive test would remove.

use penmesh::{
    AcutsParams, PressureGate, Resampler, Sample, Simplifier, acuts, pressure_error,
    pressure_variance, segment_distance, simplify,
};
use proptest::prelude::*;
use rand::rngs::StdRng;
use rand::{Rng as _, SeedableRng};

// ---------------------------------------------------------------------------------------------
// Oracles.

/// Distance slack for float rounding: relative 1e-9 of the lengths involved.
fn slack(a: &Sample, q: &Sample, e: &Sample) -> f64 {
    1e-9 * (1.0 + a.distance(q) + a.distance(e))
}

/// `angle(a->q, a->e)` in radians, accurate near 0 (atan2 of cross and dot).
fn angle(a: &Sample, q: &Sample, e: &Sample) -> f64 {
    let (aq, ae) = (q.pos() - a.pos(), e.pos() - a.pos());
    aq.perp_dot(ae).abs().atan2(aq.dot(ae))
}

/// The pressure interpolation test for one skipped sample `q` against `a–e`
/// ([`PressureGate::Interpolation`]): `|p_q - lerp(p_a, p_e, tau_q)| <= delta`, `tau_q` linear in
/// time; when `t_e == t_a`, within `delta` of both `p_a` and `p_e`. `true` for the variance gate
/// (a per-window test, see [`gate_retains`]).
fn naive_pressure_admits(
    a: &Sample,
    q: &Sample,
    e: &Sample,
    params: &AcutsParams,
    slack_on: bool,
) -> bool {
    let PressureGate::Interpolation(delta) = params.pressure else { return true };
    let delta = delta + if slack_on { 1e-9 } else { 0.0 };
    pressure_error(q, a, e) <= delta
}

/// Whether the variance gate (paper formula 3) retains `m`; `false` for the interpolation test.
fn gate_retains(a: &Sample, m: &Sample, e: &Sample, params: &AcutsParams) -> bool {
    match params.pressure {
        PressureGate::Variance(threshold) => pressure_variance(a.p, m.p, e.p) > threshold,
        PressureGate::Interpolation(_) => false,
    }
}

/// The stage-2 test for one skipped sample `q`, as the spec defines it (angle, chord height)
/// with the default's two changes (the angle not asked within `d_d` of the anchor unless
/// `angle_near_anchor`, the pressure interpolation test), with `slack` added to the thresholds
/// (pass `false` for the exact test).
fn naive_admits(a: &Sample, q: &Sample, e: &Sample, params: &AcutsParams, slack_on: bool) -> bool {
    let (distance_slack, angle_slack) = if slack_on { (slack(a, q, e), 1e-9) } else { (0.0, 0.0) };
    let tolerance = params.tolerance.max(0.0);
    let angle_asked = params.angle_near_anchor || a.distance(q) > tolerance + distance_slack;
    let angle_ok = q.pos() == a.pos()
        || e.pos() == a.pos()
        || !angle_asked
        || angle(a, q, e) <= params.angle_deg.to_radians() + angle_slack;
    angle_ok
        && segment_distance(q, a, e) <= params.tolerance + distance_slack
        && naive_pressure_admits(a, q, e, params, slack_on)
}

/// The naive stage 2 (the former placeholder): the skipped set as a list, O(|R|) per sample.
fn naive_simplify(samples: &[Sample], params: &AcutsParams) -> Vec<usize> {
    let Some(first) = samples.first() else { return Vec::new() };
    let (mut kept, mut anchor, mut skipped) = (vec![0], *first, Vec::<Sample>::new());
    for m_index in 1..samples.len().saturating_sub(1) {
        let (m, e) = (samples[m_index], samples[m_index + 1]);
        let removable = !gate_retains(&anchor, &m, &e, params)
            && skipped.iter().chain([&m]).all(|q| naive_admits(&anchor, q, &e, params, false));
        if removable {
            skipped.push(m);
        } else {
            kept.push(m_index);
            anchor = m;
            skipped.clear();
        }
    }
    if samples.len() > 1 {
        kept.push(samples.len() - 1);
    }
    kept
}

/// Structural checks: first and last kept, strictly increasing, in range.
fn check_structure(n: usize, kept: &[usize]) {
    if n == 0 {
        assert!(kept.is_empty());
        return;
    }
    assert_eq!(kept.first(), Some(&0), "first sample not kept: {kept:?}");
    assert_eq!(kept.last(), Some(&(n - 1)), "last sample not kept: {kept:?}");
    assert!(kept.windows(2).all(|w| w[0] < w[1]), "kept not strictly increasing: {kept:?}");
}

/// The guarantee: every removed sample lies within the tolerance of the retained segment that
/// spans it, within the angle of it (beyond `d_d` from the anchor, unless `angle_near_anchor`),
/// and, with the interpolation gate, within `delta_p` of the interpolated pressure.
fn check_guarantee(samples: &[Sample], kept: &[usize], params: &AcutsParams) {
    for w in kept.windows(2) {
        let (a, e) = (&samples[w[0]], &samples[w[1]]);
        for (k, q) in samples.iter().enumerate().take(w[1]).skip(w[0] + 1) {
            assert!(
                naive_admits(a, q, e, params, true),
                "removed sample {k} {q:?} is {} from segment {}-{} {a:?} {e:?} ({params:?}), angle {}°",
                segment_distance(q, a, e),
                w[0],
                w[1],
                angle(a, q, e).to_degrees()
            );
        }
    }
}

/// How a stage-2 result compares with the naive test, decision by decision.
#[derive(Debug, Default, Clone, Copy)]
struct Replay {
    /// Decisions taken (one per sample but the first and the last).
    decisions: usize,
    /// Decisions where the result retains `m` and the naive test, in the same state, removes it.
    extra_retained: usize,
}

/// Replays stage 2 with the decisions of `kept`, checking each against the naive test in the
/// same state: a removal must pass the naive test (with rounding slack) and the pressure gate, a
/// retention the gate forces must happen.
fn replay(samples: &[Sample], kept: &[usize], params: &AcutsParams) -> Replay {
    check_structure(samples.len(), kept);
    let mut is_kept = vec![false; samples.len()];
    for &k in kept {
        is_kept[k] = true;
    }
    let mut out = Replay::default();
    let (mut anchor, mut skipped) = (0, Vec::<usize>::new());
    for m in 1..samples.len().saturating_sub(1) {
        let (a, e) = (&samples[anchor], &samples[m + 1]);
        let gate = gate_retains(a, &samples[m], e, params);
        let all = |slack_on| {
            skipped.iter().chain([&m]).all(|&q| naive_admits(a, &samples[q], e, params, slack_on))
        };
        out.decisions += 1;
        if is_kept[m] {
            if !gate && all(false) {
                out.extra_retained += 1;
            }
            anchor = m;
            skipped.clear();
        } else {
            assert!(!gate, "sample {m} removed although the pressure gate retains it");
            assert!(all(true), "sample {m} removed although the naive test retains it");
            skipped.push(m);
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Generators.

/// One step of a random walk: heading change (radians), step length, pressure change, time step.
type Step = (f64, f64, f64, f64);

/// A random walk from `start` whose steps are scaled by `scale`.
fn walk(start: (f64, f64), scale: f64, steps: &[Step]) -> Vec<Sample> {
    let (mut x, mut y, mut heading, mut p, mut t) = (start.0, start.1, 0.0_f64, 0.5_f64, 0.0);
    let mut samples = Vec::with_capacity(steps.len() + 1);
    for &(turn, len, dp, dt) in [(0.0, 0.0, 0.0, 0.0)].iter().chain(steps) {
        heading += turn;
        x += heading.cos() * len * scale;
        y += heading.sin() * len * scale;
        p = (p + dp).clamp(0.0, 1.0);
        t += dt;
        samples.push(Sample::new(x, y, t, p));
    }
    samples
}

fn steps(max_len: usize, max_turn: f64) -> impl Strategy<Value = Vec<Step>> {
    prop::collection::vec(
        (
            -max_turn..max_turn,
            prop_oneof![1 => Just(0.0), 6 => 0.0..3.0],
            prop_oneof![4 => Just(0.0), 1 => -0.1..0.1, 1 => -0.5..0.5],
            // Mostly a steady rate, sometimes repeated timestamps or a pause.
            prop_oneof![6 => Just(5.0), 1 => Just(0.0), 1 => 0.0..50.0],
        ),
        0..max_len,
    )
}

/// Strokes: smooth walks, jittery walks, points on a small integer grid (many duplicates and
/// collinear samples), and samples going back and forth along a line; small or far-off origins
/// (1e9) and scales from 1e-3 to 1e3.
fn stroke() -> impl Strategy<Value = Vec<Sample>> {
    let start = prop_oneof![Just((0.0, 0.0)), (-1e9..1e9, -1e9..1e9), (-100.0..100.0, -5.0..5.0)];
    let scale = prop_oneof![4 => Just(1.0), 1 => 1e-3..1e3];
    let smooth =
        (start.clone(), scale.clone(), steps(200, 0.3)).prop_map(|(o, s, st)| walk(o, s, &st));
    let jittery = (start.clone(), scale, steps(200, 3.2)).prop_map(|(o, s, st)| walk(o, s, &st));
    let grid = (start, prop::collection::vec((0..5_i32, 0..5_i32, 0..3_i32), 0..60)).prop_map(
        |(o, pts)| {
            pts.iter()
                .enumerate()
                .map(|(i, &(x, y, p))| {
                    Sample::new(
                        o.0 + f64::from(x),
                        o.1 + f64::from(y),
                        (i / 2) as f64,
                        f64::from(p) / 2.0,
                    )
                })
                .collect()
        },
    );
    // Back and forth along one line (axis-aligned or not): reversals, repeats, single-ray cones.
    let direction =
        prop_oneof![Just((1.0, 0.0)), Just((0.0, -1.0)), Just((0.6, 0.8)), Just((1.0, 1.0))];
    let line = (direction, 0.1..2.0, prop::collection::vec(-4..5_i32, 0..40)).prop_map(
        |((dx, dy), step, ks)| {
            ks.iter()
                .enumerate()
                .map(|(i, &k)| {
                    let along = f64::from(k) * step;
                    Sample::new(along * dx, along * dy, i as f64, 0.5)
                })
                .collect()
        },
    );
    prop_oneof![smooth, jittery, grid, line]
}

fn params() -> impl Strategy<Value = AcutsParams> {
    let variance =
        prop_oneof![Just(0.0), Just(0.0015), Just(1.0), 0.0..0.05].prop_map(PressureGate::Variance);
    let interpolation = prop_oneof![Just(0.0), Just(0.2), Just(1.0), 0.0..0.3]
        .prop_map(PressureGate::Interpolation);
    (
        prop_oneof![Just(0.0), Just(0.74), Just(1.74), 0.0..3.0],
        prop_oneof![Just(0.0), Just(15.0), Just(45.0), Just(90.0), 0.0..=90.0],
        any::<bool>(),
        prop_oneof![variance, interpolation],
    )
        .prop_map(|(tolerance, angle_deg, angle_near_anchor, pressure)| AcutsParams {
            tolerance,
            angle_deg,
            angle_near_anchor,
            pressure,
        })
}

/// Stage-1 distances: none, the default, and others.
fn resample_distance() -> impl Strategy<Value = f64> {
    prop_oneof![Just(0.0), Just(1.0), 0.0..4.0]
}

/// Any finite f64, often one of a few extreme values (so that duplicates occur).
fn finite() -> impl Strategy<Value = f64> {
    use prop::num::f64::{NEGATIVE, NORMAL, POSITIVE, SUBNORMAL, ZERO};
    prop_oneof![
        POSITIVE | NEGATIVE | NORMAL | SUBNORMAL | ZERO,
        prop::sample::select(vec![0.0, 1.0, -1.0, 1e150, -1e200, f64::MAX, f64::MIN, 5e-324]),
    ]
}

/// Stage 1 and stage 2 run as a client and a proxy would: pushed one chunk at a time, stage 2
/// fed with what stage 1 keeps. Returns the input indices kept by each stage.
fn streamed(
    samples: &[Sample],
    chunks: &[usize],
    l_eps: f64,
    params: &AcutsParams,
) -> [Vec<usize>; 2] {
    let mut resampler = (l_eps > 0.0).then(|| Resampler::new(l_eps));
    let mut simplifier = Simplifier::new(*params);
    let (mut resampled, mut kept) = (Vec::new(), Vec::new());
    let mut to_stage2 =
        |index: usize, s: Sample, resampled: &mut Vec<usize>, kept: &mut Vec<usize>| {
            resampled.push(index);
            if let Some(k) = simplifier.push(s) {
                assert_eq!(samples[resampled[k.index]], k.sample);
                kept.push(resampled[k.index]);
            }
        };
    let mut start = 0_usize;
    for &chunk in chunks.iter().chain([&usize::MAX]) {
        let end = start.saturating_add(chunk).min(samples.len());
        for (index, s) in samples.iter().enumerate().take(end).skip(start) {
            match resampler.as_mut() {
                Some(r) => {
                    for (index, s) in r.push(*s) {
                        to_stage2(index, s, &mut resampled, &mut kept);
                    }
                }
                None => to_stage2(index, *s, &mut resampled, &mut kept),
            }
        }
        start = end;
    }
    if let Some((index, s)) = resampler.as_mut().and_then(Resampler::finish) {
        to_stage2(index, s, &mut resampled, &mut kept);
    }
    if let Some(k) = simplifier.finish() {
        assert_eq!(samples[resampled[k.index]], k.sample);
        kept.push(resampled[k.index]);
    }
    [resampled, kept]
}

/// The stage-2 input of an ACUTS run: the resampled samples, and `kept` as positions in them.
fn stage2_view(
    samples: &[Sample],
    resampled: &[usize],
    kept: &[usize],
) -> (Vec<Sample>, Vec<usize>) {
    let input: Vec<Sample> = resampled.iter().map(|&i| samples[i]).collect();
    let positions =
        kept.iter().map(|k| resampled.binary_search(k).expect("kept ⊆ resampled")).collect();
    (input, positions)
}

// ---------------------------------------------------------------------------------------------
// Properties.

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    // Every removed sample of the resampled stroke lies within the tolerance (and angle) of the
    // retained segment spanning it; first and last are kept; kept is strictly increasing.
    #[test]
    fn guarantee_holds(samples in stroke(), l_eps in resample_distance(), params in params()) {
        let out = acuts(&samples, l_eps, &params);
        check_structure(samples.len(), &out.resampled);
        let (input, kept) = stage2_view(&samples, &out.resampled, &out.kept);
        check_structure(input.len(), &kept);
        check_guarantee(&input, &kept, &params);
    }

    // Each removal passes the naive O(|R|) test in the same state (the O(1) test never keeps
    // fewer samples than the guarantee needs), and the pressure gate is applied exactly.
    #[test]
    fn removals_pass_naive_test(samples in stroke(), params in params()) {
        replay(&samples, &simplify(&samples, &params), &params);
    }

    // Pushing a stroke in random chunks through both streaming stages gives the batch result.
    #[test]
    fn streaming_equals_batch(
        samples in stroke(),
        chunks in prop::collection::vec(0..20_usize, 0..30),
        l_eps in resample_distance(),
        params in params(),
    ) {
        let out = acuts(&samples, l_eps, &params);
        let [resampled, kept] = streamed(&samples, &chunks, l_eps, &params);
        prop_assert_eq!(resampled, out.resampled);
        prop_assert_eq!(kept, out.kept);
    }

    // Stage 1's repeat rule (l_eps 0): a sample is dropped only when it repeats the last sample
    // let through exactly (x, y and p); the first and the pen-up sample are always sent; and
    // stage 2 behind it keeps every bound (distance, angle, pressure) over every drawn sample,
    // the dropped repeats included.
    #[test]
    fn repeat_rule_never_takes_from_the_bounds(samples in stroke(), params in params()) {
        let mut resampler = Resampler::new(0.0);
        let mut sent: Vec<usize> =
            samples.iter().flat_map(|s| resampler.push(*s)).map(|(index, _)| index).collect();
        sent.extend(resampler.finish().map(|(index, _)| index));
        check_structure(samples.len(), &sent);
        for (index, s) in samples.iter().enumerate() {
            if sent.binary_search(&index).is_err() {
                let last = &samples[sent[sent.partition_point(|&k| k < index) - 1]];
                prop_assert!(
                    last.x == s.x && last.y == s.y && last.p == s.p,
                    "sample {} {:?} was dropped but does not repeat {:?}", index, s, last
                );
            }
        }
        let input: Vec<Sample> = sent.iter().map(|&i| samples[i]).collect();
        let kept: Vec<usize> = simplify(&input, &params).into_iter().map(|k| sent[k]).collect();
        check_guarantee(&samples, &kept, &params);
    }

    // No stroke of finite values panics, whatever their magnitude, and the output keeps its
    // structure (first and last kept, strictly increasing, stage 2 within stage 1).
    #[test]
    fn finite_input_never_panics(
        values in prop::collection::vec((finite(), finite(), finite(), finite()), 0..40),
        repeat in 0..4_usize,
        l_eps in prop_oneof![Just(0.0), Just(1.0), finite()],
        params in params(),
    ) {
        let mut samples: Vec<Sample> = values.iter().map(|&(x, y, t, p)| Sample::new(x, y, t, p)).collect();
        if let Some(&s) = samples.first() {
            samples.extend(std::iter::repeat_n(s, repeat));
        }
        let out = acuts(&samples, l_eps, &params);
        check_structure(samples.len(), &out.resampled);
        let (input, kept) = stage2_view(&samples, &out.resampled, &out.kept);
        check_structure(input.len(), &kept);
    }
}

// A 1,000,000-sample straight line keeps only its two ends (and runs in linear time).
#[test]
fn long_straight_line() {
    let n = 1_000_000;
    let samples: Vec<Sample> = (0..n)
        .map(|i| Sample::new(3.0 + i as f64 * 1.5, -7.0 + i as f64 * 0.75, i as f64, 0.5))
        .collect();
    let out = acuts(&samples, 1.0, &AcutsParams::default());
    assert_eq!(out.resampled.len(), n);
    assert_eq!(out.kept, [0, n - 1]);
    let out = acuts(&samples, 0.0, &AcutsParams::paper());
    assert_eq!(out.kept, [0, n - 1]);
}

// ---------------------------------------------------------------------------------------------
// Report: how conservative the O(1) test is against the naive one.

/// A seeded generator, so every run uses the same strokes.
type Rng = StdRng;

/// A uniform value in `[lo, hi)` (`lo` when the range is empty).
fn range(rng: &mut Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

/// Makes a stroke of `n` samples.
type Generator = fn(&mut Rng, usize) -> Vec<Sample>;

/// A pen-like stroke: 1-3 units per sample, curvature drifting and sometimes jumping, pressure
/// drifting; `jitter` adds that much noise to each position.
fn pen_stroke(rng: &mut Rng, n: usize, jitter: f64) -> Vec<Sample> {
    let (mut x, mut y, mut heading, mut curvature, mut p) = (0.0, 0.0, 0.0_f64, 0.0, 0.5);
    (0..n)
        .map(|i| {
            curvature += range(rng, -0.02, 0.02);
            if rng.random::<f64>() < 0.02 {
                curvature = range(rng, -0.5, 0.5);
            }
            curvature = f64::clamp(curvature, -0.6, 0.6);
            heading += curvature;
            let len = range(rng, 1.0, 3.0);
            x += heading.cos() * len;
            y += heading.sin() * len;
            p = f64::clamp(p + range(rng, -0.02, 0.02), 0.05, 1.0);
            let (jx, jy) = (range(rng, -jitter, jitter), range(rng, -jitter, jitter));
            Sample::new(x + jx, y + jy, i as f64 * 5.0, p)
        })
        .collect()
}

/// Uniformly random points in a 20 x 20 box: the worst case for the reach bound.
fn scribble(rng: &mut Rng, n: usize) -> Vec<Sample> {
    (0..n)
        .map(|i| Sample::new(range(rng, 0.0, 20.0), range(rng, 0.0, 20.0), i as f64, 0.5))
        .collect()
}

// Reports (without asserting) how often the O(1) test retains a sample the naive test removes,
// per decision and per stroke, and the kept counts of both, on random strokes; asserts only the
// guarantee and the replay checks.
#[test]
fn report_conservativeness_vs_naive() {
    let mut rng = Rng::seed_from_u64(0x9e37_79b9_7f4a_7c15);
    let kinds: [(&str, Generator); 4] = [
        ("pen strokes", |rng, n| pen_stroke(rng, n, 0.0)),
        ("pen strokes, jitter 0.3", |rng, n| pen_stroke(rng, n, 0.3)),
        ("pen strokes, jitter 1.0", |rng, n| pen_stroke(rng, n, 1.0)),
        ("random points in 20x20", scribble),
    ];
    let param_sets = [
        ("defaults", AcutsParams::default()),
        ("d_d 3, 45°", AcutsParams { tolerance: 3.0, angle_deg: 45.0, ..AcutsParams::default() }),
        ("paper", AcutsParams::paper()),
    ];
    for (kind, generate) in kinds {
        for (param_name, params) in param_sets {
            let (n_strokes, n_samples) = (300, 400);
            let (mut total, mut strokes_more, mut strokes_fewer) = (Replay::default(), 0, 0);
            let (mut kept_fast, mut kept_naive, mut n_input) = (0, 0, 0);
            for _ in 0..n_strokes {
                let raw = generate(&mut rng, n_samples);
                let input: Vec<Sample> =
                    penmesh::resample(&raw, 1.0).iter().map(|&i| raw[i]).collect();
                let fast = simplify(&input, &params);
                let naive = naive_simplify(&input, &params);
                check_guarantee(&input, &fast, &params);
                let r = replay(&input, &fast, &params);
                total.decisions += r.decisions;
                total.extra_retained += r.extra_retained;
                strokes_more += usize::from(fast.len() > naive.len());
                strokes_fewer += usize::from(fast.len() < naive.len());
                kept_fast += fast.len();
                kept_naive += naive.len();
                n_input += input.len();
            }
            eprintln!(
                "{kind:>24}, {param_name:>10}: {:.3} % of decisions retain where naive removes; \
                 kept {kept_fast} vs naive {kept_naive} of {n_input} (+{:.2} %); strokes keeping \
                 more {strokes_more}/{n_strokes}, fewer {strokes_fewer}/{n_strokes}",
                100.0 * total.extra_retained as f64 / total.decisions as f64,
                100.0 * (kept_fast as f64 / kept_naive as f64 - 1.0),
            );
        }
    }
}
