//! The penmesh client: the CLI's commands, input sources, live streaming and reconstruction.
//!
//! File and network I/O happen here; the algorithms come from the pure `penmesh` crate.

pub mod api;
mod backoff;
pub mod cli;
pub mod commands;
pub mod draw_options;
pub mod endpoint;
pub mod input;
pub mod io;
pub mod live;
pub mod mesh_distance;
pub mod poisson;
pub mod reconstruct;
pub mod report;
pub mod wire;
