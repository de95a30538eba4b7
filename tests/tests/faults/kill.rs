//! The proxy killed with SIGKILL mid-load and restarted on the same database: what was
//! acknowledged was committed, so every pen resumes from its last ack.

use std::time::{Duration, Instant};

use penmesh_e2e::TestDatabase;

use crate::check::{Load, assert_promises, verify};
use crate::child::ProxyChild;
use crate::{PENS, RECOVERY, plan};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_proxy_killed_mid_load_and_restarted_loses_nothing_acknowledged() {
    let db = TestDatabase::fresh().await;
    let mut proxy = ProxyChild::start(&db.url, &[]).await;
    let session = proxy.create_session().await;
    let load = Load::start(&proxy, &session, PENS, plan()).await;

    // Act: SIGKILL mid-stroke, down for a second, started again on the same port and database.
    proxy.kill();
    let killed = Instant::now();
    tokio::time::sleep(Duration::from_secs(1)).await;
    proxy.restart().await;
    let back = Instant::now();
    let (session, logs) = load.finish().await;

    // Assert
    let figures = verify(&proxy, &session, &logs, back).await;
    let backend = if db.is_postgres() { "postgres" } else { "sqlite" };
    println!("{}", figures.line(&format!("kill-9 ({backend})")));
    println!("down {:?} (kill to ready)", back - killed);
    assert!(figures.reconnects >= PENS as u32, "every pen lost its connection: {figures:?}");
    assert_promises(&figures, RECOVERY);
}
