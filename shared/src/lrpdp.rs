//! LRPDP: the pressure-sensitive outline of a simplified stroke, and its layered point cloud.
//!
//! Each sample `S_k` gets a radius `r_k = brush.radius(p_k)` (formula 6) and a unit normal
//! `n_k = perp(unit(t_in + t_out))` across the stroke, where `t_in` and `t_out` are the unit
//! tangents towards the previous and next sample. At a cusp (`t_in + t_out ≈ 0`) the normal
//! falls back to `perp(t_in)`; at the ends only one tangent exists. The offset points are
//! `T_u[k] = S_k + r_k n_k` and `T_v[k] = S_k - r_k n_k` (formulas 7–15), and half circles
//! `T_f`, `T_e` close the ends (formula 16).
//!
//! Conventions, in the stroke's own `(x, y)` coordinates read as a right-handed plane (`x`
//! right, `y` up): `perp` turns a vector clockwise, so `T_u` lies on the right of the direction
//! of travel and the closed outline `T_c` is counter-clockwise (positive shoelace area).
//! `T_c` runs `T_f, T_u, T_e, reverse(T_v)`: the spec lists the end cap last, but a loop must
//! pass the end cap between the two sides, so that is the order built here.
//!
//! By default the offsets are taken along a smooth centreline through the samples
//! ([`crate::centreline`]: centripetal Catmull–Rom, real corners kept, adaptively tessellated,
//! radius interpolated along it), so the outline's `centres` are the tessellated points, a
//! superset of the samples. [`Centreline::Straight`] (or [`OutlineOptions::paper`]) offsets
//! straight through the samples, as the paper does.
//!
//! Limits: samples are expected to be validated (finite). Consecutive samples at the same
//! position are merged (the larger radius wins), so repeated points never make a zero-length
//! tangent. A stroke whose samples all coincide is a dot: its outline is a full circle. Where a
//! curve is tighter than the radius, `T_u` or `T_v` crosses itself: the outline is then not a
//! simple polygon, which the strip mesh of [`crate::solid_mesh`] tolerates by construction.

use glam::DVec2;

use crate::centreline::{
    Centreline, PathArc, SMOOTH_PATH_REACH, SMOOTH_PATH_TURN_DEG, TANGENT_SCALES, fit_centreline,
    smooth_centreline, within_directed,
};
use crate::model::{Brush, Sample};

/// What no pixel shows at 1 px per unit, px: the default largest distance of an end cap's
/// polygon from its half circle, and of a centreline point's rims from the edges that replace
/// them when the solid leaves it out ([`crate::SolidOptions::tolerance`]).
pub const PIXEL_TOLERANCE: f64 = 0.25;
/// Smallest number of points on an end cap.
pub const MIN_CAP_POINTS: usize = 3;
/// Most points on an end cap, so that memory stays bounded whatever the radius.
const MAX_CAP_POINTS: usize = 4096;

/// Below this turn of the tangent sum (`|t_in + t_out|`), a sample is treated as a cusp.
const CUSP_EPSILON: f64 = 1e-9;
/// Samples closer than this (relative to their coordinates' magnitude) are merged.
const MERGE_EPSILON: f64 = 1e-9;

/// How the outline is built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutlineOptions {
    /// Miter correction: offset by `r / cos(theta / 2)` (capped at `2 r`) at a turn of angle
    /// `theta`, so the band keeps its width `2 r` through corners. Off by default.
    pub miter: bool,
    /// Largest distance (px) of an end cap's polygon from its half circle: a cap of radius `r`
    /// has the fewest points that keep it within this, at least [`MIN_CAP_POINTS`] (see
    /// [`OutlineOptions::cap_points`]).
    pub cap_tolerance: f64,
    /// The centreline the sides are offset from: smooth by default.
    pub centreline: Centreline,
}

impl OutlineOptions {
    pub fn miter(mut self, miter: bool) -> OutlineOptions {
        self.miter = miter;
        self
    }

    pub fn cap_tolerance(mut self, cap_tolerance: f64) -> OutlineOptions {
        self.cap_tolerance = cap_tolerance;
        self
    }

    pub fn centreline(mut self, centreline: Centreline) -> OutlineOptions {
        self.centreline = centreline;
        self
    }

