//! `penmesh eval`: ACUTS and the baselines over every stroke of one or more data sets, with the
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

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use penmesh::baselines::{BASELINE_NAMES, Simplify, baseline, min_points};
use penmesh::{
    AcutsParams, Brush, GlbMeta, GlbOptions, GlbStroke, OutlineOptions, Sample, SolidOptions,
    SvgStroke,
};
use serde::Serialize;

use crate::commands::args::AcutsArgs;
use crate::io;
use crate::plot::{LineChart, Series, SeriesLabelPosition};

/// The ACUTS settings `--algos` knows, before the baselines ([`BASELINE_NAMES`]).
const ACUTS_NAMES: [&str; 2] = ["acuts", "acuts-paper"];
const DEFAULT_ALGOS: &str =
    "acuts,acuts-paper,dp,vw,window,window-p,squish-e,bqs,fbqs,dpts,optimal,optimal-p";
/// The bounds of `--sweep`, px.
const SWEEP_BOUNDS: [f64; 10] = [0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0];
/// Px per SVC2004 tablet unit (2540 lines per inch).
pub const SVC2004_PX_PER_UNIT: f64 = 96.0 / 2540.0;
/// Px per SigComp2011 tablet unit (5080 lines per inch).
pub const HWR_PX_PER_UNIT: f64 = 96.0 / 5080.0;
/// The ACUTS setting of the paper's table 3 and the spec (`acuts-paper`), for before/after
/// comparisons: d_d, l_eps, d_alpha (near the anchor too), d_sigma2.
const PAPER: AcutsParams = AcutsParams::paper();
const PAPER_RESAMPLE: f64 = penmesh::PAPER_RESAMPLE_DISTANCE;

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Data: directories (searched recursively for .txt, .hwr, .csv, .json) or files. Each
    /// folder is one data set.
    pub inputs: Vec<PathBuf>,
    /// Algorithms, comma separated: acuts, acuts-paper, dp, vw, window, window-d, window-p,
    /// squish-e, bqs, fbqs, dpts, optimal, optimal-p (window-p and optimal-p also bound the
    /// pressure error by ACUTS's pressure tolerance).
    #[arg(long, value_delimiter = ',', default_value = DEFAULT_ALGOS)]
    pub algos: Vec<String>,
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
}

/// One file's strokes, in px.
#[derive(Debug)]
pub struct DataFile {
    pub name: String,
    pub strokes: Vec<Vec<Sample>>,
}

/// A named collection of files.
#[derive(Debug)]
pub struct DataSet {
    pub name: String,
    pub files: Vec<DataFile>,
}

impl DataSet {
    fn strokes(&self) -> impl Iterator<Item = &[Sample]> + '_ {
        self.files.iter().flat_map(|f| f.strokes.iter().map(Vec::as_slice))
    }

    fn n_strokes(&self) -> usize {
        self.files.iter().map(|f| f.strokes.len()).sum()
    }
}

/// An algorithm under evaluation, run at a guaranteed bound.
pub enum Method {
    /// ACUTS with its setting; at another bound, `d_d` and `l_eps` are scaled together.
    Acuts {
        resample: f64,
        params: AcutsParams,
    },
    Baseline(Box<dyn Simplify>),
}

impl std::fmt::Debug for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Method::Acuts { resample, params } => {
                write!(f, "Acuts {{ resample: {resample}, params: {params:?} }}")
            }
            Method::Baseline(b) => write!(f, "Baseline({})", b.name()),
        }
    }
}

#[derive(Debug)]
pub struct Algo {
    pub name: String,
    pub online: bool,
    pub method: Method,
}

impl Algo {
    /// The kept indices with every removed sample guaranteed within `bound`.
    pub fn run(&self, samples: &[Sample], bound: f64) -> Vec<usize> {
        match &self.method {
            Method::Acuts { resample, params } => {
                let (tolerance, resample) = split_bound(params.tolerance, *resample, bound);
                let params = AcutsParams { tolerance, ..*params };
                penmesh::acuts(samples, resample, &params).kept
            }
            Method::Baseline(b) => b.run(samples, bound),
        }
    }
}

/// `(d_d, l_eps)` scaled so that they add up to `bound`, in the ratio of the setting.
fn split_bound(tolerance: f64, resample: f64, bound: f64) -> (f64, f64) {
    let total = tolerance + resample;
    if total > 0.0 { (bound * tolerance / total, bound * resample / total) } else { (bound, 0.0) }
}

