//! The live path of one person drawing: resample each sample as it comes (ACUTS stage 1),
//! batch what is kept, stream it to the proxy, and survive a lost connection.
//!
//! **Guarantee**: a sample is forgotten only once the proxy has acknowledged it (`Ack` means
//! committed). When the connection drops, [`draw`] reconnects with exponential backoff and
//! sends `Hello {resume}` with every stroke it has begun and not seen done; the proxy answers
//! with how far it has each one (`next_seq`), and the client resends from there. Batches carry
//! their `seq`, so a batch the proxy had already stored is recognised and not duplicated.
//!
//! Samples are snapped to the binary codec's grid ([`quantize_sample`]) before anything else,
//! so what the proxy stores equals what was drawn, bit for bit.
//!
//! When the proxy reports a stroke done, a task of its own reconstructs it (see
//! [`crate::reconstruct`]) while drawing goes on.

use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use futures_util::stream::SplitSink;
use futures_util::{SinkExt, StreamExt};
use indicatif::ProgressBar;
use penmesh::protocol::{
    ClientMessage, ErrorCode, ErrorMessage, Hello, PROTOCOL_VERSION, Ping, PointBatch, Points,
    ResumeState, ServerMessage, StrokeBegin, StrokeEnd, StrokeStatus, decode_server,
    decode_server_json, encode_client, quantize_sample,
};
use penmesh::{Brush, Resampler, Sample};
use tokio::net::TcpStream;
use tokio::sync::mpsc;
use tokio::task::JoinSet;
use tokio::time::Instant;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};
use uuid::Uuid;

use crate::input::{PenEvent, PenSource};
use crate::reconstruct::{self, FinishedStroke, StrokeReport};

/// Default time between two batches, ms.
pub const DEFAULT_BATCH_MS: u64 = 16;
/// Default largest batch, samples.
pub const DEFAULT_BATCH_SAMPLES: usize = 64;
/// Default time to keep trying to reach the proxy again after a lost connection, s.
pub const DEFAULT_RETRY_SECS: u64 = 30;
/// Attempts to reach a proxy that was never reached before giving up.
const FIRST_CONNECT_ATTEMPTS: u32 = 3;
/// Longest wait for a handshake or a `Welcome`.
const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(5);
/// A ping keeps an idle connection (a pen at rest) from the proxy's idle timeout.
const KEEPALIVE: Duration = Duration::from_secs(20);
const BACKOFF_FIRST: Duration = Duration::from_millis(100);
const BACKOFF_MAX: Duration = Duration::from_secs(2);

/// Where the proxy is and which session to draw in.
#[derive(Debug, Clone)]
pub struct Endpoint {
    /// `http://HOST:PORT` (a `ws://` URL is accepted and turned into this).
    pub base: String,
    pub session: Uuid,
    pub token: String,
}

impl Endpoint {
    /// Checks and normalises the server URL.
    pub fn new(server: &str, session: Uuid, token: String) -> anyhow::Result<Endpoint> {
        let server = server.trim().trim_end_matches('/');
        let base = if let Some(rest) = server.strip_prefix("ws://") {
            format!("http://{rest}")
        } else if server.starts_with("http://") {
            server.to_string()
        } else if server.starts_with("https://") || server.starts_with("wss://") {
            anyhow::bail!(
                "{server}: TLS is not built into this client; put the proxy behind plain http:// (e.g. a local TLS-terminating tunnel)"
            );
        } else {
            anyhow::bail!("{server}: the server URL must start with http:// or ws://");
        };
        anyhow::ensure!(!token.trim().is_empty(), "the session token is empty");
        Ok(Endpoint { base, session, token })
    }

    pub fn ws_url(&self) -> String {
        let rest = self.base.strip_prefix("http://").unwrap_or(&self.base);
        format!("ws://{rest}/v1/sessions/{}/ws", self.session)
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }
}

