//! ACUTS: angle-chord height united trajectory simplification (paper section III, made precise
//! in `shared/spec/algorithms.md`). Two streaming stages, each O(1) time and memory per sample.
//!
//! # Stage 1: chord-length resampling ([`Resampler`], [`resample`])
//!
//! Runs on the client as samples arrive. The first sample is kept; a sample is kept iff it lies
//! at least `l_eps` from the last kept sample (compared as squared distances, no square root);
//! the last sample (pen-up) is always kept, so the stroke ends where the pen lifted.
//!
//! The repeat rule (on by default, whatever `l_eps`): a sample whose `x` and `y` equal those of
//! the last kept sample, and whose pressure is within [`DEFAULT_REPEAT_PRESSURE_TOLERANCE`] of
//! it, is dropped (a pen at rest reports its position again and again). It costs no position
//! error: the dropped sample lies where a sample stage 2 bounds lies, so it is as near to every
//! segment as that one. It bounds pressure only against the kept sample at the same position;
//! against the pressure interpolated in time along its segment (`P_max`) it bounds nothing:
//! where the pressure ramps while the pen rests, a dropped repeat can be further than `delta_p`
//! from it (0.253 on the Dutch signatures, `docs/results.md`).
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
//! within `delta_p` of the pressure interpolated in time along `a–e` (what `penmesh eval`
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
//!   The interpolation test bounds exactly the error `penmesh eval` measures as `P_max` (time
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

use glam::DVec2;
use serde::{Deserialize, Serialize};

use crate::model::Sample;

/// Default chord-length threshold `l_eps` of stage 1, px: 0, stage 1 keeps every sample. The
/// paper's table 3 has 1.0, which spends more than half of the guaranteed bound
/// `d_d + l_eps = 1.74` px on stage 1 (about twice the optimum, `docs/results.md`); any
/// `l_eps > 0` also drops samples whatever their pressure (a pen-up tail loses its pressure fall
/// within a fraction of a pixel), so the pressure bound of stage 2 would not hold end to end.
/// With 0 the whole budget goes to stage 2 and both bounds hold end to end.
pub const DEFAULT_RESAMPLE_DISTANCE: f64 = 0.0;
/// Default pressure tolerance of stage 1's repeat rule ([`Resampler::repeat_pressure`]): a
/// sample at the position of the last kept one is dropped when its pressure is within this of
/// that sample's. The stage-2 pressure tolerance, so that a dropped repeat is never further in
/// pressure from the sample kept in its place than stage 2 lets a removed sample be.
pub const DEFAULT_REPEAT_PRESSURE_TOLERANCE: f64 = DEFAULT_PRESSURE_TOLERANCE;
/// Default chord-height tolerance `d_d` (same unit as x, y; table 3: 0.74): the paper's
/// guaranteed bound of 1.74 px, all of it for stage 2 (see [`DEFAULT_RESAMPLE_DISTANCE`]).
pub const DEFAULT_TOLERANCE: f64 = 1.74;
// The defaults keep the guaranteed bound of the paper's setting, d_d + l_eps = 0.74 + 1.0 px,
// checked when the crate compiles.
const _: () = assert!(
    (DEFAULT_TOLERANCE + DEFAULT_RESAMPLE_DISTANCE
        - (AcutsParams::paper().tolerance + PAPER_RESAMPLE_DISTANCE))
        .abs()
        < 1e-12
);
/// Default angle threshold `d_alpha` in degrees (table 3: 15°). At 15° the angle test, not the
/// distance, retains most samples near the anchor, where pen jitter makes directions noisy; 45°
/// still keeps every skipped sample beyond `d_d` of the anchor within 45° of the retained
/// chord's direction (see [`AcutsParams::angle_near_anchor`]).
pub const DEFAULT_ANGLE_DEG: f64 = 45.0;
/// Default pressure tolerance `delta_p` of the interpolation gate ([`PressureGate`]), for `p`
/// in `[0, 1]`: every removed sample's pressure lies within 0.2 of the pressure interpolated
/// (linearly in time) along its retained segment. With the default brush (radius `8 · 0.5 · p`
/// px) that is 0.8 px of radius, under half of the default 1.74 px bound on position. (The
/// paper's variance gate at the former default 0.01 bounded nothing and let 0.27 through on
/// SVC2004.)
pub const DEFAULT_PRESSURE_TOLERANCE: f64 = 0.2;
/// The pressure-variance threshold `d_sigma2` of the paper's table 3 (1500 on a 1024-level
/// tablet, rescaled to `p` in `[0, 1]`), for [`PressureGate::Variance`].
pub const PAPER_PRESSURE_VARIANCE: f64 = 0.0015;
/// The stage-1 distance `l_eps` of the paper's table 3, px.
pub const PAPER_RESAMPLE_DISTANCE: f64 = 1.0;

