//! The WebSocket connection: decoding, the per-connection protocol state, acks after commit,
//! and the wind-down when a connection ends.
//!
//! [`serve`] is written against a generic `Sink`/`Stream` of [`Frame`]s, so a unit test drives
//! it with channels; [`ws_handler`] adapts axum's WebSocket to it.
//!
//! Protocol decisions (see also `docs/storage.md`):
//! - Every bad input is answered with `Error {code, message, stroke}` and the connection goes
//!   on. The connection is closed only for: a first message that is not `Hello` or a protocol
//!   version this proxy does not speak (close 1002), a message past the hard size limit (1009),
//!   a full session (1008), the idle timeout (1000), shutdown (1001), and a reader too slow for
//!   its outgoing queue (dropped without a close frame, since the queue is full).
//! - Answers go out in the form (binary or JSON) of the client's latest frame.
//! - `StrokeBegin` is acknowledged with `Ack {upto_seq}` once the stroke row is committed.
//! - Resume: a stroke named in `Hello.resume` (or begun again with `StrokeBegin`) that is
//!   `open` or `interrupted` is rebuilt by replaying its committed samples through a fresh
//!   simplifier. Every sample retained so far is then sent again as one `Retained {first: 0}`
//!   (split in batches), so a client that lost some in the drop has them all; `first` lets a
//!   client that kept them drop the repeat.
//!
//! Sessions (see [`crate::fanout`]): after `Welcome`, the connection joins its session's
//! fan-out **before** it reads the session's history from the database, sends the history,
//! then `Synced`, then the live events that queued meanwhile and after. Every peer event goes
//! through the connection's [`PeerView`] (per stroke: begun, how many retained samples, done,
//! mesh time), which drops what the client already has and trims overlaps, so history and live
//! events neither overlap nor leave a gap. Peer events leave a quarter of the outgoing queue
//! to the connection's own answers; when the socket is too slow, events wait in the fan-out
//! queue, and when that overflows the client gets `Error {lagged}` and the same resync (only
//! what it lacks; past 3 overflows a minute it is dropped instead). Stroke events are
//! published once committed (by the writer), in order.

use std::collections::{HashMap, HashSet, VecDeque};
use std::sync::Arc;
use std::time::Duration;

use axum::extract::ws::{CloseFrame, Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Path, State};
use axum::http::HeaderMap;
use axum::response::{IntoResponse, Response};
use futures_util::future::BoxFuture;
use futures_util::stream::FuturesOrdered;
use futures_util::{FutureExt, Sink, SinkExt, Stream, StreamExt};
use penmesh::protocol::{
    Ack, ClientMessage, CodecError, ErrorCode, ErrorMessage, Hello, PROTOCOL_VERSION,
    ParticipantId, PointBatch, Points, ResumeState, Retained, ServerMessage, StrokeBegin,
    StrokeDone, StrokeEnd, StrokeId, StrokeStatus, Synced, Welcome, decode_client_json_limited,
    decode_client_limited, encode_server, encode_server_json,
};
use penmesh::{Kept, Sample};
use tokio::sync::mpsc;
use tokio::time::Instant;
use uuid::Uuid;

use crate::fanout::{Admit, EventKind, Lag, PeerView, Published, SessionEvent, Subscription};
use crate::http::{AppError, authorize_session};
use crate::ingest::{Accepted, Finished, Refusal, StrokeLimits, StrokeState};
use crate::state::{AppState, SessionGuard};
use crate::store::{WriteError, WriteOp};

/// A WebSocket frame, independent of the WebSocket library.
#[derive(Debug, Clone, PartialEq)]
pub enum Frame {
    Text(String),
    Binary(Vec<u8>),
    Ping(Vec<u8>),
    Pong(Vec<u8>),
    Close(Option<(u16, String)>),
}

/// Close codes this proxy sends.
pub mod close_code {
    pub const NORMAL: u16 = 1000;
    pub const GOING_AWAY: u16 = 1001;
    pub const PROTOCOL: u16 = 1002;
    pub const POLICY: u16 = 1008;
    pub const TOO_BIG: u16 = 1009;
}

/// `GET /v1/sessions/{session}/ws`: authenticates, then upgrades.
pub async fn ws_handler(
    State(state): State<AppState>,
    Path(session): Path<String>,
    headers: HeaderMap,
    upgrade: Result<WebSocketUpgrade, axum::extract::ws::rejection::WebSocketUpgradeRejection>,
) -> Result<Response, AppError> {
    if state.shutdown.is_cancelled() {
        return Err(AppError::ShuttingDown);
    }
    // A browser cannot set headers on a WebSocket: it offers its token as a subprotocol. A
    // token in the query string is not read (URLs reach access logs).
    let token = crate::web::subprotocol_token(&headers);
    let session = authorize_session(&state, &headers, token, &session).await?;
    let upgrade = match upgrade {
        Ok(upgrade) => upgrade,
        Err(rejection) => return Ok(rejection.into_response()),
    };
    let slot = state.connection_slot().ok_or_else(|| {
        AppError::Busy(format!(
            "this replica has {} WebSocket connections, the limit (--max-connections)",
            state.config.max_connections
        ))
    })?;
    let hard = state.config.hard_message_limit();
    let guard = state.join_session(session);
    let tracked = state.tracker.token();
    let upgrade = upgrade.read_buffer_size(READ_BUFFER_BYTES).protocols([crate::web::SUBPROTOCOL]);
    Ok(upgrade.max_message_size(hard).max_frame_size(hard).on_upgrade(move |socket| async move {
        let (_tracked, _slot) = (tracked, slot);
        let (sink, stream) = split(socket);
        match guard {
            Some(guard) => serve(state, session, guard, sink, stream).await,
            None => refuse_full_session(state, sink).await,
        }
    }))
}

