//! `penmesh-lab load`: many simulated pens drawing at once from one process, through the real
//! protocol, against a proxy (or the ceiling server) on this machine.
//!
//! Each pen is one tokio task with one WebSocket. It draws generated strokes at a tablet's
//! cadence (`--rate` samples per second), sends what the tablet produced every `--batch-ms` as a
//! binary `Points` frame, lifts the pen (`StrokeEnd`) when the stroke is drawn, waits
//! `--pause-ms` and draws the next one, until `--duration` or `--strokes` is reached. It measures:
//! - per sample, the time from sending its batch to the `Ack` that covers it;
//! - per stroke, the time from sending `StrokeEnd` (pen-up) to `StrokeDone`;
//! - at the end, what the proxy **stored** (`GET /v1/sessions/{s}/strokes`, summing
//!   `n_points`): `lost = sent - stored` must be 0;
//! - the server's CPU and memory from `/proc/PID` (with `--proxy-pid`, or when this command
//!   spawns the server itself with `--spawn-proxy` or `--spawn-ceiling`).
//!
//! Throughput is counted over the steady window, from the end of the ramp to the end of the
//! drawing. `--idle` opens the connections and only holds them, to measure the memory one idle
//! connection costs the server.
//!
//! Limits: loopback targets only (this is a load generator, not a tool to aim at other hosts),
//! at most [`MAX_CLIENTS`] pens and [`MAX_DURATION_SECS`] seconds.

mod drive;
mod pen;
mod procstat;
mod readings;
mod report;
mod server;
mod summary;

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args;
use serde::Serialize;

pub use self::report::{LoadReportArgs, report};
use self::summary::{Machine, print_table};

/// Most pens one run may simulate.
pub const MAX_CLIENTS: usize = 20_000;
/// Longest run, seconds.
pub const MAX_DURATION_SECS: f64 = 3600.0;
#[derive(Debug, Args)]
pub struct LoadArgs {
    /// The proxy (or ceiling server) to load, e.g. http://127.0.0.1:8080. Loopback only.
    #[arg(long, required_unless_present_any = ["spawn_proxy", "spawn_ceiling"])]
    pub url: Option<String>,
    /// Start a proxy process for this run (the same code as `penmesh-proxy`) on a fresh SQLite
    /// database in a temporary folder, or on `--database-url`, and stop it at the end.
    #[arg(long, conflicts_with_all = ["url", "spawn_ceiling"])]
    pub spawn_proxy: bool,
    /// Start the ceiling server (decode and ack only, no storage) for this run.
    #[arg(long, conflicts_with = "url")]
    pub spawn_ceiling: bool,
    /// Database of the spawned proxy, e.g. postgres://... (default: a fresh SQLite file).
    #[arg(long, requires = "spawn_proxy")]
    pub database_url: Option<String>,
    /// Extra setting for the spawned proxy, e.g. `--proxy-arg=--commit-interval-ms=5`.
    #[arg(long, value_name = "ARG", allow_hyphen_values = true)]
    pub proxy_arg: Vec<String>,
    /// Extra setting for the spawned ceiling, e.g. `--ceiling-arg=--answer-task`.
    #[arg(long, value_name = "ARG", allow_hyphen_values = true)]
    pub ceiling_arg: Vec<String>,
    /// Simulated pens, each with its own WebSocket.
    #[arg(long)]
    pub clients: usize,
    /// Tablet sampling rate of every pen, Hz (real tablets: 150 to 240).
    #[arg(long, default_value_t = 200.0)]
    pub rate: f64,
    /// How long the pens draw, seconds (the ramp included; the drain after it is not).
    #[arg(long, default_value_t = 10.0)]
    pub duration: f64,
    /// Pens connect evenly spread over this many seconds (default: a quarter of the duration,
    /// at most 10).
    #[arg(long)]
    pub ramp: Option<f64>,
    /// Sessions the pens are spread over (default: one per pen; fewer sessions means every
    /// pen's strokes are fanned out to the others of its session).
    #[arg(long)]
    pub sessions: Option<usize>,
    /// Most strokes per pen (default: as many as the duration allows).
    #[arg(long, value_name = "PER_CLIENT")]
    pub strokes: Option<u64>,
    /// A pen sends what its tablet produced every this many milliseconds (tablet apps: 8-16).
    #[arg(long, default_value_t = 12)]
    pub batch_ms: u64,
    /// Pen speed of the generated strokes, px/s.
    #[arg(long, default_value_t = penmesh::DEFAULT_SPEED_PX_PER_S)]
    pub speed: f64,
    /// Time the pen is lifted between two strokes, ms.
    #[arg(long, default_value_t = 250)]
    pub pause_ms: u64,
    /// Only connect and hold the connections (no drawing): the server's memory per idle
    /// connection.
    #[arg(long)]
    pub idle: bool,
    /// Also write the summary as JSON to this file (`-` for stdout, instead of the table).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// The server's process id, to read its CPU time and memory from /proc.
    #[arg(long, value_name = "PID", conflicts_with_all = ["spawn_proxy", "spawn_ceiling"])]
    pub proxy_pid: Option<u32>,
    /// After the drawing, wait at most this long for the outstanding acks, seconds.
    #[arg(long, default_value_t = 30)]
    pub drain_secs: u64,
    /// A name for this run in the JSON (e.g. `headline`).
    #[arg(long)]
    pub label: Option<String>,
}

