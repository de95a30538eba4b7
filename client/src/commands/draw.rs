//! `penmesh draw`: one person draws into a proxy session, live.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use penmesh::{Brush, GeneratorParams};
use serde::Serialize;

use crate::commands::args::{GeneratorArgs, GlbArg};
use crate::draw_options::DrawOptions;
use crate::endpoint::Endpoint;
use crate::input::{AxisRanges, EvdevSource, Pacing, PenSource, ReplaySource};
use crate::live;
use crate::reconstruct::StrokeReport;
use crate::report::{self, Totals};

/// Settings of the live path shared by `draw` and `demo`.
#[derive(Debug, Clone, Args)]
pub struct LiveArgs {
    /// Send what the resampler kept at least every this many milliseconds.
    #[arg(long, default_value_t = crate::draw_options::DEFAULT_BATCH_MS)]
    pub batch_ms: u64,
    /// Send as soon as this many kept samples wait.
    #[arg(long, default_value_t = crate::draw_options::DEFAULT_BATCH_SAMPLES)]
    pub batch_size: usize,
    /// Keep trying to reach the proxy (at start, or after a lost connection) and to fetch and
    /// store each stroke's mesh this many seconds without progress.
    #[arg(long, default_value_t = crate::draw_options::DEFAULT_RETRY_SECS)]
    pub retry_for: u64,
    /// Stage-1 chord-length resampling distance l_eps (px); 0 streams every sample but the
    /// repeats (see --keep-repeats).
    #[arg(long, default_value_t = penmesh::DEFAULT_RESAMPLE_DISTANCE)]
    pub resample: f64,
    /// Stream exact repeats too. By default stage 1 does not send a sample equal in x, y and
    /// pressure to the last one it sent (a pen at rest), which costs no error.
    #[arg(long)]
    pub keep_repeats: bool,
    /// Brush size E (px): the radius at full pressure with a pressure response of 1.
    #[arg(long, default_value_t = penmesh::Brush::DEFAULT_SIZE)]
    pub brush_size: f64,
    /// Pressure response chi in [0, 1].
    #[arg(long, default_value_t = penmesh::Brush::DEFAULT_PRESSURE_RESPONSE)]
    pub pressure_response: f64,
    /// How each stroke's GLB is written and uploaded: compressed (the default; three.js
    /// decodes it with its MeshoptDecoder), quantised only, or plain floats for tools that
    /// decode neither.
    #[arg(long, value_enum, default_value_t = GlbArg::default())]
    pub glb: GlbArg,
    /// Print exactly one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Log what happens to stderr (-v: info, -vv: debug).
    #[arg(short, long, action = clap::ArgAction::Count)]
    pub verbose: u8,
}

