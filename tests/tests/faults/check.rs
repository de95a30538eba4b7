//! A load of pens run through a fault, and the checks after it: what the pens were told is
//! acknowledged is stored, once, in order, every stroke is readable and finished, and every
//! pen drew again soon after the fault ended.

use std::time::{Duration, Instant};

use penmesh::Sample;
use penmesh_e2e::TestSession;

use crate::child::ProxyChild;
use crate::pen::{self, PenLog, Plan};

/// Pens drawing into one session.
pub struct Load {
    pub session: TestSession,
    pens: Vec<tokio::task::JoinHandle<PenLog>>,
}

impl Load {
    /// Starts `pens` pens drawing on `proxy` and returns once each has had an acknowledgement
    /// (so the fault hits a load in full flow).
    pub async fn start(proxy: &ProxyChild, session: &TestSession, pens: usize, plan: Plan) -> Load {
        let session = session.clone();
        let handles = (0..pens)
            .map(|k| tokio::spawn(pen::draw(proxy.port, session.clone(), k, plan)))
            .collect();
        let load = Load { session, pens: handles };
        // Warm-up: every stroke list entry appears once its begin is committed.
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            let list = proxy
                .http()
                .get(proxy.url(&format!("/v1/sessions/{}/strokes", load.session.session)))
                .bearer_auth(&load.session.token)
                .send()
                .await
                .unwrap()
                .json::<serde_json::Value>()
                .await
                .unwrap();
            let open = list["strokes"].as_array().map_or(0, |s| s.len());
            if open >= pens {
                break;
            }
            assert!(Instant::now() < deadline, "the pens did not start drawing: {list}");
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        tokio::time::sleep(Duration::from_millis(500)).await;
        load
    }

    /// Waits for every pen to finish (each gives up at its plan's `give_up`).
    pub async fn finish(self) -> (TestSession, Vec<PenLog>) {
        let mut logs = Vec::new();
        for pen in self.pens {
            logs.push(pen.await.expect("a pen does not panic"));
        }
        (self.session, logs)
    }
}

/// What a scenario measured.
#[derive(Debug, Default)]
pub struct Figures {
    pub strokes: usize,
    /// Distinct samples the pens drew.
    pub drawn: u64,
    /// Samples put on the wire, resends included.
    pub transmitted: u64,
    pub acknowledged: u64,
    pub stored: u64,
    /// Acknowledged, then missing from storage (or from a resume point).
    pub lost: u64,
    /// Stored more than once.
    pub stored_twice: u64,
    pub reconnects: u32,
    /// For each pen, from `since` to its first progress after it.
    pub recovery: Vec<Duration>,
}

impl Figures {
    pub fn slowest_recovery(&self) -> Duration {
        self.recovery.iter().copied().max().unwrap_or_default()
    }

    /// One line for the test's output (what `docs/reliability.md` quotes).
    pub fn line(&self, scenario: &str) -> String {
        format!(
            "FIGURES {scenario}: strokes {} drawn {} transmitted {} acknowledged {} stored {} \
             lost {} stored_twice {} reconnects {} recovery_max_ms {} recovery_ms {:?}",
            self.strokes,
            self.drawn,
            self.transmitted,
            self.acknowledged,
            self.stored,
            self.lost,
            self.stored_twice,
            self.reconnects,
            self.slowest_recovery().as_millis(),
            self.recovery.iter().map(|d| d.as_millis()).collect::<Vec<_>>()
        )
    }
}

/// Reads back every stroke the pens drew and checks it; `since` is when the fault ended.
pub async fn verify(
    proxy: &ProxyChild,
    session: &TestSession,
    logs: &[PenLog],
    since: Instant,
) -> Figures {
    let mut figures = Figures::default();
    for (k, log) in logs.iter().enumerate() {
        assert!(
            log.gave_up.is_none(),
            "pen {k} gave up: {:?}; failures {:?}",
            log.gave_up,
            log.failures
        );
        figures.transmitted += log.transmitted;
        figures.reconnects += log.reconnects;
        let first_after = log.progress.iter().find(|t| **t >= since);
        let first_after =
            first_after.unwrap_or_else(|| panic!("pen {k} made no progress after the fault"));
        figures.recovery.push(first_after.duration_since(since));
        for stroke in &log.strokes {
            figures.strokes += 1;
            figures.drawn += stroke.samples.len() as u64;
            figures.acknowledged += stroke.acked;
            figures.lost += stroke.lost_on_resume;
            let stored = raw_samples(proxy, session, stroke.id).await;
            figures.stored += stored.len() as u64;
            let common = stored.len().min(stroke.samples.len());
            let same = stored[..common] == stroke.samples[..common];
            assert!(same, "stroke {} holds samples that were not drawn there", stroke.id);
            figures.stored_twice += stored.len().saturating_sub(stroke.samples.len()) as u64;
            figures.lost += stroke.acked.saturating_sub(stored.len() as u64);
            assert!(stroke.done, "stroke {} of pen {k} is not finished", stroke.id);
            let info = proxy
                .http()
                .get(proxy.url(&format!("/v1/strokes/{}/simplified", stroke.id)))
                .bearer_auth(&session.token)
                .send()
                .await
                .unwrap();
            assert_eq!(info.status(), 200, "the simplified stroke {} is readable", stroke.id);
        }
    }
    figures
}

