use glam::DVec2;

use super::simplifier::Cone;
use super::*;

fn at(x: f64, y: f64) -> Sample {
    Sample::new(x, y, 0.0, 0.5)
}

fn points(xys: &[(f64, f64)]) -> Vec<Sample> {
    xys.iter().map(|&(x, y)| at(x, y)).collect()
}

/// The setting of the paper's table 3, which these tests were written for.
fn paper() -> AcutsParams {
    AcutsParams::paper()
}

fn params(tolerance: f64, angle_deg: f64) -> AcutsParams {
    AcutsParams { tolerance, angle_deg, ..AcutsParams::paper() }
}

fn check_simplify(xys: &[(f64, f64)], params: AcutsParams, expect: &[usize]) {
    assert_eq!(simplify(&points(xys), &params), expect, "{xys:?} with {params:?}");
}

// Stage 1 keeps the first sample, even when alone.
#[test]
fn resample_keeps_first() {
    assert_eq!(resample(&points(&[(3.0, 4.0)]), 1.0), [0]);
    assert_eq!(resample(&[], 1.0), Vec::<usize>::new());
}

// Stage 1 always keeps the last sample (pen-up), even when it is too near.
#[test]
fn resample_keeps_last() {
    assert_eq!(resample(&points(&[(0.0, 0.0), (0.1, 0.0), (0.2, 0.0)]), 1.0), [0, 2]);
    assert_eq!(resample(&points(&[(0.0, 0.0), (0.0, 0.0)]), 1.0), [0, 1]);
}

// Stage 1 keeps a sample iff it is at least `l_eps` from the last KEPT sample.
#[test]
fn resample_distance_threshold() {
    let xys = [(0.0, 0.0), (0.5, 0.0), (1.0, 0.0), (1.6, 0.0), (2.0, 0.0), (2.5, 0.0)];
    assert_eq!(resample(&points(&xys), 1.0), [0, 2, 4, 5]);
    let diagonal = [(0.0, 0.0), (0.6, 0.8), (1.2, 1.5)];
    assert_eq!(resample(&points(&diagonal), 1.0), [0, 1, 2]);
    assert_eq!(resample(&points(&[(0.0, 0.0), (0.0, 0.999), (0.0, 1.5)]), 1.0), [0, 2]);
}

// Stage 1 with `l_eps <= 0` keeps every sample but repeats of the last kept position.
#[test]
fn resample_zero_distance_keeps_all_but_repeats() {
    let xys = [(0.0, 0.0), (0.0, 0.0), (0.0, 0.0), (1.0, 1.0), (0.0, 0.0)];
    assert_eq!(resample(&points(&xys), 0.0), [0, 3, 4]);
    // The pen-up sample is kept even when it repeats.
    assert_eq!(resample(&points(&[(0.0, 0.0), (0.0, 0.0)]), -1.0), [0, 1]);
}

// The repeat rule drops exact repeats only, holds the rest's last sample back until the pen
// leaves it with another pressure, and can be off.
#[test]
fn repeat_rule_drops_exact_repeats_and_keeps_a_rest_at_both_ends() {
    let stroke = [
        Sample::new(0.0, 0.0, 0.0, 0.5),
        Sample::new(0.0, 0.0, 1.0, 0.5), // dropped: the rest's middle
        Sample::new(0.0, 0.0, 2.0, 0.5), // the rest's last: the pen leaves at another pressure
        Sample::new(0.0, 0.0, 3.0, 0.9), // same place, other pressure: kept
        Sample::new(0.0, 0.0, 4.0, 0.9), // dropped: the pen leaves it at the same pressure
        Sample::new(0.5, 0.0, 5.0, 0.9),
        Sample::new(0.5, 0.0, 6.0, 0.9), // the pen-up sample: always kept
    ];
    let kept = |resampler: Resampler| {
        let mut resampler = resampler;
        let mut kept: Vec<usize> =
            stroke.iter().flat_map(|s| resampler.push(*s)).map(|(i, _)| i).collect();
        kept.extend(resampler.finish().map(|(i, _)| i));
        kept
    };
    assert_eq!(kept(Resampler::new(0.0)), [0, 2, 3, 5, 6]);
    assert_eq!(kept(Resampler::new(0.0).drop_repeats(false)), [0, 1, 2, 3, 4, 5, 6]);
}

