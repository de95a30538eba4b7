//! One stroke of the live path, from its first sample until the proxy reports it done: what
//! was drawn and kept, what the proxy acknowledged, and how a reconnect resumes it. No I/O, so
//! the resume rules are tested here without a socket.

use std::collections::VecDeque;

use penmesh::protocol::{ResumeState, StrokeStatus};
use penmesh::{Resampler, Sample};
use tokio::time::Instant;
use uuid::Uuid;

/// One stroke, from its first sample until the proxy reports it done.
pub(super) struct StrokeLog {
    pub(super) id: Uuid,
    pub(super) index: usize,
    pub(super) device: String,
    pub(super) resampler: Resampler,
    /// Every drawn sample (quantised), and for each kept one its index among them.
    pub(super) drawn: Vec<Sample>,
    pub(super) resampled_from: Vec<usize>,
    /// Kept samples `acked..acked + unacked.len()`: everything the proxy has not committed.
    pub(super) unacked: VecDeque<Sample>,
    pub(super) acked: u64,
    /// The next seq to send on the current connection.
    pub(super) sent: u64,
    pub(super) pen_up: Option<Instant>,
    /// `StrokeBegin` was sent on some connection (so a reconnect resumes it).
    pub(super) begun: bool,
    /// Begun or resumed on the current connection.
    pub(super) on_link: bool,
    pub(super) end_sent: bool,
    pub(super) done: bool,
    /// A lone unsent sample was held back at the last tick (see `flush`).
    pub(super) held_lone: bool,
}

impl StrokeLog {
    /// A stroke that has just started: nothing kept, nothing sent.
    pub(super) fn new(index: usize, device: String, resampler: Resampler) -> StrokeLog {
        StrokeLog {
            // Time-ordered (UUIDv7): the database's indexes of stroke ids grow at their end.
            id: Uuid::now_v7(),
            index,
            device,
            resampler,
            drawn: Vec::new(),
            resampled_from: Vec::new(),
            unacked: VecDeque::new(),
            acked: 0,
            sent: 0,
            pen_up: None,
            begun: false,
            on_link: false,
            end_sent: false,
            held_lone: false,
            done: false,
        }
    }

    pub(super) fn n_kept(&self) -> u64 {
        self.acked + self.unacked.len() as u64
    }

    pub(super) fn keep(&mut self, drawn_idx: usize, s: Sample) {
        self.resampled_from.push(drawn_idx);
        self.unacked.push_back(s);
    }

    /// Forgets what the proxy has committed.
    pub(super) fn ack(&mut self, upto_seq: u64) {
        if upto_seq > self.acked {
            let n = ((upto_seq - self.acked) as usize).min(self.unacked.len());
            self.unacked.drain(..n);
            self.acked += n as u64;
        }
        self.sent = self.sent.max(self.acked);
    }

    /// The connection dropped: everything not acknowledged is sent again on the next one.
    pub(super) fn connection_lost(&mut self) {
        self.on_link = false;
        self.end_sent = false;
        self.sent = self.acked;
    }

    /// Takes the proxy's word on how far it has this stroke (`Welcome.resume`) and decides how
    /// to go on. Refuses an answer that would lose or invent samples: a resume point before what
    /// the proxy acknowledged or past what was drawn, or an acknowledged stroke it forgot.
    pub(super) fn resume(&mut self, state: &ResumeState) -> anyhow::Result<Resumed> {
        tracing::debug!(stroke = %self.id, next_seq = state.next_seq, status = state.status.as_str(), acked = self.acked, "resume");
        match state.status {
            StrokeStatus::Open | StrokeStatus::Interrupted => {
                anyhow::ensure!(
                    state.next_seq >= self.acked && state.next_seq <= self.n_kept(),
                    "stroke {}: the proxy resumes at sample {} but {} were acknowledged and {} drawn",
                    self.id,
                    state.next_seq,
                    self.acked,
                    self.n_kept()
                );
                self.ack(state.next_seq);
                self.on_link = true;
                self.sent = self.acked;
                Ok(Resumed::From(self.acked))
            }
            StrokeStatus::Done => Ok(Resumed::Done),
            StrokeStatus::Unknown => {
                anyhow::ensure!(
                    self.acked == 0,
                    "stroke {}: the proxy no longer knows it, but acknowledged {} samples",
                    self.id,
                    self.acked
                );
                self.on_link = false;
                Ok(Resumed::Begin)
            }
        }
    }
}

/// How a stroke goes on after a reconnect ([`StrokeLog::resume`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Resumed {
    /// The proxy has it open: send from this sample on.
    From(u64),
    /// The proxy has all of it: reconstruct it.
    Done,
    /// The proxy never stored it: begin it again.
    Begin,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stroke_with(kept: usize, sent: u64) -> StrokeLog {
        let mut s = StrokeLog::new(0, String::new(), Resampler::new(0.0));
        for i in 0..kept {
            s.keep(i, Sample::new(i as f64, 0.0, i as f64, 0.5));
        }
        s.begun = true;
        s.on_link = true;
        s.sent = sent;
        s
    }

    fn state(next_seq: u64, status: StrokeStatus) -> ResumeState {
        ResumeState { stroke: Uuid::nil(), next_seq, status }
    }

    #[test]
    fn an_ack_forgets_exactly_the_committed_samples() {
        let mut s = stroke_with(10, 10);
        s.ack(4);
        assert_eq!((s.acked, s.unacked.len(), s.unacked[0].x), (4, 6, 4.0));
        s.ack(2);
        assert_eq!(s.acked, 4);
        s.ack(99);
        assert_eq!((s.acked, s.unacked.len()), (10, 0));
    }

    #[test]
    fn a_lost_connection_sends_everything_unacknowledged_again() {
        let mut s = stroke_with(10, 10);
        s.ack(3);
        s.end_sent = true;
        s.connection_lost();
        assert_eq!((s.sent, s.on_link, s.end_sent), (3, false, false));
    }

    #[test]
    fn an_open_stroke_resumes_where_the_proxy_has_it() {
        for status in [StrokeStatus::Open, StrokeStatus::Interrupted] {
            let mut s = stroke_with(10, 10);
            s.ack(2);
            s.connection_lost();
            assert_eq!(s.resume(&state(7, status)).unwrap(), Resumed::From(7));
            assert_eq!((s.acked, s.sent, s.unacked.len(), s.on_link), (7, 7, 3, true));
        }
    }

    #[test]
    fn a_resume_point_that_would_lose_or_invent_samples_is_refused() {
        let mut s = stroke_with(10, 10);
        s.ack(5);
        let before = s.resume(&state(4, StrokeStatus::Open)).unwrap_err().to_string();
        assert!(before.contains("resumes at sample 4 but 5 were acknowledged"), "{before}");
        let past = s.resume(&state(11, StrokeStatus::Open)).unwrap_err().to_string();
        assert!(past.contains("and 10 drawn"), "{past}");
        let forgot = s.resume(&state(0, StrokeStatus::Unknown)).unwrap_err().to_string();
        assert!(forgot.contains("no longer knows it"), "{forgot}");
    }

    #[test]
    fn a_done_stroke_is_reconstructed_and_an_unknown_one_begun_again() {
        let mut s = stroke_with(10, 10);
        assert_eq!(s.resume(&state(10, StrokeStatus::Done)).unwrap(), Resumed::Done);
        assert_eq!(s.resume(&state(0, StrokeStatus::Unknown)).unwrap(), Resumed::Begin);
        assert!(!s.on_link, "an unknown stroke is begun again on the new connection");
    }
}
