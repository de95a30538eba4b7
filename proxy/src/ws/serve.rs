//! The connection loop: one WebSocket connection from `Hello` to its end.

use std::time::Duration;

use futures_util::FutureExt;
use futures_util::future::OptionFuture;
use futures_util::{Sink, Stream, StreamExt};
use penmesh::protocol::{
    ClientMessage, CodecError, ErrorCode, ServerMessage, StrokeId, binary_frame_version,
    decode_client_json_limited, decode_client_limited,
};
use tokio::time::Instant;
use uuid::Uuid;

use super::connection::Connection;
use super::error::{ConnError, End, ReadError};
use super::outgoing::{Form, Outgoing, forward};
use super::{Frame, close_code};
use crate::events::{EventKind, SessionEvent};
use crate::stages::{self, Stage};
use crate::state::{AppState, SessionGuard};
use crate::store::WriteOp;

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
    E: Into<ReadError>,
{
    let config = &state.config;
    let (outgoing, out_rx) =
        Outgoing::new(config.outgoing_queue, config.outgoing_queue_bytes, &state.counters);
    let sender = tokio::spawn(stages::timed(Stage::SenderTask, forward(out_rx, sink)));
    let mut conn = Connection::new(state.clone(), session, guard, outgoing);
    metrics::gauge!("penmesh_ws_connections").increment(1.0);
    metrics::counter!("penmesh_ws_connections_total").increment(1);
    tracing::debug!(connection = conn.id, %session, "connected");
    let idle = Duration::from_secs(config.idle_timeout_secs);
    let hello_timeout = Duration::from_secs(config.hello_timeout_secs);
    let mut heartbeat = Heartbeat::new(Duration::from_millis(config.heartbeat_ms));
    let opened = Instant::now();
    let mut last_heard = opened;
    // The last work done (a message carried out that is not a ping, or a session event passed
    // on to a watcher): what holds the slot.
    let mut last_work = opened;
    let shutdown = state.shutdown.clone();
    let mut shutting_down = std::pin::pin!(shutdown.cancelled());
    // One timer for the heartbeat, the hello deadline and the idle timeout, moved only when it
    // fired or must fire sooner: a new timer per frame (a timer-wheel entry made and cleared
    // each time) cost more than the rest of the loop's bookkeeping. It may fire early (the
    // client spoke since it was set); the branch looks at the clock and sets it again.
    let mut watch = std::pin::pin!(tokio::time::sleep_until(opened + hello_timeout));
    let slow_reader = Duration::from_millis(config.slow_reader_ms);
    while conn.end.is_none() {
        let behind = conn.outgoing.is_behind();
        let can_read = conn.can_read();
        let idle_at = if conn.hello { last_work + idle } else { opened + hello_timeout };
        // A connection that waits for its commits does not hear its client, which is not the
        // client's silence: the heartbeat counts only while reading.
        let wake = if can_read { heartbeat.due(last_heard).min(idle_at) } else { idle_at };
        if watch.is_elapsed() || watch.deadline() > wake {
            watch.as_mut().reset(wake);
        }
        let can_forward = !behind && conn.events.is_some() && conn.outgoing.has_room_for_events();
        let wait_room = !behind && conn.events.is_some() && !can_forward;
        let rename_at = conn.pending_name.as_ref().and(conn.rename_due());
        tokio::select! {
            biased;
            _ = &mut shutting_down => conn.fail(ConnError::fatal(
                ErrorCode::ShuttingDown,
                "the proxy is shutting down; resume later",
                End::Close(close_code::GOING_AWAY, "shutting down".into()),
            )),
            Some((result, after)) = conn.pending.next(), if !conn.pending.is_empty() => {
                stages::timed(Stage::Answer, conn.after_commit(result, after)).await;
            }
            event = super::peers::next_event(&mut conn.events), if can_forward => match event {
                // A page that watches a session being drawn in is in use, though it says
                // nothing: without this its slot would close every idle period and it would
                // fetch the whole history again.
                Ok(event) => {
                    last_work = Instant::now();
                    stages::timed(Stage::Events, conn.on_event(&event)).await
                }
                Err(lag) => conn.resync(Some(lag)).await,
            },
            // The socket was too slow to take peer events: wake up when it caught up. (These
            // two futures are made only when their branch is enabled: `select!` builds every
            // branch's future each round, and each holds a clone of the queue's sender.)
            Some(()) = OptionFuture::from(wait_room.then(|| conn.outgoing.room_for_events())), if wait_room => {}
            Some(permit) = OptionFuture::from(behind.then(|| conn.outgoing.place())), if behind => match permit {
                Ok(permit) => conn.outgoing.flush_one(permit),
                Err(_) => conn.end_with(End::Gone),
            },
            _ = sleep_until_some(rename_at), if rename_at.is_some() => {
                conn.store_pending_name().await;
            }
            _ = sleep_until_some(conn.outgoing.slow_reader_deadline(slow_reader)), if behind => {
                tracing::info!(connection = conn.id, "outgoing queue full: disconnecting a slow reader");
                conn.end_with(End::SlowReader);
            }
            frame = stream.next(), if can_read => {
                last_heard = Instant::now();
                let mut work = conn.on_read(frame).await;
                // The `points` frames already read from the socket with it (a client's frames
                // wait there when the connection fell behind) go with it: their batches in one
                // request (`Connection::gather`). Only while they are `points` of one stroke
                // (something else hands them over): other messages are read one a round, with
                // the commits' answers and the peers' events in between, as before.
                for _ in 1..config.gather_frames {
                    let reading = conn.gathered.is_some() && conn.end.is_none() && conn.can_read();
                    // Polled without a waker of this task's: the loop polls the stream again
                    // with its own before it waits.
                    let Some(frame) = reading.then(|| stream.next().now_or_never()).flatten()
                    else {
                        break;
                    };
                    work |= conn.on_read(frame).await;
                }
                conn.hand_over_gathered().await;
                if work {
                    last_work = Instant::now();
                }
            }
            _ = &mut watch => {
                let now = Instant::now();
                if now >= idle_at && !conn.hello {
                    conn.fail(ConnError::fatal(
                        ErrorCode::Protocol,
                        format!(
                            "no hello within {} s of connecting (--hello-timeout-secs)",
                            hello_timeout.as_secs()
                        ),
                        End::Close(close_code::POLICY, "no hello".into()),
                    ));
                } else if now >= idle_at {
                    conn.fail(ConnError::fatal(
                        ErrorCode::IdleTimeout,
                        format!(
                            "no stroke drawn and nothing drawn in the session for {} s (pings do not count); reconnect to draw",
                            idle.as_secs()
                        ),
                        End::Close(close_code::NORMAL, "idle timeout".into()),
                    ));
                } else if can_read && heartbeat.is_dead(last_heard, now) {
                    tracing::info!(connection = conn.id, "no answer to the heartbeat: the client is gone");
                    metrics::counter!("penmesh_ws_heartbeat_disconnects_total").increment(1);
                    conn.end_with(End::Gone);
                } else if can_read && now >= heartbeat.due(last_heard) {
                    heartbeat.pinged = Some(now);
                    conn.send_frame(Frame::Ping(Vec::new()));
                }
            }
        }
    }
    conn.wind_down().await;
    let end = conn.end.take().unwrap_or(End::Gone);
    if end == End::SlowReader {
        metrics::counter!("penmesh_ws_slow_reader_disconnects_total").increment(1);
    }
    let Connection { outgoing, claims, .. } = conn;
    drop(claims);
    outgoing.finish(&end, sender, Duration::from_secs(2)).await;
    metrics::gauge!("penmesh_ws_connections").decrement(1.0);
}