/// How one person draws.
#[derive(Debug, Clone)]
pub struct DrawOptions {
    /// Display name, also the GLB author and file name prefix.
    pub name: String,
    pub brush: Brush,
    /// Stage-1 resampling distance `l_eps`.
    pub resample: f64,
    /// Send what was kept at least this often.
    pub batch_interval: Duration,
    /// Send as soon as this many kept samples wait.
    pub batch_samples: usize,
    /// After a lost connection, keep trying this long without progress.
    pub retry_for: Duration,
    /// Where to write each stroke's GLB.
    pub out_dir: Option<PathBuf>,
    /// Advanced by one per drawn sample.
    pub progress: Option<ProgressBar>,
    /// Counts interrupts (Ctrl-C): the first ends the input as if the source ended, so what
    /// was drawn is still stored and meshed; the second gives up at once.
    pub interrupts: Option<tokio::sync::watch::Receiver<u32>>,
}

impl DrawOptions {
    pub fn new(name: impl Into<String>) -> DrawOptions {
        DrawOptions {
            name: name.into(),
            brush: Brush::default(),
            resample: penmesh::DEFAULT_RESAMPLE_DISTANCE,
            batch_interval: Duration::from_millis(DEFAULT_BATCH_MS),
            batch_samples: DEFAULT_BATCH_SAMPLES,
            retry_for: Duration::from_secs(DEFAULT_RETRY_SECS),
            out_dir: None,
            progress: None,
            interrupts: None,
        }
    }
}

/// Draws everything `source` produces into the session, and reconstructs each stroke.
/// Returns one report per stroke, in drawing order.
pub async fn draw(
    endpoint: &Endpoint,
    source: Box<dyn PenSource>,
    options: &DrawOptions,
) -> anyhow::Result<Vec<StrokeReport>> {
    let device = source.device();
    let stroke_devices = source.stroke_devices();
    let events = source.start();
    let http = reqwest::Client::builder()
        .connect_timeout(HANDSHAKE_TIMEOUT)
        .build()
        .context("building the HTTP client")?;
    let mut live = Live {
        endpoint: endpoint.clone(),
        options: Arc::new(options.clone()),
        device,
        stroke_devices,
        http,
        strokes: Vec::new(),
        drawing: None,
        reconstructions: JoinSet::new(),
        last_progress: Instant::now(),
        ever_connected: false,
    };
    live.run(events).await?;
    let mut reports = Vec::new();
    while let Some(joined) = live.reconstructions.join_next().await {
        reports.push(joined.context("a reconstruction task failed")??);
    }
    reports.sort_by_key(|r| r.index);
    Ok(reports)
}

type WsSink = SplitSink<WebSocketStream<MaybeTlsStream<TcpStream>>, Message>;

/// One open connection: the write half, and what the read half received.
struct Link {
    sink: WsSink,
    incoming: mpsc::UnboundedReceiver<anyhow::Result<ServerMessage>>,
    reader: tokio::task::JoinHandle<()>,
    last_sent: Instant,
}

impl Drop for Link {
    fn drop(&mut self) {
        self.reader.abort();
    }
}

/// One stroke, from its first sample until the proxy reports it done.
struct StrokeLog {
    id: Uuid,
    index: usize,
    device: String,
    resampler: Resampler,
    /// Every drawn sample (quantised), and for each kept one its index among them.
    drawn: Vec<Sample>,
    resampled_from: Vec<usize>,
    /// Kept samples `acked..acked + unacked.len()`: everything the proxy has not committed.
    unacked: VecDeque<Sample>,
    acked: u64,
    /// The next seq to send on the current connection.
    sent: u64,
    pen_up: Option<Instant>,
    /// `StrokeBegin` was sent on some connection (so a reconnect resumes it).
    begun: bool,
    /// Begun or resumed on the current connection.
    on_link: bool,
    end_sent: bool,
    done: bool,
    /// A lone unsent sample was held back at the last tick (see `flush`).
    held_lone: bool,
}

impl StrokeLog {
    fn n_kept(&self) -> u64 {
        self.acked + self.unacked.len() as u64
    }

    fn keep(&mut self, drawn_idx: usize, s: Sample) {
        self.resampled_from.push(drawn_idx);
        self.unacked.push_back(s);
    }

    /// Forgets what the proxy has committed.
    fn ack(&mut self, upto_seq: u64) {
        if upto_seq > self.acked {
            let n = ((upto_seq - self.acked) as usize).min(self.unacked.len());
            self.unacked.drain(..n);
            self.acked += n as u64;
        }
        self.sent = self.sent.max(self.acked);
    }
}

