//! Measurements of what one request may cost (issue 25), against the proxy binary on SQLite;
//! `docs/reliability.md` reports them. Ignored: run them on a release build with
//! `cargo test --release -p penmesh-e2e --test faults -- --ignored --nocapture --test-threads 1 costs::`
//! (each prints a `COSTS` line). They use only flags and routes older proxies have too, so
//! that the same measurement runs before and after a change.

use std::time::{Duration, Instant};

use penmesh::Sample;
use penmesh::protocol::{ServerMessage, StrokeId};
use penmesh_e2e::{TestDatabase, TestSession, WsClient};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use uuid::Uuid;

use crate::child::ProxyChild;

/// A gently curving stroke of `n` samples at 150 Hz (ACUTS keeps a few percent of it).
fn long_stroke(n: usize, k: usize) -> Vec<Sample> {
    (0..n)
        .map(|i| {
            let f = i as f64;
            let s = Sample::new(f * 0.5, 40.0 * (f / 3000.0).sin() + k as f64, f * 6.667, 0.5);
            penmesh::protocol::quantize_sample(&s)
        })
        .collect()
}

/// Draws `strokes` of `n` samples each at once on one connection, without ending them.
async fn draw_unfinished(
    port: u16,
    session: &TestSession,
    strokes: &[StrokeId],
    n: usize,
) -> WsClient {
    let mut ws = WsClient::try_connect(port, session).await.unwrap();
    ws.hello(vec![]).await;
    for (k, stroke) in strokes.iter().enumerate() {
        ws.begin(*stroke).await;
        ws.wait_ack(*stroke, 0).await;
        let samples = long_stroke(n, k);
        for (i, batch) in samples.chunks(4096).enumerate() {
            ws.points(*stroke, (i * 4096) as u64, batch).await;
        }
        ws.wait_ack(*stroke, n as u64).await;
    }
    ws
}

/// Resident and peak memory of process `pid`, in MB.
fn memory_mb(pid: i32) -> (u64, u64) {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    let field = |name: &str| {
        status
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
            .unwrap_or(0)
            / 1024
    };
    (field("VmRSS:"), field("VmHWM:"))
}

/// Percentiles 50 and 99 and the largest, in ms.
fn summary(mut latencies: Vec<Duration>) -> (f64, f64, f64) {
    latencies.sort();
    let at = |q: f64| {
        let i = ((latencies.len() as f64 * q) as usize).min(latencies.len().saturating_sub(1));
        latencies.get(i).map_or(f64::NAN, |d| d.as_secs_f64() * 1000.0)
    };
    (at(0.5), at(0.99), at(1.0))
}

/// A pen in a session of its own: a batch of 4 samples every 10 ms for `duration`, each
/// waited for; the time from each batch to its ack.
async fn pen_latencies(port: u16, session: TestSession, duration: Duration) -> Vec<Duration> {
    let mut ws = WsClient::try_connect(port, &session).await.unwrap();
    ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    ws.begin(stroke).await;
    ws.wait_ack(stroke, 0).await;
    let samples = long_stroke(100_000, 0);
    let (mut latencies, start, mut seq) = (Vec::new(), Instant::now(), 0);
    while start.elapsed() < duration {
        let sent = Instant::now();
        ws.points(stroke, seq as u64, &samples[seq..seq + 4]).await;
        seq += 4;
        ws.wait_ack(stroke, seq as u64).await;
        latencies.push(sent.elapsed());
        tokio::time::sleep(Duration::from_millis(10).saturating_sub(sent.elapsed())).await;
    }
    latencies
}

/// Says hello in `session` and reads its history up to `Synced`.
async fn hello(port: u16, session: &TestSession) {
    let mut ws = WsClient::try_connect(port, session).await.unwrap();
    ws.key = None;
    ws.hello(vec![]).await;
    loop {
        if let ServerMessage::Synced(_) = ws.recv_any().await {
            return;
        }
    }
}

async fn proxy_on_sqlite(args: &[&str]) -> (ProxyChild, TestDatabase) {
    let db = TestDatabase::fresh().await;
    assert!(!db.is_postgres(), "measured on SQLite: unset PENMESH_TEST_POSTGRES_URL");
    (ProxyChild::start(&db.url, args).await, db)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "a measurement (docs/reliability.md)"]
