//! Session fan-out: the events of a session (presence, strokes, meshes) delivered to every
//! connection of the session on this replica, each through its own **bounded** queue.
//!
//! Events are published by the group-commit writer once the data they describe is committed
//! (with SQLite straight into [`Fanout::dispatch`]; with PostgreSQL by `NOTIFY` inside the very
//! transaction that stores the data, and the listener of every replica dispatches them), so a
//! peer never sees what a crash could still lose, and events reach every replica in commit
//! order.
//!
//! A queue that is full (in events, or in bytes of samples) is not waited for: its subscriber
//! is marked lagged and dropped from the session, the other subscribers go on. The connection then resyncs from the database
//! ([`crate::ws`]), filtering with a [`PeerView`] of what its client already has, so the
//! client receives neither a gap nor a repeat.

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicU8, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use penmesh::protocol::{
    ParticipantId, PeerRetained, PointBatch, ServerMessage, StrokeId, encode_server,
    encode_server_json,
};
use tokio::sync::mpsc;
use uuid::Uuid;

use crate::events::{EventKind, SessionEvent};

/// An event as dispatched: shared by every subscriber, with its encodings made once (by the
/// first connection that sends it whole) for all the others.
#[derive(Debug)]
pub struct Published {
    pub event: SessionEvent,
    binary: OnceLock<Vec<u8>>,
    json: OnceLock<String>,
}

impl Published {
    pub fn new(event: SessionEvent) -> Published {
        Published { event, binary: OnceLock::new(), json: OnceLock::new() }
    }

    /// The binary frame of [`SessionEvent::message`].
    pub fn binary(&self) -> &[u8] {
        self.binary.get_or_init(|| encode_server(&self.event.message()))
    }

    /// The JSON frame of [`SessionEvent::message`].
    pub fn json(&self) -> &str {
        self.json.get_or_init(|| encode_server_json(&self.event.message()))
    }
}

/// Why a subscription ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lag {
    /// Its queue overflowed: the client is told `lagged`.
    Overflow,
    /// Events may have been lost upstream (the `LISTEN` connection dropped): a silent resync.
    Gap,
}

const LIVE: u8 = 0;
const OVERFLOW: u8 = 1;
const GAP: u8 = 2;

#[derive(Debug)]
struct Subscriber {
    id: u64,
    /// The connection subscribed (see [`SessionEvent::origin`]).
    connection: Option<u64>,
    tx: mpsc::Sender<Arc<Published>>,
    lag: Arc<AtomicU8>,
    /// Bytes of samples of the events in the queue ([`SessionEvent::sample_bytes`]).
    queued: Arc<AtomicUsize>,
    /// The most `queued` may reach with a further event (an event larger than that is taken
    /// by an empty queue).
    byte_limit: usize,
}

impl Subscriber {
    /// Counts `bytes` more in the queue if they fit.
    fn admit(&self, bytes: usize) -> bool {
        let queued = self.queued.load(Ordering::Acquire);
        if queued > 0 && queued + bytes > self.byte_limit {
            return false;
        }
        self.queued.fetch_add(bytes, Ordering::AcqRel);
        true
    }
}

#[derive(Debug, Default)]
struct Registry {
    sessions: HashMap<Uuid, Vec<Subscriber>>,
    next_id: u64,
}

/// The subscribers of every session on this replica. Cheap to clone.
#[derive(Debug, Clone)]
pub struct Fanout {
    registry: Arc<Mutex<Registry>>,
    /// This replica's tag in the events it notifies (`SessionEvent::from`): random, so that
    /// its listener knows its own events among the other replicas'.
    tag: u64,
}

impl Default for Fanout {
    fn default() -> Fanout {
        Fanout { registry: Arc::default(), tag: rand::random() }
    }
}

/// A connection's place in its session's fan-out; unsubscribes when dropped.
#[derive(Debug)]
pub struct Subscription {
    fanout: Fanout,
    session: Uuid,
    id: u64,
    rx: mpsc::Receiver<Arc<Published>>,
    lag: Arc<AtomicU8>,
    queued: Arc<AtomicUsize>,
}

impl Fanout {
    /// This replica's tag in the events it notifies.
    pub fn tag(&self) -> u64 {
        self.tag
    }