#[derive(Debug, Clone, Args)]
#[command(group(clap::ArgGroup::new("source").args(["input", "synth", "device"])))]
#[command(group(
    clap::ArgGroup::new("draw_or_watch").required(true).multiple(true)
        .args(["input", "synth", "device", "watch"])
))]
pub struct DrawArgs {
    #[command(flatten)]
    pub connection: crate::commands::args::ConnectionArgs,
    /// Replay the strokes of a file: CSV (x,y,t,p), JSON, SVC2004 .txt or SigComp2011 .hwr.
    #[arg(long, value_name = "FILE")]
    pub input: Option<PathBuf>,
    /// Draw generated strokes: figure8, semicircles, chromosome, leaf or scribble.
    #[arg(long, value_name = "SHAPE")]
    pub synth: Option<penmesh::Shape>,
    /// Read a tablet through evdev, e.g. /dev/input/event5 (or a recorded event file).
    #[arg(long, value_name = "PATH")]
    pub device: Option<PathBuf>,
    /// Replay at the recorded pace instead of as fast as possible (files and synth).
    #[arg(long)]
    pub realtime: bool,
    /// Write each stroke's GLB into this folder.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Your name in the session.
    #[arg(long, default_value = "penmesh")]
    pub name: String,
    /// Synth: how many strokes to draw (seeds SEED, SEED+1, ...).
    #[arg(long, default_value_t = 1)]
    pub count: u32,
    #[command(flatten)]
    pub generator: GeneratorArgs,
    /// evdev: ABS_X range MIN:MAX (read from the device when absent).
    #[arg(long, value_name = "MIN:MAX", value_parser = crate::input::AxisRange::parse)]
    pub abs_x: Option<crate::input::AxisRange>,
    /// evdev: ABS_Y range MIN:MAX (read from the device when absent).
    #[arg(long, value_name = "MIN:MAX", value_parser = crate::input::AxisRange::parse)]
    pub abs_y: Option<crate::input::AxisRange>,
    /// evdev: ABS_PRESSURE range MIN:MAX (read from the device when absent).
    #[arg(long, value_name = "MIN:MAX", value_parser = crate::input::AxisRange::parse)]
    pub abs_pressure: Option<crate::input::AxisRange>,
    /// evdev: pixels spanned by the tablet's width (y uses the same scale).
    #[arg(long, default_value_t = 1920.0)]
    pub canvas_width: f64,
    /// Print what the others in the session draw, and write their meshes' GLBs into --out.
    /// Without --input, --synth or --device: watch only, until Ctrl-C.
    #[arg(long)]
    pub watch: bool,
    /// Draw onto this work plane: its placement in the session's 3D space, 16 numbers
    /// m0,m1,…,m15 (glTF node.matrix, column-major; a similarity with scale in [1/1000, 1000]).
    /// Default: the board (the identity). E.g. the front plane standing on the board:
    /// 1,0,0,0,0,0,1,0,0,-1,0,0,0,0,0,1.
    #[arg(long, value_name = "M0,…,M15", value_parser = parse_placement, allow_hyphen_values = true)]
    pub placement: Option<Box<penmesh::Placement>>,
    /// What each stroke becomes: `line` (its ink: the pressure-width rod, or with --depth a
    /// wall that tall), `filled` (the region a closed stroke encloses, one plate --depth deep)
    /// or `hole` (cut out of what it overlaps in the print). Set after each stroke is done
    /// (`PUT /v1/strokes/{id}/solid`); an open stroke filled is refused, naming its gap.
    #[arg(long, value_name = "KIND", value_parser = ["line", "filled", "hole"])]
    pub solid: Option<String>,
    /// The solid's depth, px of the stroke's plane ([0.125, 10000]); needed by filled and hole.
    #[arg(long, value_name = "PX", allow_hyphen_values = true)]
    pub depth: Option<f64>,
    #[command(flatten)]
    pub live: LiveArgs,
}

/// The solid `--solid` and `--depth` ask for (the rod when neither is given): refused, naming
/// what is wrong, before anything is drawn.
fn solid(args: &DrawArgs) -> anyhow::Result<penmesh::Solid> {
    let kind = match &args.solid {
        Some(name) => penmesh::SolidKind::parse(name)?,
        None => penmesh::SolidKind::Line,
    };
    penmesh::Solid::new(kind, args.depth).map_err(|e| anyhow::anyhow!("--solid/--depth: {e}"))
}

fn parse_placement(text: &str) -> Result<Box<penmesh::Placement>, String> {
    penmesh::Placement::parse_list(text).map(Box::new)
}

