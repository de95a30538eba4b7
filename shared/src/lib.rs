//! penmesh core: the stroke model, ACUTS simplification, LRPDP stroke meshes, GLB export,
//! metrics, file formats, a stroke generator and the wire protocol.
//!
//! **This crate does no I/O**: no files, no network, no async. Everything here is a pure function
//! or a state machine, so the proxy, the client and the tests share one implementation.

mod acuts;
mod model;
pub mod protocol;

pub use crate::acuts::{
    AcutsOutput, AcutsParams, DEFAULT_ANGLE_DEG, DEFAULT_PRESSURE_VARIANCE,
    DEFAULT_RESAMPLE_DISTANCE, DEFAULT_TOLERANCE, Kept, ParamError, Resampler, Simplifier, acuts,
    pressure_variance, resample, segment_distance, simplify,
};
pub use crate::model::{
    Brush, BrushError, Sample, SampleError, Stroke, polyline_length, validate_sample,
    validate_samples,
};