/// When a silent client is pinged, and when it is taken for gone: pinged after one period of
/// silence and again after each further one; gone after [`Heartbeat::MISSED`] periods (a client
/// that is there answers a ping at once, whatever it is doing, so silence that long means the
/// peer vanished without a FIN, and its strokes must not stay claimed until the idle timeout).
#[derive(Debug, Clone, Copy)]
pub(super) struct Heartbeat {
    period: Duration,
    /// When the last ping went out.
    pinged: Option<Instant>,
}

impl Heartbeat {
    pub(super) const MISSED: u32 = 3;

    fn new(period: Duration) -> Heartbeat {
        Heartbeat { period, pinged: None }
    }

    /// When to look next at a client last heard at `heard`: a ping is due a period after it was
    /// heard or last pinged, whichever is later; it is gone [`Heartbeat::MISSED`] periods after
    /// it was heard.
    fn due(&self, heard: Instant) -> Instant {
        let since = self.pinged.map_or(heard, |pinged| pinged.max(heard));
        (since + self.period).min(heard + self.period * Self::MISSED)
    }

    fn is_dead(&self, heard: Instant, now: Instant) -> bool {
        now.saturating_duration_since(heard) >= self.period * Self::MISSED
    }
}

/// Ready at `deadline`; never without one.
async fn sleep_until_some(deadline: Option<Instant>) {
    match deadline {
        Some(deadline) => tokio::time::sleep_until(deadline).await,
        None => std::future::pending().await,
    }
}

