//! penmesh's print: the union of every stroke's placed solid as one closed manifold (by
//! Manifold, through `manifold-rs`), in millimetres, every part printable, written as STL and
//! 3MF. Its own crate because it links Manifold's C++ (built from the source the crate vendors,
//! with cmake and ninja): the pure core `penmesh` stays pure Rust.

mod apart;
pub mod boolean;
mod ordered;
mod pieces;
mod solid;
mod stl;
mod threemf;

pub use crate::solid::{
    DEFAULT_MIN_THICKNESS_MM, DEFAULT_SIZE_MM, HOLE_MARGIN_MM, IDENTITY, MAX_SIZE_MM, PRINT_AXES,
    PRINT_TOLERANCE_MM, PrintError, PrintMesh, PrintOptions, PrintStroke, Progress, print_mesh,
};
pub use crate::stl::write_stl;
pub use crate::threemf::{MODEL_PATH, model_xml, write_3mf};