/// What stage 2 asks of the pressure of the samples it removes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PressureGate {
    /// The paper's gate (formula 3, `W_s = 3`): the candidate `m` is retained when the
    /// population variance of the pressures of `{a, m, e}` exceeds this threshold `d_sigma2`.
    /// A drift heuristic: it bounds no error.
    Variance(f64),
    /// The interpolation test (the default): `m` is removed only if every skipped `q` in
    /// `R ∪ {m}` has `|p_q - lerp(p_a, p_e, tau_q)| <= delta_p`, this value, with
    /// `tau_q = (t_q - t_a) / (t_e - t_a)`. A guarantee: stage 2's pressure error is at most
    /// `delta_p`, measured as `penmesh eval`'s `P_max`.
    Interpolation(f64),
}

/// Stage-2 parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AcutsParams {
    /// Chord-height tolerance `d_d`.
    pub tolerance: f64,
    /// Angle threshold `d_alpha`, degrees.
    pub angle_deg: f64,
    /// Whether the angle test also applies to skipped samples within `d_d` of the anchor (the
    /// paper's test: `true`). The default, `false`, leaves them to the distance test: such a
    /// sample lies within `d_d` of every segment from the anchor, and its direction from the
    /// anchor is pen jitter at that scale (on the Dutch signatures the angle test there was the
    /// largest geometric cost, `docs/results.md`).
    pub angle_near_anchor: bool,
    /// The pressure gate.
    pub pressure: PressureGate,
}

impl Default for AcutsParams {
    fn default() -> AcutsParams {
        AcutsParams {
            tolerance: DEFAULT_TOLERANCE,
            angle_deg: DEFAULT_ANGLE_DEG,
            angle_near_anchor: false,
            pressure: PressureGate::Interpolation(DEFAULT_PRESSURE_TOLERANCE),
        }
    }
}

impl AcutsParams {
    /// The setting of the paper's table 3 (with [`PAPER_RESAMPLE_DISTANCE`] for stage 1):
    /// `d_d` 0.74, 15°, the angle test near the anchor, the variance gate at 0.0015.
    pub const fn paper() -> AcutsParams {
        AcutsParams {
            tolerance: 0.74,
            angle_deg: 15.0,
            angle_near_anchor: true,
            pressure: PressureGate::Variance(PAPER_PRESSURE_VARIANCE),
        }
    }
}

/// A parameter outside its range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{name} = {value} is outside {range}")]
pub struct ParamError {
    pub name: &'static str,
    pub value: f64,
    pub range: &'static str,
}

impl AcutsParams {
    /// Parameters checked on construction: an out-of-range value is refused with its name.
    pub fn new(
        tolerance: f64,
        angle_deg: f64,
        angle_near_anchor: bool,
        pressure: PressureGate,
    ) -> Result<AcutsParams, ParamError> {
        let params = AcutsParams { tolerance, angle_deg, angle_near_anchor, pressure };
        params.validate()?;
        Ok(params)
    }

    /// Checks every parameter against its range (`tolerance` and the pressure threshold
    /// finite and `>= 0`, `angle_deg` in `[0, 90]`).
    pub fn validate(&self) -> Result<(), ParamError> {
        let bad = |name, value: f64, ok: bool, range| {
            if ok && value.is_finite() { Ok(()) } else { Err(ParamError { name, value, range }) }
        };
        bad("tolerance", self.tolerance, self.tolerance >= 0.0, "[0, inf)")?;
        bad("angle_deg", self.angle_deg, (0.0..=90.0).contains(&self.angle_deg), "[0, 90]")?;
        match self.pressure {
            PressureGate::Variance(v) => bad("pressure.variance", v, v >= 0.0, "[0, inf)"),
            PressureGate::Interpolation(d) => {
                bad("pressure.interpolation", d, d >= 0.0, "[0, inf)")
            }
        }
    }
}