    /// Subscribes to `session`'s events with a queue of `capacity` events and `byte_limit`
    /// bytes of samples, for `connection`: events that connection caused are not handed back
    /// to it.
    pub fn subscribe(
        &self,
        session: Uuid,
        capacity: usize,
        byte_limit: usize,
        connection: Option<u64>,
    ) -> Subscription {
        let (tx, rx) = mpsc::channel(capacity.max(1));
        let lag = Arc::new(AtomicU8::new(LIVE));
        let queued = Arc::new(AtomicUsize::new(0));
        let mut registry = self.registry.lock().expect("fanout lock");
        registry.next_id += 1;
        let id = registry.next_id;
        let subscriber =
            Subscriber { id, connection, tx, lag: lag.clone(), queued: queued.clone(), byte_limit };
        registry.sessions.entry(session).or_default().push(subscriber);
        Subscription { fanout: self.clone(), session, id, rx, lag, queued }
    }

    /// Hands `event` to every subscriber of its session, never waiting: a subscriber whose
    /// queue is full, in events or in bytes, is marked lagged and removed.
    pub fn dispatch(&self, event: SessionEvent) {
        let session = event.session;
        let mut registry = self.registry.lock().expect("fanout lock");
        let Some(subscribers) = registry.sessions.get_mut(&session) else { return };
        let origin = event.origin;
        let is_origin = |s: &Subscriber| origin.is_some() && s.connection == origin;
        if subscribers.iter().all(is_origin) {
            return; // Only the connection that caused it listens: nobody to tell.
        }
        let bytes = event.sample_bytes();
        let event = Arc::new(Published::new(event));
        subscribers.retain(|s| {
            if is_origin(s) {
                return true;
            }
            // Counted before it is sent: the subscriber may take it at once.
            let sent = match s.admit(bytes) {
                true => s.tx.try_send(event.clone()),
                false => Err(mpsc::error::TrySendError::Full(event.clone())),
            };
            match sent {
                Ok(()) => true,
                Err(mpsc::error::TrySendError::Full(_)) => {
                    metrics::counter!("penmesh_fanout_lagged_total").increment(1);
                    s.lag.store(OVERFLOW, Ordering::Release);
                    false
                }
                Err(mpsc::error::TrySendError::Closed(_)) => false,
            }
        });
        if subscribers.is_empty() {
            registry.sessions.remove(&session);
        }
    }

    /// Marks every subscriber as having a gap (events were lost upstream): each resyncs.
    pub fn gap_all(&self) {
        let mut registry = self.registry.lock().expect("fanout lock");
        for (_, subscribers) in registry.sessions.drain() {
            for s in subscribers {
                s.lag.store(GAP, Ordering::Release);
            }
        }
    }

    /// The number of sessions with subscribers on this replica.
    pub fn n_sessions(&self) -> usize {
        self.registry.lock().expect("fanout lock").sessions.len()
    }

    /// The most events queued for one subscriber of `session`, and the queue capacity: what
    /// bounds a slow reader's memory.
    pub fn backlog(&self, session: Uuid) -> (usize, usize) {
        let registry = self.registry.lock().expect("fanout lock");
        registry
            .sessions
            .get(&session)
            .map(|subs| {
                subs.iter()
                    .map(|s| (s.tx.max_capacity() - s.tx.capacity(), s.tx.max_capacity()))
                    .max()
                    .unwrap_or((0, 0))
            })
            .unwrap_or((0, 0))
    }
}

impl Subscription {
    /// The next event, or the reason the subscription ended.
    pub async fn recv(&mut self) -> Result<Arc<Published>, Lag> {
        if let Some(lag) = self.lagged() {
            return Err(lag);
        }
        match self.rx.recv().await {
            Some(event) => {
                self.queued.fetch_sub(event.event.sample_bytes(), Ordering::AcqRel);
                Ok(event)
            }
            None => Err(self.lagged().unwrap_or(Lag::Gap)),
        }
    }

    /// Whether the subscription has ended, and why.
    pub fn lagged(&self) -> Option<Lag> {
        match self.lag.load(Ordering::Acquire) {
            OVERFLOW => Some(Lag::Overflow),
            GAP => Some(Lag::Gap),
            _ => None,
        }
    }

    /// Events waiting in the queue.
    pub fn queued(&self) -> usize {
        self.rx.len()
    }
}

impl Drop for Subscription {
    fn drop(&mut self) {
        let mut registry = self.fanout.registry.lock().expect("fanout lock");
        if let Some(subscribers) = registry.sessions.get_mut(&self.session) {
            subscribers.retain(|s| s.id != self.id);
            if subscribers.is_empty() {
                registry.sessions.remove(&self.session);
            }
        }
    }
}

