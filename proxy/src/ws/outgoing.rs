//! What goes out to one client: a bounded queue of frames, written to the socket by a task of
//! its own ([`forward`]), and the overflow of answers already owed.
//!
//! The bound: the queue holds at most its capacity. An answer that finds it full waits in the
//! overflow, in order, and while the overflow is not empty the connection reads no frame and
//! takes no peer event, so only the answers already owed (at most `max_inflight` acks) can
//! join it. A socket that takes none of them for `slow_reader_ms` belongs to a slow reader; one
//! that does was only behind by a burst (a group commit acknowledges many batches at once).

use std::collections::VecDeque;
use std::time::Duration;

use futures_util::{Sink, SinkExt};
use penmesh::protocol::{ServerMessage, encode_server, encode_server_json};
use tokio::sync::mpsc;
use tokio::task::JoinHandle;
use tokio::time::Instant;

use super::Frame;
use super::error::End;
use crate::metrics::HotCounters;

/// Which encoding the client used last.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Form {
    Binary,
    Json,
}

/// The client's socket is closed: nothing more can go out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Closed;

pub(super) struct Outgoing {
    out: mpsc::Sender<Frame>,
    /// Answers that found the queue full, in order, and since when.
    overflow: VecDeque<Frame>,
    overflow_since: Option<Instant>,
    /// The form of the client's latest frame, which answers take.
    pub form: Form,
    /// Frames sent, binary and text.
    sent: (metrics::Counter, metrics::Counter),
}

impl Outgoing {
    /// A queue of `capacity` frames, and its other end for [`forward`].
    pub fn new(capacity: usize, counters: &HotCounters) -> (Outgoing, mpsc::Receiver<Frame>) {
        let (out, rx) = mpsc::channel(capacity.max(1));
        let sent = (counters.frames_out_binary.clone(), counters.frames_out_text.clone());
        let outgoing = Outgoing {
            out,
            overflow: VecDeque::new(),
            overflow_since: None,
            form: Form::Binary,
            sent,
        };
        (outgoing, rx)
    }

    pub fn encode(&self, msg: &ServerMessage) -> Frame {
        match self.form {
            Form::Binary => Frame::Binary(encode_server(msg)),
            Form::Json => Frame::Text(encode_server_json(msg)),
        }
    }

    /// Queues an answer now: into the queue, or into the overflow when the queue is full or
    /// older answers wait there.
    pub fn send(&mut self, frame: Frame) -> Result<(), Closed> {
        if !self.overflow.is_empty() {
            self.overflow.push_back(frame);
            return Ok(());
        }
        match self.out.try_send(frame) {
            Ok(()) => {
                self.count_sent();
                Ok(())
            }
            Err(mpsc::error::TrySendError::Full(frame)) => {
                self.overflow.push_back(frame);
                self.overflow_since = Some(Instant::now());
                Ok(())
            }
            Err(mpsc::error::TrySendError::Closed(_)) => Err(Closed),
        }
    }

    /// Answers wait in the overflow.
    pub fn is_behind(&self) -> bool {
        !self.overflow.is_empty()
    }

    /// When the oldest overflowed answer has waited `slow_reader` (none when nothing waits).
    pub fn slow_reader_deadline(&self, slow_reader: Duration) -> Option<Instant> {
        self.overflow_since.map(|since| since + slow_reader)
    }

    /// The queue has room for more than `reserve` frames.
    pub fn has_room_beyond(&self, reserve: usize) -> bool {
        self.out.capacity() > reserve
    }

    /// Ready once the queue has room for `n` frames (the permits are given back at once).
    pub fn room(&self, n: usize) -> impl Future<Output = ()> + use<> {
        let out = self.out.clone();
        async move {
            let _ = out.reserve_many(n).await;
        }
    }