/// The settings of a run, checked.
#[derive(Debug, Clone, Serialize)]
pub struct Plan {
    pub clients: usize,
    pub rate_hz: f64,
    pub duration_s: f64,
    pub ramp_s: f64,
    pub sessions: usize,
    pub strokes_per_client: Option<u64>,
    pub batch_ms: u64,
    pub speed_px_per_s: f64,
    pub pause_ms: u64,
    pub idle: bool,
    pub drain_s: u64,
}

impl Plan {
    /// Checks every setting and the target; the target must be on this machine.
    pub fn from_args(args: &LoadArgs) -> anyhow::Result<Plan> {
        if let Some(url) = &args.url {
            check_loopback(url)?;
        }
        anyhow::ensure!(args.clients > 0, "--clients 0: at least one pen is needed");
        anyhow::ensure!(
            args.clients <= MAX_CLIENTS,
            "--clients {} is more than the {MAX_CLIENTS} one run may simulate",
            args.clients
        );
        anyhow::ensure!(
            args.rate.is_finite() && args.rate > 0.0 && args.rate <= 1000.0,
            "--rate {} must be in (0, 1000] Hz",
            args.rate
        );
        anyhow::ensure!(
            args.duration.is_finite() && args.duration > 0.0 && args.duration <= MAX_DURATION_SECS,
            "--duration {} must be in (0, {MAX_DURATION_SECS}] seconds",
            args.duration
        );
        let ramp = args.ramp.unwrap_or((args.duration / 4.0).min(10.0));
        anyhow::ensure!(
            ramp.is_finite() && ramp >= 0.0 && ramp < args.duration,
            "--ramp {ramp} must be at least 0 and shorter than --duration {}",
            args.duration
        );
        let sessions = args.sessions.unwrap_or(args.clients);
        anyhow::ensure!(
            sessions >= 1 && sessions <= args.clients,
            "--sessions {sessions} must be between 1 and --clients {}",
            args.clients
        );
        anyhow::ensure!(
            (1..=1000).contains(&args.batch_ms),
            "--batch-ms {} must be between 1 and 1000",
            args.batch_ms
        );
        anyhow::ensure!(args.strokes != Some(0), "--strokes 0 draws nothing");
        // Settings for a server this run does not start would be dropped without a word.
        anyhow::ensure!(
            args.proxy_arg.is_empty() || args.spawn_proxy,
            "--proxy-arg is for the proxy this run starts: add --spawn-proxy"
        );
        anyhow::ensure!(
            args.ceiling_arg.is_empty() || args.spawn_ceiling,
            "--ceiling-arg is for the ceiling this run starts: add --spawn-ceiling"
        );
        anyhow::ensure!(
            args.speed.is_finite() && args.speed > 0.0,
            "--speed {} must be a positive number of px/s",
            args.speed
        );
        Ok(Plan {
            clients: args.clients,
            rate_hz: args.rate,
            duration_s: args.duration,
            ramp_s: ramp,
            sessions,
            strokes_per_client: args.strokes,
            batch_ms: args.batch_ms,
            speed_px_per_s: args.speed,
            pause_ms: args.pause_ms,
            idle: args.idle,
            drain_s: args.drain_secs,
        })
    }
}

