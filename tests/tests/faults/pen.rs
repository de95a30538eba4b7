//! A pen that draws through the real protocol and keeps drawing through faults: it streams
//! each stroke in paced batches, counts what the proxy acknowledges, and when its connection
//! fails (closed, an error, or no answer for [`Plan::stall`]) it reconnects and resumes the
//! stroke from where the proxy says it is (`Welcome.resume`), as `penmesh draw` does. A resume
//! point behind the last acknowledged sample is a loss, and is counted, not hidden.

use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use penmesh::Sample;
use penmesh::protocol::{
    ClientMessage, Hello, PROTOCOL_VERSION, PointBatch, Points, ServerMessage, StrokeBegin,
    StrokeEnd, StrokeStatus, decode_server, encode_client, quantize_sample,
};
use penmesh_e2e::{TestSession, stroke_samples};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};
use uuid::Uuid;

type Ws = WebSocketStream<MaybeTlsStream<TcpStream>>;

/// How one pen draws.
#[derive(Debug, Clone, Copy)]
pub struct Plan {
    pub strokes: usize,
    pub samples: usize,
    /// Samples per `Points` message.
    pub batch: usize,
    /// One batch per this long (a 150 Hz tablet in batches of 4: about 27 ms).
    pub every: Duration,
    /// No answer for this long while something is owed: the connection is given up.
    pub stall: Duration,
    /// Most samples sent and not yet acknowledged.
    pub window: usize,
    /// The pen gives up at this instant.
    pub give_up: Instant,
}

/// One stroke as the pen drew it.
#[derive(Debug, Clone)]
pub struct StrokeLog {
    pub id: Uuid,
    pub samples: Vec<Sample>,
    /// The highest `Ack.upto_seq` heard.
    pub acked: u64,
    /// `StrokeDone` heard (or a resume said `done`).
    pub done: bool,
    /// Acknowledged samples a resume said the proxy did not have.
    pub lost_on_resume: u64,
}

/// What one pen did.
#[derive(Debug, Default)]
pub struct PenLog {
    pub strokes: Vec<StrokeLog>,
    /// When each acknowledgement that moved a stroke forward (or finished it) arrived.
    pub progress: Vec<Instant>,
    /// Samples put on the wire, resends after a resume included.
    pub transmitted: u64,
    pub reconnects: u32,
    /// Why each connection was given up.
    pub failures: Vec<String>,
    /// Set when the pen gave up before drawing everything.
    pub gave_up: Option<String>,
}

/// The samples of pen `pen`'s stroke `k`: the e2e stroke, moved so strokes differ.
pub fn pen_samples(pen: usize, k: usize, n: usize) -> Vec<Sample> {
    let (dx, dy) = (pen as f64 * 37.0, k as f64 * 11.0);
    stroke_samples(n)
        .iter()
        .map(|s| quantize_sample(&Sample::new(s.x + dx, s.y + dy, s.t, s.p)))
        .collect()
}

