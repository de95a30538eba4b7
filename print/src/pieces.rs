//! A stroke's outline cut into pieces whose solids do not overlap themselves.
//!
//! `penmesh::solid_mesh` is always closed and consistently wound, but where a stroke crosses
//! itself (a loop, a figure-eight) or bends tighter than its radius (the inner side runs
//! backwards), its solid passes through itself. Manifold's booleans assume inputs that do not:
//! united with its neighbours, such a solid leaves faces inside the print and vertices that
//! coincide without being shared, which an STL (no indices: readers weld by position) reads as
//! open edges. So each stroke is cut, along its centreline, into pieces whose solids are
//! embedded, and the pieces are united like strokes.
//!
//! A piece's solid is embedded when its closed outline is a simple polygon and every triangle
//! of its top face turns counter-clockwise: then the top is a valid triangulation of the
//! polygon, a graph `z = thickness * r > 0` over it, the bottom its mirror and the walls
//! vertical. A piece can also be replaced by its convex hull (always embedded) where the hull
//! adds at most the print's tolerance to the stroke, or where its segments fold (a bend tighter
//! than the radius: the stroke already covers the inside of the bend). Pieces grow greedily
//! from the start, the longer of the two kinds of run at each cut, so a fat, curly stroke is a
//! few hulls rather than dozens of short pieces (Manifold's cost is per union). Two pieces
//! share the rung (`upper[k]` to `lower[k]`) where one ends and the next begins, so their union
//! has no gap.

use glam::DVec2;
use penmesh::Outline;

/// One piece: the outline of centres `from..=to` (the stroke's caps only where it has its
/// ends), and whether its solid must be replaced by its convex hull.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Piece {
    pub outline: Outline,
    pub hull: bool,
}

/// The pieces of `outline`, in order along the centreline; one piece, the outline itself, when
/// its solid is embedded. From each cut, the longer of two runs is taken: the embedded run (its
/// solid as it is) or the hull run (its convex hull, while the hull stays within `tolerance` of
/// the stroke's own shape, or while its segments fold); the embedded one on a tie.
pub(crate) fn pieces(outline: &Outline, tolerance: f64) -> Vec<Piece> {
    let n = outline.n_samples();
    if n <= 1 {
        // Empty, or a dot: a convex disc.
        return vec![Piece { outline: outline.clone(), hull: false }];
    }
    let mut pieces = Vec::new();
    let mut from = 0;
    while from < n - 1 {
        let embedded = embedded_run_end(outline, from);
        let mut hull = if embedded.is_none() { hull_run_end(outline, from) } else { from };
        while hull < n - 1
            && hull + 1 - from <= MAX_HULL_SEGMENTS
            && hull_fits(outline, from, hull + 1, tolerance)
        {
            hull += 1;
        }
        let (to, is_hull) = match embedded {
            Some(to) if to >= hull => (to, false),
            _ => (hull, true),
        };
        pieces.push(Piece { outline: part(outline, from, to), hull: is_hull });
        from = to;
    }
    if pieces.len() == 1 {
        return vec![Piece { outline: outline.clone(), hull: pieces[0].hull }];
    }
    pieces
}

/// Most segments one hull piece within the tolerance spans: the check's work grows with the
/// square of the run, and a run this long is nearly straight, where an embedded piece serves.
const MAX_HULL_SEGMENTS: usize = 64;

/// Where the embedded piece that starts at centre `from` ends: it grows while its solid stays
/// embedded. `None` when its first segment alone is not.
fn embedded_run_end(outline: &Outline, from: usize) -> Option<usize> {
    let n = outline.n_samples();
    let mut edges = Vec::new();
    edges.extend(start_edges(outline, from));
    edges.extend(segment_edges(outline, from));
    let first_fits = segment_turns_left(outline, from)
        && fits(&[], &edges)
        && fits(&edges, &end_edges(outline, from + 1));
    if !first_fits {
        return None;
    }
    let mut to = from + 1;
    while to < n - 1 && segment_turns_left(outline, to) {
        let new = segment_edges(outline, to);
        if !fits(&edges, &new) {
            break;
        }
        let with_new: Vec<Edge> = edges.iter().chain(&new).copied().collect();
        if !fits(&with_new, &end_edges(outline, to + 1)) {
            break;
        }
        edges = with_new;
        to += 1;
    }
    Some(to)
}

