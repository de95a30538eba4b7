//! Stage 1: the streaming chord-length resampler and its repeat rule (see the module docs of
//! [`crate::acuts`]).

use crate::model::Sample;

/// Samples stage 1 lets through after one push: none, one or two, each with its input index,
/// in order.
pub type Released = std::iter::Chain<
    std::option::IntoIter<(usize, Sample)>,
    std::option::IntoIter<(usize, Sample)>,
>;

/// Stage 1: streaming chord-length resampler, with the repeat rule (see the module docs).
#[derive(Debug, Clone)]
pub struct Resampler {
    /// `l_eps²`: 0 when `l_eps <= 0` (every sample is kept), NaN when `l_eps` is NaN.
    min_distance_sq: f64,
    /// The repeat rule (on by default).
    drop_repeats: bool,
    last_kept: Option<Sample>,
    /// The newest exact repeat of `last_kept`, with its input index: let through before the
    /// next sample when that one's pressure differs, so the rest is bounded at both ends.
    held_repeat: Option<(usize, Sample)>,
    /// The newest sample if it was not let through, with its input index: let through at
    /// [`Resampler::finish`] (pen-up).
    pending_tail: Option<(usize, Sample)>,
    n_seen: usize,
}

impl Resampler {
    /// Chord length `l_eps` (`<= 0`: none), and the repeat rule on.
    pub fn new(min_distance: f64) -> Resampler {
        let min_distance_sq =
            if min_distance.is_nan() { f64::NAN } else { min_distance.max(0.0).powi(2) };
        Resampler {
            min_distance_sq,
            drop_repeats: true,
            last_kept: None,
            held_repeat: None,
            pending_tail: None,
            n_seen: 0,
        }
    }

    /// The repeat rule on or off: off, every repeat is let through (so with `l_eps <= 0`
    /// every sample is).
    pub fn drop_repeats(mut self, on: bool) -> Resampler {
        self.drop_repeats = on;
        self
    }

    /// Pushes the next sample; returns the samples let through now (with their input indices):
    /// the held repeat the pen rested on, when this sample's pressure differs from it, then
    /// this sample, when it is kept.
    pub fn push(&mut self, s: Sample) -> Released {
        let index = self.n_seen;
        self.n_seen += 1;
        let Some(last) = self.last_kept else {
            self.last_kept = Some(s);
            return None.into_iter().chain(Some((index, s)));
        };
        if self.drop_repeats && s.x == last.x && s.y == last.y && s.p == last.p {
            self.held_repeat = Some((index, s));
            self.pending_tail = Some((index, s));
            return None.into_iter().chain(None);
        }
        // The pen moves on (or presses differently): the rest's last sample is needed where the
        // pressure interpolated from the rest's first sample to this one would not be flat.
        let rest_end = self.held_repeat.take().filter(|(_, held)| held.p != s.p);
        let (dx, dy) = (s.x - last.x, s.y - last.y);
        let keep = dx * dx + dy * dy >= self.min_distance_sq;
        if keep {
            self.last_kept = Some(s);
            self.pending_tail = None;
        } else {
            self.pending_tail = Some((index, s));
        }
        rest_end.into_iter().chain(keep.then_some((index, s)))
    }

    /// Pen-up: the last sample, with its input index, if it was not let through already.
    pub fn finish(&mut self) -> Option<(usize, Sample)> {
        self.held_repeat = None;
        let tail = self.pending_tail.take();
        if let Some((_, s)) = tail {
            self.last_kept = Some(s);
        }
        tail
    }
}

/// Stage 1 over a whole stroke, as [`Resampler::new`] runs it (the repeat rule included): the
/// input indices let through, in order.
pub fn resample(samples: &[Sample], min_distance: f64) -> Vec<usize> {
    let mut resampler = Resampler::new(min_distance);
    let mut kept = Vec::with_capacity(samples.len());
    for s in samples {
        kept.extend(resampler.push(*s).map(|(index, _)| index));
    }
    kept.extend(resampler.finish().map(|(index, _)| index));
    kept
}
