//! ACUTS: angle-chord height united trajectory simplification (paper section III, made precise
//! in `shared/spec/algorithms.md`).
//!
//! Stage 1 ([`Resampler`]) runs on the client as samples arrive: a sample is kept iff it lies at
//! least `l_eps` from the last kept one; the first and the last sample are always kept.
//!
//! Stage 2 ([`Simplifier`]) runs on the proxy over the resampled stream, one sample at a time,
//! with a window of anchor `a`, skipped set `R` and candidate `m`.
//!
//! **Guarantee**: every removed sample of the stage-2 input lies within `d_d` (the tolerance) of
//! the retained segment that spans it.
//!
//! PLACEHOLDER IMPLEMENTATION: the skipped set is kept as a list, O(|R|) per sample. To be
//! replaced by the constant-time cone test.

use serde::{Deserialize, Serialize};

use crate::model::Sample;

/// Default chord-length threshold `l_eps` of stage 1 (table 3's lambda).
pub const DEFAULT_RESAMPLE_DISTANCE: f64 = 1.0;
/// Default chord-height tolerance `d_d` (same unit as x, y).
pub const DEFAULT_TOLERANCE: f64 = 0.74;
/// Default angle threshold `d_alpha` in degrees.
pub const DEFAULT_ANGLE_DEG: f64 = 15.0;
/// Default pressure-variance threshold `d_sigma2` for `p` in `[0, 1]`.
pub const DEFAULT_PRESSURE_VARIANCE: f64 = 0.0015;

/// Stage-2 parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AcutsParams {
    /// Chord-height tolerance `d_d`.
    pub tolerance: f64,
    /// Angle threshold `d_alpha`, degrees.
    pub angle_deg: f64,
    /// Pressure-variance threshold `d_sigma2`.
    pub pressure_variance: f64,
}

impl Default for AcutsParams {
    fn default() -> AcutsParams {
        AcutsParams {
            tolerance: DEFAULT_TOLERANCE,
            angle_deg: DEFAULT_ANGLE_DEG,
            pressure_variance: DEFAULT_PRESSURE_VARIANCE,
        }
    }
}

/// A parameter outside its range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{name} = {value} is outside {range}")]
pub struct ParamError {
    pub name: &'static str,
    pub value: f64,
    pub range: &'static str,
}

impl AcutsParams {
    pub fn validate(&self) -> Result<(), ParamError> {
        let bad = |name, value: f64, ok: bool, range| {
            if ok && value.is_finite() { Ok(()) } else { Err(ParamError { name, value, range }) }
        };
        bad("tolerance", self.tolerance, self.tolerance >= 0.0, "[0, inf)")?;
        bad("angle_deg", self.angle_deg, (0.0..=90.0).contains(&self.angle_deg), "[0, 90]")?;
        bad(
            "pressure_variance",
            self.pressure_variance,
            self.pressure_variance >= 0.0,
            "[0, inf)",
        )?;
        Ok(())
    }
}

/// A sample stage 2 decided to keep, with its index in the stage-2 input stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kept {
    pub index: usize,
    pub sample: Sample,
}

/// Stage 1: streaming chord-length resampler.
#[derive(Debug, Clone)]
pub struct Resampler {
    min_distance: f64,
    last_kept: Option<Sample>,
    /// The newest sample if it was not kept, with its input index: kept at [`Resampler::finish`].
    pending_tail: Option<(usize, Sample)>,
    n_seen: usize,
}

impl Resampler {
    pub fn new(min_distance: f64) -> Resampler {
        Resampler { min_distance, last_kept: None, pending_tail: None, n_seen: 0 }
    }

    /// Pushes the next sample; returns whether it is kept.
    pub fn push(&mut self, s: Sample) -> bool {
        let index = self.n_seen;
        self.n_seen += 1;
        let keep = match &self.last_kept {
            None => true,
            Some(last) => last.distance(&s) >= self.min_distance,
        };
        if keep {
            self.last_kept = Some(s);
            self.pending_tail = None;
        } else {
            self.pending_tail = Some((index, s));
        }
        keep
    }

    /// Pen-up: the last sample, with its input index, if it was not kept already.
    pub fn finish(&mut self) -> Option<(usize, Sample)> {
        let tail = self.pending_tail.take();
        if let Some((_, s)) = tail {
            self.last_kept = Some(s);
        }
        tail
    }
}