/// Builds the algorithms named in `names`.
pub fn algos(names: &[String], args_acuts: (f64, AcutsParams)) -> anyhow::Result<Vec<Algo>> {
    names
        .iter()
        .map(|name| {
            let name = name.trim().to_ascii_lowercase();
            // The pressure-aware baselines bound pressure as ACUTS's interpolation gate does.
            let pressure_tolerance = match args_acuts.1.pressure {
                penmesh::PressureGate::Interpolation(d) => d,
                penmesh::PressureGate::Variance(_) => penmesh::DEFAULT_PRESSURE_TOLERANCE,
            };
            let (online, method) = match name.as_str() {
                "acuts" => (true, Method::Acuts { resample: args_acuts.0, params: args_acuts.1 }),
                "acuts-paper" => (true, Method::Acuts { resample: PAPER_RESAMPLE, params: PAPER }),
                other => {
                    let b = baseline(other, pressure_tolerance).ok_or_else(|| {
                        anyhow::anyhow!(
                            "unknown algorithm {other:?}: expected one of {}",
                            ACUTS_NAMES
                                .iter()
                                .chain(&BASELINE_NAMES)
                                .copied()
                                .collect::<Vec<_>>()
                                .join(", ")
                        )
                    })?;
                    (b.is_online(), Method::Baseline(b))
                }
            };
            Ok(Algo { name, online, method })
        })
        .collect()
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

/// Table 8's row: the meshes of the simplified strokes against those of the originals.
#[derive(Debug, Clone, Serialize)]
pub struct MeshRow {
    pub algo: String,
    /// Samples the meshes are built from.
    pub samples: usize,
    pub vertices: usize,
    pub triangles: usize,
    /// GLB bytes (one file per signature).
    pub bytes: usize,
    pub time_ms: f64,
    /// Reductions against the unsimplified strokes' meshes, %.
    pub eta_vertices: f64,
    pub eta_triangles: f64,
    pub eta_bytes: f64,
    pub eta_time: f64,
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
    let algos = algos(&args.algos, (args.acuts.resample, params))?;
    let mut data_sets = load_data_sets(&args.inputs, args.px_per_unit)?;
    if args.synth {
        data_sets.push(synthetic_data_set()?);
    }
    anyhow::ensure!(!data_sets.is_empty(), "nothing to evaluate: give files, folders or --synth");
    let bound = args.acuts.tolerance + args.acuts.resample;

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

/// Reads every file under the inputs, grouped into data sets by their folder's name.
pub fn load_data_sets(
    inputs: &[PathBuf],
    px_per_unit: Option<f64>,
) -> anyhow::Result<Vec<DataSet>> {
    let mut files = Vec::new();
    for input in inputs {
        collect_files(input, &mut files)?;
    }
    files.sort();
    files.dedup();
    let mut by_folder: BTreeMap<String, Vec<DataFile>> = BTreeMap::new();
    for path in files {
        let folder = path
            .parent()
            .and_then(|p| p.file_name())
            .and_then(|n| n.to_str())
            .unwrap_or("data")
            .to_string();
        let scale = match extension(&path).as_str() {
            "txt" => px_per_unit.unwrap_or(SVC2004_PX_PER_UNIT),
            "hwr" => px_per_unit.unwrap_or(HWR_PX_PER_UNIT),
            _ => 1.0,
        };
        let strokes = io::read_strokes(&path)?
            .into_iter()
            .map(|stroke| {
                stroke
                    .samples()
                    .iter()
                    .map(|s| Sample::new(s.x * scale, s.y * scale, s.t, s.p))
                    .collect()
            })
            .collect();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default().to_string();
        by_folder.entry(folder).or_default().push(DataFile { name, strokes });
    }
    Ok(by_folder.into_iter().map(|(name, files)| DataSet { name, files }).collect())
}

fn extension(path: &Path) -> String {
    path.extension().and_then(|e| e.to_str()).unwrap_or_default().to_ascii_lowercase()
}

fn collect_files(path: &Path, out: &mut Vec<PathBuf>) -> anyhow::Result<()> {
    if path.is_dir() {
        let entries = fs_err::read_dir(path)?;
        for entry in entries {
            let entry = entry.with_context(|| format!("cannot list {}", path.display()))?;
            let child = entry.path();
            if child.is_dir() || ["txt", "hwr", "csv", "json"].contains(&extension(&child).as_str())
            {
                collect_files(&child, out)?;
            }
        }
    } else {
        out.push(path.to_path_buf());
    }
    Ok(())
}

/// The generated strokes: the five shapes at 200, 300, 400 and 500 px/s, two seeds each.
pub fn synthetic_data_set() -> anyhow::Result<DataSet> {
    let mut files = Vec::new();
    for shape in penmesh::Shape::ALL {
        for speed in [200.0, 300.0, 400.0, 500.0] {
            for seed in 0..2 {
                let params = penmesh::GeneratorParams {
                    shape,
                    speed,
                    seed,
                    ..penmesh::GeneratorParams::default()
                };
                let stroke = penmesh::generate_stroke(&params)
                    .map_err(|e| anyhow::anyhow!("generator: {e}"))?;
                files.push(DataFile {
                    name: format!("{shape}-{speed}-{seed}"),
                    strokes: vec![stroke.into_samples()],
                });
            }
        }
    }
    Ok(DataSet { name: "synthetic".into(), files })
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
        mesh,
        centreline,
        sweep: points,
    })
}

