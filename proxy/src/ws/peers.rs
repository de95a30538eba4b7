//! The session's events to this client: live events through the connection's `PeerView`,
//! and the resync from storage after a gap or an overflow (`lagged`).

use std::sync::Arc;
use std::time::Duration;

use penmesh::protocol::{
    ErrorCode, ErrorMessage, HistoryStroke, PeerStrokes, PointBatch, ServerMessage, StrokeId,
    Synced,
};
use tokio::time::Instant;

use super::connection::Connection;
use super::error::{ConnError, End};
use crate::events::{EventKind, SessionEvent};
use crate::fanout::{Admit, Lag, PeerView, Published, Subscription};

/// A connection that overflows its queue more than `MAX_LAGS` times within `LAG_WINDOW` is
/// dropped (its client reconnects and resumes) instead of resynced once more.
const MAX_LAGS: usize = 3;
const LAG_WINDOW: Duration = Duration::from_secs(60);

/// The next event of the subscription; never ready without one.
pub(super) async fn next_event(events: &mut Option<Subscription>) -> Result<Arc<Published>, Lag> {
    match events {
        Some(events) => events.recv().await,
        None => std::future::pending().await,
    }
}

impl Connection {
    /// A live event of the session.
    pub(super) async fn on_event(&mut self, published: &Published) {
        let event = &published.event;
        let admit = match &event.kind {
            // The client has its own strokes, so it is told when one is taken back or brought
            // back elsewhere (over HTTP, or by another connection of its participant).
            EventKind::Removed { stroke, .. } | EventKind::Restored { stroke, .. }
                if self.own.contains(stroke) =>
            {
                let removed = matches!(event.kind, EventKind::Removed { .. });
                if self.told_removed(*stroke, removed) { Admit::Whole } else { Admit::Skip }
            }
            // Likewise a placement of its own stroke set elsewhere, when newer than what it
            // holds.
            EventKind::Placed { stroke, id, .. } if self.own.contains(stroke) => {
                if self.view.tell_placement(*stroke, *id) { Admit::Whole } else { Admit::Skip }
            }
            // And its solid set elsewhere (over HTTP).
            EventKind::Solid { stroke, .. } if self.own.contains(stroke) => Admit::Whole,
            // And a mesh of its own stroke, which is stored over HTTP (an upload or a build),
            // never on this connection: the mesh is announced to the whole session.
            EventKind::Mesh { stroke, .. } if self.own.contains(stroke) => Admit::Whole,
            _ if self.is_own(event) => return,
            _ => self.view.admit(event),
        };
        match admit {
            Admit::Whole => {
                self.state.counters.fanout_events.increment(1);
                // Encoded once for every participant of the session.
                if let Some(frame) = self.published_frame(published) {
                    self.send_frame(frame);
                }
            }
            Admit::Part(msg) => {
                self.state.counters.fanout_events.increment(1);
                self.send(msg);
            }
            Admit::Skip => {}
            Admit::Gap => {
                tracing::warn!(connection = self.id, ?event, "peer event past a gap; resyncing");
                self.resync(Some(Lag::Gap)).await;
            }
            Admit::Fetch(stroke) => {
                self.state.counters.fanout_events.increment(1);
                self.send_whole_stroke(stroke).await;
            }
        }
    }

    /// A stroke the client never had (brought back, or placed by the client before its events
    /// reached it): read from storage and sent whole, as a history sends it (`PeerStrokes`
    /// carrying its placement and solid; for a client of version 5 or 4, `PeerStrokes` then its
    /// placement). Taken back meanwhile, nothing is sent (its events that follow are skipped).
    /// A read that fails falls back to a resync.
    pub(super) async fn send_whole_stroke(&mut self, stroke: StrokeId) {
        metrics::counter!("penmesh_fanout_fetches_total").increment(1);
        let events = match self.state.store.stroke_history(stroke).await {
            Ok(Some(events)) => events,
            Ok(None) => return,
            Err(err) => {
                tracing::warn!(connection = self.id, %stroke, error = %err, "reading a stroke brought back; resyncing");
                return self.resync(Some(Lag::Gap)).await;
            }
        };
        let batch = self.state.config.max_batch_samples.max(1);
        let mut whole = WholeStrokes::carrying(self.outgoing.version);
        if let Some(rest) = whole.take(&mut self.view, events, batch) {
            for event in rest {
                self.send_history_event(event, batch).await;
            }
        }
        if let Some(msg) = whole.flush() {
            self.send_wait(msg).await;
        }
        for event in std::mem::take(&mut whole.later) {
            self.send_history_event(event, batch).await;
        }
    }