/// A sample stage 2 decided to keep, with its index in the stage-2 input stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kept {
    pub index: usize,
    pub sample: Sample,
}

/// Stage 1: streaming chord-length resampler, with the repeat rule (see the module docs).
#[derive(Debug, Clone)]
pub struct Resampler {
    /// `l_eps²`: 0 when `l_eps <= 0` (every sample is kept), NaN when `l_eps` is NaN.
    min_distance_sq: f64,
    /// The repeat rule's pressure tolerance; `None` keeps repeats (then only `l_eps` drops).
    repeat_pressure: Option<f64>,
    last_kept: Option<Sample>,
    /// The newest sample if it was not kept, with its input index: kept at [`Resampler::finish`].
    pending_tail: Option<(usize, Sample)>,
    n_seen: usize,
}

impl Resampler {
    /// Chord length `l_eps` (`<= 0`: none), and the repeat rule at
    /// [`DEFAULT_REPEAT_PRESSURE_TOLERANCE`].
    pub fn new(min_distance: f64) -> Resampler {
        let min_distance_sq =
            if min_distance.is_nan() { f64::NAN } else { min_distance.max(0.0).powi(2) };
        Resampler {
            min_distance_sq,
            repeat_pressure: Some(DEFAULT_REPEAT_PRESSURE_TOLERANCE),
            last_kept: None,
            pending_tail: None,
            n_seen: 0,
        }
    }

    /// The repeat rule: drop a sample whose `x` and `y` equal the last kept sample's and whose
    /// pressure is within `tolerance` of its pressure; `None` keeps every repeat (so with
    /// `l_eps <= 0` every sample is kept). A negative or NaN tolerance drops nothing either.
    pub fn repeat_pressure(mut self, tolerance: Option<f64>) -> Resampler {
        self.repeat_pressure = tolerance;
        self
    }

    /// Pushes the next sample; returns whether it is kept.
    pub fn push(&mut self, s: Sample) -> bool {
        let index = self.n_seen;
        self.n_seen += 1;
        let keep = match &self.last_kept {
            None => true,
            Some(last) => {
                let (dx, dy) = (s.x - last.x, s.y - last.y);
                let repeat = dx == 0.0
                    && dy == 0.0
                    && self.repeat_pressure.is_some_and(|tol| (s.p - last.p).abs() <= tol);
                !repeat && dx * dx + dy * dy >= self.min_distance_sq
            }
        };
        if keep {
            self.last_kept = Some(s);
            self.pending_tail = None;
        } else {
            self.pending_tail = Some((index, s));
        }
        keep
    }

    /// Pen-up: the last sample, with its input index, if it was not kept already.
    pub fn finish(&mut self) -> Option<(usize, Sample)> {
        let tail = self.pending_tail.take();
        if let Some((_, s)) = tail {
            self.last_kept = Some(s);
        }
        tail
    }
}

/// Stage 1 over a whole stroke, as [`Resampler::new`] runs it (the repeat rule included): the
/// input indices kept, in order.
pub fn resample(samples: &[Sample], min_distance: f64) -> Vec<usize> {
    let mut resampler = Resampler::new(min_distance);
    let mut kept = Vec::with_capacity(samples.len());
    for (index, s) in samples.iter().enumerate() {
        if resampler.push(*s) {
            kept.push(index);
        }
    }
    if let Some((index, _)) = resampler.finish() {
        kept.push(index);
    }
    kept
}

