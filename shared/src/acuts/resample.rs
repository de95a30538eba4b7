//! Stage 1: the streaming chord-length resampler and its repeat rule (see the module docs of
//! [`crate::acuts`]).

use super::params::DEFAULT_REPEAT_PRESSURE_TOLERANCE;
use crate::model::Sample;

/// Stage 1: streaming chord-length resampler, with the repeat rule (see the module docs).
#[derive(Debug, Clone)]
pub struct Resampler {
    /// `l_eps²`: 0 when `l_eps <= 0` (every sample is kept), NaN when `l_eps` is NaN.
    min_distance_sq: f64,
    /// The repeat rule's pressure tolerance; `None` keeps repeats (then only `l_eps` drops).
    repeat_pressure: Option<f64>,
    last_kept: Option<Sample>,
    /// The newest sample if it was not kept, with its input index: kept at [`Resampler::finish`].
    pending_tail: Option<(usize, Sample)>,
    n_seen: usize,
}

impl Resampler {
    /// Chord length `l_eps` (`<= 0`: none), and the repeat rule at
    /// [`DEFAULT_REPEAT_PRESSURE_TOLERANCE`].
    pub fn new(min_distance: f64) -> Resampler {
        let min_distance_sq =
            if min_distance.is_nan() { f64::NAN } else { min_distance.max(0.0).powi(2) };
        Resampler {
            min_distance_sq,
            repeat_pressure: Some(DEFAULT_REPEAT_PRESSURE_TOLERANCE),
            last_kept: None,
            pending_tail: None,
            n_seen: 0,
        }
    }

    /// The repeat rule: drop a sample whose `x` and `y` equal the last kept sample's and whose
    /// pressure is within `tolerance` of its pressure; `None` keeps every repeat (so with
    /// `l_eps <= 0` every sample is kept). A negative or NaN tolerance drops nothing either.
    pub fn repeat_pressure(mut self, tolerance: Option<f64>) -> Resampler {
        self.repeat_pressure = tolerance;
        self
    }

    /// Pushes the next sample; returns whether it is kept.
    pub fn push(&mut self, s: Sample) -> bool {
        let index = self.n_seen;
        self.n_seen += 1;
        let keep = match &self.last_kept {
            None => true,
            Some(last) => {
                let (dx, dy) = (s.x - last.x, s.y - last.y);
                let repeat = dx == 0.0
                    && dy == 0.0
                    && self.repeat_pressure.is_some_and(|tol| (s.p - last.p).abs() <= tol);
                !repeat && dx * dx + dy * dy >= self.min_distance_sq
            }
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

/// Stage 1 over a whole stroke, as [`Resampler::new`] runs it (the repeat rule included): the
/// input indices kept, in order.
pub fn resample(samples: &[Sample], min_distance: f64) -> Vec<usize> {
    let mut resampler = Resampler::new(min_distance);
    let mut kept = Vec::with_capacity(samples.len());
    for (index, s) in samples.iter().enumerate() {
        if resampler.push(*s) {
            kept.push(index);
        }
    }
    if let Some((index, _)) = resampler.finish() {
        kept.push(index);
    }
    kept
}