impl Connection {
    /// Whether the loop reads its socket: not while answers owed wait for room, nor past
    /// `--max-inflight` requests awaiting their commit.
    fn can_read(&self) -> bool {
        !self.outgoing.is_behind() && self.pending.len() < self.state.config.max_inflight.max(1)
    }

    /// What the socket gave: `true` when it was work ([`Connection::on_frame`]).
    async fn on_read<E: Into<ReadError>>(&mut self, frame: Option<Result<Frame, E>>) -> bool {
        match frame {
            None | Some(Ok(Frame::Close(_))) => {
                self.end_with(End::Gone);
                false
            }
            Some(Err(err)) => {
                self.on_read_error(err.into());
                false
            }
            // The answer to the heartbeat's ping: the client is there, nothing to do.
            Some(Ok(Frame::Pong(_))) => false,
            Some(Ok(frame)) => self.on_frame(frame).await,
        }
    }

    fn on_read_error(&mut self, err: ReadError) {
        match err {
            ReadError::TooLarge(why) => self.fail(ConnError::fatal(
                ErrorCode::FrameTooLarge,
                format!("message refused: {why}"),
                End::Close(close_code::TOO_BIG, "message too large".into()),
            )),
            ReadError::Broken(why) => {
                tracing::debug!(connection = self.id, error = why, "read failed");
                self.end_with(End::Gone);
            }
        }
    }

    /// Carries out a frame's message; `true` when that was work (not a ping, not refused),
    /// which is what keeps the connection from the idle timeout.
    async fn on_frame(&mut self, frame: Frame) -> bool {
        let limit = self.state.config.max_message_bytes;
        let frame_version = match &frame {
            Frame::Binary(bytes) => binary_frame_version(bytes),
            _ => None,
        };
        if !self.hello
            && let Some(version) = frame_version
        {
            // The connection's version is not known yet: answer in the client's.
            self.outgoing.version = version;
        }
        let decoding = stages::start();
        let decoded = match &frame {
            Frame::Binary(bytes) => {
                self.outgoing.form = Form::Binary;
                self.state.counters.frames_in_binary.increment(1);
                decode_client_limited(bytes, limit, self.state.config.max_batch_samples)
                    .map_err(|e| decode_error(e, ErrorCode::Malformed))
            }
            Frame::Text(text) => {
                self.outgoing.form = Form::Json;
                self.state.counters.frames_in_text.increment(1);
                decode_client_json_limited(text, limit, self.state.config.max_batch_samples)
                    .map_err(|e| decode_error(e, ErrorCode::BadJson))
            }
            // The WebSocket library answers pings itself.
            Frame::Ping(_) | Frame::Pong(_) | Frame::Close(_) => return false,
        };
        decoding.stop(Stage::Decode);
        let done = match decoded {
            Ok(msg) => match self.speaks(frame_version, &msg) {
                Ok(()) => {
                    let work = !matches!(msg, ClientMessage::Ping(_));
                    self.on_message(msg).await.map(|()| work)
                }
                Err(err) => Err(err),
            },
            Err(err) => Err(err),
        };
        done.unwrap_or_else(|err| {
            self.fail(err);
            false
        })
    }

    async fn on_message(&mut self, msg: ClientMessage) -> Result<(), ConnError> {
        if !matches!(msg, ClientMessage::Points(_)) {
            // In order: the batches gathered before it are handed over first.
            self.hand_over_gathered().await;
        }
        if !self.hello {
            return match msg {
                ClientMessage::Hello(hello) => self.on_hello(hello).await,
                _ => Err(ConnError::fatal(
                    ErrorCode::Protocol,
                    "the first message must be hello",
                    End::Close(close_code::PROTOCOL, "hello expected".into()),
                )),
            };
        }
        match msg {
            ClientMessage::Hello(_) => Err(ConnError::refused(
                ErrorCode::Protocol,
                "hello was already received on this connection",
                None,
            )),
            ClientMessage::StrokeBegin(begin) => self.on_stroke_begin(begin).await,
            ClientMessage::Points(points) => self.on_points(points).await,
            ClientMessage::StrokeEnd(end) => self.on_stroke_end(end).await,
            ClientMessage::RemoveStroke(stroke) => self.on_set_removed(stroke, true).await,
            ClientMessage::RestoreStroke(stroke) => self.on_set_removed(stroke, false).await,
            ClientMessage::Rename(rename) => self.on_rename(rename.name).await,
            ClientMessage::SetPlacement(set) => self.on_set_placement(set).await,
            ClientMessage::SetSolid(set) => self.on_set_solid(set).await,
            ClientMessage::Ping(ping) => {
                self.send(ServerMessage::Pong(ping));
                Ok(())
            }
        }
    }