async fn hello_cost_with_long_interrupted_strokes() {
    let (proxy, _db) = proxy_on_sqlite(&[]).await;
    let session = proxy.create_session().await;
    let strokes: Vec<StrokeId> = (0..16).map(|_| Uuid::new_v4()).collect();
    let started = Instant::now();
    drop(draw_unfinished(proxy.port, &session, &strokes, 1_000_000).await);
    eprintln!("drew 16 x 1M samples in {:?}", started.elapsed());
    // Their connection is gone: the strokes are interrupted.
    loop {
        let list: serde_json::Value = proxy
            .http()
            .get(proxy.url(&format!("/v1/sessions/{}/strokes", session.session)))
            .bearer_auth(&session.token)
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        let strokes = list["strokes"].as_array().unwrap();
        if strokes.iter().all(|s| s["status"] == "interrupted") {
            break;
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    let mut hellos = Vec::new();
    for _ in 0..3 {
        let started = Instant::now();
        hello(proxy.port, &session).await;
        hellos.push(started.elapsed().as_secs_f64() * 1000.0);
    }
    eprintln!("COSTS hello: one Hello with 16 interrupted 1M-sample strokes {hellos:.0?} ms");
    let idle = summary(
        pen_latencies(proxy.port, proxy.create_session().await, Duration::from_secs(5)).await,
    );
    let stop = Instant::now() + Duration::from_secs(10);
    let loops: Vec<_> = (0..16)
        .map(|_| {
            let session = session.clone();
            let port = proxy.port;
            tokio::spawn(async move {
                let (mut n, mut failed) = (0, 0);
                while Instant::now() < stop {
                    // A Hello that fails (no answer, an error) panics its own task.
                    let session = session.clone();
                    match tokio::spawn(async move { hello(port, &session).await }).await {
                        Ok(()) => n += 1,
                        Err(_) => failed += 1,
                    }
                }
                (n, failed)
            })
        })
        .collect();
    // A pen that hears nothing for 15 s panics its task: reported as no answer.
    let pen = pen_latencies(proxy.port, proxy.create_session().await, Duration::from_secs(10));
    let pen = tokio::spawn(pen);
    let loaded = pen.await.map(summary).map_err(|_| "a wait of 15 s for an ack");
    let (mut n_hellos, mut n_failed) = (0, 0);
    for task in loops {
        let (n, failed) = task.await.unwrap();
        (n_hellos, n_failed) = (n_hellos + n, n_failed + failed);
    }
    let (rss, peak) = memory_mb(proxy.pid());
    eprintln!(
        "COSTS hello: another session's ack p50/p99/max {idle:.1?} ms alone, {loaded:.1?} ms \
         while 16 clients loop Hellos ({n_hellos} Hellos in 10 s, {n_failed} failed); proxy RSS {rss} MB, peak {peak} MB"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "a measurement (docs/reliability.md)"]
async fn memory_with_slow_raw_readers() {
    let (proxy, _db) = proxy_on_sqlite(&[]).await;
    let session = proxy.create_session().await;
    let stroke = Uuid::new_v4();
    let mut ws = draw_unfinished(proxy.port, &session, &[stroke], 1_000_000).await;
    ws.end(stroke, 1_000_000).await;
    loop {
        if let ServerMessage::StrokeDone(_) = ws.recv().await {
            break;
        }
    }
    let (before, _) = memory_mb(proxy.pid());
    // 24 clients ask for the raw samples (JSON) and read nothing past the status line.
    let mut readers = Vec::new();
    let mut statuses = std::collections::BTreeMap::new();
    for _ in 0..24 {
        let socket = tokio::net::TcpSocket::new_v4().unwrap();
        socket.set_recv_buffer_size(4096).unwrap();
        let mut tcp = socket.connect(([127, 0, 0, 1], proxy.port).into()).await.unwrap();
        let request = format!(
            "GET /v1/strokes/{stroke}/raw HTTP/1.1\r\nhost: 127.0.0.1\r\nauthorization: Bearer {}\r\n\r\n",
            session.token
        );
        tcp.write_all(request.as_bytes()).await.unwrap();
        let mut status = [0u8; 12];
        tcp.read_exact(&mut status).await.unwrap();
        *statuses.entry(String::from_utf8_lossy(&status[9..]).to_string()).or_insert(0) += 1;
        readers.push(tcp);
    }
    tokio::time::sleep(Duration::from_secs(3)).await;
    let (during, peak) = memory_mb(proxy.pid());
    eprintln!(
        "COSTS raw: 24 slow readers of a 1M-sample stroke's /raw (statuses {statuses:?}): proxy \
         RSS {before} MB before, {during} MB with them, peak {peak} MB"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "a measurement (docs/reliability.md)"]
async fn ack_latency_with_mesh_uploaders() {
    let (proxy, _db) = proxy_on_sqlite(&[]).await;
    let session = proxy.create_session().await;
    let strokes: Vec<StrokeId> = (0..4).map(|_| Uuid::new_v4()).collect();
    let mut ws = draw_unfinished(proxy.port, &session, &strokes, 100).await;
    for stroke in &strokes {
        ws.end(*stroke, 100).await;
    }
    let mut done = 0;
    while done < strokes.len() {
        if let ServerMessage::StrokeDone(_) = ws.recv().await {
            done += 1;
        }
    }
    // About 14.4 MB, under the 16 MiB body limit.
    let glb = penmesh_e2e::minimal_glb(600_000, 3);
    let idle = summary(
        pen_latencies(proxy.port, proxy.create_session().await, Duration::from_secs(5)).await,
    );
    let stop = Instant::now() + Duration::from_secs(10);
    let uploaders: Vec<_> = strokes
        .iter()
        .map(|stroke| {
            let (url, glb, session) =
                (proxy.url(&format!("/v1/strokes/{stroke}/mesh")), glb.clone(), session.clone());
            tokio::spawn(async move {
                let http = reqwest::Client::new();
                let mut statuses = std::collections::BTreeMap::new();
                while Instant::now() < stop {
                    let response = http
                        .put(&url)
                        .bearer_auth(&session.token)
                        .header(penmesh::protocol::KEY_HEADER, &session.key)
                        .body(glb.clone())
                        .send()
                        .await;
                    // 0: no answer (the connection failed).
                    let status = response.map_or(0, |r| r.status().as_u16());
                    *statuses.entry(status).or_insert(0) += 1;
                }
                statuses
            })
        })
        .collect();
    let loaded = summary(
        pen_latencies(proxy.port, proxy.create_session().await, Duration::from_secs(10)).await,
    );
    let mut statuses = std::collections::BTreeMap::new();
    for task in uploaders {
        for (status, n) in task.await.unwrap() {
            *statuses.entry(status).or_insert(0) += n;
        }
    }
    eprintln!(
        "COSTS mesh: another session's ack p50/p99/max {idle:.1?} ms alone, {loaded:.1?} ms \
         while 4 clients re-upload {} MB meshes (statuses {statuses:?})",
        glb.len() / 1_000_000
    );
}
