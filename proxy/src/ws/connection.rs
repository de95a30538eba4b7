//! One connection's state, and what every part of it uses to answer: the outgoing queue, the
//! one place errors are answered (`fail`), and how the connection ends.

use std::collections::{HashMap, HashSet, VecDeque};
use std::pin::Pin;
use std::task::Poll;
use std::time::Duration;

use penmesh::Kept;
use penmesh::protocol::{ErrorMessage, PeerPlacement, ServerMessage, StrokeId};
use tokio::time::Instant;
use uuid::Uuid;

use super::Frame;
use super::error::{ConnError, End};
use super::outgoing::Outgoing;
use super::serve::Heartbeat;
use crate::fanout::{PeerView, Subscription};
use crate::ingest::StrokeState;
use crate::state::{AppState, ConnectionClaims, SessionGuard};
use crate::store::{Committed, PlacementIds, WriteError};

/// What to send once a write request commits. The retained samples the request's batch
/// decided go out with its answer, in the same write to the socket: one write per batch, as
/// the client sends one, and what the client is shown is stored, as for the peers.
#[derive(Debug)]
pub(super) enum AfterCommit {
    Ack {
        stroke: StrokeId,
        upto_seq: u64,
        retained: Decided,
    },
    Done {
        stroke: StrokeId,
        n_retained: u64,
        retained: Decided,
    },
    /// A request about a done stroke (taking it back or bringing it back): this answer.
    Answer {
        stroke: StrokeId,
        answer: ServerMessage,
    },
    /// A stroke placed anew (`SetPlacement`): this answer, in order with the stroke's other
    /// placements ([`Connection::answer_placement`]).
    Placed {
        answer: PeerPlacement,
    },
    /// A stroke's new solid (`SetSolid`): this answer, then its mesh (built before the
    /// commit) stored.
    Solid {
        answer: penmesh::protocol::PeerSolid,
        row: Box<crate::store::StrokeRow>,
        glb: Vec<u8>,
    },
}

/// Retained samples `first..first + kept.len()` of a stroke, decided by one request.
#[derive(Debug, Default)]
pub(super) struct Decided {
    pub first: u64,
    pub kept: Vec<Kept>,
}

/// `Points` batches of one stroke read in one wake-up of the connection, not yet handed to the
/// writer: they go as one request, one commit answer and one `Ack` (`Connection::gather`).
#[derive(Debug)]
pub(super) struct Gathered {
    pub stroke: StrokeId,
    /// The seq of the first sample.
    pub seq: u64,
    pub samples: Vec<penmesh::Sample>,
    pub retained: Decided,
}

impl Gathered {
    /// The seq after the last sample: what the `Ack` says.
    pub fn upto_seq(&self) -> u64 {
        self.seq + self.samples.len() as u64
    }
}

/// The connection's requests to the writer that await their commit, oldest first. The writer
/// answers one connection's requests in the order it got them, so only the oldest is polled.
#[derive(Debug, Default)]
pub(super) struct InFlight {
    queue: VecDeque<(Committed, AfterCommit)>,
}

impl InFlight {
    pub fn push(&mut self, committed: Committed, after: AfterCommit) {
        self.queue.push_back((committed, after));
    }

    pub fn len(&self) -> usize {
        self.queue.len()
    }

    pub fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }

    /// The oldest request's answer, once it has one (`None` when none is in flight).
    pub fn next(
        &mut self,
    ) -> impl Future<Output = Option<(Result<PlacementIds, WriteError>, AfterCommit)>> + '_ {
        std::future::poll_fn(move |cx| {
            let Some((committed, _)) = self.queue.front_mut() else {
                return Poll::Ready(None);
            };
            let result = std::task::ready!(Pin::new(committed).poll(cx));
            let (_, after) = self.queue.pop_front().expect("the oldest request is there");
            Poll::Ready(Some((result, after)))
        })
    }
}