    /// The paper's outline: offsets straight through the samples.
    pub fn paper() -> OutlineOptions {
        OutlineOptions::default().centreline(Centreline::Straight)
    }

    /// Number of points on an end cap of radius `radius`: `n` points strictly inside the half
    /// circle make `n + 1` chords of `pi / (n + 1)` each, whose sagitta
    /// `r (1 - cos(pi / (2 (n + 1))))` must be at most the tolerance `t`, so
    /// `n = ceil(pi / (2 acos(1 - t / r))) - 1`, at least [`MIN_CAP_POINTS`]. The spec's
    /// `max(3, ceil(I r))` grows linearly with the radius; this grows as its square root (4
    /// points at the default brush's 4 px, 6 at 8 px, 12 at 30 px, against 8, 16 and 60).
    pub fn cap_points(&self, radius: f64) -> usize {
        let ratio = (self.cap_tolerance / radius).min(1.0);
        let wanted = (std::f64::consts::PI / (2.0 * (1.0 - ratio).acos())).ceil() - 1.0;
        // NaN (a negative tolerance) gives the floor; a zero tolerance, infinitely many, is
        // capped so memory stays bounded.
        if wanted.is_nan() {
            return MIN_CAP_POINTS;
        }
        (wanted.min(MAX_CAP_POINTS as f64) as usize).max(MIN_CAP_POINTS)
    }
}

impl Default for OutlineOptions {
    fn default() -> OutlineOptions {
        OutlineOptions {
            miter: false,
            cap_tolerance: PIXEL_TOLERANCE,
            centreline: Centreline::default(),
        }
    }
}

/// The outline of one stroke: centre line, offset sides and end caps.
///
/// All vectors indexed by centre point (`centres`, `radii`, `normals`, `upper`, `lower`) have
/// the same length: the tessellated centreline's points (the samples left after merging
/// repeated points, with a straight centreline). An empty stroke gives an empty outline.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Outline {
    /// The centreline's points: the stroke's samples (repeated positions merged) and, with a
    /// smooth centreline, the tessellated points between them.
    pub centres: Vec<DVec2>,
    /// Radius `r_k` at each centre.
    pub radii: Vec<f64>,
    /// Unit normal `n_k` at each centre, pointing towards `upper`.
    pub normals: Vec<DVec2>,
    /// `T_u`: the right-hand side, `S_k + r_k n_k` (times the miter factor, if enabled).
    pub upper: Vec<DVec2>,
    /// `T_v`: the left-hand side, `S_k - r_k n_k` (times the miter factor, if enabled).
    pub lower: Vec<DVec2>,
    /// `T_f`: the start cap, from next to `lower[0]` round the back of the stroke to next to
    /// `upper[0]` (the side points themselves excluded).
    pub start_cap: Vec<DVec2>,
    /// `T_e`: the end cap, from next to `upper[last]` round the front to next to `lower[last]`.
    pub end_cap: Vec<DVec2>,
    /// Outward unit normal of each start cap point.
    pub start_cap_normals: Vec<DVec2>,
    /// Outward unit normal of each end cap point.
    pub end_cap_normals: Vec<DVec2>,
}

impl Outline {
    /// Number of centreline points (the merged samples, with a straight centreline).
    pub fn n_samples(&self) -> usize {
        self.centres.len()
    }

    pub fn is_empty(&self) -> bool {
        self.centres.is_empty()
    }

    /// The largest radius, 0 for an empty outline.
    pub fn max_radius(&self) -> f64 {
        self.radii.iter().copied().fold(0.0, f64::max)
    }

    /// Number of points of the closed outline `T_c`.
    pub fn n_closed(&self) -> usize {
        self.start_cap.len() + self.end_cap.len() + 2 * self.centres.len()
    }

    /// The closed counter-clockwise outline `T_c = T_f, T_u, T_e, reverse(T_v)` (not repeating
    /// its first point at the end).
    pub fn closed(&self) -> Vec<DVec2> {
        self.closed_iter().map(|(point, _, _)| point).collect()
    }

    /// The outward unit normal at each point of [`Outline::closed`]: `n_k` on `T_u`, `-n_k` on
    /// `T_v`, radial on the caps.
    pub fn closed_normals(&self) -> Vec<DVec2> {
        self.closed_iter().map(|(_, normal, _)| normal).collect()
    }