    /// Records that the client is told `stroke` is taken back (`removed`) or brought back;
    /// `false` when it knew already (or never had the stroke).
    pub(super) fn told_removed(&mut self, stroke: StrokeId, removed: bool) -> bool {
        if !self.own.contains(&stroke) {
            return self.view.set_removed(stroke, removed);
        }
        if removed { self.own_removed.insert(stroke) } else { self.own_removed.remove(&stroke) }
    }

    fn is_own(&self, event: &SessionEvent) -> bool {
        match &event.kind {
            EventKind::Joined { participant, .. }
            | EventKind::Left { participant, .. }
            | EventKind::Renamed { participant, .. } => *participant == self.participant,
            _ => event.stroke().is_some_and(|s| self.own.contains(&s)),
        }
    }

    /// (Re)joins the session's fan-out, then sends the history the client lacks and `Synced`.
    /// `lag` says why a previous subscription ended (`None` on the first join).
    pub(super) async fn resync(&mut self, lag: Option<Lag>) {
        self.events = None;
        if lag == Some(Lag::Overflow) {
            let now = Instant::now();
            self.lags.retain(|at| now.duration_since(*at) < LAG_WINDOW);
            self.lags.push(now);
            if self.lags.len() > MAX_LAGS {
                tracing::info!(connection = self.id, "lagged again and again: disconnecting");
                return self.fail(ConnError::fatal(
                    ErrorCode::Lagged,
                    "this connection keeps falling behind the session's events; reconnect",
                    End::SlowReader,
                ));
            }
            self.fail(ConnError::refused(
                ErrorCode::Lagged,
                "this connection fell behind the session's events; resending what it lacks from storage",
                None,
            ));
        }
        if self.end.is_some() {
            return;
        }
        metrics::counter!("penmesh_fanout_syncs_total").increment(1);
        let (capacity, bytes) =
            (self.state.config.outgoing_queue, self.state.config.outgoing_queue_bytes);
        self.events =
            Some(self.state.fanout.subscribe(self.session, capacity, bytes, Some(self.id)));
        let mut history = match self.state.store.session_history(self.session).await {
            Ok(history) => history,
            Err(err) => {
                self.events = None;
                return self.fail(ConnError::internal(
                    "reading a session's history",
                    err,
                    "could not read the session's history; reconnect to see the others",
                    None,
                ));
            }
        };
        if !history.keep.is_empty() {
            // Kept for the next history; nobody waits for the commit.
            drop(self.state.writer.submit(std::mem::take(&mut history.keep)).await);
        }
        for (stroke, _why) in &history.unreadable {
            // Said, not hidden: the client knows the stroke exists and is missing. In order
            // with the history, so waiting for room like it.
            metrics::counter!("penmesh_errors_total", "code" => ErrorCode::Internal.as_str())
                .increment(1);
            let message = match stroke {
                Some(id) => format!("stroke {id} cannot be read from storage; the others follow"),
                None => "a stroke cannot be read from storage; the others follow".to_string(),
            };
            self.send_wait(ServerMessage::Error(ErrorMessage {
                code: ErrorCode::Internal,
                message,
                stroke: *stroke,
            }))
            .await;
        }
        let batch = self.state.config.max_batch_samples.max(1);
        let mut whole = WholeStrokes::carrying(self.outgoing.version);
        let mut events = history.events.into_iter().peekable();
        while let Some(event) = events.next() {
            // A stroke the client has shown taken back and the history holds again: brought
            // back while the client was not listening (a gap, `lagged`).
            if let EventKind::StrokeBegin { participant, stroke, .. } = &event.kind
                && self.told_removed(*stroke, false)
            {
                let (participant, stroke) = (*participant, *stroke);
                let by = participant; // only its drawer may bring it back
                let restored = EventKind::Restored { participant, stroke, by };
                self.send_wait(SessionEvent::new(self.session, restored).message()).await;
            }
            if self.is_own(&event) {
                continue;
            }
            // A stroke the client lacks entirely goes, with its events, into a `PeerStrokes`.
            if let EventKind::StrokeBegin { stroke, .. } = &event.kind
                && !self.view.has_stroke(stroke)
            {
                let stroke = *stroke;
                let mut parts = vec![event];
                // Its placement is not part of its whole form (`HistoryStroke` has none): it
                // follows as its own event, even when it comes right after the stroke's.
                let part_of_whole = |e: &SessionEvent| {
                    e.stroke() == Some(stroke) && !matches!(e.kind, EventKind::Placed { .. })
                };
                while let Some(next) = events.next_if(part_of_whole) {
                    parts.push(next);
                }
                if let Some(rest) = whole.take(&mut self.view, parts, batch) {
                    // Too many samples for one message: one event (or batch) at a time.
                    for event in rest {
                        self.send_history_event(event, batch).await;
                    }
                }
                if let Some(msg) = whole.flush_if_full(batch) {
                    self.send_wait(msg).await;
                    for event in std::mem::take(&mut whole.later) {
                        self.send_history_event(event, batch).await;
                    }
                }
                continue;
            }
            if let Some(msg) = whole.flush() {
                self.send_wait(msg).await;
            }
            for event in std::mem::take(&mut whole.later) {
                self.send_history_event(event, batch).await;
            }
            self.send_history_event(event, batch).await;
        }
        if let Some(msg) = whole.flush() {
            self.send_wait(msg).await;
        }
        for event in std::mem::take(&mut whole.later) {
            self.send_history_event(event, batch).await;
        }
        // The strokes back on the board: told only to a client that was told an older
        // placement (it shows that one); for the others only the id is kept, so that an older
        // placement arriving late (another replica's notification) is not told after it.
        for placed in history.on_board {
            if let EventKind::Placed { stroke, id, .. } = &placed.kind
                && !self.is_own(&placed)
                && self.view.has_stroke(stroke)
            {
                if self.view.placement_held(stroke) > 0 {
                    self.send_history_event(placed, batch).await;
                } else {
                    self.view.tell_placement(*stroke, *id);
                }
            }
        }
        // The strokes the client has shown that were taken back while it was not listening.
        for removed in history.removed {
            if let EventKind::Removed { stroke, .. } = removed.kind
                && self.told_removed(stroke, true)
            {
                self.send_wait(removed.message()).await;
            }
        }
        let n_strokes = self.view.n_strokes() as u64;
        self.send_wait(ServerMessage::Synced(Synced { n_strokes })).await;
    }

