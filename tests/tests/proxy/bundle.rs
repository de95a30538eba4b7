//! The mesh bundle's `PMB3` layout (`GET /v1/sessions/{id}/meshes?layout=PMB3`): each stored
//! mesh once, however many duplicates show it (issue 49, item 10), and every stroke with its
//! placement and solid (issue 51), so a page opens a session with a hole drawn as one. The
//! older layouts stay served; a layout there is none of is a 400 naming it.

use penmesh::protocol::{
    BUNDLED_STROKE_BYTES, KEY_HEADER, MESH_BUNDLE_CONTENT_TYPE, MeshTableBundle,
    decode_mesh_table_bundle, decode_placed_mesh_bundle,
};
use penmesh::{Placement, Solid, SolidKind};
use penmesh_e2e::{TestProxy, TestSession, draw_stroke, plain_glb, spawn_proxy, stroke_samples};
use serde_json::{Value, json};
use uuid::Uuid;

/// The session's strokes as listed (`GET …/strokes`): id, placement, solid, in the history's order.
async fn listed(proxy: &TestProxy, session: &TestSession) -> Vec<(Uuid, Placement, Solid)> {
    let list = proxy.get_json(&format!("/v1/sessions/{}/strokes", session.session), session).await;
    list["strokes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            (
                s["id"].as_str().unwrap().parse().unwrap(),
                serde_json::from_value(s["placement"].clone()).unwrap(),
                serde_json::from_value(s["solid"].clone()).unwrap(),
            )
        })
        .collect()
}

fn moved(dx: f64) -> Value {
    let mut m = *Placement::IDENTITY.matrix();
    m[12] = dx;
    m[13] = -dx / 2.0;
    json!({ "matrix": m })
}

async fn bundle(proxy: &TestProxy, session: &TestSession, query: &str) -> reqwest::Response {
    let path = format!("/v1/sessions/{}/meshes{query}", session.session);
    proxy.get(&path, session).send().await.unwrap()
}

/// `POST …/duplicate` of `source` at `placement`: the new stroke's id.
async fn duplicate(proxy: &TestProxy, who: &TestSession, source: Uuid, placement: Value) -> Uuid {
    let response = proxy
        .http
        .post(proxy.url(&format!("/v1/strokes/{source}/duplicate")))
        .bearer_auth(&who.token)
        .header(KEY_HEADER, &who.key)
        .json(&json!({ "placement": placement }))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 201);
    response.json::<Value>().await.unwrap()["stroke"].as_str().unwrap().parse().unwrap()
}

