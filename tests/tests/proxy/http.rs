use penmesh::protocol::{
    BundledMesh, MESH_BUNDLE_CONTENT_TYPE, ServerMessage, decode_mesh_bundle, decode_server,
};
use penmesh_e2e::{batch_simplified, draw_stroke, spawn_proxy, stroke_samples};
use uuid::Uuid;

async fn done_stroke(
    proxy: &penmesh_e2e::TestProxy,
) -> (penmesh_e2e::TestSession, Uuid, Vec<penmesh::Sample>) {
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    let samples = stroke_samples(120);
    draw_stroke(&mut ws, stroke, &samples, 30).await;
    (session, stroke, samples)
}

#[tokio::test]
async fn strokes_are_listed_and_served_in_json_and_binary() {
    let proxy = spawn_proxy().await;
    let (session, stroke, samples) = done_stroke(&proxy).await;
    let list = proxy.get_json(&format!("/v1/sessions/{}/strokes", session.session), &session).await;
    let strokes = list["strokes"].as_array().unwrap();
    assert_eq!(strokes.len(), 1);
    assert_eq!(strokes[0]["id"], stroke.to_string());
    assert_eq!(strokes[0]["n_retained"], batch_simplified(&samples).len());
    assert_eq!(strokes[0]["has_mesh"], false);

    let simplified = proxy.get_json(&format!("/v1/strokes/{stroke}/simplified"), &session).await;
    let indices: Vec<usize> = serde_json::from_value(simplified["indices"].clone()).unwrap();
    assert_eq!(indices, penmesh::simplify(&samples, &penmesh::AcutsParams::default()));

    let response = proxy
        .get(&format!("/v1/strokes/{stroke}/simplified"), &session)
        .header("accept", "application/octet-stream")
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], "application/octet-stream");
    assert_eq!(response.headers()["x-penmesh-status"], "done");
    let bytes = response.bytes().await.unwrap();
    let ServerMessage::Retained(retained) = decode_server(&bytes, usize::MAX).unwrap() else {
        panic!("binary body is a Retained message")
    };
    assert_eq!(retained.points.0, batch_simplified(&samples));
}

#[tokio::test]
async fn an_unfinished_stroke_has_raw_samples_but_no_simplified_form_yet() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    ws.begin(stroke).await;
    ws.points(stroke, 0, &stroke_samples(10)).await;
    ws.wait_ack(stroke, 10).await;
    assert_eq!(proxy.raw_samples(&session, stroke).await, stroke_samples(10));
    let response =
        proxy.get(&format!("/v1/strokes/{stroke}/simplified"), &session).send().await.unwrap();
    assert_eq!(response.status(), 409);
    let response =
        proxy.get(&format!("/v1/strokes/{}/raw", Uuid::new_v4()), &session).send().await.unwrap();
    assert_eq!(response.status(), 404);
}

#[tokio::test]
async fn a_mesh_is_validated_stored_and_served_as_gltf_binary() {
    let proxy = spawn_proxy().await;
    let (session, stroke, _) = done_stroke(&proxy).await;
    let body = penmesh_e2e::minimal_glb(8, 36);
    let response = proxy.put_mesh(&session, stroke, body.clone()).send().await.unwrap();
    assert_eq!(response.status(), 200);
    let info: serde_json::Value = response.json().await.unwrap();
    assert_eq!((info["vertices"].as_u64(), info["triangles"].as_u64()), (Some(8), Some(12)));

    let response = proxy.get(&format!("/v1/strokes/{stroke}/mesh"), &session).send().await.unwrap();
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], "model/gltf-binary");
    assert_eq!(response.bytes().await.unwrap().to_vec(), body);
    assert_eq!(proxy.stroke_info(&session, stroke).await["has_mesh"], true);

    for (bad, what) in [
        (b"nope".to_vec(), "short"),
        (
            {
                let mut b = body.clone();
                b[0] = b'g';
                b[1] = b'l';
                b[2] = b'b';
                b
            },
            "magic",
        ),
        (
            {
                let mut b = body.clone();
                b[4] = 1;
                b
            },
            "version",
        ),
        (
            {
                let mut b = body.clone();
                b.push(0);
                b
            },
            "length",
        ),
    ] {
        let response = proxy.put_mesh(&session, stroke, bad).send().await.unwrap();
        assert_eq!(response.status(), 400, "{what}");
        let err: serde_json::Value = response.json().await.unwrap();
        assert_eq!(err["error"], "bad_request", "{what}");
    }
}

#[tokio::test]
async fn a_mesh_needs_a_done_stroke() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let stroke = Uuid::new_v4();
    let _ws = proxy.drawing(&session, stroke).await;
    let response =
        proxy.put_mesh(&session, stroke, penmesh_e2e::minimal_glb(3, 3)).send().await.unwrap();
    assert_eq!(response.status(), 409);
}

