//! Direction-preserving simplification (the DPTS family), online variant.
//!
//! C. Long, R. C.-W. Wong, H. V. Jagadish, "Direction-preserving trajectory simplification",
//! PVLDB 6(10), 2013, pp. 949–960.
//!
//! DPTS bounds the *angular* error: every original segment `p_k p_{k+1}` spanned by a retained
//! segment `a–e` must point within the angle of `a->e`. Long et al. solve it exactly (and
//! approximately) in batch; this is the online greedy variant of the family (opening window):
//! the window from the anchor `a` grows while every spanned original segment of non-zero length
//! is within the angle of `a->e` and, so that it can be compared at an equal position bound,
//! every sample strictly between `a` and `e` lies within the tolerance of the segment `a–e`.
//! When `e` fails, the sample before it is kept. O(window) per sample.

use super::{Simplify, angle_between, greedy_window};
use crate::acuts::segment_distance;
use crate::model::Sample;

/// The default direction bound, degrees.
pub const DEFAULT_DPTS_ANGLE_DEG: f64 = 30.0;

/// Online direction-preserving simplification with a position bound.
#[derive(Debug, Clone, Copy)]
pub struct Dpts {
    pub angle_deg: f64,
}

impl Default for Dpts {
    fn default() -> Dpts {
        Dpts { angle_deg: DEFAULT_DPTS_ANGLE_DEG }
    }
}

impl Dpts {
    fn admits(&self, samples: &[Sample], a: usize, e: usize, tolerance: f64) -> bool {
        let (sa, se) = (&samples[a], &samples[e]);
        let ae = se.pos() - sa.pos();
        let max_angle = self.angle_deg.to_radians();
        let directions_ok = samples[a..=e].windows(2).all(|w| {
            let step = w[1].pos() - w[0].pos();
            step == glam::DVec2::ZERO
                || (ae != glam::DVec2::ZERO && angle_between(step, ae) <= max_angle)
        });
        directions_ok && samples[a + 1..e].iter().all(|q| segment_distance(q, sa, se) <= tolerance)
    }
}

impl Simplify for Dpts {
    fn name(&self) -> &'static str {
        "dpts"
    }

    fn is_online(&self) -> bool {
        true
    }

    fn run(&self, samples: &[Sample], tolerance: f64) -> Vec<usize> {
        greedy_window(samples, |anchor, e| self.admits(samples, anchor, e, tolerance))
    }
}
