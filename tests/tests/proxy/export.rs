//! The print export (`GET /v1/sessions/{id}/export`, issue 39): a session's done strokes as one
//! STL or 3MF that PrusaSlicer reads as one manifold, its longest side `size_mm`; bad requests
//! answered naming what is wrong; a print longer than its request kept for the retry, and never
//! served for a model that has changed (issue 49, item 7).

use std::process::Command;
use std::time::{Duration, Instant};

use base64::Engine as _;
use penmesh::protocol::KEY_HEADER;
use penmesh_e2e::{
    TestProxy, TestSession, draw_stroke, execute_sql, spawn_proxy, spawn_proxy_with, stroke_samples,
};
use serde_json::{Value, json};
use uuid::Uuid;

/// PrusaSlicer's `--info` of `bytes` written as `name`, as text.
fn slicer_info(name: &str, bytes: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join(name);
    std::fs::write(&file, bytes).unwrap();
    let out = Command::new("prusa-slicer")
        .args(["--loglevel", "1", "--info"])
        .arg(&file)
        .output()
        .unwrap();
    assert!(out.status.success(), "prusa-slicer --info {name}");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[tokio::test]
async fn a_session_exports_as_one_manifold_stl_and_3mf() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut drawer = proxy.connect(&session).await;
    drawer.hello(vec![]).await;
    let samples = stroke_samples(300);
    // Two strokes crossing: the second is the first turned a quarter round its middle.
    let crossing: Vec<_> = samples
        .iter()
        .map(|s| {
            penmesh::protocol::quantize_sample(&penmesh::Sample::new(
                225.0 - s.y,
                s.x - 225.0,
                s.t,
                s.p,
            ))
        })
        .collect();
    let (first, second) = (Uuid::new_v4(), Uuid::new_v4());
    draw_stroke(&mut drawer, first, &samples, 50).await;
    draw_stroke(&mut drawer, second, &crossing, 50).await;

    let path = format!("/v1/sessions/{}/export?format=stl&size_mm=80", session.session);
    let response = proxy.get(&path, &session).send().await.unwrap();
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], "model/stl");
    let stl = response.bytes().await.unwrap();
    let info = slicer_info("session.stl", &stl);
    assert!(info.contains("manifold = yes"), "{info}");
    assert!(info.contains("number_of_parts =  1"), "{info}");
    assert!(info.contains("size_x = 80.000000") || info.contains("size_y = 80.000000"), "{info}");

    // One of them alone, as 3MF.
    let path = format!("/v1/sessions/{}/export?format=3mf&strokes={first}", session.session);
    let response = proxy.get(&path, &session).send().await.unwrap();
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], "model/3mf");
    let info = slicer_info("one.3mf", &response.bytes().await.unwrap());
    assert!(info.contains("manifold = yes") && info.contains("size_x = 100.000000"), "{info}");
}

#[tokio::test]
async fn bad_export_requests_are_refused_naming_what_is_wrong() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let base = format!("/v1/sessions/{}/export", session.session);
    let answer = |query: &str| {
        let request = proxy.get(&format!("{base}?{query}"), &session);
        async move {
            let response = request.send().await.unwrap();
            let status = response.status().as_u16();
            let body: serde_json::Value = response.json().await.unwrap();
            (status, body["message"].as_str().unwrap_or_default().to_owned())
        }
    };
    let (status, body) = answer("format=stl").await;
    assert_eq!(status, 409, "{body}");
    assert!(body.contains("no done stroke"), "{body}");
    let mut drawer = proxy.connect(&session).await;
    drawer.hello(vec![]).await;
    draw_stroke(&mut drawer, Uuid::new_v4(), &stroke_samples(100), 50).await;
    for (query, code, text) in [
        ("format=obj", 400, "format=\"obj\""),
        ("format=stl&size_mm=-5", 400, "size_mm = -5"),
        ("format=stl&min_thickness_mm=40", 400, "min_thickness_mm = 40"),
        ("format=stl&strokes=nope", 400, "\"nope\" is not a stroke id"),
        (
            "format=stl&strokes=00000000-0000-0000-0000-000000000001",
            404,
            "is not a stroke of this session",
        ),
    ] {
        let (status, body) = answer(query).await;
        assert_eq!(status, code, "{query}: {body}");
        assert!(body.contains(text), "{query}: {body}");
    }
    let response = proxy.http.get(proxy.url(&format!("{base}?format=stl"))).send().await.unwrap();
    assert_eq!(response.status(), 401);
}