    /// One event of a history, through the view, its retained samples in batches of at most
    /// `batch`.
    async fn send_history_event(&mut self, event: SessionEvent, batch: usize) {
        let pieces = match event.kind {
            EventKind::Retained { participant, stroke, first, points } => points
                .chunks(batch)
                .enumerate()
                .map(|(i, chunk)| {
                    SessionEvent::new(
                        self.session,
                        EventKind::Retained {
                            participant,
                            stroke,
                            first: first + (i * batch) as u64,
                            points: chunk.to_vec(),
                        },
                    )
                })
                .collect(),
            kind => vec![SessionEvent::new(self.session, kind)],
        };
        for piece in pieces {
            match self.view.admit(&piece) {
                Admit::Whole => self.send_wait(piece.message()).await,
                Admit::Part(msg) => self.send_wait(msg).await,
                Admit::Skip | Admit::Gap | Admit::Fetch(_) => {}
            }
        }
    }
}

/// Most strokes in one `PeerStrokes` (their samples are bounded by the batch size).
const MAX_WHOLE_STROKES: usize = 256;

/// The strokes of a history the client lacks entirely, gathered into `PeerStrokes` messages of
/// at most [`MAX_WHOLE_STROKES`] strokes and about `batch` samples (the proxy's
/// `--max-batch-samples`, 4,096 by default: some 200 KB of JSON): a 1,000-stroke board in a
/// few messages instead of 4,000.
#[derive(Debug, Default)]
struct WholeStrokes {
    strokes: Vec<HistoryStroke>,
    samples: usize,
    /// Whether a `HistoryStroke` carries its placement and solid (protocol 6).
    carries: bool,
    /// A taken stroke's placement and solid for a client whose `HistoryStroke` cannot carry
    /// them: sent as their own messages after the `PeerStrokes` that holds the stroke.
    later: Vec<SessionEvent>,
}

