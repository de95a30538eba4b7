//! `penmesh-lab eval`: ACUTS and the baselines over every stroke of one or more data sets, with the
//! paper's table 6 metrics, the equal-error comparison against optimal min-#, rate–distortion
//! sweeps and the mesh table (table 8).
//!
//! **Units.** Every distance is in CSS px (96 per inch). Tablet files are converted at read time:
//! SVC2004 `.txt` at 2540 lines per inch (the WACOM Intuos of SVC2004: 0.01 mm per unit, so
//! 96 / 2540 px per unit) and SigComp2011 `.hwr` at 5080 lines per inch (the WACOM Intuos3 of
//! SigComp2011: 0.005 mm per unit). CSV and JSON are taken as px. `--px-per-unit` overrides the
//! tablet factor. So a bound in px means the same on-screen error on every data set: the
//! default guaranteed bound of 1.74 px is 0.46 mm, 46 SVC2004 units or 92 SigComp2011 units.
//!
//! **The bound.** Every method is compared at one *guaranteed* bound `B` on the distance of a
//! removed sample to its spanning retained segment: ACUTS guarantees `d_d + l_eps` (stage 1
//! drops samples within `l_eps` of a sample that stage 2 then bounds by `d_d`), the others their
//! tolerance. So the baselines and optimal min-# run at `B = d_d + l_eps`. In a sweep, ACUTS
//! keeps the ratio of `d_d` to `l_eps` and scales both to each bound.
//!
//! **Stage 1's repeat rule** (the clients' default, `penmesh::Resampler`) is not part of the
//! `acuts` rows, which run stage 2 over every sample as `penmesh::acuts` does; each data set's
//! stage-1 table shows what it changes.
//!
//! **`--meshes`** runs the paper's table 8 instead (`table8.rs`): both meshers, the paper's
//! four curves and the data sets given.

mod algos;
mod data;
mod glb_sizes;
mod meshes;
pub mod poisson_bench;
mod report;
mod stage1;
mod table;
mod table8;

use self::algos::*;
use self::data::*;
use self::glb_sizes::*;
use self::meshes::*;
use self::report::*;
use self::stage1::*;
use self::table8::*;

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use penmesh::baselines::{BASELINE_NAMES, Simplify, baseline, min_points};
use penmesh::{
    AcutsParams, Brush, GlbMeta, GlbOptions, GlbStroke, OutlineOptions, Resampler, Sample,
    SolidOptions, StrokeMesh, SvgStroke,
};
use serde::Serialize;

use crate::plot::{LineChart, Series, SeriesLabelPosition};
use penmesh_client::commands::args::AcutsArgs;
use penmesh_client::io;