#[tokio::test]
async fn a_scene_is_exported_while_a_print_is_being_made() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut drawer = proxy.connect(&session).await;
    drawer.hello(vec![]).await;
    // Enough long strokes that the print takes a while.
    for i in 0..24 {
        let samples: Vec<_> = stroke_samples(400)
            .into_iter()
            .map(|s| {
                let (dx, dy) = (f64::from(i % 6) * 60.0, f64::from(i / 6) * 60.0);
                penmesh::protocol::quantize_sample(&penmesh::Sample::new(
                    s.x + dx,
                    s.y + dy,
                    s.t,
                    s.p,
                ))
            })
            .collect();
        draw_stroke(&mut drawer, Uuid::new_v4(), &samples, 100).await;
    }
    let path = |format: &str| format!("/v1/sessions/{}/export?format={format}", session.session);
    // A print asked with its progress: once it answers, it holds its slot until its file.
    let print = proxy.get(&path("stl"), &session).header("accept", "application/x-ndjson");
    let print = print.send().await.unwrap();
    assert_eq!(print.status(), 200);
    // A scene is not held up by it.
    let scene = proxy.get(&path("glb"), &session).send().await.unwrap();
    assert_eq!(scene.status(), 200, "{}", scene.text().await.unwrap());
    assert_eq!(scene.headers()["content-type"], "model/gltf-binary");
    // The print was still being made: a second print (of another size) is refused busy.
    let other_size = format!("{}&size_mm=80", path("stl"));
    let second = proxy.get(&other_size, &session).send().await.unwrap();
    assert_eq!(second.status(), 503);
    assert!(second.text().await.unwrap().contains("1 print(s) are being made"));
    let lines = print.text().await.unwrap();
    let last: serde_json::Value = serde_json::from_str(lines.lines().last().unwrap()).unwrap();
    assert_eq!(last["file"]["content_type"], "model/stl", "{last}");
}

/// The identity moved by `(dx, dy)`.
fn moved(dx: f64, dy: f64) -> [f64; 16] {
    let mut m = *penmesh::Placement::IDENTITY.matrix();
    (m[12], m[13]) = (dx, dy);
    m
}

/// `method path` as the session's drawer (its key) with a JSON `body`: the status and answer.
async fn as_drawer(
    proxy: &TestProxy,
    session: &TestSession,
    method: reqwest::Method,
    path: &str,
    body: Option<Value>,
) -> (u16, Value) {
    let mut request = proxy
        .http
        .request(method, proxy.url(path))
        .bearer_auth(&session.token)
        .header(KEY_HEADER, &session.key);
    if let Some(body) = body {
        request = request.json(&body);
    }
    let response = request.send().await.unwrap();
    let status = response.status().as_u16();
    (status, response.json().await.unwrap_or(Value::Null))
}

/// `GET path` plainly: the status and the body's bytes.
async fn export(proxy: &TestProxy, session: &TestSession, path: &str) -> (u16, Vec<u8>) {
    let response = proxy.get(path, session).send().await.unwrap();
    (response.status().as_u16(), response.bytes().await.unwrap().to_vec())
}

