//! Per-stroke ingest state: seq contiguity, sample validation, the streaming ACUTS
//! [`Simplifier`], and the limits. No I/O: the connection loop turns the outcomes into
//! database writes and messages.

use penmesh::protocol::{ErrorCode, quantize_sample};
use penmesh::{AcutsParams, Kept, Sample, Simplifier, validate_samples};

/// A refusal: the code and a message naming what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct Refusal {
    pub code: ErrorCode,
    pub message: String,
}

impl Refusal {
    pub fn new(code: ErrorCode, message: impl Into<String>) -> Refusal {
        Refusal { code, message: message.into() }
    }
}

/// Limits that apply to one stroke.
#[derive(Debug, Clone, Copy)]
pub struct StrokeLimits {
    pub max_batch_samples: usize,
    pub max_stroke_samples: u64,
    /// Most retained samples held in memory for the stroke (one more may join at pen-up).
    pub max_stroke_retained: usize,
}

/// What a `Points` batch amounts to.
#[derive(Debug, Clone, PartialEq)]
pub enum Accepted {
    /// Every sample of the batch was accepted before: nothing to store, ack again.
    Duplicate,
    /// New samples `seq..seq + samples.len()` to store (on the codec's grid); `kept` are the newly retained ones,
    /// the first of which has index `first_kept` in the simplified stroke.
    New { seq: u64, samples: Vec<Sample>, kept: Vec<Kept>, first_kept: u64 },
}

/// A stroke at pen-up.
#[derive(Debug, Clone, PartialEq)]
pub struct Finished {
    /// The pending candidate, kept at pen-up, with its index in the simplified stroke.
    pub last: Option<(u64, Kept)>,
    /// The whole simplified stroke.
    pub kept: Vec<Kept>,
}

/// One stroke being drawn on a connection.
#[derive(Debug, Clone)]
pub struct StrokeState {
    /// Samples accepted (validated and queued for storage): the next seq expected.
    next_seq: u64,
    /// Every sample below this is committed.
    pub committed_seq: u64,
    last: Option<Sample>,
    simplifier: Simplifier,
    kept: Vec<Kept>,
}

impl StrokeState {
    pub fn new(params: AcutsParams) -> StrokeState {
        StrokeState {
            next_seq: 0,
            committed_seq: 0,
            last: None,
            simplifier: Simplifier::new(params),
            kept: Vec::new(),
        }
    }

    /// Rebuilds the state of a resumed stroke by replaying its committed samples through a
    /// fresh simplifier: the result is the state the stroke had, with every retained sample.
    pub fn replay(params: AcutsParams, samples: &[Sample]) -> StrokeState {
        let mut state = StrokeState::new(params);
        for s in samples {
            state.kept.extend(state.simplifier.push(*s));
        }
        state.next_seq = samples.len() as u64;
        state.committed_seq = state.next_seq;
        state.last = samples.last().copied();
        state
    }

    pub fn next_seq(&self) -> u64 {
        self.next_seq
    }

    /// The samples retained so far.
    pub fn kept(&self) -> &[Kept] {
        &self.kept
    }