// Stage 1 streaming reports each decision and the tail index at finish.
#[test]
fn resampler_streaming() {
    let mut r = Resampler::new(1.0);
    assert_eq!(r.push(at(0.0, 0.0)).collect::<Vec<_>>(), [(0, at(0.0, 0.0))]);
    assert_eq!(r.push(at(0.5, 0.0)).count(), 0);
    assert_eq!(r.push(at(1.5, 0.0)).collect::<Vec<_>>(), [(2, at(1.5, 0.0))]);
    assert_eq!(r.push(at(1.7, 0.0)).count(), 0);
    assert_eq!(r.finish(), Some((3, at(1.7, 0.0))));
    assert_eq!(r.finish(), None);
}

// Stage 2 on 0, 1 and 2 samples keeps everything.
#[test]
fn simplify_tiny_strokes() {
    check_simplify(&[], paper(), &[]);
    check_simplify(&[(1.0, 1.0)], paper(), &[0]);
    check_simplify(&[(1.0, 1.0), (5.0, 1.0)], paper(), &[0, 1]);
    check_simplify(&[(1.0, 1.0), (1.0, 1.0)], paper(), &[0, 1]);
}

// Stage 2 reduces a straight line, in any direction, to its ends.
#[test]
fn simplify_straight_lines() {
    for (dx, dy) in [(1.0, 0.0), (0.0, -2.0), (1.5, 0.75), (-0.3, 1.7)] {
        let xys: Vec<_> = (0..500).map(|i| (i as f64 * dx, i as f64 * dy)).collect();
        check_simplify(&xys, paper(), &[0, 499]);
    }
}