/// What to do about an `Error` from the proxy.
enum ErrorAction {
    /// Drop the connection and resume on a new one.
    Reconnect,
    Fail(anyhow::Error),
}

struct Live {
    endpoint: Endpoint,
    options: Arc<DrawOptions>,
    device: String,
    stroke_devices: Vec<String>,
    http: reqwest::Client,
    strokes: Vec<StrokeLog>,
    /// Index in `strokes` of the stroke the pen is drawing; `Some(None)` after a pen-down
    /// before its first sample.
    drawing: Option<Option<usize>>,
    reconstructions: JoinSet<anyhow::Result<StrokeReport>>,
    last_progress: Instant,
    ever_connected: bool,
}

impl Live {
    async fn run(
        &mut self,
        mut events: mpsc::Receiver<anyhow::Result<PenEvent>>,
    ) -> anyhow::Result<()> {
        let mut link: Option<Link> = None;
        let mut source_open = true;
        let mut backoff = BACKOFF_FIRST;
        let mut attempts = 0u32;
        let mut retry_at = Instant::now();
        let mut interrupts = self.options.interrupts.clone();
        let mut tick =
            tokio::time::interval(self.options.batch_interval.max(Duration::from_millis(1)));
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            if !source_open && self.strokes.iter().all(|s| s.done) {
                if let Some(mut link) = link.take() {
                    let _ = link.sink.send(Message::Close(None)).await;
                }
                return Ok(());
            }
            if link.is_none() && Instant::now() >= retry_at {
                attempts += 1;
                match self.connect().await {
                    Ok(new_link) => {
                        tracing::info!(name = %self.options.name, "connected");
                        self.ever_connected = true;
                        self.last_progress = Instant::now();
                        backoff = BACKOFF_FIRST;
                        attempts = 0;
                        link = Some(new_link);
                    }
                    Err(ConnectError::Fatal(err)) => return Err(err),
                    Err(ConnectError::Transient(err)) => {
                        let gave_up = if self.ever_connected {
                            self.last_progress.elapsed() >= self.options.retry_for
                        } else {
                            attempts >= FIRST_CONNECT_ATTEMPTS
                        };
                        if gave_up {
                            return Err(err);
                        }
                        tracing::info!(error = %format!("{err:#}"), retry_in_ms = backoff.as_millis() as u64, "connection failed");
                        retry_at = Instant::now() + backoff;
                        backoff = (backoff * 2).min(BACKOFF_MAX);
                    }
                }
                continue;
            }

            tokio::select! {
                event = events.recv(), if source_open => match event {
                    None => {
                        self.pen_up();
                        source_open = false;
                    }
                    Some(Err(err)) => return Err(err),
                    Some(Ok(event)) => {
                        if let Some(stroke_idx) = self.on_pen(event)
                            && let Some(l) = link.as_mut()
                        {
                            let s = &self.strokes[stroke_idx];
                            let full = (s.n_kept() - s.sent) as usize >= self.options.batch_samples;
                            if (s.pen_up.is_some() || full)
                                && let Err(err) = self.flush(l).await
                            {
                                self.lost(&mut link, err);
                            }
                        }
                    }
                },
                msg = recv(&mut link) => match msg {
                    Some(Ok(msg)) => {
                        if let Err(action) = self.on_message(msg) {
                            match action {
                                ErrorAction::Fail(err) => return Err(err),
                                ErrorAction::Reconnect => self.lost(&mut link, anyhow::anyhow!("the proxy asked to resume")),
                            }
                            retry_at = Instant::now() + backoff;
                        }
                    }
                    Some(Err(err)) => {
                        self.lost(&mut link, err);
                        retry_at = Instant::now() + backoff;
                    }
                    None => {
                        self.lost(&mut link, anyhow::anyhow!("the connection closed"));
                        retry_at = Instant::now() + backoff;
                    }
                },
                _ = tick.tick() => {
                    if let Some(l) = link.as_mut() {
                        let result = if l.last_sent.elapsed() >= KEEPALIVE {
                            send(l, &ClientMessage::Ping(Ping { nonce: 0 })).await
                        } else {
                            Ok(())
                        };
                        if let Err(err) = result.and(self.flush(l).await) {
                            self.lost(&mut link, err);
                            retry_at = Instant::now() + backoff;
                        }
                    }
                    if link.is_none() && self.ever_connected && self.last_progress.elapsed() >= self.options.retry_for {
                        anyhow::bail!(
                            "lost the connection to {} and could not resume within {} s",
                            self.endpoint.base,
                            self.options.retry_for.as_secs()
                        );
                    }
                }
                _ = tokio::time::sleep_until(retry_at), if link.is_none() => {}
                n = interrupted(&mut interrupts) => {
                    if n >= 2 || !source_open {
                        anyhow::bail!("interrupted");
                    }
                    tracing::warn!("interrupted: storing what was drawn (interrupt again to quit at once)");
                    self.pen_up();
                    source_open = false;
                }
            }
        }
    }

    fn lost(&mut self, link: &mut Option<Link>, err: anyhow::Error) {
        if link.take().is_some() {
            tracing::warn!(name = %self.options.name, error = %format!("{err:#}"), "connection lost; resuming");
        }
        for s in &mut self.strokes {
            s.on_link = false;
            s.end_sent = false;
            s.sent = s.acked;
        }
    }

    /// Handles a pen event; returns the stroke it touched.
    fn on_pen(&mut self, event: PenEvent) -> Option<usize> {
        match event {
            PenEvent::Down => {
                self.pen_up();
                self.drawing = Some(None);
                None
            }
            PenEvent::Sample(raw) => {
                if let Some(progress) = &self.options.progress {
                    progress.inc(1);
                }
                let stroke_idx = match self.drawing {
                    // A sample with the pen up (a source that sends no Down) starts a stroke.
                    None | Some(None) => {
                        let index = self.strokes.len();
                        let device = self.stroke_devices.get(index).unwrap_or(&self.device).clone();
                        self.strokes.push(StrokeLog {
                            id: Uuid::new_v4(),
                            index,
                            device,
                            resampler: Resampler::new(self.options.resample),
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
                        });
                        self.drawing = Some(Some(index));
                        index
                    }
                    Some(Some(index)) => index,
                };
                let s = &mut self.strokes[stroke_idx];
                let mut q = quantize_sample(&raw);
                if let Some(prev) = s.drawn.last() {
                    q.t = q.t.max(prev.t);
                }
                s.drawn.push(q);
                if s.resampler.push(q) {
                    s.keep(s.drawn.len() - 1, q);
                }
                Some(stroke_idx)
            }
            PenEvent::Up => {
                let touched = self.drawing.flatten();
                self.pen_up();
                touched
            }
        }
    }

    /// Ends the stroke being drawn, if any.
    fn pen_up(&mut self) {
        if let Some(Some(stroke_idx)) = self.drawing.take() {
            let s = &mut self.strokes[stroke_idx];
            if let Some((drawn_idx, tail)) = s.resampler.finish() {
                s.keep(drawn_idx, tail);
            }
            s.pen_up = Some(Instant::now());
            tracing::debug!(stroke = %s.id, drawn = s.drawn.len(), kept = s.n_kept(), "pen up");
        }
    }

    /// Sends what waits: begins, batches, ends.
    async fn flush(&mut self, link: &mut Link) -> anyhow::Result<()> {
        let batch = self.options.batch_samples.max(1);
        for s in self.strokes.iter_mut().filter(|s| !s.done) {
            if !s.on_link {
                let begin = StrokeBegin {
                    stroke: s.id,
                    brush: self.options.brush,
                    device: Some(s.device.clone()),
                    params: None,
                };
                send(link, &ClientMessage::StrokeBegin(begin)).await?;
                s.on_link = true;
                s.begun = true;
                s.sent = s.acked;
            }
            // A lone sample costs 7.5-8 bytes on the wire, a pair under 6 each (see
            // docs/performance.md): hold a lone one back for one tick while the pen is down.
            if s.n_kept() - s.sent == 1 && s.pen_up.is_none() && !s.held_lone {
                s.held_lone = true;
                continue;
            }
            s.held_lone = false;
            while s.sent < s.n_kept() {
                let from = (s.sent - s.acked) as usize;
                let to = (from + batch).min(s.unacked.len());
                let points: Vec<Sample> = s.unacked.range(from..to).copied().collect();
                let seq = s.sent;
                s.sent += points.len() as u64;
                send(
                    link,
                    &ClientMessage::Points(Points {
                        stroke: s.id,
                        seq,
                        points: PointBatch(points),
                    }),
                )
                .await?;
            }
            if s.pen_up.is_some() && !s.end_sent {
                send(
                    link,
                    &ClientMessage::StrokeEnd(StrokeEnd { stroke: s.id, n_points: s.n_kept() }),
                )
                .await?;
                s.end_sent = true;
            }
        }
        Ok(())
    }

    fn stroke_mut(&mut self, id: Uuid) -> Option<&mut StrokeLog> {
        self.strokes.iter_mut().find(|s| s.id == id)
    }

    fn on_message(&mut self, msg: ServerMessage) -> Result<(), ErrorAction> {
        match msg {
            ServerMessage::Ack(ack) => {
                if let Some(s) = self.stroke_mut(ack.stroke) {
                    s.ack(ack.upto_seq);
                    self.last_progress = Instant::now();
                }
            }
            ServerMessage::StrokeDone(done) => {
                self.last_progress = Instant::now();
                self.finish_stroke(done.stroke);
            }
            ServerMessage::Error(err)
                if err.code == ErrorCode::Internal
                    && err.stroke.is_some_and(|id| self.stroke_mut(id).is_none()) =>
            {
                // Another participant's stroke the proxy cannot read (in the session's
                // history): nothing of ours to resume, and reconnecting would only repeat it.
                tracing::warn!(message = %err.message, "the proxy cannot read a peer's stroke");
            }
            ServerMessage::Error(err) => return Err(self.on_error(err)),
            ServerMessage::Welcome(_) => {
                return Err(ErrorAction::Fail(anyhow::anyhow!("the proxy sent a second welcome")));
            }
            // Retained samples and peers' events: this client fetches the simplified stroke
            // over HTTP once it is done.
            _ => {}
        }
        Ok(())
    }

    fn on_error(&mut self, err: ErrorMessage) -> ErrorAction {
        let about = err.stroke.map(|s| format!(" (stroke {s})")).unwrap_or_default();
        match err.code {
            ErrorCode::ShuttingDown
            | ErrorCode::IdleTimeout
            | ErrorCode::Internal
            | ErrorCode::StrokeConflict
            | ErrorCode::UnknownStroke
            | ErrorCode::SeqGap
            | ErrorCode::Lagged
            | ErrorCode::TooManyOpenStrokes => {
                tracing::info!(code = err.code.as_str(), message = %err.message, "the proxy asks to resume");
                ErrorAction::Reconnect
            }
            ErrorCode::StrokeFinished => {
                // An end that crossed a reconnect: the stroke is stored.
                if let Some(id) = err.stroke {
                    self.finish_stroke(id);
                }
                ErrorAction::Reconnect
            }
            code => ErrorAction::Fail(anyhow::anyhow!(
                "the proxy refused{about}: {}: {}",
                code.as_str(),
                err.message
            )),
        }
    }

    /// The proxy has the stroke: forget it and reconstruct it.
    fn finish_stroke(&mut self, id: Uuid) {
        let endpoint = self.endpoint.clone();
        let http = self.http.clone();
        let options = self.options.clone();
        let Some(s) = self.stroke_mut(id) else { return };
        if s.done {
            return;
        }
        s.done = true;
        s.unacked.clear();
        s.acked = s.resampled_from.len() as u64;
        let finished = FinishedStroke {
            id: s.id,
            index: s.index,
            device: s.device.clone(),
            drawn: std::mem::take(&mut s.drawn),
            resampled_from: std::mem::take(&mut s.resampled_from),
            pen_up: s.pen_up.unwrap_or_else(Instant::now),
        };
        self.reconstructions.spawn(async move {
            reconstruct::reconstruct(&http, &endpoint, &options, finished).await
        });
    }

    /// Opens a connection and resumes every stroke begun and not done.
    async fn connect(&mut self) -> Result<Link, ConnectError> {
        let url = self.endpoint.ws_url();
        let mut request = url
            .as_str()
            .into_client_request()
            .map_err(|e| ConnectError::Fatal(anyhow::anyhow!("bad server URL {url}: {e}")))?;
        let bearer = format!("Bearer {}", self.endpoint.token).parse().map_err(|_| {
            ConnectError::Fatal(anyhow::anyhow!("the token has characters a header cannot carry"))
        })?;
        request.headers_mut().insert("authorization", bearer);
        let connected =
            tokio::time::timeout(HANDSHAKE_TIMEOUT, connect_without_nagle(request)).await;
        let (ws, _) = match connected {
            Err(_) => {
                return Err(ConnectError::Transient(anyhow::anyhow!(
                    "cannot connect to {}: no answer within {} s",
                    self.endpoint.base,
                    HANDSHAKE_TIMEOUT.as_secs()
                )));
            }
            Ok(Err(tokio_tungstenite::tungstenite::Error::Http(response))) => {
                let status = response.status();
                let err = anyhow::anyhow!(
                    "the proxy at {} refused the connection to session {}: HTTP {status}{}",
                    self.endpoint.base,
                    self.endpoint.session,
                    if status.as_u16() == 401 { " (wrong session or token)" } else { "" }
                );
                return Err(if status.is_server_error() {
                    ConnectError::Transient(err)
                } else {
                    ConnectError::Fatal(err)
                });
            }
            Ok(Err(err)) => {
                return Err(ConnectError::Transient(anyhow::anyhow!(
                    "cannot connect to {}: {err}",
                    self.endpoint.base
                )));
            }
            Ok(Ok(ws)) => ws,
        };
        let (sink, mut stream) = ws.split();
        let (tx, incoming) = mpsc::unbounded_channel();
        let reader = tokio::spawn(async move {
            while let Some(frame) = stream.next().await {
                let msg = match frame {
                    Ok(Message::Binary(bytes)) => decode_server(&bytes, usize::MAX)
                        .map_err(|e| anyhow::anyhow!("undecodable message from the proxy: {e}")),
                    Ok(Message::Text(text)) => decode_server_json(&text, usize::MAX)
                        .map_err(|e| anyhow::anyhow!("undecodable message from the proxy: {e}")),
                    Ok(Message::Close(close)) => Err(anyhow::anyhow!(
                        "the proxy closed the connection{}",
                        close.map(|c| format!(" ({} {})", c.code, c.reason)).unwrap_or_default()
                    )),
                    Ok(_) => continue,
                    Err(err) => Err(anyhow::anyhow!("connection lost: {err}")),
                };
                let stop = msg.is_err();
                if tx.send(msg).is_err() || stop {
                    return;
                }
            }
        });
        let mut link = Link { sink, incoming, reader, last_sent: Instant::now() };
        let resume: Vec<Uuid> =
            self.strokes.iter().filter(|s| s.begun && !s.done).map(|s| s.id).collect();
        let hello = Hello {
            protocol: PROTOCOL_VERSION,
            client: format!("penmesh-client/{}", env!("CARGO_PKG_VERSION")),
            name: Some(self.options.name.clone()),
            resume,
        };
        send(&mut link, &ClientMessage::Hello(hello)).await.map_err(ConnectError::Transient)?;
        let welcome = loop {
            let msg = tokio::time::timeout(HANDSHAKE_TIMEOUT, link.incoming.recv()).await.map_err(
                |_| ConnectError::Transient(anyhow::anyhow!("no welcome from the proxy")),
            )?;
            match msg {
                Some(Ok(ServerMessage::Welcome(welcome))) => break welcome,
                Some(Ok(ServerMessage::Error(err))) => {
                    return Err(match self.on_error(err) {
                        ErrorAction::Reconnect => {
                            ConnectError::Transient(anyhow::anyhow!("the proxy is not ready"))
                        }
                        ErrorAction::Fail(err) => ConnectError::Fatal(err),
                    });
                }
                Some(Ok(_)) => continue,
                Some(Err(err)) => return Err(ConnectError::Transient(err)),
                None => {
                    return Err(ConnectError::Transient(anyhow::anyhow!(
                        "the connection closed before welcome"
                    )));
                }
            }
        };
        for state in welcome.resume {
            self.apply_resume(state).map_err(ConnectError::Fatal)?;
        }
        Ok(link)
    }

    fn apply_resume(&mut self, state: ResumeState) -> anyhow::Result<()> {
        let Some(s) = self.stroke_mut(state.stroke) else { return Ok(()) };
        tracing::debug!(stroke = %s.id, next_seq = state.next_seq, status = state.status.as_str(), acked = s.acked, "resume");
        match state.status {
            StrokeStatus::Open | StrokeStatus::Interrupted => {
                anyhow::ensure!(
                    state.next_seq >= s.acked && state.next_seq <= s.n_kept(),
                    "stroke {}: the proxy resumes at sample {} but {} were acknowledged and {} drawn",
                    s.id,
                    state.next_seq,
                    s.acked,
                    s.n_kept()
                );
                s.ack(state.next_seq);
                s.on_link = true;
                s.sent = s.acked;
            }
            StrokeStatus::Done => {
                let id = s.id;
                self.finish_stroke(id);
            }
            StrokeStatus::Unknown => {
                anyhow::ensure!(
                    s.acked == 0,
                    "stroke {}: the proxy no longer knows it, but acknowledged {} samples",
                    s.id,
                    s.acked
                );
                s.on_link = false;
            }
        }
        Ok(())
    }
}

