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

mod stroke_log;

use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use futures_util::stream::SplitSink;
use futures_util::{SinkExt, StreamExt};
use penmesh::Sample;
use penmesh::protocol::{
    ClientMessage, ErrorCode, ErrorMessage, Ping, PointBatch, Points, ResumeState, ServerMessage,
    StrokeBegin, StrokeEnd, quantize_sample,
};
use tokio::sync::mpsc;
use tokio::task::JoinSet;
use tokio::time::Instant;
use tokio_tungstenite::tungstenite::Message;
use uuid::Uuid;

use self::stroke_log::{Resumed, StrokeLog};
use crate::backoff::Backoff;
use crate::draw_options::DrawOptions;
use crate::endpoint::Endpoint;
use crate::input::{PenEvent, PenSource};
use crate::reconstruct::{self, FinishedStroke, StrokeReport};
use crate::wire::{self, OpenError, Socket};

/// Strokes begun and not yet done at once: the proxy's default `--max-open-strokes`.
const MAX_OPEN_STROKES: usize = 16;
/// Longest wait for a handshake or a `Welcome`.
const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(5);
/// A ping on a quiet connection (a pen at rest) shows a live peer to the proxy's heartbeat and
/// to any proxy or load balancer between; it does not reset the proxy's idle timeout, which
/// only work does (past it the client reconnects and resumes).
const KEEPALIVE: Duration = Duration::from_secs(20);

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
        pen: Pen::Up,
        reconstructions: JoinSet::new(),
        last_progress: Instant::now(),
    };
    live.run(events).await?;
    // Every reconstruction runs to its end: one that fails (after its own retries) does not
    // take the others' meshes with it.
    let mut reports = Vec::new();
    let mut failures = Vec::new();
    while let Some(joined) = live.reconstructions.join_next().await {
        match joined.context("a reconstruction task failed").and_then(|r| r) {
            Ok(report) => reports.push(report),
            Err(err) => {
                tracing::error!(error = %format!("{err:#}"), "a stroke is stored without its mesh");
                failures.push(format!("{err:#}"));
            }
        }
    }
    if !failures.is_empty() {
        anyhow::bail!(
            "{} of {} strokes are stored without their mesh (the other {} with theirs): {}",
            failures.len(),
            failures.len() + reports.len(),
            reports.len(),
            failures.join("; ")
        );
    }
    reports.sort_by_key(|r| r.index);
    Ok(reports)
}

type WsSink = SplitSink<Socket, Message>;

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

/// What to do about an `Error` from the proxy.
enum ErrorAction {
    /// Drop the connection and resume on a new one.
    Reconnect,
    Fail(anyhow::Error),
}

/// Where the pen is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Pen {
    Up,
    /// Down, before its first sample.
    Down,
    /// Drawing the stroke at this index of `strokes`.
    Drawing(usize),
}

struct Live {
    endpoint: Endpoint,
    options: Arc<DrawOptions>,
    device: String,
    stroke_devices: Vec<String>,
    http: reqwest::Client,
    strokes: Vec<StrokeLog>,
    pen: Pen,
    reconstructions: JoinSet<anyhow::Result<StrokeReport>>,
    /// When the proxy last took something of ours (or when drawing began): the live path
    /// gives up only after `retry_for` without it.
    last_progress: Instant,
}

