//! ACUTS: angle-chord height united trajectory simplification (paper section III, made precise
//! in `shared/spec/algorithms.md`). Two streaming stages, each O(1) time and memory per sample.
//!
//! # Stage 1: chord-length resampling ([`Resampler`], [`resample`])
//!
//! Runs on the client as samples arrive. The first sample is kept; a sample is kept iff it lies
//! at least `l_eps` from the last kept sample (compared as squared distances, no square root);
//! the last sample (pen-up) is always kept, so the stroke ends where the pen lifted.
//!
//! # Stage 2: windowed simplification ([`Simplifier`], [`simplify`])
//!
//! Runs on the proxy over the resampled stream. The state is the anchor `a` (the last retained
//! sample), the skipped set `R` (samples removed since `a`) and the candidate `m` (the newest
//! undecided sample). When a sample `e` arrives, `m` is retained (and becomes the anchor) if
//! 1. the population variance of the pressures of `{a, m, e}` exceeds `d_sigma2`, or
//! 2. some `q` in `R ∪ {m}` fails the geometry test: `angle(a->q, a->e) <= d_alpha` and the
//!    distance from `q` to the SEGMENT `a–e` is `<= d_d`;
//!
//! otherwise `m` is removed and joins `R`. The first sample is retained, and at pen-up so is the
//! pending `m`. A sample is decided one sample after it arrives.
//!
//! **Guarantee**: every removed sample `q` of the stage-2 input lies within `d_d` of the retained
//! segment `a–e` that spans it, and `angle(a->q, a->e) <= d_alpha` (when `q != a` and `e != a`),
//! up to float rounding: a few ulps of the coordinates, and of the angle.
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
//!   `{u : angle(u, a->q) <= beta_q}` (`beta_q = d_alpha` when `r <= d_d`), stored as its two
//!   boundary unit vectors `lo` (clockwise) and `hi`. A direction `v` is inside iff
//!   `lo × v >= 0`, `v × hi >= 0` and `v · (lo + hi) > 0` (the last excludes `-lo` when the cone
//!   is a single ray). Every cone is narrower than a half-plane (half-angles are capped just
//!   under 90°), so the intersection of two cones is one cone or empty, and its boundaries are
//!   among the four input boundaries: folding `q` in costs a few cross products and at most one
//!   square root (`cos(beta_q) = sqrt(r² - d_d²) / r`), with no trigonometry;
//! - the **reach** `rho = max |aq|` over `R`. `e` must satisfy `rho <= d_d` or `|ae| >= rho`,
//!   which puts the foot of every `q` with `r > d_d` on the segment.
//!
//! The candidate `m` is tested exactly, as in the definition (including a foot beyond `e`:
//! distance `|me|`), and folded into the cone and reach once removed. When `e == a`, every `q`
//! passes iff `|aq| <= d_d`, which is `max(rho, |am|) <= d_d`: exact too. Samples equal to `a`
//! add no constraint.
//!
//! **When it is conservative.** The cone test is exact. The reach bound is only sufficient: when
//! `e` is nearer to `a` than an older skipped `q` with `|aq| > d_d`, the definition still
//! removes `m` if that `q` projects onto the segment or lies within `d_d` of `e`, while this test
//! retains `m`. Because `m` itself is tested exactly, this takes a stroke that steps back past an
//! older sample (a pen that turns back or jitters backwards), which forward-moving strokes rarely
//! do; the property tests (`shared/tests/acuts_props.rs`) report how often it happens. Geometry
//! whose lengths exceed `1e150` (products would overflow) and half-angles within `1e-12` rad of
//! 90° are also treated conservatively: the candidate is retained. Retaining a sample never
//! breaks the guarantee.
//!
//! Parameters outside their range (see [`AcutsParams::validate`]) are clamped by the simplifier:
//! a negative or NaN tolerance acts as 0, the angle is clamped to `[0°, 90°]` (NaN acts as 0°).

use glam::DVec2;
use serde::{Deserialize, Serialize};

use crate::model::Sample;

