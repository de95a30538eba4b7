//! `penmesh mesh`: simplify with ACUTS, build the LRPDP solid (or, with `--mesher poisson`, the
//! paper's screened Poisson mesh of the layered point cloud), write binary glTF.

use std::io::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use clap::{Args, ValueEnum as _};
use penmesh::{
    Brush, Centreline, CloudOptions, GlbMeta, GlbOptions, GlbStroke, OutlineOptions, Sample,
    SmoothOptions, SolidOptions, StrokeMesh,
};
use serde_json::json;

use crate::commands::args::GlbArg;
use crate::io;
use crate::poisson::{self, PoissonCloud, PoissonOptions};

#[derive(Debug, Args)]
pub struct MeshArgs {
    /// Input file: CSV (x,y,t,p), JSON, SVC2004 .txt or SigComp2011 .hwr.
    pub input: PathBuf,
    /// The GLB to write.
    #[arg(long)]
    pub out: PathBuf,
    /// How the GLB stores the meshes: compressed (the default; three.js decodes it with its
    /// MeshoptDecoder), quantised only, or plain floats for tools that decode neither.
    #[arg(long, value_enum, default_value_t = GlbArg::default())]
    pub glb: GlbArg,
    /// Also write the layered point cloud (the paper's Poisson input) as PLY: the cloud that
    /// --poisson-cloud names, at the layers' spacing (the reconstruction makes it denser).
    #[arg(long, value_name = "PATH")]
    pub ply: Option<PathBuf>,
    /// How the mesh is built from the outline: the direct closed solid, or the paper's screened
    /// Poisson reconstruction of the dense layered point cloud (seconds, not milliseconds).
    #[arg(long, value_enum, default_value_t = Mesher::Direct)]
    pub mesher: Mesher,
    /// With --mesher poisson: the octree depth of the reconstruction (its finest cell is the
    /// stroke's cloud's bounding cube, padded by 1.1, over 2^depth); 1 to 12.
    #[arg(long, default_value_t = poisson::DEFAULT_DEPTH)]
    pub poisson_depth: u32,
    /// With --mesher poisson / --meshes: the cloud reconstructed: the paper's open tube (the
    /// default; the mesh balloons above and below), or closed top and bottom.
    #[arg(long, value_enum, default_value_t = poisson::PoissonCloud::default())]
    pub poisson_cloud: poisson::PoissonCloud,
    /// Brush size E (px): the radius at full pressure with a pressure response of 1.
    #[arg(long, default_value_t = penmesh::Brush::DEFAULT_SIZE)]
    pub brush_size: f64,
    /// Pressure response chi in [0, 1].
    #[arg(long, default_value_t = penmesh::Brush::DEFAULT_PRESSURE_RESPONSE)]
    pub pressure_response: f64,
    /// The centreline the outline is offset from: a smooth curve through the retained samples
    /// (checked against the raw samples), or the paper's straight segments.
    #[arg(long, value_enum, default_value_t = CentrelineKind::Smooth)]
    pub centreline: CentrelineKind,
    /// Multiply x and y by this on reading (for example 0.0378 for SVC2004 tablet units to
    /// px, as `penmesh-lab eval` does); tolerances and the brush stay in the scaled unit.
    #[arg(long)]
    pub px_per_unit: Option<f64>,
    /// Print one JSON object instead of the summary lines: the centreline of each stroke as
    /// [x, y, r], its raw samples as [x, y, p], sizes and parameters.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub acuts: crate::commands::args::AcutsArgs,
}

/// `penmesh mesh --centreline`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CentrelineKind {
    Smooth,
    Straight,
}

/// `penmesh mesh --mesher` and the meshers `penmesh-lab eval --meshes` compares.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Mesher {
    /// The LRPDP solid, built directly from the outline (`penmesh::solid_mesh`).
    Direct,
    /// The paper's path: screened Poisson of the layered point cloud (`crate::poisson`).
    Poisson,
}

impl Mesher {
    pub fn name(self) -> &'static str {
        match self {
            Mesher::Direct => "direct",
            Mesher::Poisson => "poisson",
        }
    }
}

/// The mesh of one outline by `mesher` (the direct solid with its default thickness); an error
/// only from the Poisson reconstruction.
pub fn build_mesh(
    mesher: Mesher,
    outline: &penmesh::Outline,
    poisson: &PoissonOptions,
) -> anyhow::Result<StrokeMesh> {
    match mesher {
        Mesher::Direct => Ok(penmesh::solid_mesh(outline, &SolidOptions::default())),
        Mesher::Poisson => poisson::poisson_mesh(outline, poisson),
    }
}

