//! What goes out to one client: a bounded queue of frames, written to the socket by a task of
//! its own ([`forward`]), and the overflow of answers already owed.
//!
//! The bound: the queue holds at most its capacity in frames, and takes a frame only while it
//! holds fewer bytes than its byte limit, so at most the limit plus one frame (a frame larger
//! than the whole limit still goes out). An answer that finds it full waits in the
//! overflow, in order, and while the overflow is not empty the connection reads no frame and
//! takes no peer event, so only the answers already owed (at most `max_inflight` acks, and the
//! one peer event being sent) can join it. A socket that takes none of them for
//! `slow_reader_ms` belongs to a slow reader; one that does was only behind by a burst (a group
//! commit acknowledges many batches at once).
//!
//! Peer events leave a quarter of the queue, in frames and in bytes, to the connection's own
//! answers ([`Outgoing::has_room_for_events`]).

use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use futures_util::{Sink, SinkExt};
use penmesh::protocol::{ServerMessage, encode_server_as, encode_server_json_as};
use tokio::sync::{Notify, mpsc};
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
    out: mpsc::Sender<Queued>,
    /// The bytes of the frames in `out`.
    bytes: Arc<QueuedBytes>,
    /// Frames of the queue kept for the connection's own answers.
    reserve: usize,
    /// Answers that found the queue full, in order, and since when.
    overflow: VecDeque<Frame>,
    overflow_since: Option<Instant>,
    /// The form of the client's latest frame, which answers take.
    pub form: Form,
    /// The protocol version of the client's `Hello` (the current one until then): a
    /// version-4 client's frames carry its version byte and no message it lacks.
    pub version: u16,
    /// Frames sent, binary and text.
    sent: (metrics::Counter, metrics::Counter),
}

/// The bytes of the frames in a queue, and their limit: given back, with a wake-up, when the
/// writing task takes a frame.
#[derive(Debug)]
struct QueuedBytes {
    queued: AtomicUsize,
    limit: usize,
    taken: Notify,
}

impl QueuedBytes {
    fn below(&self, threshold: usize) -> bool {
        self.queued.load(Ordering::Acquire) < threshold
    }

    /// Ready once fewer than `threshold` bytes are queued (one task waits: the connection's).
    async fn wait_below(&self, threshold: usize) {
        loop {
            let taken = self.taken.notified();
            if self.below(threshold) {
                return;
            }
            taken.await;
        }
    }
}

/// A frame in the queue, counted in the queue's bytes until [`forward`] takes it out.
#[derive(Debug)]
pub(super) struct Queued {
    frame: Frame,
    bytes: Arc<QueuedBytes>,
}

impl Queued {
    fn new(frame: Frame, bytes: &Arc<QueuedBytes>) -> Queued {
        bytes.queued.fetch_add(frame_bytes(&frame), Ordering::AcqRel);
        Queued { frame, bytes: bytes.clone() }
    }
}

impl From<Queued> for Frame {
    fn from(queued: Queued) -> Frame {
        let Queued { frame, bytes } = queued;
        bytes.queued.fetch_sub(frame_bytes(&frame), Ordering::AcqRel);
        bytes.taken.notify_one();
        frame
    }
}

/// The bytes a frame counts for: its payload.
fn frame_bytes(frame: &Frame) -> usize {
    match frame {
        Frame::Text(text) => text.len(),
        Frame::Binary(bytes) | Frame::Ping(bytes) | Frame::Pong(bytes) => bytes.len(),
        Frame::Close(close) => close.as_ref().map_or(0, |(_, reason)| reason.len()),
    }
}

impl Outgoing {
    /// A queue of `capacity` frames and `byte_limit` bytes, and its other end for [`forward`].
    pub fn new(
        capacity: usize,
        byte_limit: usize,
        counters: &HotCounters,
    ) -> (Outgoing, mpsc::Receiver<Queued>) {
        let capacity = capacity.max(1);
        let (out, rx) = mpsc::channel(capacity);
        let bytes = Arc::new(QueuedBytes {
            queued: AtomicUsize::new(0),
            limit: byte_limit.max(1),
            taken: Notify::new(),
        });
        let sent = (counters.frames_out_binary.clone(), counters.frames_out_text.clone());
        let outgoing = Outgoing {
            out,
            bytes,
            reserve: capacity / 4,
            overflow: VecDeque::new(),
            overflow_since: None,
            form: Form::Binary,
            version: penmesh::protocol::PROTOCOL_VERSION,
            sent,
        };
        (outgoing, rx)
    }

