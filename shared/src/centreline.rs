//! The smooth centreline of a simplified stroke, and the measures that judge it.
//!
//! Offsetting straight through the retained samples makes every one of them a visible corner.
//! [`smooth_centreline`] instead fits a curve with a continuous tangent through them and
//! tessellates it; LRPDP then offsets that curve ([`crate::outline`] does by default).
//!
//! - **Curve**: centripetal Catmull–Rom (`alpha = 1/2`, in the Hermite form of Yuksel et al.),
//!   through every retained sample, so each retained sample lies on the centreline. Centripetal
//!   knots give no cusp and no self-intersection within a segment.
//! - **Corners stay corners.** At a retained sample where the chords turn by `theta`, a smooth
//!   pen path that stays within the bound `B` of both chords (as ACUTS guarantees) can turn at
//!   most `2 atan(2B / L_in) + 2 atan(2B / L_out)` (a circular arc of sagitta `B` over each
//!   chord of length `L`). A turn more than [`CORNER_SLACK`] times that, or more than
//!   [`HARD_CORNER_DEG`] whatever the spacing, is a turn the pen itself made: the curve keeps
//!   it as a corner, leaving and entering along the chords (a phantom point mirrored across the
//!   corner, the same as at the stroke's ends). So long chords with a sharp turn stay sharp and
//!   short, densely retained bends are rounded. That is the rule from the retained samples
//!   alone ([`knot_corners`]); where the raw samples are known, [`crate::fitted_outline`]
//!   decides by the pen's own path instead: a retained sample is a corner exactly where that
//!   path is not smooth ([`smooth_at_samples`] at [`SMOOTH_PATH_REACH`] and
//!   [`SMOOTH_PATH_TURN_DEG`]). So a bend the pen drew round is never kept sharp, and a turn
//!   the pen made within a few px (narrower than the stroke itself) costs no points.
//! - **Tessellation** is adaptive: a nearly straight segment (end tangents within half of
//!   `max_turn_deg` of the chord, offset from it bounded within `chord_tolerance`) stays one
//!   piece; any other is cut into as many equal steps of its parameter as its estimated turning
//!   divided by `max_turn_deg` (10° by default), and each step is halved until it deviates from
//!   its chord by at most `chord_tolerance` (0.5 px) and its tangent turns by at most
//!   `max_turn_deg` (and by at most half of that against its own chord, which catches
//!   S-bends). So consecutive pieces turn by at most `max_turn_deg`. At most [`MAX_DEPTH`]
//!   halvings; no piece is cut below [`MIN_PIECE`] (0.5 px) for its distance from the chord,
//!   but a piece that turns too much is cut down to [`MIN_TURN_PIECE`] (0.02 px): a tight
//!   bend needs as many points as its turning, whatever its radius (at 0.5 px, bends of a few
//!   px radius on small signatures turned by up to 29° between pieces).
//! - **Radius** is interpolated by the same Hermite form over the same knots (no steps), then
//!   kept within the two end radii of its segment, so it never overshoots (the radius is affine
//!   in pressure above the brush's floor, so this is the pressure interpolated the same way).
//!
//! No guarantee here needs the raw samples: the curve passes through the retained samples and,
//! between them, bulges from the chord by what the neighbouring samples imply. How far the raw
//! samples are from it is measured ([`directed_distance`], `penmesh-lab eval`) and property-tested.

use glam::DVec2;

/// Default largest distance of the curve from a tessellated piece's chord, px.
pub const DEFAULT_CHORD_TOLERANCE: f64 = 0.5;
/// Default largest turn of the tangent within one tessellated piece, degrees.
pub const DEFAULT_MAX_TURN_DEG: f64 = 10.0;
/// A turn above this at a retained sample is always a corner (a hairpin is never rounded).
pub const HARD_CORNER_DEG: f64 = 120.0;
/// How much more than a smooth arc within the bound can turn a knot may turn and stay smooth.
pub const CORNER_SLACK: f64 = 1.5;
/// Most halvings of one segment in the tessellation (at most `2^MAX_DEPTH` pieces).
pub const MAX_DEPTH: u32 = 10;
/// No piece is made shorter than this (px) to follow the curve's distance from its chord:
/// finer detail would not show at one px per unit.
pub const MIN_PIECE: f64 = 0.5;
/// No piece is cut below this (px) to spread a bend: a tight bend of the curve costs as many
/// points as its turning needs, whatever its radius, but a cusp does not recurse for ever.
pub const MIN_TURN_PIECE: f64 = 0.02;

