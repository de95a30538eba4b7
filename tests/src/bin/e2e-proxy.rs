//! The proxy binary for the fault tests (`tests/tests/faults`): the same `main` as
//! `proxy/src/main.rs`, built with this crate so that Cargo hands its path to the tests
//! (`CARGO_BIN_EXE_e2e-proxy`), which run it as a child process they can kill.

use penmesh_proxy::Config;

fn main() -> anyhow::Result<()> {
    penmesh_proxy::init_tracing();
    penmesh_proxy::run(Config::load()?)
}