    /// The radius that belongs to each point of [`Outline::closed`] (the end sample's radius on
    /// the caps).
    pub fn closed_radii(&self) -> Vec<f64> {
        self.closed_iter().map(|(_, _, radius)| radius).collect()
    }

    /// Point, outward unit normal and radius of each point of `T_c`, in order.
    pub fn closed_iter(&self) -> impl Iterator<Item = (DVec2, DVec2, f64)> + '_ {
        let first_radius = self.radii.first().copied().unwrap_or(0.0);
        let last_radius = self.radii.last().copied().unwrap_or(0.0);
        let start_cap = (self.start_cap.iter().zip(&self.start_cap_normals))
            .map(move |(p, n)| (*p, *n, first_radius));
        let upper =
            (self.upper.iter().zip(&self.normals).zip(&self.radii)).map(|((p, n), r)| (*p, *n, *r));
        let end_cap = (self.end_cap.iter().zip(&self.end_cap_normals))
            .map(move |(p, n)| (*p, *n, last_radius));
        let lower = (self.lower.iter().zip(&self.normals).zip(&self.radii))
            .rev()
            .map(|((p, n), r)| (*p, -*n, *r));
        start_cap.chain(upper).chain(end_cap).chain(lower)
    }
}

/// Turns `v` a quarter turn clockwise: the right-hand side of a direction of travel.
fn perp(v: DVec2) -> DVec2 {
    DVec2::new(v.y, -v.x)
}

/// Merges consecutive samples at the same position; returns centres, radii and, for each
/// centre, the index in `samples` of the first sample merged into it.
fn merged_centres(samples: &[Sample], brush: &Brush) -> (Vec<DVec2>, Vec<f64>, Vec<usize>) {
    let mut centres: Vec<DVec2> = Vec::with_capacity(samples.len());
    let mut radii: Vec<f64> = Vec::with_capacity(samples.len());
    let mut firsts: Vec<usize> = Vec::with_capacity(samples.len());
    for (sample_idx, s) in samples.iter().enumerate() {
        let pos = s.pos();
        let radius = brush.radius(s.p);
        if let (Some(last), Some(last_radius)) = (centres.last(), radii.last_mut()) {
            let scale = last.abs().max_element().max(pos.abs().max_element()).max(1.0);
            if last.distance(pos) <= MERGE_EPSILON * scale {
                *last_radius = last_radius.max(radius);
                continue;
            }
        }
        centres.push(pos);
        radii.push(radius);
        firsts.push(sample_idx);
    }
    (centres, radii, firsts)
}

/// Why [`fitted_outline`] refused its retained indices.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum KeptError {
    #[error("retained index {index} (entry {entry}) is past the {n_samples} raw samples")]
    OutOfRange { entry: usize, index: usize, n_samples: usize },
    #[error("retained indices must increase: entry {entry} is {index} after {previous}")]
    NotIncreasing { entry: usize, index: usize, previous: usize },
}

