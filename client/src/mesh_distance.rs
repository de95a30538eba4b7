//! How far apart two meshes are: the Hausdorff distance in both directions, the largest
//! distance from a point of one surface to the other surface.
//!
//! Sampled, as Metro and MeshLab do: every triangle of the measured mesh is cut into a grid of
//! points at most [`SAMPLE_STEP`] apart (its vertices, edges and inside), and each point's
//! distance to the other mesh's triangles is exact (parry's bounding-volume tree). Every point of
//! a triangle lies within `SAMPLE_STEP` of a sample, so the true distance is at most the sampled
//! one plus `SAMPLE_STEP`, and at least the sampled one.
//!
//! The largest of the samples' distances is found without asking the tree for most of them: the
//! distance to a surface changes by at most as much as the point moves (it is 1-Lipschitz), so a
//! sample within `m - d` of a sample at distance `d` cannot exceed a largest distance `m` found so
//! far, and is skipped. The result is the same maximum over the same samples as asking for every
//! one (the tests compare the two), in a fraction of the queries: neighbouring samples are a
//! fraction of a px apart, the distances tens of px for a Poisson mesh, one or two for a solid.

use glam::DVec3;
use nalgebra::Point3;
use parry3d_f64::query::PointQuery as _;
use parry3d_f64::shape::TriMesh;
use penmesh::StrokeMesh;
use serde::Serialize;

/// Largest distance between neighbouring samples on a triangle, in the meshes' unit (px).
pub const SAMPLE_STEP: f64 = 0.25;

/// The Hausdorff distance of a mesh to a reference, both directions, in the meshes' unit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Hausdorff {
    /// Largest distance from a point of the mesh to the reference.
    pub to_reference: f64,
    /// Largest distance from a point of the reference to the mesh.
    pub from_reference: f64,
}

impl Hausdorff {
    /// The symmetric Hausdorff distance, the larger of the two.
    pub fn max(&self) -> f64 {
        self.to_reference.max(self.from_reference)
    }
}

/// Both directed distances between `mesh` and `reference`; `None` when either has no triangle.
pub fn hausdorff(mesh: &StrokeMesh, reference: &StrokeMesh) -> Option<Hausdorff> {
    hausdorff_sampled(mesh, reference, SAMPLE_STEP)
}

/// [`hausdorff`] with samples at most `step` apart (the true distances are at most `step`
/// above the sampled ones): a coarser step for large meshes, whose cost grows with their area
/// over `step` squared.
pub fn hausdorff_sampled(
    mesh: &StrokeMesh,
    reference: &StrokeMesh,
    step: f64,
) -> Option<Hausdorff> {
    Some(SampledMesh::new(mesh, step)?.hausdorff_to(&SampledMesh::new(reference, step)?))
}

/// A mesh made ready to be measured against others: its triangles' bounding-volume tree and its
/// surface samples. Built once for a reference that many meshes are measured against.
#[derive(Debug)]
pub struct SampledMesh {
    tree: TriMesh,
    samples: Vec<Point3<f64>>,
}

impl SampledMesh {
    /// `mesh`'s tree and its samples at most `step` apart; `None` when it has no triangle.
    pub fn new(mesh: &StrokeMesh, step: f64) -> Option<SampledMesh> {
        Some(SampledMesh { tree: tree(mesh)?, samples: surface_samples(mesh, step) })
    }

    /// Both directed distances between this mesh and `reference`.
    pub fn hausdorff_to(&self, reference: &SampledMesh) -> Hausdorff {
        Hausdorff {
            to_reference: largest(&self.samples, &reference.tree),
            from_reference: largest(&reference.samples, &self.tree),
        }
    }
}

/// The largest distance from one of `points` to the surface of `mesh` (infinite for a mesh
/// without triangles, 0 for no points).
pub fn largest_distance(points: &[DVec3], mesh: &StrokeMesh) -> f64 {
    let Some(tree) = tree(mesh) else { return f64::INFINITY };
    let points: Vec<Point3<f64>> = points.iter().map(|p| Point3::new(p.x, p.y, p.z)).collect();
    largest(&points, &tree)
}

fn tree(mesh: &StrokeMesh) -> Option<TriMesh> {
    let vertices = mesh.positions.iter().map(|p| point(*p)).collect();
    TriMesh::new(vertices, mesh.triangles().collect()).ok()
}

fn point(p: [f32; 3]) -> Point3<f64> {
    Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))
}

/// Every how many points one is measured first, so that the scan starts with a largest
/// distance near the final one and can skip from its first point.
const SEED_STRIDE: usize = 64;

/// The largest distance from one of `points` to `surface` (0 for no points): the same value as
/// measuring every point, but a point within `largest - d` of the last measured point (at
/// distance `d`) is skipped, as it cannot be farther than `largest` (module docs).
fn largest(points: &[Point3<f64>], surface: &TriMesh) -> f64 {
    let distance = |p: &Point3<f64>| surface.distance_to_local_point(p, false);
    let mut largest = points.iter().step_by(SEED_STRIDE).map(distance).fold(0.0, f64::max);
    let mut last: Option<(Point3<f64>, f64)> = None;
    for p in points {
        if let Some((at, d)) = last {
            if d + (p - at).norm() <= largest {
                continue;
            }
        }
        let d = distance(p);
        largest = largest.max(d);
        last = Some((*p, d));
    }
    largest
}

