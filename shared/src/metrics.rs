//! Simplification metrics (paper table 5, made precise in `shared/spec/algorithms.md`).
//!
//! A simplification is a subset of an original stroke `T_o`, identified by the original indices
//! it keeps (`kept`, strictly increasing). The simplified polyline `T_s` joins the kept samples
//! in order. Original sample `i` is *spanned* by the retained segment `kept[j]–kept[j+1]` with
//! `kept[j] <= i <= kept[j+1]`. ACUTS always keeps the first and the last sample; if a
//! simplification does not, the samples before its first kept sample (after its last) are
//! measured against that kept sample itself, as if the simplified stroke stayed there.
//!
//! - `CR = (1 - C / N) · 100` (%), with `N` original and `C` kept samples.
//! - `E_max`: the largest distance from an original sample to the retained segment that spans it
//!   ([`segment_distance`]).
//! - `E_l = (L_o - L_s) / L_o · 100` (%), the relative loss of polyline length; 0 when
//!   `L_o = 0`.
//! - `SED`: the mean, over all `N` original samples, of the synchronised Euclidean distance: the
//!   distance from sample `i` to the point of its spanning segment `a–b` at the same time,
//!   `S_a + f (S_b - S_a)` with `f = (t_i - t_a) / (t_b - t_a)`. When `t_a = t_b` (several samples
//!   with one timestamp) time cannot place the point, and `f = (i - a) / (b - a)` is used: the
//!   samples are taken as evenly spread over that instant.
//! - The paper's CDF form ([`cdf_error_area`]) against a reference curve.

use serde::Serialize;

use crate::acuts::segment_distance;
use crate::model::{Sample, SampleError, polyline_length, validate_samples};

/// Table 5's metrics of one simplification.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SimplificationMetrics {
    /// Original samples `N`.
    pub n_input: usize,
    /// Kept samples `C`.
    pub n_output: usize,
    /// Compression ratio, %.
    pub cr: f64,
    /// Largest distance of an original sample to its spanning retained segment.
    pub e_max: f64,
    /// Relative loss of polyline length, %.
    pub e_l: f64,
    /// Mean synchronised Euclidean distance.
    pub sed: f64,
}

/// Why metrics cannot be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MetricsError {
    #[error("the simplification keeps no sample (the original has {n_input})")]
    NoKeptSamples { n_input: usize },
    #[error("kept[{position}] = {index} is out of range: the original has {n_input} samples")]
    KeptOutOfRange { position: usize, index: usize, n_input: usize },
    #[error("kept[{position}] = {index} does not follow kept[{}] = {previous}: indices must increase", .position - 1)]
    KeptNotIncreasing { position: usize, index: usize, previous: usize },
    #[error("the reference curve has no samples")]
    EmptyReference,
    #[error("original stroke: {0}")]
    BadOriginal(SampleError),
    #[error("reference curve: {0}")]
    BadReference(SampleError),
}

/// Checks the original samples and that `kept` is non-empty, strictly increasing and in range.
fn validate_simplification(original: &[Sample], kept: &[usize]) -> Result<(), MetricsError> {
    validate_samples(original, None, 0).map_err(MetricsError::BadOriginal)?;
    if kept.is_empty() {
        return Err(MetricsError::NoKeptSamples { n_input: original.len() });
    }
    for (position, &index) in kept.iter().enumerate() {
        if index >= original.len() {
            return Err(MetricsError::KeptOutOfRange { position, index, n_input: original.len() });
        }
        if position > 0 && index <= kept[position - 1] {
            return Err(MetricsError::KeptNotIncreasing {
                position,
                index,
                previous: kept[position - 1],
            });
        }
    }
    Ok(())
}

/// Calls `visit(i, a, b)` for every original index `i` with its spanning kept indices `a <= i <=
/// b` (`a = b` outside the kept range). Kept samples are visited once, as the start of their
/// segment (or the end of the last one).
fn for_each_spanned(n_input: usize, kept: &[usize], mut visit: impl FnMut(usize, usize, usize)) {
    let (first, last) = (kept[0], kept[kept.len() - 1]);
    for i in 0..first {
        visit(i, first, first);
    }
    for pair in kept.windows(2) {
        for i in pair[0]..pair[1] {
            visit(i, pair[0], pair[1]);
        }
    }
    for i in last..n_input {
        visit(i, last, last);
    }
}

