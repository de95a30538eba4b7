//! One module per lab subcommand.

pub mod ceiling;
pub mod demo;
pub mod eval;
pub mod load;
pub mod peers;
