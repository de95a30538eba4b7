//! The penmesh client: the CLI's commands, input sources, live streaming and reconstruction.
//!
//! File and network I/O happen here; the algorithms come from the pure `penmesh` crate.

pub mod cli;
mod commands;
pub mod input;
mod io;
pub mod live;
pub mod reconstruct;
pub mod report;