/// Points on every triangle of `mesh`, a barycentric grid at most `step` apart: each vertex
/// once, then each triangle's grid points but its corners (a triangle smaller than `step` adds
/// none, so a fine mesh costs its vertices, not six times them).
fn surface_samples(mesh: &StrokeMesh, step: f64) -> Vec<Point3<f64>> {
    let mut samples: Vec<Point3<f64>> = mesh.positions.iter().map(|p| point(*p)).collect();
    for [a, b, c] in mesh.triangles() {
        let (a, b, c) = (
            point(mesh.positions[a as usize]),
            point(mesh.positions[b as usize]),
            point(mesh.positions[c as usize]),
        );
        let longest = (b - a).norm().max((c - b).norm()).max((a - c).norm());
        // A cut of `n` pieces along every edge puts each point within longest / n of a sample.
        let n = (longest / step).ceil().clamp(1.0, 1e4) as usize;
        for i in 0..=n {
            for j in 0..=n - i {
                let corner = (i == 0 && j == 0) || i == n || j == n;
                if !corner {
                    let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                    samples.push(a + (b - a) * u + (c - a) * v);
                }
            }
        }
    }
    samples
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A square of side `side` at height `z`, two triangles.
    fn square(side: f32, z: f32) -> StrokeMesh {
        StrokeMesh {
            positions: vec![[0.0, 0.0, z], [side, 0.0, z], [side, side, z], [0.0, side, z]],
            normals: vec![[0.0, 0.0, 1.0]; 4],
            indices: vec![0, 1, 2, 0, 2, 3],
        }
    }

    #[test]
    fn hausdorff_measures_each_direction() {
        // A unit square 2 above a 3-wide one: from the small one every point is 2 above the
        // large one; from the large one the far corner is sqrt(2² + 2² + 2²) from the small one.
        let h = hausdorff(&square(1.0, 2.0), &square(3.0, 0.0)).unwrap();
        assert!((h.to_reference - 2.0).abs() < 1e-9, "{h:?}");
        assert!((h.from_reference - 12.0_f64.sqrt()).abs() < 1e-9, "{h:?}");
        assert!(hausdorff(&square(3.0, 0.0), &square(3.0, 0.0)).unwrap().max() < 1e-9);
        assert!(hausdorff(&StrokeMesh::default(), &square(1.0, 0.0)).is_none());
    }

    #[test]
    fn inside_of_a_triangle_is_sampled() {
        // The reference is a tiny triangle at each corner of a large one: the large one's
        // vertices all lie on the reference, its middle (round (20, 20)) is some 27 px away.
        let large = StrokeMesh {
            positions: vec![[0.0, 0.0, 0.0], [40.0, 0.0, 0.0], [0.0, 40.0, 0.0]],
            normals: vec![[0.0, 0.0, 1.0]; 3],
            indices: vec![0, 1, 2],
        };
        let reference = StrokeMesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [0.5, 0.0, 0.0],
                [0.0, 0.5, 0.0],
                [40.0, 0.0, 0.0],
                [39.5, 0.0, 0.0],
                [39.5, 0.5, 0.0],
                [0.0, 40.0, 0.0],
                [0.0, 39.5, 0.0],
                [0.5, 39.5, 0.0],
            ],
            normals: vec![[0.0, 0.0, 1.0]; 9],
            indices: (0..9).collect(),
        };
        let h = hausdorff(&large, &reference).unwrap();
        assert!((25.0..29.0).contains(&h.to_reference), "{h:?}");
        assert!(h.from_reference < 1e-9, "{h:?}");
    }

    #[test]
    fn skipping_samples_gives_the_largest_distance_of_every_sample() {
        // The direct solids of a generated figure-8 from all its samples and from every 8th:
        // the skipping scan finds the same largest distance, both ways, as measuring each
        // sample (and a real one: the two solids differ by about a px).
        let params = penmesh::GeneratorParams {
            shape: penmesh::Shape::Figure8,
            size: 120.0,
            ..penmesh::GeneratorParams::default()
        };
        let samples = penmesh::generate_stroke(&params).unwrap().into_samples();
        let every_8th: Vec<penmesh::Sample> = samples.iter().step_by(8).copied().collect();
        let solid = |samples: &[penmesh::Sample]| {
            let outline = penmesh::outline(
                samples,
                &penmesh::Brush::default(),
                &penmesh::OutlineOptions::default(),
            );
            penmesh::solid_mesh(&outline, &penmesh::SolidOptions::default())
        };
        let (full, coarse) = (solid(&samples), solid(&every_8th));
        for (mesh, reference) in [(&full, &coarse), (&coarse, &full)] {
            let points = surface_samples(mesh, SAMPLE_STEP);
            let surface = tree(reference).unwrap();
            let every = points
                .iter()
                .map(|p| surface.distance_to_local_point(p, false))
                .fold(0.0, f64::max);
            let skipping = largest(&points, &surface);
            assert!(every > 0.1, "the solids should differ: {every}");
            assert!((skipping - every).abs() < 1e-9, "skipping {skipping}, every sample {every}");
            // And on short runs of the samples, where the first measured point is the only
            // seed and most of the maximum's work is the skipping rule's.
            for run in points.chunks(37) {
                let every = run
                    .iter()
                    .map(|p| surface.distance_to_local_point(p, false))
                    .fold(0.0, f64::max);
                let skipping = largest(run, &surface);
                assert!((skipping - every).abs() < 1e-9, "run: {skipping} against {every}");
            }
        }
    }
}
