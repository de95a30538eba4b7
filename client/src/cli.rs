//! The command line: one clap definition per subcommand, dispatched to `commands`.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

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
    Mesh(commands::mesh::MeshArgs),
    /// Generate a stroke like a person draws on a tablet and write it as CSV or JSON.
    Synth(commands::synth::SynthArgs),
    /// Draw into a proxy session live: resample, stream, reconstruct, upload the meshes.
    Draw(commands::draw::DrawArgs),
    /// Take a session's model out: the scene as GLB, or the print as STL or 3MF.
    Export(commands::export::ExportArgs),
    /// Bring a GLB penmesh exported back into a session (all strokes or none).
    Import(commands::import::ImportArgs),
}

/// Runs the parsed command.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Simplify(args) => commands::simplify::run(&args),
        Command::Mesh(args) => commands::mesh::run(&args),
        Command::Synth(args) => commands::synth::run(&args),
        Command::Draw(args) => commands::draw::run(&args),
        Command::Export(args) => commands::export::run(&args),
        Command::Import(args) => commands::import::run(&args),
    }
}

/// Prints a command-line mistake of `program` (`penmesh`, or the lab's `penmesh-lab`) as one
/// line (help and version print as usual).
pub fn report_parse_error(err: clap::Error, program: &str) -> ExitCode {
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
            eprintln!("{line} (see '{program} --help')");
            ExitCode::from(2)
        }
    }
}
