//! `penmesh load`: many simulated pens drawing at once from one process, through the real
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

use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use anyhow::Context;
use clap::Args;
use futures_util::{SinkExt, StreamExt};
use hdrhistogram::Histogram;
use indicatif::{ProgressBar, ProgressStyle};
use penmesh::protocol::{
    ClientMessage, Hello, PROTOCOL_VERSION, PointBatch, Points, ServerMessage, StrokeBegin,
    StrokeEnd, decode_server, encode_client, quantize_sample,
};
use penmesh::{Brush, GeneratorParams, Sample, Shape};
use serde::{Deserialize, Serialize};
use tokio::time::Instant;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::protocol::WebSocketConfig;
use uuid::Uuid;

/// Most pens one run may simulate.
pub const MAX_CLIENTS: usize = 20_000;
/// Longest run, seconds.
pub const MAX_DURATION_SECS: f64 = 3600.0;
/// Different generated strokes the pens share (each pen walks through them in its own order).
const STROKE_POOL: usize = 40;
/// Longest wait for a connection's handshake and `Welcome`.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(15);
/// How often the progress line and the `/proc` sampler look.
const SAMPLE_EVERY: Duration = Duration::from_millis(250);
/// Latencies are recorded in microseconds, up to this.
const MAX_LATENCY_US: u64 = 3_600_000_000;

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
        "--url {url}: penmesh load only targets this machine (localhost, 127.0.0.0/8 or ::1)"
    );
    Ok(())
}