/// Squared offsets from the anchor outside `[MIN_LENGTH_SQ, MAX_LENGTH_SQ]` (but not zero) are
/// not trusted, so that products of up to four lengths neither overflow nor underflow: the
/// candidate is retained. That is lengths outside `[1e-60, 1e75]`.
const MIN_LENGTH_SQ: f64 = 1e-120;
const MAX_LENGTH_SQ: f64 = 1e150;
/// Smallest ratio `cos / sin` of a cone's half-angle, so that every cone is narrower than a
/// half-plane (half-angles at most 90° - 1e-12 rad).
const MIN_COT_HALF_ANGLE: f64 = 1e-12;
/// The relaxed reach bound: skipped samples within `NEAR_FRACTION · d_d` of the ray may lie up
/// to `SLACK_FRACTION · d_d` beyond `e`, since `0.8² + 0.6² = 1` (the slack is a hair under 0.6
/// so that rounding cannot make the sum exceed 1).
const NEAR_FRACTION: f64 = 0.8;
const SLACK_FRACTION: f64 = 0.6 * (1.0 - 1e-9);

/// A cone of directions from the anchor, inside the open half-plane `reference · v > 0`: the
/// directions `v` whose tangent of angle from `reference`, `(reference × v) / (reference · v)`,
/// lies in `[lo, hi]`. It is empty when `lo > hi`.
#[derive(Debug, Clone, Copy)]
struct Cone {
    reference: DVec2,
    lo: f64,
    hi: f64,
}

impl Cone {
    /// The cone of directions within the half-angle `atan2(sin, cos)` (`cos > 0`) of `center`.
    fn around(center: DVec2, sin: f64, cos: f64) -> Cone {
        let mut cone = Cone { reference: center, lo: f64::NEG_INFINITY, hi: f64::INFINITY };
        cone.narrow(center, sin, cos);
        cone
    }

    /// Whether the direction `v` (any length; the zero vector is outside) is inside.
    fn contains(&self, v: DVec2) -> bool {
        let (along, across) = (self.reference.dot(v), self.reference.perp_dot(v));
        along > 0.0 && across >= self.lo * along && across <= self.hi * along
    }

    /// Intersects with the cone of half-angle `atan2(sin, cos)` around `center`, narrower than a
    /// half-plane. Its part inside the half-plane of `reference` is one arc (or nothing), whose
    /// bounds are its own boundaries where they lie inside the half-plane, else the half-plane's.
    fn narrow(&mut self, center: DVec2, sin: f64, cos: f64) {
        let (u, w) = (self.reference.dot(center), self.reference.perp_dot(center));
        // `center` rotated by -beta and +beta, in the frame of `reference`.
        let (lo_along, lo_across) = (cos * u + sin * w, cos * w - sin * u);
        let (hi_along, hi_across) = (cos * u - sin * w, cos * w + sin * u);
        if lo_along > 0.0 {
            self.lo = self.lo.max(lo_across / lo_along);
        } else if hi_along <= 0.0 {
            // Both boundaries outside the half-plane: so is the whole arc.
            self.lo = f64::INFINITY;
        }
        if hi_along > 0.0 {
            self.hi = self.hi.min(hi_across / hi_along);
        }
    }
}

/// The candidate `m`, with its offset from the anchor and the squared length of that offset.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    index: usize,
    sample: Sample,
    offset: DVec2,
    distance_sq: f64,
}

impl Candidate {
    fn new(index: usize, sample: Sample, anchor: &Sample) -> Candidate {
        let offset = sample.pos() - anchor.pos();
        Candidate { index, sample, offset, distance_sq: offset.length_squared() }
    }
}

/// Whether an offset from the anchor is zero or of a length the tests can trust.
fn trusted(offset: DVec2, length_sq: f64) -> bool {
    offset == DVec2::ZERO || (MIN_LENGTH_SQ..=MAX_LENGTH_SQ).contains(&length_sq)
}

