//! Strokes placed in 3D (protocol version 5), as people model with them: a stroke drawn on a
//! standing work plane, moved, duplicated, mirrored and its move undone (the previous placement
//! read back from its history and set again). The drawer on one replica, a watcher and a late
//! joiner on the other (two replicas with PostgreSQL, one proxy on SQLite) end with the same
//! placements, bit for bit; bad matrices and another participant are refused and change
//! nothing; a version-4 client still draws and watches, and is never sent a placement.

use futures_util::{SinkExt, StreamExt};
use penmesh::Placement;
use penmesh::protocol::{
    ClientMessage, ErrorCode, Hello, KEY_HEADER, PointBatch, Points, ServerMessage, SetPlacement,
    StrokeBegin, StrokeEnd, StrokeId, decode_server, encode_client_as,
};
use penmesh_e2e::{TestProxy, TestSession, count_rows};
use tokio_tungstenite::tungstenite::Message;
use uuid::Uuid;

use crate::helpers::{Participant, one_or_two_replicas, put_mesh, samples_for};

/// The front plane: the board stood up about x (its y becomes the world's z).
pub(crate) fn standing() -> Placement {
    Placement::new([
        1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ])
    .unwrap()
}

/// The standing plane turned 30° about the world's z, scaled by 1.5 and moved: every element a
/// full `f64`, as a gizmo leaves it.
fn moved() -> Placement {
    let (s, c) = 30f64.to_radians().sin_cos();
    let k = 1.5;
    Placement::new([
        k * c,
        k * s,
        0.0,
        0.0,
        0.0,
        0.0,
        k,
        0.0,
        k * s,
        -k * c,
        0.0,
        0.0,
        0.1,
        -20.3,
        7.7,
        1.0,
    ])
    .unwrap()
}

/// Off to the side, on the board.
fn beside() -> Placement {
    let mut m = *Placement::IDENTITY.matrix();
    m[12] = 250.0;
    Placement::new(m).unwrap()
}

/// `beside` mirrored in x: a negative determinant.
fn mirrored() -> Placement {
    let mut m = *beside().matrix();
    m[0] = -1.0;
    Placement::new(m).unwrap()
}

pub(crate) fn bits(p: &Placement) -> Vec<u8> {
    p.to_bytes()
}

/// Draws `samples` as `stroke` on the work plane `placement`, and waits for its end.
pub(crate) async fn draw_on(p: &mut Participant, stroke: StrokeId, k: usize, placement: Placement) {
    let samples = samples_for(k, 90);
    p.ws.send(&ClientMessage::StrokeBegin(StrokeBegin {
        stroke,
        brush: Default::default(),
        device: Some("synth:e2e".into()),
        params: None,
        placement: Some(placement),
        solid: None,
    }))
    .await;
    p.wait_ack(stroke, 0).await;
    p.send_points(stroke, &samples, 0, samples.len(), 16).await;
    p.wait_ack(stroke, samples.len() as u64).await;
    p.finish(stroke, samples.len()).await;
}

/// `SetPlacement` over the socket; the answer (`PeerPlacement`) or the error's code.
async fn set_placement(
    p: &mut Participant,
    stroke: StrokeId,
    placement: Placement,
) -> Result<Placement, ErrorCode> {
    p.ws.send(&ClientMessage::SetPlacement(SetPlacement { stroke, placement })).await;
    loop {
        match p.recv().await {
            ServerMessage::PeerPlacement(answer) if answer.stroke == stroke => {
                return Ok(answer.placement);
            }
            ServerMessage::Error(e) if e.stroke == Some(stroke) => return Err(e.code),
            ServerMessage::Error(e) => panic!("unexpected error: {e:?}"),
            _ => {}
        }
    }
}

/// `PUT /v1/strokes/{stroke}/placement` with `body` as `who`: the status and the message.
pub(crate) async fn put_placement(
    proxy: &TestProxy,
    who: &TestSession,
    stroke: StrokeId,
    body: String,
) -> (u16, String) {
    let response = proxy
        .http
        .put(proxy.url(&format!("/v1/strokes/{stroke}/placement")))
        .bearer_auth(&who.token)
        .header(KEY_HEADER, &who.key)
        .header("content-type", "application/json")
        .body(body)
        .send()
        .await
        .unwrap();
    let status = response.status().as_u16();
    (status, response.text().await.unwrap())
}

pub(crate) fn matrix_body(p: &Placement) -> String {
    serde_json::json!({ "matrix": p.matrix() }).to_string()
}

/// The placement history of `stroke`: (placement, by, cause) each, oldest first.
pub(crate) async fn history(
    proxy: &TestProxy,
    session: &TestSession,
    stroke: StrokeId,
) -> Vec<(Placement, Uuid, String)> {
    let body = proxy.get_json(&format!("/v1/strokes/{stroke}/placements"), session).await;
    let history: penmesh::protocol::PlacementHistory = serde_json::from_value(body).unwrap();
    assert_eq!(history.stroke, stroke);
    history.placements.into_iter().map(|c| (c.placement, c.by, c.cause)).collect()
}