/// Builds the LRPDP solid and one GLB per file from the original strokes and from each
/// algorithm's simplification.
fn mesh_table(
    data_set: &DataSet,
    algos: &[Algo],
    kept_by_algo: &[Vec<Vec<usize>>],
    progress: &ProgressBar,
) -> Vec<MeshRow> {
    let brush = Brush::default();
    let build = |select: &dyn Fn(usize, &[Sample]) -> Vec<Sample>| {
        let (mut samples, mut vertices, mut triangles, mut bytes) = (0, 0, 0, 0);
        let mut seconds = 0.0;
        let mut stroke_idx = 0;
        for file in &data_set.files {
            let simplified: Vec<Vec<Sample>> = file
                .strokes
                .iter()
                .map(|s| {
                    stroke_idx += 1;
                    select(stroke_idx - 1, s)
                })
                .collect();
            let started = Instant::now();
            let meshes: Vec<penmesh::StrokeMesh> = simplified
                .iter()
                .map(|s| {
                    penmesh::stroke_mesh(
                        s,
                        &brush,
                        &OutlineOptions::default(),
                        &SolidOptions::default(),
                    )
                })
                .collect();
            let metas: Vec<GlbMeta> = meshes
                .iter()
                .map(|_| GlbMeta { stroke: uuid::Uuid::nil(), author: "eval".into(), brush })
                .collect();
            let strokes: Vec<GlbStroke<'_>> =
                meshes.iter().zip(&metas).map(|(mesh, meta)| GlbStroke { mesh, meta }).collect();
            let glb = penmesh::strokes_glb(&strokes, &GlbOptions::default());
            seconds += started.elapsed().as_secs_f64();
            samples += simplified.iter().map(Vec::len).sum::<usize>();
            vertices += meshes.iter().map(|m| m.stats().vertices).sum::<usize>();
            triangles += meshes.iter().map(|m| m.stats().triangles).sum::<usize>();
            bytes += glb.len();
        }
        (samples, vertices, triangles, bytes, seconds * 1e3)
    };
    let reduction = |x: f64, reference: f64| {
        if reference > 0.0 { (1.0 - x / reference) * 100.0 } else { 0.0 }
    };
    let reference = build(&|_, s| s.to_vec());
    let row = |algo: &str, r: (usize, usize, usize, usize, f64)| MeshRow {
        algo: algo.to_string(),
        samples: r.0,
        vertices: r.1,
        triangles: r.2,
        bytes: r.3,
        time_ms: r.4,
        eta_vertices: reduction(r.1 as f64, reference.1 as f64),
        eta_triangles: reduction(r.2 as f64, reference.2 as f64),
        eta_bytes: reduction(r.3 as f64, reference.3 as f64),
        eta_time: reduction(r.4, reference.4),
    };
    let mut rows = vec![row("original", reference)];
    for (algo, kept) in algos.iter().zip(kept_by_algo) {
        rows.push(row(&algo.name, build(&|i, s| picked(s, &kept[i]))));
        progress.inc(data_set.n_strokes() as u64);
    }
    rows
}

