//! Optimal min-#: the fewest samples such that every removed sample lies within the tolerance of
//! the retained segment that spans it. The lower bound every simplifier is measured against.
//!
//! - H. Imai and M. Iri, "Polygonal approximations of a curve — formulations and algorithms",
//!   in *Computational Morphology*, North-Holland, 1988, pp. 71–86: the shortcut graph, whose
//!   edge `i -> j` exists iff every sample strictly between lies within the tolerance of the
//!   segment `p_i p_j`; the answer is a shortest path from the first sample to the last.
//! - W. S. Chan and F. Chin, "Approximation of polygonal curves with minimum number of line
//!   segments or minimum error", *Int. J. Comput. Geom. Appl.* 6(1), 1996, pp. 59–77: the graph
//!   in O(n²) with wedges.
//!
//! The wedges: a sample `q` at distance `r > tol` from `p_i` is within `tol` of the ray from `p_i`
//! in direction `u` iff `angle(u, p_i->q) <= asin(tol / r)` (and always when `r <= tol`). So,
//! scanning `j` forward from `i`, the directions allowed by every sample so far are an
//! intersection of arcs, updated in O(1); `i -> j` is valid for the ray from `p_i` iff
//! `p_i->p_j` is in it. The distance to the segment is the larger of the distances to the ray
//! from `p_i` towards `p_j` and the ray from `p_j` towards `p_i`, so a backward scan from every
//! `j` gives the other half (kept as a bit matrix, n² bits). A chord of length 0 (`p_j = p_i`)
//! is valid iff every sample between lies within `tol` of `p_i`. Then a forward pass over the
//! DAG finds the shortest path. O(n²) time, n²/8 bytes.

use glam::DVec2;

use super::{Simplify, whole_if_short};
use crate::model::Sample;

/// Optimal min-# under the segment distance.
#[derive(Debug, Clone, Copy, Default)]
pub struct Optimal;

/// Optimal min-# under the segment distance and the pressure bound of ACUTS's default gate:
/// every removed sample's pressure within `pressure_tolerance` of the pressure interpolated in
/// time along its segment ([`pressure_within`](super::pressure_within)). The fewest points any
/// method bounding both can keep: the fair reference for a pressure-aware simplifier.
#[derive(Debug, Clone, Copy)]
pub struct OptimalPressure {
    pub pressure_tolerance: f64,
}

impl Simplify for OptimalPressure {
    fn name(&self) -> &'static str {
        "optimal-p"
    }

    fn is_online(&self) -> bool {
        false
    }

    fn run(&self, samples: &[Sample], tolerance: f64) -> Vec<usize> {
        min_points_with_pressure(samples, tolerance, Some(self.pressure_tolerance))
    }
}

/// The pressure half of an edge `i -> j`, scanning `j` forward from `i`: the slopes
/// `(p_j - p_i) / (t_j - t_i)` that keep every folded sample within the tolerance of the
/// interpolation (a one-dimensional wedge), and the range of pressures for `t_j == t_i`.
#[derive(Debug, Clone, Copy)]
struct PressureScan {
    apex: Sample,
    tolerance: f64,
    slope_lo: f64,
    slope_hi: f64,
    p_min: f64,
    p_max: f64,
}

impl PressureScan {
    fn new(apex: Sample, tolerance: f64) -> PressureScan {
        PressureScan {
            apex,
            tolerance,
            slope_lo: f64::NEG_INFINITY,
            slope_hi: f64::INFINITY,
            p_min: f64::INFINITY,
            p_max: f64::NEG_INFINITY,
        }
    }

    fn admits(&self, end: &Sample) -> bool {
        let (dt, dp) = (end.t - self.apex.t, end.p - self.apex.p);
        if dt > 0.0 {
            self.slope_lo * dt <= dp && dp <= self.slope_hi * dt
        } else {
            let (lo, hi) = (self.apex.p.min(end.p), self.apex.p.max(end.p));
            self.p_max - self.tolerance <= lo && hi <= self.p_min + self.tolerance
        }
    }

    fn fold(&mut self, q: &Sample) {
        self.p_min = self.p_min.min(q.p);
        self.p_max = self.p_max.max(q.p);
        let (dt, dp) = (q.t - self.apex.t, q.p - self.apex.p);
        if dt > 0.0 {
            self.slope_lo = self.slope_lo.max((dp - self.tolerance) / dt);
            self.slope_hi = self.slope_hi.min((dp + self.tolerance) / dt);
        } else if (dp).abs() > self.tolerance {
            // tau = 0 for every later chord: off by more than the tolerance whatever `p_j`.
            self.slope_lo = f64::INFINITY;
        }
    }

    /// Whether no later chord can be admitted (slopes only narrow; a folded sample at the
    /// apex's time off by more than the tolerance empties them too).
    fn is_dead(&self) -> bool {
        self.slope_lo > self.slope_hi
    }
}

