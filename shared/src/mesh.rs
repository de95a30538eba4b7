//! The direct stroke solid (LRPDP step 6): a closed, outward-wound triangle mesh built from an
//! [`Outline`] without surface reconstruction.
//!
//! The top face is the triangle strip between `T_u` and `T_v` plus a fan over each end cap; the
//! bottom face is its mirror, wound the other way; side walls join the top and bottom copies of
//! the closed outline `T_c`. A strip needs no polygon triangulator, so it stays valid where a
//! tight curve makes the outline overlap itself.
//!
//! Design:
//! - **Thickness follows the radius**: at a point of radius `r` the solid spans
//!   `z = ±thickness * r` (default `thickness = 0.5`, so it is half as thick as it is wide),
//!   which makes the stroke a flattened tube that tapers with pressure.
//! - **One vertex per outline point and face side**, shared by the face and the wall: `2 * |T_c|`
//!   vertices in all. Vertex normals are those of the elliptic tube the solid stands for: the
//!   outline's outward normal `o` tilted up (or down) to `unit(thickness * o ± z)`, so the
//!   shading reads as a rounded stroke with no duplicated vertices.
//! - Because no vertex is duplicated, the index buffer is the mesh's topology: [`mesh_defect`]
//!   checks closedness on indices, and the check means what it says.
//! - **No vertex that no pixel shows** ([`SolidOptions::tolerance`], 0.25 px by default, at
//!   1 px per unit): the centreline is tessellated for its own guarantees (no piece turns over
//!   10°, which in a bend of a few px makes pieces far shorter than a pixel), so the solid
//!   leaves out a centreline point when its four rim vertices lie within the tolerance of the
//!   edges that replace them (in 3D: the rims' offsets, so the radius, and their height
//!   `thickness * r`), the centreline turns by at most [`MAX_MERGED_TURN_DEG`] in all across the
//!   merged pieces (across an arc that turns evenly by 45°, the normals a renderer interpolates
//!   stay within half a degree of the arc's) and at most [`MAX_MERGED_PIECES`] pieces merge. The kept points keep their
//!   own normals, radii and offsets; the first and last are always kept. The outline, its
//!   centreline and their guarantees are unchanged; only the mesh is lighter.
//!
//! Guarantee: for any outline, the mesh is closed and consistently oriented (every directed edge
//! has exactly one opposite twin). Its signed volume is positive for every stroke we have tried,
//! including cusps and self-overlapping curves (see the tests), though a pathological outline
//! could fold a strip quad inside out locally.

use glam::{DVec2, DVec3};

use crate::lrpdp::{Outline, OutlineOptions, PIXEL_TOLERANCE, outline};
use crate::model::{Brush, Sample};

/// Default half-thickness of the solid, as a multiple of the local radius.
pub const DEFAULT_THICKNESS: f64 = 0.5;
/// Smallest accepted thickness factor: a thinner solid would have (almost) no volume.
pub const MIN_THICKNESS: f64 = 1e-3;
/// Most total turning (degrees) of the centreline across the pieces one edge of the solid
/// replaces: across an arc that turns evenly by 45°, normals interpolated linearly stay within
/// half a degree of the arc's.
pub const MAX_MERGED_TURN_DEG: f64 = 45.0;
/// Most centreline pieces one edge of the solid replaces (bounds the work per point).
pub const MAX_MERGED_PIECES: usize = 16;

/// How the solid is built from the outline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolidOptions {
    /// Half-thickness as a multiple of the radius: the solid spans `z = ±thickness * r`.
    /// Values below [`MIN_THICKNESS`] are raised to it; a non-finite value means the default.
    pub thickness: f64,
    /// Largest distance (px) of a left-out centreline point's rim vertices from the edges that
    /// replace them (see the module docs); 0 keeps every centreline point.
    pub tolerance: f64,
}

impl SolidOptions {
    pub fn thickness(mut self, thickness: f64) -> SolidOptions {
        self.thickness = thickness;
        self
    }

    pub fn tolerance(mut self, tolerance: f64) -> SolidOptions {
        self.tolerance = tolerance;
        self
    }

    fn effective_thickness(&self) -> f64 {
        if self.thickness.is_finite() {
            self.thickness.max(MIN_THICKNESS)
        } else {
            DEFAULT_THICKNESS
        }
    }
}

impl Default for SolidOptions {
    fn default() -> SolidOptions {
        SolidOptions { thickness: DEFAULT_THICKNESS, tolerance: PIXEL_TOLERANCE }
    }
}

/// An indexed triangle mesh with per-vertex unit normals, in the stroke's units.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StrokeMesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    /// Three indices per triangle, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
}

/// Size of a mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct MeshStats {
    pub vertices: usize,
    pub triangles: usize,
}