/// How the outline's centreline is made from the simplified samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Centreline {
    /// The paper's path: straight segments through the retained samples.
    Straight,
    /// A smooth curve through them (the default).
    Smooth(SmoothOptions),
}

impl Default for Centreline {
    fn default() -> Centreline {
        Centreline::Smooth(SmoothOptions::default())
    }
}

/// Settings of the smooth centreline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmoothOptions {
    /// The simplification's guaranteed bound `B` (px), which tells real corners from bends.
    pub bound: f64,
    /// Largest distance of the curve from a tessellated piece's chord, px.
    pub chord_tolerance: f64,
    /// Largest turn of the tangent within one tessellated piece, degrees.
    pub max_turn_deg: f64,
}

impl SmoothOptions {
    pub fn bound(mut self, bound: f64) -> SmoothOptions {
        self.bound = bound;
        self
    }

    pub fn chord_tolerance(mut self, chord_tolerance: f64) -> SmoothOptions {
        self.chord_tolerance = chord_tolerance;
        self
    }

    pub fn max_turn_deg(mut self, max_turn_deg: f64) -> SmoothOptions {
        self.max_turn_deg = max_turn_deg;
        self
    }
}

impl Default for SmoothOptions {
    fn default() -> SmoothOptions {
        SmoothOptions {
            bound: crate::acuts::DEFAULT_TOLERANCE + crate::acuts::DEFAULT_RESAMPLE_DISTANCE,
            chord_tolerance: DEFAULT_CHORD_TOLERANCE,
            max_turn_deg: DEFAULT_MAX_TURN_DEG,
        }
    }
}

/// The turn from direction `a` to direction `b`, radians in `[0, pi]`.
fn turn(a: DVec2, b: DVec2) -> f64 {
    a.perp_dot(b).atan2(a.dot(b)).abs()
}

/// Whether the retained sample `at` is a corner the pen made (see the module docs).
pub fn is_corner(before: DVec2, at: DVec2, after: DVec2, bound: f64) -> bool {
    let (chord_in, chord_out) = (at - before, after - at);
    let theta = turn(chord_in, chord_out);
    let arc = |chord: DVec2| 2.0 * (2.0 * bound / chord.length()).atan();
    let smooth_limit = CORNER_SLACK * (arc(chord_in) + arc(chord_out));
    theta > smooth_limit.min(HARD_CORNER_DEG.to_radians())
}

/// One cubic segment `a t^3 + b t^2 + c t + d`, `t` in `[0, 1]`, with its radius cubic.
struct Segment {
    pos: [DVec2; 4],
    radius: [f64; 4],
    radius_range: (f64, f64),
}

impl Segment {
    /// The centripetal Catmull–Rom segment from `p1` to `p2` with neighbours `p0`, `p3`, its
    /// two tangents scaled by `scale` (1: the spline; 0: the straight chord).
    fn new(p: [DVec2; 4], r: [f64; 4], scale: f64) -> Segment {
        let knot = |a: DVec2, b: DVec2| a.distance(b).sqrt();
        let (t01, t12, t23) = (knot(p[0], p[1]), knot(p[1], p[2]), knot(p[2], p[3]));
        let chord = p[2] - p[1];
        // Tangents at p1 and p2 for t in [0, 1] (Yuksel et al., without tension); merging
        // repeated points keeps every knot interval above zero.
        let m1 = chord + t12 * ((p[1] - p[0]) / t01 - (p[2] - p[0]) / (t01 + t12));
        let m2 = chord + t12 * ((p[3] - p[2]) / t23 - (p[3] - p[1]) / (t12 + t23));
        // A tangent that cancels out (only in degenerate geometry) falls back to the chord.
        let usable = |m: DVec2| if m.length() > 1e-9 * chord.length() { m } else { chord };
        let (m1, m2) = (scale * usable(m1), scale * usable(m2));
        let pos = [2.0 * (p[1] - p[2]) + m1 + m2, -3.0 * (p[1] - p[2]) - 2.0 * m1 - m2, m1, p[1]];
        let n1 = (r[2] - r[1]) + t12 * ((r[1] - r[0]) / t01 - (r[2] - r[0]) / (t01 + t12));
        let n2 = (r[2] - r[1]) + t12 * ((r[3] - r[2]) / t23 - (r[3] - r[1]) / (t12 + t23));
        let radius =
            [2.0 * (r[1] - r[2]) + n1 + n2, -3.0 * (r[1] - r[2]) - 2.0 * n1 - n2, n1, r[1]];
        Segment { pos, radius, radius_range: (r[1].min(r[2]), r[1].max(r[2])) }
    }