/// The whole summary of a run (the `--json` output).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Summary {
    pub label: Option<String>,
    /// `proxy` or `ceiling`.
    pub target: String,
    pub url: String,
    pub machine: Machine,
    pub settings: serde_json::Value,
    pub connections: Connections,
    pub samples: Samples,
    pub strokes: Strokes,
    pub throughput: Throughput,
    pub latency_ms: Latencies,
    pub errors: Errors,
    pub server: Option<ProcessStats>,
    pub load_tool: ProcessStats,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Machine {
    pub cores: usize,
    pub loadavg_before: Option<String>,
    pub loadavg_after: Option<String>,
    pub started_at_unix_s: u64,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Connections {
    pub made: u64,
    pub failed: u64,
    /// Connections that ended before the run did (closed or broken).
    pub dropped: u64,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Samples {
    pub sent: u64,
    pub acknowledged: u64,
    /// Counted back through the HTTP API; `None` for the ceiling, which stores nothing.
    pub stored: Option<u64>,
    /// `sent - stored`.
    pub lost: Option<i64>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Strokes {
    pub begun: u64,
    pub done: u64,
    /// Strokes the server lists as `done` (proxy only).
    pub stored_done: Option<u64>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Throughput {
    /// The steady window: from the end of the ramp to the end of the drawing.
    pub window_s: f64,
    pub acked_per_s: f64,
    pub sent_per_s: f64,
    /// `clients * rate`: what the pens would send if they never lifted.
    pub offered_per_s: f64,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Latencies {
    pub sample_to_ack: Percentiles,
    pub pen_up_to_stroke_done: Percentiles,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Percentiles {
    pub count: u64,
    pub p50: f64,
    pub p95: f64,
    pub p99: f64,
    pub max: f64,
}

impl Percentiles {
    fn of(hist: &Histogram<u64>) -> Percentiles {
        let ms = |us: u64| us as f64 / 1000.0;
        Percentiles {
            count: hist.len(),
            p50: ms(hist.value_at_quantile(0.50)),
            p95: ms(hist.value_at_quantile(0.95)),
            p99: ms(hist.value_at_quantile(0.99)),
            max: ms(hist.max()),
        }
    }
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Errors {
    pub count: u64,
    /// The first few distinct error texts.
    pub first: Vec<String>,
}

/// CPU and memory of a process, from /proc.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct ProcessStats {
    pub pid: u32,
    /// CPU time over the steady window, as a percentage of one core.
    pub cpu_percent: f64,
    /// CPU time over the whole run (ramp, drawing and drain), seconds.
    pub cpu_seconds: f64,
    pub rss_before_kb: u64,
    /// Resident memory with every connection open (at the end of the drawing).
    pub rss_connected_kb: u64,
    pub peak_rss_kb: u64,
    /// `(rss_connected - rss_before) / connections`, in KB.
    pub kb_per_connection: Option<f64>,
}

/// Counters every pen adds to, read by the progress line and the window snapshots.
#[derive(Debug, Default)]
struct Counters {
    connected: AtomicU64,
    failed: AtomicU64,
    sent: AtomicU64,
    acked: AtomicU64,
    done: AtomicU64,
    errors: AtomicU64,
}

/// What one pen brings back.
#[derive(Debug)]
struct PenResult {
    connected: bool,
    dropped: bool,
    sent: u64,
    acked: u64,
    begun: u64,
    done: u64,
    errors: Vec<String>,
    ack_us: Histogram<u64>,
    done_us: Histogram<u64>,
}

impl PenResult {
    fn new() -> PenResult {
        PenResult {
            connected: false,
            dropped: false,
            sent: 0,
            acked: 0,
            begun: 0,
            done: 0,
            errors: Vec::new(),
            ack_us: histogram(),
            done_us: histogram(),
        }
    }
}

fn histogram() -> Histogram<u64> {
    Histogram::new_with_bounds(1, MAX_LATENCY_US, 2).expect("valid histogram bounds")
}

/// A server this run started, stopped when dropped.
#[derive(Debug)]
struct Spawned {
    child: std::process::Child,
    _dir: tempfile::TempDir,
}

impl Drop for Spawned {
    fn drop(&mut self) {
        // SIGTERM lets the proxy shut down gracefully; kill it if it does not within 15 s.
        let _ = std::process::Command::new("kill")
            .arg("-TERM")
            .arg(self.child.id().to_string())
            .status();
        let deadline = std::time::Instant::now() + Duration::from_secs(15);
        while std::time::Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub fn run(args: &LoadArgs) -> anyhow::Result<()> {
    let plan = Plan::from_args(args)?;
    raise_open_file_limit(plan.clients)?;
    let started_at_unix_s = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    let loadavg_before = read_loadavg();
    let (base, spawned, pid) = if args.spawn_proxy || args.spawn_ceiling {
        let spawned = spawn_server(args, &plan)?;
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
    let mut summary = runtime.block_on(drive(&plan, &base, pid))?;
    drop(spawned);
    summary.label = args.label.clone();
    summary.machine = Machine {
        cores: std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
        loadavg_before,
        loadavg_after: read_loadavg(),
        started_at_unix_s,
    };
    let json = serde_json::to_string_pretty(&summary)?;
    match args.json.as_deref() {
        Some(path) if path == Path::new("-") => println!("{json}"),
        Some(path) => {
            if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
                std::fs::create_dir_all(parent)
                    .with_context(|| format!("cannot create {}", parent.display()))?;
            }
            std::fs::write(path, format!("{json}\n"))
                .with_context(|| format!("cannot write {}", path.display()))?;
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

/// Starts the proxy (`penmesh serve-proxy`, the same code as `penmesh-proxy`) or the ceiling on
/// a free loopback port and waits until it answers.
fn spawn_server(args: &LoadArgs, plan: &Plan) -> anyhow::Result<(String, Spawned)> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .context("cannot find a free port")?
        .port();
    let dir = tempfile::Builder::new().prefix("penmesh-load-").tempdir()?;
    let exe = std::env::current_exe().context("cannot find this program")?;
    let mut command = std::process::Command::new(exe);
    if args.spawn_proxy {
        let database = match &args.database_url {
            Some(url) => url.clone(),
            None => format!("sqlite://{}", dir.path().join("penmesh.db").display()),
        };
        let per_session = plan.clients.div_ceil(plan.sessions).max(64);
        let idle = (plan.duration_s + plan.drain_s as f64 + 60.0).ceil() as u64;
        command
            .arg("serve-proxy")
            .args(["--host", "127.0.0.1", "--port", &port.to_string()])
            .args(["--database-url", &database])
            .args(["--max-connections-per-session", &per_session.to_string()])
            .args(["--idle-timeout-secs", &idle.to_string()])
            .args(&args.proxy_arg);
    } else {
        command.arg("ceiling").args(["--host", "127.0.0.1", "--port", &port.to_string()]);
    }
    let log = std::fs::File::create(dir.path().join("server.log"))?;
    command
        .env("RUST_LOG", std::env::var("RUST_LOG").unwrap_or_else(|_| "warn".into()))
        .env_remove("PORT")
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(log);
    let child = command.spawn().context("cannot start the server")?;
    let mut spawned = Spawned { child, _dir: dir };
    let base = format!("http://127.0.0.1:{port}");
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    loop {
        if std::net::TcpStream::connect(("127.0.0.1", port)).is_ok() {
            return Ok((base, spawned));
        }
        if let Ok(Some(status)) = spawned.child.try_wait() {
            let log =
                std::fs::read_to_string(spawned._dir.path().join("server.log")).unwrap_or_default();
            anyhow::bail!("the server exited at start ({status}): {}", log.trim());
        }
        anyhow::ensure!(
            std::time::Instant::now() < deadline,
            "the server did not listen within 60 s"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[derive(Debug, Deserialize)]
struct SessionReply {
    session: Uuid,
    token: String,
    /// The ceiling server says so: it stores nothing to count back.
    #[serde(default)]
    ceiling: bool,
}

#[derive(Debug, Deserialize)]
struct StrokeRow {
    status: String,
    n_points: u64,
}

#[derive(Debug, Deserialize)]
struct StrokeRows {
    strokes: Vec<StrokeRow>,
}

/// What a pen needs to know, shared by all pens.
#[derive(Debug)]
struct Shared {
    base_ws: String,
    pool: Vec<Arc<Vec<Sample>>>,
    start: Instant,
    ramp: Duration,
    deadline: Instant,
    drain: Duration,
    batch: Duration,
    pause: Duration,
    max_strokes: u64,
    idle: bool,
    clients: usize,
    counters: Counters,
}

async fn drive(plan: &Plan, base: &str, pid: Option<u32>) -> anyhow::Result<Summary> {
    let http = reqwest::Client::builder()
        .timeout(Duration::from_secs(60))
        .build()
        .context("building the HTTP client")?;
    let mut sessions = Vec::with_capacity(plan.sessions);
    for _ in 0..plan.sessions {
        let reply: SessionReply = http
            .post(format!("{base}/v1/sessions"))
            .send()
            .await
            .and_then(|r| r.error_for_status())
            .with_context(|| format!("cannot create a session at {base}"))?
            .json()
            .await
            .with_context(|| {
                format!("{base}/v1/sessions answered something else than a session")
            })?;
        sessions.push(reply);
    }
    let is_ceiling = sessions.first().is_some_and(|s| s.ceiling);
    let pool = stroke_pool(plan)?;
    let (rss_before, _) = pid.map(read_memory).unwrap_or((0, 0));
    let cpu_start = pid.map(read_cpu_seconds).unwrap_or(0.0);
    let self_cpu_start = read_cpu_seconds(std::process::id());

    let start = Instant::now() + Duration::from_millis(200);
    let shared = Arc::new(Shared {
        base_ws: base.replacen("http://", "ws://", 1),
        pool,
        start,
        ramp: Duration::from_secs_f64(plan.ramp_s),
        deadline: start + Duration::from_secs_f64(plan.duration_s),
        drain: Duration::from_secs(plan.drain_s),
        batch: Duration::from_millis(plan.batch_ms),
        pause: Duration::from_millis(plan.pause_ms),
        max_strokes: plan.strokes_per_client.unwrap_or(u64::MAX),
        idle: plan.idle,
        clients: plan.clients,
        counters: Counters::default(),
    });
    let mut pens = tokio::task::JoinSet::new();
    for pen_idx in 0..plan.clients {
        let session = &sessions[pen_idx % sessions.len()];
        let (session_id, token) = (session.session, session.token.clone());
        let shared = shared.clone();
        pens.spawn(async move { pen(pen_idx, session_id, token, shared).await });
    }

    // The progress line, the /proc sampler and the window snapshots.
    let progress = progress_line();
    let window_start = start + shared.ramp;
    let mut window: Option<(f64, u64, u64, f64, f64)> = None; // (t, acked, sent, cpu, self cpu)
    let mut window_end: Option<(f64, u64, u64, f64, f64)> = None;
    let mut peak_rss = 0;
    let mut rss_connected = 0;
    let mut last = (Instant::now(), 0u64);
    let mut results = Vec::with_capacity(plan.clients);
    let mut ticker = tokio::time::interval(SAMPLE_EVERY);
    loop {
        tokio::select! {
            joined = pens.join_next() => match joined {
                Some(result) => results.push(result.context("a pen task panicked")?),
                None => break,
            },
            _ = ticker.tick() => {
                let now = Instant::now();
                let c = &shared.counters;
                let (acked, sent) = (c.acked.load(Ordering::Relaxed), c.sent.load(Ordering::Relaxed));
                if let Some(pid) = pid {
                    let (rss, hwm) = read_memory(pid);
                    peak_rss = peak_rss.max(rss).max(hwm);
                }
                let snapshot = || {
                    (
                        now.duration_since(start).as_secs_f64(),
                        acked,
                        sent,
                        pid.map(read_cpu_seconds).unwrap_or(0.0),
                        read_cpu_seconds(std::process::id()),
                    )
                };
                if window.is_none() && now >= window_start {
                    window = Some(snapshot());
                }
                if now >= window_start && now < shared.deadline {
                    // The last reading before the pens let go: every connection is open.
                    rss_connected = pid.map(|pid| read_memory(pid).0).unwrap_or(0);
                }
                if window_end.is_none() && now >= shared.deadline {
                    window_end = Some(snapshot());
                }
                let rate = (acked - last.1) as f64 / now.duration_since(last.0).as_secs_f64();
                last = (now, acked);
                progress.set_message(format!(
                    "pens {}/{} (failed {}) · sent {} · acked {} · {:.0} samples/s · strokes done {} · errors {}",
                    c.connected.load(Ordering::Relaxed),
                    plan.clients,
                    c.failed.load(Ordering::Relaxed),
                    sent,
                    acked,
                    rate,
                    c.done.load(Ordering::Relaxed),
                    c.errors.load(Ordering::Relaxed),
                ));
            }
        }
    }
    progress.finish_and_clear();

    let mut total = PenResult::new();
    let mut connections = Connections::default();
    let mut errors = Errors::default();
    for r in results {
        connections.made += u64::from(r.connected);
        connections.failed += u64::from(!r.connected);
        connections.dropped += u64::from(r.dropped);
        total.sent += r.sent;
        total.acked += r.acked;
        total.begun += r.begun;
        total.done += r.done;
        total.ack_us.add(&r.ack_us).expect("same histogram bounds");
        total.done_us.add(&r.done_us).expect("same histogram bounds");
        errors.count += r.errors.len() as u64;
        for e in r.errors {
            if errors.first.len() < 5 && !errors.first.contains(&e) {
                errors.first.push(e);
            }
        }
    }

    let (stored, stored_done) = if is_ceiling {
        (None, None)
    } else {
        let (points, done) = count_stored(&http, base, &sessions).await?;
        (Some(points), Some(done))
    };
    let end = Instant::now();
    let first = window.unwrap_or((0.0, 0, 0, cpu_start, self_cpu_start));
    let last = window_end.unwrap_or((
        end.duration_since(start).as_secs_f64(),
        total.acked,
        total.sent,
        pid.map(read_cpu_seconds).unwrap_or(0.0),
        read_cpu_seconds(std::process::id()),
    ));
    let window_s = (last.0 - first.0).max(1e-9);
    let server = pid.map(|pid| {
        let connected = connections.made.max(1) as f64;
        ProcessStats {
            pid,
            cpu_percent: 100.0 * (last.3 - first.3) / window_s,
            cpu_seconds: read_cpu_seconds(pid) - cpu_start,
            rss_before_kb: rss_before,
            rss_connected_kb: rss_connected,
            peak_rss_kb: peak_rss,
            kb_per_connection: (rss_connected > 0)
                .then(|| (rss_connected as f64 - rss_before as f64) / connected),
        }
    });
    let (self_rss, self_hwm) = read_memory(std::process::id());
    Ok(Summary {
        label: None,
        target: if is_ceiling { "ceiling" } else { "proxy" }.into(),
        url: base.to_string(),
        machine: Machine {
            cores: 0,
            loadavg_before: None,
            loadavg_after: None,
            started_at_unix_s: 0,
        },
        settings: serde_json::to_value(plan)?,
        connections,
        samples: Samples {
            sent: total.sent,
            acknowledged: total.acked,
            stored,
            lost: stored.map(|s| total.sent as i64 - s as i64),
        },
        strokes: Strokes { begun: total.begun, done: total.done, stored_done },
        throughput: Throughput {
            window_s,
            acked_per_s: (last.1 - first.1) as f64 / window_s,
            sent_per_s: (last.2 - first.2) as f64 / window_s,
            offered_per_s: plan.clients as f64 * plan.rate_hz,
        },
        latency_ms: Latencies {
            sample_to_ack: Percentiles::of(&total.ack_us),
            pen_up_to_stroke_done: Percentiles::of(&total.done_us),
        },
        errors,
        server,
        load_tool: ProcessStats {
            pid: std::process::id(),
            cpu_percent: 100.0 * (last.4 - first.4) / window_s,
            cpu_seconds: read_cpu_seconds(std::process::id()) - self_cpu_start,
            rss_before_kb: 0,
            rss_connected_kb: self_rss,
            peak_rss_kb: self_hwm,
            kb_per_connection: None,
        },
    })
}

/// The strokes the pens draw: every shape at the run's rate and speed, several seeds, with
/// samples snapped to the codec's grid (what the proxy stores is then what was sent).
fn stroke_pool(plan: &Plan) -> anyhow::Result<Vec<Arc<Vec<Sample>>>> {
    (0..STROKE_POOL)
        .map(|k| {
            let params = GeneratorParams {
                shape: Shape::ALL[k % Shape::ALL.len()],
                speed: plan.speed_px_per_s,
                rate_hz: plan.rate_hz,
                seed: k as u64,
                ..GeneratorParams::default()
            };
            let stroke = penmesh::generate_stroke(&params)
                .map_err(|e| anyhow::anyhow!("cannot generate the strokes: {e}"))?;
            Ok(Arc::new(stroke.samples().iter().map(quantize_sample).collect()))
        })
        .collect()
}

/// The stroke a pen is drawing.
#[derive(Debug)]
struct Drawing {
    id: Uuid,
    samples: Arc<Vec<Sample>>,
    began: Instant,
    sent: usize,
}

/// Batches of one stroke not yet acknowledged: (end seq, sent at).
#[derive(Debug, Default)]
struct Unacked {
    batches: VecDeque<(u64, Instant)>,
    acked: u64,
}

type Socket =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// One simulated pen: connect, draw strokes until the deadline, then wait for the last acks.
async fn pen(pen_idx: usize, session: Uuid, token: String, shared: Arc<Shared>) -> PenResult {
    let mut result = PenResult::new();
    let offset = shared.ramp.mul_f64(pen_idx as f64 / shared.clients as f64);
    tokio::time::sleep_until(shared.start + offset).await;
    let mut ws = match connect(&shared.base_ws, session, &token).await {
        Ok(ws) => ws,
        Err(err) => {
            shared.counters.failed.fetch_add(1, Ordering::Relaxed);
            shared.counters.errors.fetch_add(1, Ordering::Relaxed);
            result.errors.push(format!("{err:#}"));
            return result;
        }
    };
    result.connected = true;
    shared.counters.connected.fetch_add(1, Ordering::Relaxed);
    if let Err(err) = draw(pen_idx, &mut ws, &shared, &mut result).await {
        result.dropped = true;
        shared.counters.errors.fetch_add(1, Ordering::Relaxed);
        result.errors.push(format!("{err:#}"));
    }
    let _ = tokio::time::timeout(Duration::from_secs(2), ws.close(None)).await;
    result
}

async fn connect(base_ws: &str, session: Uuid, token: &str) -> anyhow::Result<Socket> {
    let url = format!("{base_ws}/v1/sessions/{session}/ws");
    let mut request = url.as_str().into_client_request()?;
    request.headers_mut().insert("authorization", format!("Bearer {token}").parse()?);
    let handshake = async {
        // A small read buffer: tungstenite zero-fills it all, and thousands of pens share
        // this process (acks are a few dozen bytes). TCP_NODELAY, as browsers set it.
        let config = WebSocketConfig::default().read_buffer_size(4 * 1024);
        let (mut ws, _) = tokio_tungstenite::connect_async_with_config(request, Some(config), true)
            .await
            .map_err(|e| anyhow::anyhow!("cannot connect: {e}"))?;
        let hello = Hello {
            protocol: PROTOCOL_VERSION,
            client: format!("penmesh-load/{}", env!("CARGO_PKG_VERSION")),
            name: None,
            resume: Vec::new(),
        };
        send(&mut ws, &ClientMessage::Hello(hello)).await?;
        loop {
            match next_message(&mut ws).await? {
                ServerMessage::Welcome(_) => return Ok(ws),
                ServerMessage::Error(e) => {
                    anyhow::bail!("refused: {}: {}", e.code.as_str(), e.message)
                }
                _ => continue,
            }
        }
    };
    tokio::time::timeout(CONNECT_TIMEOUT, handshake)
        .await
        .map_err(|_| anyhow::anyhow!("no welcome within {} s", CONNECT_TIMEOUT.as_secs()))?
}

async fn send(ws: &mut Socket, msg: &ClientMessage) -> anyhow::Result<()> {
    ws.send(Message::Binary(encode_client(msg).into())).await.context("sending")
}

async fn feed(ws: &mut Socket, msg: &ClientMessage) -> anyhow::Result<()> {
    ws.feed(Message::Binary(encode_client(msg).into())).await.context("sending")
}

/// The next protocol message (control frames are skipped; tungstenite answers pings).
async fn next_message(ws: &mut Socket) -> anyhow::Result<ServerMessage> {
    loop {
        match ws.next().await {
            Some(Ok(Message::Binary(bytes))) => {
                return decode_server(&bytes, usize::MAX)
                    .map_err(|e| anyhow::anyhow!("undecodable message: {e}"));
            }
            Some(Ok(Message::Text(text))) => {
                return penmesh::protocol::decode_server_json(&text, usize::MAX)
                    .map_err(|e| anyhow::anyhow!("undecodable message: {e}"));
            }
            Some(Ok(Message::Close(close))) => anyhow::bail!(
                "the server closed the connection{}",
                close.map(|c| format!(" ({} {})", c.code, c.reason)).unwrap_or_default()
            ),
            Some(Ok(_)) => continue,
            Some(Err(err)) => anyhow::bail!("connection lost: {err}"),
            None => anyhow::bail!("the connection ended"),
        }
    }
}

fn elapsed_us(since: Instant, now: Instant) -> u64 {
    (now.duration_since(since).as_micros() as u64).clamp(1, MAX_LATENCY_US)
}

async fn draw(
    pen_idx: usize,
    ws: &mut Socket,
    shared: &Shared,
    result: &mut PenResult,
) -> anyhow::Result<()> {
    let counters = &shared.counters;
    let mut unacked: HashMap<Uuid, Unacked> = HashMap::new();
    let mut pen_ups: HashMap<Uuid, Instant> = HashMap::new();
    let mut drawing: Option<Drawing> = None;
    // Pens start at different points of their rhythm, so batches do not all leave at once.
    let phase = shared.batch.mul_f64((pen_idx % 97) as f64 / 97.0);
    let mut next_stroke_at = Instant::now() + phase;
    let mut ticker = tokio::time::interval_at(next_stroke_at, shared.batch);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let drain_until = shared.deadline + shared.drain;
    loop {
        let finished = Instant::now() >= shared.deadline && drawing.is_none();
        if finished && (shared.idle || (pen_ups.is_empty() && unacked.is_empty())) {
            return Ok(());
        }
        tokio::select! {
            _ = ticker.tick(), if !finished && !shared.idle => {
                let now = Instant::now();
                if drawing.is_none()
                    && now >= next_stroke_at
                    && now < shared.deadline
                    && result.begun < shared.max_strokes
                {
                    let samples = shared.pool[(pen_idx * 7 + result.begun as usize) % shared.pool.len()].clone();
                    let id = Uuid::new_v4();
                    feed(ws, &ClientMessage::StrokeBegin(StrokeBegin {
                        stroke: id,
                        brush: Brush::default(),
                        device: Some("penmesh-load".into()),
                        params: None,
                    }))
                    .await?;
                    unacked.insert(id, Unacked::default());
                    result.begun += 1;
                    // The first sample is due at once: the pen touched down.
                    drawing = Some(Drawing { id, samples, began: now - Duration::from_micros(1), sent: 0 });
                }
                let Some(d) = drawing.as_mut() else { continue };
                let elapsed_ms = now.duration_since(d.began).as_secs_f64() * 1000.0;
                let lifting = now >= shared.deadline;
                let t0 = d.samples[0].t;
                let mut end = d.samples.partition_point(|s| s.t - t0 <= elapsed_ms);
                if lifting {
                    // The run is over: the pen lifts here (a stroke needs two samples).
                    end = end.max(2).min(d.samples.len());
                }
                if end > d.sent {
                    let points = Points {
                        stroke: d.id,
                        seq: d.sent as u64,
                        points: PointBatch(d.samples[d.sent..end].to_vec()),
                    };
                    feed(ws, &ClientMessage::Points(points)).await?;
                    let n = (end - d.sent) as u64;
                    unacked.entry(d.id).or_default().batches.push_back((end as u64, now));
                    d.sent = end;
                    result.sent += n;
                    counters.sent.fetch_add(n, Ordering::Relaxed);
                }
                if end == d.samples.len() || lifting {
                    feed(ws, &ClientMessage::StrokeEnd(StrokeEnd { stroke: d.id, n_points: d.sent as u64 })).await?;
                    pen_ups.insert(d.id, now);
                    drawing = None;
                    next_stroke_at = now + shared.pause;
                }
                ws.flush().await.context("sending")?;
            }
            msg = next_message(ws) => {
                let now = Instant::now();
                match msg? {
                    ServerMessage::Ack(ack) => {
                        if let Some(u) = unacked.get_mut(&ack.stroke) {
                            while let Some(&(end, sent_at)) = u.batches.front() {
                                if end > ack.upto_seq {
                                    break;
                                }
                                let n = end - u.acked.min(end);
                                u.batches.pop_front();
                                let _ = result.ack_us.record_n(elapsed_us(sent_at, now), n);
                                u.acked = end;
                                result.acked += n;
                                counters.acked.fetch_add(n, Ordering::Relaxed);
                            }
                        }
                    }
                    ServerMessage::StrokeDone(done) => {
                        if let Some(up) = pen_ups.remove(&done.stroke) {
                            let _ = result.done_us.record(elapsed_us(up, now));
                            result.done += 1;
                            counters.done.fetch_add(1, Ordering::Relaxed);
                        }
                        if unacked.get(&done.stroke).is_some_and(|u| u.batches.is_empty()) {
                            unacked.remove(&done.stroke);
                        }
                    }
                    ServerMessage::Error(e) => {
                        counters.errors.fetch_add(1, Ordering::Relaxed);
                        result.errors.push(format!("{}: {}", e.code.as_str(), e.message));
                    }
                    _ => {}
                }
                if Instant::now() >= drain_until {
                    anyhow::bail!(
                        "{} strokes and {} batches still unacknowledged {} s after the end",
                        pen_ups.len(),
                        unacked.values().map(|u| u.batches.len()).sum::<usize>(),
                        shared.drain.as_secs()
                    );
                }
            }
            _ = tokio::time::sleep_until(drain_until), if finished => {
                anyhow::bail!(
                    "{} strokes and {} batches still unacknowledged {} s after the end",
                    pen_ups.len(),
                    unacked.values().map(|u| u.batches.len()).sum::<usize>(),
                    shared.drain.as_secs()
                );
            }
            _ = tokio::time::sleep_until(shared.deadline), if shared.idle && !finished => {}
        }
    }
}

/// Sums `n_points` (and counts `done` strokes) over the run's sessions, 16 requests at a time.
async fn count_stored(
    http: &reqwest::Client,
    base: &str,
    sessions: &[SessionReply],
) -> anyhow::Result<(u64, u64)> {
    let mut points = 0;
    let mut done = 0;
    for chunk in sessions.chunks(16) {
        let replies = futures_util::future::join_all(chunk.iter().map(|s| async move {
            let url = format!("{base}/v1/sessions/{}/strokes", s.session);
            let rows: StrokeRows = http
                .get(&url)
                .bearer_auth(&s.token)
                .send()
                .await
                .and_then(|r| r.error_for_status())
                .with_context(|| format!("cannot count the stored samples: GET {url}"))?
                .json()
                .await
                .with_context(|| format!("GET {url}: not a stroke list"))?;
            anyhow::Ok(rows)
        }))
        .await;
        for rows in replies {
            for row in rows?.strokes {
                points += row.n_points;
                done += u64::from(row.status == "done");
            }
        }
    }
    Ok((points, done))
}

fn progress_line() -> ProgressBar {
    let bar = ProgressBar::new_spinner().with_style(
        ProgressStyle::with_template("{spinner} {elapsed} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.enable_steady_tick(Duration::from_millis(250));
    bar
}

/// User plus system CPU time of a process, seconds (Linux clock ticks are 1/100 s).
fn read_cpu_seconds(pid: u32) -> f64 {
    let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else { return 0.0 };
    // The command name may hold spaces; the fields after its closing parenthesis do not.
    let Some(rest) = stat.rfind(')').map(|i| &stat[i + 1..]) else { return 0.0 };
    let fields: Vec<&str> = rest.split_whitespace().collect();
    // After the name: state is field 3 of the file, utime 14 and stime 15.
    let tick = |k: usize| fields.get(k).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (tick(11) + tick(12)) / 100.0
}

/// Resident memory now and at its peak (VmRSS, VmHWM), KB.
fn read_memory(pid: u32) -> (u64, u64) {
    let Ok(status) = std::fs::read_to_string(format!("/proc/{pid}/status")) else { return (0, 0) };
    let field = |name: &str| {
        status
            .lines()
            .find_map(|l| l.strip_prefix(name))
            .and_then(|v| v.split_whitespace().next())
            .and_then(|v| v.parse().ok())
            .unwrap_or(0)
    };
    (field("VmRSS:"), field("VmHWM:"))
}

fn read_loadavg() -> Option<String> {
    std::fs::read_to_string("/proc/loadavg").ok().map(|s| s.trim().to_string())
}

fn print_table(s: &Summary) {
    let lat = &s.latency_ms;
    println!("target            {} at {}", s.target, s.url);
    println!(
        "pens              {} connected, {} failed, {} dropped",
        s.connections.made, s.connections.failed, s.connections.dropped
    );
    println!(
        "samples           sent {}, acknowledged {}, stored {}, lost {}",
        s.samples.sent,
        s.samples.acknowledged,
        s.samples.stored.map_or("-".into(), |v| v.to_string()),
        s.samples.lost.map_or("-".into(), |v| v.to_string()),
    );
    println!("strokes           begun {}, done {}", s.strokes.begun, s.strokes.done);
    println!(
        "throughput        {:.0} samples/s acknowledged ({:.0} sent, {:.0} offered) over {:.1} s",
        s.throughput.acked_per_s,
        s.throughput.sent_per_s,
        s.throughput.offered_per_s,
        s.throughput.window_s
    );
    for (name, p) in
        [("sample -> Ack", &lat.sample_to_ack), ("pen-up -> Done", &lat.pen_up_to_stroke_done)]
    {
        println!(
            "{name:<18}p50 {:.2} ms, p95 {:.2} ms, p99 {:.2} ms, max {:.2} ms ({} measured)",
            p.p50, p.p95, p.p99, p.max, p.count
        );
    }
    if let Some(server) = &s.server {
        println!(
            "server            {:.0} % of a core, {:.1} CPU s, RSS {} KB before, {} KB connected, peak {} KB{}",
            server.cpu_percent,
            server.cpu_seconds,
            server.rss_before_kb,
            server.rss_connected_kb,
            server.peak_rss_kb,
            server
                .kb_per_connection
                .map_or(String::new(), |kb| format!(", {kb:.1} KB per connection")),
        );
    }
    println!(
        "load tool         {:.0} % of a core, peak RSS {} KB",
        s.load_tool.cpu_percent, s.load_tool.peak_rss_kb
    );
    println!(
        "machine           {} cores, load average {} before, {} after",
        s.machine.cores,
        s.machine.loadavg_before.as_deref().unwrap_or("?"),
        s.machine.loadavg_after.as_deref().unwrap_or("?")
    );
    if s.errors.count > 0 {
        println!("errors            {}: {}", s.errors.count, s.errors.first.join("; "));
    }
}

/// `penmesh serve-proxy` (hidden): the proxy, the same code as the `penmesh-proxy` binary,
/// so that `penmesh load --spawn-proxy` needs nothing but this program.
#[derive(Debug, Args)]
pub struct ServeProxyArgs {
    /// The proxy's own flags (see `penmesh-proxy --help`).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub args: Vec<String>,
}

pub fn serve_proxy(args: &ServeProxyArgs) -> anyhow::Result<()> {
    let config = penmesh_proxy::Config::load_from(
        std::iter::once("penmesh-proxy".to_string()).chain(args.args.iter().cloned()),
    )?;
    penmesh_proxy::init_tracing();
    penmesh_proxy::run(config)
}

/// `penmesh load-report` (hidden): the tables and plots of `docs/performance.md` from the JSON
/// summaries of several runs (a sweep of client counts, against the proxy and the ceiling).
#[derive(Debug, Args)]
pub struct LoadReportArgs {
    /// Summaries written by `penmesh load --json`.
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
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            serde_json::from_str(&text)
                .with_context(|| format!("{}: not a penmesh load summary", path.display()))
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
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("cannot create {}", args.out_dir.display()))?;
    let series = |target: &str, value: fn(&Summary) -> f64| -> Vec<(f64, f64)> {
        runs.iter()
            .filter(|r| r.target == target)
            .map(|r| ((r.connections.made + r.connections.failed) as f64, value(r)))
            .collect()
    };
    let throughput = [
        ("proxy, acknowledged", series("proxy", |r| r.throughput.acked_per_s)),
        ("ceiling, acknowledged", series("ceiling", |r| r.throughput.acked_per_s)),
        ("offered (pens × rate)", series("proxy", |r| r.throughput.offered_per_s)),
    ];
    plot(
        &args.out_dir.join("load_throughput.svg"),
        "Throughput against pens (200 Hz each)",
        "samples per second",
        &throughput,
        false,
    )
    .map_err(|e| anyhow::anyhow!("cannot draw the throughput plot: {e}"))?;
    let p99 = [
        ("proxy, sample → Ack", series("proxy", |r| r.latency_ms.sample_to_ack.p99)),
        ("proxy, pen-up → StrokeDone", series("proxy", |r| r.latency_ms.pen_up_to_stroke_done.p99)),
        ("ceiling, sample → Ack", series("ceiling", |r| r.latency_ms.sample_to_ack.p99)),
    ];
    plot(
        &args.out_dir.join("load_p99.svg"),
        "p99 latency against pens",
        "p99, ms (log)",
        &p99,
        true,
    )
    .map_err(|e| anyhow::anyhow!("cannot draw the latency plot: {e}"))?;
    Ok(())
}

fn plot(
    path: &Path,
    caption: &str,
    y_label: &str,
    series: &[(&str, Vec<(f64, f64)>)],
    log_y: bool,
) -> Result<(), Box<dyn std::error::Error>> {
    use plotters::prelude::*;
    let points = series.iter().flat_map(|(_, s)| s.iter());
    let x_max = points.clone().map(|p| p.0).fold(1.0, f64::max) * 1.05;
    let y_max = points.map(|p| p.1).fold(1.0, f64::max) * 1.1;
    let root = SVGBackend::new(path, (800, 520)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(caption, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70);
    if log_y {
        let mut chart = builder.build_cartesian_2d(0.0..x_max, (0.5..y_max).log_scale())?;
        chart.configure_mesh().x_desc("concurrent pens").y_desc(y_label).draw()?;
        draw_lines(&mut chart, series)?;
    } else {
        let mut chart = builder.build_cartesian_2d(0.0..x_max, 0.0..y_max)?;
        chart.configure_mesh().x_desc("concurrent pens").y_desc(y_label).draw()?;
        draw_lines(&mut chart, series)?;
    }
    root.present()?;
    Ok(())
}

fn draw_lines<'a, X, Y>(
    chart: &mut plotters::chart::ChartContext<
        'a,
        plotters::backend::SVGBackend<'a>,
        plotters::coord::cartesian::Cartesian2d<X, Y>,
    >,
    series: &[(&str, Vec<(f64, f64)>)],
) -> Result<(), Box<dyn std::error::Error>>
where
    X: plotters::coord::ranged1d::Ranged<ValueType = f64>,
    Y: plotters::coord::ranged1d::Ranged<ValueType = f64>,
{
    use plotters::prelude::*;
    const COLOURS: [RGBColor; 3] =
        [RGBColor(0, 114, 178), RGBColor(213, 94, 0), RGBColor(120, 120, 120)];
    for (k, (name, points)) in series.iter().enumerate() {
        if points.is_empty() {
            continue;
        }
        let colour = COLOURS[k % COLOURS.len()];
        chart
            .draw_series(LineSeries::new(points.clone(), colour.stroke_width(2)))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
        chart.draw_series(points.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperLeft)
        .draw()?;
    Ok(())
}