impl StrokeMesh {
    pub fn stats(&self) -> MeshStats {
        MeshStats { vertices: self.positions.len(), triangles: self.indices.len() / 3 }
    }

    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    /// The triangles as index triples.
    pub fn triangles(&self) -> impl Iterator<Item = [u32; 3]> + '_ {
        self.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]])
    }

    /// Per-axis minimum and maximum of the positions, `None` for an empty mesh.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let first = *self.positions.first()?;
        Some(self.positions.iter().fold((first, first), |(lo, hi), p| {
            (
                [lo[0].min(p[0]), lo[1].min(p[1]), lo[2].min(p[2])],
                [hi[0].max(p[0]), hi[1].max(p[1]), hi[2].max(p[2])],
            )
        }))
    }
}

/// Builds the closed solid of an outline. An empty outline gives an empty mesh.
///
/// Vertex layout: the outline of the kept centreline points ([`visible_centres`]) `T_c` at the
/// top (`0..n`), then at the bottom (`n..2n`), with `n` its closed outline's point count.
/// Triangles: `8 N - 4 + 4 (m_f + m_e)` for `N` kept centreline points and end caps of `m_f`,
/// `m_e` points; vertices `4 N + 2 (m_f + m_e)`.
pub fn solid_mesh(outline: &Outline, options: &SolidOptions) -> StrokeMesh {
    let thickness = options.effective_thickness();
    let keep = visible_centres(outline, options.tolerance, thickness);
    if keep.len() == outline.n_samples() {
        closed_solid(outline, thickness)
    } else {
        closed_solid(&kept_outline(outline, &keep), thickness)
    }
}

/// The centreline points the solid keeps (increasing indices into `outline.centres`): see the
/// module docs. Greedy: from the last kept point, the edge reaches as far as every point it
/// passes over allows.
pub fn visible_centres(outline: &Outline, tolerance: f64, thickness: f64) -> Vec<usize> {
    let n = outline.n_samples();
    if n <= 2 || tolerance.is_nan() || tolerance <= 0.0 {
        return (0..n).collect();
    }
    let max_turning = MAX_MERGED_TURN_DEG.to_radians();
    let rim = |side: &[DVec2], k: usize| side[k].extend(thickness * outline.radii[k]);
    let turn_at = |k: usize| {
        let (a, b) = (
            outline.centres[k] - outline.centres[k - 1],
            outline.centres[k + 1] - outline.centres[k],
        );
        a.perp_dot(b).atan2(a.dot(b)).abs()
    };
    // Whether the edges from `from` to `to` stay within the tolerance of every rim vertex in
    // between, on both sides.
    let covers = |from: usize, to: usize| {
        [&outline.upper, &outline.lower].into_iter().all(|side| {
            let (a, b) = (rim(side, from), rim(side, to));
            (from + 1..to).all(|k| segment_distance(rim(side, k), a, b) <= tolerance)
        })
    };
    let mut keep = vec![0];
    let mut from = 0;
    while from < n - 1 {
        let mut to = from + 1;
        let mut turning = 0.0;
        while to + 1 < n && to + 1 - from <= MAX_MERGED_PIECES {
            turning += turn_at(to);
            if turning > max_turning || !covers(from, to + 1) {
                break;
            }
            to += 1;
        }
        keep.push(to);
        from = to;
    }
    keep
}

