//! What a stroke becomes (issue 51). Over HTTP: `PUT /v1/strokes/{id}/solid` by the drawer
//! (its key checked before the body is read), its history (`GET …/solids`: who, when, why;
//! nothing overwritten, undo sets the one before), the strokes list, and the mesh built anew as
//! the solid; bad bodies, another participant and an open stroke filled are refused by name and
//! store nothing. Over the socket (protocol 6): `set_solid` live to another page, undone and
//! redone, after a reload and for a late joiner; never told to a version-5 client, which cannot
//! set one. And issue 52's item 2: a stroke brought back reaches a late watcher with its
//! placement and solid. On SQLite, and on PostgreSQL with `PENMESH_TEST_POSTGRES_URL`.

use futures_util::{SinkExt, StreamExt};
use penmesh::protocol::{
    ClientMessage, ErrorCode, ErrorMessage, Hello, KEY_HEADER, Ping, ServerMessage, SetPlacement,
    SetSolid, SolidHistory, StrokeId, StrokeRef, decode_server, encode_client_as,
};
use penmesh::{Placement, Sample, Solid, SolidKind};
use penmesh_e2e::{TestProxy, TestSession, count_rows, spawn_proxy, spawn_proxy_with};
use serde_json::json;
use tokio_tungstenite::tungstenite::Message;
use uuid::Uuid;

use crate::helpers::Participant;

/// A circle of radius 60 px (closed: it ends where it began), or three quarters of one (open).
pub(crate) fn circle(turns: f64) -> Vec<Sample> {
    let n = (96.0 * turns) as usize;
    (0..=n)
        .map(|i| {
            let a = std::f64::consts::TAU * turns * i as f64 / n as f64;
            let s =
                Sample::new(200.0 + 60.0 * a.cos(), 200.0 + 60.0 * a.sin(), 8.0 * i as f64, 0.5);
            penmesh::protocol::quantize_sample(&s)
        })
        .collect()
}

/// `PUT /v1/strokes/{stroke}/solid` with `body` as `who`: the status and the answer's text.
pub(crate) async fn put_solid(
    proxy: &TestProxy,
    who: &TestSession,
    stroke: uuid::Uuid,
    body: &str,
) -> (u16, String) {
    let response = proxy
        .http
        .put(proxy.url(&format!("/v1/strokes/{stroke}/solid")))
        .bearer_auth(&who.token)
        .header(KEY_HEADER, &who.key)
        .header("content-type", "application/json")
        .body(body.to_string())
        .send()
        .await
        .unwrap();
    let status = response.status().as_u16();
    (status, response.text().await.unwrap())
}

pub(crate) async fn mesh_bytes(
    proxy: &TestProxy,
    session: &TestSession,
    stroke: uuid::Uuid,
) -> Vec<u8> {
    let response = proxy.get(&format!("/v1/strokes/{stroke}/mesh"), session).send().await.unwrap();
    assert_eq!(response.status(), 200);
    response.bytes().await.unwrap().to_vec()
}

