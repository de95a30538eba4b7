//! Sessions on one database: SQLite (one replica) or PostgreSQL (participants spread over two
//! replicas).

use std::sync::Arc;
use std::time::Duration;

use penmesh::protocol::ServerMessage;
use penmesh_e2e::spawn_proxy;
use uuid::Uuid;

use crate::helpers::{
    Participant, check_complete, expected_view, one_or_two_replicas, put_mesh, samples_for,
};

#[tokio::test]
async fn participants_see_each_other_join_draw_store_meshes_and_leave() {
    // Arrange
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ann = Participant::join(&proxy, &session, "Ann").await;
    let mut bob = Participant::join(&proxy, &session, "Bob").await;
    let (ann_stroke, bob_stroke) = (Uuid::new_v4(), Uuid::new_v4());
    let (ann_samples, bob_samples) = (samples_for(1, 250), samples_for(2, 180));

    // Act: both draw at once, then each stores the mesh of its stroke.
    tokio::join!(ann.draw(ann_stroke, &ann_samples, 7), bob.draw(bob_stroke, &bob_samples, 5));
    put_mesh(&proxy, &ann, &session, ann_stroke).await;
    put_mesh(&proxy, &bob, &session, bob_stroke).await;
    ann.wait_for(|v| v.n_meshes() == 1).await;
    bob.wait_for(|v| v.n_meshes() == 1).await;

    // Assert
    assert_eq!(ann.view.present.get(&bob.welcome.participant).map(String::as_str), Some("Bob"));
    assert_eq!(bob.view.present.get(&ann.welcome.participant).map(String::as_str), Some("Ann"));
    let expected = expected_view(
        &[(ann_stroke, ann_samples), (bob_stroke, bob_samples)],
        &[ann_stroke, bob_stroke],
    );
    check_complete(&ann, &expected);
    check_complete(&bob, &expected);
    assert_eq!(bob.view.strokes[&ann_stroke].participant, ann.welcome.participant);
    let bob_id = bob.welcome.participant;
    drop(bob);
    ann.recv_until(|m| matches!(m, ServerMessage::PeerLeft(l) if l.participant == bob_id)).await;
}

#[tokio::test]
async fn late_joiners_see_what_an_early_joiner_sees_with_no_gap_and_no_repeat() {
    // Arrange: one stroke done with a mesh; then a second stroke streams slowly while five
    // participants join one after the other, each in the middle of it.
    let proxies = one_or_two_replicas(|_| {}).await;
    let (first, last) = (&proxies[0], proxies.last().unwrap());
    let session = first.create_session().await;
    let mut early = Participant::join(first, &session, "early").await;
    let mut drawer = Participant::join(first, &session, "drawer").await;
    let (done_stroke, streaming) = (Uuid::new_v4(), Uuid::new_v4());
    let (done_samples, streaming_samples) = (samples_for(1, 200), samples_for(2, 400));
    drawer.draw(done_stroke, &done_samples, 8).await;
    put_mesh(first, &drawer, &session, done_stroke).await;

    // Act
    let mut lates = Vec::new();
    tokio::join!(
        async {
            drawer.begin(streaming).await;
            for from in (0..400).step_by(5) {
                drawer.send_points(streaming, &streaming_samples, from, from + 5, 5).await;
                tokio::time::sleep(Duration::from_millis(2)).await;
            }
            drawer.wait_ack(streaming, 400).await;
            drawer.finish(streaming, 400).await;
        },
        async {
            for i in 0..5 {
                tokio::time::sleep(Duration::from_millis(30)).await;
                let proxy = if i % 2 == 0 { last } else { first };
                lates.push(Participant::join(proxy, &session, &format!("late {i}")).await);
            }
        }
    );
    put_mesh(last, &drawer, &session, streaming).await;

    // Assert: everyone ends with the same complete session.
    let expected = expected_view(
        &[(done_stroke, done_samples), (streaming, streaming_samples)],
        &[done_stroke, streaming],
    );
    early.wait_for(|v| v.n_done() == 2 && v.n_meshes() == 2).await;
    check_complete(&early, &expected);
    for late in &mut lates {
        late.wait_for(|v| v.n_done() == 2 && v.n_meshes() == 2).await;
        check_complete(late, &expected);
        assert_eq!(late.view.strokes, early.view.strokes);
    }
}

#[tokio::test]
async fn twenty_participants_drawing_at_once_each_get_every_stroke_exactly_once() {
    // Arrange: 20 participants (over two replicas with PostgreSQL), joined before anyone draws.
    const N: usize = 20;
    const STROKES: usize = 3;
    let proxies = Arc::new(one_or_two_replicas(|_| {}).await);
    let session = proxies[0].create_session().await;
    let barrier = Arc::new(tokio::sync::Barrier::new(N));
    let plan: Vec<Vec<(Uuid, Vec<penmesh::Sample>)>> = (0..N)
        .map(|p| {
            (0..STROKES).map(|k| (Uuid::new_v4(), samples_for(p * STROKES + k, 120))).collect()
        })
        .collect();

    // Act
    let mut tasks = Vec::new();
    for (p, strokes) in plan.iter().cloned().enumerate() {
        let (proxies, session, barrier) = (proxies.clone(), session.clone(), barrier.clone());
        tasks.push(tokio::spawn(async move {
            let proxy = &proxies[p % proxies.len()];
            let mut me = Participant::join(proxy, &session, &format!("p{p}")).await;
            barrier.wait().await;
            for (stroke, samples) in &strokes {
                me.draw(*stroke, samples, 6).await;
            }
            me.wait_for(|v| v.n_done() == (N - 1) * STROKES).await;
            me
        }));
    }
    let mut participants = Vec::new();
    for task in tasks {
        participants.push(task.await.expect("a participant task"));
    }

    // Assert
    let all: Vec<_> = plan.into_iter().flatten().collect();
    let expected = expected_view(&all, &[]);
    for p in &participants {
        check_complete(p, &expected);
        assert_eq!(p.own.len(), STROKES);
    }
}
