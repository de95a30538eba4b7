//! What one request may cost (issue 25): a large body needs one of a few permits and must be
//! taken by the client within the request timeout; a mesh is written by the group commit and
//! the meshes of a session are held to its quota.

use std::time::Duration;

use penmesh::Sample;
use penmesh::protocol::{ServerMessage, StrokeId, decode_server};
use penmesh_e2e::penmesh_proxy::{CommitFaults, Fault};
use penmesh_e2e::{
    TestDatabase, TestProxy, TestSession, WsClient, draw_stroke, minimal_glb, plain_glb,
    spawn_faulty_proxy_on, spawn_proxy_with,
};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use uuid::Uuid;

/// A straight stroke of `n` samples: ACUTS retains a handful of them whatever its length.
fn straight(n: usize) -> Vec<Sample> {
    (0..n)
        .map(|i| {
            let s = Sample::new(i as f64 * 0.5, 10.0, i as f64, 0.5);
            penmesh::protocol::quantize_sample(&s)
        })
        .collect()
}

/// A connection that said hello, and done strokes of `n` samples each drawn on it.
async fn done_strokes(
    proxy: &TestProxy,
    session: &TestSession,
    k: usize,
    n: usize,
) -> (WsClient, Vec<StrokeId>) {
    let mut ws = proxy.connect(session).await;
    ws.hello(vec![]).await;
    let mut strokes = Vec::new();
    for _ in 0..k {
        let stroke = Uuid::new_v4();
        draw_stroke(&mut ws, stroke, &straight(n), 4096).await;
        strokes.push(stroke);
    }
    (ws, strokes)
}