/// The placement of each stroke of the session's strokes list.
pub(crate) async fn listed(proxy: &TestProxy, session: &TestSession) -> Vec<(StrokeId, Vec<u8>)> {
    let list = proxy.get_json(&format!("/v1/sessions/{}/strokes", session.session), session).await;
    let list: penmesh::protocol::StrokeList = serde_json::from_value(list).unwrap();
    list.strokes.iter().map(|s| (s.id, bits(&s.placement))).collect()
}

/// The bytes of a stroke's mesh.
async fn mesh_of(proxy: &TestProxy, session: &TestSession, stroke: StrokeId) -> Vec<u8> {
    let response = proxy.get(&format!("/v1/strokes/{stroke}/mesh"), session).send().await.unwrap();
    assert_eq!(response.status(), 200);
    response.bytes().await.unwrap().to_vec()
}

/// The placement each peer stroke has in a participant's view.
fn seen(p: &Participant) -> Vec<(StrokeId, Vec<u8>)> {
    p.view
        .strokes
        .iter()
        .map(|(id, s)| (*id, bits(&s.placement.unwrap_or(Placement::IDENTITY))))
        .collect()
}

#[tokio::test]
async fn strokes_placed_moved_duplicated_mirrored_and_undone_are_seen_identically_everywhere() {
    let proxies = one_or_two_replicas(|_| {}).await;
    let (a, b) = (&proxies[0], proxies.last().unwrap());
    let session = a.create_session().await;
    let mut drawer = Participant::join(a, &session, "drawer").await;
    let mut watcher = Participant::join(b, &session, "watcher").await;
    let as_drawer = TestSession { key: drawer.key.clone(), ..session.clone() };
    let as_watcher = TestSession { key: watcher.key.clone(), ..session.clone() };

    // Drawn on the standing plane; its mesh stored through the other replica.
    let chair_back = Uuid::new_v4();
    draw_on(&mut drawer, chair_back, 0, standing()).await;
    put_mesh(b, &drawer, &session, chair_back).await;
    watcher
        .wait_for(|v| {
            v.strokes.get(&chair_back).is_some_and(|s| {
                s.meshes == 1 && s.placement.is_some_and(|p| bits(&p) == bits(&standing()))
            })
        })
        .await;

    // Moved (turned, scaled, translated) by its drawer.
    assert_eq!(
        set_placement(&mut drawer, chair_back, moved()).await.map(|p| bits(&p)),
        Ok(bits(&moved()))
    );
    watcher
        .wait_for(|v| v.strokes[&chair_back].placement.is_some_and(|p| bits(&p) == bits(&moved())))
        .await;

    // Duplicated over HTTP (the other replica): a new stroke of the drawer's, its source
    // recorded, the same pen data, its mesh shared.
    let copy = Uuid::new_v4();
    let response = b
        .http
        .post(b.url(&format!("/v1/strokes/{chair_back}/duplicate")))
        .bearer_auth(&session.token)
        .header(KEY_HEADER, &drawer.key)
        .json(&serde_json::json!({ "stroke": copy, "placement": { "matrix": beside().matrix() } }))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 201);
    let made: penmesh::protocol::Duplicated = response.json().await.unwrap();
    assert_eq!((made.stroke, made.source), (copy, chair_back));
    watcher
        .wait_for(|v| {
            v.strokes.get(&copy).is_some_and(|s| {
                s.meshes == 1 && s.placement.is_some_and(|p| bits(&p) == bits(&beside()))
            })
        })
        .await;
    assert_eq!(watcher.view.strokes[&copy].retained, watcher.view.strokes[&chair_back].retained);
    assert_eq!(watcher.view.strokes[&copy].participant, drawer.welcome.participant);
    let info = b.stroke_info(&session, copy).await;
    assert_eq!(info["duplicate_of"], chair_back.to_string());
    assert_eq!(info["has_mesh"], true);
    let raw_copy = b.raw_samples(&session, copy).await;
    assert_eq!(raw_copy, b.raw_samples(&session, chair_back).await);
    assert_eq!(mesh_of(a, &session, copy).await, mesh_of(a, &session, chair_back).await);
    assert_eq!(count_rows(&a.db, "SELECT COUNT(*) FROM meshes").await, 1, "shared, not copied");

    // Mirrored (a negative determinant), over HTTP.
    assert!(mirrored().is_mirror());
    assert_eq!(put_placement(b, &as_drawer, copy, matrix_body(&mirrored())).await.0, 204);
    watcher
        .wait_for(|v| v.strokes[&copy].placement.is_some_and(|p| bits(&p) == bits(&mirrored())))
        .await;

    // Refused, changing nothing: another participant (socket and HTTP), bad matrices, no such
    // stroke.
    let before = (history(a, &session, chair_back).await, listed(a, &session).await);
    assert_eq!(set_placement(&mut watcher, chair_back, beside()).await, Err(ErrorCode::NotOwner));
    let (status, why) = put_placement(b, &as_watcher, chair_back, matrix_body(&beside())).await;
    assert_eq!(status, 403, "{why}");
    let mut shear = *Placement::IDENTITY.matrix();
    shear[4] = 0.25;
    let mut projective = *Placement::IDENTITY.matrix();
    projective[3] = 0.5;
    let huge: Vec<f64> = Placement::IDENTITY.matrix().iter().map(|v| v * 2000.0).collect();
    let mut huge_affine = huge.clone();
    huge_affine[15] = 1.0;
    for (body, names) in [
        (serde_json::json!({ "matrix": shear }).to_string(), "not a similarity"),
        (serde_json::json!({ "matrix": projective }).to_string(), "matrix[3] = 0.5"),
        (serde_json::json!({ "matrix": huge_affine }).to_string(), "scales by 2000"),
        (r#"{"matrix":[1e999,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1]}"#.to_string(), "matrix"),
        (r#"{"matrix":[1,0,0,0,0,1,0,0,0,0,1,0,0,0,0]}"#.to_string(), "16"),
    ] {
        let (status, why) = put_placement(a, &as_drawer, chair_back, body.clone()).await;
        assert_eq!(status, 400, "{body}: {why}");
        assert!(why.contains(names), "{body}: {why} (wanted {names:?})");
    }
    let (status, _) = put_placement(a, &as_drawer, Uuid::new_v4(), matrix_body(&beside())).await;
    assert_eq!(status, 404);
    assert_eq!((history(b, &session, chair_back).await, listed(b, &session).await), before);

    // The move undone: the placement before it, read from the history, set again.
    let earlier = history(a, &session, chair_back).await;
    let causes: Vec<&str> = earlier.iter().map(|(_, _, c)| c.as_str()).collect();
    assert_eq!(causes, ["begin", "set"]);
    assert!(earlier.iter().all(|(_, by, _)| *by == drawer.welcome.participant));
    let previous = earlier[earlier.len() - 2].0;
    assert_eq!(bits(&previous), bits(&standing()));
    assert_eq!(
        set_placement(&mut drawer, chair_back, previous).await.map(|p| bits(&p)),
        Ok(bits(&standing()))
    );
    watcher
        .wait_for(|v| {
            v.strokes[&chair_back].placement.is_some_and(|p| bits(&p) == bits(&standing()))
        })
        .await;
    assert_eq!(history(b, &session, chair_back).await.len(), 3, "nothing overwritten");

    // A late joiner on the other replica ends with the same placements as the watcher, as do
    // the strokes list and both replicas' lists.
    let late = Participant::join(b, &session, "late").await;
    assert_eq!(seen(&late), seen(&watcher));
    let expected = vec![(chair_back, bits(&standing())), (copy, bits(&mirrored()))];
    let mut by_id = expected.clone();
    by_id.sort();
    assert_eq!(seen(&late), by_id, "the views are keyed by stroke id");
    assert_eq!(listed(a, &session).await, expected);
    assert_eq!(listed(b, &session).await, expected);
    // And the mesh bundle with placements (PMB2): the duplicate with its source's mesh bytes.
    let response = a
        .get(&format!("/v1/sessions/{}/meshes?placements=true", session.session), &session)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    let bundle =
        penmesh::protocol::decode_placed_mesh_bundle(&response.bytes().await.unwrap()).unwrap();
    let placed: Vec<(StrokeId, Vec<u8>)> =
        bundle.iter().map(|m| (m.mesh.stroke, bits(&m.placement))).collect();
    assert_eq!(placed, expected);
    assert_eq!(bundle[0].mesh.glb, bundle[1].mesh.glb);
}

/// A version-4 client: its hello, frames and strokes as version 4 has them.
struct OldClient {
    ws: penmesh_e2e::WsClient,
}

impl OldClient {
    async fn send(&mut self, msg: &ClientMessage) {
        let frame = encode_client_as(msg, 4).expect("version 4 can say it");
        self.ws.ws.send(Message::Binary(frame.into())).await.unwrap();
    }

    /// The next message; every frame carries version byte 4 and decodes as version 4.
    async fn recv(&mut self) -> ServerMessage {
        loop {
            let frame = tokio::time::timeout(std::time::Duration::from_secs(10), self.ws.ws.next())
                .await
                .expect("a frame in time")
                .expect("open")
                .unwrap();
            if let Message::Binary(bytes) = frame {
                assert_eq!(bytes[0], 4, "a frame of another version to a version-4 client");
                let msg = decode_server(&bytes, usize::MAX).unwrap();
                assert!(!matches!(msg, ServerMessage::PeerPlacement(_)), "{msg:?}");
                return msg;
            }
        }
    }

    async fn recv_until(&mut self, pred: impl Fn(&ServerMessage) -> bool) -> Vec<ServerMessage> {
        let mut seen = Vec::new();
        loop {
            let msg = self.recv().await;
            if let ServerMessage::Error(e) = &msg {
                panic!("unexpected error: {e:?}");
            }
            let done = pred(&msg);
            seen.push(msg);
            if done {
                return seen;
            }
        }
    }
}

// A version-4 client still draws (its binary stroke_begin has no placement: its strokes lie
// on the board) and watches: it sees every stroke in its own plane's coordinates, and is never
// sent a placement, neither in the history nor live.
/// A late joiner of a session whose last stroke (here its only one) is on a standing plane is
/// told that plane. Before, the history's placement event came right after that stroke's own
/// events, was taken into the stroke's whole form (`peer_strokes`, which has no placement) and
/// dropped, so the joiner showed the stroke on the board.
#[tokio::test]
async fn a_late_joiner_is_told_the_plane_of_the_last_stroke() {
    let proxies = one_or_two_replicas(|_| {}).await;
    let (a, b) = (&proxies[0], proxies.last().unwrap());
    let session = a.create_session().await;
    let mut drawer = Participant::join(a, &session, "drawer").await;
    let stroke = Uuid::new_v4();
    draw_on(&mut drawer, stroke, 0, standing()).await;
    let late = Participant::join(b, &session, "late").await;
    let told = late.view.strokes[&stroke].placement.map(|p| bits(&p));
    assert_eq!(told, Some(bits(&standing())), "the last stroke shown on the board");
}

#[tokio::test]
async fn a_version_4_client_draws_and_watches_and_is_never_sent_a_placement() {
    let proxies = one_or_two_replicas(|_| {}).await;
    let (a, b) = (&proxies[0], proxies.last().unwrap());
    let session = a.create_session().await;
    let mut drawer = Participant::join(a, &session, "drawer").await;
    let placed = Uuid::new_v4();
    draw_on(&mut drawer, placed, 0, standing()).await;

    let mut old = OldClient { ws: b.connect(&session).await };
    old.send(&ClientMessage::Hello(Hello {
        protocol: 4,
        client: "penmesh 4".into(),
        name: Some("old".into()),
        resume: vec![],
        key: Some(penmesh_e2e::new_key()),
    }))
    .await;
    let ServerMessage::Welcome(welcome) = old.recv().await else { panic!("no welcome") };
    assert_eq!(welcome.protocol, 4);
    let history = old.recv_until(|m| matches!(m, ServerMessage::Synced(_))).await;
    let strokes: Vec<StrokeId> = history
        .iter()
        .flat_map(|m| match m {
            ServerMessage::PeerStrokes(s) => s.strokes.iter().map(|s| s.stroke).collect(),
            ServerMessage::PeerStrokeBegin(b) => vec![b.stroke],
            _ => vec![],
        })
        .collect();
    assert_eq!(strokes, vec![placed], "the placed stroke, in its own plane");

    // It draws.
    let mine = Uuid::new_v4();
    let samples = samples_for(3, 40);
    old.send(&ClientMessage::StrokeBegin(StrokeBegin {
        stroke: mine,
        brush: Default::default(),
        device: None,
        params: None,
        placement: None,
        solid: None,
    }))
    .await;
    old.send(&ClientMessage::Points(Points {
        stroke: mine,
        seq: 0,
        points: PointBatch(samples.clone()),
    }))
    .await;
    old.send(&ClientMessage::StrokeEnd(StrokeEnd { stroke: mine, n_points: samples.len() as u64 }))
        .await;
    old.recv_until(|m| matches!(m, ServerMessage::StrokeDone(d) if d.stroke == mine)).await;
    drawer
        .wait_for(|v| v.strokes.get(&mine).is_some_and(|s| s.done && s.placement.is_none()))
        .await;
    let list = a.stroke_info(&session, mine).await;
    assert_eq!(list["placement"]["matrix"], serde_json::json!(Placement::IDENTITY.matrix()));

    // The drawer moves its stroke, then draws another: the old client hears of the second
    // stroke and never of the move.
    assert!(set_placement(&mut drawer, placed, moved()).await.is_ok());
    let after = Uuid::new_v4();
    draw_on(&mut drawer, after, 1, Placement::IDENTITY).await;
    let live = old
        .recv_until(|m| matches!(m, ServerMessage::PeerStrokeDone(d) if d.stroke == after))
        .await;
    assert!(live.iter().all(|m| !matches!(m, ServerMessage::PeerPlacement(_))));
}