/// The bounds of `--sweep`, px.
const SWEEP_BOUNDS: [f64; 10] = [0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0];

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Data: directories (searched recursively for .txt, .hwr, .csv, .json) or files. Each
    /// folder is one data set.
    pub inputs: Vec<PathBuf>,
    /// Algorithms, comma separated: acuts, acuts-paper, dp, vw, window, window-d, window-p,
    /// squish-e, bqs, fbqs, dpts, optimal, optimal-p (window-p and optimal-p also bound the
    /// pressure error by ACUTS's pressure tolerance). Default: all but window-d; with --meshes,
    /// the paper's five (bqs, dp, window, squish-e, dpts), acuts-paper, acuts and optimal.
    #[arg(long, value_delimiter = ',')]
    pub algos: Option<Vec<String>>,
    /// ACUTS's setting; the bound of every method is d_d + l_eps.
    #[command(flatten)]
    pub acuts: AcutsArgs,
    /// Px per tablet unit for .txt and .hwr files (default: per format, see the docs).
    #[arg(long)]
    pub px_per_unit: Option<f64>,
    /// Also evaluate generated strokes: the four classic contours and scribbles at 200-500 px/s.
    #[arg(long)]
    pub synth: bool,
    /// Rate-distortion sweep over bounds from 0.25 to 8 px.
    #[arg(long)]
    pub sweep: bool,
    /// Write the whole report as JSON.
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// Write the tables as Markdown.
    #[arg(long, value_name = "OUT")]
    pub markdown: Option<PathBuf>,
    /// Write SVG figures (rate-distortion curves, overlays of one signature) into this folder.
    #[arg(long, value_name = "DIR")]
    pub plots: Option<PathBuf>,
    /// Only measure the pipeline's one-stroke GLB files (ACUTS, the checked smooth centreline,
    /// the default brush) in each encoding: median, largest, bytes per raw sample.
    #[arg(long, conflicts_with_all = ["algos", "sweep", "plots", "synth"])]
    pub glb_sizes: bool,
    /// With --glb-sizes: scale each stroke (about its first sample) so that the larger side of
    /// its bounding box is this many px, as a board of strokes of one size would draw them.
    #[arg(long, value_name = "PX", requires = "glb_sizes")]
    pub stroke_size: Option<f64>,
    /// With --glb-sizes: also write every stroke's GLB, in each encoding, into this folder
    /// (DATA-NNN.ENCODING.glb), for the glTF validator and three.js check
    /// (client/web/test/glb-check.mjs).
    #[arg(long, value_name = "DIR", requires = "glb_sizes")]
    pub glb_out: Option<PathBuf>,
    /// The paper's table 8 instead of the simplification tables: the meshes of the paper's four
    /// curves (generated at 300 px/s) and of the data sets given, by the paper's screened
    /// Poisson and by the direct solid; --json then writes one row per curve, method and mesher.
    /// Poisson takes seconds a stroke.
    #[arg(long, conflicts_with_all = ["sweep", "plots", "synth"])]
    pub meshes: bool,
    /// With --meshes: the generated curves (figure8, semicircles, chromosome, leaf, scribble;
    /// default the paper's four); `--curves ''` for none.
    #[arg(long, value_delimiter = ',')]
    pub curves: Option<Vec<String>>,
    /// With --meshes: the octree depth of the Poisson reconstruction (1 to 12).
    #[arg(long, default_value_t = penmesh_client::poisson::DEFAULT_DEPTH)]
    pub poisson_depth: u32,
    /// With --mesher poisson / --meshes: the cloud reconstructed: the paper's open tube (the
    /// default; the mesh balloons above and below), or closed top and bottom.
    #[arg(long, value_enum, default_value_t = penmesh_client::poisson::PoissonCloud::default())]
    pub poisson_cloud: penmesh_client::poisson::PoissonCloud,
    /// With --meshes: strokes meshed at once, one a thread (default: the machine's cores).
    #[arg(long)]
    pub jobs: Option<usize>,
}

/// Table 6's row for one algorithm on one data set, plus the equal-error ratios.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub algo: String,
    pub online: bool,
    pub n_strokes: usize,
    pub n: usize,
    pub c: usize,
    pub cr: f64,
    /// Mean synchronised Euclidean distance over all samples, px.
    pub sed: f64,
    /// Largest segment distance over the data set, px.
    pub e_max: f64,
    /// Mean of the strokes' E_max, px.
    pub e_max_mean: f64,
    /// Relative loss of polyline length over the data set, %.
    pub e_l: f64,
    /// Largest pressure error: a removed sample's pressure against the pressure interpolated
    /// (by time, as SED) along its spanning segment. What the pressure-aware methods bound.
    pub p_max: f64,
    pub time_ms: f64,
    /// Points kept over optimal min-# at the same guaranteed bound.
    pub ratio_at_bound: f64,
    /// Points kept over optimal min-# at the E_max each stroke actually reached.
    pub ratio_at_reached: f64,
}

