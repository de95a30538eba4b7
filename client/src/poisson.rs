//! The paper's mesh path (section IV.B, figure 9): screened Poisson surface reconstruction
//! (Kazhdan and Hoppe, 2013) of LRPDP's layered point cloud, by Kazhdan's own PoissonRecon (the
//! reference implementation: C++, built by the `poissonrecon` crate's build script, called
//! through its safe API), whose isosurface is extracted over its adaptive octree.
//!
//! For comparison only (`penmesh mesh --mesher poisson`, `penmesh-lab eval --meshes`): every other
//! path builds the direct solid (`penmesh::solid_mesh`), which is exact, closed and far lighter.
//! The cloud is the paper's (9 copies of `T_c` over `±2 max r`), made dense along the stroke
//! ([`penmesh::CloudOptions::dense`]) so that no stretch between two outline points is left
//! without samples. The paper's cloud has no points on its top and bottom: the reconstruction
//! closes that open tube as the screened equation pleases, far above and below the stroke.
//! `--poisson-cloud closed` ([`PoissonCloud::Closed`]) adds points on the flat top and bottom;
//! the paper's cloud stays the default until the closed one is measured on table 8's curves.
//!
//! The octree's depth ([`PoissonOptions::depth`]) sets the finest cell: the cloud's bounding cube
//! (PoissonRecon pads it by 1.1) over `2^depth`. Time and vertices grow about 4x a level
//! (`docs/results.md`, `penmesh-lab poisson-bench`, which also runs the pure-Rust
//! `poisson_reconstruction` crate this replaced, on the same clouds).
//!
//! This lives in the client, not in the pure `penmesh` crate, although it does no I/O: it
//! brings a C++ library and nalgebra, which the proxy (which links `penmesh`) never needs.
//! The C++ is behind the client's cargo feature `poisson` (off by default: its bindgen needs
//! libclang); without it the options still parse and validate, and [`ensure_built`] and
//! [`reconstruct`] say how to get a build that has it.

use nalgebra::{Point3, Vector3};
use penmesh::{CloudOptions, Outline, PointCloud, StrokeMesh};

/// Default octree depth: the paper's mesh size (a plain-float GLB of 1-4 MB for the 300-px
/// figure-8, `docs/results.md`) in about a second.
pub const DEFAULT_DEPTH: u32 = 9;
/// Deepest octree accepted: each level costs about 4x the time and memory of the one above, and
/// depth 12 is already minutes and gigabytes on a stroke.
pub const MAX_DEPTH: u32 = 12;
/// Default screening weight: Kazhdan and Hoppe's point weight (their `--pointWeight` 4).
pub const DEFAULT_SCREENING: f64 = 4.0;

/// Which layered cloud the reconstruction is given (`--poisson-cloud`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PoissonCloud {
    /// The paper's: the sides only (an open tube); the surface balloons above and below it.
    #[default]
    Paper,
    /// The sides plus the flat top and bottom ([`CloudOptions::closed`]): a closed surface,
    /// which the reconstruction follows more closely (not yet the default: not measured on the
    /// data sets yet).
    Closed,
}

/// How the reconstruction is run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoissonOptions {
    /// The octree's depth: the finest cell is the cloud's padded bounding cube over `2^depth`.
    pub depth: u32,
    pub screening: f64,
    pub cloud: PoissonCloud,
}

impl Default for PoissonOptions {
    fn default() -> PoissonOptions {
        PoissonOptions {
            depth: DEFAULT_DEPTH,
            screening: DEFAULT_SCREENING,
            cloud: PoissonCloud::default(),
        }
    }
}

impl PoissonOptions {
    /// Refuses a depth outside 1..=[`MAX_DEPTH`] and a screening weight that is not a finite
    /// number of at least 0.
    pub fn validate(&self) -> anyhow::Result<()> {
        anyhow::ensure!(
            (1..=MAX_DEPTH).contains(&self.depth),
            "the Poisson depth must be 1 to {MAX_DEPTH}, not {}",
            self.depth
        );
        anyhow::ensure!(
            self.screening.is_finite() && self.screening >= 0.0,
            "the Poisson screening weight must be a finite number of at least 0, not {}",
            self.screening
        );
        Ok(())
    }
}

