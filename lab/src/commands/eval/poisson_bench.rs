//! `penmesh-lab poisson-bench`: the two screened Poisson implementations side by side on the
//! same layered clouds, in one run: Kazhdan's PoissonRecon (what `--mesher poisson` runs,
//! `penmesh_client::poisson`) and the pure-Rust `poisson_reconstruction` crate it replaced.
//!
//! The old crate stays in the lab for this comparison only: it is the measured evidence for
//! the switch (`docs/results.md`), and a second, independent solver whose meshes can be set
//! beside PoissonRecon's. Its depth is taken the same way: the finest cell is the cloud's
//! extent over `2^depth` (PoissonRecon pads the extent by 1.1 first). Each row is one mesh, timed
//! from the cloud to the indexed mesh; PoissonRecon runs on one thread, the old crate on all
//! (rayon), so the process's CPU time is reported beside the wall time.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use nalgebra::{Point3, Vector3};
use penmesh::{Brush, OutlineOptions, PointCloud, Sample};
use penmesh_client::poisson::{self, PoissonCloud, PoissonOptions};
use poisson_reconstruction::PoissonReconstruction;
use serde::Serialize;

use super::data::load_data_sets;
use super::table::{Table, fixed};
use crate::commands::eval::table8::curves;
use penmesh_client::io;

/// The old crate's conjugate-gradient iterations per level (its own advice: about 10).
const OLD_RELAXATION_ITERS: usize = 10;
/// The old crate estimates point density this many levels above its finest one.
const OLD_DENSITY_LEVELS_UP: usize = 2;

#[derive(Debug, Args)]
pub struct PoissonBenchArgs {
    /// Recordings (files or folders, as `eval`): every stroke of each becomes one cloud.
    pub inputs: Vec<PathBuf>,
    /// Generated curves (figure8, semicircles, chromosome, leaf, scribble; 300 px/s), one cloud
    /// each; default none.
    #[arg(long, value_delimiter = ',')]
    pub curves: Vec<String>,
    /// Px per tablet unit for .txt and .hwr files (default: per format, as `eval`).
    #[arg(long)]
    pub px_per_unit: Option<f64>,
    /// Depths PoissonRecon runs at.
    #[arg(long, value_delimiter = ',', default_value = "5,6,7,8,9,10")]
    pub depths: Vec<u32>,
    /// Depths the old crate also runs at (minutes a mesh from depth 6 on).
    #[arg(long, value_delimiter = ',', default_value = "5,6")]
    pub old_depths: Vec<u32>,
    /// The cloud: the paper's open tube or closed top and bottom.
    #[arg(long, value_enum, default_value_t = PoissonCloud::default())]
    pub poisson_cloud: PoissonCloud,
    /// Write the rows as JSON.
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// Write the table as Markdown.
    #[arg(long, value_name = "OUT")]
    pub markdown: Option<PathBuf>,
}

/// One mesh: a cloud, an implementation and a depth.
#[derive(Debug, Clone, Serialize)]
pub struct BenchRow {
    pub cloud: String,
    pub points: usize,
    pub implementation: &'static str,
    pub depth: u32,
    pub vertices: usize,
    pub triangles: usize,
    pub seconds: f64,
    pub cpu_seconds: f64,
}

pub fn run(args: &PoissonBenchArgs) -> anyhow::Result<()> {
    poisson::ensure_built()?;
    for &depth in args.depths.iter().chain(&args.old_depths) {
        PoissonOptions { depth, ..PoissonOptions::default() }.validate()?;
    }
    let shapes = args
        .curves
        .iter()
        .filter(|name| !name.trim().is_empty())
        .map(|name| name.trim().parse::<penmesh::Shape>())
        .collect::<Result<Vec<_>, _>>()?;
    let mut clouds: Vec<(String, PointCloud)> = Vec::new();
    for data_set in curves(&shapes, load_data_sets(&args.inputs, args.px_per_unit)?)? {
        for file in &data_set.files {
            for (i, stroke) in file.strokes.iter().enumerate() {
                let name = if file.strokes.len() == 1 {
                    file.name.clone()
                } else {
                    format!("{} #{}", file.name, i + 1)
                };
                clouds.push((name, cloud_of(stroke, args.poisson_cloud)?));
            }
        }
    }
    anyhow::ensure!(!clouds.is_empty(), "nothing to mesh: give files, folders or --curves");
    let work = clouds.len() * (args.depths.len() + args.old_depths.len());
    let progress = ProgressBar::new(work as u64).with_style(
        ProgressStyle::with_template("{msg:>24} [{bar:40}] {pos}/{len} meshes ({elapsed})")
            .context("progress bar style")?
            .progress_chars("=> "),
    );
    let mut rows = Vec::with_capacity(work);
    for (name, cloud) in &clouds {
        for &depth in &args.depths {
            progress.set_message(format!("{name} PoissonRecon {depth}"));
            let options =
                PoissonOptions { depth, cloud: args.poisson_cloud, ..PoissonOptions::default() };
            let (mesh, seconds, cpu_seconds) = timed(|| poisson::reconstruct(cloud, &options));
            let mesh = mesh?;
            rows.push(BenchRow {
                cloud: name.clone(),
                points: cloud.len(),
                implementation: "PoissonRecon",
                depth,
                vertices: mesh.stats().vertices,
                triangles: mesh.stats().triangles,
                seconds,
                cpu_seconds,
            });
            progress.inc(1);
        }
        for &depth in &args.old_depths {
            progress.set_message(format!("{name} poisson_reconstruction {depth}"));
            let ((vertices, triangles), seconds, cpu_seconds) = timed(|| old_crate(cloud, depth));
            rows.push(BenchRow {
                cloud: name.clone(),
                points: cloud.len(),
                implementation: "poisson_reconstruction",
                depth,
                vertices,
                triangles,
                seconds,
                cpu_seconds,
            });
            progress.inc(1);
        }
    }
    progress.finish_and_clear();
    let markdown = bench_markdown(&rows);
    print!("{markdown}");
    if let Some(path) = &args.markdown {
        io::write_file(path, &markdown)?;
    }
    if let Some(path) = &args.json {
        io::write_file(path, serde_json::to_string_pretty(&rows)?)?;
    }
    Ok(())
}