/// Where the pen's path counts as smooth for the centreline table: it turns by less than
/// `SMOOTH_TURN_DEG` between the chords `SMOOTH_REACH_PX` back and ahead along it.
const SMOOTH_REACH_PX: f64 = 3.0;
const SMOOTH_TURN_DEG: f64 = 30.0;

/// How one centreline (straight or smooth) of ACUTS's simplification looks and how faithful it
/// is, over every stroke of a data set.
#[derive(Debug, Clone, Serialize)]
pub struct CentrelineRow {
    pub centreline: String,
    /// Tessellated centreline points (the retained samples, for the straight one).
    pub points: usize,
    /// Interior centreline points where the pen's path is smooth.
    pub smooth_points: usize,
    /// Of those, the share that turn by more than 10° and by more than 20°, %.
    pub over_10_deg: f64,
    pub over_20_deg: f64,
    /// Median and largest turn at those points, degrees.
    pub median_turn_deg: f64,
    pub max_turn_deg: f64,
    /// Largest distance of a raw sample to the centreline, px.
    pub raw_to_centreline: f64,
    /// Strokes with a raw sample further than the bound from the centreline.
    pub strokes_over_bound: usize,
    /// Largest distance of a point of the centreline to the raw path, px.
    pub centreline_to_raw: f64,
    pub vertices: usize,
    pub triangles: usize,
    /// Sum of the one-stroke GLB files, bytes.
    pub bytes: usize,
    /// The largest one-stroke GLB, bytes, and its raw sample count.
    pub max_stroke_bytes: usize,
    pub max_stroke_samples: usize,
    /// Outline + mesh + GLB, all strokes, ms.
    pub time_ms: f64,
}

/// Builds each stroke's outline from ACUTS's retained samples with the straight and the smooth
/// centreline, and measures them against the raw path.
fn centreline_table(data_set: &DataSet, kept: &[Vec<usize>], bound: f64) -> Vec<CentrelineRow> {
    use penmesh::centreline::{directed_distance, polyline_distance, polyline_turns};
    let brush = Brush::default();
    let smooth = penmesh::Centreline::Smooth(penmesh::SmoothOptions::default().bound(bound));
    let kinds = [
        ("straight (paper)", penmesh::Centreline::Straight, false),
        ("smooth, retained samples only", smooth, false),
        ("smooth, checked against the raw samples", smooth, true),
    ];
    let raws: Vec<Vec<_>> =
        data_set.strokes().map(|s| s.iter().map(Sample::pos).collect()).collect();
    let smooth_flags: Vec<Vec<bool>> = raws
        .iter()
        .map(|raw| {
            penmesh::centreline::smooth_at_samples(
                raw,
                SMOOTH_REACH_PX,
                SMOOTH_TURN_DEG.to_radians(),
            )
        })
        .collect();
    let meta = GlbMeta { stroke: uuid::Uuid::nil(), author: "eval".into(), brush };
    kinds
        .into_iter()
        .map(|(name, kind, fitted)| {
            let options = OutlineOptions::default().centreline(kind);
            let mut row = CentrelineRow {
                centreline: name.to_owned(),
                points: 0,
                smooth_points: 0,
                over_10_deg: 0.0,
                over_20_deg: 0.0,
                median_turn_deg: 0.0,
                max_turn_deg: 0.0,
                raw_to_centreline: 0.0,
                strokes_over_bound: 0,
                centreline_to_raw: 0.0,
                vertices: 0,
                triangles: 0,
                bytes: 0,
                max_stroke_bytes: 0,
                max_stroke_samples: 0,
                time_ms: 0.0,
            };
            let mut turns_deg = Vec::new();
            for (((samples, kept), raw), smooth) in
                data_set.strokes().zip(kept).zip(&raws).zip(&smooth_flags)
            {
                let simplified = picked(samples, kept);
                let started = Instant::now();
                let outline = if fitted {
                    penmesh::fitted_outline(samples, kept, &brush, &options)
                        .expect("the simplifiers keep increasing indices of the stroke")
                } else {
                    penmesh::outline(&simplified, &brush, &options)
                };
                let mesh = penmesh::solid_mesh(&outline, &SolidOptions::default());
                let glb = penmesh::stroke_glb(&mesh, &meta, &GlbOptions::default());
                row.time_ms += started.elapsed().as_secs_f64() * 1e3;
                let centres = &outline.centres;
                row.points += centres.len();
                row.vertices += mesh.stats().vertices;
                row.triangles += mesh.stats().triangles;
                row.bytes += glb.len();
                if glb.len() > row.max_stroke_bytes {
                    (row.max_stroke_bytes, row.max_stroke_samples) = (glb.len(), samples.len());
                }
                let to_centreline =
                    raw.iter().map(|q| polyline_distance(*q, centres)).fold(0.0, f64::max);
                row.raw_to_centreline = row.raw_to_centreline.max(to_centreline);
                row.strokes_over_bound += usize::from(to_centreline > bound + 1e-9);
                row.centreline_to_raw =
                    row.centreline_to_raw.max(directed_distance(centres, raw, 4));
                // The turn at each interior centreline point whose nearest raw sample is smooth.
                for (k, t) in polyline_turns(centres).into_iter().enumerate() {
                    let at = centres[k + 1];
                    let nearest = (0..raw.len()).min_by(|&a, &b| {
                        raw[a].distance_squared(at).total_cmp(&raw[b].distance_squared(at))
                    });
                    if nearest.is_some_and(|i| smooth[i]) {
                        turns_deg.push(t.to_degrees());
                    }
                }
            }
            turns_deg.sort_by(f64::total_cmp);
            let share = |limit: f64| {
                let over = turns_deg.iter().filter(|&&t| t > limit).count();
                over as f64 / turns_deg.len().max(1) as f64 * 100.0
            };
            row.smooth_points = turns_deg.len();
            row.over_10_deg = share(10.0);
            row.over_20_deg = share(20.0);
            row.median_turn_deg = turns_deg.get(turns_deg.len() / 2).copied().unwrap_or(0.0);
            row.max_turn_deg = turns_deg.last().copied().unwrap_or(0.0);
            row
        })
        .collect()
}