/// Stage 2: streaming windowed simplifier, O(1) time and memory per sample (see the module
/// documentation for the test and its guarantee).
#[derive(Debug, Clone)]
pub struct Simplifier {
    params: AcutsParams,
    /// `d_d`, clamped to `[0, inf]`, and its square.
    tolerance: f64,
    tolerance_sq: f64,
    /// `sin(d_alpha)` with `d_alpha` clamped to `[0°, 90°]`, and its square.
    sin_angle: f64,
    sin_angle_sq: f64,
    /// `cos(d_alpha)`, at least [`MIN_COT_HALF_ANGLE`]` * sin(d_alpha)`.
    cos_angle: f64,
    anchor: Option<Sample>,
    candidate: Option<Candidate>,
    /// The directions from the anchor that every skipped sample admits; `None`: no constraint.
    cone: Option<Cone>,
    /// The largest squared distance from the anchor to a skipped sample.
    reach_sq: f64,
    /// The directions that keep every skipped sample within `NEAR_FRACTION · d_d` of the ray
    /// (distance only); `None`: no constraint. With the slack below, it relaxes the reach bound.
    near_cone: Option<Cone>,
    /// `(NEAR_FRACTION · d_d)²`.
    near_tolerance_sq: f64,
    /// `SLACK_FRACTION · d_d`: how far `e` may fall short of the reach (see the module docs).
    slack: f64,
    /// The pressure interpolation test's state for the current anchor.
    pressure: PressureWedge,
    n_seen: usize,
}

/// The state of the pressure interpolation test ([`PressureGate::Interpolation`]) for one
/// anchor `a`: a one-dimensional Chan–Chin wedge. A skipped `q` with `t_q > t_a` admits the
/// slopes `s = (p_e - p_a) / (t_e - t_a)` with `|p_q - p_a - s (t_q - t_a)| <= delta_p`, an
/// interval; `[slope_lo, slope_hi]` is the intersection over `R`. A `q` with `t_q == t_a`
/// (`tau_q = 0`) needs `|p_q - p_a| <= delta_p`, which it passed when it was removed, whatever
/// `e`; and when `t_e == t_a`, where `tau` is undefined, every `q` must lie within `delta_p` of
/// both `p_a` and `p_e` (so of any interpolation between them), hence the range of `p` over `R`.
#[derive(Debug, Clone, Copy)]
struct PressureWedge {
    slope_lo: f64,
    slope_hi: f64,
    p_min: f64,
    p_max: f64,
}

impl PressureWedge {
    const OPEN: PressureWedge = PressureWedge {
        slope_lo: f64::NEG_INFINITY,
        slope_hi: f64::INFINITY,
        p_min: f64::INFINITY,
        p_max: f64::NEG_INFINITY,
    };

    /// Whether every `q` in `R ∪ {m}` is within `delta` of the pressure interpolated along
    /// `a–e`: `R` through the wedge, `m` exactly. No division. Any NaN (only from values out of
    /// range, e.g. time differences that overflow) retains.
    fn admits(&self, a: &Sample, m: &Sample, e: &Sample, delta: f64) -> bool {
        let (dt_e, dp_e) = (e.t - a.t, e.p - a.p);
        if dt_e > 0.0 {
            let (dt_m, dp_m) = (m.t - a.t, m.p - a.p);
            (dp_m * dt_e - dp_e * dt_m).abs() <= delta * dt_e
                && self.slope_lo * dt_e <= dp_e
                && dp_e <= self.slope_hi * dt_e
        } else {
            // `t_e == t_a` (time never goes backwards in a valid stroke): so are all `t_q`.
            let (lo, hi) = (self.p_min.min(m.p), self.p_max.max(m.p));
            hi - delta <= a.p.min(e.p) && a.p.max(e.p) <= lo + delta
        }
    }

    /// Adds a removed `q` (it passed [`PressureWedge::admits`] as `m`).
    fn fold(&mut self, a: &Sample, q: &Sample, delta: f64) {
        self.p_min = self.p_min.min(q.p);
        self.p_max = self.p_max.max(q.p);
        let (dt, dp) = (q.t - a.t, q.p - a.p);
        if dt > 0.0 {
            let inverse = 1.0 / dt;
            let (lo, hi) = ((dp - delta) * inverse, (dp + delta) * inverse);
            // A NaN bound replaces the old one and so retains from then on.
            if lo > self.slope_lo || lo.is_nan() {
                self.slope_lo = lo;
            }
            if hi < self.slope_hi || hi.is_nan() {
                self.slope_hi = hi;
            }
        }
    }
}