impl WholeStrokes {
    /// For a client of protocol `version`.
    fn carrying(version: u16) -> WholeStrokes {
        WholeStrokes { carries: version >= super::solids::SOLIDS_VERSION, ..Default::default() }
    }

    /// Takes one stroke's history events (its begin first), recording them in `view` as if
    /// each had been sent. A stroke of more than `batch` samples is not taken: its events are
    /// given back, to be sent one at a time.
    fn take(
        &mut self,
        view: &mut PeerView,
        parts: Vec<SessionEvent>,
        batch: usize,
    ) -> Option<Vec<SessionEvent>> {
        let samples: usize = parts
            .iter()
            .map(|e| match &e.kind {
                EventKind::Retained { points, .. } => points.len(),
                _ => 0,
            })
            .sum();
        if samples > batch {
            return Some(parts);
        }
        let mut whole: Option<HistoryStroke> = None;
        for part in parts {
            let placed_or_solid =
                matches!(part.kind, EventKind::Placed { .. } | EventKind::Solid { .. });
            if placed_or_solid && !self.carries {
                self.later.push(part);
                continue;
            }
            // A stroke the view does not know: each of its events is admitted whole.
            let admitted = view.admit(&part) == Admit::Whole;
            match (part.kind, whole.as_mut()) {
                (EventKind::StrokeBegin { participant, stroke, brush }, None) if admitted => {
                    whole = Some(HistoryStroke {
                        participant,
                        stroke,
                        brush,
                        points: PointBatch::default(),
                        done: false,
                        mesh: false,
                        placement: penmesh::Placement::IDENTITY,
                        solid: penmesh::Solid::ROD,
                    });
                }
                (EventKind::Placed { placement, .. }, Some(w)) if admitted => {
                    w.placement = placement
                }
                (EventKind::Solid { solid, .. }, Some(w)) if admitted => w.solid = solid,
                (EventKind::Retained { points, .. }, Some(w)) if admitted => w.points.0 = points,
                (EventKind::StrokeDone { .. }, Some(w)) if admitted => w.done = true,
                (EventKind::Mesh { .. }, Some(w)) if admitted => w.mesh = true,
                (kind, _) => {
                    tracing::warn!(?kind, "a history event of a new stroke not admitted whole");
                }
            }
        }
        if let Some(w) = whole {
            self.samples += w.points.0.len();
            self.strokes.push(w);
        }
        None
    }

    fn flush_if_full(&mut self, batch: usize) -> Option<ServerMessage> {
        if self.strokes.len() >= MAX_WHOLE_STROKES || self.samples >= batch {
            self.flush()
        } else {
            None
        }
    }

    fn flush(&mut self) -> Option<ServerMessage> {
        if self.strokes.is_empty() {
            return None;
        }
        self.samples = 0;
        Some(ServerMessage::PeerStrokes(PeerStrokes { strokes: std::mem::take(&mut self.strokes) }))
    }
}