/// Whether the convex hull of the piece `from..=to` adds at most `tolerance` to the stroke: every
/// point sampled on the hull's outline is within the stroke's radius plus `tolerance` of the
/// piece's centreline (the radius interpolated along each segment).
fn hull_fits(outline: &Outline, from: usize, to: usize, tolerance: f64) -> bool {
    const SAMPLES_PER_EDGE: usize = 8;
    let hull = convex_hull(part(outline, from, to).closed());
    let excess = |x: DVec2| {
        (from..to)
            .map(|k| {
                let (a, b) = (outline.centres[k], outline.centres[k + 1]);
                let ab = b - a;
                let t = ((x - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
                let r = outline.radii[k] + t * (outline.radii[k + 1] - outline.radii[k]);
                x.distance(a + t * ab) - r
            })
            .fold(f64::INFINITY, f64::min)
    };
    (0..hull.len()).all(|i| {
        let (p, q) = (hull[i], hull[(i + 1) % hull.len()]);
        (0..SAMPLES_PER_EDGE)
            .all(|j| excess(p.lerp(q, j as f64 / SAMPLES_PER_EDGE as f64)) <= tolerance)
    })
}

/// The convex hull of `points`, counter-clockwise (Andrew's monotone chain).
fn convex_hull(mut points: Vec<DVec2>) -> Vec<DVec2> {
    points.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    points.dedup();
    if points.len() < 3 {
        return points;
    }
    let mut hull: Vec<DVec2> = Vec::with_capacity(2 * points.len());
    for pass in [points.clone(), points.into_iter().rev().collect()] {
        let start = hull.len();
        for p in pass {
            while hull.len() >= start + 2
                && orient(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

type Edge = (DVec2, DVec2);

/// Where the hull piece that starts with the segment at `from` ends: the folded segments that
/// follow join it while the centreline turns by at most half a turn across them. A fold is a
/// bend tighter than the radius, so the stroke already covers the inside of the bend and the
/// convex hull of a bend of at most half a turn adds almost nothing to it.
fn hull_run_end(outline: &Outline, from: usize) -> usize {
    let n = outline.n_samples();
    let mut to = from + 1;
    let mut turning = 0.0;
    while to < n - 1 && !segment_turns_left(outline, to) {
        let (a, b) = (
            outline.centres[to] - outline.centres[to - 1],
            outline.centres[to + 1] - outline.centres[to],
        );
        turning += a.perp_dot(b).atan2(a.dot(b)).abs();
        if turning > std::f64::consts::PI {
            break;
        }
        to += 1;
    }
    to
}

/// The outline of centres `from..=to`, with the stroke's start cap if `from` is its start and
/// its end cap if `to` is its end; a cut end is the flat rung.
fn part(outline: &Outline, from: usize, to: usize) -> Outline {
    let last = outline.n_samples() - 1;
    let (start_cap, start_cap_normals) = if from == 0 {
        (outline.start_cap.clone(), outline.start_cap_normals.clone())
    } else {
        (Vec::new(), Vec::new())
    };
    let (end_cap, end_cap_normals) = if to == last {
        (outline.end_cap.clone(), outline.end_cap_normals.clone())
    } else {
        (Vec::new(), Vec::new())
    };
    Outline {
        centres: outline.centres[from..=to].to_vec(),
        radii: outline.radii[from..=to].to_vec(),
        normals: outline.normals[from..=to].to_vec(),
        upper: outline.upper[from..=to].to_vec(),
        lower: outline.lower[from..=to].to_vec(),
        start_cap,
        end_cap,
        start_cap_normals,
        end_cap_normals,
    }
}

/// The closed outline's edges at the start of a piece beginning at centre `from`: round the
/// start cap from `lower[0]` to `upper[0]`, or the rung `lower[from] -> upper[from]`.
fn start_edges(outline: &Outline, from: usize) -> Vec<Edge> {
    if from > 0 {
        return vec![(outline.lower[from], outline.upper[from])];
    }
    chain(
        std::iter::once(outline.lower[0])
            .chain(outline.start_cap.iter().copied())
            .chain(std::iter::once(outline.upper[0])),
    )
}

/// The closed outline's edges at the end of a piece ending at centre `to`: round the end cap
/// from `upper[last]` to `lower[last]`, or the rung `upper[to] -> lower[to]`.
fn end_edges(outline: &Outline, to: usize) -> Vec<Edge> {
    if to + 1 < outline.n_samples() {
        return vec![(outline.upper[to], outline.lower[to])];
    }
    chain(
        std::iter::once(outline.upper[to])
            .chain(outline.end_cap.iter().copied())
            .chain(std::iter::once(outline.lower[to])),
    )
}

/// The two side edges of centreline segment `k` (`k` to `k + 1`), in the closed outline's
/// counter-clockwise direction.
fn segment_edges(outline: &Outline, k: usize) -> Vec<Edge> {
    vec![(outline.upper[k], outline.upper[k + 1]), (outline.lower[k + 1], outline.lower[k])]
}

fn chain(points: impl Iterator<Item = DVec2>) -> Vec<Edge> {
    let points: Vec<DVec2> = points.collect();
    points.windows(2).map(|w| (w[0], w[1])).collect()
}

/// Whether both top triangles of segment `k` (as `penmesh::solid_mesh` builds them) turn
/// counter-clockwise.
fn segment_turns_left(outline: &Outline, k: usize) -> bool {
    let (u0, u1, l0, l1) =
        (outline.upper[k], outline.upper[k + 1], outline.lower[k], outline.lower[k + 1]);
    orient(u0, u1, l1) > 0.0 && orient(u0, l1, l0) > 0.0
}

/// Whether the edges `new` cross neither `old` nor one another (`old` is known not to cross
/// itself).
fn fits(old: &[Edge], new: &[Edge]) -> bool {
    new.iter()
        .enumerate()
        .all(|(i, a)| old.iter().chain(&new[i + 1..]).all(|b| !edges_cross(*a, *b)))
}

/// Twice the signed area of the triangle `a b c`: positive when it turns counter-clockwise.
fn orient(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    (b - a).perp_dot(c - a)
}

/// Whether two edges of a closed outline meet anywhere but at an end they share (there they
/// cross only if they run back over each other).
fn edges_cross((p1, p2): Edge, (q1, q2): Edge) -> bool {
    let (lo_p, hi_p) = (p1.min(p2), p1.max(p2));
    let (lo_q, hi_q) = (q1.min(q2), q1.max(q2));
    if hi_p.x < lo_q.x || hi_q.x < lo_p.x || hi_p.y < lo_q.y || hi_q.y < lo_p.y {
        return false;
    }
    for (shared, p, q) in [(p1, p2, q1), (p1, p2, q2), (p2, p1, q1), (p2, p1, q2)] {
        if shared == q {
            let other = if q == q1 { q2 } else { q1 };
            return orient(shared, p, other) == 0.0 && (p - shared).dot(other - shared) > 0.0;
        }
    }
    let (d1, d2) = (orient(q1, q2, p1), orient(q1, q2, p2));
    let (d3, d4) = (orient(p1, p2, q1), orient(p1, p2, q2));
    d1 * d2 <= 0.0 && d3 * d4 <= 0.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use penmesh::{Brush, OutlineOptions, Sample, outline};

    fn stroke_outline(points: &[(f64, f64)], size: f64) -> Outline {
        let samples: Vec<Sample> = points
            .iter()
            .enumerate()
            .map(|(i, &(x, y))| Sample::new(x, y, i as f64, 0.5))
            .collect();
        let brush = Brush { size, pressure_response: 1.0, min_radius: 0.25, color: None };
        outline(&samples, &brush, &OutlineOptions::default())
    }

    #[test]
    fn a_straight_stroke_is_one_piece() {
        let line: Vec<(f64, f64)> = (0..20).map(|i| (i as f64 * 10.0, 0.0)).collect();
        let o = stroke_outline(&line, 10.0);
        assert_eq!(pieces(&o, 0.25), vec![Piece { outline: o.clone(), hull: false }]);
    }

    #[test]
    fn a_loop_that_crosses_itself_is_cut_into_pieces_that_do_not() {
        // A circle of radius 50 drawn one and a quarter times round: it crosses its start.
        let points: Vec<(f64, f64)> = (0..=50)
            .map(|i| {
                let a = i as f64 / 40.0 * std::f64::consts::TAU;
                (50.0 * a.cos(), 50.0 * a.sin())
            })
            .collect();
        let o = stroke_outline(&points, 8.0);
        let cut = pieces(&o, 0.25);
        assert!(cut.len() >= 2, "{} pieces", cut.len());
        assert!(cut.iter().all(|p| !p.hull));
        // Consecutive pieces share their rung; together they cover every centre once more per cut.
        let centres: usize = cut.iter().map(|p| p.outline.n_samples()).sum();
        assert_eq!(centres, o.n_samples() + cut.len() - 1);
        assert_eq!(cut[0].outline.start_cap, o.start_cap);
        assert_eq!(cut.last().unwrap().outline.end_cap, o.end_cap);
    }

    #[test]
    fn a_bend_tighter_than_the_radius_folds_and_its_segments_become_hulls() {
        // A hairpin: out along y = 0, back along y = 4, with a radius of 20.
        let mut points: Vec<(f64, f64)> = (0..10).map(|i| (i as f64 * 10.0, 0.0)).collect();
        points.extend((0..10).rev().map(|i| (i as f64 * 10.0, 4.0)));
        let o = stroke_outline(&points, 40.0);
        let cut = pieces(&o, 0.25);
        assert!(cut.len() >= 2, "{} pieces", cut.len());
        assert!(cut.iter().any(|p| p.hull));
    }
}