/// Distance from `q` to the segment `a b`, in 3D.
fn segment_distance(q: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 { ((q - a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
    q.distance(a + t * ab)
}

/// The outline with only the centreline points `keep` (increasing indices), caps unchanged.
pub(crate) fn kept_outline(outline: &Outline, keep: &[usize]) -> Outline {
    let pick = |values: &[DVec2]| keep.iter().map(|&k| values[k]).collect();
    Outline {
        centres: pick(&outline.centres),
        radii: keep.iter().map(|&k| outline.radii[k]).collect(),
        normals: pick(&outline.normals),
        upper: pick(&outline.upper),
        lower: pick(&outline.lower),
        start_cap: outline.start_cap.clone(),
        end_cap: outline.end_cap.clone(),
        start_cap_normals: outline.start_cap_normals.clone(),
        end_cap_normals: outline.end_cap_normals.clone(),
    }
}

/// The closed solid of every point of `outline` (see [`solid_mesh`]).
fn closed_solid(outline: &Outline, thickness: f64) -> StrokeMesh {
    let n_samples = outline.n_samples();
    if n_samples == 0 {
        return StrokeMesh::default();
    }
    let n_start = outline.start_cap.len();
    let n_end = outline.end_cap.len();
    let n_loop = outline.n_closed();

    let mut mesh = StrokeMesh {
        positions: Vec::with_capacity(2 * n_loop),
        normals: Vec::with_capacity(2 * n_loop),
        indices: Vec::with_capacity(3 * (8 * n_samples + 4 * (n_start + n_end))),
    };
    // The tube's normal at a rim point with outward outline normal `o` is `unit(thickness * o ±
    // z)`; `o` is a unit vector, so one scale serves every vertex.
    let inv_length = 1.0 / thickness.hypot(1.0);
    for (point, normal, radius) in outline.closed_iter() {
        mesh.positions.push(to_f32(point.extend(thickness * radius)));
        mesh.normals.push(to_f32((thickness * normal).extend(1.0) * inv_length));
    }
    // The bottom copy mirrors the top in z.
    let mirror = |v: &[f32; 3]| [v[0], v[1], -v[2]];
    mesh.positions.extend_from_within(..);
    mesh.normals.extend_from_within(..);
    for (position, normal) in mesh.positions[n_loop..].iter_mut().zip(&mut mesh.normals[n_loop..]) {
        *position = mirror(position);
        *normal = mirror(normal);
    }

    // Loop indices of the outline's parts (see `Outline::closed`).
    let upper = |k: usize| (n_start + k) as u32;
    let lower = |k: usize| (n_start + n_samples + n_end + (n_samples - 1 - k)) as u32;
    let start_cap = |j: usize| j as u32;
    let end_cap = |j: usize| (n_start + n_samples + j) as u32;

    // The top face, counter-clockwise seen from +z.
    let top = &mut mesh.indices;
    for k in 0..n_samples - 1 {
        top.extend_from_slice(&[upper(k), upper(k + 1), lower(k + 1)]);
        top.extend_from_slice(&[upper(k), lower(k + 1), lower(k)]);
    }
    // Start cap: the half disc lower[0], cap..., upper[0], fanned from lower[0].
    for j in 0..n_start {
        let next = if j + 1 < n_start { start_cap(j + 1) } else { upper(0) };
        top.extend_from_slice(&[lower(0), start_cap(j), next]);
    }
    // End cap: the half disc upper[last], cap..., lower[last], fanned from upper[last].
    let last = n_samples - 1;
    for j in 0..n_end {
        let next = if j + 1 < n_end { end_cap(j + 1) } else { lower(last) };
        top.extend_from_slice(&[upper(last), end_cap(j), next]);
    }

    // The bottom face: the top's triangles on the bottom vertices, wound the other way.
    let n_top = mesh.indices.len();
    let bottom = |i: u32| i + n_loop as u32;
    mesh.indices.extend_from_within(..);
    for triangle in mesh.indices[n_top..].chunks_exact_mut(3) {
        let [a, b, c] = [triangle[0], triangle[1], triangle[2]];
        triangle.copy_from_slice(&[bottom(a), bottom(c), bottom(b)]);
    }
    // Walls: each outline edge a -> b (counter-clockwise) becomes an outward quad.
    for a in 0..n_loop as u32 {
        let b = (a + 1) % n_loop as u32;
        mesh.indices.extend_from_slice(&[bottom(a), bottom(b), b, bottom(a), b, a]);
    }
    mesh
}

/// Outline, then solid: the whole LRPDP mesh path for one simplified stroke.
pub fn stroke_mesh(
    samples: &[Sample],
    brush: &Brush,
    outline_options: &OutlineOptions,
    solid_options: &SolidOptions,
) -> StrokeMesh {
    solid_mesh(&outline(samples, brush, outline_options), solid_options)
}

fn to_f32(v: DVec3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// Signed volume of a triangle mesh (positive when it is closed and wound outward), computed
/// in `f64` as the sum of the tetrahedra spanned by the origin and each triangle.
pub fn signed_volume(mesh: &StrokeMesh) -> f64 {
    let vertex = |i: u32| {
        mesh.positions
            .get(i as usize)
            .map_or(DVec3::NAN, |p| DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
    };
    mesh.triangles().map(|[a, b, c]| vertex(a).dot(vertex(b).cross(vertex(c)))).sum::<f64>() / 6.0
}

/// Why a mesh is not a closed, consistently oriented surface.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MeshDefect {
    #[error("the index count {0} is not a multiple of 3")]
    RaggedIndices(usize),
    #[error("triangle {triangle} refers to vertex {index}, past the {n_vertices} vertices")]
    IndexOutOfRange { triangle: usize, index: u32, n_vertices: usize },
    #[error("triangle {triangle} repeats a vertex")]
    DegenerateTriangle { triangle: usize },
    #[error("the edge {from} -> {to} has no opposite edge {to} -> {from}")]
    OpenEdge { from: u32, to: u32 },
    #[error("the edge {from} -> {to} is used {count} times in that direction")]
    RepeatedEdge { from: u32, to: u32, count: usize },
    #[error("the positions and normals have different lengths")]
    NormalCount,
}

/// Checks that `mesh` is closed and consistently oriented, on its indices: every directed edge
/// `a -> b` occurs exactly once and its twin `b -> a` exactly once, so every undirected edge is
/// shared by exactly two triangles that agree on orientation. An empty mesh passes.
pub fn mesh_defect(mesh: &StrokeMesh) -> Result<(), MeshDefect> {
    if mesh.indices.len() % 3 != 0 {
        return Err(MeshDefect::RaggedIndices(mesh.indices.len()));
    }
    if mesh.normals.len() != mesh.positions.len() {
        return Err(MeshDefect::NormalCount);
    }
    let n_vertices = mesh.positions.len();
    let mut edges: Vec<(u32, u32)> = Vec::with_capacity(mesh.indices.len());
    for (triangle, [a, b, c]) in mesh.triangles().enumerate() {
        for index in [a, b, c] {
            if index as usize >= n_vertices {
                return Err(MeshDefect::IndexOutOfRange { triangle, index, n_vertices });
            }
        }
        if a == b || b == c || c == a {
            return Err(MeshDefect::DegenerateTriangle { triangle });
        }
        edges.extend_from_slice(&[(a, b), (b, c), (c, a)]);
    }
    edges.sort_unstable();
    for run in edges.chunk_by(|x, y| x == y) {
        let (from, to) = run[0];
        if run.len() > 1 {
            return Err(MeshDefect::RepeatedEdge { from, to, count: run.len() });
        }
        if edges.binary_search(&(to, from)).is_err() {
            return Err(MeshDefect::OpenEdge { from, to });
        }
    }
    Ok(())
}

/// Whether [`mesh_defect`] finds nothing.
pub fn is_closed(mesh: &StrokeMesh) -> bool {
    mesh_defect(mesh).is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mesh_of(samples: &[Sample]) -> StrokeMesh {
        stroke_mesh(
            samples,
            &Brush::default(),
            &OutlineOptions::default(),
            &SolidOptions::default(),
        )
    }

    #[test]
    fn straight_stroke_is_a_closed_box_like_solid_with_the_expected_counts() {
        // Counts follow 4N + 2M vertices and 8N - 4 + 4M triangles for the N kept centreline
        // points (all five with a zero tolerance, the two ends by default: the middle ones
        // change no pixel); volume ≈ area × thickness either way.
        let samples: Vec<Sample> =
            (0..5).map(|i| Sample::new(i as f64 * 2.0, 0.0, i as f64, 1.0)).collect();
        let every = stroke_mesh(
            &samples,
            &Brush::default(),
            &OutlineOptions::default(),
            &SolidOptions::default().tolerance(0.0),
        );
        assert_eq!(every.stats(), MeshStats { vertices: 4 * 5 + 2 * 8, triangles: 40 - 4 + 32 });
        let mesh = mesh_of(&samples);
        assert_eq!(mesh.stats(), MeshStats { vertices: 4 * 2 + 2 * 8, triangles: 16 - 4 + 32 });
        for mesh in [every, mesh] {
            assert_eq!(mesh_defect(&mesh), Ok(()));
            // Band 8 × 8 plus a disc of radius 4 (as 10-gon halves), 4 thick.
            let volume = signed_volume(&mesh);
            let expected = (8.0 * 8.0 + std::f64::consts::PI * 16.0) * 4.0;
            assert!(volume > 0.0 && (volume - expected).abs() < 0.05 * expected, "{volume}");
        }
    }

    #[test]
    fn empty_stroke_gives_an_empty_closed_mesh() {
        // No samples: an empty mesh, vacuously closed, zero volume.
        let mesh = mesh_of(&[]);
        assert!(mesh.is_empty() && is_closed(&mesh) && signed_volume(&mesh) == 0.0);
        assert_eq!(mesh.bounds(), None);
    }

    #[test]
    fn defects_are_found() {
        // Removing a triangle opens the mesh; flipping one breaks orientation.
        let mesh = mesh_of(&[Sample::new(0.0, 0.0, 0.0, 1.0)]);
        let mut open = mesh.clone();
        open.indices.truncate(open.indices.len() - 3);
        assert!(matches!(mesh_defect(&open), Err(MeshDefect::OpenEdge { .. })));
        let mut flipped = mesh.clone();
        flipped.indices.swap(0, 1);
        assert!(matches!(mesh_defect(&flipped), Err(MeshDefect::RepeatedEdge { .. })));
        let mut bad = mesh;
        bad.indices[0] = 10_000;
        assert!(matches!(mesh_defect(&bad), Err(MeshDefect::IndexOutOfRange { .. })));
    }
}