    /// The frame of `msg` for this client; none when its protocol version lacks the message.
    pub fn encode(&self, msg: &ServerMessage) -> Option<Frame> {
        match self.form {
            Form::Binary => encode_server_as(msg, self.version).map(Frame::Binary),
            Form::Json => encode_server_json_as(msg, self.version).map(Frame::Text),
        }
    }

    /// Queues an answer now: into the queue, or into the overflow when the queue is full or
    /// older answers wait there.
    pub fn send(&mut self, frame: Frame) -> Result<(), Closed> {
        if !self.overflow.is_empty() {
            self.overflow.push_back(frame);
            return Ok(());
        }
        let permit = match self.out.try_reserve() {
            Ok(permit) if self.bytes.below(self.bytes.limit) => permit,
            Ok(_) | Err(mpsc::error::TrySendError::Full(())) => {
                self.overflow.push_back(frame);
                self.overflow_since = Some(Instant::now());
                return Ok(());
            }
            Err(mpsc::error::TrySendError::Closed(())) => return Err(Closed),
        };
        permit.send(Queued::new(frame, &self.bytes));
        self.count_sent();
        Ok(())
    }

    /// Answers wait in the overflow.
    pub fn is_behind(&self) -> bool {
        !self.overflow.is_empty()
    }

    /// When the oldest overflowed answer has waited `slow_reader` (none when nothing waits).
    pub fn slow_reader_deadline(&self, slow_reader: Duration) -> Option<Instant> {
        self.overflow_since.map(|since| since + slow_reader)
    }

    /// Below this many queued bytes a peer event may be taken.
    fn event_bytes(&self) -> usize {
        self.bytes.limit - self.bytes.limit / 4
    }

    /// The queue has room for a peer event beyond what it keeps for the connection's answers:
    /// more than a quarter of its frames free, and fewer than three quarters of its bytes
    /// queued.
    pub fn has_room_for_events(&self) -> bool {
        self.out.capacity() > self.reserve && self.bytes.below(self.event_bytes())
    }

    /// Ready once [`Outgoing::has_room_for_events`] holds (the frame permits are given back at
    /// once).
    pub fn room_for_events(&self) -> impl Future<Output = ()> + use<> {
        let (out, bytes, n, threshold) =
            (self.out.clone(), self.bytes.clone(), self.reserve + 1, self.event_bytes());
        async move {
            let _ = out.reserve_many(n).await;
            bytes.wait_below(threshold).await;
        }
    }

    /// Ready with a place in the queue for the oldest overflowed answer (cancel safe).
    pub fn place(&self) -> impl Future<Output = Result<mpsc::OwnedPermit<Queued>, Closed>> + use<> {
        let (out, bytes) = (self.out.clone(), self.bytes.clone());
        async move {
            let permit = out.reserve_owned().await.map_err(|_| Closed)?;
            bytes.wait_below(bytes.limit).await;
            Ok(permit)
        }
    }