enum ConnectError {
    /// Worth another try.
    Transient(anyhow::Error),
    /// Trying again will not help (wrong token, refused protocol).
    Fatal(anyhow::Error),
}

/// Small frames go out at once: with Nagle's algorithm a `StrokeEnd` right after a batch
/// would wait for the proxy's delayed ACK (~40 ms).
async fn connect_without_nagle(
    request: tokio_tungstenite::tungstenite::handshake::client::Request,
) -> Result<
    (
        WebSocketStream<MaybeTlsStream<TcpStream>>,
        tokio_tungstenite::tungstenite::handshake::client::Response,
    ),
    tokio_tungstenite::tungstenite::Error,
> {
    tokio_tungstenite::connect_async_with_config(request, None, true).await
}

async fn send(link: &mut Link, msg: &ClientMessage) -> anyhow::Result<()> {
    link.sink
        .send(Message::Binary(encode_client(msg).into()))
        .await
        .context("sending to the proxy")?;
    link.last_sent = Instant::now();
    Ok(())
}

/// The number of interrupts so far, once it changes; pending forever without a watch.
async fn interrupted(interrupts: &mut Option<tokio::sync::watch::Receiver<u32>>) -> u32 {
    match interrupts {
        Some(rx) => match rx.changed().await {
            Ok(()) => *rx.borrow_and_update(),
            Err(_) => {
                *interrupts = None;
                std::future::pending().await
            }
        },
        None => std::future::pending().await,
    }
}