    /// Ready with a place in the queue for the oldest overflowed answer (cancel safe).
    pub fn place(&self) -> impl Future<Output = Result<mpsc::OwnedPermit<Frame>, Closed>> + use<> {
        let out = self.out.clone();
        async move { out.reserve_owned().await.map_err(|_| Closed) }
    }

    /// Moves the oldest overflowed answer into the queue.
    pub fn flush_one(&mut self, permit: mpsc::OwnedPermit<Frame>) {
        if let Some(frame) = self.overflow.pop_front() {
            permit.send(frame);
            self.count_sent();
        }
        if self.overflow.is_empty() {
            self.overflow_since = None;
        }
    }

    /// Sends after the overflowed answers, waiting for room (history and resyncs, which can be
    /// long). A client that takes nothing for `patience` is a slow reader.
    pub async fn send_wait(&mut self, frame: Frame, patience: Duration) -> Result<(), End> {
        let mut frames = std::mem::take(&mut self.overflow);
        self.overflow_since = None;
        frames.push_back(frame);
        for frame in frames {
            match tokio::time::timeout(patience, self.out.send(frame)).await {
                Ok(Ok(())) => self.count_sent(),
                Ok(Err(_)) => return Err(End::Gone),
                Err(_) => return Err(End::SlowReader),
            }
        }
        Ok(())
    }

    /// Ends the connection's output: the answers still owed go first (the acks of the last
    /// commits), then the close frame, each within `grace`; a slow reader or a client that is
    /// gone gets nothing more.
    pub async fn finish(self, end: &End, sender: JoinHandle<()>, grace: Duration) {
        let End::Close(code, reason) = end else {
            sender.abort();
            return;
        };
        let Outgoing { out, overflow, .. } = self;
        let frames = overflow.into_iter().chain([Frame::Close(Some((*code, reason.clone())))]);
        let _ = tokio::time::timeout(grace, async {
            for frame in frames {
                if out.send(frame).await.is_err() {
                    break;
                }
            }
        })
        .await;
        drop(out);
        let mut sender = sender;
        if tokio::time::timeout(grace, &mut sender).await.is_err() {
            sender.abort();
        }
    }

    fn count_sent(&self) {
        match self.form {
            Form::Binary => self.sent.0.increment(1),
            Form::Json => self.sent.1.increment(1),
        }
    }
}

/// Frames already queued go out with one flush (one write to the socket under load, as when a
/// session's events fan out), up to this many.
const FRAMES_PER_FLUSH: usize = 64;