#[tokio::test]
async fn a_drawers_solid_is_stored_as_history_listed_and_meshed_and_bad_ones_store_nothing() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ann = Participant::join(&proxy, &session, "Ann").await;
    let drawer = TestSession { key: ann.key.clone(), ..session.clone() };
    let (closed, open) = (Uuid::new_v4(), Uuid::new_v4());
    ann.draw(closed, &circle(1.0), 16).await;
    ann.draw(open, &circle(0.75), 16).await;
    let rod = proxy.build_mesh(&drawer, closed).send().await.unwrap();
    assert_eq!(rod.status(), 200);
    let rod_glb = mesh_bytes(&proxy, &session, closed).await;
    assert_eq!(
        proxy.stroke_info(&session, closed).await["solid"],
        json!({"kind": "line", "depth": null})
    );

    // Set: committed, listed, and the mesh is the plate now.
    let (status, text) =
        put_solid(&proxy, &drawer, closed, r#"{"kind":"filled","depth":24}"#).await;
    assert_eq!(status, 200, "{text}");
    let info: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(info["uploader"], "penmesh-proxy");
    assert_eq!(
        proxy.stroke_info(&session, closed).await["solid"],
        json!({"kind": "filled", "depth": 24.0})
    );
    let plate_glb = mesh_bytes(&proxy, &session, closed).await;
    assert_ne!(plate_glb, rod_glb, "the mesh was built anew as the plate");
    let list = proxy.get_json(&format!("/v1/sessions/{}/strokes", session.session), &session).await;
    let listed = list["strokes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["id"] == closed.to_string())
        .unwrap()
        .clone();
    assert_eq!(listed["solid"]["kind"], "filled");

    // A duplicate is what its source is (it shows its source's mesh).
    let identity = serde_json::json!({"placement": {"matrix": Placement::IDENTITY.matrix()}});
    let response = proxy
        .http
        .post(proxy.url(&format!("/v1/strokes/{closed}/duplicate")))
        .bearer_auth(&session.token)
        .header(KEY_HEADER, &drawer.key)
        .json(&identity)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 201);
    let copy: serde_json::Value = response.json().await.unwrap();
    let copy: Uuid = copy["stroke"].as_str().unwrap().parse().unwrap();
    assert_eq!(
        proxy.stroke_info(&session, copy).await["solid"],
        json!({"kind": "filled", "depth": 24.0})
    );

    // Refused, naming why, and nothing stored: each check before any write.
    let rows = || count_rows(&proxy.db, "SELECT COUNT(*) FROM stroke_solids");
    let before = rows().await;
    let stranger = session.stranger();
    for (who, stroke, body, status, says) in [
        (&stranger, closed, r#"{"kind":"hole","depth":5}"#, 403, "only its drawer"),
        // Authorised before the body is read: a stranger's bad body is still 403.
        (&stranger, closed, "not json", 403, "only its drawer"),
        (&drawer, open, r#"{"kind":"filled","depth":5}"#, 409, "an open stroke cannot be filled"),
        (&drawer, closed, r#"{"kind":"filled","depth":-1}"#, 400, "outside [0.125, 10000] px"),
        (&drawer, closed, r#"{"kind":"hole","depth":1e9}"#, 400, "outside [0.125, 10000] px"),
        (&drawer, closed, r#"{"kind":"hole","depth":null}"#, 400, "a hole solid needs a depth"),
        (&drawer, closed, r#"{"kind":"plate","depth":3}"#, 400, "unknown variant"),
    ] {
        let (got, text) = put_solid(&proxy, who, stroke, body).await;
        assert_eq!(got, status, "{body}: {text}");
        assert!(text.contains(says), "{body}: {text}");
    }
    assert_eq!(rows().await, before, "nothing stored for a refusal");
    assert_eq!(mesh_bytes(&proxy, &session, closed).await, plate_glb);

    // Undo: the rod again, a third entry; nothing overwritten.
    let (status, text) =
        put_solid(&proxy, &drawer, closed, r#"{"kind":"line","depth":null}"#).await;
    assert_eq!(status, 200, "{text}");
    let body = proxy.get_json(&format!("/v1/strokes/{closed}/solids"), &session).await;
    let history: SolidHistory = serde_json::from_value(body).unwrap();
    let kinds: Vec<(Solid, &str)> =
        history.solids.iter().map(|s| (s.solid, s.cause.as_str())).collect();
    let filled = Solid::new(SolidKind::Filled, Some(24.0)).unwrap();
    assert_eq!(kinds, vec![(Solid::ROD, "begin"), (filled, "set"), (Solid::ROD, "set")]);
    assert!(history.solids.iter().all(|s| s.by == ann.welcome.participant));
    assert_eq!(
        mesh_bytes(&proxy, &session, closed).await.len(),
        rod_glb.len(),
        "the rod's mesh again"
    );
}

/// A client of an older `version` (binary), its frames as that version has them.
struct OldClient {
    ws: penmesh_e2e::WsClient,
    version: u8,
}

impl OldClient {
    async fn join(
        proxy: &TestProxy,
        session: &TestSession,
        version: u16,
    ) -> (OldClient, Vec<ServerMessage>) {
        let mut old = OldClient { ws: proxy.connect(session).await, version: version as u8 };
        old.send(&ClientMessage::Hello(Hello {
            protocol: version,
            client: format!("penmesh {version}"),
            name: Some("old".into()),
            resume: vec![],
            key: Some(penmesh_e2e::new_key()),
        }))
        .await;
        let history = old.recv_until(|m| matches!(m, ServerMessage::Synced(_))).await;
        (old, history)
    }

    async fn send(&mut self, msg: &ClientMessage) {
        let frame = encode_client_as(msg, self.version.into()).expect("the version can say it");
        self.ws.ws.send(Message::Binary(frame.into())).await.unwrap();
    }

    /// The next message; every frame carries the connection's version and decodes as it.
    async fn recv(&mut self) -> ServerMessage {
        loop {
            let frame = tokio::time::timeout(std::time::Duration::from_secs(10), self.ws.ws.next())
                .await
                .expect("a frame in time")
                .expect("open")
                .unwrap();
            if let Message::Binary(bytes) = frame {
                assert_eq!(bytes[0], self.version, "a frame of another version");
                let msg = decode_server(&bytes, usize::MAX).unwrap();
                assert!(!matches!(msg, ServerMessage::PeerSolid(_)), "{msg:?}");
                if let ServerMessage::PeerStrokes(s) = &msg {
                    assert!(
                        s.strokes.iter().all(|s| s.solid.is_rod() && s.placement.is_identity())
                    );
                }
                return msg;
            }
        }
    }

    async fn recv_until(&mut self, pred: impl Fn(&ServerMessage) -> bool) -> Vec<ServerMessage> {
        let mut seen = Vec::new();
        loop {
            let msg = self.recv().await;
            let done = pred(&msg);
            seen.push(msg);
            if done {
                return seen;
            }
        }
    }
}

/// `SetSolid` over the socket; the answer (`PeerSolid`) or the error.
async fn set_solid(
    p: &mut Participant,
    stroke: StrokeId,
    solid: Solid,
) -> Result<Solid, ErrorMessage> {
    p.ws.send(&ClientMessage::SetSolid(SetSolid { stroke, solid })).await;
    loop {
        match p.recv().await {
            ServerMessage::PeerSolid(answer) if answer.stroke == stroke => return Ok(answer.solid),
            ServerMessage::Error(e) if e.stroke == Some(stroke) => return Err(e),
            ServerMessage::Error(e) => panic!("unexpected error: {e:?}"),
            _ => {}
        }
    }
}

fn solid_of(p: &Participant, stroke: StrokeId) -> Option<Solid> {
    p.view.strokes.get(&stroke).and_then(|s| s.solid)
}

// A solid set on one page is seen live on another, undone and redone; after a reload (a new
// connection of the same participant) and by a late joiner it is there; a version-5 client is
// never told and cannot set one; an open stroke filled is refused and stores nothing.
#[tokio::test]
async fn a_solid_set_on_one_page_is_live_on_another_after_a_reload_and_never_told_to_version_5() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ann = Participant::join(&proxy, &session, "Ann").await;
    let mut bob = Participant::join(&proxy, &session, "Bob").await;
    let (mut old, _) = OldClient::join(&proxy, &session, 5).await;
    let (closed, open) = (Uuid::new_v4(), Uuid::new_v4());
    ann.draw(closed, &circle(1.0), 16).await;
    ann.draw(open, &circle(0.75), 16).await;
    let filled = Solid::new(SolidKind::Filled, Some(24.0)).unwrap();

    assert_eq!(set_solid(&mut ann, closed, filled).await.unwrap(), filled);
    bob.wait_for(|v| v.strokes.get(&closed).is_some_and(|s| s.solid == Some(filled))).await;
    // The stroke's new mesh is announced to the others once stored.
    bob.wait_for(|v| v.strokes.get(&closed).is_some_and(|s| s.meshes >= 1)).await;
    // Undo and redo: the rod, then the plate again; the other page follows each.
    assert_eq!(set_solid(&mut ann, closed, Solid::ROD).await.unwrap(), Solid::ROD);
    bob.wait_for(|v| v.strokes.get(&closed).is_some_and(|s| s.solid == Some(Solid::ROD))).await;
    assert_eq!(set_solid(&mut ann, closed, filled).await.unwrap(), filled);
    bob.wait_for(|v| v.strokes.get(&closed).is_some_and(|s| s.solid == Some(filled))).await;

    // Refused and stored nothing: an open stroke filled (bad_solid, naming its gap), another's
    // stroke (not_owner).
    let rows = || count_rows(&proxy.db, "SELECT COUNT(*) FROM stroke_solids");
    let before = rows().await;
    let refused = set_solid(&mut ann, open, filled).await.unwrap_err();
    assert_eq!(refused.code, ErrorCode::BadSolid);
    assert!(refused.message.contains("an open stroke cannot be filled"), "{}", refused.message);
    let refused = set_solid(&mut bob, closed, Solid::ROD).await.unwrap_err();
    assert_eq!(refused.code, ErrorCode::NotOwner);
    assert_eq!(rows().await, before);

    // A reload of Bob's page, and a late joiner: the plate, from the history.
    let bob_again = Participant::join_resuming(&proxy, &session, "Bob", &bob.key, vec![]).await;
    assert_eq!(solid_of(&bob_again, closed), Some(filled));
    let carl = Participant::join(&proxy, &session, "Carl").await;
    assert_eq!(solid_of(&carl, closed), Some(filled));
    assert_eq!(solid_of(&carl, open), None, "the rod is not told");

    // The version-5 client heard none of it, and its set_solid is not a message it has.
    old.send(&ClientMessage::Ping(Ping { nonce: 5 })).await;
    old.recv_until(|m| matches!(m, ServerMessage::Pong(_))).await;
    let mut json_old = proxy.connect(&session).await.json();
    json_old
        .send_text(r#"{"hello":{"protocol":5,"client":"json 5","key":"0123456789abcdef0123456789abcdef"}}"#)
        .await;
    assert!(matches!(json_old.recv().await, ServerMessage::Welcome(w) if w.protocol == 5));
    let set =
        format!(r#"{{"set_solid":{{"stroke":"{closed}","solid":{{"kind":"hole","depth":3}}}}}}"#);
    json_old.send_text(&set).await;
    let error = json_old.expect_error(ErrorCode::UnknownMessage).await;
    assert!(error.message.contains("version 6"), "{}", error.message);
}

// Issue 52, item 2: a stroke moved, then taken back before a watcher came, then brought back:
// the watcher gets it whole with its placement (version 6: in the `HistoryStroke`; version 5:
// a `peer_placement` after it), and with its solid (version 6).
#[tokio::test]
async fn a_stroke_brought_back_reaches_a_late_watcher_with_its_placement_and_solid() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ann = Participant::join(&proxy, &session, "Ann").await;
    let stroke = Uuid::new_v4();
    ann.draw(stroke, &circle(1.0), 16).await;
    let mut m = *Placement::IDENTITY.matrix();
    m[12] = 250.0;
    let moved = Placement::new(m).unwrap();
    ann.ws.send(&ClientMessage::SetPlacement(SetPlacement { stroke, placement: moved })).await;
    ann.recv_until(|m| matches!(m, ServerMessage::PeerPlacement(p) if p.stroke == stroke)).await;
    let hole = Solid::new(SolidKind::Hole, Some(8.0)).unwrap();
    set_solid(&mut ann, stroke, hole).await.unwrap();
    ann.ws.send(&ClientMessage::RemoveStroke(StrokeRef { stroke })).await;
    ann.recv_until(|m| matches!(m, ServerMessage::StrokeRemoved(r) if r.stroke == stroke)).await;

    let mut watcher = Participant::join(&proxy, &session, "Watcher").await;
    let (mut old, _) = OldClient::join(&proxy, &session, 5).await;
    assert!(!watcher.view.strokes.contains_key(&stroke));
    ann.ws.send(&ClientMessage::RestoreStroke(StrokeRef { stroke })).await;

    let whole = watcher.recv_until(|m| matches!(m, ServerMessage::PeerStrokes(_))).await;
    let ServerMessage::PeerStrokes(whole) = whole else { unreachable!() };
    assert_eq!(whole.strokes.len(), 1);
    assert_eq!((whole.strokes[0].placement, whole.strokes[0].solid), (moved, hole));
    let held = &watcher.view.strokes[&stroke];
    assert_eq!((held.placement, held.solid), (Some(moved), Some(hole)));

    let seen = old
        .recv_until(|m| matches!(m, ServerMessage::PeerPlacement(p) if p.stroke == stroke))
        .await;
    assert!(
        seen.iter()
            .any(|m| matches!(m, ServerMessage::PeerStrokes(s) if s.strokes[0].stroke == stroke))
    );
    let ServerMessage::PeerPlacement(told) = seen.last().unwrap() else { unreachable!() };
    assert_eq!(told.placement, moved);
}

async fn export_glb(proxy: &TestProxy, session: &TestSession) -> Vec<u8> {
    let path = format!("/v1/sessions/{}/export?format=glb&size_mm=120", session.session);
    let response = proxy.get(&path, session).send().await.unwrap();
    assert_eq!(response.status(), 200);
    response.bytes().await.unwrap().to_vec()
}

// The scene carries each stroke's solid in its extras (none for the rod); an import stores it
// exactly (its history's cause `import`), meshed as that solid, and exports again the same.
#[tokio::test]
async fn a_solid_leaves_in_the_scene_and_comes_back_exactly_with_an_import() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ann = Participant::join(&proxy, &session, "Ann").await;
    let drawer = TestSession { key: ann.key.clone(), ..session.clone() };
    let (plate, rod) = (Uuid::new_v4(), Uuid::new_v4());
    ann.draw(plate, &circle(1.0), 16).await;
    ann.draw(rod, &circle(0.75), 16).await;
    assert_eq!(proxy.build_mesh(&drawer, rod).send().await.unwrap().status(), 200);
    let (status, text) =
        put_solid(&proxy, &drawer, plate, r#"{"kind":"filled","depth":12.25}"#).await;
    assert_eq!(status, 200, "{text}");
    let filled = Solid::new(SolidKind::Filled, Some(12.25)).unwrap();

    let first = penmesh::read_scene(&export_glb(&proxy, &session).await).unwrap();
    let solids: Vec<(Uuid, Solid)> =
        first.iter().map(|s| (s.extras.stroke, s.extras.solid)).collect();
    assert_eq!(solids, vec![(plate, filled), (rod, Solid::ROD)]);

    let second = proxy.create_session().await;
    let response = proxy
        .http
        .post(proxy.url(&format!("/v1/sessions/{}/import", second.session)))
        .bearer_auth(&second.token)
        .header(KEY_HEADER, &second.key)
        .header("content-type", "model/gltf-binary")
        .body(export_glb(&proxy, &session).await)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 201, "{}", response.text().await.unwrap());
    let again = penmesh::read_scene(&export_glb(&proxy, &second).await).unwrap();
    // By where each came from (an import's order among strokes of one instant is by id).
    let mut solids: Vec<(Uuid, Solid)> = again
        .iter()
        .map(|s| (s.extras.imported_from.as_ref().unwrap().stroke, s.extras.solid))
        .collect();
    solids.sort_by_key(|(from, _)| if *from == plate { 0 } else { 1 });
    assert_eq!(solids, vec![(plate, filled), (rod, Solid::ROD)]);
    let imported = again.iter().find(|s| s.extras.solid == filled).unwrap().extras.stroke;
    let body = proxy.get_json(&format!("/v1/strokes/{imported}/solids"), &second).await;
    let history: SolidHistory = serde_json::from_value(body).unwrap();
    let causes: Vec<&str> = history.solids.iter().map(|s| s.cause.as_str()).collect();
    assert_eq!(causes, vec!["import"], "imported as a plate: never a rod");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn racing_solid_changes_leave_the_mesh_of_the_solid_stored_last() {
    // Two changes of one stroke's solid at once, round after round: whichever is stored last,
    // the stored mesh is that solid's (the bytes the proxy builds for it alone), never the
    // other request's mesh stored after it. (202 changes as fast as they go: the rate off.)
    let proxy = spawn_proxy_with(|c| c.solid_rate_per_second = 0).await;
    let session = proxy.create_session().await;
    let mut ann = Participant::join(&proxy, &session, "Ann").await;
    let drawer = TestSession { key: ann.key.clone(), ..session.clone() };
    let stroke = Uuid::new_v4();
    ann.draw(stroke, &circle(1.0), 16).await;
    let plate = r#"{"kind": "filled", "depth": 12}"#;
    let wall = r#"{"kind": "line", "depth": 40}"#;
    let mut alone = std::collections::HashMap::new();
    for body in [plate, wall] {
        assert_eq!(put_solid(&proxy, &drawer, stroke, body).await.0, 200);
        alone.insert(body, mesh_bytes(&proxy, &session, stroke).await);
    }
    assert_ne!(alone[plate], alone[wall]);
    for round in 0..100 {
        let (a, b) = tokio::join!(
            put_solid(&proxy, &drawer, stroke, plate),
            put_solid(&proxy, &drawer, stroke, wall)
        );
        assert_eq!((a.0, b.0), (200, 200), "round {round}: {a:?} {b:?}");
        let stored = proxy.stroke_info(&session, stroke).await["solid"].clone();
        let body = if stored["kind"] == "filled" { plate } else { wall };
        assert!(
            mesh_bytes(&proxy, &session, stroke).await == alone[body],
            "round {round}: the stored mesh is not that of the stored solid {stored}"
        );
    }
}