/// (Issue 49, item 7) A print longer than the request timeout is answered 408 and goes on; the
/// same request again waits for that same work, then is answered with its file, and later
/// ones (plain or with progress) from the kept file at once: one print made in all.
#[tokio::test]
async fn a_print_that_outlives_its_request_is_kept_for_its_retry() {
    let proxy = spawn_proxy_with(|c| c.request_timeout_secs = 1).await;
    let session = proxy.create_session().await;
    // Enough solids that the print outlasts the 1 s timeout.
    proxy.slow_print_model(&session).await;
    let path = format!("/v1/sessions/{}/export?format=stl", session.session);
    let made = || proxy.state.kept_prints.made();

    let response = proxy.get(&path, &session).send().await.unwrap();
    assert_eq!(response.status(), 408, "the print outlasts its request (else this shows nothing)");
    let body: Value = response.json().await.unwrap();
    assert_eq!(body["error"], "timeout", "{body}");
    let message = body["message"].as_str().unwrap();
    assert!(message.contains("the same request again is answered with it"), "{message}");
    // Asked again at once, as a client told so does: each waits for the same work.
    let started = Instant::now();
    let mut timeouts = 1;
    let file = loop {
        let (status, body) = export(&proxy, &session, &path).await;
        match status {
            200 => break body,
            408 => timeouts += 1,
            other => panic!("{other}: {}", String::from_utf8_lossy(&body)),
        }
        assert!(started.elapsed() < Duration::from_secs(300), "never delivered");
    };
    let triangles = u32::from_le_bytes(file[80..84].try_into().unwrap()) as usize;
    assert_eq!(file.len(), 84 + 50 * triangles, "a binary STL");
    assert_eq!(made(), 1, "one print made for {timeouts} timed-out requests and their retry");

    // Asked again: the kept file, at once, the same bytes.
    let asked = Instant::now();
    let (status, again) = export(&proxy, &session, &path).await;
    assert_eq!((status, asked.elapsed() < Duration::from_secs(1)), (200, true));
    assert_eq!(again, file);
    // With its progress: the file's line straight away.
    let response = proxy.get(&path, &session).header("accept", "application/x-ndjson");
    let lines = response.send().await.unwrap().text().await.unwrap();
    let last: Value = serde_json::from_str(lines.lines().last().unwrap()).unwrap();
    let base64 = last["file"]["base64"].as_str().expect("the file's line");
    assert_eq!(base64::engine::general_purpose::STANDARD.decode(base64).unwrap(), file);
    assert_eq!(made(), 1, "answered from the kept print");
    let metrics = proxy.metrics().await;
    assert!(metrics.contains("penmesh_prints_total{answer=\"existing\"}"), "{metrics}");
}