pub(super) struct Connection {
    pub state: AppState,
    pub id: u64,
    /// Who is drawing: derived from `Hello.key` (crate::identity), a fresh id until then or
    /// without a key.
    pub participant: Uuid,
    /// This connection's presence row (`participants.connection`), named by its presence
    /// events: one participant may be on several connections at once.
    pub presence: Uuid,
    pub session: Uuid,
    pub _guard: SessionGuard,
    /// Lets go of every stroke this connection holds when dropped, a panic included.
    pub claims: ConnectionClaims,
    pub hello: bool,
    /// The participant row is written (and `Leave` is owed at the end).
    pub joined: bool,
    /// Every stroke drawn on this connection: its client has them, peer events skip them.
    pub own: HashSet<StrokeId>,
    /// Those of `own` the client knows to be taken back: a removal or restore of one is told
    /// once, however many times it is asked for.
    pub own_removed: HashSet<StrokeId>,
    /// What the client has of the other participants' strokes.
    pub view: PeerView,
    /// The session's events, once the client said hello.
    pub events: Option<Subscription>,
    /// When the last overflows happened: a reader that lags again and again is dropped, so
    /// that it does not reload the session's history from the database in a loop.
    pub lags: Vec<Instant>,
    /// Strokes being drawn on this connection (claimed through `claims`).
    pub strokes: HashMap<StrokeId, StrokeState>,
    /// Strokes whose `StrokeEnd` awaits its commit (still claimed).
    pub finishing: HashSet<StrokeId>,
    pub outgoing: Outgoing,
    pub pending: InFlight,
    pub end: Option<End>,
    /// When the last new name was stored, and the one that waits for its turn (the latest
    /// asked for): at most one rename per `RENAME_INTERVAL` (`ws/hello.rs`).
    pub renamed_at: Option<Instant>,
    pub pending_name: Option<String>,
    /// Batches read but not handed to the writer yet ([`Gathered`]).
    pub gathered: Option<Gathered>,
}

impl Connection {
    pub fn new(state: AppState, session: Uuid, guard: SessionGuard, outgoing: Outgoing) -> Self {
        let id = state.next_connection_id();
        Connection {
            id,
            participant: Uuid::new_v4(),
            presence: Uuid::new_v4(),
            session,
            _guard: guard,
            claims: ConnectionClaims::new(state.clone(), id),
            hello: false,
            joined: false,
            own: HashSet::new(),
            own_removed: HashSet::new(),
            view: PeerView::default(),
            events: None,
            lags: Vec::new(),
            strokes: HashMap::new(),
            finishing: HashSet::new(),
            outgoing,
            pending: InFlight::default(),
            end: None,
            renamed_at: None,
            pending_name: None,
            gathered: None,
            state,
        }
    }

    pub fn end_with(&mut self, end: End) {
        if self.end.is_none() {
            self.end = Some(end);
        }
    }

    pub fn send(&mut self, msg: ServerMessage) {
        let Some(frame) = self.outgoing.encode(&msg) else { return };
        self.send_frame(frame);
    }

    pub fn send_frame(&mut self, frame: Frame) {
        if self.outgoing.send(frame).is_err() {
            self.end_with(End::Gone);
        }
    }

    /// Sends, waiting for room in the outgoing queue (history and resyncs, which can be long),
    /// after the overflowed answers, so that the order holds. A client that takes nothing for
    /// as long as the heartbeat gives a silent one (three periods: the loop, and with it the
    /// heartbeat, waits meanwhile) is dropped as a slow reader.
    pub async fn send_wait(&mut self, msg: ServerMessage) {
        if self.end.is_some() {
            return;
        }
        let Some(frame) = self.outgoing.encode(&msg) else { return };
        let patience = Duration::from_millis(self.state.config.heartbeat_ms) * Heartbeat::MISSED;
        if let Err(end) = self.outgoing.send_wait(frame, patience).await {
            self.end_with(end);
        }
    }

    /// The one place a message that was not carried out is counted, logged and answered.
    pub fn fail(&mut self, err: ConnError) {
        let code = err.code();
        metrics::counter!("penmesh_errors_total", "code" => code.as_str()).increment(1);
        let (message, stroke, end) = match err {
            ConnError::Refused { message, stroke, .. } => {
                tracing::debug!(connection = self.id, code = code.as_str(), %message, "refused");
                (message, stroke, None)
            }
            ConnError::Internal { doing, cause, advice, stroke } => {
                tracing::error!(connection = self.id, ?stroke, error = %cause, "{doing} failed");
                (advice, stroke, None)
            }
            ConnError::Fatal { message, end, .. } => {
                tracing::debug!(connection = self.id, code = code.as_str(), %message, "closing");
                (message, None, Some(end))
            }
        };
        self.send(ServerMessage::Error(ErrorMessage { code, message, stroke }));
        if let Some(end) = end {
            self.end_with(end);
        }
    }
}