/// The Markdown tables of the whole report.
pub fn markdown(report: &EvalReport) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "ACUTS: d_d = {} px, l_eps = {} px, angle = {}° ({}), {}; \
         guaranteed bound B = d_d + l_eps = {} px (the baselines' tolerance).\n",
        report.tolerance,
        report.resample,
        report.angle_deg,
        if report.angle_near_anchor { "near the anchor too" } else { "beyond d_d from the anchor" },
        match report.pressure {
            penmesh::PressureGate::Interpolation(d) => format!("pressure tolerance = {d}"),
            penmesh::PressureGate::Variance(v) => format!("pressure variance = {v}"),
        },
        report.bound
    );
    for d in &report.data_sets {
        let _ = writeln!(
            md,
            "### {} ({} files, {} strokes, {} samples)\n",
            d.name,
            d.n_files,
            d.n_strokes,
            d.rows.first().map_or(0, |r| r.n)
        );
        let _ = writeln!(
            md,
            "| algorithm | online | N | C | CR % | SED px | E_max px | mean E_max px | E_l % | P_max | time ms | C / opt at B | C / opt at reached E_max |"
        );
        let _ = writeln!(md, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
        for r in &d.rows {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {:.1} | {:.3} | {:.3} | {:.3} | {:.2} | {:.3} | {:.2} | {:.3} | {:.3} |",
                r.algo,
                if r.online { "yes" } else { "no" },
                r.n,
                r.c,
                r.cr,
                r.sed,
                r.e_max,
                r.e_max_mean,
                r.e_l,
                r.p_max,
                r.time_ms,
                r.ratio_at_bound,
                r.ratio_at_reached
            );
        }
        let _ = writeln!(md, "\nMeshes (LRPDP solid, default brush, one GLB per file):\n");
        let _ = writeln!(
            md,
            "| from | samples | N' vertices | F triangles | S bytes | T ms | eta N' % | eta F % | eta S % | eta T % |"
        );
        let _ = writeln!(md, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
        for r in &d.mesh {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {} | {:.2} | {:.1} | {:.1} | {:.1} | {:.1} |",
                r.algo,
                r.samples,
                r.vertices,
                r.triangles,
                r.bytes,
                r.time_ms,
                r.eta_vertices,
                r.eta_triangles,
                r.eta_bytes,
                r.eta_time
            );
        }
        if !d.centreline.is_empty() {
            let _ = writeln!(
                md,
                "\nCentreline of ACUTS's strokes (turns at centreline points where the pen's path \
                 turns < {SMOOTH_TURN_DEG}° within {SMOOTH_REACH_PX} px either side; distances \
                 against the raw samples; one GLB per stroke):\n"
            );
            let _ = writeln!(
                md,
                "| centreline | points | smooth-path points | > 10° % | > 20° % | median turn ° | max turn ° | raw → centreline px | strokes over B | centreline → raw px | vertices | triangles | GLB bytes | largest GLB (raw samples) | T ms |"
            );
            let _ = writeln!(
                md,
                "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
            );
            for r in &d.centreline {
                let _ = writeln!(
                    md,
                    "| {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.3} | {} | {:.3} | {} | {} | {} | {} ({}) | {:.2} |",
                    r.centreline,
                    r.points,
                    r.smooth_points,
                    r.over_10_deg,
                    r.over_20_deg,
                    r.median_turn_deg,
                    r.max_turn_deg,
                    r.raw_to_centreline,
                    r.strokes_over_bound,
                    r.centreline_to_raw,
                    r.vertices,
                    r.triangles,
                    r.bytes,
                    r.max_stroke_bytes,
                    r.max_stroke_samples,
                    r.time_ms
                );
            }
        }
        if !d.sweep.is_empty() {
            let algos: Vec<&str> =
                d.sweep.iter().map(|p| p.algo.as_str()).fold(Vec::new(), |mut v, a| {
                    if !v.contains(&a) {
                        v.push(a);
                    }
                    v
                });
            let _ = writeln!(md, "\nSweep: points kept / optimal min-# at each bound B:\n");
            let _ = write!(md, "| B px |");
            for a in &algos {
                let _ = write!(md, " {a} |");
            }
            let _ = writeln!(md);
            let _ = writeln!(md, "|---:|{}", "---:|".repeat(algos.len()));
            for &b in &SWEEP_BOUNDS {
                let _ = write!(md, "| {b} |");
                for a in &algos {
                    let p = d.sweep.iter().find(|p| p.bound == b && p.algo == *a);
                    let _ = write!(
                        md,
                        " {} |",
                        p.map_or("".into(), |p| format!("{:.3}", p.ratio_at_bound))
                    );
                }
                let _ = writeln!(md);
            }
        }
        let _ = writeln!(md);
    }
    md
}