impl Simplifier {
    /// A simplifier for valid parameters ([`AcutsParams::validate`]; every entry point checks
    /// them, so an invalid value here is a bug of the caller's).
    pub fn new(params: AcutsParams) -> Simplifier {
        debug_assert!(params.validate().is_ok(), "unchecked ACUTS parameters: {params:?}");
        let tolerance = params.tolerance;
        let (sin_angle, cos_angle) = params.angle_deg.to_radians().sin_cos();
        Simplifier {
            params,
            tolerance,
            tolerance_sq: tolerance * tolerance,
            sin_angle,
            sin_angle_sq: sin_angle * sin_angle,
            cos_angle: cos_angle.max(MIN_COT_HALF_ANGLE * sin_angle),
            anchor: None,
            candidate: None,
            cone: None,
            reach_sq: 0.0,
            near_cone: None,
            near_tolerance_sq: (NEAR_FRACTION * tolerance).powi(2),
            slack: SLACK_FRACTION * tolerance,
            pressure: PressureWedge::OPEN,
            n_seen: 0,
        }
    }

    pub fn params(&self) -> &AcutsParams {
        &self.params
    }

    /// Pushes the next sample; returns the sample this push decided to keep, if any.
    pub fn push(&mut self, e: Sample) -> Option<Kept> {
        let index = self.n_seen;
        self.n_seen += 1;
        let Some(a) = self.anchor else {
            self.anchor = Some(e);
            return Some(Kept { index, sample: e });
        };
        let Some(m) = self.candidate else {
            self.candidate = Some(Candidate::new(index, e, &a));
            return None;
        };
        let pressure_admits = match self.params.pressure {
            PressureGate::Variance(threshold) => {
                // As the spec words it: retained when the variance exceeds the threshold.
                let retains = pressure_variance(a.p, m.sample.p, e.p) > threshold;
                !retains
            }
            PressureGate::Interpolation(delta) => self.pressure.admits(&a, &m.sample, &e, delta),
        };
        if pressure_admits {
            let next = Candidate::new(index, e, &a);
            if self.admits(&m, next.offset, next.distance_sq) {
                self.fold(m.offset, m.distance_sq);
                if let PressureGate::Interpolation(delta) = self.params.pressure {
                    self.pressure.fold(&a, &m.sample, delta);
                }
                self.candidate = Some(next);
                return None;
            }
        }
        self.anchor = Some(m.sample);
        self.cone = None;
        self.reach_sq = 0.0;
        self.near_cone = None;
        self.pressure = PressureWedge::OPEN;
        self.candidate = Some(Candidate::new(index, e, &m.sample));
        Some(Kept { index: m.index, sample: m.sample })
    }

    /// Pen-up: the pending candidate is kept. The simplifier then starts afresh, as
    /// [`Simplifier::new`] with the same parameters (indices restart at 0 for the next stroke).
    pub fn finish(&mut self) -> Option<Kept> {
        let last = self.candidate.map(|m| Kept { index: m.index, sample: m.sample });
        *self = Simplifier::new(self.params);
        last
    }

    /// Whether every `q` in `R ∪ {m}` passes the geometry test against the segment `a–e`, where
    /// `ae = e - a` and `ae_len_sq = |ae|²`. Conservative as the module documentation says.
    fn admits(&self, m: &Candidate, ae: DVec2, ae_len_sq: f64) -> bool {
        if !(trusted(ae, ae_len_sq) && trusted(m.offset, m.distance_sq)) {
            return false;
        }
        if ae == DVec2::ZERO {
            // The segment is the point `a`: angles pass, distances are `|aq|`.
            return self.reach_sq <= self.tolerance_sq && m.distance_sq <= self.tolerance_sq;
        }
        let reach_ok = self.reach_sq <= self.tolerance_sq
            || ae_len_sq >= self.reach_sq
            || (ae_len_sq.sqrt() >= self.reach_sq.sqrt() - self.slack
                && self.near_cone.is_none_or(|cone| cone.contains(ae)));
        let cone_ok = self.cone.is_none_or(|cone| cone.contains(ae));
        reach_ok && cone_ok && self.admits_exactly(m.offset, m.distance_sq, ae, ae_len_sq)
    }

