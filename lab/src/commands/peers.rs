//! `penmesh-lab peers` (hidden): the Rust half of `bench/run.sh`, which times penmesh against the
//! libraries web drawing apps use, on identical strokes.
//!
//! - `peers export` writes the benchmark strokes (every generated shape, several seeds, at a
//!   tablet's rate) as JSON for `bench/peers.mjs`.
//! - `peers compare` times the LRPDP outline and ACUTS on the same strokes, reads the Node
//!   timings (perfect-freehand's `getStroke`, simplify-js) and prints the ratios.
//!
//! Timing, the same on both sides: a warm-up, then as many calls as fill 100 ms, seven times;
//! the median of the seven is the time per call.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::{Args, Subcommand};
use penmesh::{AcutsParams, Brush, GeneratorParams, OutlineOptions, Sample, Shape};
use serde::{Deserialize, Serialize};

#[derive(Debug, Args)]
pub struct PeersArgs {
    #[command(subcommand)]
    pub action: PeersAction,
}

#[derive(Debug, Subcommand)]
pub enum PeersAction {
    /// Write the benchmark strokes as JSON.
    Export {
        #[arg(long)]
        out: PathBuf,
        /// Tablet rate of the strokes, Hz.
        #[arg(long, default_value_t = 200.0)]
        rate: f64,
        /// Strokes per shape (seeds 0, 1, ...).
        #[arg(long, default_value_t = 2)]
        seeds: u64,
    },
    /// Time LRPDP and ACUTS on the exported strokes and compare with the Node timings.
    Compare {
        /// The strokes `peers export` wrote.
        #[arg(long)]
        strokes: PathBuf,
        /// The timings `bench/peers.mjs` wrote.
        #[arg(long)]
        node: PathBuf,
        /// Also write the comparison as JSON.
        #[arg(long)]
        json: Option<PathBuf>,
    },
}

/// The exchange file: strokes as `[x, y, t, p]` rows and the settings both sides use.
#[derive(Debug, Serialize, Deserialize)]
struct BenchStrokes {
    tolerance: f64,
    brush_size: f64,
    pressure_response: f64,
    strokes: Vec<BenchStroke>,
}

#[derive(Debug, Serialize, Deserialize)]
struct BenchStroke {
    name: String,
    samples: Vec<[f64; 4]>,
}

#[derive(Debug, Deserialize)]
struct NodeTimings {
    runtime: String,
    strokes: Vec<NodeStroke>,
}

#[derive(Debug, Deserialize)]
struct NodeStroke {
    name: String,
    n_samples: usize,
    freehand_ns: f64,
    simplify_hq_ns: f64,
    simplify_fast_ns: f64,
    simplify_hq_kept: usize,
}

#[derive(Debug, Serialize)]
struct StrokeComparison {
    name: String,
    n_samples: usize,
    lrpdp_outline_ns: f64,
    /// The paper's straight outline (`OutlineOptions::paper()`) on the same samples.
    lrpdp_straight_ns: f64,
    freehand_ns: f64,
    acuts_ns: f64,
    acuts_kept: usize,
    simplify_hq_ns: f64,
    simplify_hq_kept: usize,
    simplify_fast_ns: f64,
}

#[derive(Debug, Serialize)]
struct Comparison {
    node: String,
    tolerance: f64,
    n_strokes: usize,
    n_samples: usize,
    /// Sums over the strokes, ns.
    lrpdp_outline_ns: f64,
    lrpdp_straight_ns: f64,
    freehand_ns: f64,
    acuts_ns: f64,
    simplify_hq_ns: f64,
    simplify_fast_ns: f64,
    /// perfect-freehand time / LRPDP time with the default (smooth) centreline.
    outline_speedup: f64,
    /// perfect-freehand time / the paper's straight LRPDP time (goal: at least 10).
    straight_speedup: f64,
    /// simplify-js (high quality, pure Douglas-Peucker) time / ACUTS time (goal: at least 3).
    simplify_hq_speedup: f64,
    /// simplify-js (default: radial pre-pass, then Douglas-Peucker) time / ACUTS time.
    simplify_fast_speedup: f64,
    acuts_ns_per_sample: f64,
    simplify_hq_ns_per_sample: f64,
    strokes: Vec<StrokeComparison>,
}

