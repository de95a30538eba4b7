//! The layered point cloud of LRPDP step 5 (formulas 17–22), built from an [`Outline`], for
//! the paper's own mesh path (screened Poisson, in the client) and `--ply`; optionally closed
//! top and bottom. Apart from the outline (`lrpdp.rs`), which the direct solid needs alone.

use glam::{DVec2, DVec3};

use crate::lrpdp::Outline;

/// Default depth of the layered point cloud, as a multiple of the largest radius (`D = 2 max r`).
pub const DEFAULT_CLOUD_DEPTH_FACTOR: f64 = 2.0;
/// Default number of layer spacings in the depth (`d_s = D / 4`).
pub const DEFAULT_CLOUD_DIVISIONS: u32 = 4;
/// Most points one layer of a dense cloud ([`CloudOptions::dense`]) gets; past it the points
/// are spread further apart than `d_s`, so a stroke with far-apart samples cannot exhaust memory.
pub const MAX_DENSE_LAYER_POINTS: usize = 1 << 20;

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
