//! One simulated pen: a WebSocket that draws generated strokes at a tablet's cadence, sends a
//! binary `Points` frame every batch interval, and times every `Ack` and `StrokeDone`.

use std::collections::{HashMap, VecDeque};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use anyhow::Context;
use futures_util::{SinkExt, StreamExt};
use hdrhistogram::Histogram;
use penmesh::protocol::{
    ClientMessage, PointBatch, Points, ServerMessage, StrokeBegin, StrokeEnd, quantize_sample,
};
use penmesh::{Brush, GeneratorParams, Sample, Shape};
use tokio::time::Instant;
use tokio_tungstenite::tungstenite::protocol::WebSocketConfig;
use uuid::Uuid;

use super::Plan;
use penmesh_client::wire::{self, Socket};

/// Different generated strokes the pens share (each pen walks through them in its own order).
const STROKE_POOL: usize = 40;
/// Longest wait for a connection's handshake and `Welcome`.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(15);
/// Latencies are recorded in microseconds, up to this.
const MAX_LATENCY_US: u64 = 3_600_000_000;

/// What a pen needs to know, shared by all pens.
#[derive(Debug)]
pub(super) struct Shared {
    pub(super) base_ws: String,
    pub(super) pool: Vec<Arc<Vec<Sample>>>,
    pub(super) start: Instant,
    pub(super) ramp: Duration,
    pub(super) deadline: Instant,
    pub(super) drain: Duration,
    pub(super) batch: Duration,
    pub(super) pause: Duration,
    pub(super) max_strokes: u64,
    pub(super) idle: bool,
    pub(super) clients: usize,
    pub(super) counters: Counters,
}

/// Counters every pen adds to, read by the progress line and the window snapshots.
#[derive(Debug, Default)]
pub(super) struct Counters {
    pub(super) connected: AtomicU64,
    pub(super) failed: AtomicU64,
    pub(super) sent: AtomicU64,
    pub(super) acked: AtomicU64,
    pub(super) done: AtomicU64,
    pub(super) errors: AtomicU64,
}

/// What one pen brings back.
#[derive(Debug)]
pub(super) struct PenResult {
    pub(super) connected: bool,
    pub(super) dropped: bool,
    pub(super) sent: u64,
    pub(super) acked: u64,
    pub(super) begun: u64,
    pub(super) done: u64,
    pub(super) errors: Vec<String>,
    pub(super) ack_us: Histogram<u64>,
    /// Pen-up to `StrokeDone`, strokes the pen ended by itself.
    pub(super) done_us: Histogram<u64>,
    /// The same for the strokes lifted because the run ended.
    pub(super) run_end_done_us: Histogram<u64>,
    /// The acknowledged samples by the second of the run they were sent in: when a run's slow
    /// spell was (a p99 alone does not say).
    pub(super) ack_seconds: AckSeconds,
}

/// The samples sent in one second of the run and acknowledged: how many, how many waited
/// [`SLOW_ACK_US`] or more, and the longest wait.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub(super) struct AckSecond {
    pub(super) acked: u64,
    pub(super) slow: u64,
    pub(super) max_us: u64,
}

/// An acknowledgement this late is slow (the pinned goal's p99 bound).
pub(super) const SLOW_ACK_US: u64 = 50_000;

impl AckSecond {
    fn add(&mut self, other: &AckSecond) {
        self.acked += other.acked;
        self.slow += other.slow;
        self.max_us = self.max_us.max(other.max_us);
    }
}

/// [`AckSecond`]s, one for each second of the run from its start.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub(super) struct AckSeconds(pub(super) Vec<AckSecond>);

impl AckSeconds {
    /// The tally of `second`, made (with those before it) when it is the first.
    fn at(&mut self, second: usize) -> &mut AckSecond {
        if self.0.len() <= second {
            self.0.resize(second + 1, AckSecond::default());
        }
        &mut self.0[second]
    }

    /// Adds `n` samples acknowledged after `latency_us` to the tally of `second`.
    fn record(&mut self, second: usize, latency_us: u64, n: u64) {
        let slow = if latency_us >= SLOW_ACK_US { n } else { 0 };
        self.at(second).add(&AckSecond { acked: n, slow, max_us: latency_us });
    }

