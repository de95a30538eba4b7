//! ACUTS: angle-chord height united trajectory simplification (paper section III, made precise
//! in `shared/spec/algorithms.md`). Two streaming stages, each O(1) time and memory per sample.
//!
//! # Stage 1: chord-length resampling ([`Resampler`], [`resample`])
//!
//! Runs on the client as samples arrive. The first sample is kept; a sample is kept iff it lies
//! at least `l_eps` from the last kept sample (compared as squared distances, no square root);
//! the last sample (pen-up) is always kept, so the stroke ends where the pen lifted.
//!
//! The repeat rule (on by default, whatever `l_eps`): a pen at rest reports the same sample
//! again and again. A sample equal to the last kept one in `x`, `y` and `p` (an *exact repeat*)
//! is held back; when the next sample that is not one comes, the last held repeat is let
//! through first if that sample's pressure differs from it (so a rest is sent as its first and
//! last sample, or as its first only when the pen leaves it at the same pressure), and at pen-up
//! it is let through as the last sample. This never takes from stage 2's bounds, over every
//! drawn sample, the dropped ones included: a dropped repeat `q` lies between two samples that
//! stage 2 sees one after the other, `u` (the rest's first) and `v` (the rest's last, or the
//! next sample when it has `u`'s pressure), at `u`'s position and with `p_q = p_u = p_v`; so
//! a retained segment that spans `q` spans `u` and `v` too (or ends at them), `q` is as far
//! from it as `u` is, and `q`'s pressure error is a weighted mean of `u`'s and `v`'s. A repeat
//! whose pressure differs is not dropped: the pressure interpolated in time along its segment
//! could miss it by more than stage 2 allows.
//!
//! # Stage 2: windowed simplification ([`Simplifier`], [`simplify`])
//!
//! Runs on the proxy over the resampled stream. The state is the anchor `a` (the last retained
//! sample), the skipped set `R` (samples removed since `a`) and the candidate `m` (the newest
//! undecided sample). When a sample `e` arrives, `m` is retained (and becomes the anchor) if
//! 1. the pressure gate ([`PressureGate`]) retains it:
//!    - `Interpolation(delta_p)` (the default): some `q` in `R ∪ {m}` has
//!      `|p_q - lerp(p_a, p_e, tau_q)| > delta_p`, `tau_q = (t_q - t_a) / (t_e - t_a)` (linear in
//!      time; when `t_e == t_a`, and so every `t_q`, `q` must be within `delta_p` of both `p_a`
//!      and `p_e`);
//!    - `Variance(d_sigma2)` (the paper's formula 3): the population variance of the pressures
//!      of `{a, m, e}` exceeds `d_sigma2`;
//! 2. or some `q` in `R ∪ {m}` fails the geometry test: `angle(a->q, a->e) <= d_alpha` (asked
//!    only of `q` farther than `d_d` from `a`, unless [`AcutsParams::angle_near_anchor`]) and
//!    the distance from `q` to the SEGMENT `a–e` is `<= d_d`;
//!
//! otherwise `m` is removed and joins `R`. The first sample is retained, and at pen-up so is the
//! pending `m`. A sample is decided one sample after it arrives.
//!
//! **Guarantee**: every removed sample `q` of the stage-2 input lies within `d_d` of the retained
//! segment `a–e` that spans it, `angle(a->q, a->e) <= d_alpha` (when `q != a`, `e != a`, and
//! `|aq| > d_d` or `angle_near_anchor`), and with the interpolation gate its pressure lies
//! within `delta_p` of the pressure interpolated in time along `a–e` (what `penmesh-lab eval`
//! reports as `P_max`), up to float rounding: a few ulps of the coordinates, the angle and the
//! pressure. End to end, stage 1 adds `l_eps` to the distance and bounds nothing of pressure;
//! the default `l_eps = 0` keeps both bounds end to end.
//!
//! # How the defaults differ from the spec (`shared/spec/algorithms.md`), and why
//!
//! Measured on the real signatures of `../shared/data` (`docs/results.md`, 2026-11-22):
//! - **Pressure**: the spec's gate is the variance of `{a, m, e}` (formula 3). It bounds no
//!   error (measured `P_max` 0.275 on SVC2004 at 0.01) yet retains a sample at every ~0.2 of
//!   drift on a linear pressure ramp, which interpolation reproduces exactly; on the 200 Hz
//!   Dutch signatures it was the largest cost (1.97x the optimum with the former defaults).
//!   The interpolation test bounds exactly the error `penmesh-lab eval` measures as `P_max` (time
//!   interpolation, a close stand-in for the radius the mesh interpolates along a segment), and
//!   lets ramps through. `delta_p = 0.2` is 0.8 px of radius with the
//!   default brush, under half of the 1.74 px position bound. The variance gate stays
//!   available ([`PressureGate::Variance`], [`AcutsParams::paper`]).
//! - **Angle near the anchor**: the spec asks the angle of every skipped sample. Within `d_d` of
//!   the anchor a sample is within `d_d` of every segment from the anchor, and its direction is
//!   pen jitter; on the Dutch set asking it there cost more than any other geometric test (the
//!   naive stage 2 with `l_eps` 0 and pressure off: 1.38x the optimum against 1.07x without
//!   it). Beyond `d_d` the angle holds.
//! - **Stage 1**: `l_eps = 0` (the spec: 1.0), so `d_d = 1.74` is the whole bound, and no
//!   pressure change is dropped unseen.
//!
//! # The constant-time geometry test
//!
//! `R` is never stored. Take `q != a` with `r = |aq|`, `e != a` and `theta = angle(a->q, a->e)`.
//! Once `theta <= d_alpha <= 90°`, the foot of `q` on the line `a–e` lies at `r cos(theta) >= 0`
//! from `a`, so the distance from `q` to the segment is at most `r`, and it is `r sin(theta)`
//! when the foot lies on the segment. Hence `q` passes
//! - if `r <= d_d`: iff `theta <= d_alpha`;
//! - if `r > d_d` and `|ae| >= r` (foot on the segment): iff
//!   `theta <= beta_q = min(d_alpha, asin(d_d / r))`.
//!
//! So the simplifier keeps, for the current anchor:
//! - the **cone**: the intersection over `q` in `R` of the direction cones
//!   `{u : angle(u, a->q) <= beta_q}` (`beta_q = d_alpha` when `r <= d_d`). Half-angles are
//!   capped at 90° - 1e-12 rad, so every cone, and the intersection, lies inside the open
//!   half-plane around the direction `a->q1` of the first skipped sample `q1 != a`. There a
//!   direction `v` is known by the tangent of its angle from `a->q1`,
//!   `t(v) = (aq1 × v) / (aq1 · v)`, which grows with the angle, so the cone is an interval
//!   `[lo, hi]` of tangents: `v` is inside iff `aq1 · v > 0` and
//!   `lo (aq1 · v) <= aq1 × v <= hi (aq1 · v)` (no division). Folding `q` in rotates `a->q` by
//!   `-beta_q` and `+beta_q` (`sin : cos = d_d : sqrt(r² - d_d²)` or `sin(d_alpha) : cos(d_alpha)`,
//!   no trigonometry), and takes `lo := max(lo, t(lo_q))`, `hi := min(hi, t(hi_q))`; a boundary
//!   outside the half-plane leaves that side open, both outside make the cone empty (an arc
//!   narrower than a half-turn whose ends are outside the half-plane lies outside it);
//! - the **reach** `rho = max |aq|` over `R`. `e` must satisfy `rho <= d_d` or `|ae| >= rho`,
//!   which puts the foot of every `q` with `r > d_d` on the segment; or, relaxed,
//!   `|ae| >= rho - 0.6 d_d` with `a->e` inside the **near cone**, the intersection of the
//!   distance-only cones of half-angle `asin(0.8 d_d / r)` (every `q` within `0.8 d_d` of the ray
//!   `a->e`). Then a `q` whose foot lies beyond `e` is at most `0.6 d_d` past it along the ray and
//!   `0.8 d_d` across, so within `sqrt(0.6² + 0.8²) d_d = d_d` of `e`. This keeps a pen that
//!   jitters back by a fraction of the tolerance from retaining a sample (on the real signatures
//!   of `../shared/data` that was the largest cost of the plain reach bound).
//!
//! The candidate `m` is tested exactly, as in the definition (including a foot beyond `e`:
//! distance `|me|`), and folded into the cone and reach once removed. When `e == a`, every `q`
//! passes iff `|aq| <= d_d`, which is `max(rho, |am|) <= d_d`: exact too. Samples equal to `a`
//! add no constraint.
//!
//! Samples within `d_d` of `a` need no cone when the angle is not asked of them (they pass
//! against any `e`), and are not folded.
//!
//! # The constant-time pressure test
//!
//! The interpolation test is a one-dimensional Chan–Chin wedge in the (time, pressure) plane
//! from `a`: a skipped `q` with `t_q > t_a` admits the slopes `s = (p_e - p_a) / (t_e - t_a)` in
//! `[(p_q - p_a - delta_p) / (t_q - t_a), (p_q - p_a + delta_p) / (t_q - t_a)]`; the simplifier
//! keeps the intersection `[s_lo, s_hi]` over `R` and tests `e` without division,
//! `s_lo (t_e - t_a) <= p_e - p_a <= s_hi (t_e - t_a)`. A `q` with `t_q == t_a` (`tau_q = 0`)
//! passed `|p_q - p_a| <= delta_p` when it was removed, whatever `e`; for `t_e == t_a` the range
//! of `p` over `R` decides. `m` is tested exactly. Exact, no conservative case; one division
//! (a reciprocal) per removed sample.
//!
//! Cost per sample: everything is computed on squared lengths, with cross and dot products; when
//! a sample is folded in, one square root (`sqrt(r² - d_d²)`, when `beta_q = asin(d_d / r)`) and
//! two independent divisions (the tangents of its cone's boundaries); no trigonometry.
//!
//! **When it is conservative.** The cone test is exact. The reach bound is only sufficient: when
//! `e` is nearer to `a` than an older skipped `q` with `|aq| > d_d` (by more than the relaxed
//! bound allows), the definition still
//! removes `m` if that `q` projects onto the segment or lies within `d_d` of `e`, while this test
//! retains `m`. Because `m` itself is tested exactly, this takes a stroke that steps back past an
//! older sample (a pen that turns back or jitters backwards), which forward-moving strokes rarely
//! do: on the random strokes of the property tests (`shared/tests/acuts_props.rs`, which report
//! it), none of 1e5 decisions differ on pen-like strokes at the default parameters, and under
//! 0.1 % on jittery or random-point strokes with a wide tolerance; on the real signatures it
//! keeps 0.2–1 % more than the naive definition (`docs/results.md`). Offsets from the anchor that
//! are not zero but shorter than `1e-60` or longer than `1e75` (where products of four lengths
//! would underflow or overflow), and half-angles within `1e-12` rad of 90°, are also treated
//! conservatively: the candidate is retained. Retaining a sample never breaks the guarantee.
//!
//! Parameters outside their range are refused where they enter, never clamped:
//! [`AcutsParams::new`] and [`AcutsParams::validate`] name the bad one, and every entry point
//! (the CLI, the proxy's settings at start-up, `StrokeBegin`) checks them before a [`Simplifier`]
//! is built.

