//! A duplicate shares its source's mesh (`strokes.mesh_of`, never a copy) and keeps showing the
//! mesh of its own solid whatever happens to the source's (issue 51): a source's solid changed,
//! a mesh built or uploaded for a source or for a duplicate, a duplicate made while its source's
//! solid changes; then taken back and brought back, nothing lost. And a page watching is told
//! the mesh of the stroke that changed, never one of a duplicate that did not. On SQLite, and on
//! PostgreSQL with `PENMESH_TEST_POSTGRES_URL`.

use penmesh::Placement;
use penmesh::protocol::{ClientMessage, KEY_HEADER, Ping, ServerMessage, StrokeId};
use penmesh_e2e::{TestProxy, TestSession, count_rows, minimal_glb, spawn_proxy};
use serde_json::{Value, json};
use uuid::Uuid;

use crate::helpers::Participant;
use crate::removal::http_removal;
use crate::solids::{circle, mesh_bytes, put_solid};

const PLATE: &str = r#"{"kind":"filled","depth":24}"#;
const WALL: &str = r#"{"kind":"line","depth":40}"#;
const HOLE: &str = r#"{"kind":"hole","depth":8}"#;

/// `POST /v1/strokes/{source}/duplicate` as `who`: the status and the new stroke (when 201).
async fn duplicate(proxy: &TestProxy, who: &TestSession, source: StrokeId) -> (u16, Value) {
    let response = proxy
        .http
        .post(proxy.url(&format!("/v1/strokes/{source}/duplicate")))
        .bearer_auth(&who.token)
        .header(KEY_HEADER, &who.key)
        .json(&json!({"placement": {"matrix": Placement::IDENTITY.matrix()}}))
        .send()
        .await
        .unwrap();
    let status = response.status().as_u16();
    (status, response.json().await.unwrap())
}

async fn duplicated(proxy: &TestProxy, who: &TestSession, source: StrokeId) -> StrokeId {
    let (status, body) = duplicate(proxy, who, source).await;
    assert_eq!(status, 201, "{body}");
    body["stroke"].as_str().unwrap().parse().unwrap()
}

/// The stroke's current solid, from its history (a stroke taken back is in it too).
async fn solid_of(proxy: &TestProxy, session: &TestSession, stroke: StrokeId) -> Value {
    let history = proxy.get_json(&format!("/v1/strokes/{stroke}/solids"), session).await;
    history["solids"].as_array().unwrap().last().unwrap()["solid"].clone()
}

fn solid(body: &str) -> Value {
    let mut solid: Value = serde_json::from_str(body).unwrap();
    solid["depth"] = json!(solid["depth"].as_f64());
    solid
}

async fn mesh_status(proxy: &TestProxy, session: &TestSession, stroke: StrokeId) -> u16 {
    let response = proxy.get(&format!("/v1/strokes/{stroke}/mesh"), session).send().await.unwrap();
    response.status().as_u16()
}

/// Every message the proxy sent `p` before a pong to a ping sent now is read.
async fn read_all(p: &mut Participant, nonce: u64) {
    p.ws.send(&ClientMessage::Ping(Ping { nonce })).await;
    p.recv_until(|m| matches!(m, ServerMessage::Pong(pong) if pong.nonce == nonce)).await;
}

