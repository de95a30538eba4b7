//! The command line: one clap definition per subcommand, dispatched to `commands`.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};

use crate::commands;

#[derive(Debug, Parser)]
#[command(name = "penmesh", version, about = "Pressure-pen strokes to light 3D stroke meshes")]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Simplify the strokes of a file with ACUTS and report what was kept.
    Simplify(SimplifyArgs),
    /// Simplify, build the LRPDP solid mesh and write it as binary glTF.
    Mesh(MeshArgs),
    /// Generate a stroke like a person draws on a tablet and write it as CSV or JSON.
    Synth(SynthArgs),
    /// Evaluate ACUTS against the baselines and optimal min-#: tables, sweeps, plots.
    Eval(commands::eval::EvalArgs),
    /// Draw into a proxy session live: resample, stream, reconstruct, upload the meshes.
    Draw(DrawArgs),
    /// Start a proxy in process and let simulated people draw at once through the real path.
    Demo(DemoArgs),
    /// Load a proxy on this machine with many simulated pens; throughput, latency, lost samples.
    Load(commands::load::LoadArgs),
    /// The ceiling server for `load`: decode and ack only, on the proxy's stack.
    #[command(hide = true)]
    Ceiling(commands::ceiling::CeilingArgs),
    /// The proxy itself, for `load --spawn-proxy` (the flags of `penmesh-proxy`).
    #[command(hide = true)]
    ServeProxy(commands::load::ServeProxyArgs),
    /// Time LRPDP and ACUTS against perfect-freehand and simplify-js (see bench/run.sh).
    #[command(hide = true)]
    Peers(commands::peers::PeersArgs),
    /// Tables and plots from `load --json` summaries.
    #[command(hide = true)]
    LoadReport(commands::load::LoadReportArgs),
}

/// ACUTS settings shared by the commands that simplify.
#[derive(Debug, Clone, Args)]
pub struct AcutsArgs {
    /// Chord-height tolerance d_d, in the stroke's unit.
    #[arg(long, default_value_t = penmesh::DEFAULT_TOLERANCE)]
    pub tolerance: f64,
    /// Angle threshold d_alpha, in degrees.
    #[arg(long, default_value_t = penmesh::DEFAULT_ANGLE_DEG)]
    pub angle: f64,
    /// Also ask the angle of skipped samples within d_d of the anchor (the paper's test).
    #[arg(long)]
    pub angle_near_anchor: bool,
    /// Pressure tolerance delta_p (pressure in [0, 1]): every removed sample's pressure within
    /// this of the pressure interpolated in time along its retained segment.
    #[arg(long, default_value_t = penmesh::DEFAULT_PRESSURE_TOLERANCE)]
    pub pressure_tolerance: f64,
    /// Use the paper's pressure-variance gate (formula 3) with this threshold d_sigma2 instead
    /// of the pressure tolerance (the paper: 0.0015).
    #[arg(long = "pressure-var", conflicts_with = "pressure_tolerance")]
    pub pressure_var: Option<f64>,
    /// Stage-1 chord-length resampling distance l_eps; 0 turns resampling off.
    #[arg(long, default_value_t = penmesh::DEFAULT_RESAMPLE_DISTANCE)]
    pub resample: f64,
}

/// The pressure gate the flags pick: `--pressure-var` if given, else `--pressure-tolerance`.
pub fn pressure_gate(tolerance: f64, variance: Option<f64>) -> penmesh::PressureGate {
    match variance {
        Some(v) => penmesh::PressureGate::Variance(v),
        None => penmesh::PressureGate::Interpolation(tolerance),
    }
}

impl AcutsArgs {
    pub fn params(&self) -> anyhow::Result<penmesh::AcutsParams> {
        let params = penmesh::AcutsParams {
            tolerance: self.tolerance,
            angle_deg: self.angle,
            angle_near_anchor: self.angle_near_anchor,
            pressure: pressure_gate(self.pressure_tolerance, self.pressure_var),
        };
        params.validate().map_err(|e| anyhow::anyhow!("bad ACUTS setting: {e}"))?;
        anyhow::ensure!(
            self.resample.is_finite() && self.resample >= 0.0,
            "bad ACUTS setting: resample = {} must be a finite number >= 0",
            self.resample
        );
        Ok(params)
    }
}

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

#[derive(Debug, Args)]
pub struct MeshArgs {
    /// Input file: CSV (x,y,t,p), JSON, SVC2004 .txt or SigComp2011 .hwr.
    pub input: PathBuf,
    /// The GLB to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Quantise positions (16-bit) and normals (8-bit) with KHR_mesh_quantization.
    #[arg(long)]
    pub quantize: bool,
    /// Also write the layered point cloud (the paper's Poisson input) as PLY.
    #[arg(long, value_name = "PATH")]
    pub ply: Option<PathBuf>,
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
    /// px, as `penmesh eval` does); tolerances and the brush stay in the scaled unit.
    #[arg(long)]
    pub px_per_unit: Option<f64>,
    /// Print one JSON object instead of the summary lines: the centreline of each stroke as
    /// [x, y, r], its raw samples as [x, y, p], sizes and parameters.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub acuts: AcutsArgs,
}

/// `penmesh mesh --centreline`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CentrelineKind {
    Smooth,
    Straight,
}

