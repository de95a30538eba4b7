//! `penmesh draw`: one person draws into a proxy session, live.

use std::time::Duration;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use penmesh::{Brush, GeneratorParams};
use serde::Serialize;

use crate::cli::{DrawArgs, LiveArgs};
use crate::input::{AxisRanges, EvdevSource, Pacing, PenSource, ReplaySource};
use crate::live::{self, DrawOptions, Endpoint};
use crate::reconstruct::StrokeReport;
use crate::report::{self, Totals};

pub fn run(args: &DrawArgs) -> anyhow::Result<()> {
    init_tracing(args.live.verbose);
    let endpoint = Endpoint::new(&args.server, args.session, args.token.clone())?;
    let mut options = draw_options(&args.live, &args.name)?;
    // Bad input fails here, before anything touches the network.
    let source = source(args)?;
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        options.out_dir = Some(dir.clone());
    }
    let progress = (!args.live.json).then(|| progress_bar(source.total_samples(), &args.name));
    options.progress = progress.clone();

    let runtime = runtime()?;
    let reports = runtime.block_on(async {
        options.interrupts = Some(interrupts());
        live::draw(&endpoint, source, &options).await
    });
    // A tablet's reading thread may sit in a blocking read: do not wait for it.
    runtime.shutdown_timeout(Duration::from_millis(100));
    if let Some(progress) = &progress {
        progress.finish_and_clear();
    }
    let reports = reports?;
    if args.live.json {
        let summary = DrawSummary {
            server: &endpoint.base,
            session: endpoint.session,
            totals: Totals::of(&reports),
            strokes: &reports,
        };
        println!("{}", serde_json::to_string(&summary)?);
    } else {
        print!("{}", report::table(&reports));
        if let Some(dir) = &args.out {
            println!("GLB files: {}", dir.display());
        }
    }
    Ok(())
}

#[derive(Debug, Serialize)]
struct DrawSummary<'a> {
    server: &'a str,
    session: uuid::Uuid,
    totals: Totals,
    strokes: &'a [StrokeReport],
}

fn source(args: &DrawArgs) -> anyhow::Result<Box<dyn PenSource>> {
    let pacing = if args.realtime { Pacing::Realtime } else { Pacing::Fast };
    if let Some(path) = &args.input {
        return Ok(Box::new(ReplaySource::from_file(path, pacing)?));
    }
    if let Some(shape) = args.synth {
        anyhow::ensure!(args.count >= 1, "--count must be at least 1");
        let params: Vec<GeneratorParams> = (0..u64::from(args.count))
            .map(|i| GeneratorParams {
                shape,
                speed: args.speed,
                size: args.size,
                rate_hz: args.rate,
                seed: args.seed.wrapping_add(i),
            })
            .collect();
        return Ok(Box::new(ReplaySource::synth(&params, pacing)?));
    }
    let Some(path) = &args.device else {
        anyhow::bail!("give one of --input, --synth or --device");
    };
    anyhow::ensure!(
        args.canvas_width.is_finite() && args.canvas_width > 0.0,
        "--canvas-width must be a positive number"
    );
    let (name, x, y, pressure) = match (args.abs_x, args.abs_y) {
        (Some(x), Some(y)) => {
            let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("device").to_string();
            (name, x, y, args.abs_pressure)
        }
        _ => {
            let (name, x, y, pressure) = crate::input::read_axis_ranges(path).context(
                "pass --abs-x and --abs-y (and --abs-pressure) to give the ranges yourself",
            )?;
            (name, args.abs_x.unwrap_or(x), args.abs_y.unwrap_or(y), args.abs_pressure.or(pressure))
        }
    };
    // Fail now, not in the reading thread, when the file cannot be opened.
    std::fs::File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let ranges = AxisRanges { x, y, pressure, canvas_width: args.canvas_width };
    Ok(Box::new(EvdevSource::new(path.clone(), name, ranges)))
}

/// The live settings of `draw` and `demo`, checked.
pub(crate) fn draw_options(live: &LiveArgs, name: &str) -> anyhow::Result<DrawOptions> {
    let brush = Brush {
        size: live.brush_size,
        pressure_response: live.pressure_response,
        ..Brush::default()
    };
    brush.validate().map_err(|e| anyhow::anyhow!("bad brush: {e}"))?;
    anyhow::ensure!(
        live.resample.is_finite() && live.resample >= 0.0,
        "--resample must be a finite number >= 0"
    );
    anyhow::ensure!(live.batch_size >= 1, "--batch-size must be at least 1");
    anyhow::ensure!(!name.trim().is_empty(), "--name must not be empty");
    Ok(DrawOptions {
        brush,
        resample: live.resample,
        batch_interval: Duration::from_millis(live.batch_ms),
        batch_samples: live.batch_size,
        retry_for: Duration::from_secs(live.retry_for),
        ..DrawOptions::new(name)
    })
}

/// A bar for a replay of known length, a spinner otherwise; hidden when stderr is no terminal.
pub(crate) fn progress_bar(total: Option<u64>, name: &str) -> ProgressBar {
    let bar = match total {
        Some(total) => ProgressBar::new(total).with_style(
            ProgressStyle::with_template("{prefix:>10} [{bar:30}] {pos}/{len} samples {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        ),
        None => ProgressBar::new_spinner().with_style(
            ProgressStyle::with_template("{prefix:>10} {spinner} {pos} samples {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        ),
    };
    bar.with_prefix(name.to_string())
}

/// Counts Ctrl-C presses: the first ends the input, the second gives up at once.
fn interrupts() -> tokio::sync::watch::Receiver<u32> {
    let (tx, rx) = tokio::sync::watch::channel(0u32);
    tokio::spawn(async move {
        while tokio::signal::ctrl_c().await.is_ok() {
            tx.send_modify(|n| *n += 1);
        }
    });
    rx
}

pub(crate) fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread().enable_all().build().context("starting the runtime")
}

/// Logs to stderr: warnings by default, `-v` info, `-vv` debug; `RUST_LOG` wins.
pub(crate) fn init_tracing(verbose: u8) {
    let default = match verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .try_init();
}
