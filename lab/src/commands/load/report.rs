//! `penmesh-lab load-report`: the tables and plots of `docs/performance-log.md` from several runs.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use super::summary::Summary;
use crate::plot::{LineChart, Series, SeriesLabelPosition};

/// `penmesh-lab load-report` (hidden): the tables and plots of `docs/performance-log.md` from the
/// JSON summaries of several runs (a sweep of client counts, against the proxy and the ceiling).
#[derive(Debug, Args)]
pub struct LoadReportArgs {
    /// Summaries written by `penmesh-lab load --json`.
    #[arg(required = true)]
    pub runs: Vec<PathBuf>,
    /// Where to write `load_throughput.svg` and `load_p99.svg`.
    #[arg(long)]
    pub out_dir: PathBuf,
}

pub fn report(args: &LoadReportArgs) -> anyhow::Result<()> {
    let mut runs: Vec<Summary> = args
        .runs
        .iter()
        .map(|path| {
            let text = fs_err::read_to_string(path)?;
            serde_json::from_str(&text)
                .with_context(|| format!("{}: not a penmesh-lab load summary", path.display()))
        })
        .collect::<anyhow::Result<_>>()?;
    runs.retain(|r| r.settings["idle"] != serde_json::Value::Bool(true));
    runs.sort_by_key(|r| (r.target.clone(), r.connections.made + r.connections.failed));
    println!(
        "| target | pens | offered/s | acked/s | p99 sample→Ack ms | p99 pen-up→Done ms | lost | server CPU % | peak RSS MB | load avg |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---|");
    for r in &runs {
        let server = r.server.as_ref();
        println!(
            "| {} | {} | {:.0} | {:.0} | {:.1} | {:.1} | {} | {} | {} | {} |",
            r.target,
            r.connections.made + r.connections.failed,
            r.throughput.offered_per_s,
            r.throughput.acked_per_s,
            r.latency_ms.sample_to_ack.p99,
            r.latency_ms.pen_up_to_stroke_done.p99,
            r.samples.lost.map_or("-".into(), |l| l.to_string()),
            server.map_or("-".into(), |s| format!("{:.0}", s.cpu_percent)),
            server.map_or("-".into(), |s| format!("{:.0}", s.peak_rss_kb as f64 / 1024.0)),
            r.machine.loadavg_before.as_deref().and_then(|l| l.split(' ').next()).unwrap_or("?"),
        );
    }
    fs_err::create_dir_all(&args.out_dir)?;
    let series = |name: &str, target: &str, value: fn(&Summary) -> f64| Series {
        name: name.to_string(),
        points: runs
            .iter()
            .filter(|r| r.target == target)
            .map(|r| ((r.connections.made + r.connections.failed) as f64, value(r)))
            .collect(),
    };
    let throughput = [
        series("proxy, acknowledged", "proxy", |r| r.throughput.acked_per_s),
        series("ceiling, acknowledged", "ceiling", |r| r.throughput.acked_per_s),
        series("offered (pens × rate)", "proxy", |r| r.throughput.offered_per_s),
    ];
    let p99 = [
        series("proxy, sample → Ack", "proxy", |r| r.latency_ms.sample_to_ack.p99),
        series("proxy, pen-up → StrokeDone", "proxy", |r| r.latency_ms.pen_up_to_stroke_done.p99),
        series("ceiling, sample → Ack", "ceiling", |r| r.latency_ms.sample_to_ack.p99),
    ];
    let chart = |caption, y_label, series: &[Series], log_y, file: &str| {
        LineChart {
            caption,
            x_label: "concurrent pens",
            y_label,
            series,
            log_y,
            legend: SeriesLabelPosition::UpperLeft,
            size: (800, 520),
        }
        .write_svg(&args.out_dir.join(file))
    };
    chart(
        "Throughput against pens (200 Hz each)",
        "samples per second",
        &throughput,
        false,
        "load_throughput.svg",
    )?;
    chart("p99 latency against pens", "p99, ms (log)", &p99, true, "load_p99.svg")?;
    Ok(())
}