    /// Adds another pen's tallies, second by second.
    pub(super) fn merge(&mut self, other: &AckSeconds) {
        for (second, tally) in other.0.iter().enumerate() {
            self.at(second).add(tally);
        }
    }
}

impl PenResult {
    pub(super) fn new() -> PenResult {
        PenResult {
            connected: false,
            dropped: false,
            sent: 0,
            acked: 0,
            begun: 0,
            done: 0,
            errors: Vec::new(),
            ack_us: histogram(),
            done_us: histogram(),
            run_end_done_us: histogram(),
            ack_seconds: AckSeconds::default(),
        }
    }
}

pub(super) fn histogram() -> Histogram<u64> {
    Histogram::new_with_bounds(1, MAX_LATENCY_US, 2).expect("valid histogram bounds")
}

/// The strokes the pens draw: every shape at the run's rate and speed, several seeds, with
/// samples snapped to the codec's grid (what the proxy stores is then what was sent), and what
/// the native client's default stage 1 keeps of them (`penmesh::resample`: repeats dropped).
pub(super) fn stroke_pool(plan: &Plan) -> anyhow::Result<Vec<Arc<Vec<Sample>>>> {
    (0..STROKE_POOL)
        .map(|k| {
            let params = GeneratorParams {
                shape: Shape::ALL[k % Shape::ALL.len()],
                speed: plan.speed_px_per_s,
                rate_hz: plan.rate_hz,
                seed: k as u64,
                ..GeneratorParams::default()
            };
            let stroke = penmesh::generate_stroke(&params)
                .map_err(|e| anyhow::anyhow!("cannot generate the strokes: {e}"))?;
            let drawn: Vec<Sample> = stroke.samples().iter().map(quantize_sample).collect();
            let kept = penmesh::resample(&drawn, penmesh::DEFAULT_RESAMPLE_DISTANCE);
            Ok(Arc::new(kept.into_iter().map(|i| drawn[i]).collect()))
        })
        .collect()
}

/// The stroke a pen is drawing.
#[derive(Debug)]
struct Drawing {
    id: Uuid,
    samples: Arc<Vec<Sample>>,
    began: Instant,
    sent: usize,
}

/// Batches of one stroke not yet acknowledged: (end seq, sent at).
#[derive(Debug, Default)]
struct Unacked {
    batches: VecDeque<(u64, Instant)>,
    acked: u64,
}

/// One simulated pen: connect, draw strokes until the deadline, then wait for the last acks.
pub(super) async fn pen(
    pen_idx: usize,
    session: Uuid,
    token: String,
    shared: Arc<Shared>,
) -> PenResult {
    let mut result = PenResult::new();
    let offset = shared.ramp.mul_f64(pen_idx as f64 / shared.clients as f64);
    tokio::time::sleep_until(shared.start + offset).await;
    let mut ws = match connect(&shared.base_ws, session, &token).await {
        Ok(ws) => ws,
        Err(err) => {
            shared.counters.failed.fetch_add(1, Ordering::Relaxed);
            shared.counters.errors.fetch_add(1, Ordering::Relaxed);
            result.errors.push(format!("{err:#}"));
            return result;
        }
    };
    result.connected = true;
    shared.counters.connected.fetch_add(1, Ordering::Relaxed);
    if let Err(err) = draw(pen_idx, &mut ws, &shared, &mut result).await {
        result.dropped = true;
        shared.counters.errors.fetch_add(1, Ordering::Relaxed);
        result.errors.push(format!("{err:#}"));
    }
    let _ = tokio::time::timeout(Duration::from_secs(2), ws.close(None)).await;
    result
}

