//! A database written before samples were stored compactly (migration `20261123000000`) still
//! opens and reads: its strokes' `/raw` and `/simplified` samples come back exactly as they
//! were stored, an interrupted stroke of it resumes, and strokes stored after read the same.

use std::borrow::Cow;
use std::path::Path;

use penmesh::protocol::ServerMessage;
use penmesh::{AcutsParams, Brush, Sample};
use penmesh_e2e::penmesh_proxy::{hash_token, participant_id};
use penmesh_e2e::{
    TestDatabase, TestSession, batch_simplified, count_rows, spawn_proxy_on, stroke_samples,
};
use sqlx::Row;
use uuid::Uuid;

/// The connection of the old database's participant row.
const OLD_CONNECTION: Uuid = Uuid::from_u128(0x0123_4567_89ab_4def_8123_4567_89ab_cdef);

/// The last migration of the version that stored `f64` samples.
const LAST_OLD_MIGRATION: i64 = 20261122000000;

/// The sample blob as the previous version wrote it: little-endian `f64` quadruples.
fn old_blob(samples: &[Sample]) -> Vec<u8> {
    samples.iter().flat_map(|s| [s.x, s.y, s.t, s.p]).flat_map(f64::to_le_bytes).collect()
}

/// `samples` as they read back from JSON: the API sends the shortest text of each `f64`, and
/// serde_json parses it within an ulp, so an exact comparison goes through the same text.
fn via_json(samples: &[Sample]) -> Vec<Sample> {
    serde_json::from_str(&serde_json::to_string(samples).unwrap()).unwrap()
}

/// Samples as a JSON client sent them to the previous version: off the codec's grid.
fn off_grid(n: usize) -> Vec<Sample> {
    (0..n)
        .map(|i| {
            let f = i as f64;
            Sample::new(0.1 + 2.03 * f, 7.77 - 0.31 * f, 0.013 + 5.001 * f, 0.333)
        })
        .collect()
}

/// Creates the previous version's schema on `db` and stores in it, the way it did, an
/// interrupted stroke and a finished one.
async fn write_old_database(
    db: &TestDatabase,
    session: &TestSession,
    interrupted: (Uuid, &[Sample]),
    done: (Uuid, &[Sample], &[u64]),
) {
    sqlx::any::install_default_drivers();
    let folder = if db.is_postgres() { "postgres" } else { "sqlite" };
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../migrations").join(folder);
    let mut migrator = sqlx::migrate::Migrator::new(dir).await.unwrap();
    let old: Vec<_> =
        migrator.migrations.iter().filter(|m| m.version <= LAST_OLD_MIGRATION).cloned().collect();
    assert!(old.len() < migrator.migrations.len(), "the compact layout is a newer migration");
    migrator.migrations = Cow::Owned(old);
    let url = if db.is_postgres() { db.url.clone() } else { format!("{}?mode=rwc", db.url) };
    let pool = sqlx::AnyPool::connect(&url).await.unwrap();
    migrator.run(&pool).await.unwrap();

    let q = |sql: &'static str| sqlx::query(sql);
    q("INSERT INTO sessions (id, token_hash, created_at) VALUES ($1, $2, 1)")
        .bind(session.session.to_string())
        .bind(hash_token(&session.token))
        .execute(&pool)
        .await
        .unwrap();
    let brush = serde_json::to_string(&Brush::default()).unwrap();
    let params = serde_json::to_string(&AcutsParams::default()).unwrap();
    for (stroke, status, n_retained) in
        [(interrupted.0, "interrupted", 0), (done.0, "done", done.2.len() as i64)]
    {
        q("INSERT INTO strokes (id, session_id, participant, brush, params, device, status, \
           n_retained, created_at, updated_at) VALUES ($1, $2, $3, $4, $5, NULL, $6, $7, 1, 1)")
        .bind(stroke.to_string())
        .bind(session.session.to_string())
        // The participant the test's connections are (an old client had no key, so nobody
        // could resume its strokes now: the test draws as their owner to read them).
        .bind(participant_id(session.session, &session.key).to_string())
        .bind(brush.clone())
        .bind(params.clone())
        .bind(status)
        .bind(n_retained)
        .execute(&pool)
        .await
        .unwrap();
    }
    for (stroke, samples) in [(interrupted.0, interrupted.1), (done.0, done.1)] {
        for (i, chunk) in samples.chunks(7).enumerate() {
            q("INSERT INTO stroke_chunks (stroke_id, seq, n, data) VALUES ($1, $2, $3, $4)")
                .bind(stroke.to_string())
                .bind((i * 7) as i64)
                .bind(chunk.len() as i64)
                .bind(old_blob(chunk))
                .execute(&pool)
                .await
                .unwrap();
        }
    }
    // A participant row of the old schema: one per connection, keyed by `id`.
    q("INSERT INTO participants (id, session_id, name, joined_at, left_at) \
       VALUES ($1, $2, 'old', 1, 2)")
    .bind(OLD_CONNECTION.to_string())
    .bind(session.session.to_string())
    .execute(&pool)
    .await
    .unwrap();
    let kept: Vec<Sample> = done.2.iter().map(|&i| done.1[i as usize]).collect();
    q("INSERT INTO simplified (stroke_id, indices, data) VALUES ($1, $2, $3)")
        .bind(done.0.to_string())
        .bind(done.2.iter().flat_map(|i| i.to_le_bytes()).collect::<Vec<u8>>())
        .bind(old_blob(&kept))
        .execute(&pool)
        .await
        .unwrap();
    pool.close().await;
}

