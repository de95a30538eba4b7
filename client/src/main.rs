//! `penmesh`: the command-line client. Parsing lives here; the work lives in the library.

use std::process::ExitCode;

use clap::Parser;
use penmesh_client::cli::Cli;

/// mimalloc rather than the system allocator: the proxy (`penmesh serve-proxy`) allocates and
/// frees a few small buffers per batch across its threads, which glibc's allocator did at
/// about 8 % of the proxy's CPU under load (docs/performance.md). The no-op ceiling, in this
/// binary too, gets the same allocator, so comparisons stay fair.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(err) => return penmesh_client::cli::report_parse_error(err),
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
