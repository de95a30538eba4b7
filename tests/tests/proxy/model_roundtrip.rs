//! The scene export and import (issue 39, `docs/model-format.md`): a 3D session (strokes on
//! three planes, one moved, one mirrored, one duplicated) exported as GLB, imported into a new
//! session, exported again gives the same samples, brushes and placements, bit for bit; the
//! importer is the drawer and the original author is kept; others see the strokes live. Every
//! bad import is refused naming what is wrong, with nothing stored.

use penmesh::protocol::{KEY_HEADER, ServerMessage};
use penmesh::{ReadStroke, Sample, read_scene};
use penmesh_e2e::penmesh_proxy::{CommitFaults, Fault};
use penmesh_e2e::{
    TestDatabase, TestProxy, TestSession, count_rows, draw_stroke, spawn_faulty_proxy_on,
    spawn_proxy, spawn_proxy_with, stroke_samples,
};
use serde_json::{Value, json};
use uuid::Uuid;

/// Column-major matrices: a quarter turn about y (the plane x = 0), a quarter turn about x
/// (the plane y = 0) moved, and a mirror in x, scaled by 1.5.
const UPRIGHT_X: [f64; 16] =
    [0.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
const UPRIGHT_Y: [f64; 16] =
    [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
const MOVED_Y: [f64; 16] =
    [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 40.5, -12.25, 30.0, 1.0];
const MIRRORED: [f64; 16] =
    [-1.5, 0.0, 0.0, 0.0, 0.0, 1.5, 0.0, 0.0, 0.0, 0.0, 1.5, 0.0, 300.0, 0.0, 0.0, 1.0];

async fn put_placement(proxy: &TestProxy, session: &TestSession, stroke: Uuid, m: [f64; 16]) {
    let response = proxy
        .http
        .put(proxy.url(&format!("/v1/strokes/{stroke}/placement")))
        .bearer_auth(&session.token)
        .header(KEY_HEADER, &session.key)
        .json(&json!({ "matrix": m }))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 204);
}

/// `GET …/export?format=glb` of the session, asserting 200.
async fn export_glb(proxy: &TestProxy, session: &TestSession) -> Vec<u8> {
    let path = format!("/v1/sessions/{}/export?format=glb&size_mm=120", session.session);
    let response = proxy.get(&path, session).send().await.unwrap();
    assert_eq!(response.status(), 200, "{}", response.text().await.unwrap());
    assert_eq!(response.headers()["content-type"], "model/gltf-binary");
    response.bytes().await.unwrap().to_vec()
}

/// `POST …/import` of `glb` as the session's participant: the status and the body.
async fn import(proxy: &TestProxy, session: &TestSession, glb: Vec<u8>) -> (u16, Value) {
    let response = proxy
        .http
        .post(proxy.url(&format!("/v1/sessions/{}/import?name=Imogen", session.session)))
        .bearer_auth(&session.token)
        .header(KEY_HEADER, &session.key)
        .header("content-type", "model/gltf-binary")
        .body(glb)
        .send()
        .await
        .unwrap();
    let status = response.status().as_u16();
    (status, response.json().await.unwrap())
}

/// A 3D session of four drawn strokes and a duplicate, each with a mesh.
async fn three_d_session(proxy: &TestProxy) -> (TestSession, Vec<Uuid>) {
    let session = proxy.create_session().await;
    let mut drawer = proxy.connect(&session).await;
    drawer.hello(vec![]).await;
    let mut ids = Vec::new();
    for (i, n) in [120, 200, 90, 150].into_iter().enumerate() {
        let samples: Vec<Sample> = stroke_samples(n)
            .into_iter()
            .map(|s| {
                penmesh::protocol::quantize_sample(&Sample::new(
                    s.x,
                    s.y + 40.0 * i as f64,
                    s.t,
                    s.p,
                ))
            })
            .collect();
        let id = Uuid::new_v4();
        draw_stroke(&mut drawer, id, &samples, 50).await;
        let built = proxy.build_mesh(&session, id).send().await.unwrap();
        assert_eq!(built.status(), 200);
        ids.push(id);
    }
    put_placement(proxy, &session, ids[1], UPRIGHT_X).await;
    put_placement(proxy, &session, ids[2], UPRIGHT_Y).await;
    put_placement(proxy, &session, ids[2], MOVED_Y).await;
    put_placement(proxy, &session, ids[3], MIRRORED).await;
    let duplicate = proxy
        .http
        .post(proxy.url(&format!("/v1/strokes/{}/duplicate", ids[0])))
        .bearer_auth(&session.token)
        .header(KEY_HEADER, &session.key)
        .json(&json!({ "placement": { "matrix": UPRIGHT_X } }))
        .send()
        .await
        .unwrap();
    assert_eq!(duplicate.status(), 201);
    let duplicate: Value = duplicate.json().await.unwrap();
    ids.push(duplicate["stroke"].as_str().unwrap().parse().unwrap());
    (session, ids)
}

/// What must survive a round trip: the samples, the brush and the placement, bit for bit.
fn pen_data(stroke: &ReadStroke) -> (Vec<[u64; 4]>, penmesh::Brush, [u64; 16]) {
    let samples =
        stroke.extras.samples.iter().map(|s| [s.x, s.y, s.t, s.p].map(f64::to_bits)).collect();
    (samples, stroke.extras.brush, stroke.placement.map(f64::to_bits))
}

#[tokio::test]
async fn a_3d_session_exported_imported_and_exported_again_has_the_same_pen_data() {
    let proxy = spawn_proxy().await;
    let (first, ids) = three_d_session(&proxy).await;
    let glb = export_glb(&proxy, &first).await;
    let exported = read_scene(&glb).unwrap();
    assert_eq!(exported.len(), 5);
    let by_id = |id: Uuid| exported.iter().find(|s| s.extras.stroke == id).unwrap();
    assert_eq!(by_id(ids[2]).placement, MOVED_Y, "the moved stroke's latest placement");
    assert_eq!(by_id(ids[3]).placement, MIRRORED);
    assert_eq!(by_id(ids[4]).extras.duplicate_of, Some(ids[0]));
    let simplified = proxy.get_json(&format!("/v1/strokes/{}/simplified", ids[1]), &first).await;
    let stored: Vec<Sample> = serde_json::from_value(simplified["samples"].clone()).unwrap();
    assert_eq!(by_id(ids[1]).extras.samples, stored, "the simplified samples as stored");

    // A new session, with someone watching it live.
    let second = proxy.create_session().await;
    let mut watcher = proxy.connect(&second.stranger()).await;
    watcher.hello(vec![]).await;
    let (status, body) = import(&proxy, &second, glb.clone()).await;
    assert_eq!(status, 201, "{body}");
    let imported = body["strokes"].as_array().unwrap();
    assert_eq!(imported.len(), 5);
    let mut done = 0;
    while done < 5 {
        match watcher.recv_any().await {
            ServerMessage::PeerStrokeDone(_) => done += 1,
            ServerMessage::PeerStrokes(whole) => done += whole.strokes.len(),
            _ => {}
        }
    }

    // The importer is the drawer; the author it came from is kept.
    let importer = penmesh_proxy::participant_id(second.session, &second.key);
    let again = read_scene(&export_glb(&proxy, &second).await).unwrap();
    assert_eq!(again.len(), 5);
    for original in &exported {
        let copy = again
            .iter()
            .find(|s| {
                s.extras.imported_from.as_ref().map(|f| f.stroke) == Some(original.extras.stroke)
            })
            .unwrap_or_else(|| panic!("stroke {} was not imported", original.extras.stroke));
        assert_eq!(pen_data(copy), pen_data(original), "stroke {}", original.extras.stroke);
        assert_eq!(copy.extras.author.participant, importer);
        assert_eq!(copy.extras.author.name, "Imogen");
        let from = copy.extras.imported_from.as_ref().unwrap();
        assert_eq!(from.author, original.extras.author);
        assert_eq!(from.drawn_at, original.extras.drawn_at);
        let info = proxy.stroke_info(&second, copy.extras.stroke).await;
        assert_eq!(info["participant"], importer.to_string());
        assert_eq!(info["has_mesh"], true, "its mesh is built as for the page");
    }

    // The duplicate and its source came in the same file: the new duplicate names the new
    // source.
    let copy_of = |id: Uuid| {
        again
            .iter()
            .find(|s| s.extras.imported_from.as_ref().map(|f| f.stroke) == Some(id))
            .unwrap()
            .extras
            .stroke
    };
    let new_duplicate = again.iter().find(|s| s.extras.stroke == copy_of(ids[4])).unwrap();
    assert_eq!(new_duplicate.extras.duplicate_of, Some(copy_of(ids[0])));
    let plain = again.iter().filter(|s| s.extras.duplicate_of.is_none()).count();
    assert_eq!(plain, 4, "only the duplicate is one");
    // The duplicate alone: its source is not in the file, so it comes in as a plain stroke.
    let alone = proxy.create_session().await;
    let path = format!("/v1/sessions/{}/export?format=glb&strokes={}", first.session, ids[4]);
    let response = proxy.get(&path, &first).send().await.unwrap();
    assert_eq!(response.status(), 200);
    let (status, body) = import(&proxy, &alone, response.bytes().await.unwrap().to_vec()).await;
    assert_eq!(status, 201, "{body}");
    let single = read_scene(&export_glb(&proxy, &alone).await).unwrap();
    assert_eq!(single.len(), 1);
    assert_eq!(single[0].extras.duplicate_of, None);

    // Imported once more: the first origin stays.
    let third = proxy.create_session().await;
    let (status, body) = import(&proxy, &third, export_glb(&proxy, &second).await).await;
    assert_eq!(status, 201, "{body}");
    let thrice = read_scene(&export_glb(&proxy, &third).await).unwrap();
    for copy in &thrice {
        let from = copy.extras.imported_from.as_ref().unwrap();
        assert!(exported.iter().any(|s| s.extras.stroke == from.stroke), "{from:?}");
    }
}

/// The GLB with its JSON chunk changed by `edit` (the BIN chunk kept).
fn edited(glb: &[u8], edit: impl FnOnce(&mut Value)) -> Vec<u8> {
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut json: Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    edit(&mut json);
    let mut text = serde_json::to_vec(&json).unwrap();
    text.resize(text.len().next_multiple_of(4), b' ');
    let bin = &glb[20 + json_len..];
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + 8 + text.len() + bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    out.extend_from_slice(bin);
    out
}

/// The `n`th stroke node's `extras.penmesh`.
fn stroke_extras(json: &mut Value, n: usize) -> &mut Value {
    json["nodes"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .filter(|node| node["extras"]["penmesh"].is_object())
        .nth(n)
        .unwrap()
        .get_mut("extras")
        .unwrap()
        .get_mut("penmesh")
        .unwrap()
}

async fn strokes_of(db: &TestDatabase, session: &TestSession) -> i64 {
    count_rows(
        db,
        &format!("SELECT COUNT(*) FROM strokes WHERE session_id = '{}'", session.session),
    )
    .await
}

#[tokio::test]
async fn bad_imports_are_refused_naming_what_is_wrong_and_store_nothing() {
    let proxy = spawn_proxy_with(|config| config.max_body_bytes = 512 * 1024).await;
    let (first, ids) = three_d_session(&proxy).await;
    let glb = export_glb(&proxy, &first).await;
    let target = proxy.create_session().await;
    let stored_mesh = proxy.get(&format!("/v1/strokes/{}/mesh", ids[0]), &first).send().await;
    let stored_mesh = stored_mesh.unwrap().bytes().await.unwrap().to_vec();
    // The last stroke bad, the others good: all or nothing.
    let last_bad = |edit: fn(&mut Value)| edited(&glb, |json| edit(stroke_extras(json, 4)));
    let cases: Vec<(&str, Vec<u8>, u16, &str)> = vec![
        ("a stroke's own mesh, no extras", stored_mesh, 400, "no penmesh strokes in the file"),
        ("truncated", glb[..glb.len() / 2].to_vec(), 400, "truncated"),
        ("not a GLB", b"solid cube\nendsolid".to_vec(), 400, "not a GLB"),
        ("oversized", vec![0; 600 * 1024], 413, "at most 524288"),
        ("a pressure of 1.5", last_bad(|e| e["samples"][1][3] = json!(1.5)), 400, "pressure 1.5"),
        (
            "time going back",
            last_bad(|e| e["samples"][2][2] = json!(-1.0)),
            400,
            "time goes backwards",
        ),
        (
            "off the grid",
            last_bad(|e| e["samples"][0][0] = json!(0.01)),
            400,
            "not on penmesh's grid",
        ),
        ("no samples", last_bad(|e| e["samples"] = json!([])), 400, "no samples"),
        ("a bad brush", last_bad(|e| e["brush"]["size"] = json!(-3.0)), 400, "its brush"),
        ("another format", last_bad(|e| e["format"] = json!(99)), 400, "format 99"),
        // What the review of issue 49 found stored (its low items).
        (
            "its own duplicate",
            last_bad(|e| e["duplicate_of"] = e["stroke"].clone()),
            400,
            "names itself as the stroke it duplicates",
        ),
        (
            "a 100k-character author name",
            last_bad(|e| e["author"]["name"] = json!("a".repeat(100_000))),
            400,
            "its author's name is 100000 characters",
        ),
        (
            "a NUL in the author's name",
            last_bad(|e| e["author"]["name"] = json!("Ad\u{0}a")),
            400,
            "its author's name holds a NUL byte",
        ),
        (
            "drawn at i64::MIN",
            last_bad(|e| e["drawn_at"] = json!(i64::MIN)),
            400,
            "drawn_at = -9223372036854775808",
        ),
        ("a nil id", last_bad(|e| e["stroke"] = json!(Uuid::nil())), 400, "the nil UUID"),
        (
            "a missing field",
            last_bad(|e| {
                e.as_object_mut().unwrap().remove("brush");
            }),
            400,
            "missing field `brush`",
        ),
        (
            "a shear",
            edited(&glb, |json| {
                let node = json["nodes"]
                    .as_array_mut()
                    .unwrap()
                    .iter_mut()
                    .filter(|n| n["extras"]["penmesh"].is_object())
                    .nth(4)
                    .unwrap();
                node["matrix"] = json!([1, 0, 0, 0, 0.5, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);
            }),
            400,
            "not a similarity",
        ),
        (
            "a translation far past any model",
            edited(&glb, |json| {
                let node = json["nodes"]
                    .as_array_mut()
                    .unwrap()
                    .iter_mut()
                    .filter(|n| n["extras"]["penmesh"].is_object())
                    .nth(4)
                    .unwrap();
                node["matrix"] = json!([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 1e30, 0, 0, 1]);
            }),
            400,
            "a translation (elements 12, 13, 14) is at most 1e9 px",
        ),
    ];
    for (what, body, code, text) in cases {
        let (status, answer) = import(&proxy, &target, body).await;
        assert_eq!(status, code, "{what}: {answer}");
        let message = answer["message"].as_str().unwrap_or_default();
        assert!(message.contains(text), "{what}: {message}");
        assert_eq!(strokes_of(&proxy.db, &target).await, 0, "{what}: nothing stored");
    }
    // No participant key: no drawer (403, as on every route that needs a key).
    let response = proxy
        .http
        .post(proxy.url(&format!("/v1/sessions/{}/import", target.session)))
        .bearer_auth(&target.token)
        .body(glb.clone())
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 403);
    assert!(response.text().await.unwrap().contains(KEY_HEADER));
    // Another session's token: 401.
    let response = proxy
        .http
        .post(proxy.url(&format!("/v1/sessions/{}/import", target.session)))
        .bearer_auth(&first.token)
        .header(KEY_HEADER, &target.key)
        .body(glb.clone())
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 401);
    assert_eq!(strokes_of(&proxy.db, &target).await, 0);
    // The good file is taken whole.
    let (status, answer) = import(&proxy, &target, glb).await;
    assert_eq!(status, 201, "{answer}");
    assert_eq!(strokes_of(&proxy.db, &target).await, 5);
}

#[tokio::test]
async fn an_import_past_the_session_mesh_quota_stores_nothing() {
    let proxy = spawn_proxy_with(|config| config.max_session_mesh_bytes = 40_000).await;
    let session = proxy.create_session().await;
    let mut drawer = proxy.connect(&session).await;
    drawer.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    draw_stroke(&mut drawer, stroke, &stroke_samples(200), 50).await;
    assert_eq!(proxy.build_mesh(&session, stroke).send().await.unwrap().status(), 200);
    let glb = export_glb(&proxy, &session).await;
    // The same session already holds that mesh; ten copies of it do not fit.
    let many = edited(&glb, |json| {
        let nodes = json["nodes"].as_array_mut().unwrap();
        let node = nodes.iter().find(|n| n["extras"]["penmesh"].is_object()).unwrap().clone();
        for _ in 0..30 {
            nodes.push(node.clone());
        }
    });
    let (status, answer) = import(&proxy, &session, many).await;
    assert_eq!(status, 413, "{answer}");
    assert_eq!(answer["error"], "quota_exceeded");
    assert!(answer["message"].as_str().unwrap().contains("nothing imported"), "{answer}");
    assert_eq!(strokes_of(&proxy.db, &session).await, 1);
}

#[tokio::test]
async fn a_storage_failure_during_an_import_stores_nothing_and_a_lost_mesh_loses_no_stroke() {
    let faults = CommitFaults::new();
    let proxy =
        spawn_faulty_proxy_on(TestDatabase::fresh().await, Some(faults.clone()), |_| {}).await;
    let (first, _) = three_d_session(&proxy).await;
    let glb = export_glb(&proxy, &first).await;
    let target = proxy.create_session().await;

    // The strokes' one transaction fails: the import fails, nothing is stored.
    faults.fail_transaction(1, Fault::Fail);
    let (status, answer) = import(&proxy, &target, glb.clone()).await;
    assert_eq!(status, 500, "{answer}");
    assert_eq!(strokes_of(&proxy.db, &target).await, 0, "all or nothing");

    // The strokes commit, then the first mesh's write fails: the import has happened and says
    // so; every stroke is stored, that one without its mesh.
    faults.fail_transaction(2, Fault::Fail);
    let (status, answer) = import(&proxy, &target, glb).await;
    assert_eq!(status, 201, "{answer}");
    let strokes = answer["strokes"].as_array().unwrap();
    assert_eq!(strokes.len(), 5);
    assert_eq!(strokes_of(&proxy.db, &target).await, 5);
    let mut meshless = 0;
    for stroke in strokes {
        let id: Uuid = stroke["stroke"].as_str().unwrap().parse().unwrap();
        let info = proxy.stroke_info(&target, id).await;
        assert_eq!(info["status"], "done");
        if info["has_mesh"] == false {
            meshless += 1;
        }
    }
    assert_eq!(meshless, 1, "only the mesh whose write failed is missing");
}
