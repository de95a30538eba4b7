//! Records of the append log that cannot be moved into `stroke_chunks` (a stroke with no row,
//! a record that does not decode): each is set aside on its own, and neither the start of the
//! next proxy (SQLite) nor the clearing of a dead replica's log (PostgreSQL) stops at it.

use std::time::{Duration, Instant};

use penmesh::protocol::ServerMessage;
use penmesh_e2e::{TestDatabase, TestSession, WsClient, count_rows, stroke_samples};
use uuid::Uuid;

use crate::check::raw_samples;
use crate::child::ProxyChild;

/// A proxy killed with `strokes` drawn (30 samples each, acknowledged) and left in its log;
/// returns it, its session, and its writer's id.
async fn killed_with(db: &TestDatabase, strokes: &[Uuid]) -> (ProxyChild, TestSession, i64) {
    let mut proxy = ProxyChild::start(&db.url, &[]).await;
    let session = proxy.create_session().await;
    let samples = stroke_samples(30);
    let mut ws = WsClient::try_connect(proxy.port, &session).await.unwrap();
    ws.hello(vec![]).await;
    for &stroke in strokes {
        ws.begin(stroke).await;
        ws.wait_ack(stroke, 0).await;
        for (i, batch) in samples.chunks(6).enumerate() {
            ws.points(stroke, (i * 6) as u64, batch).await;
        }
        ws.wait_ack(stroke, samples.len() as u64).await;
    }
    let writer = count_rows(db, "SELECT MAX(writer) FROM stroke_log").await;
    proxy.kill();
    (proxy, session, writer)
}

/// Runs `sql` (with `$1` bound to `value`) on the database.
async fn execute(db: &TestDatabase, sql: &str, value: impl ToString) {
    sqlx::any::install_default_drivers();
    let pool = sqlx::AnyPool::connect(&db.url).await.unwrap();
    sqlx::query(sql).bind(value.to_string()).execute(&pool).await.unwrap();
    pool.close().await;
}

/// Waits until the killed writer's records are gone (SQLite: at start; PostgreSQL: within a
/// few reaper rounds).
async fn until_cleared(proxy: &ProxyChild, db: &TestDatabase, writer: i64) {
    let dead = format!("SELECT COUNT(*) FROM stroke_log WHERE writer = {writer}");
    let deadline = Instant::now() + Duration::from_secs(20);
    while count_rows(db, &dead).await > 0 {
        assert!(Instant::now() < deadline, "the log is not cleared:\n{}", proxy.log_text());
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

fn set_aside_for(stroke: &str) -> String {
    format!("SELECT COUNT(*) FROM stroke_log_set_aside WHERE stroke_id = '{stroke}'")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stroke_of_the_log_without_its_row_is_set_aside_and_the_others_are_moved() {
    // Arrange: two strokes left in a killed proxy's log; one then loses its row (what a begin
    // that failed left behind, before the writer checked that a stroke exists).
    let db = TestDatabase::fresh().await;
    let (orphan, kept) = (Uuid::new_v4(), Uuid::new_v4());
    let (mut proxy, session, writer) = killed_with(&db, &[orphan, kept]).await;
    execute(&db, "DELETE FROM strokes WHERE id = $1", orphan).await;

    // Act: the next proxy on the same database, and a pen drawing there while the log is
    // cleared.
    proxy.restart().await;
    let mut pen = WsClient::try_connect(proxy.port, &session).await.unwrap();
    pen.hello(vec![]).await;
    let (drawn, long) = (Uuid::new_v4(), stroke_samples(1000));
    pen.begin(drawn).await;
    pen.wait_ack(drawn, 0).await;
    let dead = format!("SELECT COUNT(*) FROM stroke_log WHERE writer = {writer}");
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut sent = 0;
    while count_rows(&db, &dead).await > 0 {
        let in_time = Instant::now() < deadline && sent + 4 <= long.len();
        assert!(in_time, "the log is not cleared:\n{}", proxy.log_text());
        pen.points(drawn, sent as u64, &long[sent..sent + 4]).await;
        sent += 4;
        pen.wait_ack(drawn, sent as u64).await;
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    pen.end(drawn, sent as u64).await;
    let (done, others) =
        pen.recv_until(|m| matches!(m, ServerMessage::StrokeDone(d) if d.stroke == drawn)).await;

    // Assert: the pen saw no error, the other stroke is whole, the orphan's entries are kept
    // aside and counted.
    assert!(matches!(done, ServerMessage::StrokeDone(_)));
    assert!(!others.iter().any(|m| matches!(m, ServerMessage::Error(_))), "{others:?}");
    assert_eq!(raw_samples(&proxy, &session, kept).await, stroke_samples(30));
    assert!(count_rows(&db, &set_aside_for(&orphan.to_string())).await >= 1);
    assert!(proxy.counter("penmesh_log_set_aside_total").await >= 1.0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_log_record_that_does_not_decode_is_set_aside_and_the_others_are_moved() {
    // Arrange: a stroke left in a killed proxy's log, and a record of the same writer that
    // does not decode.
    let db = TestDatabase::fresh().await;
    let kept = Uuid::new_v4();
    let (mut proxy, session, writer) = killed_with(&db, &[kept]).await;
    let garbage = "INSERT INTO stroke_log (writer, data) VALUES ($1, X'DEAD')";
    let garbage = if db.is_postgres() {
        "INSERT INTO stroke_log (writer, data) VALUES ($1::bigint, '\\xdead'::bytea)"
    } else {
        garbage
    };
    execute(&db, garbage, writer).await;

    // Act
    proxy.restart().await;
    until_cleared(&proxy, &db, writer).await;

    // Assert: the stroke is whole, the record is kept aside and counted.
    assert_eq!(raw_samples(&proxy, &session, kept).await, stroke_samples(30));
    assert_eq!(count_rows(&db, &set_aside_for("")).await, 1, "the record that does not decode");
    assert!(proxy.counter("penmesh_log_set_aside_total").await >= 1.0);
}
