//! One module per CLI subcommand.

pub mod demo;
pub mod draw;
pub mod eval;
pub mod mesh;
pub mod simplify;
pub mod synth;