async fn connect(base_ws: &str, session: Uuid, token: &str) -> anyhow::Result<Socket> {
    let url = format!("{base_ws}{}", penmesh_client::api::session_ws(session));
    // A small read buffer: tungstenite zero-fills it all, and thousands of pens share this
    // process (acks are a few dozen bytes).
    let config = WebSocketConfig::default().read_buffer_size(4 * 1024);
    let handshake = async {
        let mut ws = wire::open(&url, token, Some(config), CONNECT_TIMEOUT)
            .await
            .map_err(|e| anyhow::anyhow!("cannot connect: {e}"))?;
        // A participant of its own per pen.
        let key = Some(wire::new_participant_key());
        ws.send(wire::frame(&wire::hello("penmesh-load", None, Vec::new(), key)))
            .await
            .context("sending")?;
        let answer =
            wire::await_welcome(CONNECT_TIMEOUT, std::pin::pin!(wire::messages(&mut ws))).await?;
        match answer {
            Ok(_) => Ok(ws),
            Err(e) => anyhow::bail!("refused: {}: {}", e.code.as_str(), e.message),
        }
    };
    tokio::time::timeout(CONNECT_TIMEOUT, handshake)
        .await
        .map_err(|_| anyhow::anyhow!("no welcome within {} s", CONNECT_TIMEOUT.as_secs()))?
}

async fn feed(ws: &mut Socket, msg: &ClientMessage) -> anyhow::Result<()> {
    ws.feed(wire::frame(msg)).await.context("sending")
}

/// The next protocol message (control frames are passed over; tungstenite answers pings).
async fn next_message(ws: &mut Socket) -> anyhow::Result<ServerMessage> {
    wire::messages(ws).next().await.unwrap_or_else(|| anyhow::bail!("the connection ended"))
}

fn elapsed_us(since: Instant, now: Instant) -> u64 {
    (now.duration_since(since).as_micros() as u64).clamp(1, MAX_LATENCY_US)
}

