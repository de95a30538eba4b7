//! A late joiner's history comes a few messages for many strokes (`PeerStrokes`), and ends the
//! same as what an early joiner saw live.

use uuid::Uuid;

use crate::helpers::{
    Participant, check_complete, expected_view, one_or_two_replicas, put_mesh, samples_for,
};

#[tokio::test]
async fn a_late_joiner_gets_fifty_strokes_in_one_message_and_the_same_view() {
    let proxies = one_or_two_replicas(|_| {}).await;
    let (a, b) = (&proxies[0], proxies.last().unwrap());
    let session = a.create_session().await;
    let mut drawer = Participant::join(a, &session, "drawer").await;
    let mut early = Participant::join(b, &session, "early").await;
    let strokes: Vec<_> = (0..50).map(|k| (Uuid::new_v4(), samples_for(k, 60))).collect();
    for (stroke, samples) in &strokes {
        drawer.draw(*stroke, samples, 20).await;
        put_mesh(a, &drawer, &session, *stroke).await;
    }
    early.wait_for(|v| v.n_meshes() == 50).await;

    let late = Participant::join(b, &session, "late").await;

    let meshes: Vec<Uuid> = strokes.iter().map(|(id, _)| *id).collect();
    let expected = expected_view(&strokes, &meshes);
    check_complete(&early, &expected);
    check_complete(&late, &expected);
    assert_eq!(late.view.n_messages_of_strokes, 1, "50 small strokes in one PeerStrokes");
    assert_eq!(early.view.n_messages_of_strokes, 0, "live strokes come one event at a time");
}