/// Writes queued frames to the socket until the queue closes or a close frame went out.
pub async fn forward<Si: Sink<Frame>>(mut rx: mpsc::Receiver<Frame>, sink: Si) {
    let mut sink = std::pin::pin!(sink);
    'frames: while let Some(frame) = rx.recv().await {
        let mut closing = matches!(frame, Frame::Close(_));
        if sink.feed(frame).await.is_err() {
            break;
        }
        for _ in 1..FRAMES_PER_FLUSH {
            if closing {
                break;
            }
            let Ok(frame) = rx.try_recv() else { break };
            closing = matches!(frame, Frame::Close(_));
            if sink.feed(frame).await.is_err() {
                break 'frames;
            }
        }
        if sink.flush().await.is_err() || closing {
            break;
        }
    }
    let _ = sink.close().await;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text(i: usize) -> Frame {
        Frame::Text(i.to_string())
    }

    /// Everything queued, in the order sent.
    fn drain(rx: &mut mpsc::Receiver<Frame>) -> Vec<Frame> {
        std::iter::from_fn(|| rx.try_recv().ok()).collect()
    }

    #[test]
    fn answers_past_the_bound_wait_in_order_and_none_is_lost() {
        let (mut outgoing, mut rx) = Outgoing::new(4, &HotCounters::register());
        for i in 0..10 {
            outgoing.send(text(i)).unwrap();
        }
        assert!(outgoing.is_behind());
        assert_eq!(rx.len(), 4, "the queue holds no more than its capacity");
        let mut got = drain(&mut rx);
        // The reader catches up: each place in the queue takes the oldest waiting answer.
        while outgoing.is_behind() {
            let permit = outgoing.out.clone().try_reserve_owned().expect("room after a drain");
            outgoing.flush_one(permit);
            got.extend(drain(&mut rx));
        }
        assert_eq!(got, (0..10).map(text).collect::<Vec<_>>());
        assert_eq!(outgoing.slow_reader_deadline(Duration::from_secs(1)), None);
    }

    #[test]
    fn an_answer_after_an_overflow_waits_behind_it_even_when_the_queue_has_room() {
        let (mut outgoing, mut rx) = Outgoing::new(1, &HotCounters::register());
        outgoing.send(text(0)).unwrap();
        outgoing.send(text(1)).unwrap();
        assert_eq!(drain(&mut rx), vec![text(0)]);
        // Room now, but 1 waits: 2 must not overtake it.
        outgoing.send(text(2)).unwrap();
        assert!(rx.is_empty());
        assert_eq!(outgoing.overflow, VecDeque::from([text(1), text(2)]));
    }

    #[tokio::test(start_paused = true)]
    async fn the_slow_reader_deadline_counts_from_the_first_overflow() {
        let (mut outgoing, _rx) = Outgoing::new(1, &HotCounters::register());
        outgoing.send(text(0)).unwrap();
        assert_eq!(outgoing.slow_reader_deadline(Duration::from_secs(1)), None);
        let first = Instant::now();
        outgoing.send(text(1)).unwrap();
        tokio::time::advance(Duration::from_millis(300)).await;
        outgoing.send(text(2)).unwrap();
        assert_eq!(
            outgoing.slow_reader_deadline(Duration::from_secs(1)),
            Some(first + Duration::from_secs(1))
        );
    }

    #[tokio::test(start_paused = true)]
    async fn send_wait_goes_after_the_overflow_and_gives_up_on_a_reader_that_takes_nothing() {
        let (mut outgoing, mut rx) = Outgoing::new(2, &HotCounters::register());
        for i in 0..3 {
            outgoing.send(text(i)).unwrap();
        }
        let reader = tokio::spawn(async move {
            let mut got = Vec::new();
            while let Some(frame) = rx.recv().await {
                got.push(frame);
                if got.len() == 4 {
                    break;
                }
            }
            (got, rx)
        });
        outgoing.send_wait(text(3), Duration::from_secs(1)).await.unwrap();
        let (got, rx) = reader.await.unwrap();
        assert_eq!(got, (0..4).map(text).collect::<Vec<_>>());
        // Nobody reads any more: the queue fills, then the wait ends as a slow reader.
        outgoing.send(text(4)).unwrap();
        outgoing.send(text(5)).unwrap();
        let result = outgoing.send_wait(text(6), Duration::from_secs(1)).await;
        assert_eq!(result, Err(End::SlowReader));
        drop(rx);
        assert_eq!(outgoing.send_wait(text(7), Duration::from_secs(1)).await, Err(End::Gone));
        assert_eq!(outgoing.send(text(8)), Err(Closed));
    }

    #[tokio::test]
    async fn forward_writes_in_order_and_stops_after_the_close_frame() {
        let (tx, rx) = mpsc::channel(16);
        for i in 0..3 {
            tx.send(text(i)).await.unwrap();
        }
        tx.send(Frame::Close(Some((1000, "bye".into())))).await.unwrap();
        tx.send(text(99)).await.unwrap();
        let (sink_tx, mut sink_rx) = mpsc::channel(16);
        forward(rx, tokio_util::sync::PollSender::new(sink_tx)).await;
        let written = drain(&mut sink_rx);
        assert_eq!(written.len(), 4, "{written:?}");
        assert_eq!(written[3], Frame::Close(Some((1000, "bye".into()))));
    }
}
