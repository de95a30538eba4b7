//! `penmesh simplify`: ACUTS over every stroke of a file, with the paper's metrics.

use std::path::PathBuf;

use clap::Args;
use penmesh::{Stroke, SvgStroke, polyline_length};
use serde::Serialize;

use crate::commands::args::AcutsArgs;
use crate::io;

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Algo {
    Acuts,
}

#[derive(Debug, Args)]
pub struct SimplifyArgs {
    /// Input file: CSV (x,y,t,p), JSON, SVC2004 .txt or SigComp2011 .hwr.
    pub input: PathBuf,
    #[arg(long, value_enum, default_value_t = Algo::Acuts)]
    pub algo: Algo,
    #[command(flatten)]
    pub acuts: AcutsArgs,
    /// Print exactly one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Write an SVG of the original and simplified strokes.
    #[arg(long, value_name = "OUT")]
    pub svg: Option<PathBuf>,
}

/// What one stroke's simplification gives.
#[derive(Debug, Serialize)]
pub struct StrokeReport {
    pub n_input: usize,
    pub n_resampled: usize,
    pub n_output: usize,
    pub metrics: Metrics,
}

/// The metrics of table 5 (percentages for `cr` and `e_l`).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Metrics {
    pub cr: f64,
    pub e_max: f64,
    pub e_l: f64,
    pub sed: f64,
}

/// The one JSON object `--json` prints.
#[derive(Debug, Serialize)]
pub struct SimplifyReport {
    pub algo: &'static str,
    pub n_input: usize,
    pub n_resampled: usize,
    pub n_output: usize,
    /// Indices into the input samples (all strokes of the file, in file order).
    pub kept: Vec<usize>,
    pub metrics: Metrics,
    pub params: Params,
    pub strokes: Vec<StrokeReport>,
}

#[derive(Debug, Serialize)]
pub struct Params {
    pub tolerance: f64,
    pub angle_deg: f64,
    pub angle_near_anchor: bool,
    pub pressure: penmesh::PressureGate,
    pub resample: f64,
}

pub fn run(args: &SimplifyArgs) -> anyhow::Result<()> {
    let params = args.acuts.params()?;
    let strokes = io::read_strokes(&args.input)?;
    let Algo::Acuts = args.algo;
    let report = simplify_strokes(&strokes, args.acuts.resample, &params)?;
    if let Some(path) = &args.svg {
        let kept_per_stroke = kept_per_stroke(&strokes, &report.kept);
        let pictures: Vec<SvgStroke<'_>> = strokes
            .iter()
            .zip(&kept_per_stroke)
            .map(|(s, k)| SvgStroke { original: s.samples(), kept: k })
            .collect();
        io::write_file(path, penmesh::strokes_svg(&pictures))?;
    }
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_table(&report);
    }
    Ok(())
}

/// ACUTS over each stroke; `kept` indexes the concatenation of all strokes' samples.
pub fn simplify_strokes(
    strokes: &[Stroke],
    resample_distance: f64,
    params: &penmesh::AcutsParams,
) -> anyhow::Result<SimplifyReport> {
    let mut kept = Vec::new();
    let mut per_stroke = Vec::with_capacity(strokes.len());
    let (mut length_in, mut length_out, mut sed_sum, mut e_max) = (0.0, 0.0, 0.0, 0.0_f64);
    let mut offset = 0;
    for stroke in strokes {
        let samples = stroke.samples();
        let output = penmesh::acuts(samples, resample_distance, params);
        let m = penmesh::simplification_metrics(samples, &output.kept)?;
        length_in += polyline_length(samples);
        length_out += polyline_length(&output.kept.iter().map(|&i| samples[i]).collect::<Vec<_>>());
        sed_sum += m.sed * samples.len() as f64;
        e_max = e_max.max(m.e_max);
        kept.extend(output.kept.iter().map(|&i| i + offset));
        per_stroke.push(StrokeReport {
            n_input: samples.len(),
            n_resampled: output.resampled.len(),
            n_output: output.kept.len(),
            metrics: Metrics { cr: m.cr, e_max: m.e_max, e_l: m.e_l, sed: m.sed },
        });
        offset += samples.len();
    }
    let n_input = offset;
    let n_output = kept.len();
    let metrics = Metrics {
        cr: if n_input == 0 { 0.0 } else { (1.0 - n_output as f64 / n_input as f64) * 100.0 },
        e_max,
        e_l: if length_in > 0.0 { (length_in - length_out) / length_in * 100.0 } else { 0.0 },
        sed: if n_input == 0 { 0.0 } else { sed_sum / n_input as f64 },
    };
    Ok(SimplifyReport {
        algo: "acuts",
        n_input,
        n_resampled: per_stroke.iter().map(|s| s.n_resampled).sum(),
        n_output,
        kept,
        metrics,
        params: Params {
            tolerance: params.tolerance,
            angle_deg: params.angle_deg,
            angle_near_anchor: params.angle_near_anchor,
            pressure: params.pressure,
            resample: resample_distance,
        },
        strokes: per_stroke,
    })
}

/// Splits global kept indices back into per-stroke local ones.
fn kept_per_stroke(strokes: &[Stroke], kept: &[usize]) -> Vec<Vec<usize>> {
    let mut out = Vec::with_capacity(strokes.len());
    let (mut offset, mut cursor) = (0, 0);
    for stroke in strokes {
        let end = offset + stroke.len();
        let mut local = Vec::new();
        while cursor < kept.len() && kept[cursor] < end {
            local.push(kept[cursor] - offset);
            cursor += 1;
        }
        out.push(local);
        offset = end;
    }
    out
}

fn print_table(report: &SimplifyReport) {
    println!(
        "{:>6} {:>8} {:>10} {:>8} {:>7} {:>8} {:>7} {:>8}",
        "stroke", "N", "resampled", "C", "CR %", "E_max", "E_l %", "SED"
    );
    for (i, s) in report.strokes.iter().enumerate() {
        let m = &s.metrics;
        println!(
            "{:>6} {:>8} {:>10} {:>8} {:>7.1} {:>8.3} {:>7.2} {:>8.3}",
            i, s.n_input, s.n_resampled, s.n_output, m.cr, m.e_max, m.e_l, m.sed
        );
    }
    let m = &report.metrics;
    println!(
        "{:>6} {:>8} {:>10} {:>8} {:>7.1} {:>8.3} {:>7.2} {:>8.3}",
        "all", report.n_input, report.n_resampled, report.n_output, m.cr, m.e_max, m.e_l, m.sed
    );
}