// Draw, make it a plate, duplicate it three times, make the source a wall: every duplicate
// still shows the plate (the same bytes) and is a plate, the source shows the wall, and the
// plate is stored once for the three. A watching page is told the source's new mesh and
// nothing of the duplicates. Then a duplicate's own solid changes only its mesh; each stroke
// taken back and brought back (the source, the duplicates) changes nothing; the source's undo
// brings its plate back and leaves the duplicates' alone.
#[tokio::test]
async fn a_sources_new_solid_leaves_its_duplicates_showing_the_mesh_of_theirs() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ann = Participant::join(&proxy, &session, "Ann").await;
    let mut bob = Participant::join(&proxy, &session, "Bob").await;
    let drawer = TestSession { key: ann.key.clone(), ..session.clone() };
    let source = Uuid::new_v4();
    ann.draw(source, &circle(1.0), 16).await;
    assert_eq!(put_solid(&proxy, &drawer, source, PLATE).await.0, 200);
    let plate_glb = mesh_bytes(&proxy, &session, source).await;
    let mut copies = Vec::new();
    for _ in 0..3 {
        copies.push(duplicated(&proxy, &drawer, source).await);
    }
    for &copy in &copies {
        assert!(mesh_bytes(&proxy, &session, copy).await == plate_glb);
    }
    let meshes = || count_rows(&proxy.db, "SELECT COUNT(*) FROM meshes");
    assert_eq!(meshes().await, 1, "shared, not copied");
    bob.wait_for(|v| copies.iter().all(|c| v.strokes.get(c).is_some_and(|s| s.meshes == 1))).await;
    let source_meshes = bob.view.strokes[&source].meshes;

    let (status, text) = put_solid(&proxy, &drawer, source, WALL).await;
    assert_eq!(status, 200, "{text}");
    let wall_glb = mesh_bytes(&proxy, &session, source).await;
    assert_ne!(wall_glb, plate_glb, "the source's mesh is the wall's");
    // What every stroke shows and is, and the meshes stored.
    let expect = |glbs: Vec<(StrokeId, Vec<u8>, Value)>| {
        let (proxy, session) = (&proxy, &session);
        async move {
            for (stroke, glb, solid) in glbs {
                assert!(mesh_bytes(proxy, session, stroke).await == glb, "the mesh of {stroke}");
                assert_eq!(solid_of(proxy, session, stroke).await, solid, "{stroke}");
            }
        }
    };
    let plate = || copies.iter().map(|&c| (c, plate_glb.clone(), solid(PLATE))).collect();
    let now: Vec<_> = plate();
    expect([vec![(source, wall_glb.clone(), solid(WALL))], now].concat()).await;
    assert_eq!(meshes().await, 2, "the plate is kept once for the three duplicates");

    // The watching page: the source's new mesh, nothing about the duplicates.
    bob.wait_for(|v| v.strokes[&source].meshes == source_meshes + 1).await;
    read_all(&mut bob, 1).await;
    for copy in &copies {
        assert_eq!(bob.view.strokes[copy].meshes, 1, "a duplicate's mesh did not change");
        assert_eq!(bob.view.strokes[copy].solid.map(|s| s.kind().name()), Some("filled"));
    }

    // A duplicate's own solid: its own mesh; the others' and the source's stay.
    assert_eq!(put_solid(&proxy, &drawer, copies[1], HOLE).await.0, 200);
    let hole_glb = mesh_bytes(&proxy, &session, copies[1]).await;
    assert!(hole_glb != plate_glb && hole_glb != wall_glb);
    let mut all: Vec<_> = plate();
    all[1] = (copies[1], hole_glb.clone(), solid(HOLE));
    all.push((source, wall_glb.clone(), solid(WALL)));
    expect(all.clone()).await;
    assert_eq!(meshes().await, 3);

    // Each taken back and brought back (the source, the duplicate that keeps the plate's row,
    // whichever it is): nothing lost.
    for stroke in [source, copies[0], copies[1], copies[2]] {
        assert_eq!(http_removal(&proxy, &drawer, stroke, true).await, 204);
        expect(all.clone()).await;
        assert_eq!(http_removal(&proxy, &drawer, stroke, false).await, 204);
    }
    expect(all.clone()).await;

    // The source's undo: a plate again, and the duplicates' meshes as they were.
    assert_eq!(put_solid(&proxy, &drawer, source, PLATE).await.0, 200);
    let again = mesh_bytes(&proxy, &session, source).await;
    assert_eq!(again.len(), plate_glb.len(), "the plate's mesh again");
    all[3] = (source, again, solid(PLATE));
    expect(all).await;
}