/// The outline of the simplification `kept` (increasing indices into `raw`), with the smooth
/// centreline fitted to the raw samples:
/// - a retained sample is a corner exactly where the raw path is not smooth
///   ([`crate::centreline::SMOOTH_PATH_REACH`]), not by the chords' rule of [`outline`];
/// - it is checked in both directions: a segment that would leave a raw sample it spans further
///   than the bound from the centreline, or put a tessellated point or the midpoint of a
///   tessellated piece further than the bound from that stretch of the raw path, is flattened
///   until neither happens (at worst to the chord, which satisfies both when every raw sample is
///   within the bound of it, as ACUTS guarantees);
/// - a segment that fell to its chord (a kink at both its knots) gets the raw sample in the
///   middle of its span as one more knot and the stroke is fitted again, at most
///   `MAX_KNOT_ROUNDS` times; the last fit keeps its chords.
///
/// With a straight centreline this is [`outline`] of the retained samples.
pub fn fitted_outline(
    raw: &[Sample],
    kept: &[usize],
    brush: &Brush,
    options: &OutlineOptions,
) -> Result<Outline, KeptError> {
    for (entry, &index) in kept.iter().enumerate() {
        if index >= raw.len() {
            return Err(KeptError::OutOfRange { entry, index, n_samples: raw.len() });
        }
        if let Some(&previous) = entry.checked_sub(1).and_then(|e| kept.get(e)) {
            if index <= previous {
                return Err(KeptError::NotIncreasing { entry, index, previous });
            }
        }
    }
    let Centreline::Smooth(smooth) = &options.centreline else {
        let samples: Vec<Sample> = kept.iter().map(|&i| raw[i]).collect();
        let (centres, radii, _) = merged_centres(&samples, brush);
        return Ok(offset_outline(centres, radii, options));
    };
    let path: Vec<DVec2> = raw.iter().map(Sample::pos).collect();
    let path_arc = PathArc::new(&path);
    let max_turn = SMOOTH_PATH_TURN_DEG.to_radians();
    let smooth_path = |k: usize| path_arc.is_smooth_at(k, SMOOTH_PATH_REACH, max_turn);
    let bound = smooth.bound;
    let mut knots = kept.to_vec();
    let mut round = 0;
    loop {
        let samples: Vec<Sample> = knots.iter().map(|&i| raw[i]).collect();
        let (centres, radii, firsts) = merged_centres(&samples, brush);
        // A knot is a corner where the pen's own path is not smooth, whatever its chords say.
        let corners: Vec<bool> = firsts.iter().map(|&f| !smooth_path(knots[f])).collect();
        let mut refusals = vec![0; centres.len()];
        let (centres, radii) =
            fit_centreline(&centres, &radii, smooth, &corners, &mut |segment, points| {
                let (from, to) = (knots[firsts[segment]], knots[firsts[segment + 1]]);
                let span = &path[from..=to];
                let ok = within_directed(span, points, 1, bound)
                    && within_directed(points, span, 2, bound);
                refusals[segment] += usize::from(!ok);
                ok
            });
        // A segment that fell to its chord between two smooth knots turns there: give it the
        // raw sample in the middle of its span as one more knot, and fit again.
        let mut more = Vec::new();
        for (segment, &refused) in refusals.iter().enumerate() {
            if refused == TANGENT_SCALES.len() - 1 {
                let (from, to) = (knots[firsts[segment]], knots[firsts[segment + 1]]);
                if to - from >= 2 {
                    more.push((from + to) / 2);
                }
            }
        }
        if more.is_empty() || round == MAX_KNOT_ROUNDS {
            return Ok(offset_outline(centres, radii, options));
        }
        knots.extend(more);
        knots.sort_unstable();
        round += 1;
    }
}

/// Rounds of knots added from the raw samples where a segment fell to its chord.
const MAX_KNOT_ROUNDS: usize = 4;

/// Builds the outline of a simplified stroke (LRPDP steps 1–4).
///
/// Never panics; an empty stroke gives an empty outline, and a stroke whose samples all coincide
/// gives a dot (a full circle of cap points around the one centre).
pub fn outline(samples: &[Sample], brush: &Brush, options: &OutlineOptions) -> Outline {
    let (mut centres, mut radii, _) = merged_centres(samples, brush);
    if let Centreline::Smooth(smooth) = &options.centreline {
        (centres, radii) = smooth_centreline(&centres, &radii, smooth);
    }
    offset_outline(centres, radii, options)
}

/// LRPDP steps 2–4 on a centreline: offsets, normals and caps.
fn offset_outline(centres: Vec<DVec2>, radii: Vec<f64>, options: &OutlineOptions) -> Outline {
    let n_samples = centres.len();
    if n_samples == 0 {
        return Outline::default();
    }

    // Unit direction of each segment; merging (and the tessellation) guarantee none has zero
    // length.
    let directions: Vec<DVec2> = centres.windows(2).map(|w| (w[1] - w[0]).normalize()).collect();
    let mut normals = Vec::with_capacity(n_samples);
    let mut upper = Vec::with_capacity(n_samples);
    let mut lower = Vec::with_capacity(n_samples);
    for sample_idx in 0..n_samples {
        let centre = centres[sample_idx];
        let t_in = sample_idx.checked_sub(1).map(|segment_idx| directions[segment_idx]);
        let t_out = directions.get(sample_idx).copied();
        let (normal, miter_factor) = match (t_in, t_out) {
            (Some(t_in), Some(t_out)) => {
                let sum = t_in + t_out;
                let sum_len = sum.length();
                if sum_len > CUSP_EPSILON {
                    // |t_in + t_out| = 2 cos(theta / 2) for a turn of angle theta.
                    (perp(sum / sum_len), (2.0 / sum_len).min(2.0))
                } else {
                    (perp(t_in), 2.0)
                }
            }
            (Some(t), None) | (None, Some(t)) => (perp(t), 1.0),
            // A dot: any direction will do.
            (None, None) => (perp(DVec2::X), 1.0),
        };
        let offset = radii[sample_idx] * if options.miter { miter_factor } else { 1.0 };
        normals.push(normal);
        upper.push(centre + offset * normal);
        lower.push(centre - offset * normal);
    }

    let first_normal = normals[0];
    let last_normal = normals[n_samples - 1];
    // Start cap: from -n_0, counter-clockwise round the back (-t) to +n_0.
    let (start_cap, start_cap_normals) =
        half_circle(centres[0], radii[0], -first_normal, options.cap_points(radii[0]));
    // End cap: from +n_last, counter-clockwise round the front (+t) to -n_last.
    let last_radius = radii[n_samples - 1];
    let (end_cap, end_cap_normals) = half_circle(
        centres[n_samples - 1],
        last_radius,
        last_normal,
        options.cap_points(last_radius),
    );

    Outline {
        centres,
        radii,
        normals,
        upper,
        lower,
        start_cap,
        end_cap,
        start_cap_normals,
        end_cap_normals,
    }
}

