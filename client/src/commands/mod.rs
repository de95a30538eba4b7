//! One module per CLI subcommand.

pub mod args;
pub mod ceiling;
pub mod demo;
pub mod draw;
pub mod eval;
pub mod load;
pub mod mesh;
pub mod peers;
pub mod simplify;
pub mod synth;