/// One point of a rate–distortion curve.
#[derive(Debug, Clone, Serialize)]
pub struct SweepPoint {
    pub algo: String,
    pub bound: f64,
    pub kept_percent: f64,
    pub e_max_mean: f64,
    pub sed: f64,
    pub ratio_at_bound: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct DataSetReport {
    pub name: String,
    pub n_files: usize,
    pub n_strokes: usize,
    pub bound: f64,
    /// The file the overlay figures show.
    pub overlay_file: Option<String>,
    pub rows: Vec<Row>,
    /// ACUTS with stage 1's repeat rule off and on.
    pub stage1: Vec<Stage1Row>,
    pub mesh: Vec<MeshRow>,
    /// The straight and the smooth centreline of ACUTS's simplification, against the raw path.
    pub centreline: Vec<CentrelineRow>,
    pub sweep: Vec<SweepPoint>,
}

#[derive(Debug, Clone, Serialize)]
pub struct EvalReport {
    pub tolerance: f64,
    pub resample: f64,
    pub angle_deg: f64,
    pub angle_near_anchor: bool,
    pub pressure: penmesh::PressureGate,
    pub bound: f64,
    pub data_sets: Vec<DataSetReport>,
}

pub fn run(args: &EvalArgs) -> anyhow::Result<()> {
    let params = args.acuts.params()?;
    if let Some(scale) = args.px_per_unit {
        anyhow::ensure!(scale.is_finite() && scale > 0.0, "--px-per-unit must be > 0");
    }
    if args.meshes {
        return run_meshes(args, params);
    }
    let names = args.algos.clone().unwrap_or_else(|| split_names(DEFAULT_ALGOS));
    let algos = algos(&names, (args.acuts.resample, params))?;
    let mut data_sets = load_data_sets(&args.inputs, args.px_per_unit)?;
    if args.synth {
        data_sets.push(synthetic_data_set()?);
    }
    anyhow::ensure!(!data_sets.is_empty(), "nothing to evaluate: give files, folders or --synth");
    let bound = args.acuts.tolerance + args.acuts.resample;
    if args.glb_sizes {
        if let Some(size) = args.stroke_size {
            anyhow::ensure!(size.is_finite() && size > 0.0, "--stroke-size must be > 0");
            for data_set in &mut data_sets {
                scale_strokes_to(data_set, size);
            }
        }
        let rows =
            glb_size_rows(&data_sets, args.acuts.resample, &params, args.glb_out.as_deref())?;
        let markdown = glb_size_markdown(&rows);
        print!("{markdown}");
        if let Some(path) = &args.markdown {
            io::write_file(path, &markdown)?;
        }
        if let Some(path) = &args.json {
            io::write_file(path, serde_json::to_string_pretty(&rows)?)?;
        }
        return Ok(());
    }

    let work: usize = data_sets
        .iter()
        .map(|d| {
            d.n_strokes() * algos.len() * (2 + if args.sweep { SWEEP_BOUNDS.len() } else { 0 })
        })
        .sum();
    let progress = ProgressBar::new(work as u64).with_style(
        ProgressStyle::with_template("{msg:>18} [{bar:40}] {pos}/{len} ({eta})")
            .context("progress bar style")?
            .progress_chars("=> "),
    );
    let mut reports = Vec::with_capacity(data_sets.len());
    for data_set in &data_sets {
        progress.set_message(data_set.name.clone());
        reports.push(evaluate(data_set, &algos, bound, args.sweep, &progress)?);
        if let Some(dir) = &args.plots {
            write_plots(dir, data_set, &reports[reports.len() - 1], &algos, bound)?;
        }
    }
    progress.finish_and_clear();

    let report = EvalReport {
        tolerance: args.acuts.tolerance,
        resample: args.acuts.resample,
        angle_deg: args.acuts.angle,
        angle_near_anchor: args.acuts.angle_near_anchor,
        pressure: params.pressure,
        bound,
        data_sets: reports,
    };
    let markdown = markdown(&report);
    print!("{markdown}");
    if let Some(path) = &args.markdown {
        io::write_file(path, &markdown)?;
    }
    if let Some(path) = &args.json {
        io::write_file(path, serde_json::to_string_pretty(&report)?)?;
    }
    Ok(())
}

fn split_names(names: &str) -> Vec<String> {
    names.split(',').map(str::to_owned).collect()
}

/// `--meshes`: table 8, printed as Markdown; `--markdown` and `--json` write it.
fn run_meshes(args: &EvalArgs, params: AcutsParams) -> anyhow::Result<()> {
    let poisson = penmesh_client::poisson::PoissonOptions {
        depth: args.poisson_depth,
        cloud: args.poisson_cloud,
        ..Default::default()
    };
    poisson.validate()?;
    penmesh_client::poisson::ensure_built()?;
    let names = args.algos.clone().unwrap_or_else(|| split_names(MESH_ALGOS));
    let algos = algos(&names, (args.acuts.resample, params))?;
    let shapes = match &args.curves {
        None => CURVES.to_vec(),
        Some(names) => names
            .iter()
            .filter(|name| !name.trim().is_empty())
            .map(|name| name.trim().parse::<penmesh::Shape>())
            .collect::<Result<_, _>>()?,
    };
    let curves = curves(&shapes, load_data_sets(&args.inputs, args.px_per_unit)?)?;
    let bound = args.acuts.tolerance + args.acuts.resample;
    let work: usize = curves.iter().map(|c| c.n_strokes() * (algos.len() + 1) * 2).sum();
    let progress = ProgressBar::new(work as u64).with_style(
        ProgressStyle::with_template(
            "{msg:>18} [{bar:40}] {pos}/{len} meshes ({elapsed}, {eta} left)",
        )
        .context("progress bar style")?
        .progress_chars("=> "),
    );
    let jobs = match args.jobs {
        Some(jobs) => {
            anyhow::ensure!(jobs > 0, "--jobs must be at least 1");
            jobs
        }
        None => std::thread::available_parallelism().map_or(1, usize::from),
    };
    let phases = PhaseTimes::default();
    let rows = mesh_rows(&curves, &algos, bound, &poisson, jobs, &progress, &phases)?;
    progress.finish_and_clear();
    let markdown = mesh_markdown(&rows, &poisson) + "\n" + &phases.markdown();
    print!("{markdown}");
    if let Some(path) = &args.markdown {
        io::write_file(path, &markdown)?;
    }
    if let Some(path) = &args.json {
        io::write_file(path, serde_json::to_string_pretty(&rows)?)?;
    }
    Ok(())
}

/// Sums over the strokes of a data set for one algorithm at one bound.
#[derive(Debug, Default)]
struct Totals {
    n: usize,
    c: usize,
    sed_sum: f64,
    e_max: f64,
    e_max_sum: f64,
    length_in: f64,
    length_out: f64,
    seconds: f64,
    optimal_at_bound: usize,
    optimal_at_reached: usize,
    n_strokes: usize,
    p_max: f64,
}

/// Runs `algo` over every stroke at `bound`; `optimal` holds optimal min-# per stroke at `bound`.
fn measure(
    data_set: &DataSet,
    algo: &Algo,
    bound: f64,
    optimal: &[usize],
    at_reached: bool,
    progress: &ProgressBar,
) -> anyhow::Result<(Totals, Vec<Vec<usize>>)> {
    let mut totals = Totals::default();
    let mut all_kept = Vec::with_capacity(optimal.len());
    for (samples, &n_optimal) in data_set.strokes().zip(optimal) {
        let started = Instant::now();
        let kept = algo.run(samples, bound);
        totals.seconds += started.elapsed().as_secs_f64();
        let m = penmesh::simplification_metrics(samples, &kept)
            .with_context(|| format!("{} on {}", algo.name, data_set.name))?;
        totals.n += samples.len();
        totals.c += kept.len();
        totals.sed_sum += m.sed * samples.len() as f64;
        totals.e_max = totals.e_max.max(m.e_max);
        totals.e_max_sum += m.e_max;
        totals.p_max = totals.p_max.max(penmesh::p_max(samples, &kept));
        totals.length_in += penmesh::polyline_length(samples);
        totals.length_out += penmesh::polyline_length(&picked(samples, &kept));
        totals.optimal_at_bound += n_optimal;
        if at_reached {
            // A hair above the reached E_max, so that rounding at the boundary cannot refuse
            // the very chords that reached it.
            let reached = m.e_max * (1.0 + 1e-9) + 1e-12;
            totals.optimal_at_reached += min_points(samples, reached).len();
        }
        totals.n_strokes += 1;
        all_kept.push(kept);
        progress.inc(1);
    }
    Ok((totals, all_kept))
}

fn picked(samples: &[Sample], kept: &[usize]) -> Vec<Sample> {
    kept.iter().map(|&i| samples[i]).collect()
}

fn ratio(a: usize, b: usize) -> f64 {
    if b == 0 { 1.0 } else { a as f64 / b as f64 }
}

fn evaluate(
    data_set: &DataSet,
    algos: &[Algo],
    bound: f64,
    sweep: bool,
    progress: &ProgressBar,
) -> anyhow::Result<DataSetReport> {
    let optimal_at = |b: f64| -> Vec<usize> {
        data_set.strokes().map(|samples| min_points(samples, b).len()).collect()
    };
    let optimal = optimal_at(bound);
    let mut rows = Vec::with_capacity(algos.len());
    let mut kept_by_algo = Vec::with_capacity(algos.len());
    for algo in algos {
        let (t, kept) = measure(data_set, algo, bound, &optimal, true, progress)?;
        rows.push(Row {
            algo: algo.name.clone(),
            online: algo.online,
            n_strokes: t.n_strokes,
            n: t.n,
            c: t.c,
            cr: (1.0 - ratio(t.c, t.n)) * 100.0,
            sed: t.sed_sum / t.n.max(1) as f64,
            e_max: t.e_max,
            e_max_mean: t.e_max_sum / t.n_strokes.max(1) as f64,
            e_l: if t.length_in > 0.0 {
                (t.length_in - t.length_out) / t.length_in * 100.0
            } else {
                0.0
            },
            p_max: t.p_max,
            time_ms: t.seconds * 1e3,
            ratio_at_bound: ratio(t.c, t.optimal_at_bound),
            ratio_at_reached: ratio(t.c, t.optimal_at_reached),
        });
        kept_by_algo.push(kept);
    }
    let stage1 = match algos.iter().find(|a| a.name == "acuts").map(|a| &a.method) {
        Some(Method::Acuts { resample, params }) => {
            stage1_table(data_set, *resample, params, &optimal)
        }
        _ => Vec::new(),
    };
    let mesh = mesh_table(data_set, algos, &kept_by_algo, progress);
    let centreline = match algos.iter().position(|a| a.name == "acuts") {
        Some(i) => centreline_table(data_set, &kept_by_algo[i], bound),
        None => Vec::new(),
    };

    let mut points = Vec::new();
    if sweep {
        for &b in &SWEEP_BOUNDS {
            let optimal = optimal_at(b);
            for algo in algos {
                let (t, _) = measure(data_set, algo, b, &optimal, false, progress)?;
                points.push(SweepPoint {
                    algo: algo.name.clone(),
                    bound: b,
                    kept_percent: ratio(t.c, t.n) * 100.0,
                    e_max_mean: t.e_max_sum / t.n_strokes.max(1) as f64,
                    sed: t.sed_sum / t.n.max(1) as f64,
                    ratio_at_bound: ratio(t.c, t.optimal_at_bound),
                });
            }
        }
    }
    Ok(DataSetReport {
        name: data_set.name.clone(),
        n_files: data_set.files.len(),
        n_strokes: data_set.n_strokes(),
        bound,
        overlay_file: data_set.files.first().map(|f| f.name.clone()),
        rows,
        stage1,
        mesh,
        centreline,
        sweep: points,
    })
}