/// What one client has received of each peer stroke and of presence: filters history and live
/// events so that the client gets each piece once, in order, whatever the mix of the two.
#[derive(Debug, Default)]
pub struct PeerView {
    strokes: HashMap<StrokeId, StrokeView>,
    /// The connections of each participant present: `PeerJoined` when the first appears,
    /// `PeerLeft` when the last goes (the name is the first connection's).
    present: HashMap<ParticipantId, HashSet<Uuid>>,
    /// The id of the newest placement the client holds of each stroke, a peer's or its own
    /// (told by a history, an event, or as the answer to its request): an older one or a
    /// repeat is not told, so that its strokes only ever move forward to their current one.
    placed: HashMap<StrokeId, i64>,
}

#[derive(Debug, Default, Clone, Copy)]
struct StrokeView {
    /// Retained samples received: the next `first` expected.
    n_retained: u64,
    done: bool,
    mesh_at: Option<i64>,
    /// Taken back (`StrokeRemoved` sent), until brought back.
    removed: bool,
}

/// What [`PeerView::admit`] decided.
#[derive(Debug, Clone, PartialEq)]
pub enum Admit {
    /// Send the event's message ([`SessionEvent::message`]) as it is.
    Whole,
    /// Send this part of it (the retained samples the client lacks).
    Part(ServerMessage),
    /// The client has it already.
    Skip,
    /// The event is past a gap (something before it was lost): resync.
    Gap,
    /// A stroke the client lacks entirely was brought back: send it whole, read from storage.
    Fetch(StrokeId),
}

impl PeerView {
    /// Decides what the client gets for `event`, and records it as received.
    pub fn admit(&mut self, event: &SessionEvent) -> Admit {
        match &event.kind {
            EventKind::Joined { participant, connection, .. } => {
                let connections = self.present.entry(*participant).or_default();
                let first = connections.is_empty();
                connections.insert(*connection);
                if first { Admit::Whole } else { Admit::Skip }
            }
            EventKind::Left { participant, connection } => {
                let Some(connections) = self.present.get_mut(participant) else {
                    return Admit::Skip;
                };
                if !connections.remove(connection) || !connections.is_empty() {
                    return Admit::Skip;
                }
                self.present.remove(participant);
                Admit::Whole
            }
            // Only of a participant the client knows to be present (else its join, to come or
            // in a history, carries the name).
            EventKind::Renamed { participant, .. } => {
                if self.present.contains_key(participant) {
                    Admit::Whole
                } else {
                    Admit::Skip
                }
            }
            EventKind::StrokeBegin { stroke, .. } => {
                if self.strokes.contains_key(stroke) {
                    return Admit::Skip;
                }
                self.strokes.insert(*stroke, StrokeView::default());
                Admit::Whole
            }
            // An event of a stroke the client never had is not a gap: within a subscription
            // events come in commit order after the history, which holds every stroke begun
            // before it except those taken back at the time. Such a stroke comes whole if it is
            // brought back (`Fetch`); until then its events (a mesh built in flight, another
            // upload) are none of the client's business.
            EventKind::Retained { participant, stroke, first, points } => {
                let Some(view) = self.strokes.get_mut(stroke) else { return Admit::Skip };
                let end = first + points.len() as u64;
                if end <= view.n_retained {
                    return Admit::Skip;
                }
                if *first > view.n_retained {
                    return Admit::Gap;
                }
                let from = view.n_retained;
                view.n_retained = end;
                if from == *first {
                    return Admit::Whole;
                }
                Admit::Part(ServerMessage::PeerRetained(PeerRetained {
                    participant: *participant,
                    stroke: *stroke,
                    first: from,
                    points: PointBatch(points[(from - first) as usize..].to_vec()),
                }))
            }
            EventKind::StrokeDone { stroke, n_retained, .. } => {
                let Some(view) = self.strokes.get_mut(stroke) else { return Admit::Skip };
                if view.done {
                    return Admit::Skip;
                }
                if view.n_retained != *n_retained {
                    return Admit::Gap;
                }
                view.done = true;
                Admit::Whole
            }
            EventKind::Mesh { stroke, created_at, .. } => {
                let Some(view) = self.strokes.get_mut(stroke) else { return Admit::Skip };
                if !view.done {
                    return Admit::Gap;
                }
                if view.mesh_at.is_some_and(|at| at >= *created_at) {
                    return Admit::Skip;
                }
                view.mesh_at = Some(*created_at);
                Admit::Whole
            }
            // A stroke the client never had (it joined while the stroke was taken back) need
            // not be hidden; brought back, the client lacks all of it: it is read from storage
            // and sent whole, like a history's stroke.
            EventKind::Removed { stroke, .. } => match self.strokes.get_mut(stroke) {
                Some(view) if !view.removed => {
                    view.removed = true;
                    Admit::Whole
                }
                _ => Admit::Skip,
            },
            EventKind::Restored { stroke, .. } => match self.strokes.get_mut(stroke) {
                Some(view) if view.removed => {
                    view.removed = false;
                    Admit::Whole
                }
                Some(_) => Admit::Skip,
                None => Admit::Fetch(*stroke),
            },
            // Of a stroke the client has, when newer than what it holds (a history and the live
            // events overlap; another replica's notification can arrive after a newer
            // placement). Of one it lacks: its history (or its begin, to come) carries it. The
            // identity is what a client assumes of a stroke it was told no placement of, so it
            // is told only to a client that holds another (as a history does): a stroke begun,
            // duplicated or imported at the identity gets no `PeerPlacement`, live or not.
            EventKind::Placed { stroke, id, placement, .. } => {
                let assumed = placement.is_identity() && self.placement_held(stroke) == 0;
                if self.strokes.contains_key(stroke)
                    && self.tell_placement(*stroke, *id)
                    && !assumed
                {
                    Admit::Whole
                } else {
                    Admit::Skip
                }
            }
            // Of a stroke the client has; of one it lacks, its history carries it.
            EventKind::Solid { stroke, .. } => {
                if self.strokes.contains_key(stroke) {
                    Admit::Whole
                } else {
                    Admit::Skip
                }
            }
        }
    }