    fn point(&self, t: f64) -> DVec2 {
        let [a, b, c, d] = self.pos;
        ((a * t + b) * t + c) * t + d
    }

    /// The direction of travel at `t` (the chord where the derivative vanishes).
    fn tangent(&self, t: f64) -> DVec2 {
        let [a, b, c, _] = self.pos;
        let d = (3.0 * a * t + 2.0 * b) * t + c;
        if d.length_squared() > 0.0 { d } else { self.point(1.0) - self.point(0.0) }
    }

    fn radius(&self, t: f64) -> f64 {
        let [a, b, c, d] = self.radius;
        (((a * t + b) * t + c) * t + d).clamp(self.radius_range.0, self.radius_range.1)
    }
}

/// Tangent scales tried, in turn, for a segment the caller's check refuses; the last is the
/// chord, which the check must accept (ACUTS bounds the raw samples by it).
pub const TANGENT_SCALES: [f64; 4] = [1.0, 0.5, 0.25, 0.0];

/// The smooth centreline through `centres` (distinct consecutive points) with their radii:
/// the tessellated points and the radius at each. Every input point is an output point; the
/// first and last are the input's. Fewer than three points give the input back.
pub fn smooth_centreline(
    centres: &[DVec2],
    radii: &[f64],
    options: &SmoothOptions,
) -> (Vec<DVec2>, Vec<f64>) {
    let corners = knot_corners(centres, options.bound);
    fit_centreline(centres, radii, options, &corners, &mut |_, _| true)
}

/// Which of `centres` are corners by the knots alone ([`is_corner`]; the two ends always are).
pub fn knot_corners(centres: &[DVec2], bound: f64) -> Vec<bool> {
    let n = centres.len();
    (0..n)
        .map(|k| {
            k == 0 || k == n - 1 || is_corner(centres[k - 1], centres[k], centres[k + 1], bound)
        })
        .collect()
}

/// [`smooth_centreline`] with the given corners (`corner[k]` for each of `centres`; the ends
/// are corners whatever it says), each segment's tessellation (both ends included) offered to
/// `accept(segment index, points)`: a refused segment is rebuilt with its two tangents halved,
/// then quartered, then as the straight chord ([`TANGENT_SCALES`]). Halving keeps the
/// tangents' directions, so the curve stays smooth at the knots; only the refused segment
/// flattens, and only the chord makes corners of its two knots.
pub fn fit_centreline(
    centres: &[DVec2],
    radii: &[f64],
    options: &SmoothOptions,
    corner: &[bool],
    accept: &mut dyn FnMut(usize, &[DVec2]) -> bool,
) -> (Vec<DVec2>, Vec<f64>) {
    let n = centres.len().min(radii.len());
    if n < 3 {
        return (centres[..n].to_vec(), radii[..n].to_vec());
    }
    let corner: Vec<bool> =
        (0..n).map(|k| k == 0 || k == n - 1 || corner.get(k).copied().unwrap_or(false)).collect();
    let mut points = vec![centres[0]];
    let mut out_radii = vec![radii[0]];
    let mut piece_points = Vec::new();
    let mut piece_radii = Vec::new();
    for i in 0..n - 1 {
        // At a corner or an end, mirror the far neighbour: the curve leaves along the chord.
        let (p1, p2, r1, r2) = (centres[i], centres[i + 1], radii[i], radii[i + 1]);
        let (p0, r0) =
            if corner[i] { (2.0 * p1 - p2, 2.0 * r1 - r2) } else { (centres[i - 1], radii[i - 1]) };
        let (p3, r3) = if corner[i + 1] {
            (2.0 * p2 - p1, 2.0 * r2 - r1)
        } else {
            (centres[i + 2], radii[i + 2])
        };
        for scale in TANGENT_SCALES {
            piece_points.clear();
            piece_radii.clear();
            piece_points.push(p1);
            piece_radii.push(r1);
            // Both tangents along the chord (two corners) or none: a straight piece.
            if scale > 0.0 && !(corner[i] && corner[i + 1]) {
                let segment = Segment::new([p0, p1, p2, p3], [r0, r1, r2, r3], scale);
                tessellate(&segment, options, &mut piece_points, &mut piece_radii);
            }
            // The knot itself, exactly, replacing a tessellated point that rounds onto it.
            if piece_points.len() > 1 && piece_points.last().is_some_and(|q| same_point(*q, p2)) {
                piece_points.pop();
                piece_radii.pop();
            }
            piece_points.push(p2);
            piece_radii.push(r2);
            if scale == 0.0 || accept(i, &piece_points) {
                break;
            }
        }
        points.extend_from_slice(&piece_points[1..]);
        out_radii.extend_from_slice(&piece_radii[1..]);
    }
    (points, out_radii)
}