/// The point of segment `a–b` at the time of sample `i` (`a <= i <= b`), see the module docs.
fn synchronised_point(original: &[Sample], i: usize, a: usize, b: usize) -> glam::DVec2 {
    let (sa, sb) = (&original[a], &original[b]);
    if a == b {
        return sa.pos();
    }
    let f = if sb.t > sa.t {
        (original[i].t - sa.t) / (sb.t - sa.t)
    } else {
        (i - a) as f64 / (b - a) as f64
    };
    sa.pos().lerp(sb.pos(), f)
}

/// The pressure error of sample `q` spanned by the retained segment `a–b`: its distance to the
/// pressure interpolated linearly in time along the segment, `|p_q - lerp(p_a, p_b, tau_q)|`.
/// A segment without duration (`t_b <= t_a`) cannot place `q` in time, so the error is the
/// larger distance to either end's pressure. This is the quantity ACUTS's interpolation gate
/// ([`crate::PressureGate::Interpolation`]) bounds, and the same rule on a zero-duration segment.
pub fn pressure_error(q: &Sample, a: &Sample, b: &Sample) -> f64 {
    if b.t > a.t {
        let tau = (q.t - a.t) / (b.t - a.t);
        (q.p - (a.p + tau * (b.p - a.p))).abs()
    } else {
        (q.p - a.p).abs().max((q.p - b.p).abs())
    }
}

/// `P_max`: the largest [`pressure_error`] of a removed sample against the retained segment
/// that spans it. `kept` must be strictly increasing indices into `original` (samples outside
/// the kept range are not measured: no segment spans them).
pub fn p_max(original: &[Sample], kept: &[usize]) -> f64 {
    let mut worst: f64 = 0.0;
    for pair in kept.windows(2) {
        let (a, b) = (&original[pair[0]], &original[pair[1]]);
        for q in &original[pair[0] + 1..pair[1]] {
            worst = worst.max(pressure_error(q, a, b));
        }
    }
    worst
}

/// `E_max` without the other metrics: the largest distance of an original sample to the
/// retained segment that spans it, as in [`simplification_metrics`]. `kept` must be strictly
/// increasing indices into `original`; 0 when it is empty (an empty stroke keeps nothing).
pub fn e_max(original: &[Sample], kept: &[usize]) -> f64 {
    let mut worst: f64 = 0.0;
    if kept.is_empty() {
        return worst;
    }
    for_each_spanned(original.len(), kept, |i, a, b| {
        worst = worst.max(segment_distance(&original[i], &original[a], &original[b]));
    });
    worst
}

/// CR, E_max, E_l and SED of the simplification of `original` that keeps the samples at `kept`.
pub fn simplification_metrics(
    original: &[Sample],
    kept: &[usize],
) -> Result<SimplificationMetrics, MetricsError> {
    validate_simplification(original, kept)?;
    let n_input = original.len();
    let n_output = kept.len();

    let mut sed_sum = 0.0;
    for_each_spanned(n_input, kept, |i, a, b| {
        sed_sum += original[i].pos().distance(synchronised_point(original, i, a, b));
    });

    let simplified: Vec<Sample> = kept.iter().map(|&i| original[i]).collect();
    let length_original = polyline_length(original);
    let length_simplified = polyline_length(&simplified);
    let e_l = if length_original > 0.0 {
        (length_original - length_simplified) / length_original * 100.0
    } else {
        0.0
    };

    Ok(SimplificationMetrics {
        n_input,
        n_output,
        cr: (1.0 - n_output as f64 / n_input as f64) * 100.0,
        e_max: e_max(original, kept),
        e_l,
        sed: sed_sum / n_input as f64,
    })
}

/// The paper's CDF form of SED: the area between the cumulative distributions of the errors of
/// `T_o` and of `T_s` against a reference (standard) curve.
///
/// The error of a sample is its distance to the reference polyline (the smallest
/// [`segment_distance`] to a reference segment; the distance to the point if the reference has
/// one sample). `F_o` and `F_s` are the empirical distribution functions of the errors of the
/// `N` original and the `C` kept samples (`F(e)` = the fraction of samples with error `<= e`).
/// The result is `∫_0^∞ |F_o(e) - F_s(e)| de`, in the unit of x and y: the 1-Wasserstein
/// distance between the two error distributions, 0 when the simplification keeps errors
/// distributed as the original's. The paper prints the integrand without the absolute value;
/// without it, gains and losses at different error levels would cancel.
pub fn cdf_error_area(
    original: &[Sample],
    kept: &[usize],
    reference: &[Sample],
) -> Result<f64, MetricsError> {
    validate_simplification(original, kept)?;
    if reference.is_empty() {
        return Err(MetricsError::EmptyReference);
    }
    validate_samples(reference, None, 0).map_err(MetricsError::BadReference)?;
    let error = |q: &Sample| -> f64 {
        if reference.len() == 1 {
            return q.distance(&reference[0]);
        }
        reference
            .windows(2)
            .map(|w| segment_distance(q, &w[0], &w[1]))
            .fold(f64::INFINITY, f64::min)
    };
    let mut errors_original: Vec<f64> = original.iter().map(error).collect();
    let mut errors_simplified: Vec<f64> = kept.iter().map(|&i| errors_original[i]).collect();
    errors_original.sort_by(f64::total_cmp);
    errors_simplified.sort_by(f64::total_cmp);
    Ok(area_between_cdfs(&errors_original, &errors_simplified))
}

