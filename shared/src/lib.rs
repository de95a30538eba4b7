//! penmesh core: the stroke model, ACUTS simplification, LRPDP stroke meshes, GLB export,
//! metrics, file formats, a stroke generator and the wire protocol.
//!
//! **This crate does no I/O**: no files, no network, no async. Everything here is a pure function
//! or a state machine, so the proxy, the client and the tests share one implementation.

mod acuts;
pub mod baselines;
mod formats;
mod generator;
mod glb;
mod lrpdp;
mod mesh;
mod metrics;
mod model;
pub mod protocol;
mod svg;

pub use crate::acuts::{
    AcutsOutput, AcutsParams, DEFAULT_ANGLE_DEG, DEFAULT_PRESSURE_VARIANCE,
    DEFAULT_RESAMPLE_DISTANCE, DEFAULT_TOLERANCE, Kept, ParamError, Resampler, Simplifier, acuts,
    pressure_variance, resample, segment_distance, simplify,
};
pub use crate::model::{
    Brush, BrushError, Sample, SampleError, Stroke, polyline_length, validate_sample,
    validate_samples,
};

// Modules being written in parallel re-export everything they make public; the list is made
// explicit once they settle.
#[allow(unused_imports)]
pub use crate::formats::*;
#[allow(unused_imports)]
pub use crate::generator::*;
#[allow(unused_imports)]
pub use crate::glb::*;
#[allow(unused_imports)]
pub use crate::lrpdp::*;
#[allow(unused_imports)]
pub use crate::mesh::*;
#[allow(unused_imports)]
pub use crate::metrics::*;
#[allow(unused_imports)]
pub use crate::svg::*;