/// Socket read buffer per connection. tungstenite zero-fills the whole buffer on its first
/// read, so its default (128 KiB) would make every idle connection cost that much resident
/// memory; `Points` frames are a few hundred bytes, and larger messages still arrive whole
/// (the buffer grows for them).
const READ_BUFFER_BYTES: usize = 4 * 1024;

type FrameSink = std::pin::Pin<Box<dyn Sink<Frame, Error = axum::Error> + Send>>;
type FrameStream = std::pin::Pin<Box<dyn Stream<Item = Result<Frame, axum::Error>> + Send>>;

fn split(socket: WebSocket) -> (FrameSink, FrameStream) {
    let (sink, stream) = socket.split();
    let sink = sink.with(|frame: Frame| {
        futures_util::future::ready(Ok::<_, axum::Error>(match frame {
            Frame::Text(text) => Message::Text(text.into()),
            Frame::Binary(bytes) => Message::Binary(bytes.into()),
            Frame::Ping(bytes) => Message::Ping(bytes.into()),
            Frame::Pong(bytes) => Message::Pong(bytes.into()),
            Frame::Close(close) => Message::Close(
                close.map(|(code, reason)| CloseFrame { code, reason: reason.into() }),
            ),
        }))
    });
    let stream = stream.map(|msg| {
        msg.map(|msg| match msg {
            Message::Text(text) => Frame::Text(text.to_string()),
            Message::Binary(bytes) => Frame::Binary(bytes.to_vec()),
            Message::Ping(bytes) => Frame::Ping(bytes.to_vec()),
            Message::Pong(bytes) => Frame::Pong(bytes.to_vec()),
            Message::Close(close) => Frame::Close(close.map(|c| (c.code, c.reason.to_string()))),
        })
    });
    (Box::pin(sink), Box::pin(stream))
}

async fn refuse_full_session(state: AppState, mut sink: FrameSink) {
    metrics::counter!("penmesh_errors_total", "code" => ErrorCode::TooManyConnections.as_str())
        .increment(1);
    let msg = ServerMessage::Error(ErrorMessage {
        code: ErrorCode::TooManyConnections,
        message: format!(
            "this session already has {} connections, the limit",
            state.config.max_connections_per_session
        ),
        stroke: None,
    });
    // The client has said nothing yet: JSON is readable by everyone.
    let _ = sink.send(Frame::Text(encode_server_json(&msg))).await;
    let _ =
        sink.send(Frame::Close(Some((close_code::POLICY, "too many connections".into())))).await;
}

/// Which encoding the client used last.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Form {
    Binary,
    Json,
}

/// Why a connection ended.
#[derive(Debug, Clone, PartialEq)]
enum End {
    /// The client closed or vanished.
    Gone,
    /// Close with this code and reason.
    Close(u16, String),
    /// The outgoing queue is full: drop the connection.
    SlowReader,
}

/// What to send once a write request commits.
#[derive(Debug)]
enum AfterCommit {
    Ack { stroke: StrokeId, upto_seq: u64 },
    Done { stroke: StrokeId, n_retained: u64 },
}

type Pending = BoxFuture<'static, (Result<(), WriteError>, AfterCommit)>;