/// Default chord-length threshold `l_eps` of stage 1 (table 3's lambda).
pub const DEFAULT_RESAMPLE_DISTANCE: f64 = 1.0;
/// Default chord-height tolerance `d_d` (same unit as x, y).
pub const DEFAULT_TOLERANCE: f64 = 0.74;
/// Default angle threshold `d_alpha` in degrees.
pub const DEFAULT_ANGLE_DEG: f64 = 15.0;
/// Default pressure-variance threshold `d_sigma2` for `p` in `[0, 1]`.
pub const DEFAULT_PRESSURE_VARIANCE: f64 = 0.0015;

/// Stage-2 parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AcutsParams {
    /// Chord-height tolerance `d_d`.
    pub tolerance: f64,
    /// Angle threshold `d_alpha`, degrees.
    pub angle_deg: f64,
    /// Pressure-variance threshold `d_sigma2`.
    pub pressure_variance: f64,
}

impl Default for AcutsParams {
    fn default() -> AcutsParams {
        AcutsParams {
            tolerance: DEFAULT_TOLERANCE,
            angle_deg: DEFAULT_ANGLE_DEG,
            pressure_variance: DEFAULT_PRESSURE_VARIANCE,
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
    pub fn validate(&self) -> Result<(), ParamError> {
        let bad = |name, value: f64, ok: bool, range| {
            if ok && value.is_finite() { Ok(()) } else { Err(ParamError { name, value, range }) }
        };
        bad("tolerance", self.tolerance, self.tolerance >= 0.0, "[0, inf)")?;
        bad("angle_deg", self.angle_deg, (0.0..=90.0).contains(&self.angle_deg), "[0, 90]")?;
        bad(
            "pressure_variance",
            self.pressure_variance,
            self.pressure_variance >= 0.0,
            "[0, inf)",
        )?;
        Ok(())
    }
}

/// A sample stage 2 decided to keep, with its index in the stage-2 input stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kept {
    pub index: usize,
    pub sample: Sample,
}

/// Stage 1: streaming chord-length resampler.
#[derive(Debug, Clone)]
pub struct Resampler {
    /// `l_eps²`: 0 when `l_eps <= 0` (every sample is kept), NaN when `l_eps` is NaN.
    min_distance_sq: f64,
    last_kept: Option<Sample>,
    /// The newest sample if it was not kept, with its input index: kept at [`Resampler::finish`].
    pending_tail: Option<(usize, Sample)>,
    n_seen: usize,
}

impl Resampler {
    pub fn new(min_distance: f64) -> Resampler {
        let min_distance_sq =
            if min_distance.is_nan() { f64::NAN } else { min_distance.max(0.0).powi(2) };
        Resampler { min_distance_sq, last_kept: None, pending_tail: None, n_seen: 0 }
    }

