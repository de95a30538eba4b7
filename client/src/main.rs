//! `penmesh`: the command-line client. Parsing lives here; the work lives in the library.

use std::process::ExitCode;

use clap::Parser;
use penmesh_client::cli::Cli;

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(err) => return penmesh_client::cli::report_parse_error(err, "penmesh"),
    };
    match penmesh_client::cli::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            // One clear line: the whole context chain, no backtrace.
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}