// Stage 2 keeps a corner, and the samples just past it.
#[test]
fn simplify_keeps_corner() {
    let xys = [(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (3.0, 0.0), (3.0, 1.0), (3.0, 2.0), (3.0, 3.0)];
    check_simplify(&xys, paper(), &[0, 3, 6]);
}

// Stage 2 keeps a sample farther than the tolerance from the chord, not one within it.
#[test]
fn simplify_chord_height() {
    // A wide angle, so that only the chord height decides.
    let p = params(0.5, 90.0);
    check_simplify(&[(0.0, 0.0), (5.0, 0.4), (10.0, 0.0)], p, &[0, 2]);
    check_simplify(&[(0.0, 0.0), (5.0, 0.6), (10.0, 0.0)], p, &[0, 1, 2]);
    // An older skipped sample beyond the tolerance of the new chord retains the candidate.
    // (10, 0) is 0.45 from the chord (0, 0)-(20, -0.9), but (5, 0.4) is 0.62 from it.
    check_simplify(&[(0.0, 0.0), (5.0, 0.4), (10.0, 0.0), (20.0, -0.9)], p, &[0, 2, 3]);
    check_simplify(&[(0.0, 0.0), (5.0, 0.4), (10.0, 0.0), (20.0, -0.2)], p, &[0, 3]);
}

// Stage 2 keeps a sample whose angle from the anchor exceeds `d_alpha`, even within the
// tolerance.
#[test]
fn simplify_angle() {
    // (1, 0.3) is 16.7° off the chord to (3, 0) but only 0.3 from it.
    check_simplify(&[(0.0, 0.0), (1.0, 0.3), (3.0, 0.0)], params(0.74, 15.0), &[0, 1, 2]);
    check_simplify(&[(0.0, 0.0), (1.0, 0.3), (3.0, 0.0)], params(0.74, 20.0), &[0, 2]);
}

// Stage 2 with angle 0 and tolerance 0 removes only exactly collinear samples.
#[test]
fn simplify_zero_tolerance_and_angle() {
    let p = params(0.0, 0.0);
    check_simplify(&[(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (3.0, 0.0)], p, &[0, 3]);
    check_simplify(&[(0.0, 0.0), (1.0, 0.0), (2.0, 1e-9), (3.0, 0.0)], p, &[0, 1, 2, 3]);
    check_simplify(&[(0.0, 0.0), (1.0, 1e-12), (2.0, 0.0)], params(0.0, 90.0), &[0, 1, 2]);
}

// Stage 2 on repeated points: samples equal to the anchor add no constraint, and a chord of
// length 0 (e == a) removes only samples within the tolerance of a.
#[test]
fn simplify_repeated_points() {
    let p = paper();
    check_simplify(&[(2.0, 2.0); 6], p, &[0, 5]);
    check_simplify(&[(0.0, 0.0), (0.0, 0.0), (0.0, 0.0), (5.0, 0.0), (5.0, 0.0)], p, &[0, 4]);
    // Out and back within the tolerance: the chord (0,0)-(0,0) spans (0.5, 0).
    check_simplify(&[(0.0, 0.0), (0.5, 0.0), (0.0, 0.0)], p, &[0, 2]);
    // Out and back beyond the tolerance: (2, 0) is retained.
    check_simplify(&[(0.0, 0.0), (2.0, 0.0), (0.0, 0.0)], p, &[0, 1, 2]);
    // Back to the anchor after skipped samples: a sample beyond the tolerance blocks.
    check_simplify(&[(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (0.0, 0.0)], p, &[0, 2, 3]);
}

// Stage 2 retains the candidate when the pressure variance of {a, m, e} is too high.
#[test]
fn simplify_pressure_gate() {
    let mut samples = points(&[(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (3.0, 0.0)]);
    assert_eq!(simplify(&samples, &paper()), [0, 3]);
    samples[2].p = 0.9;
    // {0.5, 0.5, 0.9} at e = 2 keeps nothing ({a, m, e} = {0, 1, 2}: variance 0.036 > 0.0015
    // retains 1); then {0.5, 0.9, 0.5} retains 2.
    assert_eq!(simplify(&samples, &paper()), [0, 1, 2, 3]);
    let lax = AcutsParams { pressure: PressureGate::Variance(1.0), ..paper() };
    assert_eq!(simplify(&samples, &lax), [0, 3]);
}

fn with_pressure(xytp: &[(f64, f64, f64, f64)]) -> Vec<Sample> {
    xytp.iter().map(|&(x, y, t, p)| Sample::new(x, y, t, p)).collect()
}

fn interpolation(delta: f64) -> AcutsParams {
    AcutsParams { pressure: PressureGate::Interpolation(delta), ..AcutsParams::default() }
}

// The interpolation gate lets a steady pressure ramp through (the variance gate does not),
// and retains where a sample leaves the interpolated pressure by more than delta_p.
#[test]
fn simplify_pressure_interpolation() {
    let ramp: Vec<_> =
        (0..20).map(|i| (f64::from(i), 0.0, f64::from(i), 0.05 * f64::from(i))).collect();
    assert_eq!(simplify(&with_pressure(&ramp), &interpolation(0.01)), [0, 19]);
    assert_eq!(simplify(&with_pressure(&ramp), &paper()).len(), 20);
    // A bump of 0.3 at t = 2 on a flat 0.5: within 0.31 it is removed, within 0.2 it is kept
    // (its neighbours are 0.15 off the lines to it, and removed).
    let bump = [
        (0.0, 0.0, 0.0, 0.5),
        (1.0, 0.0, 1.0, 0.5),
        (2.0, 0.0, 2.0, 0.8),
        (3.0, 0.0, 3.0, 0.5),
        (4.0, 0.0, 4.0, 0.5),
    ];
    assert_eq!(simplify(&with_pressure(&bump), &interpolation(0.31)), [0, 4]);
    assert_eq!(simplify(&with_pressure(&bump), &interpolation(0.2)), [0, 2, 4]);
    assert_eq!(simplify(&with_pressure(&bump), &interpolation(0.1)), [0, 1, 2, 3, 4]);
    // Interpolation is in time, not in index: the same pressures at uneven times.
    // (1, 0.6) at t = 1 of 0..10 from 0.5 to 0.6 is 0.09 above the line: within 0.1 only.
    let uneven = [(0.0, 0.0, 0.0, 0.5), (1.0, 0.0, 1.0, 0.6), (2.0, 0.0, 10.0, 0.6)];
    assert_eq!(simplify(&with_pressure(&uneven), &interpolation(0.1)), [0, 2]);
    assert_eq!(simplify(&with_pressure(&uneven), &interpolation(0.08)), [0, 1, 2]);
    // An older skipped sample off the new interpolation retains: 0.6 at t = 1 is fine for
    // 0.5 -> 0.7 over 0..2, not for 0.5 -> 0.5 over 0..3.
    let older =
        [(0.0, 0.0, 0.0, 0.5), (1.0, 0.0, 1.0, 0.6), (2.0, 0.0, 2.0, 0.7), (3.0, 0.0, 3.0, 0.5)];
    assert_eq!(simplify(&with_pressure(&older), &interpolation(0.05)), [0, 2, 3]);
}

// Samples at the anchor's time: tau = 0 when e is later (within delta_p of p_a), and within
// delta_p of both ends when e has the anchor's time too.
#[test]
fn simplify_pressure_interpolation_equal_times() {
    let p = interpolation(0.1);
    let same_t =
        [(0.0, 0.0, 0.0, 0.5), (1.0, 0.0, 0.0, 0.55), (2.0, 0.0, 0.0, 0.62), (3.0, 0.0, 0.0, 0.7)];
    // At e = 2: 0.55 is within 0.1 of 0.5 and 0.62; at e = 3, 0.55 is 0.15 from 0.7.
    assert_eq!(simplify(&with_pressure(&same_t), &p), [0, 2, 3]);
    let then_later =
        [(0.0, 0.0, 0.0, 0.5), (1.0, 0.0, 0.0, 0.58), (2.0, 0.0, 5.0, 0.9), (3.0, 0.0, 6.0, 0.9)];
    // 0.58 at tau = 0 is 0.08 from 0.5, whatever e; 0.9 at t = 5 is 0.07 off 0.5 -> 0.9.
    assert_eq!(simplify(&with_pressure(&then_later), &p), [0, 3]);
    let too_far = [(0.0, 0.0, 0.0, 0.5), (1.0, 0.0, 0.0, 0.65), (2.0, 0.0, 5.0, 0.65)];
    assert_eq!(simplify(&with_pressure(&too_far), &p), [0, 1, 2]);
}

// By default the angle test leaves samples within d_d of the anchor to the distance test;
// the paper's setting asks the angle of them too.
#[test]
fn simplify_angle_near_anchor() {
    // (0.5, 0.5) is 45° off the chord to (5, 0) and 0.71 from the anchor (0, 0).
    let xys = [(0.0, 0.0), (0.5, 0.5), (5.0, 0.0)];
    let near = AcutsParams { tolerance: 0.74, angle_deg: 15.0, ..AcutsParams::default() };
    check_simplify(&xys, near, &[0, 2]);
    check_simplify(&xys, AcutsParams { angle_near_anchor: true, ..near }, &[0, 1, 2]);
    // Behind the anchor within d_d: removed, as the distance allows.
    check_simplify(&[(0.0, 0.0), (-0.5, 0.0), (5.0, 0.0)], near, &[0, 2]);
    // Beyond d_d the angle still applies: (1, 0.5) is 26.6° off, 1.1 from the anchor.
    check_simplify(&[(0.0, 0.0), (1.0, 0.5), (5.0, 0.0)], near, &[0, 1, 2]);
}

// JSON of the parameters round-trips in one form (the store reads older rows itself).
#[test]
fn params_json() {
    let params = AcutsParams::default();
    let json = serde_json::to_string(&params).unwrap();
    assert_eq!(
        json,
        r#"{"tolerance":1.74,"angle_deg":45.0,"angle_near_anchor":false,"pressure":{"interpolation":0.2}}"#
    );
    assert_eq!(serde_json::from_str::<AcutsParams>(&json).unwrap(), params);
    let neither = r#"{"tolerance":1,"angle_deg":15,"angle_near_anchor":true}"#;
    assert!(serde_json::from_str::<AcutsParams>(neither).is_err());
}

// Validation names the pressure gate's value.
#[test]
fn params_validate_pressure() {
    let bad = AcutsParams { pressure: PressureGate::Interpolation(-0.1), ..AcutsParams::default() };
    assert_eq!(bad.validate().unwrap_err().name, "pressure.interpolation");
    let bad = AcutsParams { pressure: PressureGate::Variance(f64::NAN), ..AcutsParams::default() };
    assert_eq!(bad.validate().unwrap_err().name, "pressure.variance");
}

// Stage 2 is conservative when the stroke steps back past an older skipped sample: the
// definition would remove (4.6, 0) since (5, 0) lies within 0.74 of (4.5, 0.05), the reach
// bound retains it.
#[test]
fn simplify_reach_bound_is_conservative() {
    let xys = [(0.0, 0.0), (5.0, 0.0), (4.6, 0.0), (4.5, 0.05)];
    check_simplify(&xys, paper(), &[0, 2, 3]);
}

// The relaxed reach bound: the pen steps back by 0.1 past an older skipped sample, which
// stays within 0.74 of the new chord (its foot 0.4 beyond `e`, on the near cone's ray).
#[test]
fn simplify_relaxed_reach_bound() {
    let xys = [(0.0, 0.0), (5.0, 0.0), (4.7, 0.0), (4.6, 0.0)];
    check_simplify(&xys, paper(), &[0, 3]);
    // Farther back than 0.6 d_d = 0.444 past the reach: still retained.
    let xys = [(0.0, 0.0), (5.0, 0.0), (4.7, 0.0), (4.5, 0.0)];
    check_simplify(&xys, paper(), &[0, 2, 3]);
}

// The default and the paper's settings are in range.
#[test]
fn default_and_paper_settings_are_valid() {
    assert!(AcutsParams::default().validate().is_ok());
    assert!(AcutsParams::paper().validate().is_ok());
}

// Stage 2 on huge coordinates: exact on a line far from the origin, and no panic at the edge
// of the f64 range (lengths beyond 1e150 retain everything).
#[test]
fn simplify_huge_coordinates() {
    let xys: Vec<_> = (0..100).map(|i| (1e12 + i as f64 * 2.0, -1e12)).collect();
    check_simplify(&xys, paper(), &[0, 99]);
    let xys = [(f64::MAX, f64::MAX), (-f64::MAX, 0.0), (0.0, f64::MIN), (1e200, 1e200)];
    check_simplify(&xys, paper(), &[0, 1, 2, 3]);
}

// Out-of-range parameters are refused by the constructor, naming the parameter.
#[test]
fn out_of_range_params_are_refused() {
    let gate = PressureGate::Interpolation(0.2);
    assert_eq!(AcutsParams::new(-1.0, 15.0, false, gate).unwrap_err().name, "tolerance");
    assert_eq!(AcutsParams::new(f64::NAN, 15.0, false, gate).unwrap_err().name, "tolerance");
    assert_eq!(AcutsParams::new(1.0, 400.0, false, gate).unwrap_err().name, "angle_deg");
    assert_eq!(AcutsParams::new(1.0, f64::NAN, false, gate).unwrap_err().name, "angle_deg");
    assert!(AcutsParams::new(0.0, 90.0, true, gate).is_ok());
}

// Stage 2 streaming: decisions come one sample late, with the right index and sample, and
// finish starts a new stroke.
#[test]
fn simplifier_streaming() {
    let mut s = Simplifier::new(paper());
    assert_eq!(s.push(at(0.0, 0.0)), Some(Kept { index: 0, sample: at(0.0, 0.0) }));
    assert_eq!(s.push(at(3.0, 0.0)), None);
    assert_eq!(s.push(at(3.0, 3.0)), Some(Kept { index: 1, sample: at(3.0, 0.0) }));
    assert_eq!(s.push(at(3.0, 6.0)), None);
    assert_eq!(s.finish(), Some(Kept { index: 3, sample: at(3.0, 6.0) }));
    assert_eq!(s.finish(), None);
    assert_eq!(s.push(at(9.0, 9.0)), Some(Kept { index: 0, sample: at(9.0, 9.0) }));
}

// Both stages together map stage-2 indices back to input indices.
#[test]
fn acuts_maps_indices() {
    let samples = points(&[(0.0, 0.0), (0.2, 0.0), (1.0, 0.0), (2.0, 0.0), (2.0, 2.0)]);
    let out = acuts(&samples, 1.0, &paper());
    assert_eq!(out.resampled, [0, 2, 3, 4]);
    assert_eq!(out.kept, [0, 3, 4]);
    let out = acuts(&samples, 0.0, &paper());
    assert_eq!(out.resampled, [0, 1, 2, 3, 4]);
    assert_eq!(out.kept, [0, 3, 4]);
}

// The cone as an interval of tangents: nested, overlapping, disjoint, single rays, and
// boundaries outside the reference half-plane.
#[test]
fn cone_narrowing() {
    let dir = |deg: f64| {
        let (s, c) = deg.to_radians().sin_cos();
        DVec2::new(c, s)
    };
    let cone = |center_deg: f64, half_deg: f64| {
        let (s, c) = half_deg.to_radians().sin_cos();
        Cone::around(dir(center_deg), s, c)
    };
    let narrowed = |mut a: Cone, center_deg: f64, half_deg: f64| {
        let (s, c) = half_deg.to_radians().sin_cos();
        a.narrow(dir(center_deg) * 7.0, s, c);
        a
    };
    let both = narrowed(cone(0.0, 20.0), 15.0, 10.0);
    assert!(both.contains(dir(5.5)) && both.contains(dir(19.5)) && both.contains(dir(12.0)));
    assert!(!both.contains(dir(4.5)) && !both.contains(dir(20.5)));
    let nested = narrowed(cone(0.0, 80.0), 10.0, 5.0);
    assert!(nested.contains(dir(10.0)) && !nested.contains(dir(0.0)));
    assert!(!narrowed(cone(0.0, 10.0), 90.0, 10.0).contains(dir(5.0)));
    assert!(!narrowed(cone(0.0, 10.0), 90.0, 10.0).contains(dir(85.0)));
    let ray = cone(0.0, 0.0);
    assert!(ray.contains(DVec2::X * 3.0) && !ray.contains(-DVec2::X) && !ray.contains(DVec2::ZERO));
    assert!(narrowed(ray, 0.0, 0.0).contains(DVec2::X));
    assert!(!narrowed(ray, 180.0, 0.0).contains(DVec2::X));
    assert!(!narrowed(ray, 180.0, 0.0).contains(-DVec2::X));
    // A wide cone whose lower boundary is beyond -90° of the reference: that side stays open.
    let wide = narrowed(cone(0.0, 80.0), -60.0, 45.0);
    assert!(wide.contains(dir(-79.0)) && wide.contains(dir(-15.5)) && !wide.contains(dir(-14.0)));
    // Both boundaries outside the half-plane: empty.
    let opposite = narrowed(cone(0.0, 89.0), 180.0, 80.0);
    assert!((-89..=89).all(|d| !opposite.contains(dir(f64::from(d)))));
}