async fn draw(
    pen_idx: usize,
    ws: &mut Socket,
    shared: &Shared,
    result: &mut PenResult,
) -> anyhow::Result<()> {
    let counters = &shared.counters;
    let mut unacked: HashMap<Uuid, Unacked> = HashMap::new();
    // When each ended stroke's `StrokeEnd` went, and whether the run's end lifted it.
    let mut pen_ups: HashMap<Uuid, (Instant, bool)> = HashMap::new();
    let mut drawing: Option<Drawing> = None;
    // Pens start at different points of their rhythm, so batches do not all leave at once.
    let phase = shared.batch.mul_f64((pen_idx % 97) as f64 / 97.0);
    let mut next_stroke_at = Instant::now() + phase;
    let mut ticker = tokio::time::interval_at(next_stroke_at, shared.batch);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let drain_until = shared.deadline + shared.drain;
    loop {
        let finished = Instant::now() >= shared.deadline && drawing.is_none();
        if finished && (shared.idle || (pen_ups.is_empty() && unacked.is_empty())) {
            return Ok(());
        }
        tokio::select! {
            _ = ticker.tick(), if !finished && !shared.idle => {
                let now = Instant::now();
                if drawing.is_none()
                    && now >= next_stroke_at
                    && now < shared.deadline
                    && result.begun < shared.max_strokes
                {
                    let samples = shared.pool[(pen_idx * 7 + result.begun as usize) % shared.pool.len()].clone();
                    // Time-ordered, as the native client's (`live::stroke_log`).
                    let id = Uuid::now_v7();
                    feed(ws, &ClientMessage::StrokeBegin(StrokeBegin {
                        stroke: id,
                        brush: Brush::default(),
                        device: Some("penmesh-load".into()),
                        params: None,
                        placement: None,
                        solid: None,
                    }))
                    .await?;
                    unacked.insert(id, Unacked::default());
                    result.begun += 1;
                    // The first sample is due at once: the pen touched down.
                    drawing = Some(Drawing { id, samples, began: now - Duration::from_micros(1), sent: 0 });
                }
                let Some(d) = drawing.as_mut() else { continue };
                let elapsed_ms = now.duration_since(d.began).as_secs_f64() * 1000.0;
                let lifting = now >= shared.deadline;
                let t0 = d.samples[0].t;
                let mut end = d.samples.partition_point(|s| s.t - t0 <= elapsed_ms);
                if lifting {
                    // The run is over: the pen lifts here (a stroke needs two samples).
                    end = end.max(2).min(d.samples.len());
                }
                if end > d.sent {
                    let points = Points {
                        stroke: d.id,
                        seq: d.sent as u64,
                        points: PointBatch(d.samples[d.sent..end].to_vec()),
                    };
                    feed(ws, &ClientMessage::Points(points)).await?;
                    let n = (end - d.sent) as u64;
                    unacked.entry(d.id).or_default().batches.push_back((end as u64, now));
                    d.sent = end;
                    result.sent += n;
                    counters.sent.fetch_add(n, Ordering::Relaxed);
                }
                if end == d.samples.len() || lifting {
                    feed(ws, &ClientMessage::StrokeEnd(StrokeEnd { stroke: d.id, n_points: d.sent as u64 })).await?;
                    pen_ups.insert(d.id, (now, end < d.samples.len()));
                    drawing = None;
                    next_stroke_at = now + shared.pause;
                }
                ws.flush().await.context("sending")?;
            }
            msg = next_message(ws) => {
                let now = Instant::now();
                match msg? {
                    ServerMessage::Ack(ack) => {
                        if let Some(u) = unacked.get_mut(&ack.stroke) {
                            while let Some(&(end, sent_at)) = u.batches.front() {
                                if end > ack.upto_seq {
                                    break;
                                }
                                let n = end - u.acked.min(end);
                                u.batches.pop_front();
                                let latency_us = elapsed_us(sent_at, now);
                                let _ = result.ack_us.record_n(latency_us, n);
                                let second = sent_at.saturating_duration_since(shared.start).as_secs();
                                result.ack_seconds.record(second as usize, latency_us, n);
                                u.acked = end;
                                result.acked += n;
                                counters.acked.fetch_add(n, Ordering::Relaxed);
                            }
                        }
                    }
                    ServerMessage::StrokeDone(done) => {
                        if let Some((up, by_run_end)) = pen_ups.remove(&done.stroke) {
                            let latency = if by_run_end {
                                &mut result.run_end_done_us
                            } else {
                                &mut result.done_us
                            };
                            let _ = latency.record(elapsed_us(up, now));
                            result.done += 1;
                            counters.done.fetch_add(1, Ordering::Relaxed);
                        }
                        if unacked.get(&done.stroke).is_some_and(|u| u.batches.is_empty()) {
                            unacked.remove(&done.stroke);
                        }
                    }
                    ServerMessage::Error(e) => {
                        counters.errors.fetch_add(1, Ordering::Relaxed);
                        result.errors.push(format!("{}: {}", e.code.as_str(), e.message));
                    }
                    _ => {}
                }
                if Instant::now() >= drain_until {
                    anyhow::bail!(
                        "{} strokes and {} batches still unacknowledged {} s after the end",
                        pen_ups.len(),
                        unacked.values().map(|u| u.batches.len()).sum::<usize>(),
                        shared.drain.as_secs()
                    );
                }
            }
            _ = tokio::time::sleep_until(drain_until), if finished => {
                anyhow::bail!(
                    "{} strokes and {} batches still unacknowledged {} s after the end",
                    pen_ups.len(),
                    unacked.values().map(|u| u.batches.len()).sum::<usize>(),
                    shared.drain.as_secs()
                );
            }
            _ = tokio::time::sleep_until(shared.deadline), if shared.idle && !finished => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn acks_are_tallied_in_the_second_they_were_sent_and_slow_from_the_bound_on() {
        let mut seconds = AckSeconds::default();
        seconds.record(2, SLOW_ACK_US - 1, 3);
        seconds.record(2, SLOW_ACK_US, 2);
        seconds.record(0, 10, 1);
        let second = |acked, slow, max_us| AckSecond { acked, slow, max_us };
        assert_eq!(
            seconds.0,
            vec![second(1, 0, 10), AckSecond::default(), second(5, 2, SLOW_ACK_US)]
        );
        let mut sum = AckSeconds(vec![second(1, 1, 70_000)]);
        sum.merge(&seconds);
        assert_eq!(sum.0[0], second(2, 1, 70_000));
        assert_eq!(sum.0[2], second(5, 2, SLOW_ACK_US));
    }
}
