//! The proxy killed with SIGKILL mid-load and restarted on the same database: what was
//! acknowledged was committed, so every pen resumes from its last ack.

use std::time::{Duration, Instant};

use penmesh::protocol::ServerMessage;
use penmesh_e2e::{TestDatabase, WsClient, count_rows, stroke_samples};

use crate::check::{Load, assert_promises, raw_samples, verify};
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

/// A proxy killed mid-stroke leaves the appends it acknowledged in the append log (they move
/// to `stroke_chunks` when a stroke ends). The proxy that takes over moves them and empties the
/// log: SQLite at start, PostgreSQL (where the dead replica's records could be anyone's) once
/// it sees the dead writer's lock gone. Otherwise every reader would scan them for ever.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_append_log_of_a_killed_proxy_is_emptied_and_its_samples_stay_readable() {
    let db = TestDatabase::fresh().await;
    let mut proxy = ProxyChild::start(&db.url, &[]).await;
    let session = proxy.create_session().await;
    let stroke = uuid::Uuid::new_v4();
    let samples = stroke_samples(60);
    let mut ws = WsClient::try_connect(proxy.port, &session).await.unwrap();
    ws.hello(vec![]).await;
    ws.begin(stroke).await;
    for (i, batch) in samples.chunks(6).enumerate() {
        ws.points(stroke, (i * 6) as u64, batch).await;
    }
    ws.wait_ack(stroke, samples.len() as u64).await;
    let in_log = count_rows(&db, "SELECT COUNT(*) FROM stroke_log").await;
    assert!(in_log > 0, "the acknowledged appends are in the log");

    // Act: SIGKILL with the stroke open, and another proxy on the same database.
    proxy.kill();
    drop(ws);
    proxy.restart().await;

    // Assert: the log empties (PostgreSQL: within a few reaper rounds), and the stroke reads
    // back whole, from its chunks.
    wait_for(&proxy, "the killed proxy's log emptied", || async {
        count_rows(&db, "SELECT COUNT(*) FROM stroke_log").await == 0
    })
    .await;
    let chunks = format!("SELECT COUNT(*) FROM stroke_chunks WHERE stroke_id = '{stroke}'");
    assert!(count_rows(&db, &chunks).await >= 1, "the samples are in stroke_chunks");
    assert_eq!(raw_samples(&proxy, &session, stroke).await, samples);
    // And nobody draws it any more: `interrupted`, not `open` for ever (PostgreSQL: the
    // reaper, once the killed replica's participants have left).
    wait_for(&proxy, "the killed proxy's stroke interrupted", || async {
        has_status(&db, stroke, "interrupted").await
    })
    .await;
}

/// The same, with one of the killed proxy's strokes resumed on the next proxy at once: while
/// it is being drawn again the log's clearing leaves it to its new writer (and clears the
/// other stroke); once it ends, the killed proxy's records are gone and both strokes read back
/// whole, every sample once.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stroke_resumed_after_the_kill_is_left_to_its_new_writer_while_the_log_is_cleared() {
    let db = TestDatabase::fresh().await;
    let mut proxy = ProxyChild::start(&db.url, &[]).await;
    let session = proxy.create_session().await;
    let (held, other) = (uuid::Uuid::new_v4(), uuid::Uuid::new_v4());
    let samples = stroke_samples(600);
    let mut ws = WsClient::try_connect(proxy.port, &session).await.unwrap();
    ws.hello(vec![]).await;
    for stroke in [held, other] {
        ws.begin(stroke).await;
        ws.wait_ack(stroke, 0).await;
        for (i, batch) in samples[..30].chunks(6).enumerate() {
            ws.points(stroke, (i * 6) as u64, batch).await;
        }
        ws.wait_ack(stroke, 30).await;
    }
    // Every record so far is the killed proxy's: its writer id.
    let killed_writer = count_rows(&db, "SELECT MAX(writer) FROM stroke_log").await;
    assert_eq!(count_rows(&db, "SELECT COUNT(DISTINCT writer) FROM stroke_log").await, 1);

    // Act: SIGKILL, another proxy, and `held` resumed there at once.
    proxy.kill();
    drop(ws);
    proxy.restart().await;
    let mut ws = WsClient::try_connect(proxy.port, &session).await.unwrap();
    let welcome = ws.hello(vec![held]).await;
    assert_eq!(welcome.resume[0].next_seq, 30, "{welcome:?}");

    // Assert: the stroke nobody draws is moved out of the log while `held` is drawn again (a
    // batch every 100 ms, so its new writer always has appends that only the log holds).
    let other_chunks = format!("SELECT COUNT(*) FROM stroke_chunks WHERE stroke_id = '{other}'");
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut sent = 30;
    while count_rows(&db, &other_chunks).await == 0 {
        assert!(Instant::now() < deadline, "the other stroke is not moved:\n{}", proxy.log_text());
        assert!(sent < samples.len(), "the stroke is drawn out before the other one moved");
        ws.points(held, sent as u64, &samples[sent..sent + 6]).await;
        sent += 6;
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    // The stroke nobody draws is `interrupted`; the one drawn again is `open`.
    wait_for(&proxy, "the stroke nobody draws interrupted", || async {
        has_status(&db, other, "interrupted").await
    })
    .await;
    assert!(has_status(&db, held, "open").await, "the stroke drawn again is open");
    for (i, batch) in samples[sent..].chunks(6).enumerate() {
        ws.points(held, (sent + i * 6) as u64, batch).await;
    }
    ws.wait_ack(held, samples.len() as u64).await;
    ws.end(held, samples.len() as u64).await;
    ws.recv_until(|m| matches!(m, ServerMessage::StrokeDone(d) if d.stroke == held)).await;
    let dead = format!("SELECT COUNT(*) FROM stroke_log WHERE writer = {killed_writer}");
    wait_for(&proxy, "the killed proxy's records deleted", || async {
        count_rows(&db, &dead).await == 0
    })
    .await;
    assert_eq!(raw_samples(&proxy, &session, held).await, samples);
    assert_eq!(raw_samples(&proxy, &session, other).await, samples[..30]);
}

async fn has_status(db: &TestDatabase, stroke: uuid::Uuid, status: &str) -> bool {
    let sql = format!("SELECT COUNT(*) FROM strokes WHERE id = '{stroke}' AND status = '{status}'");
    count_rows(db, &sql).await == 1
}

/// Polls `done` for up to 20 s (a few of the PostgreSQL reaper's rounds).
async fn wait_for<F: Future<Output = bool>>(
    proxy: &ProxyChild,
    what: &str,
    mut done: impl FnMut() -> F,
) {
    let deadline = Instant::now() + Duration::from_secs(20);
    while !done().await {
        assert!(Instant::now() < deadline, "not within 20 s: {what}\n{}", proxy.log_text());
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}