/// The stored raw samples of a stroke (the HTTP API, which reads every chunk and refuses a
/// stroke whose chunks overlap or leave a hole).
pub async fn raw_samples(
    proxy: &ProxyChild,
    session: &TestSession,
    stroke: uuid::Uuid,
) -> Vec<Sample> {
    let response = proxy
        .http()
        .get(proxy.url(&format!("/v1/strokes/{stroke}/raw")))
        .bearer_auth(&session.token)
        .send()
        .await
        .unwrap();
    let status = response.status();
    let body: serde_json::Value = response.json().await.unwrap();
    assert_eq!(status, 200, "stroke {stroke} is readable: {body}");
    serde_json::from_value(body["samples"].clone()).unwrap()
}

/// Asserts the scenario's promises: nothing acknowledged lost, nothing stored twice, every
/// pen drawing again within `deadline` of the fault's end.
pub fn assert_promises(figures: &Figures, deadline: Duration) {
    assert_eq!(figures.lost, 0, "acknowledged samples lost: {figures:?}");
    assert_eq!(figures.stored_twice, 0, "samples stored twice: {figures:?}");
    assert_eq!(figures.stored, figures.drawn, "every drawn sample stored: {figures:?}");
    assert!(
        figures.slowest_recovery() <= deadline,
        "a pen took {:?} to draw again (deadline {deadline:?}): {figures:?}",
        figures.slowest_recovery()
    );
}

/// A participant that only watches: it collects the strokes whose `PeerStrokeDone` it saw,
/// reconnecting (and so reading the session's history again) whenever its connection ends or
/// the proxy tells it to, as a client does.
pub struct Watcher {
    seen: std::sync::Arc<std::sync::Mutex<std::collections::HashSet<uuid::Uuid>>>,
    task: tokio::task::JoinHandle<()>,
}

impl Drop for Watcher {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl Watcher {
    pub fn join(port: u16, session: &TestSession) -> Watcher {
        use futures_util::{SinkExt, StreamExt};
        use penmesh::protocol::{ClientMessage, Hello, PROTOCOL_VERSION, ServerMessage};
        use tokio_tungstenite::tungstenite::Message;
        use tokio_tungstenite::tungstenite::client::IntoClientRequest;

        let seen = std::sync::Arc::new(std::sync::Mutex::new(std::collections::HashSet::new()));
        let (out, session) = (seen.clone(), session.clone());
        let task = tokio::spawn(async move {
            loop {
                let mut request =
                    format!("ws://127.0.0.1:{port}/v1/sessions/{}/ws", session.session)
                        .into_client_request()
                        .unwrap();
                request
                    .headers_mut()
                    .insert("authorization", format!("Bearer {}", session.token).parse().unwrap());
                if let Ok((mut ws, _)) = tokio_tungstenite::connect_async(request).await {
                    let hello = ClientMessage::Hello(Hello {
                        protocol: PROTOCOL_VERSION,
                        client: "penmesh-faults-watcher".into(),
                        name: None,
                        resume: vec![],
                        key: None,
                    });
                    let frame = Message::Binary(penmesh::protocol::encode_client(&hello).into());
                    if ws.send(frame).await.is_ok() {
                        while let Some(Ok(frame)) = ws.next().await {
                            let Message::Binary(bytes) = frame else { continue };
                            match penmesh::protocol::decode_server(&bytes, usize::MAX) {
                                Ok(ServerMessage::PeerStrokeDone(done)) => {
                                    out.lock().unwrap().insert(done.stroke);
                                }
                                // A history's whole strokes, several to a message.
                                Ok(ServerMessage::PeerStrokes(strokes)) => {
                                    let done = strokes.strokes.iter().filter(|s| s.done);
                                    out.lock().unwrap().extend(done.map(|s| s.stroke));
                                }
                                // "could not read the session's history; reconnect".
                                Ok(ServerMessage::Error(err))
                                    if err.message.contains("reconnect") =>
                                {
                                    break;
                                }
                                _ => {}
                            }
                        }
                    }
                }
                tokio::time::sleep(Duration::from_millis(200)).await;
            }
        });
        Watcher { seen, task }
    }

    /// Waits until every stroke of `logs` was seen done; returns how long that took from
    /// `since`, or the strokes still unseen at `deadline` after it.
    pub async fn wait_all(
        &self,
        logs: &[PenLog],
        since: Instant,
        deadline: Duration,
    ) -> Result<Duration, Vec<uuid::Uuid>> {
        let ids: Vec<uuid::Uuid> = logs.iter().flat_map(|l| &l.strokes).map(|s| s.id).collect();
        loop {
            let missing: Vec<uuid::Uuid> = {
                let seen = self.seen.lock().unwrap();
                ids.iter().filter(|id| !seen.contains(id)).copied().collect()
            };
            if missing.is_empty() {
                return Ok(since.elapsed());
            }
            if since.elapsed() > deadline {
                return Err(missing);
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }
}
