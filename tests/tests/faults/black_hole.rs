//! PostgreSQL cut off mid-load for longer than any of the proxy's timeouts, then back: the
//! connections that lived through it stay silent forever (see `forwarder.rs`). Without
//! deadlines the writer's commit, the stroke locks and the listener would wait on them for
//! good; with them, each gives up, reconnects once the network is back, and the listener's
//! heartbeat notices the lost `LISTEN` and resyncs the session.

use std::time::{Duration, Instant};

use penmesh_e2e::TestDatabase;

use crate::check::{Load, Watcher, assert_promises, verify};
use crate::child::ProxyChild;
use crate::forwarder::Forwarder;
use crate::{PENS, RECOVERY, plan, postgres_server};

/// How long PostgreSQL is out of reach: longer than every deadline below, the pens' 2 s
/// stall and the 2 s claim wait.
const OUTAGE: Duration = Duration::from_secs(5);
/// The proxy's deadlines, shorter than their defaults (10 s and 5 s) to keep the test short.
const DEADLINES: [&str; 4] = ["--db-timeout-ms", "1000", "--listener-heartbeat-ms", "500"];

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(not(penmesh_postgres), ignore = "needs PostgreSQL: set PENMESH_TEST_POSTGRES_URL")]
async fn postgres_black_holed_longer_than_any_timeout_recovers_after() {
    let db = TestDatabase::fresh().await;
    assert!(db.is_postgres(), "this scenario needs PostgreSQL");
    let network = Forwarder::start(postgres_server(&db.url)).await;
    let proxy = ProxyChild::start(&network.rewrite_url(&db.url), &DEADLINES).await;
    let session = proxy.create_session().await;
    let watcher = Watcher::join(proxy.port, &session);
    let load = Load::start(&proxy, &session, PENS, plan()).await;

    // Act
    network.black_hole();
    tokio::time::sleep(OUTAGE).await;
    network.heal();
    let healed = Instant::now();
    let (session, logs) = load.finish().await;

    // Assert
    let figures = verify(&proxy, &session, &logs, healed).await;
    println!("{}", figures.line(&format!("black hole {OUTAGE:?} (postgres)")));
    assert_promises(&figures, RECOVERY);
    let seen = watcher.wait_all(&logs, Instant::now(), RECOVERY).await;
    assert!(seen.is_ok(), "the watcher never saw these strokes finish: {seen:?}");
    assert!(proxy.counter("penmesh_listener_heartbeat_failures_total").await >= 1.0);
    assert!(proxy.counter("penmesh_listener_resyncs_total").await >= 1.0);
}