pub fn run(args: &PeersArgs) -> anyhow::Result<()> {
    match &args.action {
        PeersAction::Export { out, rate, seeds } => export(out, *rate, *seeds),
        PeersAction::Compare { strokes, node, json } => compare(strokes, node, json.as_ref()),
    }
}

fn export(out: &PathBuf, rate: f64, seeds: u64) -> anyhow::Result<()> {
    let mut strokes = Vec::new();
    for shape in Shape::ALL {
        for seed in 0..seeds {
            let params =
                GeneratorParams { shape, rate_hz: rate, seed, ..GeneratorParams::default() };
            let stroke = penmesh::generate_stroke(&params)
                .map_err(|e| anyhow::anyhow!("cannot generate {}: {e}", shape.name()))?;
            strokes.push(BenchStroke {
                name: format!("{}-{seed}", shape.name()),
                samples: stroke.samples().iter().map(|s| [s.x, s.y, s.t, s.p]).collect(),
            });
        }
    }
    let brush = Brush::default();
    let file = BenchStrokes {
        tolerance: penmesh::DEFAULT_TOLERANCE,
        brush_size: brush.size,
        pressure_response: brush.pressure_response,
        strokes,
    };
    fs_err::write(out, serde_json::to_string(&file)?)?;
    Ok(())
}

fn read_text(path: &PathBuf) -> anyhow::Result<String> {
    Ok(fs_err::read_to_string(path)?)
}

fn ns_per_call(mut f: impl FnMut()) -> f64 {
    for _ in 0..50 {
        f();
    }
    let mut calls = 1u64;
    loop {
        let start = Instant::now();
        for _ in 0..calls {
            f();
        }
        if start.elapsed().as_secs_f64() > 0.1 {
            break;
        }
        calls *= 2;
    }
    let mut runs: Vec<f64> = (0..7)
        .map(|_| {
            let start = Instant::now();
            for _ in 0..calls {
                f();
            }
            start.elapsed().as_nanos() as f64 / calls as f64
        })
        .collect();
    runs.sort_by(f64::total_cmp);
    runs[3]
}