/// Pushes the interior points of `segment`: first as many equal steps of `t` as its estimated
/// turning needs, then each step halved until it is flat (see the module docs).
fn tessellate(
    segment: &Segment,
    options: &SmoothOptions,
    points: &mut Vec<DVec2>,
    radii: &mut Vec<f64>,
) {
    const PROBES: usize = 8;
    let max_turn = options.max_turn_deg.to_radians().max(1e-3);
    // Fast path for the common nearly straight segment: end tangents within half the turn limit
    // of the chord, and the cubic's offset from the chord, at most 4/27 of the tangents' parts
    // across it, within the chord tolerance. Then the segment is one flat piece.
    let [_, _, m1, p1] = segment.pos;
    let (m2, chord) = (segment.tangent(1.0), segment.point(1.0) - p1);
    let across = |m: DVec2| chord.perp_dot(m).abs() / chord.length();
    // `turn(a, b) <= half` without the arc tangent: this path runs once per segment.
    let cos_half = (0.5 * max_turn).cos();
    let near = |a: DVec2, b: DVec2| a.dot(b) >= cos_half * a.length() * b.length();
    if near(m1, chord)
        && near(chord, m2)
        && 4.0 / 27.0 * (across(m1) + across(m2)) <= options.chord_tolerance
    {
        return;
    }
    let probes: Vec<DVec2> =
        (0..=PROBES).map(|k| segment.point(k as f64 / PROBES as f64)).collect();
    let chords: Vec<DVec2> = probes.windows(2).map(|w| w[1] - w[0]).collect();
    let length: f64 = chords.iter().map(|c| c.length()).sum();
    let turning = turn(segment.tangent(0.0), chords[0])
        + chords.windows(2).map(|w| turn(w[0], w[1])).sum::<f64>()
        + turn(chords[PROBES - 1], segment.tangent(1.0));
    let by_turn = (turning / max_turn).ceil();
    let by_length = (length / MIN_PIECE).floor().max(1.0);
    let steps = by_turn.min(by_length).clamp(1.0, 64.0) as usize;
    let mut piece = Piece { segment, options, max_turn, points, radii };
    let mut t0 = 0.0;
    let mut p0 = segment.point(0.0);
    let mut d0 = segment.tangent(0.0);
    for k in 1..=steps {
        let t1 = k as f64 / steps as f64;
        let (p1, d1) = (segment.point(t1), segment.tangent(t1));
        piece.split(t0, p0, d0, t1, p1, d1, 0);
        if k < steps {
            piece.push(t1, p1);
        }
        (t0, p0, d0) = (t1, p1, d1);
    }
}

/// Whether two points coincide up to rounding (relative to their magnitude).
fn same_point(a: DVec2, b: DVec2) -> bool {
    a.distance(b) <= 1e-9 * a.abs().max_element().max(b.abs().max_element()).max(1.0)
}

/// Adaptive subdivision of one segment, pushing the interior points in order.
struct Piece<'a> {
    segment: &'a Segment,
    options: &'a SmoothOptions,
    max_turn: f64,
    points: &'a mut Vec<DVec2>,
    radii: &'a mut Vec<f64>,
}