    /// Pushes the next sample; returns whether it is kept.
    pub fn push(&mut self, s: Sample) -> bool {
        let index = self.n_seen;
        self.n_seen += 1;
        let keep = match &self.last_kept {
            None => true,
            Some(last) => {
                let (dx, dy) = (s.x - last.x, s.y - last.y);
                dx * dx + dy * dy >= self.min_distance_sq
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

/// Stage 1 over a whole stroke: the input indices kept, in order.
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

/// Lengths above this are not trusted: products of two of them must stay finite.
const MAX_LENGTH: f64 = 1e150;
/// Smallest cosine of a cone's half-angle, so that every cone is narrower than a half-plane.
const MIN_COS_HALF_ANGLE: f64 = 1e-12;

/// A cone of directions from the anchor, narrower than a half-plane: from `lo` counter-clockwise
/// to `hi`. The empty cone has NaN boundaries, so that nothing is inside it.
#[derive(Debug, Clone, Copy)]
struct Cone {
    lo: DVec2,
    hi: DVec2,
}

impl Cone {
    const EMPTY: Cone = Cone { lo: DVec2::NAN, hi: DVec2::NAN };

    /// The cone of directions within the half-angle `(sin, cos)` of the unit vector `center`.
    fn around(center: DVec2, sin: f64, cos: f64) -> Cone {
        let (c, s) = (cos * center, sin * center.perp());
        Cone { lo: c - s, hi: c + s }
    }

    /// Whether the direction `v` (any length; the zero vector is outside) is inside.
    fn contains(&self, v: DVec2) -> bool {
        self.lo.perp_dot(v) >= 0.0 && v.perp_dot(self.hi) >= 0.0 && v.dot(self.lo + self.hi) > 0.0
    }

    /// The intersection. Two arcs narrower than a half-circle meet in one arc or not at all, and
    /// that arc starts at the `lo` of one that lies inside the other (likewise for `hi`).
    fn intersect(&self, other: &Cone) -> Cone {
        let lo = if self.contains(other.lo) {
            other.lo
        } else if other.contains(self.lo) {
            self.lo
        } else {
            return Cone::EMPTY;
        };
        let hi = if self.contains(other.hi) {
            other.hi
        } else if other.contains(self.hi) {
            self.hi
        } else {
            return Cone::EMPTY;
        };
        // Rounding can pick boundaries that cross over (a near-empty intersection): refuse them.
        let cross = lo.perp_dot(hi);
        if cross > 0.0 || (cross == 0.0 && lo.dot(hi) > 0.0) {
            Cone { lo, hi }
        } else {
            Cone::EMPTY
        }
    }
}

/// The candidate `m`, with its offset from the anchor and the length of that offset.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    index: usize,
    sample: Sample,
    offset: DVec2,
    distance: f64,
}

/// Stage 2: streaming windowed simplifier, O(1) time and memory per sample (see the module
/// documentation for the test and its guarantee).
#[derive(Debug, Clone)]
pub struct Simplifier {
    params: AcutsParams,
    /// `d_d`, clamped to `[0, inf]`.
    tolerance: f64,
    /// `sin(d_alpha)` with `d_alpha` clamped to `[0°, 90°]`.
    sin_angle: f64,
    /// `cos(d_alpha)`, at least [`MIN_COS_HALF_ANGLE`].
    cos_angle: f64,
    anchor: Option<Sample>,
    candidate: Option<Candidate>,
    /// The directions from the anchor that every skipped sample admits; `None`: no constraint.
    cone: Option<Cone>,
    /// The largest distance from the anchor to a skipped sample.
    reach: f64,
    n_seen: usize,
}

impl Simplifier {
    pub fn new(params: AcutsParams) -> Simplifier {
        let tolerance = if params.tolerance > 0.0 { params.tolerance } else { 0.0 };
        let angle_deg = if params.angle_deg > 0.0 { params.angle_deg.min(90.0) } else { 0.0 };
        let (sin_angle, cos_angle) = angle_deg.to_radians().sin_cos();
        Simplifier {
            params,
            tolerance,
            sin_angle,
            cos_angle: cos_angle.max(MIN_COS_HALF_ANGLE),
            anchor: None,
            candidate: None,
            cone: None,
            reach: 0.0,
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
        if !(pressure_variance(a.p, m.sample.p, e.p) > self.params.pressure_variance) {
            let ae = e.pos() - a.pos();
            let ae_len = ae.length();
            if self.admits(&m, ae, ae_len) {
                self.fold(m.offset, m.distance);
                self.candidate = Some(Candidate { index, sample: e, offset: ae, distance: ae_len });
                return None;
            }
        }
        self.anchor = Some(m.sample);
        self.cone = None;
        self.reach = 0.0;
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
    /// `ae = e - a` and `ae_len = |ae|`. Conservative as the module documentation says.
    fn admits(&self, m: &Candidate, ae: DVec2, ae_len: f64) -> bool {
        let tolerance = self.tolerance;
        if !(ae_len <= MAX_LENGTH && m.distance <= MAX_LENGTH) {
            return false;
        }
        if ae_len == 0.0 {
            // The segment is the point `a`: angles pass, distances are `|aq|`.
            return self.reach <= tolerance && m.distance <= tolerance;
        }
        let reach_ok = self.reach <= tolerance || ae_len >= self.reach;
        let cone_ok = self.cone.is_none_or(|cone| cone.contains(ae));
        reach_ok && cone_ok && self.admits_exactly(m.offset, m.distance, ae)
    }

    /// The geometry test for one `q != a` at `aq = q - a`, `r = |aq|`, against `ae = e - a != 0`.
    fn admits_exactly(&self, aq: DVec2, r: f64, ae: DVec2) -> bool {
        if r == 0.0 {
            return true;
        }
        let ae_len_sq = ae.length_squared();
        let ae_len = ae_len_sq.sqrt();
        let along = aq.dot(ae);
        let across = aq.perp_dot(ae).abs();
        // angle <= d_alpha <= 90° iff cos >= 0 and sin <= sin(d_alpha).
        if !(along >= 0.0 && across <= self.sin_angle * r * ae_len) {
            return false;
        }
        if along <= ae_len_sq {
            // The foot is on the segment: the distance is `r sin(angle) = across / |ae|`.
            across <= self.tolerance * ae_len
        } else {
            // The foot is beyond `e`: the distance is `|qe|`.
            (aq - ae).length_squared() <= self.tolerance * self.tolerance
        }
    }

    /// Adds a removed sample at `aq = q - a`, `r = |aq|`, to the cone and the reach.
    fn fold(&mut self, aq: DVec2, r: f64) {
        if r == 0.0 {
            return;
        }
        self.reach = self.reach.max(r);
        let tolerance = self.tolerance;
        let (sin, cos) = if r * self.sin_angle <= tolerance {
            (self.sin_angle, self.cos_angle)
        } else {
            // asin(d_d / r) < d_alpha.
            let cos = ((r - tolerance) * (r + tolerance)).sqrt() / r;
            (tolerance / r, cos.max(MIN_COS_HALF_ANGLE))
        };
        let cone = Cone::around(aq / r, sin, cos);
        self.cone = Some(match self.cone {
            None => cone,
            Some(current) => current.intersect(&cone),
        });
    }
}

impl Candidate {
    fn new(index: usize, sample: Sample, anchor: &Sample) -> Candidate {
        let offset = sample.pos() - anchor.pos();
        Candidate { index, sample, offset, distance: offset.length() }
    }
}

/// Population variance of three pressures (paper formula 3, `W_s = 3`).
pub fn pressure_variance(p0: f64, p1: f64, p2: f64) -> f64 {
    let mean = (p0 + p1 + p2) / 3.0;
    ((p0 - mean).powi(2) + (p1 - mean).powi(2) + (p2 - mean).powi(2)) / 3.0
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

    fn params(tolerance: f64, angle_deg: f64) -> AcutsParams {
        AcutsParams { tolerance, angle_deg, pressure_variance: DEFAULT_PRESSURE_VARIANCE }
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

    // Stage 1 with `l_eps <= 0` keeps every sample, repeated ones too.
    #[test]
    fn resample_zero_distance_keeps_all() {
        assert_eq!(resample(&points(&[(0.0, 0.0), (0.0, 0.0), (1.0, 1.0)]), 0.0), [0, 1, 2]);
        assert_eq!(resample(&points(&[(0.0, 0.0), (0.0, 0.0)]), -1.0), [0, 1]);
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
        check_simplify(&[], AcutsParams::default(), &[]);
        check_simplify(&[(1.0, 1.0)], AcutsParams::default(), &[0]);
        check_simplify(&[(1.0, 1.0), (5.0, 1.0)], AcutsParams::default(), &[0, 1]);
        check_simplify(&[(1.0, 1.0), (1.0, 1.0)], AcutsParams::default(), &[0, 1]);
    }

    // Stage 2 reduces a straight line, in any direction, to its ends.
    #[test]
    fn simplify_straight_lines() {
        for (dx, dy) in [(1.0, 0.0), (0.0, -2.0), (1.5, 0.75), (-0.3, 1.7)] {
            let xys: Vec<_> = (0..500).map(|i| (i as f64 * dx, i as f64 * dy)).collect();
            check_simplify(&xys, AcutsParams::default(), &[0, 499]);
        }
    }

    // Stage 2 keeps a corner, and the samples just past it.
    #[test]
    fn simplify_keeps_corner() {
        let xys =
            [(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (3.0, 0.0), (3.0, 1.0), (3.0, 2.0), (3.0, 3.0)];
        check_simplify(&xys, AcutsParams::default(), &[0, 3, 6]);
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
        let p = AcutsParams::default();
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
        assert_eq!(simplify(&samples, &AcutsParams::default()), [0, 3]);
        samples[2].p = 0.9;
        // {0.5, 0.5, 0.9} at e = 2 keeps nothing ({a, m, e} = {0, 1, 2}: variance 0.036 > 0.0015
        // retains 1); then {0.5, 0.9, 0.5} retains 2.
        assert_eq!(simplify(&samples, &AcutsParams::default()), [0, 1, 2, 3]);
        let lax = AcutsParams { pressure_variance: 1.0, ..AcutsParams::default() };
        assert_eq!(simplify(&samples, &lax), [0, 3]);
    }

    // Stage 2 is conservative when the stroke steps back past an older skipped sample: the
    // definition would remove (4.6, 0) since (5, 0) lies within 0.74 of (4.5, 0.05), the reach
    // bound retains it.
    #[test]
    fn simplify_reach_bound_is_conservative() {
        let xys = [(0.0, 0.0), (5.0, 0.0), (4.6, 0.0), (4.5, 0.05)];
        check_simplify(&xys, AcutsParams::default(), &[0, 2, 3]);
    }

    // Stage 2 on huge coordinates: exact on a line far from the origin, and no panic at the edge
    // of the f64 range (lengths beyond 1e150 retain everything).
    #[test]
    fn simplify_huge_coordinates() {
        let xys: Vec<_> = (0..100).map(|i| (1e12 + i as f64 * 2.0, -1e12)).collect();
        check_simplify(&xys, AcutsParams::default(), &[0, 99]);
        let xys = [(f64::MAX, f64::MAX), (-f64::MAX, 0.0), (0.0, f64::MIN), (1e200, 1e200)];
        check_simplify(&xys, AcutsParams::default(), &[0, 1, 2, 3]);
    }

    // Stage 2 clamps out-of-range parameters instead of misbehaving.
    #[test]
    fn simplify_out_of_range_params() {
        let xys = [(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (3.0, 0.1), (4.0, 0.0)];
        check_simplify(&xys, params(-1.0, 15.0), &[0, 2, 3, 4]);
        check_simplify(&xys, params(f64::NAN, f64::NAN), &[0, 2, 3, 4]);
        check_simplify(&xys, params(1.0, 400.0), &[0, 4]);
    }

    // Stage 2 streaming: decisions come one sample late, with the right index and sample, and
    // finish starts a new stroke.
    #[test]
    fn simplifier_streaming() {
        let mut s = Simplifier::new(AcutsParams::default());
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
        let out = acuts(&samples, 1.0, &AcutsParams::default());
        assert_eq!(out.resampled, [0, 2, 3, 4]);
        assert_eq!(out.kept, [0, 3, 4]);
        let out = acuts(&samples, 0.0, &AcutsParams::default());
        assert_eq!(out.resampled, [0, 1, 2, 3, 4]);
        assert_eq!(out.kept, [0, 3, 4]);
    }

    // The cone intersection: nested, overlapping, disjoint, and single rays.
    #[test]
    fn cone_intersection() {
        let deg = |d: f64| d.to_radians().sin_cos();
        let cone = |dir_deg: f64, half_deg: f64| {
            let (s, c) = deg(half_deg);
            let (sd, cd) = deg(dir_deg);
            Cone::around(DVec2::new(cd, sd), s, c)
        };
        let dir = |d: f64| {
            let (s, c) = deg(d);
            DVec2::new(c, s)
        };
        let both = cone(0.0, 20.0).intersect(&cone(15.0, 10.0));
        assert!(both.contains(dir(7.0)) && both.contains(dir(20.0)));
        assert!(!both.contains(dir(4.0)) && !both.contains(dir(21.0)));
        let nested = cone(0.0, 80.0).intersect(&cone(10.0, 5.0));
        assert!(nested.contains(dir(10.0)) && !nested.contains(dir(0.0)));
        assert!(!cone(0.0, 10.0).intersect(&cone(90.0, 10.0)).contains(dir(45.0)));
        let ray = cone(0.0, 0.0);
        assert!(ray.contains(DVec2::X) && !ray.contains(-DVec2::X) && !ray.contains(DVec2::ZERO));
        assert!(ray.intersect(&cone(0.0, 0.0)).contains(DVec2::X));
        assert!(!ray.intersect(&cone(180.0, 0.0)).contains(DVec2::X));
        let wide = cone(0.0, 89.0).intersect(&cone(180.0, 89.0));
        assert!(!wide.contains(DVec2::Y) && !wide.contains(DVec2::X));
    }
}
