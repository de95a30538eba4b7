//! Baseline simplifiers, to measure ACUTS against: each returns the indices it keeps, so every
//! metric is computed the same way for all of them.
//!
//! | name | kind | guarantee at `tolerance` |
//! |---|---|---|
//! | [`DouglasPeucker`] | batch | every removed sample within `tolerance` of its spanning segment |
//! | [`Visvalingam`] | batch | by area, by count, or (error-bound mode) as Douglas–Peucker |
//! | [`OpeningWindow`] | online | segment distance, plus an optional angle bound (ISWTC) |
//! | [`SquishE`] | online | SED of every removed sample `<= tolerance` (error mode), or a count |
//! | [`Bqs`] | online | segment distance (the bounded quadrant system decides most samples in O(1)) |
//! | [`Dpts`] | online | segment distance, and every original direction within an angle |
//! | [`Optimal`] | batch | the fewest samples with every removed one within `tolerance` |
//! | [`PressureWindow`] | online | segment distance, and pressure within a tolerance of the interpolation (ACUTS's default pressure bound) |
//! | [`OptimalPressure`] | batch | the fewest samples keeping both: the reference for a pressure-aware method |
//!
//! The *segment distance* of a removed sample `q` is its distance to the retained segment
//! `a–b` with `a < q < b` ([`segment_distance`]): what `E_max` measures. Every simplifier keeps
//! the first and the last sample; a stroke of 0, 1 or 2 samples is returned whole.

mod bqs;
mod douglas_peucker;
mod dpts;
mod optimal;
mod squish_e;
mod visvalingam;
mod window;

pub use bqs::Bqs;
pub use douglas_peucker::DouglasPeucker;
pub use dpts::{DEFAULT_DPTS_ANGLE_DEG, Dpts};
pub use optimal::{Optimal, OptimalPressure, min_points, min_points_with_pressure};
pub use squish_e::{SquishE, sed};
pub use visvalingam::{Visvalingam, VwStop};
pub use window::{DEFAULT_WINDOW_ANGLE_DEG, OpeningWindow, PressureWindow};

use crate::acuts::segment_distance;
use crate::metrics::pressure_error;
use crate::model::Sample;

/// A simplifier that keeps a subset of a stroke's samples.
pub trait Simplify {
    /// The short name `penmesh-lab eval --algos` uses.
    fn name(&self) -> &'static str;
    /// Whether it decides each sample from the samples seen so far, as they arrive.
    fn is_online(&self) -> bool;
    /// The kept indices, strictly increasing, always with the first and the last sample.
    fn run(&self, samples: &[Sample], tolerance: f64) -> Vec<usize>;
}

/// Every baseline's name, in the order of `penmesh-lab eval`'s tables.
pub const BASELINE_NAMES: [&str; 11] = [
    "dp",
    "vw",
    "window",
    "window-d",
    "window-p",
    "squish-e",
    "bqs",
    "fbqs",
    "dpts",
    "optimal",
    "optimal-p",
];

/// The baseline called `name` (one of [`BASELINE_NAMES`]) in its evaluation setting; the
/// pressure-aware ones (`window-p`, `optimal-p`) bound the pressure error by
/// `pressure_tolerance`, as ACUTS's interpolation gate does. `None` for an unknown name.
pub fn baseline(name: &str, pressure_tolerance: f64) -> Option<Box<dyn Simplify>> {
    Some(match name {
        "dp" => Box::new(DouglasPeucker),
        "vw" => Box::new(Visvalingam { stop: VwStop::ErrorBound }),
        "window" => Box::new(OpeningWindow::default()),
        "window-d" => Box::new(OpeningWindow { angle_deg: None }),
        "window-p" => Box::new(PressureWindow { pressure_tolerance }),
        "squish-e" => Box::new(SquishE::default()),
        "bqs" => Box::new(Bqs { fast: false }),
        "fbqs" => Box::new(Bqs { fast: true }),
        "dpts" => Box::new(Dpts::default()),
        "optimal" => Box::new(Optimal),
        "optimal-p" => Box::new(OptimalPressure { pressure_tolerance }),
        _ => return None,
    })
}

/// The answer for strokes too short to simplify: all of their samples.
fn whole_if_short(samples: &[Sample]) -> Option<Vec<usize>> {
    (samples.len() <= 2).then(|| (0..samples.len()).collect())
}

/// The opening-window loop shared by the online window methods: extend the segment from the
/// anchor while `admits(anchor, e)` holds; when it fails, the sample before `e` is kept and
/// becomes the anchor. First and last samples are always kept.
fn greedy_window(samples: &[Sample], mut admits: impl FnMut(usize, usize) -> bool) -> Vec<usize> {
    if let Some(all) = whole_if_short(samples) {
        return all;
    }
    let mut kept = vec![0];
    let mut anchor = 0;
    for e in 2..samples.len() {
        if !admits(anchor, e) {
            anchor = e - 1;
            kept.push(anchor);
        }
    }
    kept.push(samples.len() - 1);
    kept
}

/// Whether every sample strictly between `a` and `b` lies within `tolerance` of the segment
/// `a–b`. O(b - a).
pub fn span_within(samples: &[Sample], a: usize, b: usize, tolerance: f64) -> bool {
    let (sa, sb) = (&samples[a], &samples[b]);
    samples[a + 1..b].iter().all(|q| segment_distance(q, sa, sb) <= tolerance)
}

/// Whether every sample strictly between `a` and `b` has its pressure within `tolerance` of the
/// pressure interpolated in time along `a–b` (ACUTS's default pressure bound; when `t_b == t_a`,
/// within `tolerance` of both `p_a` and `p_b`). O(b - a).
pub fn pressure_within(samples: &[Sample], a: usize, b: usize, tolerance: f64) -> bool {
    let (sa, sb) = (&samples[a], &samples[b]);
    samples[a + 1..b].iter().all(|q| pressure_error(q, sa, sb) <= tolerance)
}

/// The angle in radians between the vectors `u` and `v` (0 when either is zero).
fn angle_between(u: glam::DVec2, v: glam::DVec2) -> f64 {
    u.perp_dot(v).abs().atan2(u.dot(v))
}

#[cfg(test)]
mod tests {
    use super::*;

    // Every name finds the baseline that calls itself by it; other names find none.
    #[test]
    fn baselines_by_name() {
        for name in BASELINE_NAMES {
            assert_eq!(baseline(name, 0.2).map(|b| b.name()), Some(name));
        }
        assert!(baseline("acuts", 0.2).is_none());
    }

    // The angle helper is symmetric, unsigned and 0 for a zero vector.
    #[test]
    fn angles() {
        use glam::DVec2;
        assert!((angle_between(DVec2::X, DVec2::Y) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((angle_between(DVec2::Y, DVec2::X) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((angle_between(DVec2::X, -DVec2::X) - std::f64::consts::PI).abs() < 1e-12);
        assert_eq!(angle_between(DVec2::ZERO, DVec2::X), 0.0);
    }
}
