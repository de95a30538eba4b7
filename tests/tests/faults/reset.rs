//! PostgreSQL's connections reset mid-load: the writer's, the listener's, the stroke locks'
//! and the pool's, all at once, twice. The writer fails the commit in flight and reconnects,
//! the pens resume from their last ack, the listener listens again and resyncs the session.

use std::time::{Duration, Instant};

use penmesh_e2e::TestDatabase;

use crate::check::{Load, Watcher, assert_promises, verify};
use crate::child::ProxyChild;
use crate::forwarder::Forwarder;
use crate::{PENS, RECOVERY, plan, postgres_server};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(not(penmesh_postgres), ignore = "needs PostgreSQL: set PENMESH_TEST_POSTGRES_URL")]
async fn postgres_connections_reset_mid_load_lose_nothing_acknowledged() {
    let db = TestDatabase::fresh().await;
    assert!(db.is_postgres(), "this scenario needs PostgreSQL");
    let network = Forwarder::start(postgres_server(&db.url)).await;
    let proxy = ProxyChild::start(&network.rewrite_url(&db.url), &[]).await;
    let session = proxy.create_session().await;
    let watcher = Watcher::join(proxy.port, &session);
    let load = Load::start(&proxy, &session, PENS, plan()).await;

    // Act: every connection to PostgreSQL reset, twice, a second apart.
    network.reset_all();
    tokio::time::sleep(Duration::from_secs(1)).await;
    network.reset_all();
    let healed = Instant::now();
    let (session, logs) = load.finish().await;

    // Assert
    let figures = verify(&proxy, &session, &logs, healed).await;
    println!("{}", figures.line("reset x2 (postgres)"));
    assert_promises(&figures, RECOVERY);
    // The listener is back: the watcher has seen every stroke finish (live or by a resync).
    let seen = watcher.wait_all(&logs, Instant::now(), RECOVERY).await;
    assert!(seen.is_ok(), "the watcher never saw these strokes finish: {seen:?}");
    // The resets did hit: the listener listened again and the writer reconnected.
    assert!(proxy.counter("penmesh_listener_resyncs_total").await >= 1.0);
    assert!(proxy.log_text().contains("write connection"), "{}", proxy.log_text());
}