    /// Waits for every pending commit (sending its ack if the client still listens), then
    /// marks the strokes still open `interrupted` and lets go of them.
    async fn wind_down(&mut self) {
        // The batches gathered when the loop ended (mid-burst) go to the writer like the rest.
        self.hand_over_gathered().await;
        // A name asked for is stored, even by a client that leaves before its turn.
        if self.joined {
            self.store_pending_name().await;
        }
        while let Some((result, after)) = self.pending.next().await {
            if matches!(self.end, Some(End::Close(..))) {
                self.after_commit(result, after).await;
            } else {
                self.after_commit_unheard(result, after);
            }
        }
        let open: Vec<StrokeId> = self.strokes.keys().copied().collect();
        if !open.is_empty() {
            let ops = open
                .iter()
                .map(|&stroke| WriteOp::SetStatus {
                    stroke,
                    status: penmesh::protocol::StrokeStatus::Interrupted,
                })
                .collect();
            if let Err(err) = self.state.writer.write(ops).await {
                tracing::error!(connection = self.id, error = %err, "marking strokes interrupted failed");
            }
            metrics::counter!("penmesh_strokes_total", "event" => "interrupted")
                .increment(open.len() as u64);
        }
        for stroke in open.into_iter().chain(self.finishing.drain()) {
            self.claims.release(stroke);
        }
        self.strokes.clear();
        self.events = None;
        if self.joined {
            let (participant, connection) = (self.participant, self.presence);
            let left = self
                .state
                .writer
                .write_with(
                    vec![WriteOp::Leave { connection }],
                    vec![SessionEvent::new(
                        self.session,
                        EventKind::Left { participant, connection },
                    )],
                )
                .await;
            if let Err(err) = left {
                tracing::error!(connection = self.id, error = %err, "storing a participant's leave failed");
            }
        }
        tracing::debug!(connection = self.id, end = ?self.end, "disconnected");
    }
}

/// The refusal of a frame that cannot be decoded; `malformed` is the code of a broken frame in
/// its form (binary or JSON).
fn decode_error(err: CodecError, malformed: ErrorCode) -> ConnError {
    let code = match err {
        CodecError::BatchTooLarge { .. } => ErrorCode::BatchTooLarge,
        CodecError::TooLarge { .. } => ErrorCode::FrameTooLarge,
        CodecError::UnknownMessage(_) => ErrorCode::UnknownMessage,
        _ => malformed,
    };
    ConnError::refused(code, err.to_string(), None)
}

#[cfg(test)]
mod tests {
    use penmesh::protocol::{
        Ack, Hello, PROTOCOL_VERSION, Ping, StrokeBegin, Synced, decode_server, decode_server_json,
        encode_client, encode_client_json,
    };
    use tokio::sync::mpsc;
    use tokio_util::sync::{CancellationToken, PollSender};

    use super::*;
    use crate::config::Config;
    use crate::fanout::Fanout;
    use crate::store::{Store, WriterTask};

    async fn app(dir: &tempfile::TempDir) -> (AppState, WriterTask, Uuid) {
        app_with(dir, |_| {}).await
    }

    async fn app_with(
        dir: &tempfile::TempDir,
        configure: impl FnOnce(&mut Config),
    ) -> (AppState, WriterTask, Uuid) {
        let mut config = Config::defaults();
        configure(&mut config);
        config.database_url = format!("sqlite://{}", dir.path().join("t.db").display()).into();
        let store = Store::connect(&config).await.unwrap();
        let (writer, writer_task) = WriterTask::start(
            &store,
            Duration::from_millis(1),
            100,
            100,
            Fanout::default(),
            None,
            None,
        )
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
        (state, writer_task, session)
    }

