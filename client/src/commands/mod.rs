//! One module per CLI subcommand.

pub mod args;
pub mod draw;
pub mod export;
pub mod import;
pub mod mesh;
pub mod simplify;
pub mod synth;