#[tokio::test]
async fn health_readiness_metrics_and_openapi_answer() {
    let proxy = spawn_proxy().await;
    done_stroke(&proxy).await;
    for (path, needle) in [
        ("/healthz", "ok"),
        ("/readyz", "ready"),
        ("/metrics", "penmesh_samples_in_total"),
        ("/v1/openapi.json", "/v1/strokes/{id}/simplified"),
    ] {
        let response = proxy.http.get(proxy.url(path)).send().await.unwrap();
        assert_eq!(response.status(), 200, "{path}");
        let text = response.text().await.unwrap();
        assert!(text.contains(needle), "{path} lacks {needle}");
    }
    let metrics = proxy.metrics().await;
    for name in [
        "penmesh_ws_connections",
        "penmesh_ws_frames_total",
        "penmesh_samples_retained_total",
        "penmesh_strokes_total",
        "penmesh_commit_seconds_bucket",
        "penmesh_commit_batch_requests",
    ] {
        assert!(metrics.contains(name), "metrics lack {name}");
    }
}

#[tokio::test]
async fn a_sessions_meshes_come_in_one_bundle_with_an_etag_and_304() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let path = format!("/v1/sessions/{}/meshes", session.session);
    // Two people draw: two strokes with a mesh (in the order drawn) and one without.
    let other = session.stranger();
    let mut strokes = Vec::new();
    for who in [&session, &other, &session] {
        let mut ws = proxy.connect(who).await;
        let me = ws.hello(vec![]).await.participant;
        let stroke = Uuid::new_v4();
        draw_stroke(&mut ws, stroke, &stroke_samples(40), 20).await;
        strokes.push((who, me, stroke));
    }
    let glbs = [penmesh_e2e::minimal_glb(8, 36), penmesh_e2e::minimal_glb(3, 3)];
    for ((who, _, stroke), glb) in strokes.iter().zip(&glbs) {
        assert_eq!(proxy.put_mesh(who, *stroke, glb.clone()).send().await.unwrap().status(), 200);
    }
    // A mesh of another session is not in this one's bundle.
    let (elsewhere, stroke_elsewhere, _) = done_stroke(&proxy).await;
    let response = proxy.put_mesh(&elsewhere, stroke_elsewhere, glbs[0].clone()).send().await;
    assert_eq!(response.unwrap().status(), 200);

    let response = proxy.get(&path, &session).send().await.unwrap();
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], MESH_BUNDLE_CONTENT_TYPE);
    assert_eq!(response.headers()["cache-control"], "private, no-cache");
    let etag = response.headers()["etag"].to_str().unwrap().to_string();
    let bundle = decode_mesh_bundle(&response.bytes().await.unwrap()).unwrap();
    let expected: Vec<BundledMesh> = strokes[..2]
        .iter()
        .zip(&glbs)
        .map(|((_, me, stroke), glb)| BundledMesh {
            stroke: *stroke,
            participant: *me,
            glb: glb.clone(),
        })
        .collect();
    assert_eq!(bundle, expected);

    // The client's copy is current: 304, no body, the same ETag (also in weak form or a list).
    for tag in [etag.clone(), format!("W/{etag}"), format!("\"x\", {etag}")] {
        let response =
            proxy.get(&path, &session).header("if-none-match", tag).send().await.unwrap();
        assert_eq!(response.status(), 304);
        assert_eq!(response.headers()["etag"], etag.as_str());
        assert!(response.bytes().await.unwrap().is_empty());
    }
    // Gzipped for a client that asks: the same bundle, its own ETag, its own 304.
    let gzipped =
        proxy.get(&path, &session).header("accept-encoding", "gzip").send().await.unwrap();
    assert_eq!(gzipped.headers()["content-encoding"], "gzip");
    let gzip_etag = gzipped.headers()["etag"].to_str().unwrap().to_string();
    assert_ne!(gzip_etag, etag);
    let mut unzipped = Vec::new();
    let body = gzipped.bytes().await.unwrap();
    std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(&body[..]), &mut unzipped)
        .unwrap();
    assert_eq!(decode_mesh_bundle(&unzipped).unwrap(), expected);
    let response = proxy.get(&path, &session).header("accept-encoding", "gzip");
    let response = response.header("if-none-match", &gzip_etag).send().await.unwrap();
    assert_eq!(response.status(), 304);
    // A new mesh makes the copy stale: 200 with a new ETag and the mesh in it.
    let (who, _, third) = strokes[2];
    assert_eq!(proxy.put_mesh(who, third, glbs[1].clone()).send().await.unwrap().status(), 200);
    let response = proxy.get(&path, &session).header("if-none-match", &etag).send().await.unwrap();
    assert_eq!(response.status(), 200);
    assert_ne!(response.headers()["etag"], etag.as_str());
    let bundle = decode_mesh_bundle(&response.bytes().await.unwrap()).unwrap();
    assert_eq!(
        bundle.iter().map(|m| m.stroke).collect::<Vec<_>>(),
        strokes.iter().map(|s| s.2).collect::<Vec<_>>()
    );

    // Like every session route: the session's own token only, 401 otherwise.
    assert_eq!(proxy.http.get(proxy.url(&path)).send().await.unwrap().status(), 401);
    assert_eq!(proxy.get(&path, &elsewhere).send().await.unwrap().status(), 401);
    // A session without meshes has an empty bundle.
    let empty = proxy.create_session().await;
    let response = proxy.get(&format!("/v1/sessions/{}/meshes", empty.session), &empty);
    let bundle =
        decode_mesh_bundle(&response.send().await.unwrap().bytes().await.unwrap()).unwrap();
    assert_eq!(bundle, vec![]);
}