fn write_plots(
    dir: &Path,
    data_set: &DataSet,
    report: &DataSetReport,
    algos: &[Algo],
    bound: f64,
) -> anyhow::Result<()> {
    fs_err::create_dir_all(dir)?;
    if !report.sweep.is_empty() {
        for (metric, label) in [("emax", "mean E_max per stroke (px)"), ("sed", "SED (px)")] {
            let path = dir.join(format!("rd_{metric}_{}.svg", report.name));
            rate_distortion_plot(&path, report, metric, label)?;
        }
    }
    // Figure 12: one signature (the first file) and each algorithm's simplification at B.
    if let Some(file) = data_set.files.first() {
        for algo in algos {
            let kept: Vec<Vec<usize>> = file.strokes.iter().map(|s| algo.run(s, bound)).collect();
            let pictures: Vec<SvgStroke<'_>> = file
                .strokes
                .iter()
                .zip(&kept)
                .map(|(s, k)| SvgStroke { original: s, kept: k })
                .collect();
            let path = dir.join(format!("overlay_{}_{}.svg", report.name, algo.name));
            io::write_file(&path, penmesh::strokes_svg(&pictures))?;
        }
    }
    Ok(())
}

/// Figure 11: points kept against `metric` for every algorithm of the sweep.
fn rate_distortion_plot(
    path: &Path,
    report: &DataSetReport,
    metric: &str,
    label: &str,
) -> anyhow::Result<()> {
    let value = |p: &SweepPoint| if metric == "sed" { p.sed } else { p.e_max_mean };
    let mut series: Vec<Series> = Vec::new();
    for p in &report.sweep {
        let point = (p.kept_percent, value(p));
        match series.iter_mut().find(|s| s.name == p.algo) {
            Some(line) => line.points.push(point),
            None => series.push(Series { name: p.algo.clone(), points: vec![point] }),
        }
    }
    LineChart {
        caption: &format!("{}: points kept vs {label}", report.name),
        x_label: "points kept (% of N)",
        y_label: label,
        series: &series,
        log_y: false,
        legend: SeriesLabelPosition::UpperRight,
        size: (800, 560),
    }
    .write_svg(path)
}
