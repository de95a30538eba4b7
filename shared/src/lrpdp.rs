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

use glam::{DVec2, DVec3};

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
/// Default depth of the layered point cloud, as a multiple of the largest radius (`D = 2 max r`).
pub const DEFAULT_CLOUD_DEPTH_FACTOR: f64 = 2.0;
/// Default number of layer spacings in the depth (`d_s = D / 4`).
pub const DEFAULT_CLOUD_DIVISIONS: u32 = 4;
/// Most points one layer of a dense cloud ([`CloudOptions::dense`]) gets; past it the points
/// are spread further apart than `d_s`, so a stroke with far-apart samples cannot exhaust memory.
pub const MAX_DENSE_LAYER_POINTS: usize = 1 << 20;

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

/// How the layered point cloud is built (LRPDP step 5, formulas 17–22).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CloudOptions {
    /// Depth `D` as a multiple of the largest radius.
    pub depth_factor: f64,
    /// `D / d_s`: layers sit at `z = ±xi * d_s` for `xi = 0..=divisions`.
    pub divisions: u32,
    /// Dense along the stroke: each layer is `T_c` with points added along every edge longer
    /// than `d_s`, so neighbouring points are at most `d_s` apart along the stroke as they are
    /// across the layers (what surface reconstruction needs: the outline's own points can be
    /// tens of px apart on a straight stretch). Off: the points of `T_c` only, as printed.
    pub dense: bool,
    /// Closed top and bottom: besides the layers (the solid's sides and end caps), points on
    /// the flat top `z = D` and bottom `z = -D` of the solid, a grid `d_s` apart over the
    /// stroke's area with normals `+z` and `-z`, so that the cloud samples a closed surface.
    /// Off (the paper's cloud): the sides only, an open tube that surface reconstruction closes
    /// wherever its equation pleases (far above and below the stroke, `docs/results.md`).
    pub closed: bool,
}

impl CloudOptions {
    pub fn depth_factor(mut self, depth_factor: f64) -> CloudOptions {
        self.depth_factor = depth_factor;
        self
    }

    pub fn divisions(mut self, divisions: u32) -> CloudOptions {
        self.divisions = divisions;
        self
    }

    pub fn dense(mut self, dense: bool) -> CloudOptions {
        self.dense = dense;
        self
    }

    pub fn closed(mut self, closed: bool) -> CloudOptions {
        self.closed = closed;
        self
    }
}

impl Default for CloudOptions {
    fn default() -> CloudOptions {
        CloudOptions {
            depth_factor: DEFAULT_CLOUD_DEPTH_FACTOR,
            divisions: DEFAULT_CLOUD_DIVISIONS,
            dense: false,
            closed: false,
        }
    }
}

/// Oriented points: copies of `T_c` stacked in depth, with outward normals.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PointCloud {
    pub points: Vec<DVec3>,
    pub normals: Vec<DVec3>,
}