    /// Takes a batch starting at `seq`. A batch wholly before `next_seq` is a duplicate; one
    /// that overlaps contributes only its new tail; one that starts past it is a gap.
    /// Nothing changes when the batch is refused.
    pub fn push_points(
        &mut self,
        seq: u64,
        points: &[Sample],
        limits: &StrokeLimits,
    ) -> Result<Accepted, Refusal> {
        if points.len() > limits.max_batch_samples {
            return Err(Refusal::new(
                ErrorCode::BatchTooLarge,
                format!(
                    "batch of {} samples is larger than the limit of {}",
                    points.len(),
                    limits.max_batch_samples
                ),
            ));
        }
        if seq > self.next_seq {
            return Err(Refusal::new(
                ErrorCode::SeqGap,
                format!("seq gap: expected seq {}, got {seq}", self.next_seq),
            ));
        }
        let end = seq + points.len() as u64;
        if end <= self.next_seq {
            return Ok(Accepted::Duplicate);
        }
        let tail = &points[(self.next_seq - seq) as usize..];
        if end > limits.max_stroke_samples {
            return Err(Refusal::new(
                ErrorCode::StrokeTooLong,
                format!(
                    "stroke would have {end} samples, more than the limit of {}",
                    limits.max_stroke_samples
                ),
            ));
        }
        // On the codec's grid from here on (a binary client's samples are there already, a
        // JSON client's move by at most half a step), so that what ACUTS sees, what is stored
        // compactly and what `/raw` returns are the same values. The values as sent are checked
        // (a pressure of 1.0003 is refused, not rounded into range); the order across batches
        // is checked on the grid, where `last` is.
        let bad = |e: penmesh::SampleError| Refusal::new(ErrorCode::BadSample, e.to_string());
        validate_samples(tail, None, self.next_seq as usize).map_err(bad)?;
        let tail: Vec<Sample> = tail.iter().map(quantize_sample).collect();
        validate_samples(&tail, self.last.as_ref(), self.next_seq as usize).map_err(bad)?;
        let first_kept = self.kept.len() as u64;
        // On a copy (its state is a few numbers), so that a refused batch changes nothing.
        let mut simplifier = self.simplifier.clone();
        let mut kept = Vec::new();
        for s in &tail {
            kept.extend(simplifier.push(*s));
        }
        let retained = self.kept.len() + kept.len();
        if retained > limits.max_stroke_retained {
            return Err(Refusal::new(
                ErrorCode::StrokeTooLong,
                format!(
                    "stroke would retain {retained} samples, more than the limit of {} (a larger \
                     tolerance retains fewer); end it and begin another",
                    limits.max_stroke_retained
                ),
            ));
        }
        self.simplifier = simplifier;
        self.kept.extend_from_slice(&kept);
        let seq = self.next_seq;
        self.next_seq = end;
        self.last = tail.last().copied();
        Ok(Accepted::New { seq, samples: tail, kept, first_kept })
    }

