//! One module per CLI subcommand.

pub mod mesh;
pub mod simplify;
pub mod synth;
