//! What a newcomer's history costs (issue 25): a long unfinished stroke is replayed for the
//! first history that needs it, and what it retains is kept for the next ones.

use std::time::Duration;

use penmesh::Sample;
use penmesh::protocol::StrokeId;
use penmesh_e2e::{TestDatabase, TestProxy, TestSession, count_rows, new_key, spawn_proxy};
use uuid::Uuid;

use crate::helpers::{Participant, samples_for};

/// What ACUTS retains of `samples` before the pen is lifted.
fn retained_before_the_end(samples: &[Sample]) -> Vec<Sample> {
    let mut simplifier = penmesh::Simplifier::new(penmesh::AcutsParams::default());
    samples.iter().filter_map(|s| simplifier.push(*s)).map(|k| k.sample).collect()
}

async fn wait_until_interrupted(proxy: &TestProxy, session: &TestSession, stroke: StrokeId) {
    for _ in 0..150 {
        if proxy.stroke_info(session, stroke).await["status"] == "interrupted" {
            return;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    panic!("stroke {stroke} was not interrupted");
}

/// Waits until the database keeps what `stroke` retains of its first `upto` samples.
async fn wait_until_kept(db: &TestDatabase, stroke: StrokeId, upto: u64) {
    let sql =
        format!("SELECT COUNT(*) FROM simplified WHERE stroke_id = '{stroke}' AND upto = {upto}");
    for _ in 0..150 {
        if count_rows(db, &sql).await == 1 {
            return;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    panic!("what stroke {stroke} retains of {upto} samples was not kept");
}

/// Makes every stored chunk of `stroke` unreadable, straight in the database.
async fn break_samples(db: &TestDatabase, stroke: StrokeId) {
    sqlx::any::install_default_drivers();
    let pool = sqlx::AnyPool::connect(&db.url).await.unwrap();
    sqlx::query("UPDATE stroke_chunks SET data = $1 WHERE stroke_id = $2")
        .bind(vec![0xffu8; 3])
        .bind(stroke.to_string())
        .execute(&pool)
        .await
        .unwrap();
    pool.close().await;
}

#[tokio::test]
async fn a_long_unfinished_stroke_is_replayed_for_one_history_not_for_every_one() {
    // Arrange: a long stroke drawn to 2,500 samples, then its connection ends.
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let (stroke, samples, key) = (Uuid::new_v4(), samples_for(1, 3000), new_key());
    let mut drawer = Participant::join_resuming(&proxy, &session, "drawer", &key, vec![]).await;
    drawer.begin(stroke).await;
    drawer.send_points(stroke, &samples, 0, 2500, 100).await;
    drawer.wait_ack(stroke, 2500).await;
    drop(drawer);
    wait_until_interrupted(&proxy, &session, stroke).await;

    // Act, assert: the first newcomer's history replays it, and what it retains is kept; it
    // is not the stroke's simplified form, which only its end makes.
    let first = Participant::join(&proxy, &session, "first").await;
    assert_eq!(first.view.strokes[&stroke].retained, retained_before_the_end(&samples[..2500]));
    wait_until_kept(&proxy.db, stroke, 2500).await;
    let simplified = proxy.get(&format!("/v1/strokes/{stroke}/simplified"), &session);
    assert_eq!(simplified.send().await.unwrap().status(), 409);

    // Drawn further: what was kept covers too few samples, so the next history replays it.
    let mut drawer =
        Participant::join_resuming(&proxy, &session, "drawer", &key, vec![stroke]).await;
    drawer.send_points(stroke, &samples, 2500, 3000, 100).await;
    drawer.wait_ack(stroke, 3000).await;
    drop(drawer);
    wait_until_interrupted(&proxy, &session, stroke).await;
    let second = Participant::join(&proxy, &session, "second").await;
    assert_eq!(second.view.strokes[&stroke].retained, retained_before_the_end(&samples));
    wait_until_kept(&proxy.db, stroke, 3000).await;

    // With its samples unreadable, a history that replayed them would report the stroke
    // unreadable: the next newcomer still gets what it retains, read from what was kept.
    break_samples(&proxy.db, stroke).await;
    let third = Participant::join(&proxy, &session, "third").await;
    let seen = third.view.strokes.get(&stroke).expect("the stroke is in the history");
    assert_eq!(seen.retained, retained_before_the_end(&samples));
}
