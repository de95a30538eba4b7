//! PostgreSQL's connections reset mid-load, a second apart: the listener's, then the stroke
//! locks', then the others (the writer's and the pool's), then all at once. The writer fails
//! the commit in flight and reconnects, the pens resume from their last ack, the lock
//! connection reconnects and takes its locks again, the listener listens again and resyncs.

use std::time::{Duration, Instant};

use penmesh_e2e::TestDatabase;
use penmesh_proxy::{LISTENER_APPLICATION, LOCKS_APPLICATION, REAP_INTERVAL};

use crate::check::{Load, Watcher, assert_promises, verify};
use crate::child::ProxyChild;
use crate::forwarder::Forwarder;
use crate::{PENS, RECOVERY, pen, plan, postgres_server};

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

    // Act
    let second = Duration::from_secs(1);
    network.reset_where(|app| app == LISTENER_APPLICATION);
    tokio::time::sleep(second).await;
    let resynced = Instant::now() + RECOVERY;
    while proxy.counter("penmesh_listener_resyncs_total").await < 1.0 {
        assert!(Instant::now() < resynced, "the listener did not listen again");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    // Only the listener was hit (the forwarder tells the connections apart).
    assert_eq!(proxy.counter("penmesh_listener_resyncs_total").await, 1.0);
    assert!(!proxy.log_text().contains("write connection"), "{}", proxy.log_text());
    network.reset_where(|app| app == LOCKS_APPLICATION);
    tokio::time::sleep(second).await;
    network.reset_where(|app| app != LISTENER_APPLICATION && app != LOCKS_APPLICATION);
    tokio::time::sleep(second).await;
    network.reset_all();
    let healed = Instant::now();
    let (session, logs) = load.finish().await;

    // Assert
    let figures = verify(&proxy, &session, &logs, healed).await;
    println!("{}", figures.line("resets (postgres)"));
    if figures.lost > 0 {
        eprintln!("the proxy's log:\n{}", proxy.log_text());
    }
    assert_promises(&figures, RECOVERY);
    // The listener is back: the watcher has seen every stroke finish (live or by a resync).
    let seen = watcher.wait_all(&logs, Instant::now(), RECOVERY).await;
    assert!(seen.is_ok(), "the watcher never saw these strokes finish: {seen:?}");
    // The resets did hit: the listener listened again (twice), the writer and the lock
    // connection reconnected.
    assert!(proxy.counter("penmesh_listener_resyncs_total").await >= 2.0);
    let log = proxy.log_text();
    assert!(log.contains("write connection"), "{log}");
    assert!(log.contains("stroke-lock connection broke"), "{log}");
}

/// The lock connection reset while nobody claims a stroke (one person in the middle of a long
/// stroke, the only one): the replica opens it again by itself and takes its locks back, so
/// no reaper takes it for dead. Without that, two reaping rounds later its participant would
/// be closed, its stroke marked interrupted while drawn and its append log moved under it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(not(penmesh_postgres), ignore = "needs PostgreSQL: set PENMESH_TEST_POSTGRES_URL")]
async fn postgres_lock_connection_reset_between_claims_is_opened_again_at_once() {
    let db = TestDatabase::fresh().await;
    assert!(db.is_postgres(), "this scenario needs PostgreSQL");
    let network = Forwarder::start(postgres_server(&db.url)).await;
    let proxy = ProxyChild::start(&network.rewrite_url(&db.url), &[]).await;
    let session = proxy.create_session().await;
    // One stroke of 2,000 samples at 160 Hz: 12.5 s, begun before the reset and ended after.
    let plan = pen::Plan { strokes: 1, samples: 2000, ..plan() };
    let load = Load::start(&proxy, &session, 1, plan).await;
    sqlx::any::install_default_drivers();
    let pool = sqlx::AnyPool::connect(&db.url).await.unwrap();

    // Act
    network.reset_where(|app| app == LOCKS_APPLICATION);
    // Past two reaping rounds: a replica whose lock is free in both is taken for dead.
    tokio::time::sleep(REAP_INTERVAL * 2 + Duration::from_millis(1500)).await;
    let left: i64 =
        sqlx::query_scalar("SELECT COUNT(*) FROM participants WHERE left_at IS NOT NULL")
            .fetch_one(&pool)
            .await
            .unwrap();
    let statuses: Vec<String> =
        sqlx::query_scalar("SELECT status FROM strokes").fetch_all(&pool).await.unwrap();
    let healed = Instant::now();
    let (session, logs) = load.finish().await;

    // Assert
    let log = proxy.log_text();
    assert!(log.contains("stroke-lock connection broke; relocking"), "{log}");
    assert_eq!(left, 0, "a participant of the live replica was closed: {log}");
    assert_eq!(statuses, ["open"], "the stroke being drawn was marked: {log}");
    let figures = verify(&proxy, &session, &logs, healed).await;
    assert_promises(&figures, RECOVERY);
}
