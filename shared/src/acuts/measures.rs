//! The measures both stages and the baselines share.

use crate::model::Sample;

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