    /// A connection served over channels: what the client sends, what it receives, the task.
    /// A text frame `"panic"` makes the socket's stream panic inside the connection's task.
    fn connect(
        state: &AppState,
        session: Uuid,
    ) -> (mpsc::Sender<Frame>, mpsc::Receiver<Frame>, tokio::task::JoinHandle<()>) {
        let guard = state.join_session(session).unwrap();
        let (to_server, from_client) = mpsc::channel::<Frame>(16);
        let (to_client, from_server) = mpsc::channel::<Frame>(16);
        let stream = futures_util::stream::unfold(from_client, |mut rx| async move {
            match rx.recv().await {
                Some(Frame::Text(t)) if t == "panic" => panic!("injected: the socket blew up"),
                Some(frame) => Some((Ok::<_, std::convert::Infallible>(frame), rx)),
                None => None,
            }
        })
        .boxed();
        let sink = PollSender::new(to_client);
        let task = tokio::spawn(serve(state.clone(), session, guard, sink, stream));
        (to_server, from_server, task)
    }

    fn decode(frame: Option<Frame>) -> ServerMessage {
        match frame {
            Some(Frame::Binary(b)) => decode_server(&b, usize::MAX).unwrap(),
            Some(Frame::Text(t)) => decode_server_json(&t, usize::MAX).unwrap(),
            other => panic!("{other:?}"),
        }
    }

    fn hello() -> Frame {
        Frame::Binary(encode_client(&ClientMessage::Hello(Hello {
            protocol: PROTOCOL_VERSION,
            client: "unit".into(),
            name: None,
            resume: vec![],
            key: None,
        })))
    }

    fn begin(stroke: StrokeId) -> Frame {
        Frame::Binary(encode_client(&ClientMessage::StrokeBegin(StrokeBegin {
            stroke,
            brush: Default::default(),
            device: None,
            params: None,
            placement: None,
            solid: None,
        })))
    }

    /// The connection loop driven through channels, with no socket.
    #[tokio::test]
    async fn serve_speaks_the_protocol_over_channels() {
        let dir = tempfile::tempdir().unwrap();
        let (state, writer_task, session) = app(&dir).await;
        let (to_server, mut from_server, task) = connect(&state, session);

        to_server.send(hello()).await.unwrap();
        assert!(matches!(decode(from_server.recv().await), ServerMessage::Welcome(_)));
        // An empty session: no history, then the marker.
        assert_eq!(
            decode(from_server.recv().await),
            ServerMessage::Synced(Synced { n_strokes: 0 })
        );
        let ping = ClientMessage::Ping(Ping { nonce: 3 });
        to_server.send(Frame::Text(encode_client_json(&ping))).await.unwrap();
        assert!(matches!(from_server.recv().await, Some(Frame::Text(_))));
        let stroke = Uuid::new_v4();
        to_server.send(begin(stroke)).await.unwrap();
        assert_eq!(
            decode(from_server.recv().await),
            ServerMessage::Ack(Ack { stroke, upto_seq: 0 })
        );

        drop(to_server);
        task.await.unwrap();
        writer_task.stop().await;
    }

    /// The acks a client gets for three batches of a stroke that wait in its socket together
    /// (sent with its hello and begin before the connection's task first runs: the test's
    /// runtime has one thread), with `gather_frames`; then the stroke ends with all nine stored.
    async fn acks_for_three_waiting_batches(gather_frames: u64) -> Vec<u64> {
        let dir = tempfile::tempdir().unwrap();
        let (state, writer_task, session) =
            app_with(&dir, |c| c.gather_frames = gather_frames).await;
        let (to_server, mut from_server, task) = connect(&state, session);
        let stroke = Uuid::new_v4();
        to_server.send(hello()).await.unwrap();
        to_server.send(begin(stroke)).await.unwrap();
        for seq in [0u64, 3, 6] {
            let points = (seq..seq + 3)
                .map(|i| penmesh::Sample::new(i as f64 * 7.0, (i * i) as f64, i as f64 * 8.0, 0.5))
                .collect();
            let batch = penmesh::protocol::Points {
                stroke,
                seq,
                points: penmesh::protocol::PointBatch(points),
            };
            to_server
                .send(Frame::Binary(encode_client(&ClientMessage::Points(batch))))
                .await
                .unwrap();
        }
        let mut acks = Vec::new();
        while acks.last() != Some(&9) {
            if let ServerMessage::Ack(ack) = decode(from_server.recv().await) {
                acks.push(ack.upto_seq);
            }
        }
        let end = penmesh::protocol::StrokeEnd { stroke, n_points: 9 };
        to_server.send(Frame::Binary(encode_client(&ClientMessage::StrokeEnd(end)))).await.unwrap();
        while !matches!(decode(from_server.recv().await), ServerMessage::StrokeDone(_)) {}
        let row = state.store.stroke(stroke).await.unwrap().expect("stored");
        assert_eq!(row.n_points, 9, "every sample stored");
        drop(to_server);
        task.await.unwrap();
        writer_task.stop().await;
        acks
    }