impl PointCloud {
    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

/// The layered point cloud of an outline: copies of `T_c` at `z = ±xi * d_s` for
/// `xi = 0..=ceil(D / d_s)` (the layer `z = 0` once), `D = depth_factor * max r`,
/// `d_s = D / divisions`. Normals are the outline's outward normals (horizontal).
///
/// The range of `xi` is read as inclusive, so the cloud spans `[-D, D]` and has
/// `2 * divisions + 1` layers (9 by default). With `divisions = 0` there is one layer.
/// With [`CloudOptions::dense`], each layer has points at most `d_s` apart along `T_c`.
pub fn point_cloud(outline: &Outline, options: &CloudOptions) -> PointCloud {
    let depth = options.depth_factor * outline.max_radius();
    let divisions = options.divisions;
    let spacing = if divisions == 0 { 0.0 } else { depth / f64::from(divisions) };
    let (loop_points, loop_normals) = if options.dense {
        dense_loop(&outline.closed(), &outline.closed_normals(), spacing)
    } else {
        (outline.closed(), outline.closed_normals())
    };
    let mut layers_z = vec![0.0];
    for xi in 1..=divisions {
        let z = f64::from(xi) * spacing;
        layers_z.push(z);
        layers_z.push(-z);
    }
    let n_points = layers_z.len() * loop_points.len();
    let mut cloud =
        PointCloud { points: Vec::with_capacity(n_points), normals: Vec::with_capacity(n_points) };
    for z in layers_z {
        for (point, normal) in loop_points.iter().zip(&loop_normals) {
            cloud.points.push(point.extend(z));
            cloud.normals.push(normal.extend(0.0));
        }
    }
    if options.closed && divisions > 0 && spacing > 0.0 {
        for point in interior_grid(outline, spacing) {
            for (z, nz) in [(depth, 1.0), (-depth, -1.0)] {
                cloud.points.push(point.extend(z));
                cloud.normals.push(DVec3::new(0.0, 0.0, nz));
            }
        }
    }
    cloud
}

/// Points of a square grid `step` apart (wider if the stroke's bounding box would need more
/// than [`MAX_DENSE_LAYER_POINTS`]) that lie inside the stroke's area, at least `step / 2` in
/// from its edge (the layers' rim is there already). The area is the union of the tapered
/// capsules round the centreline's segments (radius interpolated along each), the region `T_c`
/// bounds (without the miter option), also where the outline crosses itself.
fn interior_grid(outline: &Outline, step: f64) -> Vec<DVec2> {
    let (centres, radii) = (&outline.centres, &outline.radii);
    if centres.is_empty() {
        return Vec::new();
    }
    let max_r = outline.max_radius();
    let (lo, hi) = centres
        .iter()
        .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), c| (lo.min(*c), hi.max(*c)));
    let (lo, hi) = (lo - DVec2::splat(max_r), hi + DVec2::splat(max_r));
    let size = hi - lo;
    let step = step.max((size.x * size.y / MAX_DENSE_LAYER_POINTS as f64).sqrt());
    if !step.is_finite() || step <= 0.0 {
        return Vec::new();
    }
    let (nx, ny) = ((size.x / step) as usize + 1, (size.y / step) as usize + 1);
    let margin = step / 2.0;
    let mut inside = vec![false; nx * ny];
    let n_segments = centres.len().saturating_sub(1).max(1);
    for k in 0..n_segments {
        let (a, b) = (centres[k], centres[(k + 1).min(centres.len() - 1)]);
        let (ra, rb) = (radii[k], radii[(k + 1).min(centres.len() - 1)]);
        let reach = ra.max(rb);
        let (box_lo, box_hi) = (a.min(b) - DVec2::splat(reach), a.max(b) + DVec2::splat(reach));
        let (i0, j0) = (
            ((box_lo.x - lo.x) / step).floor().max(0.0) as usize,
            ((box_lo.y - lo.y) / step).floor().max(0.0) as usize,
        );
        let (i1, j1) = (
            (((box_hi.x - lo.x) / step).ceil() as usize).min(nx - 1),
            (((box_hi.y - lo.y) / step).ceil() as usize).min(ny - 1),
        );
        let ab = b - a;
        let len2 = ab.length_squared();
        for j in j0..=j1 {
            for i in i0..=i1 {
                let p = lo + DVec2::new(i as f64, j as f64) * step;
                let t = if len2 > 0.0 { ((p - a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
                let r = ra + (rb - ra) * t;
                if p.distance(a + ab * t) <= r - margin {
                    inside[j * nx + i] = true;
                }
            }
        }
    }
    (0..nx * ny)
        .filter(|&cell| inside[cell])
        .map(|cell| lo + DVec2::new((cell % nx) as f64, (cell / nx) as f64) * step)
        .collect()
}

/// The closed loop `points` with points added evenly along each edge (the last one back to the
/// first included) so that none is longer than `max_gap` (or than the loop's length over
/// [`MAX_DENSE_LAYER_POINTS`]); the added points' normals are the normalised interpolation of
/// the edge ends' (the start's where that vanishes).
fn dense_loop(points: &[DVec2], normals: &[DVec2], max_gap: f64) -> (Vec<DVec2>, Vec<DVec2>) {
    let n = points.len();
    let edge = |i: usize| (points[i], points[(i + 1) % n]);
    let length: f64 = (0..n).map(|i| edge(i).0.distance(edge(i).1)).sum();
    let max_gap = max_gap.max(length / MAX_DENSE_LAYER_POINTS as f64);
    if n < 2 || max_gap.is_nan() || max_gap <= 0.0 {
        return (points.to_vec(), normals.to_vec());
    }
    let (mut dense_points, mut dense_normals) = (Vec::new(), Vec::new());
    for i in 0..n {
        let (from, to) = edge(i);
        let (n_from, n_to) = (normals[i], normals[(i + 1) % n]);
        let pieces = (from.distance(to) / max_gap).ceil().max(1.0) as usize;
        for k in 0..pieces {
            let f = k as f64 / pieces as f64;
            dense_points.push(from.lerp(to, f));
            dense_normals.push(n_from.lerp(n_to, f).try_normalize().unwrap_or(n_from));
        }
    }
    (dense_points, dense_normals)
}

/// The point cloud as binary little-endian PLY: an ASCII header declaring
/// `element vertex N` with `float x, y, z, nx, ny, nz`, then `N` records of six little-endian
/// `f32` (24 bytes each).
pub fn point_cloud_ply(cloud: &PointCloud) -> Vec<u8> {
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment penmesh LRPDP layered point cloud\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\nend_header\n",
        cloud.len()
    );
    let mut bytes = Vec::with_capacity(header.len() + 24 * cloud.len());
    bytes.extend_from_slice(header.as_bytes());
    for (point, normal) in cloud.points.iter().zip(&cloud.normals) {
        for value in point.to_array().into_iter().chain(normal.to_array()) {
            bytes.extend_from_slice(&(value as f32).to_le_bytes());
        }
    }
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;

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