impl Simplify for Optimal {
    fn name(&self) -> &'static str {
        "optimal"
    }

    fn is_online(&self) -> bool {
        false
    }

    fn run(&self, samples: &[Sample], tolerance: f64) -> Vec<usize> {
        min_points(samples, tolerance)
    }
}

/// An arc of directions `[lo, hi]` (radians, `hi - lo < π`), or every direction.
#[derive(Debug, Clone, Copy)]
enum Wedge {
    All,
    Arc { lo: f64, hi: f64 },
    Empty,
}

/// `angle` shifted by a multiple of 2π to lie within π of `reference`.
fn near(angle: f64, reference: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    angle - ((angle - reference) / tau).round() * tau
}

/// The directions from the apex that keep every folded sample within the tolerance of the ray,
/// and the largest distance of a folded sample from the apex.
#[derive(Debug, Clone, Copy)]
struct Scan {
    apex: DVec2,
    tolerance: f64,
    wedge: Wedge,
    reach: f64,
}

impl Scan {
    fn new(apex: DVec2, tolerance: f64) -> Scan {
        Scan { apex, tolerance, wedge: Wedge::All, reach: 0.0 }
    }

    /// Whether the chord from the apex to `end` keeps every folded sample within the tolerance of
    /// the ray from the apex through `end`.
    fn admits(&self, end: DVec2) -> bool {
        let v = end - self.apex;
        if v == DVec2::ZERO {
            return self.reach <= self.tolerance;
        }
        match self.wedge {
            Wedge::All => true,
            Wedge::Empty => false,
            Wedge::Arc { lo, hi } => {
                let angle = near(v.y.atan2(v.x), (lo + hi) / 2.0);
                lo <= angle && angle <= hi
            }
        }
    }

    /// Adds the sample at `q` to the constraints.
    fn fold(&mut self, q: DVec2) {
        let v = q - self.apex;
        let r = v.length();
        self.reach = self.reach.max(r);
        if r <= self.tolerance {
            return;
        }
        let half = (self.tolerance / r).asin();
        let center = v.y.atan2(v.x);
        self.wedge = match self.wedge {
            Wedge::All => Wedge::Arc { lo: center - half, hi: center + half },
            Wedge::Empty => Wedge::Empty,
            Wedge::Arc { lo, hi } => {
                let center = near(center, (lo + hi) / 2.0);
                let (lo, hi) = (lo.max(center - half), hi.min(center + half));
                if lo <= hi { Wedge::Arc { lo, hi } } else { Wedge::Empty }
            }
        };
    }

    /// Whether no chord of non-zero length can be admitted any more, nor one of length 0.
    fn is_dead(&self) -> bool {
        matches!(self.wedge, Wedge::Empty) && self.reach > self.tolerance
    }
}

/// The fewest kept indices (first and last included) such that every removed sample lies within
/// `tolerance` of its spanning retained segment.
pub fn min_points(samples: &[Sample], tolerance: f64) -> Vec<usize> {
    min_points_with_pressure(samples, tolerance, None)
}

/// [`min_points`], and with `pressure_tolerance` every removed sample's pressure also within it
/// of the pressure interpolated in time along its segment (see [`OptimalPressure`]).
pub fn min_points_with_pressure(
    samples: &[Sample],
    tolerance: f64,
    pressure_tolerance: Option<f64>,
) -> Vec<usize> {
    if let Some(all) = whole_if_short(samples) {
        return all;
    }
    let n = samples.len();
    let words = n.div_ceil(64);
    // backward[j * words + i / 64] bit i: the chord j -> i (i < j) passes the ray test from p_j.
    let mut backward = vec![0_u64; n * words];
    for j in 1..n {
        let mut scan = Scan::new(samples[j].pos(), tolerance);
        for i in (0..j).rev() {
            if scan.admits(samples[i].pos()) {
                backward[j * words + i / 64] |= 1 << (i % 64);
            }
            scan.fold(samples[i].pos());
            if scan.is_dead() {
                break;
            }
        }
    }
    let mut hops = vec![usize::MAX; n];
    let mut parent = vec![0; n];
    hops[0] = 0;
    for i in 0..n - 1 {
        if hops[i] == usize::MAX {
            continue;
        }
        let mut scan = Scan::new(samples[i].pos(), tolerance);
        let mut pressure = pressure_tolerance.map(|d| PressureScan::new(samples[i], d));
        for j in i + 1..n {
            let back = backward[j * words + i / 64] >> (i % 64) & 1 == 1;
            if back
                && scan.admits(samples[j].pos())
                && pressure.is_none_or(|p| p.admits(&samples[j]))
                && hops[i] + 1 < hops[j]
            {
                hops[j] = hops[i] + 1;
                parent[j] = i;
            }
            scan.fold(samples[j].pos());
            if let Some(p) = &mut pressure {
                p.fold(&samples[j]);
            }
            if scan.is_dead() || pressure.is_some_and(|p| p.is_dead()) {
                break;
            }
        }
    }
    let mut kept = vec![n - 1];
    let mut at = n - 1;
    while at != 0 {
        at = parent[at];
        kept.push(at);
    }
    kept.reverse();
    kept
}