impl Piece<'_> {
    /// Pushes a point, never making a zero-length piece (only conceivable through rounding).
    fn push(&mut self, t: f64, p: DVec2) {
        if !self.points.last().is_some_and(|last| same_point(*last, p)) {
            self.points.push(p);
            self.radii.push(self.segment.radius(t));
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn split(&mut self, t0: f64, p0: DVec2, d0: DVec2, t1: f64, p1: DVec2, d1: DVec2, depth: u32) {
        let length = p0.distance(p1);
        if depth >= MAX_DEPTH || length < 2.0 * MIN_TURN_PIECE {
            return;
        }
        let chord = p1 - p0;
        let bends = turn(d0, d1) > self.max_turn
            || turn(d0, chord) > 0.5 * self.max_turn
            || turn(chord, d1) > 0.5 * self.max_turn;
        let tm = 0.5 * (t0 + t1);
        let pm = self.segment.point(tm);
        // Below the piece floor only a bend is split further: a short piece cannot spread it.
        let deviates = length >= 2.0 * MIN_PIECE
            && chord.perp_dot(pm - p0).abs() / chord.length() > self.options.chord_tolerance;
        if !bends && !deviates {
            return;
        }
        let dm = self.segment.tangent(tm);
        self.split(t0, p0, d0, tm, pm, dm, depth + 1);
        self.push(tm, pm);
        self.split(tm, pm, dm, t1, p1, d1, depth + 1);
    }
}

/// Distance from `q` to the segment `a b`.
fn point_segment_distance(q: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 { ((q - a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
    q.distance(a + t * ab)
}

/// Distance from `q` to the polyline through `path` (infinite for an empty path).
pub fn polyline_distance(q: DVec2, path: &[DVec2]) -> f64 {
    match path {
        [] => f64::INFINITY,
        [only] => q.distance(*only),
        _ => path
            .windows(2)
            .map(|w| point_segment_distance(q, w[0], w[1]))
            .fold(f64::INFINITY, f64::min),
    }
}

/// Directed Hausdorff distance from the polyline `from` to the polyline `to`: the largest
/// distance to `to` of a point of `from`, sampled at `from`'s vertices and at `samples_per_edge
/// - 1` evenly spaced points inside each of its edges (0 if `from` is empty).
pub fn directed_distance(from: &[DVec2], to: &[DVec2], samples_per_edge: usize) -> f64 {
    let per_edge = samples_per_edge.max(1);
    let mut worst = from.first().map_or(0.0, |p| polyline_distance(*p, to));
    for w in from.windows(2) {
        for k in 1..=per_edge {
            let q = w[0].lerp(w[1], k as f64 / per_edge as f64);
            worst = worst.max(polyline_distance(q, to));
        }
    }
    worst
}

/// Whether `directed_distance(from, to, samples_per_edge) <= bound`, exactly, in about linear
/// time when the two polylines run the same way (a centreline and the raw path it was fitted
/// to): the nearest edge of `to` moves forward with the sample of `from`, so the edges near the
/// last nearest one are tried first (a distance to some edges is at least the distance to all),
/// and all of `to` only when those are not within `bound`.
pub fn within_directed(from: &[DVec2], to: &[DVec2], samples_per_edge: usize, bound: f64) -> bool {
    /// Edges tried on either side of the last nearest one.
    const WINDOW: usize = 2;
    if to.len() < 2 {
        return directed_distance(from, to, samples_per_edge) <= bound;
    }
    let n_edges = to.len() - 1;
    let mut near: usize = 0;
    let nearest = |q: DVec2, edges: std::ops::RangeInclusive<usize>| {
        edges
            .map(|i| (point_segment_distance(q, to[i], to[i + 1]), i))
            .fold((f64::INFINITY, 0), |best, d| if d.0 < best.0 { d } else { best })
    };
    let mut admits = |q: DVec2| {
        let window = near.saturating_sub(WINDOW)..=(near + WINDOW).min(n_edges - 1);
        let (mut distance, mut edge) = nearest(q, window);
        if distance > bound {
            (distance, edge) = nearest(q, 0..=n_edges - 1);
        }
        near = edge;
        distance <= bound
    };
    let per_edge = samples_per_edge.max(1);
    if let Some(first) = from.first()
        && !admits(*first)
    {
        return false;
    }
    from.windows(2)
        .all(|w| (1..=per_edge).all(|k| admits(w[0].lerp(w[1], k as f64 / per_edge as f64))))
}

/// The turn (radians) at each interior vertex of a polyline.
pub fn polyline_turns(path: &[DVec2]) -> Vec<f64> {
    path.windows(3).map(|w| turn(w[1] - w[0], w[2] - w[1])).collect()
}

/// Where the pen's path counts as smooth: it turns by less than [`SMOOTH_PATH_TURN_DEG`]
/// between the chords [`SMOOTH_PATH_REACH`] px back and ahead along it ([`smooth_at_samples`]).
/// [`crate::fitted_outline`] keeps a retained sample as a corner exactly where the path is not
/// smooth, and `penmesh-lab eval` judges the centreline's turns where it is.
pub const SMOOTH_PATH_REACH: f64 = 3.0;
pub const SMOOTH_PATH_TURN_DEG: f64 = 30.0;

/// Whether the raw path is smooth at each of its samples: the chord from the point `reach` px
/// back along the path to the sample and the chord from the sample to the point `reach` px
/// ahead turn by less than `max_turn` (radians). Samples within `reach` of an end are not smooth
/// (there is no path on one side to judge by).
pub fn smooth_at_samples(raw: &[DVec2], reach: f64, max_turn: f64) -> Vec<bool> {
    let path = PathArc::new(raw);
    (0..raw.len()).map(|k| path.is_smooth_at(k, reach, max_turn)).collect()
}

/// A raw path with its arc length at each sample, to judge smoothness at single samples
/// (`fitted_outline` asks only at its knots, a few dozen of a thousand samples).
pub(crate) struct PathArc<'a> {
    raw: &'a [DVec2],
    arc: Vec<f64>,
}

impl<'a> PathArc<'a> {
    pub(crate) fn new(raw: &'a [DVec2]) -> PathArc<'a> {
        let mut arc = Vec::with_capacity(raw.len());
        let mut total = 0.0;
        for (k, p) in raw.iter().enumerate() {
            if k > 0 {
                total += p.distance(raw[k - 1]);
            }
            arc.push(total);
        }
        PathArc { raw, arc }
    }

    /// The point of the path at arc length `s` (0 <= s <= total).
    fn at_arc(&self, s: f64) -> DVec2 {
        let (raw, arc) = (self.raw, &self.arc);
        let k = arc.partition_point(|&a| a < s).clamp(1, raw.len() - 1);
        let span = arc[k] - arc[k - 1];
        let t = if span > 0.0 { (s - arc[k - 1]) / span } else { 0.0 };
        raw[k - 1].lerp(raw[k], t)
    }

    /// [`smooth_at_samples`] at sample `k` alone.
    pub(crate) fn is_smooth_at(&self, k: usize, reach: f64, max_turn: f64) -> bool {
        let total = self.arc.last().copied().unwrap_or(0.0);
        if self.arc[k] < reach || self.arc[k] + reach > total {
            return false;
        }
        let (back, ahead) = (self.at_arc(self.arc[k] - reach), self.at_arc(self.arc[k] + reach));
        turn(self.raw[k] - back, ahead - self.raw[k]) < max_turn
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_long_sharp_turn_is_a_corner_and_a_short_gentle_one_is_not() {
        let b = 1.74;
        assert!(is_corner(DVec2::new(0.0, 0.0), DVec2::new(30.0, 0.0), DVec2::new(30.0, 30.0), b));
        assert!(!is_corner(DVec2::new(0.0, 0.0), DVec2::new(5.0, 0.0), DVec2::new(9.0, 3.0), b));
        // A hairpin is a corner however short its chords.
        assert!(is_corner(DVec2::new(0.0, 0.0), DVec2::new(1.0, 0.0), DVec2::new(0.0, 0.01), b));
    }

    #[test]
    fn points_on_a_circle_give_a_curve_close_to_the_circle() {
        let circle: Vec<DVec2> =
            (0..12).map(|k| DVec2::from_angle(k as f64 * 0.5) * 40.0).collect();
        let radii = vec![2.0; circle.len()];
        let (points, out_radii) = smooth_centreline(&circle, &radii, &SmoothOptions::default());
        assert!(points.len() >= circle.len() * 3);
        // Away from the ends (which leave along their chords), the curve follows the circle.
        let inner = points.iter().filter(|p| (0.5..=5.0).contains(&p.y.atan2(p.x).rem_euclid(6.3)));
        for p in inner {
            assert!((p.length() - 40.0).abs() < 0.2, "{p} is off the circle");
        }
        assert!(out_radii.iter().all(|&r| r == 2.0));
        let turns = polyline_turns(&points);
        assert!(turns.iter().all(|t| t.to_degrees() < 10.0));
    }
}
