//! The data model: samples, strokes, brushes, and the validation every entry point applies.
//!
//! A sample is `(x, y, t, p)`: position in the stroke's unit, milliseconds since the stroke's
//! first sample, and pressure in `[0, 1]`. Bad samples are refused with an error that names the
//! sample's index; they are never clamped or dropped.

use serde::{Deserialize, Serialize};

/// One pen sample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(from = "[f64; 4]", into = "[f64; 4]")]
pub struct Sample {
    pub x: f64,
    pub y: f64,
    /// Milliseconds since the stroke's first sample; non-decreasing along a stroke.
    pub t: f64,
    /// Pressure normalised to `[0, 1]`.
    pub p: f64,
}

impl Sample {
    pub const fn new(x: f64, y: f64, t: f64, p: f64) -> Sample {
        Sample { x, y, t, p }
    }

    pub fn pos(&self) -> glam::DVec2 {
        glam::DVec2::new(self.x, self.y)
    }

    pub fn distance(&self, other: &Sample) -> f64 {
        (self.x - other.x).hypot(self.y - other.y)
    }
}

impl From<[f64; 4]> for Sample {
    fn from([x, y, t, p]: [f64; 4]) -> Sample {
        Sample { x, y, t, p }
    }
}

impl From<Sample> for [f64; 4] {
    fn from(s: Sample) -> [f64; 4] {
        [s.x, s.y, s.t, s.p]
    }
}

/// Largest magnitude of a coordinate (x or y, in the stroke's unit: CSS px or tablet units).
/// A tablet's raw units reach about 10^5; past 10^6 a value is not a pen's, and the mesh's
/// arithmetic (squared distances, `f32` positions of the GLB) loses what it needs.
pub const MAX_COORDINATE: f64 = 1e6;

/// Why a sample is bad input. Each variant names the sample's index in its stroke.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SampleError {
    #[error("sample {index}: {field} is not a finite number ({value})")]
    NonFinite { index: usize, field: &'static str, value: f64 },
    #[error(
        "sample {index}: {field} = {value} is beyond ±{}, the largest coordinate",
        MAX_COORDINATE
    )]
    CoordinateOutOfRange { index: usize, field: &'static str, value: f64 },
    #[error("sample {index}: pressure {value} is outside [0, 1]")]
    PressureOutOfRange { index: usize, value: f64 },
    #[error("sample {index}: time goes backwards ({value} ms after {previous} ms)")]
    TimeBackwards { index: usize, value: f64, previous: f64 },
}

impl SampleError {
    /// The index of the offending sample.
    pub fn index(&self) -> usize {
        match self {
            SampleError::NonFinite { index, .. }
            | SampleError::CoordinateOutOfRange { index, .. }
            | SampleError::PressureOutOfRange { index, .. }
            | SampleError::TimeBackwards { index, .. } => *index,
        }
    }

    /// The same error for a sample `offset` places further along (a batch inside a stroke).
    pub fn shifted(self, offset: usize) -> SampleError {
        match self {
            SampleError::NonFinite { index, field, value } => {
                SampleError::NonFinite { index: index + offset, field, value }
            }
            SampleError::CoordinateOutOfRange { index, field, value } => {
                SampleError::CoordinateOutOfRange { index: index + offset, field, value }
            }
            SampleError::PressureOutOfRange { index, value } => {
                SampleError::PressureOutOfRange { index: index + offset, value }
            }
            SampleError::TimeBackwards { index, value, previous } => {
                SampleError::TimeBackwards { index: index + offset, value, previous }
            }
        }
    }
}

/// Checks one sample on its own (finite values, coordinates within [`MAX_COORDINATE`],
/// pressure range) at `index`.
pub fn validate_sample(index: usize, s: &Sample) -> Result<(), SampleError> {
    for (field, value) in [("x", s.x), ("y", s.y), ("t", s.t), ("p", s.p)] {
        if !value.is_finite() {
            return Err(SampleError::NonFinite { index, field, value });
        }
    }
    for (field, value) in [("x", s.x), ("y", s.y)] {
        if value.abs() > MAX_COORDINATE {
            return Err(SampleError::CoordinateOutOfRange { index, field, value });
        }
    }
    if !(0.0..=1.0).contains(&s.p) {
        return Err(SampleError::PressureOutOfRange { index, value: s.p });
    }
    Ok(())
}

/// Checks a run of samples that follows `previous` (the stroke's sample before the run, if any).
/// `first_index` is the index of `samples[0]` in its stroke, so errors name stroke indices.
pub fn validate_samples(
    samples: &[Sample],
    previous: Option<&Sample>,
    first_index: usize,
) -> Result<(), SampleError> {
    let mut last_t = previous.map(|s| s.t);
    for (offset, s) in samples.iter().enumerate() {
        let index = first_index + offset;
        validate_sample(index, s)?;
        if let Some(prev) = last_t
            && s.t < prev
        {
            return Err(SampleError::TimeBackwards { index, value: s.t, previous: prev });
        }
        last_t = Some(s.t);
    }
    Ok(())
}

/// A validated sequence of samples between pen-down and pen-up.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(try_from = "Vec<Sample>", into = "Vec<Sample>")]
pub struct Stroke {
    samples: Vec<Sample>,
}

impl Stroke {
    /// Validates and wraps `samples`.
    pub fn new(samples: Vec<Sample>) -> Result<Stroke, SampleError> {
        validate_samples(&samples, None, 0)?;
        Ok(Stroke { samples })
    }