impl Live {
    async fn run(
        &mut self,
        mut events: mpsc::Receiver<anyhow::Result<PenEvent>>,
    ) -> anyhow::Result<()> {
        let mut link: Option<Link> = None;
        let mut source_open = true;
        let mut backoff = Backoff::default();
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
                match self.connect().await {
                    Ok(new_link) => {
                        tracing::info!(name = %self.options.name, "connected");
                        self.last_progress = Instant::now();
                        backoff.reset();
                        link = Some(new_link);
                    }
                    Err(ConnectError::Fatal(err)) => return Err(err),
                    // The first connection too: a proxy busy with a crowd joining, or starting
                    // up, is waited for with the same backoff as a lost one.
                    Err(ConnectError::Transient(err)) => {
                        if self.last_progress.elapsed() >= self.options.retry_for {
                            return Err(err.context(format!(
                                "could not reach the proxy within {} s",
                                self.options.retry_for.as_secs()
                            )));
                        }
                        tracing::info!(error = %format!("{err:#}"), retry_in_ms = backoff.peek().as_millis() as u64, "connection failed");
                        retry_at = Instant::now() + backoff.next_delay();
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
                            retry_at = Instant::now() + backoff.peek();
                        }
                    }
                    Some(Err(err)) => {
                        self.lost(&mut link, err);
                        retry_at = Instant::now() + backoff.peek();
                    }
                    None => {
                        self.lost(&mut link, anyhow::anyhow!("the connection closed"));
                        retry_at = Instant::now() + backoff.peek();
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
                            retry_at = Instant::now() + backoff.peek();
                        }
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
            s.connection_lost();
        }
    }

    /// Handles a pen event; returns the stroke it touched.
    fn on_pen(&mut self, event: PenEvent) -> Option<usize> {
        match event {
            PenEvent::Down => {
                self.pen_up();
                self.pen = Pen::Down;
                None
            }
            PenEvent::Sample(raw) => {
                if let Some(progress) = &self.options.progress {
                    progress.inc(1);
                }
                let stroke_idx = match self.pen {
                    // A sample with the pen up (a source that sends no Down) starts a stroke.
                    Pen::Up | Pen::Down => {
                        let index = self.strokes.len();
                        let device = self.stroke_devices.get(index).unwrap_or(&self.device).clone();
                        self.strokes.push(StrokeLog::new(index, device, self.options.resampler()));
                        self.pen = Pen::Drawing(index);
                        index
                    }
                    Pen::Drawing(index) => index,
                };
                let s = &mut self.strokes[stroke_idx];
                let mut q = quantize_sample(&raw);
                if let Some(prev) = s.drawn.last() {
                    q.t = q.t.max(prev.t);
                }
                s.drawn.push(q);
                for (drawn_idx, kept) in s.resampler.push(q) {
                    s.keep(drawn_idx, kept);
                }
                Some(stroke_idx)
            }
            PenEvent::Up => {
                let touched = match self.pen {
                    Pen::Drawing(index) => Some(index),
                    Pen::Up | Pen::Down => None,
                };
                self.pen_up();
                touched
            }
        }
    }

    /// Ends the stroke being drawn, if any.
    fn pen_up(&mut self) {
        if let Pen::Drawing(stroke_idx) = std::mem::replace(&mut self.pen, Pen::Up) {
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
        let mut open = self.strokes.iter().filter(|s| s.begun && !s.done).count();
        for s in self.strokes.iter_mut().filter(|s| !s.done) {
            // A stroke not begun yet waits while the proxy holds the most open strokes it
            // allows a connection (a fast replay runs ahead of the commits): past it a begin
            // is refused, and so is a `Hello` that resumes more.
            if !s.begun && open >= MAX_OPEN_STROKES {
                break;
            }
            if !s.on_link {
                if !s.begun {
                    open += 1;
                }
                let begin = StrokeBegin {
                    stroke: s.id,
                    brush: self.options.brush,
                    device: Some(s.device.clone()),
                    params: None,
                    placement: self.options.placement,
                    solid: None,
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
            // This client reads nothing of the peers' events, so falling behind them costs it
            // nothing: the proxy resyncs the connection itself, and its own answers are never
            // dropped. Reconnecting would fetch the whole history again and, with many people
            // drawing fast, fall behind again (ten fast replays at once never got back in).
            ServerMessage::Error(err) if err.code == ErrorCode::Lagged => {
                tracing::debug!(message = %err.message, "behind the session's events");
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
        let ws = wire::open(&self.endpoint.ws_url(), &self.endpoint.token, None, HANDSHAKE_TIMEOUT)
            .await
            .map_err(|err| {
                let transient = match &err {
                    OpenError::BadRequest(_) => false,
                    OpenError::Refused { status } => status.is_server_error(),
                    OpenError::Timeout(_) | OpenError::Failed(_) => true,
                };
                let err = match err {
                    OpenError::Refused { .. } => anyhow::anyhow!(
                        "the proxy at {} refused the connection to session {}: {err}",
                        self.endpoint.base,
                        self.endpoint.session
                    ),
                    OpenError::BadRequest(_) => anyhow::anyhow!(err),
                    _ => anyhow::anyhow!("cannot connect to {}: {err}", self.endpoint.base),
                };
                if transient { ConnectError::Transient(err) } else { ConnectError::Fatal(err) }
            })?;
        let (sink, mut stream) = ws.split();
        let (tx, incoming) = mpsc::unbounded_channel();
        let reader = tokio::spawn(async move {
            while let Some(frame) = stream.next().await {
                let msg = match frame {
                    Ok(frame) => match wire::decode_frame(frame) {
                        Some(msg) => msg,
                        None => continue,
                    },
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
        let hello = wire::hello(
            "penmesh-client",
            Some(self.options.name.clone()),
            resume,
            Some(self.options.key.clone()),
        );
        send(&mut link, &hello).await.map_err(ConnectError::Transient)?;
        let incoming = futures_util::stream::poll_fn(|cx| link.incoming.poll_recv(cx));
        let answer = wire::await_welcome(HANDSHAKE_TIMEOUT, incoming).await;
        let welcome = match answer {
            Ok(Ok(welcome)) => welcome,
            Ok(Err(refusal)) => {
                let said = format!("{}: {}", refusal.code.as_str(), refusal.message);
                return Err(match self.on_error(refusal) {
                    ErrorAction::Reconnect => {
                        ConnectError::Transient(anyhow::anyhow!("the proxy is not ready ({said})"))
                    }
                    ErrorAction::Fail(err) => ConnectError::Fatal(err),
                });
            }
            Err(err) => return Err(ConnectError::Transient(err)),
        };
        for state in welcome.resume {
            self.apply_resume(state).map_err(ConnectError::Fatal)?;
        }
        Ok(link)
    }

    fn apply_resume(&mut self, state: ResumeState) -> anyhow::Result<()> {
        let Some(s) = self.stroke_mut(state.stroke) else { return Ok(()) };
        if s.resume(&state)? == Resumed::Done {
            self.finish_stroke(state.stroke);
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

async fn send(link: &mut Link, msg: &ClientMessage) -> anyhow::Result<()> {
    link.sink.send(wire::frame(msg)).await.context("sending to the proxy")?;
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