#[tokio::test]
async fn a_table_bundle_sends_each_mesh_once_with_every_strokes_placement_and_solid() {
    const DUPLICATES: usize = 30;
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    // A stroke with a 240 KB mesh and its duplicates, each placed apart.
    let source = Uuid::new_v4();
    draw_stroke(&mut ws, source, &stroke_samples(40), 20).await;
    let glb = plain_glb(10_000);
    assert_eq!(proxy.put_mesh(&session, source, glb.clone()).send().await.unwrap().status(), 200);
    let mut copies = Vec::new();
    for k in 0..DUPLICATES {
        copies.push(duplicate(&proxy, &session, source, moved(50.0 * (k + 1) as f64)).await);
    }
    // A stroke made a hole (the proxy builds its mesh) and a duplicate of it, which keeps it.
    let hole = Uuid::new_v4();
    draw_stroke(&mut ws, hole, &stroke_samples(60), 20).await;
    let response = proxy
        .http
        .put(proxy.url(&format!("/v1/strokes/{hole}/solid")))
        .bearer_auth(&session.token)
        .header(KEY_HEADER, &session.key)
        .json(&json!({"kind": "hole", "depth": 24.0}))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    let hole_copy = duplicate(&proxy, &session, hole, moved(-40.0)).await;
    // A duplicate taken back is not in the bundle; its mesh, still shown by others, is.
    let taken_back = copies.pop().unwrap();
    let response = proxy
        .http
        .delete(proxy.url(&format!("/v1/strokes/{taken_back}")))
        .bearer_auth(&session.token)
        .header(KEY_HEADER, &session.key)
        .send()
        .await
        .unwrap();
    assert!(response.status().is_success(), "{}", response.status());

    let response = bundle(&proxy, &session, "?layout=PMB3").await;
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], MESH_BUNDLE_CONTENT_TYPE);
    let etag = response.headers()["etag"].to_str().unwrap().to_string();
    let body = response.bytes().await.unwrap();
    let MeshTableBundle { meshes, strokes } = decode_mesh_table_bundle(&body).unwrap();

    // Two meshes, each once: the body is about one mesh, the hole's and a header per stroke.
    let hole_glb = proxy.get(&format!("/v1/strokes/{hole}/mesh"), &session).send().await;
    let hole_glb = hole_glb.unwrap().bytes().await.unwrap().to_vec();
    assert_eq!(meshes, vec![glb.clone(), hole_glb.clone()]);
    let n_strokes = 1 + (DUPLICATES - 1) + 2;
    assert_eq!(
        body.len(),
        12 + (4 + glb.len()) + (4 + hole_glb.len()) + n_strokes * BUNDLED_STROKE_BYTES
    );
    // Every stroke the list has, in its order, with its placement, its solid and its mesh.
    let expected = listed(&proxy, &session).await;
    let got: Vec<(Uuid, Placement, Solid)> =
        strokes.iter().map(|s| (s.stroke, s.placement, s.solid)).collect();
    assert_eq!(got, expected);
    let ids: Vec<Uuid> = strokes.iter().map(|s| s.stroke).collect();
    let mut wanted = vec![source];
    wanted.extend(&copies);
    wanted.extend([hole, hole_copy]);
    assert_eq!(ids, wanted);
    let hole_solid = Solid::new(SolidKind::Hole, Some(24.0)).unwrap();
    for s in &strokes {
        let (mesh, solid) =
            if [hole, hole_copy].contains(&s.stroke) { (1, hole_solid) } else { (0, Solid::ROD) };
        assert_eq!((s.mesh, s.solid), (mesh, solid), "stroke {}", s.stroke);
        let own = proxy.get(&format!("/v1/strokes/{}/mesh", s.stroke), &session).send().await;
        assert_eq!(own.unwrap().bytes().await.unwrap(), meshes[s.mesh as usize], "{}", s.stroke);
    }

    // Gzipped, the same bundle; its own tag; a 304 for a copy that is current.
    let gzipped =
        proxy.get(&format!("/v1/sessions/{}/meshes?layout=PMB3", session.session), &session);
    let gzipped = gzipped.header("accept-encoding", "gzip").send().await.unwrap();
    assert_eq!(gzipped.headers()["content-encoding"], "gzip");
    assert_ne!(gzipped.headers()["etag"], etag.as_str());
    let mut unzipped = Vec::new();
    let zipped = gzipped.bytes().await.unwrap();
    std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(&zipped[..]), &mut unzipped)
        .unwrap();
    assert_eq!(unzipped, body);
    let path = format!("/v1/sessions/{}/meshes?layout=PMB3", session.session);
    let again = proxy.get(&path, &session).header("if-none-match", &etag).send().await.unwrap();
    assert_eq!(again.status(), 304);

    // The older layouts are still served, a mesh per stroke: PMB2 repeats the shared mesh.
    let placed = bundle(&proxy, &session, "?placements=true").await.bytes().await.unwrap();
    let placed = decode_placed_mesh_bundle(&placed).unwrap();
    assert_eq!(placed.len(), n_strokes);
    assert!(placed.iter().filter(|m| m.mesh.glb == glb).count() == DUPLICATES);
    let same = bundle(&proxy, &session, "?layout=PMB2").await.bytes().await.unwrap();
    assert_eq!(decode_placed_mesh_bundle(&same).unwrap(), placed);

    // A duplicate moved changes the table's tag.
    let response = proxy
        .http
        .put(proxy.url(&format!("/v1/strokes/{}/placement", copies[0])))
        .bearer_auth(&session.token)
        .header(KEY_HEADER, &session.key)
        .json(&moved(7.0))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 204);
    let moved_on = proxy.get(&path, &session).header("if-none-match", &etag).send().await.unwrap();
    assert_eq!(moved_on.status(), 200);
    let moved_on = decode_mesh_table_bundle(&moved_on.bytes().await.unwrap()).unwrap();
    assert_eq!(moved_on.strokes[1].placement, serde_json::from_value(moved(7.0)).unwrap());

    // A layout there is none of, or two asked at once: 400 naming it.
    for (query, names) in [
        ("?layout=PMB9", "layout: unknown variant `PMB9`"),
        ("?placements=true&layout=PMB3", "placements=true asks for the PMB2 layout"),
    ] {
        let response = bundle(&proxy, &session, query).await;
        assert_eq!(response.status(), 400, "{query}");
        let message = response.json::<Value>().await.unwrap()["message"].to_string();
        assert!(message.contains(names), "{query}: {message}");
    }
    // An empty session: an empty table.
    let empty = proxy.create_session().await;
    let body = bundle(&proxy, &empty, "?layout=PMB3").await.bytes().await.unwrap();
    assert_eq!(decode_mesh_table_bundle(&body).unwrap(), MeshTableBundle::default());
}