    /// The geometry test for one `q` at `aq = q - a`, `r² = |aq|²`, against `ae = e - a != 0`,
    /// `|ae|²`. Squared throughout: `along = r |ae| cos(angle)`, `across = r |ae| sin(angle)`.
    fn admits_exactly(&self, aq: DVec2, r_sq: f64, ae: DVec2, ae_len_sq: f64) -> bool {
        if aq == DVec2::ZERO || (!self.params.angle_near_anchor && r_sq <= self.tolerance_sq) {
            // Within `d_d` of `a`, so of the segment; the angle is not asked there.
            return true;
        }
        let along = aq.dot(ae);
        let across = aq.perp_dot(ae);
        let across_sq = across * across;
        // angle <= d_alpha <= 90° iff cos >= 0 and sin <= sin(d_alpha).
        if !(along >= 0.0 && across_sq <= self.sin_angle_sq * r_sq * ae_len_sq) {
            return false;
        }
        if along <= ae_len_sq {
            // The foot is on the segment: the distance is `r sin(angle) = across / |ae|`.
            across_sq <= self.tolerance_sq * ae_len_sq
        } else {
            // The foot is beyond `e`: the distance is `|qe|`.
            (aq - ae).length_squared() <= self.tolerance_sq
        }
    }

    /// Adds a removed sample at `aq = q - a`, `r² = |aq|²`, to the cone and the reach.
    fn fold(&mut self, aq: DVec2, r_sq: f64) {
        if aq == DVec2::ZERO || (!self.params.angle_near_anchor && r_sq <= self.tolerance_sq) {
            // No constraint: within `d_d` of every segment from `a`, and the angle is not asked.
            return;
        }
        self.reach_sq = self.reach_sq.max(r_sq);
        let (sin, cos) = if r_sq * self.sin_angle_sq <= self.tolerance_sq {
            (self.sin_angle, self.cos_angle)
        } else {
            // asin(d_d / r) < d_alpha: sin : cos = d_d : sqrt(r² - d_d²).
            let cos = (r_sq - self.tolerance_sq).sqrt().max(MIN_COT_HALF_ANGLE * self.tolerance);
            (self.tolerance, cos)
        };
        match &mut self.cone {
            None => self.cone = Some(Cone::around(aq, sin, cos)),
            Some(cone) => cone.narrow(aq, sin, cos),
        }
        if r_sq > self.near_tolerance_sq {
            // asin(d' / r) with d' = NEAR_FRACTION · d_d: sin : cos = d' : sqrt(r² - d'²).
            let near = self.near_tolerance_sq.sqrt();
            let cos = (r_sq - self.near_tolerance_sq).sqrt().max(MIN_COT_HALF_ANGLE * near);
            match &mut self.near_cone {
                None => self.near_cone = Some(Cone::around(aq, near, cos)),
                Some(cone) => cone.narrow(aq, near, cos),
            }
        }
    }
}

/// Population variance of three pressures (paper formula 3, `W_s = 3`), computed as the mean
/// squared pairwise difference `((p0-p1)² + (p1-p2)² + (p2-p0)²) / 9`, which is the same value
/// without a division (this runs once per sample).
pub fn pressure_variance(p0: f64, p1: f64, p2: f64) -> f64 {
    let (d01, d12, d20) = (p0 - p1, p1 - p2, p2 - p0);
    (d01 * d01 + d12 * d12 + d20 * d20) * (1.0 / 9.0)
}