/// Stage 1 over a whole stroke: the input indices kept, in order.
pub fn resample(samples: &[Sample], min_distance: f64) -> Vec<usize> {
    let mut resampler = Resampler::new(min_distance);
    let mut kept: Vec<usize> =
        samples.iter().enumerate().filter(|(_, s)| resampler.push(**s)).map(|(i, _)| i).collect();
    if let Some((index, _)) = resampler.finish() {
        kept.push(index);
    }
    kept
}

/// Stage 2: streaming windowed simplifier.
#[derive(Debug, Clone)]
pub struct Simplifier {
    params: AcutsParams,
    anchor: Option<Sample>,
    skipped: Vec<Sample>,
    candidate: Option<(usize, Sample)>,
    n_seen: usize,
}

impl Simplifier {
    pub fn new(params: AcutsParams) -> Simplifier {
        Simplifier { params, anchor: None, skipped: Vec::new(), candidate: None, n_seen: 0 }
    }

    pub fn params(&self) -> &AcutsParams {
        &self.params
    }

    /// Pushes the next sample; returns the sample this push decided to keep, if any.
    pub fn push(&mut self, e: Sample) -> Option<Kept> {
        let index = self.n_seen;
        self.n_seen += 1;
        let Some(a) = self.anchor else {
            self.anchor = Some(e);
            return Some(Kept { index, sample: e });
        };
        let Some((m_index, m)) = self.candidate else {
            self.candidate = Some((index, e));
            return None;
        };
        let keep_m = pressure_variance(a.p, m.p, e.p) > self.params.pressure_variance
            || !self.skipped.iter().chain(std::iter::once(&m)).all(|q| self.admits(&a, q, &e));
        self.candidate = Some((index, e));
        if keep_m {
            self.anchor = Some(m);
            self.skipped.clear();
            Some(Kept { index: m_index, sample: m })
        } else {
            self.skipped.push(m);
            None
        }
    }

    /// Pen-up: the pending candidate is kept.
    pub fn finish(&mut self) -> Option<Kept> {
        self.candidate.take().map(|(index, sample)| Kept { index, sample })
    }

    fn admits(&self, a: &Sample, q: &Sample, e: &Sample) -> bool {
        let (aq, ae) = (q.pos() - a.pos(), e.pos() - a.pos());
        let angle_ok = aq.length() == 0.0
            || ae.length() == 0.0
            || aq.angle_to(ae).abs() <= self.params.angle_deg.to_radians();
        angle_ok && segment_distance(q, a, e) <= self.params.tolerance
    }
}

/// Population variance of three pressures (paper formula 3, `W_s = 3`).
pub fn pressure_variance(p0: f64, p1: f64, p2: f64) -> f64 {
    let mean = (p0 + p1 + p2) / 3.0;
    ((p0 - mean).powi(2) + (p1 - mean).powi(2) + (p2 - mean).powi(2)) / 3.0
}

/// Distance from `q` to the segment `a–b`.
pub fn segment_distance(q: &Sample, a: &Sample, b: &Sample) -> f64 {
    let (ab, aq) = (b.pos() - a.pos(), q.pos() - a.pos());
    let len2 = ab.length_squared();
    if len2 == 0.0 {
        return aq.length();
    }
    let t = (aq.dot(ab) / len2).clamp(0.0, 1.0);
    (aq - ab * t).length()
}

/// Stage 2 over a whole (resampled) stroke: the indices kept, in order.
pub fn simplify(samples: &[Sample], params: &AcutsParams) -> Vec<usize> {
    let mut simplifier = Simplifier::new(*params);
    let mut kept: Vec<usize> =
        samples.iter().filter_map(|s| simplifier.push(*s)).map(|k| k.index).collect();
    kept.extend(simplifier.finish().map(|k| k.index));
    kept
}

/// Both stages over a whole stroke, as the client and proxy run them together.
#[derive(Debug, Clone, PartialEq)]
pub struct AcutsOutput {
    /// Input indices kept by stage 1.
    pub resampled: Vec<usize>,
    /// Input indices kept by stage 2 (a subset of `resampled`).
    pub kept: Vec<usize>,
}

/// Runs stage 1 (skipped when `resample_distance <= 0`) then stage 2.
pub fn acuts(samples: &[Sample], resample_distance: f64, params: &AcutsParams) -> AcutsOutput {
    let resampled: Vec<usize> = if resample_distance > 0.0 {
        resample(samples, resample_distance)
    } else {
        (0..samples.len()).collect()
    };
    let stage2_input: Vec<Sample> = resampled.iter().map(|&i| samples[i]).collect();
    let kept = simplify(&stage2_input, params).into_iter().map(|j| resampled[j]).collect();
    AcutsOutput { resampled, kept }
}