/// The next message of the link; pending forever without one.
async fn recv(link: &mut Option<Link>) -> Option<anyhow::Result<ServerMessage>> {
    match link {
        Some(link) => link.incoming.recv().await,
        None => std::future::pending().await,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn server_urls_are_normalised_and_tls_is_refused_clearly() {
        let session = Uuid::nil();
        let e = Endpoint::new("ws://127.0.0.1:8080/", session, "t".into()).unwrap();
        assert_eq!(e.base, "http://127.0.0.1:8080");
        assert_eq!(e.ws_url(), format!("ws://127.0.0.1:8080/v1/sessions/{session}/ws"));
        assert!(
            Endpoint::new("https://x", session, "t".into())
                .unwrap_err()
                .to_string()
                .contains("TLS")
        );
        assert!(Endpoint::new("localhost:1", session, "t".into()).is_err());
    }

    #[test]
    fn an_ack_forgets_exactly_the_committed_samples() {
        let mut s = StrokeLog {
            id: Uuid::nil(),
            index: 0,
            device: String::new(),
            resampler: Resampler::new(0.0),
            drawn: Vec::new(),
            resampled_from: Vec::new(),
            unacked: VecDeque::new(),
            acked: 0,
            sent: 0,
            pen_up: None,
            begun: true,
            on_link: true,
            end_sent: false,
            held_lone: false,
            done: false,
        };
        for i in 0..10 {
            s.keep(i, Sample::new(i as f64, 0.0, i as f64, 0.5));
        }
        s.sent = 10;
        s.ack(4);
        assert_eq!((s.acked, s.unacked.len(), s.unacked[0].x), (4, 6, 4.0));
        s.ack(2);
        assert_eq!(s.acked, 4);
        s.ack(99);
        assert_eq!((s.acked, s.unacked.len()), (10, 0));
    }
}
