//! What the session is told, as `docs/protocol.md` says (issue 52): a `stroke_begin` of
//! another participant's open stroke is `not_owner` at once (item 5); a mesh stored over HTTP
//! is announced to the drawer's connection too (item 7); a stroke begun at the identity is not
//! followed by a `peer_placement`, live as in a history (item 8); a second connection of a
//! participant keeps its name unless its hello names another, which the session then hears,
//! and the export's author is that name (item 9).

use std::time::{Duration, Instant};

use penmesh::Placement;
use penmesh::protocol::{ClientMessage, ErrorCode, Hello, PROTOCOL_VERSION, ServerMessage};
use penmesh::read_scene;
use penmesh_e2e::{TestSession, spawn_proxy_with};
use uuid::Uuid;

use crate::helpers::{Participant, one_or_two_replicas, samples_for};
use crate::placement::draw_on;

/// Another participant's stroke, open on its drawer's live connection: `stroke_begin` of it is
/// `not_owner`, at once (not after waiting `--claim-wait-ms` for the drawer to let go, and not
/// `stroke_conflict`, which says to retry).
#[tokio::test]
async fn beginning_another_participants_open_stroke_is_not_owner_at_once() {
    let proxy = spawn_proxy_with(|c| c.claim_wait_ms = 5_000).await;
    let session = proxy.create_session().await;
    let mut drawer = Participant::join(&proxy, &session, "drawer").await;
    let stroke = Uuid::new_v4();
    let samples = samples_for(0, 40);
    drawer.begin(stroke).await;
    drawer.send_points(stroke, &samples, 0, 20, 10).await;
    drawer.wait_ack(stroke, 20).await;

    let mut other = Participant::join(&proxy, &session, "other").await;
    let asked = Instant::now();
    other.ws.begin(stroke).await;
    let err = loop {
        if let ServerMessage::Error(err) = other.recv().await {
            break err;
        }
    };
    assert_eq!((err.code, err.stroke), (ErrorCode::NotOwner, Some(stroke)), "{err:?}");
    assert!(asked.elapsed() < Duration::from_secs(4), "answered after {:?}", asked.elapsed());
    // The drawer goes on.
    drawer.send_points(stroke, &samples, 20, 40, 10).await;
    drawer.wait_ack(stroke, 40).await;
    drawer.finish(stroke, 40).await;
}

/// A mesh built over HTTP is announced to the whole session: the watcher and the drawer's own
/// connection both get its `peer_mesh`.
#[tokio::test]
async fn a_mesh_built_over_http_is_announced_to_the_drawers_connection_too() {
    let proxies = one_or_two_replicas(|_| {}).await;
    let (a, b) = (&proxies[0], proxies.last().unwrap());
    let session = a.create_session().await;
    let mut drawer = Participant::join(a, &session, "drawer").await;
    let mut watcher = Participant::join(b, &session, "watcher").await;
    let stroke = Uuid::new_v4();
    drawer.draw(stroke, &samples_for(1, 60), 16).await;
    let as_drawer = TestSession { key: drawer.key.clone(), ..session.clone() };
    let built = a.build_mesh(&as_drawer, stroke).send().await.unwrap();
    assert_eq!(built.status(), 200);
    let told =
        drawer.recv_until(|m| matches!(m, ServerMessage::PeerMesh(p) if p.stroke == stroke)).await;
    let ServerMessage::PeerMesh(told) = told else { unreachable!() };
    assert_eq!(told.participant, drawer.welcome.participant);
    assert_eq!(told.url, format!("/v1/strokes/{stroke}/mesh"));
    watcher.wait_for(|v| v.strokes.get(&stroke).is_some_and(|s| s.meshes == 1)).await;
}

/// A stroke begun with the identity as its placement is not followed by a `peer_placement`
/// (live), as a history sends none for it: a watcher and a late joiner see the same.
#[tokio::test]
async fn a_stroke_begun_at_the_identity_gets_no_placement_live_or_in_a_history() {
    let proxies = one_or_two_replicas(|_| {}).await;
    let (a, b) = (&proxies[0], proxies.last().unwrap());
    let session = a.create_session().await;
    let mut drawer = Participant::join(a, &session, "drawer").await;
    let mut watcher = Participant::join(b, &session, "watcher").await;
    let (board, marker) = (Uuid::new_v4(), Uuid::new_v4());
    draw_on(&mut drawer, board, 0, Placement::IDENTITY).await;
    // A second stroke after it: once the watcher has it done, it has every event of the first.
    drawer.draw(marker, &samples_for(2, 30), 16).await;
    watcher.wait_for(|v| v.strokes.get(&marker).is_some_and(|s| s.done)).await;
    assert_eq!(watcher.view.strokes[&board].placement, None, "an identity peer_placement, live");
    let late = Participant::join(b, &session, "late").await;
    assert_eq!(late.view.strokes[&board].placement, None, "in the history");
}

/// The name a participant's connections show, and its strokes' author in the export.
async fn author_in_export(
    proxy: &penmesh_e2e::TestProxy,
    session: &TestSession,
    stroke: Uuid,
) -> String {
    let path = format!("/v1/sessions/{}/export?format=glb", session.session);
    let response = proxy.get(&path, session).send().await.unwrap();
    assert_eq!(response.status(), 200);
    let scene = read_scene(&response.bytes().await.unwrap()).unwrap();
    let read = scene.iter().find(|s| s.extras.stroke == stroke).expect("the stroke exported");
    read.extras.author.name.clone()
}

/// A second connection of a participant whose hello has no name keeps the participant's name
/// (not its `client` string), in the session and in the export; one whose hello names another
/// renames the participant, and the session hears `peer_renamed`.
#[tokio::test]
async fn a_second_connection_keeps_the_name_or_renames_for_everyone() {
    let proxies = one_or_two_replicas(|_| {}).await;
    let (a, b) = (&proxies[0], proxies.last().unwrap());
    let session = a.create_session().await;
    let mut drawer = Participant::join(a, &session, "Ada").await;
    let mut watcher = Participant::join(b, &session, "watcher").await;
    let stroke = Uuid::new_v4();
    drawer.draw(stroke, &samples_for(3, 40), 16).await;
    watcher.wait_for(|v| v.strokes.get(&stroke).is_some_and(|s| s.done)).await;
    let ada = drawer.welcome.participant;
    assert_eq!(watcher.view.present[&ada], "Ada");

    let second = |name: Option<&str>| {
        ClientMessage::Hello(Hello {
            protocol: PROTOCOL_VERSION,
            client: "second-client/1.0".into(),
            name: name.map(String::from),
            resume: vec![],
            key: Some(drawer.key.clone()),
        })
    };
    let mut unnamed = b.connect(&session).await;
    unnamed.send(&second(None)).await;
    loop {
        match unnamed.recv_any().await {
            ServerMessage::Synced(_) => break,
            ServerMessage::Error(e) => panic!("{e:?}"),
            _ => {}
        }
    }
    assert_eq!(author_in_export(a, &session, stroke).await, "Ada");

    let mut renamed = b.connect(&session).await;
    renamed.send(&second(Some("Ada L."))).await;
    watcher
        .recv_until(|m| matches!(m, ServerMessage::PeerRenamed(r) if r.participant == ada))
        .await;
    assert_eq!(watcher.view.present[&ada], "Ada L.");
    assert_eq!(author_in_export(a, &session, stroke).await, "Ada L.");
}