    /// Records that the client was told a peer stroke is taken back (`removed`) or brought
    /// back, as the answer to its own request; `false` when it knew already or never had it.
    pub fn set_removed(&mut self, stroke: StrokeId, removed: bool) -> bool {
        match self.strokes.get_mut(&stroke) {
            Some(view) if view.removed != removed => {
                view.removed = removed;
                true
            }
            _ => false,
        }
    }

    /// Records that the client holds placement `id` (a `stroke_placements` row id) of `stroke`;
    /// `false` when it holds that one or a newer one already (then it is not to be told).
    pub fn tell_placement(&mut self, stroke: StrokeId, id: i64) -> bool {
        let held = self.placed.entry(stroke).or_default();
        if id <= *held {
            return false;
        }
        *held = id;
        true
    }

    /// The id of the newest placement of `stroke` the client holds (0: none).
    pub fn placement_held(&self, stroke: &StrokeId) -> i64 {
        self.placed.get(stroke).copied().unwrap_or(0)
    }

    /// Whether the client has heard of the peer stroke `stroke`.
    pub fn has_stroke(&self, stroke: &StrokeId) -> bool {
        self.strokes.contains_key(stroke)
    }

    /// Peer strokes the client has heard of.
    pub fn n_strokes(&self) -> usize {
        self.strokes.len()
    }
}

#[cfg(test)]
mod tests {
    use penmesh::{Brush, Sample};

    use super::*;

    fn retained(stroke: Uuid, first: u64, n: usize) -> SessionEvent {
        let points = (0..n).map(|i| Sample::new(i as f64, 0.0, i as f64, 0.5)).collect();
        SessionEvent::new(
            Uuid::nil(),
            EventKind::Retained { participant: Uuid::nil(), stroke, first, points },
        )
    }

    fn begin(stroke: Uuid) -> SessionEvent {
        SessionEvent::new(
            Uuid::nil(),
            EventKind::StrokeBegin { participant: Uuid::nil(), stroke, brush: Brush::default() },
        )
    }