#[tokio::test]
async fn a_database_of_the_previous_version_opens_and_reads_the_same_samples() {
    // Arrange: the previous version's database with an interrupted and a finished stroke.
    let db = TestDatabase::fresh().await;
    let session = TestSession::new(Uuid::new_v4(), "an old session's token".into());
    let (interrupted, done) = (Uuid::new_v4(), Uuid::new_v4());
    let old_interrupted = off_grid(30);
    let old_done = off_grid(20);
    let done_indices = [0u64, 7, 19];
    write_old_database(
        &db,
        &session,
        (interrupted, &old_interrupted),
        (done, &old_done, &done_indices),
    )
    .await;

    // Act: the new version opens it (migrating it).
    let proxy = spawn_proxy_on(db, |_| {}).await;

    // Assert: what was stored reads back bit for bit.
    assert_eq!(proxy.raw_samples(&session, interrupted).await, via_json(&old_interrupted));
    assert_eq!(proxy.raw_samples(&session, done).await, via_json(&old_done));
    let simplified = proxy.get_json(&format!("/v1/strokes/{done}/simplified"), &session).await;
    let samples: Vec<Sample> = serde_json::from_value(simplified["samples"].clone()).unwrap();
    let expected: Vec<Sample> = done_indices.iter().map(|&i| old_done[i as usize]).collect();
    assert_eq!(samples, via_json(&expected));

    // The old participant row is one connection's, and names it as its participant.
    let old_row = format!(
        "SELECT COUNT(*) FROM participants WHERE connection = '{OLD_CONNECTION}' \
         AND participant = connection"
    );
    assert_eq!(count_rows(&proxy.db, &old_row).await, 1);

    // The interrupted stroke resumes: its old samples, then new ones in the compact layout.
    let more = stroke_samples(60)[30..].to_vec();
    let mut ws = proxy.connect(&session).await;
    let welcome = ws.hello(vec![interrupted]).await;
    assert_eq!(welcome.resume[0].next_seq, 30);
    ws.begin(interrupted).await;
    ws.wait_ack(interrupted, 30).await;
    ws.points(interrupted, 30, &more).await;
    ws.end(interrupted, 60).await;
    let (end, _) = ws.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;
    assert!(matches!(end, ServerMessage::StrokeDone(_)));
    let whole: Vec<Sample> = old_interrupted.iter().chain(&more).copied().collect();
    assert_eq!(proxy.raw_samples(&session, interrupted).await, via_json(&whole));

    // A stroke stored by the new version reads back as sent.
    let (fresh, samples) = (Uuid::new_v4(), stroke_samples(80));
    ws.begin(fresh).await;
    ws.wait_ack(fresh, 0).await;
    for (i, chunk) in samples.chunks(3).enumerate() {
        ws.points(fresh, (i * 3) as u64, chunk).await;
    }
    ws.end(fresh, 80).await;
    ws.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;
    assert_eq!(proxy.raw_samples(&session, fresh).await, samples);
    let simplified = proxy.get_json(&format!("/v1/strokes/{fresh}/simplified"), &session).await;
    let kept: Vec<Sample> = serde_json::from_value(simplified["samples"].clone()).unwrap();
    assert_eq!(kept, batch_simplified(&samples));

    // And the rows say which layout each holds.
    let pool = sqlx::AnyPool::connect(&proxy.db.url).await.unwrap();
    let layouts = sqlx::query(
        "SELECT stroke_id, CAST(layout AS BIGINT) AS layout FROM stroke_chunks ORDER BY stroke_id, seq",
    )
    .fetch_all(&pool)
    .await
    .unwrap();
    for row in layouts {
        let (stroke, layout): (String, i64) = (row.get("stroke_id"), row.get("layout"));
        let old = stroke == done.to_string() || (stroke == interrupted.to_string() && layout == 0);
        assert_eq!(layout, if old { 0 } else { 1 }, "stroke {stroke}");
    }
    pool.close().await;
}