    pub fn samples(&self) -> &[Sample] {
        &self.samples
    }

    pub fn into_samples(self) -> Vec<Sample> {
        self.samples
    }

    pub fn len(&self) -> usize {
        self.samples.len()
    }

    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// Polyline length.
    pub fn length(&self) -> f64 {
        polyline_length(&self.samples)
    }
}

impl TryFrom<Vec<Sample>> for Stroke {
    type Error = SampleError;
    fn try_from(samples: Vec<Sample>) -> Result<Stroke, SampleError> {
        Stroke::new(samples)
    }
}

impl From<Stroke> for Vec<Sample> {
    fn from(stroke: Stroke) -> Vec<Sample> {
        stroke.samples
    }
}

/// Length of the polyline through `samples`.
pub fn polyline_length(samples: &[Sample]) -> f64 {
    samples.windows(2).map(|w| w[0].distance(&w[1])).sum()
}

/// How a stroke is drawn: brush size and pressure response (LRPDP formula 6).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Brush {
    /// Conversion constant `E` (px): the radius at full pressure and `chi = 1`.
    pub size: f64,
    /// Pressure response `chi` in `[0, 1]`.
    pub pressure_response: f64,
    /// Smallest radius `r_min`, so a feather-light touch still has a body.
    pub min_radius: f64,
    /// The colour the stroke is shown in, `0xRRGGBB`; `None`: its drawer's colour, which each
    /// page works out from the participant id.
    #[serde(default)]
    pub color: Option<u32>,
}

impl Brush {
    pub const DEFAULT_SIZE: f64 = 8.0;
    pub const DEFAULT_PRESSURE_RESPONSE: f64 = 0.5;
    pub const DEFAULT_MIN_RADIUS: f64 = 0.25;
    /// The largest colour, `0xFFFFFF` (white).
    pub const MAX_COLOR: u32 = 0xFF_FF_FF;

    /// Radius at pressure `p`: `max(r_min, E * chi * p)`.
    pub fn radius(&self, p: f64) -> f64 {
        (self.size * self.pressure_response * p).max(self.min_radius)
    }

    /// Refuses brushes that would make a degenerate or absurd mesh.
    pub fn validate(&self) -> Result<(), BrushError> {
        let check = |name: &'static str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(BrushError { field: name, value: v, min: lo, max: hi })
            }
        };
        check("size", self.size, 0.0, 10_000.0)?;
        check("pressure_response", self.pressure_response, 0.0, 1.0)?;
        check("min_radius", self.min_radius, 1e-6, 10_000.0)?;
        if let Some(color) = self.color {
            check("color", f64::from(color), 0.0, f64::from(Brush::MAX_COLOR))?;
        }
        Ok(())
    }
}

impl Default for Brush {
    fn default() -> Brush {
        Brush {
            size: Brush::DEFAULT_SIZE,
            pressure_response: Brush::DEFAULT_PRESSURE_RESPONSE,
            min_radius: Brush::DEFAULT_MIN_RADIUS,
            color: None,
        }
    }
}

/// A brush setting out of its range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("brush {field} = {value} is outside [{min}, {max}]")]
pub struct BrushError {
    pub field: &'static str,
    pub value: f64,
    pub min: f64,
    pub max: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_each_kind_of_bad_sample_naming_its_index() {
        let good = Sample::new(0.0, 0.0, 0.0, 0.5);
        let cases = [
            (Sample::new(f64::NAN, 0.0, 1.0, 0.5), 1, "x is not a finite"),
            (Sample::new(0.0, f64::INFINITY, 1.0, 0.5), 1, "y is not a finite"),
            (Sample::new(1e50, 0.0, 1.0, 0.5), 1, "x = 1000000000"),
            (Sample::new(0.0, -1_000_000.5, 1.0, 0.5), 1, "y = -1000000.5 is beyond ±1000000"),
            (Sample::new(0.0, 0.0, 1.0, 1.5), 1, "pressure 1.5 is outside"),
            (Sample::new(0.0, 0.0, -1.0, 0.5), 1, "time goes backwards"),
        ];
        for (bad, index, text) in cases {
            let err = Stroke::new(vec![good, bad]).unwrap_err();
            assert_eq!(err.index(), index);
            assert!(err.to_string().contains(text), "{err}");
            assert!(err.to_string().starts_with("sample 1:"), "{err}");
        }
    }

    #[test]
    fn coordinates_at_the_bound_are_accepted() {
        let edge = [
            Sample::new(-MAX_COORDINATE, MAX_COORDINATE, 0.0, 0.5),
            Sample::new(MAX_COORDINATE, -MAX_COORDINATE, 1.0, 0.5),
        ];
        assert!(Stroke::new(edge.to_vec()).is_ok());
    }

    #[test]
    fn batch_errors_name_stroke_indices() {
        let prev = Sample::new(0.0, 0.0, 10.0, 0.5);
        let err =
            validate_samples(&[Sample::new(1.0, 1.0, 5.0, 0.5)], Some(&prev), 40).unwrap_err();
        assert_eq!(err.index(), 40);
    }

    #[test]
    fn radius_has_a_floor() {
        let brush = Brush::default();
        assert_eq!(brush.radius(0.0), 0.25);
        assert_eq!(brush.radius(1.0), 4.0);
    }
}