    /// Moves the oldest overflowed answer into the queue.
    pub fn flush_one(&mut self, permit: mpsc::OwnedPermit<Queued>) {
        if let Some(frame) = self.overflow.pop_front() {
            permit.send(Queued::new(frame, &self.bytes));
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
            let place = async {
                self.bytes.wait_below(self.bytes.limit).await;
                self.out.reserve().await
            };
            match tokio::time::timeout(patience, place).await {
                Ok(Ok(permit)) => {
                    permit.send(Queued::new(frame, &self.bytes));
                    self.count_sent();
                }
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
        let Outgoing { out, bytes, overflow, .. } = self;
        let frames = overflow.into_iter().chain([Frame::Close(Some((*code, reason.clone())))]);
        let _ = tokio::time::timeout(grace, async {
            for frame in frames {
                if out.send(Queued::new(frame, &bytes)).await.is_err() {
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

/// Writes queued frames to the socket until the queue closes or a close frame went out. A
/// frame leaves the queue's count ([`Queued`]) as it is handed to the socket.
pub async fn forward<F: Into<Frame>, Si: Sink<Frame>>(mut rx: mpsc::Receiver<F>, sink: Si) {
    let mut sink = std::pin::pin!(sink);
    'frames: while let Some(frame) = rx.recv().await {
        let frame = frame.into();
        let mut closing = matches!(frame, Frame::Close(_));
        if sink.feed(frame).await.is_err() {
            break;
        }
        for _ in 1..FRAMES_PER_FLUSH {
            if closing {
                break;
            }
            let Ok(frame) = rx.try_recv() else { break };
            let frame = frame.into();
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
    fn drain<F: Into<Frame>>(rx: &mut mpsc::Receiver<F>) -> Vec<Frame> {
        std::iter::from_fn(|| rx.try_recv().ok().map(Into::into)).collect()
    }

    #[test]
    fn answers_past_the_bound_wait_in_order_and_none_is_lost() {
        let (mut outgoing, mut rx) = Outgoing::new(4, usize::MAX, &HotCounters::register());
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
    fn the_queue_holds_no_more_than_its_bytes_and_one_frame_and_none_is_lost() {
        let big = |i: usize| Frame::Binary(vec![i as u8; 300]);
        let (mut outgoing, mut rx) = Outgoing::new(100, 1000, &HotCounters::register());
        for i in 0..10 {
            outgoing.send(big(i)).unwrap();
        }
        // 0, 300, 600 and 900 bytes were queued when each of the first four went in.
        assert_eq!(rx.len(), 4, "frames go in while fewer than 1000 bytes are queued");
        assert_eq!(outgoing.bytes.queued.load(Ordering::Acquire), 1200);
        assert!(outgoing.is_behind());
        let mut got = drain(&mut rx);
        assert_eq!(
            outgoing.bytes.queued.load(Ordering::Acquire),
            0,
            "taken frames are not counted"
        );
        while outgoing.is_behind() {
            let permit = outgoing.out.clone().try_reserve_owned().expect("room after a drain");
            outgoing.flush_one(permit);
            got.extend(drain(&mut rx));
        }
        assert_eq!(got, (0..10).map(big).collect::<Vec<_>>());
        // A frame larger than the whole limit still goes out.
        outgoing.send(Frame::Binary(vec![0; 5000])).unwrap();
        assert!(!outgoing.is_behind());
    }

    #[test]
    fn peer_events_leave_a_quarter_of_the_bytes_to_the_answers() {
        let (mut outgoing, mut rx) = Outgoing::new(100, 1000, &HotCounters::register());
        assert!(outgoing.has_room_for_events());
        outgoing.send(Frame::Binary(vec![0; 700])).unwrap();
        assert!(outgoing.has_room_for_events(), "700 of 1000 bytes queued");
        outgoing.send(Frame::Binary(vec![0; 50])).unwrap();
        assert!(!outgoing.has_room_for_events(), "750 of 1000 bytes queued");
        // The answers still have the rest.
        outgoing.send(Frame::Binary(vec![0; 200])).unwrap();
        assert!(!outgoing.is_behind());
        drain(&mut rx);
        assert!(outgoing.has_room_for_events());
    }

    #[tokio::test(start_paused = true)]
    async fn the_wait_for_room_ends_when_the_writer_takes_bytes() {
        let (mut outgoing, mut rx) = Outgoing::new(100, 1000, &HotCounters::register());
        outgoing.send(Frame::Binary(vec![0; 900])).unwrap();
        let room = outgoing.room_for_events();
        let mut room = std::pin::pin!(room);
        assert!(futures_util::poll!(room.as_mut()).is_pending());
        drain(&mut rx);
        tokio::time::timeout(Duration::from_secs(1), room).await.expect("woken by the take");
        // The same for the oldest overflowed answer.
        outgoing.send(Frame::Binary(vec![0; 1000])).unwrap();
        outgoing.send(text(1)).unwrap();
        assert!(outgoing.is_behind());
        let place = outgoing.place();
        let mut place = std::pin::pin!(place);
        assert!(futures_util::poll!(place.as_mut()).is_pending());
        drain(&mut rx);
        let permit = tokio::time::timeout(Duration::from_secs(1), place).await.unwrap().unwrap();
        outgoing.flush_one(permit);
        assert_eq!(drain(&mut rx), vec![text(1)]);
    }

    #[test]
    fn an_answer_after_an_overflow_waits_behind_it_even_when_the_queue_has_room() {
        let (mut outgoing, mut rx) = Outgoing::new(1, usize::MAX, &HotCounters::register());
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
        let (mut outgoing, _rx) = Outgoing::new(1, usize::MAX, &HotCounters::register());
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
        let (mut outgoing, mut rx) = Outgoing::new(2, usize::MAX, &HotCounters::register());
        for i in 0..3 {
            outgoing.send(text(i)).unwrap();
        }
        let reader = tokio::spawn(async move {
            let mut got = Vec::new();
            while let Some(frame) = rx.recv().await {
                got.push(Frame::from(frame));
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
