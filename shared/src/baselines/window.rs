//! The opening (sliding) window with a distance and an angle threshold: the ISWTC baseline of
//! the ACUTS paper's table 6.
//!
//! From the anchor `a` (the last kept sample), the window grows one sample at a time. When the
//! sample `e` arrives, every sample `q` strictly between `a` and `e` must lie within the
//! tolerance of the segment `a–e` and, when an angle is set, satisfy
//! `angle(a->q, a->e) <= angle`. If some `q` fails, the sample before `e` is kept and becomes the
//! anchor. This is the classic opening window of
//!
//! - D. Meratnia and R. A. de By, "Spatiotemporal compression techniques for moving point
//!   objects", EDBT 2004, LNCS 2992, pp. 765–782 (opening window, "NOPW"), and
//! - E. Keogh, S. Chu, D. Hart, M. Pazzani, "An online algorithm for segmenting time series",
//!   ICDM 2001 (sliding window),
//!
//! with the angle threshold of the ISWTC variant the ACUTS paper compares against. Without an
//! angle it is the plain greedy window. Online (a sample is decided when the next one arrives),
//! O(window) per sample.

use super::{Simplify, angle_between, greedy_window};
use crate::acuts::segment_distance;
use crate::model::Sample;

/// The angle threshold `penmesh-lab eval` gives the window (ISWTC), degrees: ACUTS's default.
pub const DEFAULT_WINDOW_ANGLE_DEG: f64 = 15.0;

/// Opening window; `angle_deg: None` checks distances only.
#[derive(Debug, Clone, Copy)]
pub struct OpeningWindow {
    pub angle_deg: Option<f64>,
}

impl Default for OpeningWindow {
    fn default() -> OpeningWindow {
        OpeningWindow { angle_deg: Some(DEFAULT_WINDOW_ANGLE_DEG) }
    }
}

impl OpeningWindow {
    /// Whether every sample strictly between `a` and `e` passes.
    fn admits(&self, samples: &[Sample], a: usize, e: usize, tolerance: f64) -> bool {
        let (sa, se) = (&samples[a], &samples[e]);
        let ae = se.pos() - sa.pos();
        let max_angle = self.angle_deg.map(f64::to_radians);
        samples[a + 1..e].iter().all(|q| {
            let angle_ok = max_angle.is_none_or(|max| {
                let aq = q.pos() - sa.pos();
                aq == glam::DVec2::ZERO || ae == glam::DVec2::ZERO || angle_between(aq, ae) <= max
            });
            angle_ok && segment_distance(q, sa, se) <= tolerance
        })
    }
}

impl Simplify for OpeningWindow {
    fn name(&self) -> &'static str {
        if self.angle_deg.is_some() { "window" } else { "window-d" }
    }

    fn is_online(&self) -> bool {
        true
    }

    fn run(&self, samples: &[Sample], tolerance: f64) -> Vec<usize> {
        greedy_window(samples, |anchor, e| self.admits(samples, anchor, e, tolerance))
    }
}

/// The plain greedy window (distance only, as [`Bqs`](super::Bqs) decides) with the pressure
/// bound of ACUTS's default gate added: `e` extends the window only if every sample between also
/// has its pressure within `pressure_tolerance` of the interpolation along `a–e`
/// ([`pressure_within`](super::pressure_within)). The online method ACUTS's default is fairly
/// compared with: the same two bounds, no angle. Online, O(window) per sample.
#[derive(Debug, Clone, Copy)]
pub struct PressureWindow {
    pub pressure_tolerance: f64,
}

impl Simplify for PressureWindow {
    fn name(&self) -> &'static str {
        "window-p"
    }

    fn is_online(&self) -> bool {
        true
    }

    fn run(&self, samples: &[Sample], tolerance: f64) -> Vec<usize> {
        greedy_window(samples, |a, e| {
            super::span_within(samples, a, e, tolerance)
                && super::pressure_within(samples, a, e, self.pressure_tolerance)
        })
    }
}