/// Runs one connection to its end.
pub async fn serve<Si, St, E>(
    state: AppState,
    session: Uuid,
    guard: SessionGuard,
    sink: Si,
    mut stream: St,
) where
    Si: Sink<Frame> + Send + 'static,
    St: Stream<Item = Result<Frame, E>> + Unpin + Send,
    E: std::fmt::Display,
{
    let (out, out_rx) = mpsc::channel(state.config.outgoing_queue.max(1));
    let sender = tokio::spawn(forward(out_rx, sink));
    let mut conn = Connection {
        id: state.next_connection_id(),
        participant: Uuid::new_v4(),
        session,
        _guard: guard,
        form: Form::Binary,
        hello: false,
        joined: false,
        owners: HashMap::new(),
        own: HashSet::new(),
        view: PeerView::default(),
        events: None,
        lags: Vec::new(),
        strokes: HashMap::new(),
        finishing: HashSet::new(),
        out,
        overflow: VecDeque::new(),
        overflow_since: None,
        pending: FuturesOrdered::new(),
        end: None,
        state: state.clone(),
    };
    metrics::gauge!("penmesh_ws_connections").increment(1.0);
    metrics::counter!("penmesh_ws_connections_total").increment(1);
    tracing::debug!(connection = conn.id, %session, "connected");
    let idle = Duration::from_secs(state.config.idle_timeout_secs);
    let mut last_heard = Instant::now();
    let shutdown = state.shutdown.clone();
    // A quarter of the outgoing queue stays free for the connection's own answers.
    let reserve = state.config.outgoing_queue.max(1) / 4;
    let slow_reader = Duration::from_millis(state.config.slow_reader_ms);
    while conn.end.is_none() {
        let behind = !conn.overflow.is_empty();
        let can_read = !behind && conn.pending.len() < state.config.max_inflight.max(1);
        let can_forward = !behind && conn.events.is_some() && conn.out.capacity() > reserve;
        let overflow_deadline = conn.overflow_since.map(|since| since + slow_reader);
        tokio::select! {
            biased;
            _ = shutdown.cancelled() => {
                conn.send_error(ErrorCode::ShuttingDown, "the proxy is shutting down; resume later", None);
                conn.end_with(End::Close(close_code::GOING_AWAY, "shutting down".into()));
            }
            Some((result, after)) = conn.pending.next(), if !conn.pending.is_empty() => {
                conn.after_commit(result, after);
            }
            event = next_event(&mut conn.events), if can_forward => match event {
                Ok(event) => conn.on_event(&event).await,
                Err(lag) => conn.resync(Some(lag)).await,
            },
            // The socket was too slow to take peer events: wake up when it caught up.
            _ = room(&conn.out, reserve + 1), if !behind && conn.events.is_some() && !can_forward => {}
            permit = conn.out.clone().reserve_owned(), if behind => match permit {
                Ok(permit) => conn.flush_one(permit),
                Err(_) => conn.end_with(End::Gone),
            },
            _ = sleep_until_some(overflow_deadline), if behind => {
                tracing::info!(connection = conn.id, "outgoing queue full: disconnecting a slow reader");
                conn.end_with(End::SlowReader);
            }
            frame = stream.next(), if can_read => {
                last_heard = Instant::now();
                match frame {
                    None | Some(Ok(Frame::Close(_))) => conn.end_with(End::Gone),
                    Some(Err(err)) => conn.on_read_error(&err.to_string()),
                    Some(Ok(frame)) => conn.on_frame(frame).await,
                }
            }
            _ = tokio::time::sleep_until(last_heard + idle) => {
                conn.send_error(
                    ErrorCode::IdleTimeout,
                    format!("nothing received for {} s", idle.as_secs()),
                    None,
                );
                conn.end_with(End::Close(close_code::NORMAL, "idle timeout".into()));
            }
        }
    }
    conn.wind_down().await;
    let end = conn.end.take().unwrap_or(End::Gone);
    let out = conn.out.clone();
    let overflow = std::mem::take(&mut conn.overflow);
    drop(conn);
    match end {
        End::SlowReader => {
            metrics::counter!("penmesh_ws_slow_reader_disconnects_total").increment(1);
            sender.abort();
        }
        End::Gone => sender.abort(),
        End::Close(code, reason) => {
            let grace = Duration::from_secs(2);
            // The answers still owed go first (the acks of the last commits), then the close.
            let frames = overflow.into_iter().chain([Frame::Close(Some((code, reason)))]);
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
    }
    metrics::gauge!("penmesh_ws_connections").decrement(1.0);
}

/// Ready at `deadline`; never without one.
async fn sleep_until_some(deadline: Option<Instant>) {
    match deadline {
        Some(deadline) => tokio::time::sleep_until(deadline).await,
        None => std::future::pending().await,
    }
}

/// Ready once the queue has room for `n` frames (the permits are given back at once).
fn room(out: &mpsc::Sender<Frame>, n: usize) -> impl Future<Output = ()> + use<> {
    let out = out.clone();
    async move {
        let _ = out.reserve_many(n).await;
    }
}

/// The next event of the subscription; never ready without one.
async fn next_event(events: &mut Option<Subscription>) -> Result<Arc<Published>, Lag> {
    match events {
        Some(events) => events.recv().await,
        None => std::future::pending().await,
    }
}

/// Writes queued frames to the socket until the queue closes or a close frame went out.
/// A connection that overflows its queue more than `MAX_LAGS` times within `LAG_WINDOW` is
/// dropped (its client reconnects and resumes) instead of resynced once more.
const MAX_LAGS: usize = 3;
const LAG_WINDOW: Duration = Duration::from_secs(60);

/// Frames already queued go out with one flush (one write to the socket under load, as when a
/// session's events fan out), up to this many.
const FRAMES_PER_FLUSH: usize = 64;

async fn forward<Si: Sink<Frame>>(mut rx: mpsc::Receiver<Frame>, sink: Si) {
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

struct Connection {
    state: AppState,
    id: u64,
    participant: Uuid,
    session: Uuid,
    _guard: SessionGuard,
    form: Form,
    hello: bool,
    /// The participant row is written (and `Leave` is owed at the end).
    joined: bool,
    /// The participant who began each stroke drawn here (a resumed stroke keeps its drawer).
    owners: HashMap<StrokeId, ParticipantId>,
    /// Every stroke drawn on this connection: its client has them, peer events skip them.
    own: HashSet<StrokeId>,
    /// What the client has of the other participants' strokes.
    view: PeerView,
    /// The session's events, once the client said hello.
    events: Option<Subscription>,
    /// When the last overflows happened: a reader that lags again and again is dropped, so
    /// that it does not reload the session's history from the database in a loop.
    lags: Vec<Instant>,
    /// Strokes being drawn on this connection (claimed in [`crate::state::Claims`]).
    strokes: HashMap<StrokeId, StrokeState>,
    /// Strokes whose `StrokeEnd` awaits its commit (still claimed).
    finishing: HashSet<StrokeId>,
    out: mpsc::Sender<Frame>,
    /// Answers that found the outgoing queue full, in order, and since when. Bounded: no frame
    /// is read and no peer event is taken while it is not empty, so only the answers already
    /// owed (at most `max_inflight` acks) can join it. A socket that takes none of them for
    /// `slow_reader_ms` belongs to a slow reader; one that does was only behind by a burst (a
    /// group commit acknowledges many batches at once).
    overflow: VecDeque<Frame>,
    overflow_since: Option<Instant>,
    pending: FuturesOrdered<Pending>,
    end: Option<End>,
}

impl Connection {
    fn end_with(&mut self, end: End) {
        if self.end.is_none() {
            self.end = Some(end);
        }
    }

    fn limits(&self) -> StrokeLimits {
        StrokeLimits {
            max_batch_samples: self.state.config.max_batch_samples,
            max_stroke_samples: self.state.config.max_stroke_samples,
            max_stroke_retained: self.state.config.max_stroke_retained,
        }
    }

    fn claim_wait(&self) -> Duration {
        Duration::from_millis(self.state.config.claim_wait_ms)
    }

    fn send(&mut self, msg: ServerMessage) {
        let frame = self.encode(&msg);
        self.send_frame(frame);
    }

    fn send_frame(&mut self, frame: Frame) {
        if !self.overflow.is_empty() {
            return self.overflow.push_back(frame);
        }
        match self.out.try_send(frame) {
            Ok(()) => self.count_sent(),
            Err(mpsc::error::TrySendError::Full(frame)) => {
                self.overflow.push_back(frame);
                self.overflow_since = Some(Instant::now());
            }
            Err(mpsc::error::TrySendError::Closed(_)) => self.end_with(End::Gone),
        }
    }

    /// Moves the oldest overflowed answer into the outgoing queue.
    fn flush_one(&mut self, permit: mpsc::OwnedPermit<Frame>) {
        if let Some(frame) = self.overflow.pop_front() {
            permit.send(frame);
            self.count_sent();
        }
        if self.overflow.is_empty() {
            self.overflow_since = None;
        }
    }

    fn count_sent(&self) {
        let kind = if self.form == Form::Binary { "binary" } else { "text" };
        metrics::counter!("penmesh_ws_frames_total", "direction" => "out", "kind" => kind)
            .increment(1);
    }

    fn encode(&self, msg: &ServerMessage) -> Frame {
        match self.form {
            Form::Binary => Frame::Binary(encode_server(msg)),
            Form::Json => Frame::Text(encode_server_json(msg)),
        }
    }

    /// Sends, waiting for room in the outgoing queue (history and resyncs, which can be long),
    /// after the overflowed answers, so that the order holds. A client that reads nothing for
    /// the idle timeout is dropped as a slow reader.
    async fn send_wait(&mut self, msg: ServerMessage) {
        if self.end.is_some() {
            return;
        }
        let frame = self.encode(&msg);
        let idle = Duration::from_secs(self.state.config.idle_timeout_secs);
        let mut frames = std::mem::take(&mut self.overflow);
        self.overflow_since = None;
        frames.push_back(frame);
        for frame in frames {
            match tokio::time::timeout(idle, self.out.send(frame)).await {
                Ok(Ok(())) => self.count_sent(),
                Ok(Err(_)) => return self.end_with(End::Gone),
                Err(_) => return self.end_with(End::SlowReader),
            }
        }
    }

    /// A live event of the session.
    async fn on_event(&mut self, published: &Published) {
        let event = &published.event;
        if self.is_own(event) {
            return;
        }
        match self.view.admit(event) {
            Admit::Whole => {
                metrics::counter!("penmesh_fanout_events_total").increment(1);
                let frame = match self.form {
                    Form::Binary => Frame::Binary(published.binary().to_vec()),
                    Form::Json => Frame::Text(published.json().to_string()),
                };
                self.send_frame(frame);
            }
            Admit::Part(msg) => {
                metrics::counter!("penmesh_fanout_events_total").increment(1);
                self.send(msg);
            }
            Admit::Skip => {}
            Admit::Gap => {
                tracing::warn!(connection = self.id, ?event, "peer event past a gap; resyncing");
                self.resync(Some(Lag::Gap)).await;
            }
        }
    }

    fn is_own(&self, event: &SessionEvent) -> bool {
        match &event.kind {
            EventKind::Joined { participant, .. } | EventKind::Left { participant } => {
                *participant == self.participant
            }
            _ => event.stroke().is_some_and(|s| self.own.contains(&s)),
        }
    }

    /// (Re)joins the session's fan-out, then sends the history the client lacks and `Synced`.
    /// `lag` says why a previous subscription ended (`None` on the first join).
    async fn resync(&mut self, lag: Option<Lag>) {
        self.events = None;
        if lag == Some(Lag::Overflow) {
            let now = Instant::now();
            self.lags.retain(|at| now.duration_since(*at) < LAG_WINDOW);
            self.lags.push(now);
            if self.lags.len() > MAX_LAGS {
                tracing::info!(connection = self.id, "lagged again and again: disconnecting");
                self.send_error(
                    ErrorCode::Lagged,
                    "this connection keeps falling behind the session's events; reconnect",
                    None,
                );
                return self.end_with(End::SlowReader);
            }
            self.send_error(
                ErrorCode::Lagged,
                "this connection fell behind the session's events; resending what it lacks from storage",
                None,
            );
        }
        if self.end.is_some() {
            return;
        }
        metrics::counter!("penmesh_fanout_syncs_total").increment(1);
        let capacity = self.state.config.outgoing_queue;
        self.events = Some(self.state.fanout.subscribe(self.session, capacity));
        let history = match self.state.store.session_history(self.session).await {
            Ok(history) => history,
            Err(err) => {
                tracing::error!(error = %err, "reading a session's history");
                self.events = None;
                return self.send_error(
                    ErrorCode::Internal,
                    "could not read the session's history; reconnect to see the others",
                    None,
                );
            }
        };
        for (stroke, _why) in &history.unreadable {
            // Said, not hidden: the client knows the stroke exists and is missing.
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
        for event in history.events {
            if self.is_own(&event) {
                continue;
            }
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
                    Admit::Skip | Admit::Gap => {}
                }
            }
        }
        let n_strokes = self.view.n_strokes() as u64;
        self.send_wait(ServerMessage::Synced(Synced { n_strokes })).await;
    }

    fn send_error(
        &mut self,
        code: ErrorCode,
        message: impl Into<String>,
        stroke: Option<StrokeId>,
    ) {
        metrics::counter!("penmesh_errors_total", "code" => code.as_str()).increment(1);
        let message = message.into();
        tracing::debug!(connection = self.id, code = code.as_str(), %message, "refused");
        self.send(ServerMessage::Error(ErrorMessage { code, message, stroke }));
    }

    fn refuse(&mut self, refusal: Refusal, stroke: Option<StrokeId>) {
        self.send_error(refusal.code, refusal.message, stroke);
    }

    fn on_read_error(&mut self, err: &str) {
        if err.contains("too long") || err.contains("Space limit") {
            self.send_error(ErrorCode::FrameTooLarge, format!("message refused: {err}"), None);
            self.end_with(End::Close(close_code::TOO_BIG, "message too large".into()));
        } else {
            tracing::debug!(connection = self.id, error = err, "read failed");
            self.end_with(End::Gone);
        }
    }

    async fn on_frame(&mut self, frame: Frame) {
        let limit = self.state.config.max_message_bytes;
        let decoded = match &frame {
            Frame::Binary(bytes) => {
                self.form = Form::Binary;
                metrics::counter!("penmesh_ws_frames_total", "direction" => "in", "kind" => "binary")
                    .increment(1);
                decode_client_limited(bytes, limit, self.state.config.max_batch_samples)
                    .map_err(binary_refusal)
            }
            Frame::Text(text) => {
                self.form = Form::Json;
                metrics::counter!("penmesh_ws_frames_total", "direction" => "in", "kind" => "text")
                    .increment(1);
                decode_client_json_limited(text, limit, self.state.config.max_batch_samples)
                    .map_err(json_refusal)
            }
            // The WebSocket library answers pings itself.
            Frame::Ping(_) | Frame::Pong(_) | Frame::Close(_) => return,
        };
        match decoded {
            Ok(msg) => self.on_message(msg).await,
            Err(refusal) => self.refuse(refusal, None),
        }
    }

    async fn on_message(&mut self, msg: ClientMessage) {
        if !self.hello {
            match msg {
                ClientMessage::Hello(hello) => self.on_hello(hello).await,
                _ => {
                    self.send_error(ErrorCode::Protocol, "the first message must be hello", None);
                    self.end_with(End::Close(close_code::PROTOCOL, "hello expected".into()));
                }
            }
            return;
        }
        match msg {
            ClientMessage::Hello(_) => self.send_error(
                ErrorCode::Protocol,
                "hello was already received on this connection",
                None,
            ),
            ClientMessage::StrokeBegin(begin) => self.on_stroke_begin(begin).await,
            ClientMessage::Points(points) => self.on_points(points).await,
            ClientMessage::StrokeEnd(end) => self.on_stroke_end(end).await,
            ClientMessage::Ping(ping) => self.send(ServerMessage::Pong(ping)),
        }
    }

    async fn on_hello(&mut self, hello: Hello) {
        if hello.protocol != PROTOCOL_VERSION {
            self.send_error(
                ErrorCode::Protocol,
                format!(
                    "protocol version {} is not supported; this proxy speaks {PROTOCOL_VERSION}",
                    hello.protocol
                ),
                None,
            );
            self.end_with(End::Close(close_code::PROTOCOL, "unsupported protocol".into()));
            return;
        }
        let max_resume = self.state.config.max_open_strokes;
        if hello.resume.len() > max_resume {
            // Each entry costs a query and perhaps a claim wait: refuse a long list outright.
            self.send_error(
                ErrorCode::TooManyOpenStrokes,
                format!(
                    "hello.resume names {} strokes, more than the limit of {max_resume} open \
                     strokes per connection",
                    hello.resume.len()
                ),
                None,
            );
            self.end_with(End::Close(close_code::POLICY, "resume list too long".into()));
            return;
        }
        self.hello = true;
        tracing::debug!(connection = self.id, client = %hello.client, "hello");
        let mut resume = Vec::with_capacity(hello.resume.len());
        let mut resent = Vec::new();
        let mut seen = HashSet::new();
        for stroke in hello.resume.into_iter().filter(|s| seen.insert(*s)) {
            let row = match self.state.store.stroke(stroke).await {
                Ok(row) => row.filter(|row| row.session_id == self.session),
                Err(err) => {
                    tracing::error!(error = %err, "reading a stroke to resume");
                    self.send_error(ErrorCode::Internal, "could not read the stroke", Some(stroke));
                    None
                }
            };
            let Some(row) = row else {
                resume.push(ResumeState { stroke, next_seq: 0, status: StrokeStatus::Unknown });
                continue;
            };
            let mut status = row.status;
            let mut next_seq = row.n_points;
            if status != StrokeStatus::Done
                && self.strokes.len() < self.state.config.max_open_strokes
            {
                match self.take_over(stroke, row.params, row.participant).await {
                    Ok(state) => {
                        next_seq = state.next_seq();
                        status = StrokeStatus::Open;
                        resent.push((stroke, state.kept().to_vec()));
                        self.strokes.insert(stroke, state);
                    }
                    Err(refusal) => self.refuse(refusal, Some(stroke)),
                }
            }
            resume.push(ResumeState { stroke, next_seq, status });
        }
        self.send(ServerMessage::Welcome(Welcome {
            protocol: PROTOCOL_VERSION,
            session: self.session,
            participant: self.participant,
            resume,
        }));
        for (stroke, kept) in resent {
            self.send_retained(stroke, 0, &kept);
        }
        let name: String = hello
            .name
            .as_deref()
            .map(str::trim)
            .filter(|n| !n.is_empty())
            .unwrap_or(hello.client.as_str())
            .chars()
            .take(200)
            .collect();
        let (participant, session) = (self.participant, self.session);
        let joined = self
            .state
            .writer
            .write_with(
                vec![WriteOp::Join {
                    participant,
                    session,
                    name: name.clone(),
                    replica: self.state.claims.replica_key(),
                }],
                vec![SessionEvent::new(session, EventKind::Joined { participant, name })],
            )
            .await;
        match joined {
            Ok(()) => self.joined = true,
            Err(err) => tracing::error!(error = %err, "storing a participant"),
        }
        self.resync(None).await;
    }

    /// Claims a stroke that is not on this connection, and rebuilds its state from the
    /// database. Marks it `open` again.
    async fn take_over(
        &mut self,
        stroke: StrokeId,
        params: penmesh::AcutsParams,
        participant: ParticipantId,
    ) -> Result<StrokeState, Refusal> {
        if !self.state.claims.claim(stroke, self.id, self.claim_wait()).await {
            return Err(Refusal::new(
                ErrorCode::StrokeConflict,
                format!("stroke {stroke} is being drawn on another connection"),
            ));
        }
        let internal = |err: &dyn std::fmt::Display| {
            tracing::error!(error = %err, %stroke, "resuming a stroke");
            Refusal::new(ErrorCode::Internal, "could not load the stroke to resume it")
        };
        let result = async {
            let samples = self.state.store.raw_samples(stroke).await.map_err(|e| internal(&e))?;
            self.state
                .writer
                .write(vec![WriteOp::SetStatus { stroke, status: StrokeStatus::Open }])
                .await
                .map_err(|e| internal(&e))?;
            Ok(StrokeState::replay(params, &samples))
        }
        .await;
        if result.is_err() {
            self.state.claims.release(stroke, self.id);
        } else {
            self.owners.insert(stroke, participant);
            self.own.insert(stroke);
        }
        result
    }

    fn send_retained(&mut self, stroke: StrokeId, first: u64, kept: &[Kept]) {
        if kept.is_empty() {
            return;
        }
        metrics::counter!("penmesh_samples_retained_total").increment(kept.len() as u64);
        let batch = self.state.config.max_batch_samples.max(1);
        for (i, chunk) in kept.chunks(batch).enumerate() {
            let points: Vec<Sample> = chunk.iter().map(|k| k.sample).collect();
            self.send(ServerMessage::Retained(Retained {
                stroke,
                first: first + (i * batch) as u64,
                points: PointBatch(points),
            }));
        }
    }

    fn owner(&self, stroke: StrokeId) -> ParticipantId {
        self.owners.get(&stroke).copied().unwrap_or(self.participant)
    }

    /// The peers' event for retained samples `first..` of a stroke drawn here.
    fn retained_event(&self, stroke: StrokeId, first: u64, kept: &[Kept]) -> Option<SessionEvent> {
        if kept.is_empty() {
            return None;
        }
        let participant = self.owner(stroke);
        let points = kept.iter().map(|k| k.sample).collect();
        Some(SessionEvent::new(
            self.session,
            EventKind::Retained { participant, stroke, first, points },
        ))
    }

    fn queue_write(
        &mut self,
        pending: impl Future<Output = Result<(), WriteError>> + Send + 'static,
        after: AfterCommit,
    ) {
        self.pending.push_back(pending.map(move |result| (result, after)).boxed());
    }

    async fn on_stroke_begin(&mut self, begin: StrokeBegin) {
        let stroke = begin.stroke;
        if let Err(err) = begin.brush.validate() {
            return self.send_error(ErrorCode::BadBrush, err.to_string(), Some(stroke));
        }
        if let Some(refusal) =
            device_refusal(begin.device.as_deref(), self.state.config.max_device_chars)
        {
            return self.refuse(refusal, Some(stroke));
        }
        let params = begin.params.unwrap_or_else(|| self.state.config.default_params());
        if let Err(err) = params.validate() {
            return self.send_error(ErrorCode::BadParams, format!("params: {err}"), Some(stroke));
        }
        if let Some(state) = self.strokes.get(&stroke) {
            // A repeat on the same connection: already begun.
            let upto_seq = state.committed_seq;
            return self.send(ServerMessage::Ack(Ack { stroke, upto_seq }));
        }
        if self.finishing.contains(&stroke) {
            return self.send_error(
                ErrorCode::StrokeFinished,
                format!("stroke {stroke} has ended"),
                Some(stroke),
            );
        }
        if self.strokes.len() >= self.state.config.max_open_strokes {
            return self.send_error(
                ErrorCode::TooManyOpenStrokes,
                format!(
                    "this connection already has {} open strokes, the limit; end one first",
                    self.strokes.len()
                ),
                Some(stroke),
            );
        }
        if !self.state.claims.claim(stroke, self.id, self.claim_wait()).await {
            return self.send_error(
                ErrorCode::StrokeConflict,
                format!("stroke {stroke} is being drawn on another connection"),
                Some(stroke),
            );
        }
        let existing = match self.state.store.stroke(stroke).await {
            Ok(existing) => existing,
            Err(err) => {
                tracing::error!(error = %err, "reading a stroke");
                self.state.claims.release(stroke, self.id);
                return self.send_error(
                    ErrorCode::Internal,
                    "could not read the stroke",
                    Some(stroke),
                );
            }
        };
        match existing {
            Some(row) if row.session_id != self.session => {
                self.state.claims.release(stroke, self.id);
                self.send_error(
                    ErrorCode::StrokeConflict,
                    // Says no more than that the id is taken (not where, nor anything of
                    // the stroke): ids are global, see docs/reliability-limits.md.
                    format!("stroke id {stroke} is taken; choose a new random id"),
                    Some(stroke),
                );
            }
            Some(row) if row.status == StrokeStatus::Done => {
                self.state.claims.release(stroke, self.id);
                self.send(ServerMessage::StrokeDone(done_message(stroke, row.n_retained)));
            }
            Some(row) => match self.take_over(stroke, row.params, row.participant).await {
                // Begun before on another connection: resume it.
                Ok(state) => {
                    let kept = state.kept().to_vec();
                    let upto_seq = state.committed_seq;
                    self.strokes.insert(stroke, state);
                    self.send(ServerMessage::Ack(Ack { stroke, upto_seq }));
                    self.send_retained(stroke, 0, &kept);
                }
                Err(refusal) => self.refuse(refusal, Some(stroke)),
            },
            None => {
                let (session, participant) = (self.session, self.participant);
                let event = SessionEvent::new(
                    session,
                    EventKind::StrokeBegin { participant, stroke, brush: begin.brush },
                );
                let pending = self
                    .state
                    .writer
                    .submit_with(
                        vec![WriteOp::BeginStroke {
                            stroke,
                            session,
                            participant,
                            brush: begin.brush,
                            params,
                            device: begin.device,
                        }],
                        vec![event],
                    )
                    .await;
                self.owners.insert(stroke, participant);
                self.own.insert(stroke);
                metrics::counter!("penmesh_strokes_total", "event" => "begun").increment(1);
                self.strokes.insert(stroke, StrokeState::new(params));
                self.queue_write(pending, AfterCommit::Ack { stroke, upto_seq: 0 });
            }
        }
    }

    /// Why a stroke that is not open on this connection cannot take points or an end.
    async fn not_open(
        &mut self,
        stroke: StrokeId,
    ) -> (ErrorCode, String, Option<crate::store::StrokeRow>) {
        if self.finishing.contains(&stroke) {
            return (ErrorCode::StrokeFinished, format!("stroke {stroke} has ended"), None);
        }
        match self.state.store.stroke(stroke).await {
            Ok(Some(row)) if row.session_id == self.session && row.status == StrokeStatus::Done => {
                (ErrorCode::StrokeFinished, format!("stroke {stroke} has ended"), Some(row))
            }
            Ok(Some(row)) if row.session_id == self.session => (
                ErrorCode::UnknownStroke,
                format!(
                    "stroke {stroke} is not open on this connection; resume it with hello.resume or stroke_begin"
                ),
                Some(row),
            ),
            _ => (
                ErrorCode::UnknownStroke,
                format!("unknown stroke {stroke}: send stroke_begin first"),
                None,
            ),
        }
    }

    async fn on_points(&mut self, points: Points) {
        let stroke = points.stroke;
        let limits = self.limits();
        let Some(state) = self.strokes.get_mut(&stroke) else {
            let (code, message, _) = self.not_open(stroke).await;
            return self.send_error(code, message, Some(stroke));
        };
        metrics::counter!("penmesh_samples_in_total").increment(points.points.0.len() as u64);
        match state.push_points(points.seq, &points.points.0, &limits) {
            Err(refusal) => self.refuse(refusal, Some(stroke)),
            Ok(Accepted::Duplicate) => {
                let end = points.seq + points.points.0.len() as u64;
                if end <= state.committed_seq {
                    let upto_seq = state.committed_seq;
                    self.send(ServerMessage::Ack(Ack { stroke, upto_seq }));
                }
                // Otherwise the ack of the first copy is on its way.
            }
            Ok(Accepted::New { seq, samples, kept, first_kept }) => {
                let upto_seq = seq + samples.len() as u64;
                self.send_retained(stroke, first_kept, &kept);
                let events = self.retained_event(stroke, first_kept, &kept).into_iter().collect();
                let pending = self
                    .state
                    .writer
                    .submit_with(vec![WriteOp::Append { stroke, seq, samples }], events)
                    .await;
                self.queue_write(pending, AfterCommit::Ack { stroke, upto_seq });
            }
        }
    }

    async fn on_stroke_end(&mut self, end: StrokeEnd) {
        let stroke = end.stroke;
        let Some(state) = self.strokes.get_mut(&stroke) else {
            let (code, message, row) = self.not_open(stroke).await;
            if let Some(row) =
                row.filter(|r| r.status == StrokeStatus::Done && r.n_points == end.n_points)
            {
                // A resent end after a reconnect: say done again.
                return self.send(ServerMessage::StrokeDone(done_message(stroke, row.n_retained)));
            }
            return self.send_error(code, message, Some(stroke));
        };
        let Finished { last, kept } = match state.finish(end.n_points) {
            Ok(finished) => finished,
            Err(refusal) => return self.refuse(refusal, Some(stroke)),
        };
        self.strokes.remove(&stroke);
        self.finishing.insert(stroke);
        let mut events = Vec::new();
        if let Some((index, k)) = last {
            self.send_retained(stroke, index, &[k]);
            events.extend(self.retained_event(stroke, index, &[k]));
        }
        let n_retained = kept.len() as u64;
        let participant = self.owner(stroke);
        events.push(SessionEvent::new(
            self.session,
            EventKind::StrokeDone { participant, stroke, n_retained },
        ));
        let pending =
            self.state.writer.submit_with(vec![WriteOp::Finish { stroke, kept }], events).await;
        self.queue_write(pending, AfterCommit::Done { stroke, n_retained });
    }

    fn after_commit(&mut self, result: Result<(), WriteError>, after: AfterCommit) {
        match (result, after) {
            (Ok(()), AfterCommit::Ack { stroke, upto_seq }) => {
                if let Some(state) = self.strokes.get_mut(&stroke) {
                    state.committed_seq = state.committed_seq.max(upto_seq);
                }
                self.send(ServerMessage::Ack(Ack { stroke, upto_seq }));
            }
            (Ok(()), AfterCommit::Done { stroke, n_retained }) => {
                self.finishing.remove(&stroke);
                self.state.claims.release(stroke, self.id);
                metrics::counter!("penmesh_strokes_total", "event" => "done").increment(1);
                self.send(ServerMessage::StrokeDone(done_message(stroke, n_retained)));
            }
            (Err(err), after) => {
                let stroke = match after {
                    AfterCommit::Ack { stroke, .. } | AfterCommit::Done { stroke, .. } => stroke,
                };
                // The in-memory state is ahead of the database: drop it, so the client
                // resumes from what is committed.
                self.strokes.remove(&stroke);
                self.finishing.remove(&stroke);
                self.state.claims.release(stroke, self.id);
                self.send_error(
                    ErrorCode::Internal,
                    format!("storing the stroke failed ({err}); resume it from the last ack"),
                    Some(stroke),
                );
            }
        }
    }

    /// Waits for every pending commit (sending its ack if the client still listens), then
    /// marks the strokes still open `interrupted` and lets go of them.
    async fn wind_down(&mut self) {
        while let Some((result, after)) = self.pending.next().await {
            if matches!(self.end, Some(End::Close(..))) {
                self.after_commit(result, after);
            } else if let (Ok(()), AfterCommit::Done { stroke, .. }) = (&result, &after) {
                self.finishing.remove(stroke);
                self.state.claims.release(*stroke, self.id);
                metrics::counter!("penmesh_strokes_total", "event" => "done").increment(1);
            }
        }
        let open: Vec<StrokeId> = self.strokes.keys().copied().collect();
        if !open.is_empty() {
            let ops = open
                .iter()
                .map(|&stroke| WriteOp::SetStatus { stroke, status: StrokeStatus::Interrupted })
                .collect();
            if let Err(err) = self.state.writer.write(ops).await {
                tracing::error!(error = %err, "marking strokes interrupted");
            }
            metrics::counter!("penmesh_strokes_total", "event" => "interrupted")
                .increment(open.len() as u64);
        }
        for stroke in open.into_iter().chain(self.finishing.drain()) {
            self.state.claims.release(stroke, self.id);
        }
        self.strokes.clear();
        self.events = None;
        if self.joined {
            let participant = self.participant;
            let left = self
                .state
                .writer
                .write_with(
                    vec![WriteOp::Leave { participant }],
                    vec![SessionEvent::new(self.session, EventKind::Left { participant })],
                )
                .await;
            if let Err(err) = left {
                tracing::error!(error = %err, "storing a participant's leave");
            }
        }
        tracing::debug!(connection = self.id, end = ?self.end, "disconnected");
    }
}

fn done_message(stroke: StrokeId, n_retained: u64) -> StrokeDone {
    StrokeDone { stroke, n_retained, url: format!("/v1/strokes/{stroke}/simplified") }
}

/// `StrokeBegin.device` longer than `max` characters.
fn device_refusal(device: Option<&str>, max: usize) -> Option<Refusal> {
    let n = device?.chars().count();
    (n > max).then(|| {
        Refusal::new(
            ErrorCode::Malformed,
            format!("stroke_begin.device is {n} characters, more than the limit of {max}"),
        )
    })
}

fn binary_refusal(err: CodecError) -> Refusal {
    match err {
        CodecError::BatchTooLarge { .. } => Refusal::new(ErrorCode::BatchTooLarge, err.to_string()),
        CodecError::TooLarge { .. } => Refusal::new(ErrorCode::FrameTooLarge, err.to_string()),
        CodecError::UnknownMessage(_) => Refusal::new(ErrorCode::UnknownMessage, err.to_string()),
        _ => Refusal::new(ErrorCode::Malformed, err.to_string()),
    }
}

fn json_refusal(err: CodecError) -> Refusal {
    match err {
        CodecError::BatchTooLarge { .. } => Refusal::new(ErrorCode::BatchTooLarge, err.to_string()),
        CodecError::TooLarge { .. } => Refusal::new(ErrorCode::FrameTooLarge, err.to_string()),
        CodecError::UnknownMessage(_) => Refusal::new(ErrorCode::UnknownMessage, err.to_string()),
        _ => Refusal::new(ErrorCode::BadJson, err.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use penmesh::protocol::{
        Ping, decode_server, decode_server_json, encode_client, encode_client_json,
    };
    use tokio_util::sync::{CancellationToken, PollSender};

    use super::*;
    use crate::config::Config;
    use crate::fanout::Fanout;
    use crate::store::{Store, WriterTask};

    /// The connection loop driven through channels, with no socket.
    #[tokio::test]
    async fn serve_speaks_the_protocol_over_channels() {
        let dir = tempfile::tempdir().unwrap();
        let mut config = Config::defaults();
        config.database_url = format!("sqlite://{}", dir.path().join("t.db").display());
        let store = Store::connect(&config).await.unwrap();
        let (writer, writer_task) =
            WriterTask::start(&store, Duration::from_millis(1), 100, 100, Fanout::default(), None)
                .await
                .unwrap();
        let session = Uuid::new_v4();
        store.create_session(session, "hash").await.unwrap();
        let state = AppState::new(
            config,
            store,
            writer,
            CancellationToken::new(),
            crate::metrics::install(),
            Fanout::default(),
            None,
        );
        let guard = state.join_session(session).unwrap();
        let (to_server, from_client) = mpsc::channel::<Frame>(16);
        let (to_client, mut from_server) = mpsc::channel::<Frame>(16);
        let stream = futures_util::stream::unfold(from_client, |mut rx| async move {
            rx.recv().await.map(|f| (Ok::<_, std::convert::Infallible>(f), rx))
        })
        .boxed();
        let task = tokio::spawn(serve(state, session, guard, PollSender::new(to_client), stream));
        let recv = |frame: Option<Frame>| match frame {
            Some(Frame::Binary(b)) => decode_server(&b, usize::MAX).unwrap(),
            Some(Frame::Text(t)) => decode_server_json(&t, usize::MAX).unwrap(),
            other => panic!("{other:?}"),
        };

        let hello = ClientMessage::Hello(Hello {
            protocol: PROTOCOL_VERSION,
            client: "unit".into(),
            name: None,
            resume: vec![],
        });
        to_server.send(Frame::Binary(encode_client(&hello))).await.unwrap();
        assert!(matches!(recv(from_server.recv().await), ServerMessage::Welcome(_)));
        // An empty session: no history, then the marker.
        assert_eq!(recv(from_server.recv().await), ServerMessage::Synced(Synced { n_strokes: 0 }));
        let ping = ClientMessage::Ping(Ping { nonce: 3 });
        to_server.send(Frame::Text(encode_client_json(&ping))).await.unwrap();
        assert!(matches!(from_server.recv().await, Some(Frame::Text(_))));
        let stroke = Uuid::new_v4();
        let begin = ClientMessage::StrokeBegin(StrokeBegin {
            stroke,
            brush: Default::default(),
            device: None,
            params: None,
        });
        to_server.send(Frame::Binary(encode_client(&begin))).await.unwrap();
        assert_eq!(recv(from_server.recv().await), ServerMessage::Ack(Ack { stroke, upto_seq: 0 }));

        drop(to_server);
        task.await.unwrap();
        writer_task.stop().await;
    }
}
