//! Stage 2: the windowed simplifier, with its constant-time geometry and pressure tests (see
//! the module docs of [`crate::acuts`]).

use glam::DVec2;

use super::measures::pressure_variance;
use super::params::{AcutsParams, PressureGate};
use crate::model::Sample;

/// A sample stage 2 decided to keep, with its index in the stage-2 input stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kept {
    pub index: usize,
    pub sample: Sample,
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
pub(super) struct Cone {
    reference: DVec2,
    lo: f64,
    hi: f64,
}

impl Cone {
    /// The cone of directions within the half-angle `atan2(sin, cos)` (`cos > 0`) of `center`.
    pub(super) fn around(center: DVec2, sin: f64, cos: f64) -> Cone {
        let mut cone = Cone { reference: center, lo: f64::NEG_INFINITY, hi: f64::INFINITY };
        cone.narrow(center, sin, cos);
        cone
    }

    /// Whether the direction `v` (any length; the zero vector is outside) is inside.
    pub(super) fn contains(&self, v: DVec2) -> bool {
        let (along, across) = (self.reference.dot(v), self.reference.perp_dot(v));
        along > 0.0 && across >= self.lo * along && across <= self.hi * along
    }

    /// Intersects with the cone of half-angle `atan2(sin, cos)` around `center`, narrower than a
    /// half-plane. Its part inside the half-plane of `reference` is one arc (or nothing), whose
    /// bounds are its own boundaries where they lie inside the half-plane, else the half-plane's.
    pub(super) fn narrow(&mut self, center: DVec2, sin: f64, cos: f64) {
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