/// Draws `plan.strokes` strokes into `session` on the proxy at `port`, through every fault.
pub async fn draw(port: u16, session: TestSession, pen: usize, plan: Plan) -> PenLog {
    // A participant of its own, the same across its reconnects.
    let session = session.stranger();
    let mut log = PenLog::default();
    let mut conn: Option<Ws> = None;
    for k in 0..plan.strokes {
        let mut stroke = Stroke {
            log: StrokeLog {
                id: Uuid::new_v4(),
                samples: pen_samples(pen, k, plan.samples),
                acked: 0,
                done: false,
                lost_on_resume: 0,
            },
            begin_sent: false,
            begun: false,
            next: 0,
        };
        while !stroke.log.done {
            if Instant::now() > plan.give_up {
                log.gave_up = Some(format!("stroke {k} not done: {:?}", log.failures.last()));
                log.strokes.push(stroke.log);
                return log;
            }
            if let Err(why) = stroke.attempt(&mut conn, port, &session, &plan, &mut log).await {
                log.failures.push(why);
                log.reconnects += 1;
                conn = None;
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
        }
        log.strokes.push(stroke.log);
    }
    if let Some(mut ws) = conn {
        let _ = ws.close(None).await;
    }
    log
}

struct Stroke {
    log: StrokeLog,
    /// A `StrokeBegin` went out: the stroke may exist, so a reconnect asks to resume it.
    begin_sent: bool,
    /// The begin was acknowledged: the stroke exists.
    begun: bool,
    /// The next sample to send.
    next: usize,
}

impl Stroke {
    /// Draws the rest of the stroke on `conn` (connecting first if needed), until `StrokeDone`.
    async fn attempt(
        &mut self,
        conn: &mut Option<Ws>,
        port: u16,
        session: &TestSession,
        plan: &Plan,
        log: &mut PenLog,
    ) -> Result<(), String> {
        let id = self.log.id;
        if conn.is_none() {
            let resume = if self.begin_sent { vec![id] } else { vec![] };
            let (ws, welcome) = connect(port, session, resume, plan.stall).await?;
            *conn = Some(ws);
            if let Some(state) = welcome.into_iter().next() {
                match state.status {
                    StrokeStatus::Done => {
                        self.log.done = true;
                        log.progress.push(Instant::now());
                        return Ok(());
                    }
                    StrokeStatus::Open => {
                        let next = state.next_seq;
                        if next < self.log.acked {
                            // Counted as lost (the test fails with the figures); named here.
                            eprintln!(
                                "stroke {id}: resumed at {next} after {} were acknowledged",
                                self.log.acked
                            );
                        }
                        self.log.lost_on_resume += self.log.acked.saturating_sub(next);
                        // Everything before the resume point is committed: as good as an ack.
                        self.log.acked = self.log.acked.max(next);
                        self.next = next as usize;
                        self.begun = true;
                    }
                    StrokeStatus::Unknown if self.log.acked == 0 => self.begun = false,
                    other => {
                        return Err(format!("stroke {id} cannot be resumed yet: {other:?}"));
                    }
                }
            }
        }
        let ws = conn.as_mut().expect("connected");
        let n = self.log.samples.len();
        if !self.begun {
            self.begin_sent = true;
            self.next = 0;
            let begin = ClientMessage::StrokeBegin(StrokeBegin {
                stroke: id,
                brush: Default::default(),
                device: Some("synth:faults".into()),
                params: None,
                placement: None,
                solid: None,
            });
            send(ws, &begin, plan.stall).await?;
        }
        let mut ticker = tokio::time::interval(plan.every);
        let mut last_heard = Instant::now();
        let mut ended = false;
        loop {
            if self.begun && self.log.acked == n as u64 && !ended {
                let end = ClientMessage::StrokeEnd(StrokeEnd { stroke: id, n_points: n as u64 });
                send(ws, &end, plan.stall).await?;
                ended = true;
            }
            let owed = !self.begun || (self.log.acked as usize) < self.next || ended;
            let can_send = self.begun
                && self.next < n
                && self.next.saturating_sub(self.log.acked as usize) < plan.window;
            tokio::select! {
                _ = ticker.tick(), if can_send => {
                    let end = (self.next + plan.batch).min(n);
                    let points = ClientMessage::Points(Points {
                        stroke: id,
                        seq: self.next as u64,
                        points: PointBatch(self.log.samples[self.next..end].to_vec()),
                    });
                    if !owed {
                        last_heard = Instant::now();
                    }
                    send(ws, &points, plan.stall).await?;
                    log.transmitted += (end - self.next) as u64;
                    self.next = end;
                }
                _ = tokio::time::sleep_until((last_heard + plan.stall).into()), if owed => {
                    return Err(format!("no answer for {:?}", plan.stall));
                }
                frame = ws.next() => {
                    last_heard = Instant::now();
                    let msg = match frame {
                        Some(Ok(Message::Binary(bytes))) => decode_server(&bytes, usize::MAX)
                            .map_err(|e| format!("undecodable frame: {e}"))?,
                        Some(Ok(Message::Close(close))) => return Err(format!("closed: {close:?}")),
                        Some(Ok(_)) => continue,
                        Some(Err(err)) => return Err(format!("socket: {err}")),
                        None => return Err("socket ended".into()),
                    };
                    match msg {
                        ServerMessage::Ack(ack) if ack.stroke == id => {
                            if !self.begun {
                                self.begun = true;
                                log.progress.push(Instant::now());
                            }
                            if ack.upto_seq > self.log.acked {
                                self.log.acked = ack.upto_seq;
                                log.progress.push(Instant::now());
                            }
                        }
                        ServerMessage::StrokeDone(done) if done.stroke == id => {
                            self.log.done = true;
                            log.progress.push(Instant::now());
                            return Ok(());
                        }
                        ServerMessage::Error(err) => {
                            return Err(format!("error {:?}: {}", err.code, err.message));
                        }
                        _ => {}
                    }
                }
            }
        }
    }
}

async fn send(ws: &mut Ws, msg: &ClientMessage, within: Duration) -> Result<(), String> {
    let frame = Message::Binary(encode_client(msg).into());
    match tokio::time::timeout(within, ws.send(frame)).await {
        Ok(Ok(())) => Ok(()),
        Ok(Err(err)) => Err(format!("sending: {err}")),
        Err(_) => Err(format!("sending took longer than {within:?}")),
    }
}

/// Opens a connection, says hello asking to resume `resume`, and returns the resume states.
async fn connect(
    port: u16,
    session: &TestSession,
    resume: Vec<Uuid>,
    within: Duration,
) -> Result<(Ws, Vec<penmesh::protocol::ResumeState>), String> {
    let opened = async {
        let (mut ws, _) = tokio_tungstenite::connect_async(penmesh_e2e::ws_request(port, session))
            .await
            .map_err(|e| format!("connect: {e}"))?;
        let hello = ClientMessage::Hello(Hello {
            protocol: PROTOCOL_VERSION,
            client: "penmesh-faults".into(),
            name: None,
            resume,
            key: Some(session.key.clone()),
        });
        ws.send(Message::Binary(encode_client(&hello).into()))
            .await
            .map_err(|e| format!("hello: {e}"))?;
        loop {
            match ws.next().await {
                Some(Ok(Message::Binary(bytes))) => {
                    match decode_server(&bytes, usize::MAX).map_err(|e| e.to_string())? {
                        ServerMessage::Welcome(welcome) => return Ok((ws, welcome.resume)),
                        ServerMessage::Error(err) => {
                            return Err(format!("hello refused {:?}: {}", err.code, err.message));
                        }
                        _ => {}
                    }
                }
                Some(Ok(Message::Close(close))) => return Err(format!("closed: {close:?}")),
                Some(Ok(_)) => {}
                Some(Err(err)) => return Err(format!("socket: {err}")),
                None => return Err("socket ended before welcome".into()),
            }
        }
    };
    tokio::time::timeout(within, opened)
        .await
        .unwrap_or_else(|_| Err(format!("no welcome within {within:?}")))
}