/// (Issue 49, item 7) A kept print is never served for a model that has changed: a move, a
/// solid changed, a stroke taken back each make a new print; a stroke brought back is the
/// model before its removal again, answered from that model's kept print.
#[tokio::test]
async fn a_kept_print_is_never_served_for_a_changed_model() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut drawer = proxy.connect(&session).await;
    drawer.hello(vec![]).await;
    let strokes: Vec<Uuid> = (0..3).map(|_| Uuid::new_v4()).collect();
    for (i, &stroke) in strokes.iter().enumerate() {
        let samples: Vec<_> = stroke_samples(120)
            .into_iter()
            .map(|s| {
                penmesh::protocol::quantize_sample(&penmesh::Sample::new(
                    s.x,
                    s.y + 80.0 * i as f64,
                    s.t,
                    s.p,
                ))
            })
            .collect();
        draw_stroke(&mut drawer, stroke, &samples, 40).await;
    }
    let path = format!("/v1/sessions/{}/export?format=stl", session.session);
    let made = || proxy.state.kept_prints.made();
    let print = || async {
        let (status, file) = export(&proxy, &session, &path).await;
        assert_eq!(status, 200, "{}", String::from_utf8_lossy(&file));
        file
    };
    let first = print().await;
    assert_eq!((print().await, made()), (first.clone(), 1), "the same model: the kept print");

    let put = reqwest::Method::PUT;
    let placement = format!("/v1/strokes/{}/placement", strokes[0]);
    let body = json!({ "matrix": moved(35.0, -20.0) });
    assert_eq!(as_drawer(&proxy, &session, put.clone(), &placement, Some(body)).await.0, 204);
    let after_move = print().await;
    assert_eq!(made(), 2, "a move makes a new print");
    assert_ne!(after_move, first);

    let solid = format!("/v1/strokes/{}/solid", strokes[1]);
    let body = json!({ "kind": "line", "depth": 30 });
    assert_eq!(as_drawer(&proxy, &session, put, &solid, Some(body)).await.0, 200);
    let after_solid = print().await;
    assert_eq!(made(), 3, "a solid changed makes a new print");
    assert_ne!(after_solid, after_move);

    let stroke = format!("/v1/strokes/{}", strokes[2]);
    let (status, _) = as_drawer(&proxy, &session, reqwest::Method::DELETE, &stroke, None).await;
    assert_eq!(status, 204);
    let after_removal = print().await;
    assert_eq!(made(), 4, "a removal makes a new print");
    assert_ne!(after_removal, after_solid);

    let restore = format!("/v1/strokes/{}/restore", strokes[2]);
    let (status, _) = as_drawer(&proxy, &session, reqwest::Method::POST, &restore, None).await;
    assert_eq!(status, 204);
    assert_eq!(print().await, after_solid, "brought back: the model before the removal");
    assert_eq!(made(), 4, "answered from that model's kept print");
}

/// (Issue 49, low) A translation past ±1e9 px is refused naming the element; one stored before
/// that bound still reads, and the export refuses it naming the stroke.
#[tokio::test]
async fn a_placement_far_past_any_model_is_refused_and_one_stored_before_is_named() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let stroke = proxy.done_stroke(&session, 200).await;
    let placement = format!("/v1/strokes/{stroke}/placement");
    let put = reqwest::Method::PUT;
    let body = json!({ "matrix": moved(1e39, 0.0) });
    let (status, answer) = as_drawer(&proxy, &session, put.clone(), &placement, Some(body)).await;
    assert_eq!(status, 400, "{answer}");
    let message = answer["message"].as_str().unwrap();
    assert!(message.contains("matrix[12] = 1e39: a translation"), "{message}");
    // At the bound: a placement.
    let body = json!({ "matrix": moved(0.0, -penmesh::MAX_TRANSLATION) });
    assert_eq!(as_drawer(&proxy, &session, put, &placement, Some(body)).await.0, 204);

    // One stored past it before the bound (written behind the proxy's back).
    let far: Vec<u8> = moved(0.0, 1e20).iter().flat_map(|v| v.to_le_bytes()).collect();
    let blob = if proxy.db.is_postgres() {
        format!("'\\x{}'::bytea", hex::encode(&far))
    } else {
        format!("X'{}'", hex::encode(&far))
    };
    let sql = format!(
        "UPDATE stroke_placements SET matrix = {blob} WHERE id = (SELECT MAX(id) FROM \
         stroke_placements WHERE stroke_id = '{stroke}')"
    );
    execute_sql(&proxy.db, &sql).await;
    let info = proxy.stroke_info(&session, stroke).await;
    assert_eq!(info["placement"]["matrix"][13], 1e20, "it still reads: {info}");
    for format in ["stl", "glb"] {
        let path = format!("/v1/sessions/{}/export?format={format}", session.session);
        let response = proxy.get(&path, &session).send().await.unwrap();
        assert_eq!(response.status(), 409, "{format}");
        let body: Value = response.json().await.unwrap();
        let message = body["message"].as_str().unwrap();
        assert!(message.contains(&format!("stroke {stroke} cannot be exported")), "{message}");
        assert!(message.contains("matrix[13] = 1e20"), "{message}");
    }
}