pub fn run(args: &DrawArgs) -> anyhow::Result<()> {
    init_tracing(args.live.verbose);
    let endpoint = args.connection.endpoint()?;
    if args.watch && args.input.is_none() && args.synth.is_none() && args.device.is_none() {
        return watch_only(args, &endpoint);
    }
    let mut options = draw_options(&args.live, &args.name)?;
    options.placement = args.placement.as_deref().copied();
    options.solid = solid(args)?;
    // Bad input fails here, before anything touches the network.
    let source = source(args)?;
    if let Some(dir) = &args.out {
        fs_err::create_dir_all(dir)?;
        options.out_dir = Some(dir.clone());
    }
    let progress = (!args.live.json).then(|| progress_bar(source.total_samples(), &args.name));
    options.progress = progress.clone();

    let runtime = runtime()?;
    let reports = runtime.block_on(async {
        options.interrupts = Some(interrupts());
        let watcher = args.watch.then(|| tokio::spawn(watch(args.clone(), endpoint.clone(), true)));
        let reports = live::draw(&endpoint, source, &options).await;
        if let Some(watcher) = watcher {
            watcher.abort();
        }
        reports
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
        let params: Vec<GeneratorParams> =
            (0..u64::from(args.count)).map(|i| args.generator.params(shape, i)).collect();
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
    fs_err::File::open(path)?;
    let ranges = AxisRanges { x, y, pressure, canvas_width: args.canvas_width };
    Ok(Box::new(EvdevSource::new(path.clone(), name, ranges)))
}

/// The live settings of `draw` and `demo`, checked.
pub fn draw_options(live: &LiveArgs, name: &str) -> anyhow::Result<DrawOptions> {
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
    penmesh::protocol::check_text(name, penmesh::protocol::MAX_NAME_CHARS)
        .map_err(|why| anyhow::anyhow!("--name {why}"))?;
    Ok(DrawOptions {
        brush,
        resample: live.resample,
        drop_repeats: !live.keep_repeats,
        batch_interval: Duration::from_millis(live.batch_ms),
        batch_samples: live.batch_size,
        retry_for: Duration::from_secs(live.retry_for),
        glb: live.glb.into(),
        ..DrawOptions::new(name)
    })
}

/// A bar for a replay of known length, a spinner otherwise; hidden when stderr is no terminal.
pub fn progress_bar(total: Option<u64>, name: &str) -> ProgressBar {
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

pub fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread().enable_all().build().context("starting the runtime")
}

/// Logs to stderr: warnings by default, `-v` info, `-vv` debug; `RUST_LOG` wins.
pub fn init_tracing(verbose: u8) {
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

/// `--watch` alone: prints the session until Ctrl-C.
fn watch_only(args: &DrawArgs, endpoint: &Endpoint) -> anyhow::Result<()> {
    if let Some(dir) = &args.out {
        fs_err::create_dir_all(dir)?;
    }
    let runtime = runtime()?;
    let result = runtime.block_on(async {
        tokio::select! {
            result = watch(args.clone(), endpoint.clone(), false) => result,
            _ = tokio::signal::ctrl_c() => Ok(()),
        }
    });
    runtime.shutdown_timeout(Duration::from_millis(100));
    result
}

/// Joins the session as a watcher: prints the others' presence and strokes (one JSON message
/// a line with `--json`) and writes each mesh they store into `--out` as `STROKE.glb`. The
/// history comes first, up to the proxy's `synced`, then the live events. While this client
/// draws too (`drawing`), the strokes of participants named `--name` are its own: not repeated.
async fn watch(args: DrawArgs, endpoint: Endpoint, drawing: bool) -> anyhow::Result<()> {
    use futures_util::{SinkExt, StreamExt};
    use penmesh::protocol::{
        ClientMessage, ErrorCode, Hello, PROTOCOL_VERSION, ServerMessage, decode_server,
        encode_client, encode_server_json,
    };
    use tokio_tungstenite::tungstenite::Message;
    use tokio_tungstenite::tungstenite::client::IntoClientRequest;

    let url = endpoint.ws_url();
    let mut request = url.as_str().into_client_request().context("bad server URL")?;
    let bearer = format!("Bearer {}", endpoint.token).parse().context("the token")?;
    request.headers_mut().insert("authorization", bearer);
    let (mut ws, _) = tokio_tungstenite::connect_async(request)
        .await
        .with_context(|| format!("cannot connect to {url}"))?;
    let hello = ClientMessage::Hello(Hello {
        protocol: PROTOCOL_VERSION,
        client: format!("penmesh-watch {}", env!("CARGO_PKG_VERSION")),
        name: Some(format!("{} (watching)", args.name)),
        resume: vec![],
        // A watcher resumes and stores nothing: no key, an identity of its own.
        key: None,
    });
    ws.send(Message::Binary(encode_client(&hello).into())).await.context("sending hello")?;
    let http = reqwest::Client::new();
    let mut names = std::collections::HashMap::new();
    let mut mine = std::collections::HashSet::new();
    let short = |id: uuid::Uuid| id.to_string()[..8].to_string();
    while let Some(frame) = ws.next().await {
        let bytes = match frame.context("reading from the proxy")? {
            Message::Binary(bytes) => bytes,
            Message::Close(_) => break,
            _ => continue,
        };
        let msg = decode_server(&bytes, usize::MAX).context("a message from the proxy")?;
        // A history's strokes come several to a message: each as its own events would.
        let msgs = match msg {
            ServerMessage::PeerStrokes(strokes) => strokes.messages(),
            msg => vec![msg],
        };
        for msg in msgs {
            if let ServerMessage::PeerJoined(j) = &msg
                && drawing
                && j.name == args.name
            {
                mine.insert(j.participant);
            }
            let participant = match &msg {
                ServerMessage::PeerStrokeBegin(m) => Some(m.participant),
                ServerMessage::PeerStrokeDone(m) => Some(m.participant),
                ServerMessage::PeerMesh(m) => Some(m.participant),
                ServerMessage::StrokeRemoved(m) | ServerMessage::StrokeRestored(m) => {
                    Some(m.participant)
                }
                ServerMessage::PeerPlacement(m) => Some(m.participant),
                ServerMessage::PeerSolid(m) => Some(m.participant),
                _ => None,
            };
            if participant.is_some_and(|p| mine.contains(&p)) {
                continue;
            }
            if args.live.json && !matches!(msg, ServerMessage::PeerRetained(_)) {
                println!("{}", encode_server_json(&msg));
            }
            let who = |names: &std::collections::HashMap<uuid::Uuid, String>, id| {
                names.get(&id).cloned().unwrap_or_else(|| short(id))
            };
            let line = match &msg {
                ServerMessage::PeerJoined(j) => {
                    names.insert(j.participant, j.name.clone());
                    Some(format!("+ {} joined", j.name))
                }
                ServerMessage::PeerLeft(l) => {
                    Some(format!("- {} left", who(&names, l.participant)))
                }
                ServerMessage::PeerStrokeBegin(b) => {
                    Some(format!("{} draws stroke {}", who(&names, b.participant), short(b.stroke)))
                }
                ServerMessage::PeerStrokeDone(d) => Some(format!(
                    "{} finished stroke {}: {} retained samples",
                    who(&names, d.participant),
                    short(d.stroke),
                    d.n_retained
                )),
                ServerMessage::PeerMesh(m) => {
                    let glb = http
                        .get(endpoint.url(&m.url))
                        .bearer_auth(&endpoint.token)
                        .send()
                        .await
                        .and_then(|r| r.error_for_status())
                        .with_context(|| format!("fetching {}", m.url))?
                        .bytes()
                        .await?;
                    let saved = match &args.out {
                        Some(dir) => {
                            let path = dir.join(format!("{}.glb", m.stroke));
                            fs_err::write(&path, &glb)?;
                            format!(" -> {}", path.display())
                        }
                        None => String::new(),
                    };
                    Some(format!(
                        "{}'s mesh of stroke {}: {} bytes{saved}",
                        who(&names, m.participant),
                        short(m.stroke),
                        glb.len()
                    ))
                }
                // A stroke taken back (undo, the eraser) stays stored; its mesh file is left as is.
                ServerMessage::StrokeRemoved(r) => {
                    Some(format!("{} took back stroke {}", who(&names, r.by), short(r.stroke)))
                }
                ServerMessage::StrokeRestored(r) => {
                    Some(format!("{} brought back stroke {}", who(&names, r.by), short(r.stroke)))
                }
                ServerMessage::PeerPlacement(p) => {
                    let matrix: Vec<String> =
                        p.placement.matrix().iter().map(|v| format!("{v:?}")).collect();
                    Some(format!(
                        "{} placed stroke {} at {}{}",
                        who(&names, p.participant),
                        short(p.stroke),
                        matrix.join(","),
                        if p.placement.is_mirror() { " (mirrored)" } else { "" }
                    ))
                }
                ServerMessage::PeerSolid(s) => Some(format!(
                    "{} made stroke {} {}",
                    who(&names, s.participant),
                    short(s.stroke),
                    s.solid
                )),
                ServerMessage::Synced(s) => Some(format!(
                    "-- up to date: {} strokes by the others; live from here --",
                    s.n_strokes
                )),
                ServerMessage::Error(e) if e.code == ErrorCode::Lagged => {
                    Some("-- fell behind the session; catching up from storage --".to_string())
                }
                ServerMessage::Error(e) => {
                    anyhow::bail!("the proxy refused: {}: {}", e.code.as_str(), e.message)
                }
                _ => None,
            };
            if let (Some(line), false) = (line, args.live.json) {
                println!("{line}");
            }
        }
    }
    Ok(())
}