fn compare(
    strokes_path: &PathBuf,
    node_path: &PathBuf,
    json: Option<&PathBuf>,
) -> anyhow::Result<()> {
    let strokes: BenchStrokes = serde_json::from_str(&read_text(strokes_path)?)
        .with_context(|| format!("{}: not a peers stroke file", strokes_path.display()))?;
    let node: NodeTimings = serde_json::from_str(&read_text(node_path)?)
        .with_context(|| format!("{}: not bench/peers.mjs output", node_path.display()))?;
    anyhow::ensure!(
        node.strokes.len() == strokes.strokes.len(),
        "{} has {} strokes, {} has {}",
        node_path.display(),
        node.strokes.len(),
        strokes_path.display(),
        strokes.strokes.len()
    );
    let brush = Brush {
        size: strokes.brush_size,
        pressure_response: strokes.pressure_response,
        ..Brush::default()
    };
    let params = AcutsParams { tolerance: strokes.tolerance, ..AcutsParams::default() };
    let (options, straight) = (OutlineOptions::default(), OutlineOptions::paper());
    let mut rows = Vec::new();
    for (stroke, peer) in strokes.strokes.iter().zip(&node.strokes) {
        anyhow::ensure!(
            stroke.name == peer.name && stroke.samples.len() == peer.n_samples,
            "the Node timings are of other strokes ({} vs {})",
            peer.name,
            stroke.name
        );
        let samples: Vec<Sample> =
            stroke.samples.iter().map(|&[x, y, t, p]| Sample { x, y, t, p }).collect();
        let lrpdp_outline_ns = ns_per_call(|| {
            std::hint::black_box(penmesh::outline(
                std::hint::black_box(&samples),
                &brush,
                &options,
            ));
        });
        let lrpdp_straight_ns = ns_per_call(|| {
            std::hint::black_box(penmesh::outline(
                std::hint::black_box(&samples),
                &brush,
                &straight,
            ));
        });
        let acuts_ns = ns_per_call(|| {
            std::hint::black_box(penmesh::acuts(
                std::hint::black_box(&samples),
                penmesh::DEFAULT_RESAMPLE_DISTANCE,
                &params,
            ));
        });
        let acuts_kept =
            penmesh::acuts(&samples, penmesh::DEFAULT_RESAMPLE_DISTANCE, &params).kept.len();
        rows.push(StrokeComparison {
            name: stroke.name.clone(),
            n_samples: samples.len(),
            lrpdp_outline_ns,
            lrpdp_straight_ns,
            freehand_ns: peer.freehand_ns,
            acuts_ns,
            acuts_kept,
            simplify_hq_ns: peer.simplify_hq_ns,
            simplify_hq_kept: peer.simplify_hq_kept,
            simplify_fast_ns: peer.simplify_fast_ns,
        });
    }
    let sum = |f: fn(&StrokeComparison) -> f64| rows.iter().map(f).sum::<f64>();
    let n_samples: usize = rows.iter().map(|r| r.n_samples).sum();
    let (outline, freehand) = (sum(|r| r.lrpdp_outline_ns), sum(|r| r.freehand_ns));
    let straight = sum(|r| r.lrpdp_straight_ns);
    let (acuts, hq, fast) =
        (sum(|r| r.acuts_ns), sum(|r| r.simplify_hq_ns), sum(|r| r.simplify_fast_ns));
    let comparison = Comparison {
        node: node.runtime,
        tolerance: strokes.tolerance,
        n_strokes: rows.len(),
        n_samples,
        lrpdp_outline_ns: outline,
        lrpdp_straight_ns: straight,
        freehand_ns: freehand,
        acuts_ns: acuts,
        simplify_hq_ns: hq,
        simplify_fast_ns: fast,
        outline_speedup: freehand / outline,
        straight_speedup: freehand / straight,
        simplify_hq_speedup: hq / acuts,
        simplify_fast_speedup: fast / acuts,
        acuts_ns_per_sample: acuts / n_samples as f64,
        simplify_hq_ns_per_sample: hq / n_samples as f64,
        strokes: rows,
    };
    println!(
        "{:<16} {:>7} {:>12} {:>12} {:>12} {:>10} {:>12} {:>12}",
        "stroke",
        "samples",
        "LRPDP us",
        "straight us",
        "freehand us",
        "ACUTS us",
        "DP(hq) us",
        "DP(fast) us"
    );
    for r in &comparison.strokes {
        println!(
            "{:<16} {:>7} {:>12.2} {:>12.2} {:>12.2} {:>10.2} {:>12.2} {:>12.2}",
            r.name,
            r.n_samples,
            r.lrpdp_outline_ns / 1e3,
            r.lrpdp_straight_ns / 1e3,
            r.freehand_ns / 1e3,
            r.acuts_ns / 1e3,
            r.simplify_hq_ns / 1e3,
            r.simplify_fast_ns / 1e3
        );
    }
    println!(
        "outline:        the paper's straight LRPDP is {:.1}x faster than perfect-freehand \
         getStroke ({}); the default smooth LRPDP {:.1}x on these unsimplified strokes",
        comparison.straight_speedup, comparison.node, comparison.outline_speedup
    );
    println!(
        "simplification: ACUTS (stage 1 + 2) {:.1} ns/sample; {:.1}x faster than simplify-js \
         high quality ({:.1} ns/sample), {:.1}x than its default (radial + DP), tolerance {}",
        comparison.acuts_ns_per_sample,
        comparison.simplify_hq_speedup,
        comparison.simplify_hq_ns_per_sample,
        comparison.simplify_fast_speedup,
        comparison.tolerance
    );
    if let Some(path) = json {
        fs_err::write(path, serde_json::to_string_pretty(&comparison)? + "\n")?;
    }
    Ok(())
}