mod measures;
mod params;
mod resample;
mod simplifier;
#[cfg(test)]
mod tests;

pub use measures::{pressure_variance, segment_distance};
pub use params::{
    AcutsParams, DEFAULT_ANGLE_DEG, DEFAULT_PRESSURE_TOLERANCE, DEFAULT_RESAMPLE_DISTANCE,
    DEFAULT_TOLERANCE, PAPER_PRESSURE_VARIANCE, PAPER_RESAMPLE_DISTANCE, ParamError, PressureGate,
};
pub use resample::{Released, Resampler, resample};
pub use simplifier::{Kept, Simplifier};

use crate::model::Sample;

/// Stage 2 over a whole (resampled) stroke: the indices kept, in order.
pub fn simplify(samples: &[Sample], params: &AcutsParams) -> Vec<usize> {
    let mut simplifier = Simplifier::new(*params);
    let mut kept: Vec<usize> =
        samples.iter().filter_map(|s| simplifier.push(*s)).map(|k| k.index).collect();
    kept.extend(simplifier.finish().map(|k| k.index));
    kept
}

/// Both stages over a whole stroke, as the client and proxy run them together.
#[derive(Debug, Clone, PartialEq)]
pub struct AcutsOutput {
    /// Input indices kept by stage 1.
    pub resampled: Vec<usize>,
    /// Input indices kept by stage 2 (a subset of `resampled`).
    pub kept: Vec<usize>,
}

/// Runs stage 1 (skipped when `resample_distance <= 0`) then stage 2, streaming each sample
/// kept by stage 1 straight into stage 2.
pub fn acuts(samples: &[Sample], resample_distance: f64, params: &AcutsParams) -> AcutsOutput {
    let mut resampled = Vec::with_capacity(samples.len());
    let mut kept = Vec::new();
    let mut simplifier = Simplifier::new(*params);
    let mut to_stage2 = |index: usize, s: Sample, resampled: &mut Vec<usize>| {
        resampled.push(index);
        if let Some(k) = simplifier.push(s) {
            kept.push(resampled[k.index]);
        }
    };
    if resample_distance > 0.0 {
        let mut resampler = Resampler::new(resample_distance);
        for s in samples {
            for (index, s) in resampler.push(*s) {
                to_stage2(index, s, &mut resampled);
            }
        }
        if let Some((index, s)) = resampler.finish() {
            to_stage2(index, s, &mut resampled);
        }
    } else {
        for (index, s) in samples.iter().enumerate() {
            to_stage2(index, *s, &mut resampled);
        }
    }
    if let Some(k) = simplifier.finish() {
        kept.push(resampled[k.index]);
    }
    AcutsOutput { resampled, kept }
}