/// Distance from `q` to the segment `a–b`.
pub fn segment_distance(q: &Sample, a: &Sample, b: &Sample) -> f64 {
    let (ab, aq) = (b.pos() - a.pos(), q.pos() - a.pos());
    let len2 = ab.length_squared();
    if len2 == 0.0 {
        return aq.length();
    }
    let t = (aq.dot(ab) / len2).clamp(0.0, 1.0);
    (aq - ab * t).length()
}

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
        for (index, s) in samples.iter().enumerate() {
            if resampler.push(*s) {
                to_stage2(index, *s, &mut resampled);
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

#[cfg(test)]
mod tests {
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

    // The repeat rule looks at pressure: a repeat whose pressure moved past the tolerance is
    // kept, and without the rule every repeat is kept.
    #[test]
    fn repeat_rule_keeps_pressure_changes_and_can_be_off() {
        let stroke = [
            Sample::new(0.0, 0.0, 0.0, 0.5),
            Sample::new(0.0, 0.0, 1.0, 0.6),
            Sample::new(0.0, 0.0, 2.0, 0.71),
            Sample::new(0.0, 0.0, 3.0, 0.9),
            Sample::new(0.5, 0.0, 4.0, 0.9),
        ];
        let kept = |resampler: Resampler| {
            let mut resampler = resampler;
            let mut kept: Vec<usize> =
                (0..stroke.len()).filter(|&i| resampler.push(stroke[i])).collect();
            kept.extend(resampler.finish().map(|(i, _)| i));
            kept
        };
        assert_eq!(kept(Resampler::new(0.0)), [0, 2, 4]);
        assert_eq!(kept(Resampler::new(0.0).repeat_pressure(Some(0.0))), [0, 1, 2, 3, 4]);
        assert_eq!(kept(Resampler::new(0.0).repeat_pressure(None)), [0, 1, 2, 3, 4]);
    }

    // Stage 1 streaming reports each decision and the tail index at finish.
    #[test]
    fn resampler_streaming() {
        let mut r = Resampler::new(1.0);
        assert!(r.push(at(0.0, 0.0)));
        assert!(!r.push(at(0.5, 0.0)));
        assert!(r.push(at(1.5, 0.0)));
        assert!(!r.push(at(1.7, 0.0)));
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
        let xys =
            [(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (3.0, 0.0), (3.0, 1.0), (3.0, 2.0), (3.0, 3.0)];
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
        let older = [
            (0.0, 0.0, 0.0, 0.5),
            (1.0, 0.0, 1.0, 0.6),
            (2.0, 0.0, 2.0, 0.7),
            (3.0, 0.0, 3.0, 0.5),
        ];
        assert_eq!(simplify(&with_pressure(&older), &interpolation(0.05)), [0, 2, 3]);
    }

    // Samples at the anchor's time: tau = 0 when e is later (within delta_p of p_a), and within
    // delta_p of both ends when e has the anchor's time too.
    #[test]
    fn simplify_pressure_interpolation_equal_times() {
        let p = interpolation(0.1);
        let same_t = [
            (0.0, 0.0, 0.0, 0.5),
            (1.0, 0.0, 0.0, 0.55),
            (2.0, 0.0, 0.0, 0.62),
            (3.0, 0.0, 0.0, 0.7),
        ];
        // At e = 2: 0.55 is within 0.1 of 0.5 and 0.62; at e = 3, 0.55 is 0.15 from 0.7.
        assert_eq!(simplify(&with_pressure(&same_t), &p), [0, 2, 3]);
        let then_later = [
            (0.0, 0.0, 0.0, 0.5),
            (1.0, 0.0, 0.0, 0.58),
            (2.0, 0.0, 5.0, 0.9),
            (3.0, 0.0, 6.0, 0.9),
        ];
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
        let bad =
            AcutsParams { pressure: PressureGate::Interpolation(-0.1), ..AcutsParams::default() };
        assert_eq!(bad.validate().unwrap_err().name, "pressure.interpolation");
        let bad =
            AcutsParams { pressure: PressureGate::Variance(f64::NAN), ..AcutsParams::default() };
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
        assert!(
            ray.contains(DVec2::X * 3.0) && !ray.contains(-DVec2::X) && !ray.contains(DVec2::ZERO)
        );
        assert!(narrowed(ray, 0.0, 0.0).contains(DVec2::X));
        assert!(!narrowed(ray, 180.0, 0.0).contains(DVec2::X));
        assert!(!narrowed(ray, 180.0, 0.0).contains(-DVec2::X));
        // A wide cone whose lower boundary is beyond -90° of the reference: that side stays open.
        let wide = narrowed(cone(0.0, 80.0), -60.0, 45.0);
        assert!(
            wide.contains(dir(-79.0)) && wide.contains(dir(-15.5)) && !wide.contains(dir(-14.0))
        );
        // Both boundaries outside the half-plane: empty.
        let opposite = narrowed(cone(0.0, 89.0), 180.0, 80.0);
        assert!((-89..=89).all(|d| !opposite.contains(dir(f64::from(d)))));
    }
}