pub fn run(args: &MeshArgs) -> anyhow::Result<()> {
    let params = args.acuts.params()?;
    let poisson_options = PoissonOptions {
        depth: args.poisson_depth,
        cloud: args.poisson_cloud,
        ..PoissonOptions::default()
    };
    poisson_options.validate()?;
    if args.mesher == Mesher::Poisson {
        poisson::ensure_built()?;
    }
    let brush = Brush {
        size: args.brush_size,
        pressure_response: args.pressure_response,
        ..Brush::default()
    };
    brush.validate().map_err(|e| anyhow::anyhow!("bad brush: {e}"))?;
    let mut strokes: Vec<Vec<Sample>> =
        io::read_strokes(&args.input)?.iter().map(|s| s.samples().to_vec()).collect();
    if let Some(scale) = args.px_per_unit {
        anyhow::ensure!(scale.is_finite() && scale > 0.0, "--px-per-unit must be > 0");
        for sample in strokes.iter_mut().flatten() {
            (sample.x, sample.y) = (sample.x * scale, sample.y * scale);
        }
    }
    // The smooth centreline tells corners by, and is checked against, ACUTS's guaranteed bound.
    let bound = params.tolerance + args.acuts.resample;
    let centreline = match args.centreline {
        CentrelineKind::Smooth => Centreline::Smooth(SmoothOptions::default().bound(bound)),
        CentrelineKind::Straight => Centreline::Straight,
    };
    let outline_options = OutlineOptions::default().centreline(centreline);
    let solid_options = SolidOptions::default();

    let started = Instant::now();
    let kept: Vec<Vec<usize>> = strokes
        .iter()
        .map(|stroke| penmesh::acuts(stroke, args.acuts.resample, &params).kept)
        .collect();
    let simplify_time = started.elapsed();

    let started = Instant::now();
    let outlines = strokes
        .iter()
        .zip(&kept)
        .map(|(stroke, kept)| penmesh::fitted_outline(stroke, kept, &brush, &outline_options))
        .collect::<Result<Vec<_>, _>>()?;
    let meshes: Vec<StrokeMesh> = outlines
        .iter()
        .map(|o| build_mesh(args.mesher, o, &poisson_options))
        .collect::<anyhow::Result<_>>()?;
    let metas: Vec<GlbMeta> = (0..meshes.len())
        .map(|_| GlbMeta { stroke: uuid::Uuid::new_v4(), author: "penmesh mesh".into(), brush })
        .collect();
    let glb_strokes: Vec<GlbStroke<'_>> =
        meshes.iter().zip(&metas).map(|(mesh, meta)| GlbStroke { mesh, meta }).collect();
    let glb = penmesh::strokes_glb(&glb_strokes, &GlbOptions::default().encoding(args.glb.into()));
    let build_time = started.elapsed();

    io::write_file(&args.out, &glb)?;
    if let Some(path) = &args.ply {
        let mut cloud = penmesh::PointCloud::default();
        for outline in &outlines {
            let options =
                CloudOptions::default().closed(args.poisson_cloud == PoissonCloud::Closed);
            let part = penmesh::point_cloud(outline, &options);
            cloud.points.extend(part.points);
            cloud.normals.extend(part.normals);
        }
        io::write_file(path, penmesh::point_cloud_ply(&cloud))?;
    }

    let vertices: usize = meshes.iter().map(|m| m.stats().vertices).sum();
    let triangles: usize = meshes.iter().map(|m| m.stats().triangles).sum();
    let n_input: usize = strokes.iter().map(Vec::len).sum();
    let n_kept: usize = kept.iter().map(Vec::len).sum();
    if args.json {
        let centrelines: Vec<Vec<[f64; 3]>> = outlines
            .iter()
            .map(|o| o.centres.iter().zip(&o.radii).map(|(c, r)| [c.x, c.y, *r]).collect())
            .collect();
        let smooth = match centreline {
            Centreline::Smooth(s) => json!({
                "bound": s.bound,
                "chord_tolerance": s.chord_tolerance,
                "max_turn_deg": s.max_turn_deg,
            }),
            Centreline::Straight => serde_json::Value::Null,
        };
        let raw: Vec<Vec<[f64; 3]>> =
            strokes.iter().map(|s| s.iter().map(|q| [q.x, q.y, q.p]).collect()).collect();
        let report = json!({
            "out": args.out,
            "raw": raw,
            "strokes": strokes.len(),
            "samples": n_input,
            "kept": n_kept,
            "centreline": centrelines,
            "vertices": vertices,
            "triangles": triangles,
            "bytes": glb.len(),
            "parameters": {
                "acuts": params,
                "resample": args.acuts.resample,
                "brush": brush,
                "px_per_unit": args.px_per_unit,
                "centreline": match args.centreline {
                    CentrelineKind::Smooth => "smooth",
                    CentrelineKind::Straight => "straight",
                },
                "smooth": smooth,
                "cap_tolerance": outline_options.cap_tolerance,
                "miter": outline_options.miter,
                "thickness": solid_options.thickness,
                "glb": args.glb.to_possible_value().map(|v| v.get_name().to_owned()),
                "mesher": args.mesher,
                "poisson_depth": args.poisson_depth,
                "poisson_cloud": args.poisson_cloud,
            },
        });
        // Written, not printed: a closed pipe is an error to report, not a panic.
        let mut out = std::io::stdout().lock();
        serde_json::to_writer(&mut out, &report)?;
        writeln!(out)?;
        return Ok(());
    }
    println!(
        "{}: {} strokes, {n_input} samples -> {n_kept} kept; {} mesh: {vertices} vertices, {triangles} triangles, {} bytes{}",
        args.out.display(),
        strokes.len(),
        args.mesher.name(),
        glb.len(),
        match args.glb {
            GlbArg::Meshopt => " (quantised, meshopt-compressed)",
            GlbArg::Quantized => " (quantised)",
            GlbArg::Plain => "",
        },
    );
    println!(
        "simplify {:.3} ms, outline + mesh + GLB {:.3} ms",
        simplify_time.as_secs_f64() * 1e3,
        build_time.as_secs_f64() * 1e3
    );
    Ok(())
}