    #[test]
    fn the_view_drops_repeats_trims_overlaps_and_spots_gaps() {
        let stroke = Uuid::new_v4();
        let mut view = PeerView::default();
        assert_eq!(view.admit(&retained(stroke, 0, 3)), Admit::Skip, "a stroke never had");
        assert_eq!(view.admit(&begin(stroke)), Admit::Whole);
        assert_eq!(view.admit(&begin(stroke)), Admit::Skip);
        assert_eq!(view.admit(&retained(stroke, 0, 5)), Admit::Whole);
        assert_eq!(view.admit(&retained(stroke, 2, 3)), Admit::Skip);
        match view.admit(&retained(stroke, 3, 4)) {
            Admit::Part(ServerMessage::PeerRetained(r)) => {
                assert_eq!((r.first, r.points.0.len()), (5, 2));
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(view.admit(&retained(stroke, 9, 1)), Admit::Gap);
    }

    fn removal(stroke: Uuid, removed: bool) -> SessionEvent {
        let (participant, by) = (Uuid::nil(), Uuid::nil());
        let kind = if removed {
            EventKind::Removed { participant, stroke, by }
        } else {
            EventKind::Restored { participant, stroke, by }
        };
        SessionEvent::new(Uuid::nil(), kind)
    }

    // A removal and a restore reach the client once each, in turn; a stroke the client never
    // had is not hidden, its events are not a gap, and brought back it is fetched whole.
    #[test]
    fn removals_and_restores_are_told_once_and_an_unknown_restore_is_fetched() {
        let (known, unknown) = (Uuid::new_v4(), Uuid::new_v4());
        let mut view = PeerView::default();
        assert_eq!(view.admit(&begin(known)), Admit::Whole);
        assert_eq!(view.admit(&removal(known, false)), Admit::Skip, "not removed");
        assert_eq!(view.admit(&removal(known, true)), Admit::Whole);
        assert_eq!(view.admit(&removal(known, true)), Admit::Skip, "a repeat");
        assert_eq!(view.admit(&removal(known, false)), Admit::Whole);
        assert_eq!(view.admit(&removal(known, false)), Admit::Skip, "a repeat");
        assert_eq!(view.admit(&removal(unknown, true)), Admit::Skip);
        let mesh = EventKind::Mesh { participant: Uuid::nil(), stroke: unknown, created_at: 1 };
        assert_eq!(view.admit(&SessionEvent::new(Uuid::nil(), mesh)), Admit::Skip);
        assert_eq!(view.admit(&removal(unknown, false)), Admit::Fetch(unknown));
    }

    fn placed(stroke: Uuid, id: i64) -> SessionEvent {
        placed_at(stroke, id, penmesh::Placement::new(moved()).unwrap())
    }

    /// The identity moved 250 along x.
    fn moved() -> [f64; 16] {
        let mut m = *penmesh::Placement::IDENTITY.matrix();
        m[12] = 250.0;
        m
    }

    fn placed_at(stroke: Uuid, id: i64, placement: penmesh::Placement) -> SessionEvent {
        let kind = EventKind::Placed { participant: Uuid::nil(), stroke, placement, id };
        SessionEvent::new(Uuid::nil(), kind)
    }

    // A placement is told once, and never after a newer one: a history and the live events
    // overlap, and another replica's notification can come after a newer placement.
    #[test]
    fn placements_are_told_once_and_never_an_older_one_after_a_newer_one() {
        let (stroke, unknown) = (Uuid::new_v4(), Uuid::new_v4());
        let mut view = PeerView::default();
        assert_eq!(view.admit(&placed(stroke, 3)), Admit::Skip, "a stroke never had");
        assert_eq!(view.admit(&begin(stroke)), Admit::Whole);
        assert_eq!(view.admit(&placed(stroke, 3)), Admit::Whole);
        assert_eq!(view.admit(&placed(stroke, 3)), Admit::Skip, "a repeat");
        assert_eq!(view.admit(&placed(stroke, 2)), Admit::Skip, "an older one");
        assert!(view.tell_placement(stroke, 7), "the client's own change, answered");
        assert_eq!(view.admit(&placed(stroke, 5)), Admit::Skip, "older than its answer");
        assert_eq!(view.admit(&placed(stroke, 8)), Admit::Whole);
        assert_eq!(view.placement_held(&stroke), 8);
        assert_eq!(view.placement_held(&unknown), 0);
    }

    // The identity is told only to a client that holds another placement of the stroke: a
    // stroke begun (or duplicated, imported) at the identity is not followed by one, live as
    // in a history; a stroke moved back to the identity is.
    #[test]
    fn the_identity_is_told_only_after_another_placement() {
        let stroke = Uuid::new_v4();
        let identity = penmesh::Placement::IDENTITY;
        let mut view = PeerView::default();
        assert_eq!(view.admit(&begin(stroke)), Admit::Whole);
        assert_eq!(view.admit(&placed_at(stroke, 1, identity)), Admit::Skip, "assumed");
        assert_eq!(view.admit(&placed(stroke, 2)), Admit::Whole);
        assert_eq!(view.admit(&placed_at(stroke, 3, identity)), Admit::Whole, "moved back");
        assert_eq!(view.admit(&placed_at(stroke, 1, identity)), Admit::Skip, "an older one");
    }

    fn joined(participant: Uuid, connection: Uuid) -> SessionEvent {
        SessionEvent::new(
            Uuid::nil(),
            EventKind::Joined { participant, connection, name: "p".into() },
        )
    }

    fn left(participant: Uuid, connection: Uuid) -> SessionEvent {
        SessionEvent::new(Uuid::nil(), EventKind::Left { participant, connection })
    }

    /// One participant on two connections (a reconnect whose new connection says hello before
    /// the old one's end is noticed): joined once, and left only when the last one leaves.
    #[test]
    fn a_participant_is_present_while_any_of_its_connections_is() {
        let (p, first, second) = (Uuid::new_v4(), Uuid::new_v4(), Uuid::new_v4());
        let mut view = PeerView::default();
        assert_eq!(view.admit(&joined(p, first)), Admit::Whole);
        assert_eq!(view.admit(&joined(p, first)), Admit::Skip, "a repeat (history and live)");
        assert_eq!(view.admit(&joined(p, second)), Admit::Skip, "already present");
        assert_eq!(view.admit(&left(p, first)), Admit::Skip, "still on the second connection");
        assert_eq!(view.admit(&left(p, first)), Admit::Skip);
        assert_eq!(view.admit(&left(p, second)), Admit::Whole);
        assert_eq!(view.admit(&left(p, second)), Admit::Skip, "not present");
        assert_eq!(view.admit(&joined(p, Uuid::new_v4())), Admit::Whole, "back");
    }

    #[tokio::test]
    async fn a_full_queue_lags_its_subscriber_only() {
        let fanout = Fanout::default();
        let session = Uuid::nil();
        let mut slow = fanout.subscribe(session, 2, usize::MAX, None);
        let mut fast = fanout.subscribe(session, 100, usize::MAX, None);
        for i in 0..5 {
            fanout.dispatch(retained(Uuid::nil(), i, 1));
            fast.recv().await.unwrap();
        }
        assert_eq!(slow.recv().await.unwrap_err(), Lag::Overflow);
        assert_eq!(fanout.backlog(session), (0, 100));
    }

    #[tokio::test]
    async fn a_queue_full_in_bytes_of_samples_lags_its_subscriber_only() {
        let fanout = Fanout::default();
        let session = Uuid::nil();
        let sample = std::mem::size_of::<Sample>();
        // Room for 10 samples: the events of 4, 4 and 3 samples do not fit together.
        let mut slow = fanout.subscribe(session, 100, 10 * sample, None);
        let mut fast = fanout.subscribe(session, 100, 10 * sample, None);
        for (first, n) in [(0, 4), (4, 4), (8, 3)] {
            fanout.dispatch(retained(Uuid::nil(), first, n));
            fast.recv().await.unwrap();
        }
        assert_eq!(slow.queued(), 2, "the two events that fit");
        assert_eq!(slow.recv().await.unwrap_err(), Lag::Overflow);
        // An event larger than the whole limit reaches a subscriber whose queue is empty.
        fanout.dispatch(retained(Uuid::nil(), 11, 50));
        assert_eq!(fast.recv().await.unwrap().event.sample_bytes(), 50 * sample);
    }

    #[tokio::test]
    async fn an_event_is_not_handed_back_to_the_connection_that_caused_it() {
        let fanout = Fanout::default();
        let session = Uuid::nil();
        let mut drawer = fanout.subscribe(session, 10, usize::MAX, Some(1));
        let mut peer = fanout.subscribe(session, 10, usize::MAX, Some(2));
        let mut theirs = retained(Uuid::new_v4(), 0, 1);
        theirs.origin = Some(1);
        fanout.dispatch(theirs.clone());
        fanout.dispatch(begin(Uuid::new_v4())); // no origin (a mesh upload, another replica)
        assert_eq!(peer.recv().await.unwrap().event, theirs);
        assert_eq!(peer.queued(), 1);
        assert_eq!(drawer.queued(), 1, "only the event it did not cause");
        assert!(drawer.recv().await.unwrap().event.origin.is_none());
        // Alone in its session, the drawer's events are not even published.
        drop(peer);
        fanout.dispatch(theirs);
        assert_eq!((drawer.queued(), fanout.n_sessions()), (0, 1));
    }
}