    /// Batches read in one wake-up go to the writer as one request, with one ack for them all;
    /// with `--gather-frames 1`, one each.
    #[tokio::test]
    async fn batches_waiting_together_are_stored_and_acknowledged_as_one() {
        assert_eq!(acks_for_three_waiting_batches(16).await, [0, 9]);
        assert_eq!(acks_for_three_waiting_batches(1).await, [0, 3, 6, 9]);
    }

    /// A connection task that panics (here its socket's stream does) lets go of its strokes:
    /// the claims are held by a guard, not released by a code path the panic skips.
    #[tokio::test]
    async fn a_panicking_connection_lets_go_of_its_strokes() {
        let dir = tempfile::tempdir().unwrap();
        let (state, writer_task, session) = app(&dir).await;
        let stroke = Uuid::new_v4();
        let (to_server, mut from_server, task) = connect(&state, session);
        to_server.send(hello()).await.unwrap();
        to_server.send(begin(stroke)).await.unwrap();
        while !matches!(decode(from_server.recv().await), ServerMessage::Ack(_)) {}
        let other_connection = u64::MAX;
        assert!(
            !state.claims.claim(stroke, other_connection, Duration::ZERO).await,
            "the stroke is held while its connection lives"
        );

        to_server.send(Frame::Text("panic".into())).await.unwrap();
        assert!(task.await.unwrap_err().is_panic());
        assert!(
            state.claims.claim(stroke, other_connection, Duration::ZERO).await,
            "the stroke is free once its connection's task is gone"
        );
        writer_task.stop().await;
    }

    #[tokio::test]
    async fn a_silent_client_is_pinged_and_then_taken_for_gone() {
        let dir = tempfile::tempdir().unwrap();
        let (state, writer_task, session) = app_with(&dir, |c| c.heartbeat_ms = 300).await;
        let period = Duration::from_millis(state.config.heartbeat_ms);
        let (to_server, mut from_server, task) = connect(&state, session);
        to_server.send(hello()).await.unwrap();
        let stroke = Uuid::new_v4();
        to_server.send(begin(stroke)).await.unwrap();
        let start = Instant::now();
        let mut pings = Vec::new();
        // The client answers nothing from here on (a peer gone without a FIN).
        while let Some(frame) = from_server.recv().await {
            if frame == Frame::Ping(Vec::new()) {
                pings.push(start.elapsed());
            }
        }
        task.await.unwrap();
        let gone = start.elapsed();
        assert_eq!(pings.len(), Heartbeat::MISSED as usize - 1, "{pings:?}");
        // The clock starts a little after the last frame was read: allow for that.
        let slack = period / 2;
        assert!(pings[0] + slack >= period && pings[0] < 2 * period, "{pings:?}");
        assert!(
            gone + slack >= period * Heartbeat::MISSED
                && gone < period * (Heartbeat::MISSED + 1) + slack,
            "gone after {gone:?}"
        );
        assert!(
            state.claims.claim(stroke, u64::MAX, Duration::ZERO).await,
            "the stroke of a client taken for gone is free"
        );
        drop(to_server);
        writer_task.stop().await;
    }

    #[tokio::test]
    async fn a_client_that_answers_the_pings_stays() {
        let dir = tempfile::tempdir().unwrap();
        let (state, writer_task, session) = app_with(&dir, |c| c.heartbeat_ms = 300).await;
        let period = Duration::from_millis(state.config.heartbeat_ms);
        let (to_server, mut from_server, task) = connect(&state, session);
        to_server.send(hello()).await.unwrap();
        let start = Instant::now();
        let mut pongs = 0;
        while start.elapsed() < period * (Heartbeat::MISSED * 2) {
            match from_server.recv().await {
                Some(Frame::Ping(payload)) => {
                    to_server.send(Frame::Pong(payload)).await.unwrap();
                    pongs += 1;
                }
                Some(_) => {}
                None => panic!("a client that answers the pings was dropped after {pongs} pongs"),
            }
        }
        assert!(pongs >= 3, "{pongs} pongs");
        assert!(!task.is_finished());
        drop(to_server);
        task.await.unwrap();
        writer_task.stop().await;
    }
}
