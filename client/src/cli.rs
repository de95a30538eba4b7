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
    /// Pressure-variance threshold d_sigma2 (pressure in [0, 1]).
    #[arg(long = "pressure-var", default_value_t = penmesh::DEFAULT_PRESSURE_VARIANCE)]
    pub pressure_var: f64,
    /// Stage-1 chord-length resampling distance l_eps; 0 turns resampling off.
    #[arg(long, default_value_t = penmesh::DEFAULT_RESAMPLE_DISTANCE)]
    pub resample: f64,
}

impl AcutsArgs {
    pub fn params(&self) -> anyhow::Result<penmesh::AcutsParams> {
        let params = penmesh::AcutsParams {
            tolerance: self.tolerance,
            angle_deg: self.angle,
            pressure_variance: self.pressure_var,
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
    #[command(flatten)]
    pub acuts: AcutsArgs,
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

/// Runs the parsed command.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Simplify(args) => commands::simplify::run(&args),
        Command::Mesh(args) => commands::mesh::run(&args),
        Command::Synth(args) => commands::synth::run(&args),
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
            let first = rendered.lines().next().unwrap_or("error: bad command line");
            eprintln!("{first} (see 'penmesh --help')");
            ExitCode::from(2)
        }
    }
}
