//! `penmesh-lab`: the lab's command line. Parsing lives here; the work lives in the library.

use std::process::ExitCode;

use clap::Parser;
use penmesh_lab::cli::Cli;

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(err) => return penmesh_client::cli::report_parse_error(err, "penmesh-lab"),
    };
    match penmesh_lab::cli::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            // One clear line: the whole context chain, no backtrace.
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}