/// The layered cloud `--mesher poisson` reconstructs for one unsimplified stroke (the default
/// brush and smooth centreline).
fn cloud_of(stroke: &[Sample], cloud: PoissonCloud) -> anyhow::Result<PointCloud> {
    let kept: Vec<usize> = (0..stroke.len()).collect();
    let outline =
        penmesh::fitted_outline(stroke, &kept, &Brush::default(), &OutlineOptions::default())?;
    Ok(penmesh::point_cloud(&outline, &poisson::cloud_options(cloud)))
}

/// `f`'s result, wall seconds and this process's CPU seconds.
fn timed<T>(f: impl FnOnce() -> T) -> (T, f64, f64) {
    let cpu = cpu_time::ProcessTime::now();
    let started = Instant::now();
    let result = f();
    (result, started.elapsed().as_secs_f64(), cpu.elapsed().as_secs_f64())
}

/// The old crate's mesh of `cloud` at `depth` (the settings `--mesher poisson` used with it):
/// its vertices and triangles.
fn old_crate(cloud: &PointCloud, depth: u32) -> (usize, usize) {
    let points: Vec<Point3<f64>> =
        cloud.points.iter().map(|p| Point3::new(p.x, p.y, p.z)).collect();
    let normals: Vec<Vector3<f64>> =
        cloud.normals.iter().map(|n| Vector3::new(n.x, n.y, n.z)).collect();
    let depth = depth as usize;
    let surface = PoissonReconstruction::from_points_and_normals(
        &points,
        &normals,
        poisson::DEFAULT_SCREENING,
        depth.saturating_sub(OLD_DENSITY_LEVELS_UP),
        depth,
        OLD_RELAXATION_ITERS,
    );
    let buffers = surface.reconstruct_mesh_buffers();
    (buffers.vertices().len(), buffers.indices().len() / 3)
}

/// The rows as one Markdown table, each old-crate row beside PoissonRecon's at the same depth.
fn bench_markdown(rows: &[BenchRow]) -> String {
    let mut table = Table::new(
        &["cloud", "points", "implementation", "depth", "vertices", "triangles", "wall s", "CPU s"],
        3,
    );
    for r in rows {
        table.row(vec![
            r.cloud.clone(),
            r.points.to_string(),
            r.implementation.to_string(),
            r.depth.to_string(),
            r.vertices.to_string(),
            r.triangles.to_string(),
            fixed(r.seconds, 3),
            fixed(r.cpu_seconds, 3),
        ]);
    }
    let mut md = String::from(
        "Screened Poisson: PoissonRecon (the mesher) against poisson_reconstruction (the old \
         crate), the same clouds and depths; PoissonRecon on one thread, the old crate on all.\n\n",
    );
    table.write(&mut md);
    md
}

#[cfg(all(test, feature = "poisson"))]
mod tests {
    use super::*;

    #[test]
    fn both_implementations_mesh_the_same_small_cloud() {
        // A 30-px leaf at depth 4: one row per implementation and depth, each a closed surface
        // of some vertices, and the table names both; a depth past the maximum is refused.
        let params = penmesh::GeneratorParams {
            shape: penmesh::Shape::Leaf,
            size: 30.0,
            ..penmesh::GeneratorParams::default()
        };
        let stroke = penmesh::generate_stroke(&params).unwrap().into_samples();
        let cloud = cloud_of(&stroke, PoissonCloud::Paper).unwrap();
        let options = PoissonOptions { depth: 4, ..PoissonOptions::default() };
        let new = poisson::reconstruct(&cloud, &options).unwrap();
        let (old_vertices, old_triangles) = old_crate(&cloud, 4);
        assert!(new.stats().vertices > 20 && old_vertices > 20, "{:?} {old_vertices}", new.stats());
        assert!(old_triangles > 20);
        let row = |implementation, vertices| BenchRow {
            cloud: "leaf".into(),
            points: cloud.len(),
            implementation,
            depth: 4,
            vertices,
            triangles: 0,
            seconds: 0.0,
            cpu_seconds: 0.0,
        };
        let md = bench_markdown(&[
            row("PoissonRecon", new.stats().vertices),
            row("poisson_reconstruction", old_vertices),
        ]);
        assert!(md.contains("| leaf |") && md.contains("poisson_reconstruction"), "{md}");
        let args = PoissonBenchArgs {
            inputs: Vec::new(),
            curves: vec!["leaf".into()],
            px_per_unit: None,
            depths: vec![poisson::MAX_DEPTH + 1],
            old_depths: Vec::new(),
            poisson_cloud: PoissonCloud::Paper,
            json: None,
            markdown: None,
        };
        assert!(run(&args).unwrap_err().to_string().contains("Poisson depth"));
    }
}
