//! The print export (`GET /v1/sessions/{id}/export`, issue 39): a session's done strokes as one
//! STL or 3MF that PrusaSlicer reads as one manifold, its longest side `size_mm`; bad requests
//! answered naming what is wrong.

use std::process::Command;

use penmesh_e2e::{draw_stroke, spawn_proxy, stroke_samples};
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
    // The print was still being made: a second print is refused busy.
    let second = proxy.get(&path("stl"), &session).send().await.unwrap();
    assert_eq!(second.status(), 503);
    assert!(second.text().await.unwrap().contains("1 print(s) are being made"));
    let lines = print.text().await.unwrap();
    let last: serde_json::Value = serde_json::from_str(lines.lines().last().unwrap()).unwrap();
    assert_eq!(last["file"]["content_type"], "model/stl", "{last}");
}