/// The cloud the reconstruction of `outline` is given: the dense layered cloud, closed top and
/// bottom unless `cloud` is the paper's.
pub fn cloud_options(cloud: PoissonCloud) -> CloudOptions {
    CloudOptions::default().dense(true).closed(cloud == PoissonCloud::Closed)
}

/// Whether this build has the Poisson mesher (the cargo feature `poisson`).
pub const BUILT: bool = cfg!(feature = "poisson");

/// What a command that needs the mesher says in a build without it.
pub const NOT_BUILT: &str = "the Poisson mesher is not in this build: build with \
    `--features poisson` (for example `cargo run --release --features poisson --bin penmesh -- \
    mesh ...`, or `--bin penmesh-lab`); it compiles Kazhdan's PoissonRecon (C++), which needs a \
    C++ compiler and libclang: `scripts/native-deps.sh test` installs them with apt-get";

/// An error naming the cargo feature when this build has no Poisson mesher: the commands that
/// need it call this before any work.
pub fn ensure_built() -> anyhow::Result<()> {
    anyhow::ensure!(BUILT, NOT_BUILT);
    Ok(())
}

/// The stroke's mesh by the paper's path: the dense layered point cloud of `outline` (closed
/// or the paper's, [`PoissonOptions::cloud`]), then [`reconstruct`]. An empty outline gives an
/// empty mesh.
pub fn poisson_mesh(outline: &Outline, options: &PoissonOptions) -> anyhow::Result<StrokeMesh> {
    reconstruct(&penmesh::point_cloud(outline, &cloud_options(options.cloud)), options)
}

/// Screened Poisson reconstruction of an oriented point cloud: the isosurface as an indexed
/// mesh wound outward (positive signed volume), with area-weighted vertex normals. Fewer than
/// four points, or a cloud with no extent, give an empty mesh; bad options, or a failure
/// inside PoissonRecon, an error; so does a build without the feature `poisson`
/// ([`NOT_BUILT`]).
pub fn reconstruct(cloud: &PointCloud, options: &PoissonOptions) -> anyhow::Result<StrokeMesh> {
    options.validate()?;
    ensure_built()?;
    let points: Vec<Point3<f64>> =
        cloud.points.iter().map(|p| Point3::new(p.x, p.y, p.z)).collect();
    let normals: Vec<Vector3<f64>> =
        cloud.normals.iter().map(|n| Vector3::new(n.x, n.y, n.z)).collect();
    let (lo, hi) = points.iter().fold(
        (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.inf(&p.coords), hi.sup(&p.coords)),
    );
    let extent = (hi - lo).max();
    if points.len() < 4 || !extent.is_finite() || extent <= 0.0 {
        return Ok(StrokeMesh::default());
    }
    let (vertices, triangles) = poisson_recon(&points, &normals, options)?;
    let positions: Vec<[f32; 3]> =
        vertices.iter().map(|p| [p.x as f32, p.y as f32, p.z as f32]).collect();
    let indices = triangles
        .iter()
        .flatten()
        .map(|&i| {
            u32::try_from(i)
                .ok()
                .filter(|&i| (i as usize) < positions.len())
                .ok_or_else(|| anyhow::anyhow!("Poisson mesh: vertex index {i} out of range"))
        })
        .collect::<anyhow::Result<Vec<u32>>>()?;
    let mut mesh = StrokeMesh { positions, normals: Vec::new(), indices };
    if penmesh::signed_volume(&mesh) < 0.0 {
        for triangle in mesh.indices.chunks_exact_mut(3) {
            triangle.swap(1, 2);
        }
    }
    mesh.normals = vertex_normals(&mesh);
    Ok(mesh)
}

/// An isosurface: its vertices and triangles.
type Surface = (Vec<Point3<f64>>, Vec<[usize; 3]>);