/// Refuses any target that is not this machine: `localhost`, 127.0.0.0/8 or ::1.
pub fn check_loopback(url: &str) -> anyhow::Result<()> {
    let parsed = reqwest::Url::parse(url.trim())
        .with_context(|| format!("--url {url}: not a URL (e.g. http://127.0.0.1:8080)"))?;
    anyhow::ensure!(
        matches!(parsed.scheme(), "http" | "ws"),
        "--url {url}: must start with http:// or ws://"
    );
    let host = parsed.host_str().unwrap_or("");
    let host = host.strip_prefix('[').and_then(|h| h.strip_suffix(']')).unwrap_or(host);
    let loopback = match host.parse::<std::net::IpAddr>() {
        Ok(ip) => ip.is_loopback(),
        Err(_) => host.eq_ignore_ascii_case("localhost"),
    };
    anyhow::ensure!(
        loopback,
        "--url {url}: penmesh-lab load only targets this machine (localhost, 127.0.0.0/8 or ::1)"
    );
    Ok(())
}

pub fn run(args: &LoadArgs) -> anyhow::Result<()> {
    let plan = Plan::from_args(args)?;
    raise_open_file_limit(plan.clients)?;
    let started_at_unix_s = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    let loadavg_before = procstat::loadavg();
    let (base, spawned, pid) = if args.spawn_proxy || args.spawn_ceiling {
        let spawned = server::spawn_server(args, &plan)?;
        let pid = spawned.1.child.id();
        (spawned.0, Some(spawned.1), Some(pid))
    } else {
        let url = args.url.as_deref().expect("clap requires --url without --spawn-*");
        let base = url.trim().trim_end_matches('/').replacen("ws://", "http://", 1);
        (base, None, args.proxy_pid)
    };
    if let Some(pid) = pid {
        anyhow::ensure!(
            Path::new(&format!("/proc/{pid}/stat")).exists(),
            "--proxy-pid {pid}: no such process"
        );
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the runtime")?;
    let mut summary = runtime.block_on(drive::drive(&plan, &base, pid))?;
    drop(spawned);
    summary.label = args.label.clone();
    summary.machine = Machine {
        cores: std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
        loadavg_before,
        loadavg_after: procstat::loadavg(),
        started_at_unix_s,
    };
    let json = serde_json::to_string_pretty(&summary)?;
    match args.json.as_deref() {
        Some(path) if path == Path::new("-") => println!("{json}"),
        Some(path) => {
            if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
                fs_err::create_dir_all(parent)?;
            }
            fs_err::write(path, format!("{json}\n"))?;
            print_table(&summary);
        }
        None => print_table(&summary),
    }
    if let Some(lost) = summary.samples.lost {
        anyhow::ensure!(lost == 0, "{lost} samples were sent and not stored");
    }
    anyhow::ensure!(
        summary.connections.failed == 0,
        "{} of {} connections failed (first errors: {})",
        summary.connections.failed,
        plan.clients,
        summary.errors.first.join("; ")
    );
    Ok(())
}

/// Raises the soft open-file limit so that every pen (and a spawned server) gets its socket.
fn raise_open_file_limit(clients: usize) -> anyhow::Result<()> {
    let needed = 2 * clients as u64 + 256;
    let limit = rlimit::increase_nofile_limit(needed.max(65_536))
        .context("cannot read or raise the open-file limit (RLIMIT_NOFILE)")?;
    anyhow::ensure!(
        limit >= needed,
        "{clients} pens need about {needed} open files and the hard limit is {limit}; raise it \
         (ulimit -Hn) or run fewer --clients"
    );
    Ok(())
}