#[derive(Debug, Args)]
pub struct SynthArgs {
    /// The shape: figure8, semicircles, chromosome, leaf or scribble.
    pub shape: penmesh::Shape,
    /// Where to write the stroke; `.json` writes JSON, anything else CSV.
    #[arg(long)]
    pub out: PathBuf,
    /// Average pen speed, px/s (the paper's table 4 uses 200 to 500).
    #[arg(long, default_value_t = penmesh::DEFAULT_SPEED_PX_PER_S)]
    pub speed: f64,
    /// Longer side of the shape's bounding box, px.
    #[arg(long, default_value_t = penmesh::DEFAULT_SHAPE_SIZE_PX)]
    pub size: f64,
    /// Tablet sampling rate, Hz.
    #[arg(long, default_value_t = penmesh::DEFAULT_SAMPLE_RATE_HZ)]
    pub rate: f64,
    /// Seed of the hand's jitter and timing; the same seed gives the same stroke.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// Settings of the live path shared by `draw` and `demo`.
#[derive(Debug, Clone, Args)]
pub struct LiveArgs {
    /// Send what the resampler kept at least every this many milliseconds.
    #[arg(long, default_value_t = crate::live::DEFAULT_BATCH_MS)]
    pub batch_ms: u64,
    /// Send as soon as this many kept samples wait.
    #[arg(long, default_value_t = crate::live::DEFAULT_BATCH_SAMPLES)]
    pub batch_size: usize,
    /// After a lost connection, keep trying to resume this many seconds.
    #[arg(long, default_value_t = crate::live::DEFAULT_RETRY_SECS)]
    pub retry_for: u64,
    /// Stage-1 chord-length resampling distance l_eps (px); 0 streams every sample.
    #[arg(long, default_value_t = penmesh::DEFAULT_RESAMPLE_DISTANCE)]
    pub resample: f64,
    /// Brush size E (px): the radius at full pressure with a pressure response of 1.
    #[arg(long, default_value_t = penmesh::Brush::DEFAULT_SIZE)]
    pub brush_size: f64,
    /// Pressure response chi in [0, 1].
    #[arg(long, default_value_t = penmesh::Brush::DEFAULT_PRESSURE_RESPONSE)]
    pub pressure_response: f64,
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
    /// The proxy, e.g. http://127.0.0.1:8080.
    #[arg(long, env = "PENMESH_SERVER")]
    pub server: String,
    /// The session id (from POST /v1/sessions or `penmesh demo --keep-serving`).
    #[arg(long, env = "PENMESH_SESSION")]
    pub session: uuid::Uuid,
    /// The session's bearer token.
    #[arg(long, env = "PENMESH_TOKEN", hide_env_values = true)]
    pub token: String,
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
    /// Synth: average pen speed, px/s.
    #[arg(long, default_value_t = penmesh::DEFAULT_SPEED_PX_PER_S)]
    pub speed: f64,
    /// Synth: longer side of the shape's bounding box, px.
    #[arg(long, default_value_t = penmesh::DEFAULT_SHAPE_SIZE_PX)]
    pub size: f64,
    /// Synth: tablet sampling rate, Hz.
    #[arg(long, default_value_t = penmesh::DEFAULT_SAMPLE_RATE_HZ)]
    pub rate: f64,
    /// Synth: seed of the hand's jitter and timing.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
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
    #[command(flatten)]
    pub live: LiveArgs,
}

#[derive(Debug, Args)]
pub struct DemoArgs {
    /// The SQLite database file (created if missing). Default: a temporary one, removed on exit.
    #[arg(long, value_name = "PATH")]
    pub db: Option<PathBuf>,
    /// Where to write the GLB files.
    #[arg(long, value_name = "DIR", default_value = "penmesh-demo-out")]
    pub out: PathBuf,
    /// Draw as fast as possible instead of at the people's real pace.
    #[arg(long)]
    pub fast: bool,
    /// Leave the proxy up after the drawing, until Ctrl-C, so other clients can join.
    #[arg(long)]
    pub keep_serving: bool,
    /// How many simulated people draw at once (0 with --keep-serving: only serve).
    #[arg(long, default_value_t = 4)]
    pub people: usize,
    /// Address of the proxy.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// Port of the proxy (0 picks a free one).
    #[arg(long, default_value_t = 0)]
    pub port: u16,
    #[command(flatten)]
    pub live: LiveArgs,
}

/// Runs the parsed command.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Simplify(args) => commands::simplify::run(&args),
        Command::Mesh(args) => commands::mesh::run(&args),
        Command::Synth(args) => commands::synth::run(&args),
        Command::Eval(args) => commands::eval::run(&args),
        Command::Draw(args) => commands::draw::run(&args),
        Command::Demo(args) => commands::demo::run(&args),
        Command::Load(args) => commands::load::run(&args),
        Command::Ceiling(args) => commands::ceiling::run(&args),
        Command::ServeProxy(args) => commands::load::serve_proxy(&args),
        Command::Peers(args) => commands::peers::run(&args),
        Command::LoadReport(args) => commands::load::report(&args),
    }
}

/// Prints a command-line mistake as one line (help and version print as usual).
pub fn report_parse_error(err: clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    match err.kind() {
        ErrorKind::DisplayHelp
        | ErrorKind::DisplayVersion
        | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
            let _ = err.print();
            ExitCode::from(if err.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
                2
            } else {
                0
            })
        }
        _ => {
            let rendered = err.render().to_string();
            // Clap puts what is missing on the lines after the first: keep them on one line.
            let line = rendered
                .lines()
                .take_while(|l| !l.starts_with("Usage:"))
                .map(str::trim)
                .filter(|l| !l.is_empty() && !l.starts_with("tip:") && !l.starts_with("For more"))
                .collect::<Vec<_>>()
                .join(" ");
            let line = if line.is_empty() { "error: bad command line".to_string() } else { line };
            eprintln!("{line} (see 'penmesh --help')");
            ExitCode::from(2)
        }
    }
}