// The same rule for a mesh stored any other way: one built or uploaded for a source replaces
// what its duplicates of the same solid show (a duplicate made before its source had a mesh
// gets it), and a watching page is told of each; one uploaded for a duplicate is that
// duplicate's own, the source's untouched.
#[tokio::test]
async fn a_mesh_built_or_uploaded_follows_the_same_rule_for_duplicates() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ann = Participant::join(&proxy, &session, "Ann").await;
    let mut bob = Participant::join(&proxy, &session, "Bob").await;
    let drawer = TestSession { key: ann.key.clone(), ..session.clone() };
    let source = Uuid::new_v4();
    ann.draw(source, &circle(1.0), 16).await;
    let early = duplicated(&proxy, &drawer, source).await;
    assert_eq!(mesh_status(&proxy, &session, early).await, 404, "no mesh yet");

    // Built for the source: its duplicate of the same solid shows it, and a watching page is
    // told so (a `peer_mesh` of the duplicate).
    assert_eq!(proxy.build_mesh(&drawer, source).send().await.unwrap().status(), 200);
    let built = mesh_bytes(&proxy, &session, source).await;
    assert!(mesh_bytes(&proxy, &session, early).await == built);
    bob.wait_for(|v| v.strokes.get(&early).is_some_and(|s| s.meshes == 1)).await;

    // Uploaded for the source (the same solid): the duplicate follows, told again.
    let upload = minimal_glb(3, 3);
    assert_eq!(proxy.put_mesh(&drawer, source, upload.clone()).send().await.unwrap().status(), 200);
    assert!(mesh_bytes(&proxy, &session, source).await == upload);
    assert!(mesh_bytes(&proxy, &session, early).await == upload);
    bob.wait_for(|v| v.strokes.get(&early).is_some_and(|s| s.meshes == 2)).await;

    // Uploaded for the duplicate: its own, shown; the source's stays.
    let own = minimal_glb(4, 6);
    assert_ne!(own, upload);
    assert_eq!(proxy.put_mesh(&drawer, early, own.clone()).send().await.unwrap().status(), 200);
    assert!(mesh_bytes(&proxy, &session, early).await == own, "the duplicate's upload");
    assert!(mesh_bytes(&proxy, &session, source).await == upload);
    let later = duplicated(&proxy, &drawer, early).await;
    assert!(mesh_bytes(&proxy, &session, later).await == own, "a duplicate of it shares it");
    assert_eq!(count_rows(&proxy.db, "SELECT COUNT(*) FROM meshes").await, 2);
}

// A duplicate made while its source's solid changes, round after round: each duplicate made
// shows the mesh of the solid it is (the bytes the proxy builds for that solid alone), or is
// refused, naming the change, and stores nothing.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_duplicate_racing_its_sources_solid_change_shows_the_mesh_of_its_own_solid() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ann = Participant::join(&proxy, &session, "Ann").await;
    let drawer = TestSession { key: ann.key.clone(), ..session.clone() };
    let source = Uuid::new_v4();
    ann.draw(source, &circle(1.0), 16).await;
    let mut alone = std::collections::HashMap::new();
    for body in [PLATE, WALL] {
        assert_eq!(put_solid(&proxy, &drawer, source, body).await.0, 200);
        alone.insert(solid(body).to_string(), mesh_bytes(&proxy, &session, source).await);
    }
    let (mut made, mut refused) = (Vec::new(), 0);
    for round in 0..40 {
        let body = if round % 2 == 0 { PLATE } else { WALL };
        let (dup, set) = tokio::join!(
            duplicate(&proxy, &drawer, source),
            put_solid(&proxy, &drawer, source, body)
        );
        assert_eq!(set.0, 200, "round {round}: {set:?}");
        match dup {
            (201, copy) => made.push(copy["stroke"].as_str().unwrap().parse::<Uuid>().unwrap()),
            (409, why) => {
                assert!(why["message"].as_str().unwrap().contains("while it was being duplicated"));
                refused += 1;
            }
            other => panic!("round {round}: {other:?}"),
        }
    }
    // Every duplicate, against what the source does afterwards too.
    assert_eq!(put_solid(&proxy, &drawer, source, HOLE).await.0, 200);
    for copy in &made {
        let is = solid_of(&proxy, &session, *copy).await;
        assert!(
            mesh_bytes(&proxy, &session, *copy).await == alone[&is.to_string()],
            "duplicate {copy} is {is} but shows another solid's mesh"
        );
    }
    let strokes = count_rows(&proxy.db, "SELECT COUNT(*) FROM strokes").await;
    assert_eq!(strokes as usize, 1 + made.len(), "a refused duplicate stored nothing");
    eprintln!("{} duplicates made, {refused} refused as their source changed", made.len());
}