/// PoissonRecon's isosurface of the cloud.
#[cfg(feature = "poisson")]
fn poisson_recon(
    points: &[Point3<f64>],
    normals: &[Vector3<f64>],
    options: &PoissonOptions,
) -> anyhow::Result<Surface> {
    use poissonrecon::{PoissonParamsBuilder, SolutionParametersBuilder};
    let params = PoissonParamsBuilder::default()
        .solution_params(
            SolutionParametersBuilder::default()
                .depth(options.depth)
                .point_weight(options.screening)
                .build(),
        )
        .build();
    let surface = poissonrecon::reconstruct_surface(points, normals, &params)
        .map_err(|e| anyhow::anyhow!("Poisson reconstruction of {} points: {e}", points.len()))?;
    Ok((surface.vertices, surface.triangles))
}

/// Without the feature there is no PoissonRecon to call ([`reconstruct`] refuses first).
#[cfg(not(feature = "poisson"))]
fn poisson_recon(
    _: &[Point3<f64>],
    _: &[Vector3<f64>],
    _: &PoissonOptions,
) -> anyhow::Result<Surface> {
    anyhow::bail!(NOT_BUILT)
}

/// Each vertex's normal: the sum of its triangles' (area-weighted) normals, normalised.
fn vertex_normals(mesh: &StrokeMesh) -> Vec<[f32; 3]> {
    let position = |i: u32| {
        let p = mesh.positions[i as usize];
        Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))
    };
    let mut sums = vec![Vector3::<f64>::zeros(); mesh.positions.len()];
    for [a, b, c] in mesh.triangles() {
        let face = (position(b) - position(a)).cross(&(position(c) - position(a)));
        for i in [a, b, c] {
            sums[i as usize] += face;
        }
    }
    sums.iter()
        .map(|n| {
            let n = n.try_normalize(0.0).unwrap_or(Vector3::z());
            [n.x as f32, n.y as f32, n.z as f32]
        })
        .collect()
}

#[cfg(not(feature = "poisson"))]
#[cfg(test)]
mod without_the_feature {
    use super::*;

    #[test]
    fn the_mesher_names_the_feature_that_brings_it() {
        // A build without `poisson`: the options still validate, and asking for a mesh says
        // which feature to build with and what it needs, instead of a mesh or a panic.
        let error = ensure_built().unwrap_err().to_string();
        assert!(error.contains("--features poisson") && error.contains("libclang"), "{error}");
        let cloud = PointCloud {
            points: vec![glam::DVec3::ZERO, glam::DVec3::X, glam::DVec3::Y, glam::DVec3::Z],
            normals: vec![glam::DVec3::Z; 4],
        };
        let error = reconstruct(&cloud, &PoissonOptions::default()).unwrap_err().to_string();
        assert!(error.contains("--features poisson"), "{error}");
    }
}

#[cfg(feature = "poisson")]
#[cfg(test)]
mod tests {
    use super::*;
    use penmesh::{Brush, GeneratorParams, OutlineOptions, Shape};

