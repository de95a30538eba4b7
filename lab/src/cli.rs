//! The lab's command line: one clap definition per subcommand, dispatched to `commands`.

use clap::{Parser, Subcommand};

use crate::commands;

#[derive(Debug, Parser)]
#[command(
    name = "penmesh-lab",
    version,
    about = "The penmesh lab: the whole system in one command, load, evaluation"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Start a proxy in process and let simulated people draw at once through the real path.
    Demo(commands::demo::DemoArgs),
    /// Evaluate ACUTS against the baselines and optimal min-#: tables, sweeps, plots.
    Eval(commands::eval::EvalArgs),
    /// Screened Poisson: PoissonRecon (the mesher) against the old pure-Rust crate, same clouds.
    PoissonBench(commands::eval::poisson_bench::PoissonBenchArgs),
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

/// Runs the parsed command.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Demo(args) => commands::demo::run(&args),
        Command::Eval(args) => commands::eval::run(&args),
        Command::PoissonBench(args) => commands::eval::poisson_bench::run(&args),
        Command::Load(args) => commands::load::run(&args),
        Command::Ceiling(args) => commands::ceiling::run(&args),
        Command::ServeProxy(args) => commands::demo::serve_proxy(&args),
        Command::Peers(args) => commands::peers::run(&args),
        Command::LoadReport(args) => commands::load::report(&args),
    }
}