    /// Pen-up: checks the count and finishes the simplifier.
    pub fn finish(&mut self, n_points: u64) -> Result<Finished, Refusal> {
        if n_points != self.next_seq {
            return Err(Refusal::new(
                ErrorCode::CountMismatch,
                format!("stroke_end says {n_points} samples, but {} were received", self.next_seq),
            ));
        }
        let last = self.simplifier.finish().map(|k| {
            self.kept.push(k);
            (self.kept.len() as u64 - 1, k)
        });
        Ok(Finished { last, kept: std::mem::take(&mut self.kept) })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: StrokeLimits = StrokeLimits {
        max_batch_samples: 100,
        max_stroke_samples: 1000,
        max_stroke_retained: 1000,
    };

    #[test]
    fn retained_samples_held_per_stroke_are_limited_and_a_refusal_changes_nothing() {
        // A zigzag: every sample is retained.
        let zigzag: Vec<Sample> = (0..40)
            .map(|i| {
                Sample::new(i as f64 * 4.0, if i % 2 == 0 { 0.0 } else { 50.0 }, i as f64, 0.5)
            })
            .collect();
        let limits = StrokeLimits { max_stroke_retained: 25, ..LIMITS };
        let mut s = state();
        s.push_points(0, &zigzag[..20], &limits).unwrap();
        let before = (s.next_seq(), s.kept().len());
        let err = s.push_points(20, &zigzag[20..], &limits).unwrap_err();
        assert_eq!(err.code, ErrorCode::StrokeTooLong);
        assert!(err.message.contains("retain") && err.message.contains("25"), "{}", err.message);
        assert_eq!((s.next_seq(), s.kept().len()), before, "a refused batch changes nothing");
        // What fits still goes in, and the result is what the batch simplification keeps.
        s.push_points(20, &zigzag[20..24], &limits).unwrap();
        let kept = s.finish(24).unwrap().kept;
        let indices: Vec<usize> = kept.iter().map(|k| k.index).collect();
        assert_eq!(indices, penmesh::simplify(&zigzag[..24], &AcutsParams::default()));
    }

    fn line(from: usize, to: usize) -> Vec<Sample> {
        (from..to)
            .map(|i| Sample::new(i as f64 * 3.0, ((i * 7) % 5) as f64 * 4.0, i as f64, 0.5))
            .collect()
    }

    fn state() -> StrokeState {
        StrokeState::new(AcutsParams::default())
    }

    #[test]
    fn streamed_batches_retain_what_batch_simplify_keeps() {
        let samples = line(0, 60);
        let mut s = state();
        for (i, chunk) in samples.chunks(7).enumerate() {
            s.push_points((i * 7) as u64, chunk, &LIMITS).unwrap();
        }
        let kept = s.finish(60).unwrap().kept;
        let indices: Vec<usize> = kept.iter().map(|k| k.index).collect();
        assert_eq!(indices, penmesh::simplify(&samples, &AcutsParams::default()));
    }

    #[test]
    fn duplicates_overlaps_and_gaps() {
        let samples = line(0, 20);
        let mut s = state();
        s.push_points(0, &samples[..10], &LIMITS).unwrap();
        assert_eq!(s.push_points(0, &samples[..10], &LIMITS).unwrap(), Accepted::Duplicate);
        match s.push_points(5, &samples[5..15], &LIMITS).unwrap() {
            Accepted::New { seq, samples: new, .. } => {
                assert_eq!(seq, 10);
                assert_eq!(new, samples[10..15].to_vec());
            }
            other => panic!("{other:?}"),
        }
        let gap = s.push_points(16, &samples[16..], &LIMITS).unwrap_err();
        assert_eq!(gap.code, ErrorCode::SeqGap);
        assert!(gap.message.contains("expected seq 15"), "{}", gap.message);
    }

    #[test]
    fn refused_batches_change_nothing() {
        let mut s = state();
        s.push_points(0, &line(0, 5), &LIMITS).unwrap();
        let mut bad = line(5, 8);
        bad[1].p = 2.0;
        let err = s.push_points(5, &bad, &LIMITS).unwrap_err();
        assert_eq!(err.code, ErrorCode::BadSample);
        assert!(err.message.contains("sample 6"), "{}", err.message);
        assert_eq!(s.next_seq(), 5);
        assert_eq!(
            s.push_points(0, &line(0, 101), &LIMITS).unwrap_err().code,
            ErrorCode::BatchTooLarge
        );
        assert_eq!(s.finish(4).unwrap_err().code, ErrorCode::CountMismatch);
    }

    #[test]
    fn samples_are_put_on_the_grid_and_checked_as_sent() {
        let mut s = state();
        let sent = vec![Sample::new(1.03, 2.0, 10.07, 0.5001), Sample::new(2.0, 2.0, 10.08, 0.5)];
        let Accepted::New { samples, .. } = s.push_points(0, &sent, &LIMITS).unwrap() else {
            panic!("new samples")
        };
        let on_grid: Vec<Sample> = sent.iter().map(quantize_sample).collect();
        assert_eq!(samples, on_grid);
        assert_ne!(samples[0], sent[0]);
        // 10.08 follows 10.07 as sent, though 10.07 is 10.125 on the grid: accepted.
        let next = [Sample::new(3.0, 2.0, 10.09, 0.5)];
        assert!(s.push_points(2, &next, &LIMITS).is_ok());
        // A pressure just over 1 is refused, not rounded into range.
        let err = s.push_points(3, &[Sample::new(4.0, 2.0, 11.0, 1.0003)], &LIMITS).unwrap_err();
        assert_eq!(err.code, ErrorCode::BadSample);
    }

    #[test]
    fn replay_rebuilds_the_same_state() {
        let samples = line(0, 40);
        let mut streamed = state();
        streamed.push_points(0, &samples, &LIMITS).unwrap();
        let mut replayed = StrokeState::replay(AcutsParams::default(), &samples[..25]);
        replayed.push_points(25, &samples[25..], &LIMITS).unwrap();
        assert_eq!(streamed.finish(40).unwrap().kept, replayed.finish(40).unwrap().kept);
    }
}
