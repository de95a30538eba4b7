//! The fan-out latency harness of `docs/performance.md` (ignored: run it in release):
//!
//! ```text
//! CARGO_TARGET_DIR=target-proxy cargo test --release -p penmesh-e2e --test sessions \
//!     -- --ignored --nocapture fanout_latency
//! ```
//!
//! Every participant draws one stroke at a pen's pace (4 samples every 25 ms, 160 Hz) while
//! reading. A retained sample's latency runs from the send of the batch that made the proxy
//! decide it (the drawer's own `Retained` tells which) to its `PeerRetained` at each peer. On
//! localhost the send is the arrival. Two replicas (with PostgreSQL) count only deliveries from
//! a drawer on one replica to a peer on the other.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

use penmesh::protocol::ServerMessage;
use penmesh_e2e::{TestDatabase, TestProxy, spawn_proxy_on, spawn_replica};
use uuid::Uuid;

use crate::helpers::{Participant, samples_for};

const BATCH: usize = 4;
const PACE: Duration = Duration::from_millis(25);
const BATCHES: usize = 120;

/// What one participant saw: when each own retained sample was caused, and when each peer
/// sample arrived.
#[derive(Debug, Default)]
struct Record {
    replica: usize,
    caused: HashMap<(Uuid, u64), Instant>,
    received: Vec<(Uuid, u64, Instant)>,
}

async fn run_participant(
    mut me: Participant,
    replica: usize,
    k: usize,
    start: Arc<tokio::sync::Barrier>,
    n_peers: usize,
) -> Record {
    let stroke = Uuid::new_v4();
    let samples = samples_for(k, BATCH * BATCHES);
    let mut record = Record { replica, ..Record::default() };
    start.wait().await;
    me.begin(stroke).await;
    let mut tick = tokio::time::interval(PACE);
    let (mut next_batch, mut last_sent) = (0, Instant::now());
    let mut peers_done = me.view.n_done();
    let mut ended = false;
    while !(ended && peers_done == n_peers) {
        tokio::select! {
            _ = tick.tick(), if next_batch < BATCHES => {
                let from = next_batch * BATCH;
                last_sent = Instant::now();
                me.ws.points(stroke, from as u64, &samples[from..from + BATCH]).await;
                next_batch += 1;
                if next_batch == BATCHES {
                    me.ws.end(stroke, samples.len() as u64).await;
                    ended = true;
                }
            }
            msg = me.ws.recv_any() => {
                let now = Instant::now();
                match &msg {
                    ServerMessage::Retained(r) => {
                        for i in 0..r.points.0.len() as u64 {
                            record.caused.insert((r.stroke, r.first + i), last_sent);
                        }
                    }
                    ServerMessage::PeerRetained(r) => {
                        for i in 0..r.points.0.len() as u64 {
                            record.received.push((r.stroke, r.first + i, now));
                        }
                    }
                    ServerMessage::Error(e) => panic!("error while measuring: {e:?}"),
                    _ => {}
                }
                me.view.apply(&msg);
                peers_done = me.view.n_done();
            }
        }
    }
    record
}

async fn measure(proxies: &[TestProxy], n: usize) -> (Vec<f64>, Vec<f64>) {
    let session = proxies[0].create_session().await;
    let start = Arc::new(tokio::sync::Barrier::new(n));
    let mut tasks = Vec::new();
    for k in 0..n {
        let replica = k % proxies.len();
        let me = Participant::join(&proxies[replica], &session, &format!("p{k}")).await;
        tasks.push(tokio::spawn(run_participant(me, replica, k, start.clone(), n - 1)));
    }
    let mut records = Vec::new();
    for task in tasks {
        records.push(task.await.unwrap());
    }
    let mut caused = HashMap::new();
    for r in &records {
        for (key, t) in &r.caused {
            caused.insert(*key, (r.replica, *t));
        }
    }
    let (mut same, mut across) = (Vec::new(), Vec::new());
    for r in &records {
        for (stroke, index, at) in &r.received {
            // The final retained sample is decided by the stroke's end, not by a batch.
            let Some((replica, sent)) = caused.get(&(*stroke, *index)) else { continue };
            let ms = at.duration_since(*sent).as_secs_f64() * 1000.0;
            if *replica == r.replica { same.push(ms) } else { across.push(ms) }
        }
    }
    (same, across)
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() as f64 * p).ceil() as usize).clamp(1, sorted.len()) - 1]
}

fn report(label: &str, n: usize, mut ms: Vec<f64>) {
    ms.sort_by(f64::total_cmp);
    println!(
        "| {label} | {n} | {} | {:.2} | {:.2} | {:.2} |",
        ms.len(),
        percentile(&ms, 0.5),
        percentile(&ms, 0.99),
        ms.last().copied().unwrap_or(f64::NAN)
    );
}

#[tokio::test(flavor = "multi_thread")]
#[ignore = "a measurement: run in release with --ignored --nocapture"]
async fn fanout_latency() {
    println!("| setup | participants | deliveries | p50 ms | p99 ms | max ms |");
    println!("|---|---:|---:|---:|---:|---:|");
    for n in [2, 10, 50] {
        let db = TestDatabase::fresh().await;
        let label =
            if db.is_postgres() { "one replica, PostgreSQL" } else { "one replica, SQLite" };
        let proxy = spawn_proxy_on(db, |c| c.max_connections_per_session = 128).await;
        let (same, _) = measure(std::slice::from_ref(&proxy), n).await;
        report(label, n, same);
        proxy.stop().await;
    }
    let db = TestDatabase::fresh().await;
    if !db.is_postgres() {
        println!("(two replicas need PENMESH_TEST_POSTGRES_URL)");
        return;
    }
    for n in [2, 10, 50] {
        let db = TestDatabase::fresh().await;
        let tweak = |c: &mut penmesh_proxy::Config| c.max_connections_per_session = 128;
        let proxies = vec![spawn_replica(db.clone(), tweak).await, spawn_replica(db, tweak).await];
        let (same, across) = measure(&proxies, n).await;
        report("two replicas, same replica", n, same);
        report("two replicas, across", n, across);
        for proxy in proxies {
            proxy.stop().await;
        }
    }
}