/// `n_points` points strictly inside the half circle that starts at `centre + radius * from`
/// and turns counter-clockwise by half a turn, with their outward normals.
fn half_circle(
    centre: DVec2,
    radius: f64,
    from: DVec2,
    n_points: usize,
) -> (Vec<DVec2>, Vec<DVec2>) {
    let step = std::f64::consts::PI / (n_points + 1) as f64;
    let normals: Vec<DVec2> = (1..=n_points)
        .map(|point_idx| DVec2::from_angle(step * point_idx as f64).rotate(from))
        .collect();
    let points = normals.iter().map(|n| centre + radius * *n).collect();
    (points, normals)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    use crate::cloud::{CloudOptions, point_cloud};

    fn line(n: usize, p: f64) -> Vec<Sample> {
        (0..n).map(|i| Sample::new(i as f64 * 2.0, 0.0, i as f64, p)).collect()
    }

    fn shoelace(points: &[DVec2]) -> f64 {
        let n = points.len();
        (0..n).map(|i| points[i].perp_dot(points[(i + 1) % n])).sum::<f64>() / 2.0
    }

    #[test]
    fn straight_stroke_offsets_across_and_is_counter_clockwise() {
        // Offsets of a straight stroke sit at ±r across it and T_c has positive area.
        let brush = Brush::default();
        let out = outline(&line(5, 1.0), &brush, &OutlineOptions::default());
        assert_eq!(out.n_samples(), 5);
        for k in 0..5 {
            assert!((out.upper[k] - DVec2::new(2.0 * k as f64, -4.0)).length() < 1e-12);
            assert!((out.lower[k] - DVec2::new(2.0 * k as f64, 4.0)).length() < 1e-12);
        }
        let closed = out.closed();
        assert_eq!(closed.len(), 10 + 2 * 4);
        assert!(shoelace(&closed) > 0.0);
    }

    #[test]
    fn cap_point_count_is_the_fewest_within_the_tolerance_with_a_floor_of_three() {
        // The cap's chords stay within the tolerance of the half circle, with one point fewer
        // they would not; small, zero and non-finite values give the floor.
        let options = OutlineOptions::default();
        assert_eq!([0.25, 2.2, 4.0, 8.0, 30.0].map(|r| options.cap_points(r)), [3, 3, 4, 6, 12]);
        for radius in [2.2, 4.0, 8.0, 30.0, 300.0] {
            let sagitta =
                |n: usize| radius * (1.0 - (std::f64::consts::PI / (2.0 * (n + 1) as f64)).cos());
            let n = options.cap_points(radius);
            assert!(sagitta(n) <= PIXEL_TOLERANCE + 1e-12, "{radius}: {n} points");
            assert!(n == MIN_CAP_POINTS || sagitta(n - 1) > PIXEL_TOLERANCE, "{radius}: {n}");
        }
        assert_eq!(options.cap_tolerance(1.0).cap_points(4.0), 3);
        assert_eq!(options.cap_tolerance(0.0).cap_points(4.0), MAX_CAP_POINTS);
        assert_eq!(options.cap_tolerance(-1.0).cap_points(4.0), MIN_CAP_POINTS);
        assert_eq!(options.cap_points(f64::NAN), MIN_CAP_POINTS);
        assert_eq!(options.cap_points(0.0), MIN_CAP_POINTS);
    }

    #[test]
    fn repeated_points_are_merged_keeping_the_larger_radius() {
        // Consecutive duplicates collapse to one centre with the larger radius.
        let samples = [
            Sample::new(0.0, 0.0, 0.0, 0.2),
            Sample::new(0.0, 0.0, 1.0, 1.0),
            Sample::new(3.0, 0.0, 2.0, 0.5),
            Sample::new(3.0, 0.0, 3.0, 0.5),
        ];
        let out = outline(&samples, &Brush::default(), &OutlineOptions::default());
        assert_eq!(out.n_samples(), 2);
        assert_eq!(out.radii, vec![4.0, 2.0]);
        assert!(out.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-12));
    }

    #[test]
    fn one_sample_is_a_full_circle() {
        // A dot's outline is a circle of radius r round the sample.
        let out = outline(
            &[Sample::new(1.0, 2.0, 0.0, 1.0)],
            &Brush::default(),
            &OutlineOptions::default(),
        );
        let closed = out.closed();
        assert_eq!(closed.len(), 2 + 2 * 4);
        for p in &closed {
            assert!((p.distance(DVec2::new(1.0, 2.0)) - 4.0).abs() < 1e-12);
        }
        assert!((shoelace(&closed) - std::f64::consts::PI * 16.0).abs() < 4.0);
    }

    #[test]
    fn cusp_falls_back_to_the_incoming_normal() {
        // A stroke that reverses on itself uses perp(t_in) at the turn.
        let samples = [
            Sample::new(0.0, 0.0, 0.0, 1.0),
            Sample::new(10.0, 0.0, 1.0, 1.0),
            Sample::new(0.0, 0.0, 2.0, 1.0),
        ];
        let out = outline(&samples, &Brush::default(), &OutlineOptions::default());
        assert!((out.normals[1] - DVec2::new(0.0, -1.0)).length() < 1e-12);
    }

    #[test]
    fn miter_widens_corners_up_to_twice_the_radius() {
        // A right-angle corner is offset by r / cos(45°) with the miter option.
        let samples = [
            Sample::new(0.0, 0.0, 0.0, 1.0),
            Sample::new(10.0, 0.0, 1.0, 1.0),
            Sample::new(10.0, 10.0, 2.0, 1.0),
        ];
        // The straight centreline: the smooth one would round this corner of short chords.
        let options = OutlineOptions::paper().miter(true);
        let out = outline(&samples, &Brush::default(), &options);
        let offset = out.upper[1].distance(out.centres[1]);
        assert!((offset - 4.0 * std::f64::consts::SQRT_2).abs() < 1e-9);
    }

    #[test]
    fn empty_stroke_gives_empty_outline_and_cloud() {
        // No samples: nothing to outline, no panic.
        let out = outline(&[], &Brush::default(), &OutlineOptions::default());
        assert!(out.is_empty() && out.closed().is_empty());
        assert!(point_cloud(&out, &CloudOptions::default()).is_empty());
    }

    #[test]
    fn dense_cloud_has_no_gap_over_the_layer_spacing() {
        // A long straight stroke: T_c has two far-apart points per side; the dense cloud fills
        // them in at most d_s apart, on the outline, with unit normals.
        let samples = [Sample::new(0.0, 0.0, 0.0, 1.0), Sample::new(100.0, 0.0, 1.0, 1.0)];
        let out = outline(&samples, &Brush::default(), &OutlineOptions::default());
        let sparse = point_cloud(&out, &CloudOptions::default());
        let dense = point_cloud(&out, &CloudOptions::default().dense(true));
        let layer = dense.len() / 9;
        let spacing = 2.0 * 4.0 / 4.0;
        assert!(dense.len() > 9 * 2 * (100 / 2) && 4 * sparse.len() < dense.len());
        for k in 0..layer {
            let (a, b) = (dense.points[k], dense.points[(k + 1) % layer]);
            assert!(a.distance(b) <= spacing + 1e-9, "{a} to {b}");
            // On the capsule of radius 4 round the stroke (a cap's chords sag by at most
            // PIXEL_TOLERANCE, the cap rule).
            let to_stroke = a.truncate().distance(DVec2::new(a.x.clamp(0.0, 100.0), 0.0));
            let on_outline = 4.0 - PIXEL_TOLERANCE - 1e-9..=4.0 + 1e-9;
            assert!(on_outline.contains(&to_stroke), "{a} is off the outline");
            assert!((dense.normals[k].length() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn cloud_has_nine_layers_spanning_the_depth() {
        // Default cloud: 2 * 4 + 1 layers of T_c from -D to D, horizontal unit normals.
        let out = outline(&line(3, 1.0), &Brush::default(), &OutlineOptions::default());
        let cloud = point_cloud(&out, &CloudOptions::default());
        assert_eq!(cloud.len(), 9 * out.n_closed());
        let max_z = cloud.points.iter().map(|p| p.z).fold(f64::MIN, f64::max);
        let min_z = cloud.points.iter().map(|p| p.z).fold(f64::MAX, f64::min);
        assert_eq!((min_z, max_z), (-8.0, 8.0));
        assert!(cloud.normals.iter().all(|n| n.z == 0.0 && (n.length() - 1.0).abs() < 1e-12));
    }

    #[test]
    fn closed_cloud_lies_on_the_solid_with_outward_normals_and_covers_top_and_bottom() {
        // A straight stroke of radius 4 from (0, 0) to (100, 0): the solid is the capsule
        // round the segment, extruded over z in [-D, D], D = 8, d_s = 2. Every point of the
        // closed cloud is on that solid's surface (the sides within the caps' chord sag, the
        // top and bottom inside the capsule) with its outward normal; every spot of the top and
        // bottom at least d_s inside the edge has a cloud point within d_s.
        let samples = [Sample::new(0.0, 0.0, 0.0, 1.0), Sample::new(100.0, 0.0, 1.0, 1.0)];
        let out = outline(&samples, &Brush::default(), &OutlineOptions::default());
        let options = CloudOptions::default().dense(true);
        let open = point_cloud(&out, &options);
        let closed = point_cloud(&out, &options.closed(true));
        let (depth, radius, spacing) = (8.0, 4.0, 2.0);
        let to_axis = |p: DVec3| p.truncate().distance(DVec2::new(p.x.clamp(0.0, 100.0), 0.0));
        let (mut top, mut bottom) = (Vec::new(), Vec::new());
        for (p, n) in closed.points.iter().zip(&closed.normals) {
            assert!((n.length() - 1.0).abs() < 1e-12, "normal {n} at {p}");
            if n.z != 0.0 {
                // Top or bottom: on the flat face, inside the capsule, normal away from z = 0.
                assert!(p.z.abs() == depth && n.z == p.z.signum() && n.x == 0.0 && n.y == 0.0);
                assert!(to_axis(*p) <= radius - spacing / 2.0 + 1e-9, "{p} is off the top");
                if p.z > 0.0 { top.push(p.truncate()) } else { bottom.push(p.truncate()) }
            } else {
                // Side: on the capsule's rim, within the depth, normal away from the axis.
                let on_side = radius - PIXEL_TOLERANCE - 1e-9..=radius + 1e-9;
                assert!(on_side.contains(&to_axis(*p)) && p.z.abs() <= depth + 1e-9, "{p}");
                let axis = DVec2::new(p.x.clamp(0.0, 100.0), 0.0);
                assert!(n.truncate().dot(p.truncate() - axis) > 0.9 * radius, "{n} at {p}");
            }
        }
        assert_eq!(closed.len() - open.len(), top.len() + bottom.len());
        assert_eq!(top.len(), bottom.len());
        let near = |points: &[DVec2], q: DVec2| points.iter().any(|p| p.distance(q) <= spacing);
        for i in 0..=200 {
            for j in -8..=8 {
                let q = DVec2::new(-4.0 + i as f64 * 0.54, j as f64 * 0.5);
                if to_axis(q.extend(0.0)) <= radius - spacing {
                    assert!(near(&top, q) && near(&bottom, q), "no top or bottom point near {q}");
                }
            }
        }
        // The paper's cloud has nothing on top: the same spots have no point at z = D.
        assert!(open.points.iter().all(|p| p.z.abs() < depth || to_axis(*p) > radius - 0.5));
    }
}