#[tokio::test]
async fn a_large_body_needs_a_permit_and_a_reader_too_slow_for_the_deadline_is_cut_off() {
    // Arrange: one large body at a time, 3 s to send it; a stroke whose raw samples are
    // about 8 MB of JSON, more than the sockets between the proxy and a client hold.
    let proxy = spawn_proxy_with(|c| {
        c.max_large_bodies = 1;
        c.request_timeout_secs = 3;
    })
    .await;
    let session = proxy.create_session().await;
    let (_ws, strokes) = done_strokes(&proxy, &session, 1, 300_000).await;
    let path = format!("/v1/strokes/{}/raw", strokes[0]);

    // Act: a client asks for it and reads the status line, then nothing more.
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    socket.set_recv_buffer_size(4096).unwrap();
    let mut slow = socket.connect(([127, 0, 0, 1], proxy.port).into()).await.unwrap();
    let request = format!(
        "GET {path} HTTP/1.1\r\nhost: 127.0.0.1\r\nauthorization: Bearer {}\r\n\r\n",
        session.token
    );
    slow.write_all(request.as_bytes()).await.unwrap();
    let mut status = [0u8; 12];
    slow.read_exact(&mut status).await.unwrap();
    assert_eq!(&status, b"HTTP/1.1 200");

    // Assert: meanwhile another large body is refused, with a time to try again.
    let busy = proxy.get(&path, &session).send().await.unwrap();
    assert_eq!(busy.status(), 503);
    assert_eq!(busy.headers()["retry-after"], "1");
    let err: serde_json::Value = busy.json().await.unwrap();
    assert_eq!(err["error"], "busy");
    assert!(err["message"].as_str().unwrap().contains("1 bodies over"), "{err}");
    // A small body needs no permit.
    let list = proxy.get(&format!("/v1/sessions/{}/strokes", session.session), &session);
    assert_eq!(list.send().await.unwrap().status(), 200);
    // Once the deadline has passed the slow client is cut off, and its permit is free again.
    let mut answered = None;
    for _ in 0..100 {
        let request = proxy.get(&path, &session).header("accept", "application/octet-stream");
        let response = request.send().await.unwrap();
        if response.status() != 503 {
            answered = Some(response);
            break;
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    let answered = answered.expect("the permit frees once the slow body is cut off");
    assert_eq!(answered.status(), 200);
    let body = answered.bytes().await.unwrap();
    let ServerMessage::Retained(retained) = decode_server(&body, usize::MAX).unwrap() else {
        panic!("the binary body is a Retained message")
    };
    assert_eq!(retained.points.0, straight(300_000), "a client that reads gets every sample");
    let mut rest = Vec::new();
    let _ = tokio::time::timeout(Duration::from_secs(10), slow.read_to_end(&mut rest))
        .await
        .expect("the slow client's connection is closed");
    assert!(!rest.ends_with(b"0\r\n\r\n"), "the slow client never got the whole body");
}

#[tokio::test]
async fn a_mesh_is_stored_by_the_group_commit() {
    // Arrange: the writer's next transaction will fail.
    let faults = CommitFaults::new();
    let proxy =
        spawn_faulty_proxy_on(TestDatabase::fresh().await, Some(faults.clone()), |_| {}).await;
    let session = proxy.create_session().await;
    let (_ws, strokes) = done_strokes(&proxy, &session, 1, 50).await;
    let glb = minimal_glb(8, 36);
    faults.fail_transaction(1, Fault::Fail);

    // Act
    let failed = proxy.put_mesh(&session, strokes[0], glb.clone()).send().await.unwrap();

    // Assert: the upload was in that transaction: it failed, and nothing is stored.
    assert_eq!(failed.status(), 500);
    let mesh = format!("/v1/strokes/{}/mesh", strokes[0]);
    assert_eq!(proxy.get(&mesh, &session).send().await.unwrap().status(), 404);
    assert_eq!(proxy.stroke_info(&session, strokes[0]).await["has_mesh"], false);
    let stored = proxy.put_mesh(&session, strokes[0], glb.clone()).send().await.unwrap();
    assert_eq!(stored.status(), 200);
    let served = proxy.get(&mesh, &session).send().await.unwrap();
    assert_eq!(served.bytes().await.unwrap().to_vec(), glb);
}

#[tokio::test]
async fn the_meshes_of_a_session_are_held_to_its_quota() {
    // Arrange: room for two meshes and a half.
    let glb = minimal_glb(8, 36);
    let quota = (glb.len() * 5 / 2) as u64;
    let proxy = spawn_proxy_with(|c| c.max_session_mesh_bytes = quota).await;
    let session = proxy.create_session().await;
    let (_ws, strokes) = done_strokes(&proxy, &session, 3, 50).await;
    for stroke in &strokes[..2] {
        let response = proxy.put_mesh(&session, *stroke, glb.clone()).send().await.unwrap();
        assert_eq!(response.status(), 200);
    }

    // Act
    let refused = proxy.put_mesh(&session, strokes[2], glb.clone()).send().await.unwrap();

    // Assert: refused, naming the quota, and nothing stored.
    assert_eq!(refused.status(), 413);
    let err: serde_json::Value = refused.json().await.unwrap();
    assert_eq!(err["error"], "quota_exceeded");
    let message = err["message"].as_str().unwrap();
    assert!(message.contains(&format!("quota of {quota} bytes")), "{message}");
    assert!(message.contains(&format!("hold {} bytes", 2 * glb.len())), "{message}");
    let mesh = format!("/v1/strokes/{}/mesh", strokes[2]);
    assert_eq!(proxy.get(&mesh, &session).send().await.unwrap().status(), 404);
    assert_eq!(proxy.stroke_info(&session, strokes[2]).await["has_mesh"], false);
    // A mesh replaced counts once; another session has a quota of its own.
    let again = proxy.put_mesh(&session, strokes[0], glb.clone()).send().await.unwrap();
    assert_eq!(again.status(), 200);
    let other = proxy.create_session().await;
    let (_other_ws, other_strokes) = done_strokes(&proxy, &other, 1, 50).await;
    let elsewhere = proxy.put_mesh(&other, other_strokes[0], glb).send().await.unwrap();
    assert_eq!(elsewhere.status(), 200);
}

/// The mesh bundle is a large body like the others: a 200 waits for one of the permits (and
/// takes its turn rather than failing), while a 304 needs neither a permit nor a mesh read:
/// its ETag is made from what the bundle holds (stroke, drawer, size, counts, time stored),
/// so that bytes changed behind the proxy's back, at the same size, do not change it. Before,
/// the bundle took no permit and every request, a 304 too, read and hashed every mesh.
#[tokio::test]
async fn a_mesh_bundle_takes_a_large_body_permit_and_a_304_reads_no_mesh() {
    let proxy = spawn_proxy_with(|c| c.max_large_bodies = 1).await;
    let session = proxy.create_session().await;
    let (_ws, strokes) = done_strokes(&proxy, &session, 3, 50).await;
    // About 1.4 MB of meshes: a large body.
    let glbs: Vec<Vec<u8>> = (0..3).map(|k| plain_glb(20_000 + k)).collect();
    for (stroke, glb) in strokes.iter().zip(&glbs) {
        let response = proxy.put_mesh(&session, *stroke, glb.clone()).send().await.unwrap();
        assert_eq!(response.status(), 200);
    }
    let path = format!("/v1/sessions/{}/meshes", session.session);
    let get = |etag: Option<String>, gzip: bool| {
        let mut request = proxy.get(&path, &session);
        if let Some(etag) = etag {
            request = request.header("if-none-match", etag);
        }
        if gzip {
            request = request.header("accept-encoding", "gzip");
        }
        request.send()
    };
    let first = get(None, false).await.unwrap();
    assert_eq!(first.status(), 200);
    let etag = first.headers()["etag"].to_str().unwrap().to_string();
    let bundle = penmesh::protocol::decode_mesh_bundle(&first.bytes().await.unwrap()).unwrap();
    assert_eq!(bundle.iter().map(|m| m.glb.clone()).collect::<Vec<_>>(), glbs);

    // Every permit taken (another large body being sent).
    let held = proxy.state.large_body(2 << 20).expect("a permit").expect("a large body's");
    let started = std::time::Instant::now();
    let revalidated = get(Some(etag.clone()), false).await.unwrap();
    assert_eq!(revalidated.status(), 304);
    assert!(started.elapsed() < Duration::from_secs(2), "a 304 waited for a permit");
    // A 200 waits for its turn, then comes whole (gzipped here, piece by piece).
    let waiting = tokio::spawn(get(None, true));
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert!(!waiting.is_finished(), "a bundle was sent without a large-body permit");
    drop(held);
    let served = waiting.await.unwrap().unwrap();
    assert_eq!(served.status(), 200);
    let mut unzipped = Vec::new();
    let body = served.bytes().await.unwrap();
    std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(&body[..]), &mut unzipped)
        .unwrap();
    assert_eq!(penmesh::protocol::decode_mesh_bundle(&unzipped).unwrap(), bundle);

    // Bytes changed at the same size, behind the proxy's back: the ETag, made without reading
    // them, is the same.
    let zeroes = if proxy.db.is_postgres() {
        "decode(repeat('00', length(glb)), 'hex')"
    } else {
        "zeroblob(length(glb))"
    };
    penmesh_e2e::execute_sql(&proxy.db, &format!("UPDATE meshes SET glb = {zeroes}")).await;
    assert_eq!(get(Some(etag.clone()), false).await.unwrap().status(), 304);
    // A mesh replaced through the proxy changes it.
    let replaced = proxy.put_mesh(&session, strokes[0], glbs[0].clone()).send().await.unwrap();
    assert_eq!(replaced.status(), 200);
    let after = get(Some(etag.clone()), false).await.unwrap();
    assert_eq!(after.status(), 200);
    assert_ne!(after.headers()["etag"].to_str().unwrap(), etag);
}

/// The rule: a stroke taken back keeps its mesh stored (it can be brought back), so the mesh
/// still counts toward the session's quota; taking strokes back frees nothing, or removing and
/// uploading in turn would store any amount.
#[tokio::test]
async fn a_mesh_of_a_stroke_taken_back_still_counts_toward_the_quota() {
    let glb = minimal_glb(8, 36);
    let quota = (glb.len() * 5 / 2) as u64;
    let proxy = spawn_proxy_with(|c| c.max_session_mesh_bytes = quota).await;
    let session = proxy.create_session().await;
    let (_ws, strokes) = done_strokes(&proxy, &session, 3, 50).await;
    for stroke in &strokes[..2] {
        let response = proxy.put_mesh(&session, *stroke, glb.clone()).send().await.unwrap();
        assert_eq!(response.status(), 200);
    }
    let removed = proxy.http.delete(proxy.url(&format!("/v1/strokes/{}", strokes[0])));
    let removed = removed
        .bearer_auth(&session.token)
        .header(penmesh::protocol::KEY_HEADER, &session.key)
        .send()
        .await
        .unwrap();
    assert_eq!(removed.status(), 204);
    let refused = proxy.put_mesh(&session, strokes[2], glb.clone()).send().await.unwrap();
    assert_eq!(refused.status(), 413);
    let err: serde_json::Value = refused.json().await.unwrap();
    assert_eq!(err["error"], "quota_exceeded");
}
