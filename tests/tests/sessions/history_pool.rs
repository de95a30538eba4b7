//! A session's history is read through one pooled connection (issue 25's join storm: a
//! reader that waited for a second connection while holding one ran the pool dry).

use std::time::Duration;

use penmesh_e2e::spawn_proxy_with;
use uuid::Uuid;

use crate::helpers::{Participant, put_mesh, samples_for};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn history_reads_hold_one_pooled_connection() {
    // Arrange: a session with finished strokes, on a proxy whose read pool has a single
    // connection: a history read that waits for a second connection while it holds one can
    // never finish.
    let proxy = spawn_proxy_with(|c| {
        c.db_max_connections = 1;
        c.db_timeout_ms = 2000;
    })
    .await;
    let session = proxy.create_session().await;
    let mut drawer = Participant::join(&proxy, &session, "drawer").await;
    let strokes = [Uuid::new_v4(), Uuid::new_v4()];
    for (k, &stroke) in strokes.iter().enumerate() {
        drawer.draw(stroke, &samples_for(k, 120), 10).await;
    }
    put_mesh(&proxy, &drawer, &session, strokes[0]).await;

    // Act
    let late =
        tokio::time::timeout(Duration::from_secs(20), Participant::join(&proxy, &session, "late"))
            .await
            .expect("the late joiner's history within 20 s");

    // Assert
    assert_eq!(late.view.n_done(), 2, "both finished strokes in the history");
    assert_eq!(late.view.n_meshes(), 1);
}