/// `∫ |F_a - F_b|` for the empirical distribution functions of two sorted, non-empty samples.
fn area_between_cdfs(a: &[f64], b: &[f64]) -> f64 {
    let (mut i, mut j) = (0, 0);
    let mut area = 0.0;
    let mut position = a[0].min(b[0]);
    while i < a.len() || j < b.len() {
        let next = match (a.get(i), b.get(j)) {
            (Some(&x), Some(&y)) => x.min(y),
            (Some(&x), None) => x,
            (None, Some(&y)) => y,
            (None, None) => break,
        };
        let gap = (i as f64 / a.len() as f64 - j as f64 / b.len() as f64).abs();
        area += gap * (next - position);
        position = next;
        while a.get(i) == Some(&next) {
            i += 1;
        }
        while b.get(j) == Some(&next) {
            j += 1;
        }
    }
    area
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(x: f64, y: f64, t: f64) -> Sample {
        Sample::new(x, y, t, 0.5)
    }

    /// Asserts each metric to 1e-9.
    fn check(original: &[Sample], kept: &[usize], expected: SimplificationMetrics) {
        let got = simplification_metrics(original, kept).unwrap();
        assert_eq!((got.n_input, got.n_output), (expected.n_input, expected.n_output));
        for (name, g, e) in [
            ("cr", got.cr, expected.cr),
            ("e_max", got.e_max, expected.e_max),
            ("e_l", got.e_l, expected.e_l),
            ("sed", got.sed, expected.sed),
        ] {
            assert!((g - e).abs() < 1e-9, "{name}: got {g}, expected {e} ({got:?})");
        }
    }

    fn m(
        n_input: usize,
        n_output: usize,
        cr: f64,
        e_max: f64,
        e_l: f64,
        sed: f64,
    ) -> SimplificationMetrics {
        SimplificationMetrics { n_input, n_output, cr, e_max, e_l, sed }
    }

    #[test]
    // Keeping everything costs nothing and compresses nothing.
    fn identity_simplification() {
        let stroke = [s(0.0, 0.0, 0.0), s(1.0, 1.0, 10.0), s(2.0, 0.0, 20.0)];
        check(&stroke, &[0, 1, 2], m(3, 3, 0.0, 0.0, 0.0, 0.0));
    }

    #[test]
    // A tent with its apex removed: E_max is the height, E_l the lost length, SED synchronous.
    fn tent_without_apex() {
        // Apex (1, 1) at t = 10; the chord (0,0)-(2,0) at t = 10 is at (1, 0): SED sum 1.
        let stroke = [s(0.0, 0.0, 0.0), s(1.0, 1.0, 10.0), s(2.0, 0.0, 20.0)];
        let l_o = 2.0 * 2f64.sqrt();
        check(&stroke, &[0, 2], m(3, 2, 100.0 / 3.0, 1.0, (l_o - 2.0) / l_o * 100.0, 1.0 / 3.0));
    }

    #[test]
    // SED follows time, not position: a sample late in time is compared with a later point.
    fn sed_is_synchronised_in_time() {
        // Middle sample at (1, 0) but at t = 30 of 40: the chord is at (1.5, 0) then.
        let stroke = [s(0.0, 0.0, 0.0), s(1.0, 0.0, 30.0), s(2.0, 0.0, 40.0)];
        check(&stroke, &[0, 2], m(3, 2, 100.0 / 3.0, 0.0, 0.0, 0.5 / 3.0));
    }

    #[test]
    // Equal timestamps fall back to the index fraction instead of dividing by zero.
    fn sed_with_equal_timestamps() {
        let stroke = [s(0.0, 0.0, 5.0), s(3.0, 0.0, 5.0), s(1.0, 0.0, 5.0), s(3.0, 0.0, 5.0)];
        // f = 1/3 and 2/3 along (0,0)-(3,0): points (1,0) and (2,0); distances 2 and 1.
        check(&stroke, &[0, 3], m(4, 2, 50.0, 0.0, (7.0 - 3.0) / 7.0 * 100.0, 3.0 / 4.0));
    }

    #[test]
    // E_max uses the segment that spans a sample, even when another segment is nearer.
    fn e_max_uses_the_spanning_segment() {
        // Samples 1 lies on segment 2-3 but is spanned by 0-2.
        let stroke = [s(0.0, 0.0, 0.0), s(4.0, 2.0, 1.0), s(4.0, 0.0, 2.0), s(4.0, 4.0, 3.0)];
        let l_o = 20f64.sqrt() + 2.0 + 4.0;
        let sed = ((4.0f64 - 2.0).hypot(2.0)) / 4.0;
        check(&stroke, &[0, 2, 3], m(4, 3, 25.0, 2.0, (l_o - 8.0) / l_o * 100.0, sed));
    }

    #[test]
    // Samples outside the kept range are measured against the nearest kept end.
    fn samples_outside_the_kept_range() {
        let stroke = [s(0.0, 0.0, 0.0), s(3.0, 4.0, 1.0), s(6.0, 8.0, 2.0)];
        check(&stroke, &[1], m(3, 1, 200.0 / 3.0, 5.0, 100.0, 10.0 / 3.0));
    }

    #[test]
    // A stroke that never moves has no length to lose.
    fn zero_length_stroke() {
        let stroke = [s(1.0, 1.0, 0.0), s(1.0, 1.0, 0.0)];
        check(&stroke, &[0], m(2, 1, 50.0, 0.0, 0.0, 0.0));
    }

    #[test]
    // Bad kept indices and bad samples are refused with a clear error.
    fn refuses_bad_input() {
        let stroke = [s(0.0, 0.0, 0.0), s(1.0, 0.0, 1.0), s(2.0, 0.0, 2.0)];
        let cases: [(&[Sample], &[usize], &str); 5] = [
            (&stroke, &[], "keeps no sample (the original has 3)"),
            (&stroke, &[0, 3], "kept[1] = 3 is out of range: the original has 3 samples"),
            (&stroke, &[0, 2, 2], "kept[2] = 2 does not follow kept[1] = 2"),
            (&stroke, &[1, 0], "kept[1] = 0 does not follow kept[0] = 1"),
            (&[s(0.0, 0.0, 1.0), s(0.0, 0.0, 0.0)], &[0, 1], "original stroke: sample 1: time"),
        ];
        for (original, kept, text) in cases {
            let err = simplification_metrics(original, kept).unwrap_err();
            assert!(err.to_string().contains(text), "{err} should contain {text:?}");
        }
        let err = cdf_error_area(&stroke, &[0], &[]).unwrap_err();
        assert_eq!(err, MetricsError::EmptyReference);
    }

    #[test]
    // The CDF area is the mean gap between the sorted error distributions.
    fn cdf_area_against_a_reference_line() {
        // Reference: the x axis. Errors of T_o: 0, 2, 0, 1; T_s keeps indices 0 and 1: 0, 2.
        // F_o = 1/2 on [0,1), 3/4 on [1,2), 1 after; F_s = 1/2 on [0,2), 1 after.
        // Area = |1/2 - 1/2| * 1 + |3/4 - 1/2| * 1 = 1/4.
        let stroke = [s(0.0, 0.0, 0.0), s(1.0, 2.0, 1.0), s(2.0, 0.0, 2.0), s(3.0, 1.0, 3.0)];
        let reference = [s(-10.0, 0.0, 0.0), s(10.0, 0.0, 1.0)];
        let cases: [(&[usize], f64); 3] = [(&[0, 1], 0.25), (&[0, 1, 2, 3], 0.0), (&[2], 0.75)];
        for (kept, expected) in cases {
            let got = cdf_error_area(&stroke, kept, &reference).unwrap();
            assert!((got - expected).abs() < 1e-12, "{kept:?}: got {got}, expected {expected}");
        }
        // A one-point reference measures distances to that point.
        let got = cdf_error_area(&stroke, &[0], &[s(0.0, 0.0, 0.0)]).unwrap();
        let mean_error = (0.0 + 5f64.sqrt() + 2.0 + 10f64.sqrt()) / 4.0;
        assert!((got - mean_error).abs() < 1e-12, "{got}");
    }
}
