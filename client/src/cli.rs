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
    Simplify(commands::simplify::SimplifyArgs),
    /// Simplify, build the LRPDP solid mesh and write it as binary glTF.
    Mesh(MeshArgs),
    /// Generate a stroke like a person draws on a tablet and write it as CSV or JSON.
    Synth(commands::synth::SynthArgs),
    /// Evaluate ACUTS against the baselines and optimal min-#: tables, sweeps, plots.
    Eval(commands::eval::EvalArgs),
    /// Draw into a proxy session live: resample, stream, reconstruct, upload the meshes.
    Draw(commands::draw::DrawArgs),
    /// Start a proxy in process and let simulated people draw at once through the real path.
    Demo(DemoArgs),
    /// Load a proxy on this machine with many simulated pens; throughput, latency, lost samples.
    Load(commands::load::LoadArgs),
    /// The ceiling server for `load`: decode and ack only, on the proxy's stack.
    #[command(hide = true)]
    Ceiling(commands::ceiling::CeilingArgs),
    /// The proxy itself, for `load --spawn-proxy` (the flags of `penmesh-proxy`).
    #[command(hide = true)]
    ServeProxy(commands::demo::ServeProxyArgs),
    /// Time LRPDP and ACUTS against perfect-freehand and simplify-js (see bench/run.sh).
    #[command(hide = true)]
    Peers(commands::peers::PeersArgs),
    /// Tables and plots from `load --json` summaries.
    #[command(hide = true)]
    LoadReport(commands::load::LoadReportArgs),
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
    pub acuts: crate::commands::args::AcutsArgs,
}

/// `penmesh mesh --centreline`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CentrelineKind {
    Smooth,
    Straight,
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
    pub live: crate::commands::draw::LiveArgs,
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
        Command::ServeProxy(args) => commands::demo::serve_proxy(&args),
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