    /// The finest cell of a reconstruction at `depth` of `cloud`: its padded bounding cube (1.1,
    /// PoissonRecon's default scale) over `2^depth`.
    fn finest_cell(cloud: &PointCloud, depth: u32) -> f64 {
        let (lo, hi) = cloud
            .points
            .iter()
            .fold((glam::DVec3::INFINITY, glam::DVec3::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(*p), hi.max(*p))
            });
        (hi - lo).max_element() * 1.1 / f64::from(1u32 << depth)
    }

    #[test]
    fn generated_stroke_gives_a_closed_mesh_near_its_cloud() {
        // A small generated figure-8 (40 px, depth 7, so that the test is quick): the Poisson
        // mesh is closed, wound outward, and every cloud point lies within six finest cells of
        // it (measured: 1.64 px, 4.3 cells of 0.38 px, where the stroke's loops cross).
        let params =
            GeneratorParams { shape: Shape::Figure8, size: 40.0, ..GeneratorParams::default() };
        let stroke = penmesh::generate_stroke(&params).unwrap();
        let outline =
            penmesh::outline(stroke.samples(), &Brush::default(), &OutlineOptions::default());
        let options = PoissonOptions { depth: 7, ..PoissonOptions::default() };
        let mesh = poisson_mesh(&outline, &options).unwrap();
        assert!(mesh.stats().triangles > 100, "{:?}", mesh.stats());
        assert_eq!(penmesh::mesh_defect(&mesh), Ok(()));
        assert!(penmesh::signed_volume(&mesh) > 0.0);
        let cloud = penmesh::point_cloud(&outline, &cloud_options(options.cloud));
        let cell = finest_cell(&cloud, options.depth);
        let far = crate::mesh_distance::largest_distance(&cloud.points, &mesh);
        assert!(far < 6.0 * cell, "a cloud point is {far} px from the mesh (cell {cell} px)");
    }

    #[test]
    fn empty_outline_gives_an_empty_mesh_and_bad_options_are_refused() {
        // No samples: nothing to reconstruct, no panic; a depth of 0 or past the maximum, and a
        // screening weight that is NaN or negative, are named, before any C++ runs.
        assert!(poisson_mesh(&Outline::default(), &PoissonOptions::default()).unwrap().is_empty());
        for depth in [0, MAX_DEPTH + 1, u32::MAX] {
            let error = PoissonOptions { depth, ..PoissonOptions::default() }.validate();
            assert!(error.unwrap_err().to_string().contains("Poisson depth"));
        }
        for screening in [f64::NAN, -1.0, f64::INFINITY] {
            let error = PoissonOptions { screening, ..PoissonOptions::default() }.validate();
            assert!(error.unwrap_err().to_string().contains("screening"));
        }
        let cloud = PointCloud {
            points: vec![glam::DVec3::ZERO, glam::DVec3::X, glam::DVec3::Y, glam::DVec3::Z],
            normals: vec![glam::DVec3::Z; 4],
        };
        let bad = PoissonOptions { depth: 0, ..PoissonOptions::default() };
        assert!(reconstruct(&cloud, &bad).unwrap_err().to_string().contains("Poisson depth"));
    }

    #[test]
    fn closed_cloud_keeps_the_mesh_within_the_cloud_depth_and_the_paper_cloud_balloons() {
        // A short straight stroke (60 px, radius 4: the cloud spans z in [-8, 8]), depth 7
        // (a cell of about 0.6 px). From the closed cloud the Poisson mesh stays within two
        // px of that range; from the paper's open tube it closes further out (the balloon of
        // docs/results.md).
        let samples: Vec<penmesh::Sample> = (0..=30)
            .map(|i| penmesh::Sample::new(f64::from(i) * 2.0, 0.0, f64::from(i), 1.0))
            .collect();
        let outline = penmesh::outline(&samples, &Brush::default(), &OutlineOptions::default());
        let z_range = |cloud: PoissonCloud| {
            let options = PoissonOptions { depth: 7, cloud, ..PoissonOptions::default() };
            let mesh = poisson_mesh(&outline, &options).unwrap();
            assert!(mesh.stats().triangles > 100, "{cloud:?}: {:?}", mesh.stats());
            mesh.positions
                .iter()
                .fold((f32::MAX, f32::MIN), |(lo, hi), p| (lo.min(p[2]), hi.max(p[2])))
        };
        let (lo, hi) = z_range(PoissonCloud::Closed);
        eprintln!("closed cloud: z {lo}..{hi}");
        let (paper_lo, paper_hi) = z_range(PoissonCloud::Paper);
        eprintln!("paper cloud: z {paper_lo}..{paper_hi}");
        assert!(lo > -8.0 - 2.0 && hi < 8.0 + 2.0, "closed cloud: z {lo}..{hi}");
        assert!(paper_lo < -8.0 - 2.0 || paper_hi > 8.0 + 2.0, "paper: z {paper_lo}..{paper_hi}");
    }
}
