//! The penmesh lab: the measurements and the demonstration, apart from the user's CLI.
//!
//! `penmesh-lab` runs the proxy in process (`demo`, `serve-proxy`), drives it under load
//! (`load`, `ceiling`, `load-report`), and evaluates the algorithms (`eval`, `peers`). It builds
//! on the client's library (`penmesh_client`: the live path, reconstruction, the meshers) and on
//! the proxy (`penmesh_proxy`), so that the user's CLI, `penmesh`, does not link the server.

pub mod cli;
mod commands;
mod plot;
