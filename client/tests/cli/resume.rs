//! A proxy killed in the middle of a stroke and restarted on the same database and port: the
//! client resumes and the stored stroke equals the one drawn.

use std::process::Stdio;
use std::time::Duration;

use penmesh::Shape;

use crate::helpers::{
    Proxy, assert_stored_complete, expected_resampled, stored_strokes, synth, wait,
};

#[tokio::test]
async fn a_killed_proxy_loses_and_duplicates_nothing() {
    // Arrange: a stroke of about five seconds, drawn at its real pace.
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("p.db");
    let mut proxy = Proxy::start(&db, 0);
    let (speed, size, seed) = (300.0, 400.0, 3);
    let drawn = synth(Shape::Scribble, speed, size, seed);
    let duration_ms = drawn.samples().last().unwrap().t - drawn.samples()[0].t;
    assert!(duration_ms > 3000.0, "the stroke is too short to be cut: {duration_ms} ms");

    // Act
    let client = proxy
        .draw()
        .args(["--synth", "scribble", "--realtime", "-v", "--retry-for", "30"])
        .args([
            "--speed",
            &speed.to_string(),
            "--size",
            &size.to_string(),
            "--seed",
            &seed.to_string(),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Mid-stroke: once the proxy has stored some of it (the client's start-up takes longer on a
    // busy machine; the stroke itself is paced in real time, about five seconds).
    until_samples_stored(&db).await;
    let port = proxy.port;
    proxy.kill();
    std::thread::sleep(Duration::from_millis(500));
    let restarted = Proxy::start(&db, port);
    let out = wait(client);

    // Assert
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "draw failed: {stderr}");
    assert!(stderr.contains("connection lost"), "the cut was not noticed: {stderr}");
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let id = summary["strokes"][0]["stroke"].as_str().unwrap();
    let stored = stored_strokes(&restarted.db).await;
    assert_eq!(stored.len(), 1);
    assert_eq!(stored[0].id, id);
    assert_stored_complete(&stored[0]);
    assert_eq!(
        stored[0].raw,
        expected_resampled(drawn.samples()),
        "stored stroke differs from the drawn one"
    );
    // Stored in pieces across the kill (what the killed proxy left in its log, moved at the
    // restart, then the rest): rows that follow each other from 0 to the end, no overlap.
    let chunks = &stored[0].chunks;
    assert!(chunks.len() >= 2, "the kill should leave the stroke in pieces: {chunks:?}");
    let mut end = 0;
    for &(seq, n) in chunks {
        assert_eq!(seq, end, "rows must follow each other: {chunks:?}");
        end += n;
    }
    assert_eq!(end, stored[0].n_points);
}

/// Waits until the proxy on `db` has stored samples of a stroke (its log or its chunks); fails
/// after a minute.
async fn until_samples_stored(db: &std::path::Path) {
    let url = format!("sqlite://{}?mode=ro", db.display());
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    loop {
        if let Ok(pool) = sqlx::SqlitePool::connect(&url).await {
            let rows: Result<i64, _> = sqlx::query_scalar(
                "SELECT (SELECT COUNT(*) FROM stroke_log) + (SELECT COUNT(*) FROM stroke_chunks)",
            )
            .fetch_one(&pool)
            .await;
            pool.close().await;
            if rows.is_ok_and(|n| n > 0) {
                return;
            }
        }
        assert!(std::time::Instant::now() < deadline, "no samples stored in a minute");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// Forwards TCP connections to `upstream` until told to cut every open one.
async fn relay(upstream: u16) -> (u16, tokio::sync::watch::Sender<u32>) {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = listener.local_addr().unwrap().port();
    let (cut, cuts) = tokio::sync::watch::channel(0u32);
    tokio::spawn(async move {
        loop {
            let Ok((mut downstream, _)) = listener.accept().await else { return };
            let mut cuts = cuts.clone();
            cuts.mark_unchanged();
            tokio::spawn(async move {
                let Ok(mut up) = tokio::net::TcpStream::connect(("127.0.0.1", upstream)).await
                else {
                    return;
                };
                tokio::select! {
                    _ = tokio::io::copy_bidirectional(&mut downstream, &mut up) => {}
                    _ = cuts.changed() => {}
                }
            });
        }
    });
    (port, cut)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn network_blips_mid_stroke_lose_and_duplicate_nothing() {
    // Arrange: the client reaches a live proxy through a relay that drops every connection.
    let dir = tempfile::tempdir().unwrap();
    let proxy = Proxy::start(&dir.path().join("p.db"), 0);
    let (relay_port, cut) = relay(proxy.port).await;
    let (speed, size, seed) = (300.0, 400.0, 5);
    let drawn = synth(Shape::Scribble, speed, size, seed);

    // Act: two blips while the stroke is being drawn.
    let mut cmd = crate::helpers::penmesh();
    cmd.args(["draw", "--json", "--server", &format!("http://127.0.0.1:{relay_port}")])
        .args(["--session", &proxy.session, "--token", &proxy.token])
        .args(["--synth", "scribble", "--realtime", "-v"])
        .args([
            "--speed",
            &speed.to_string(),
            "--size",
            &size.to_string(),
            "--seed",
            &seed.to_string(),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let client = cmd.spawn().unwrap();
    // The first blip once the stroke is flowing (not at a fixed time after the start: the
    // client's start-up takes longer on a busy machine), the second 1.2 s of its real-time pace
    // later.
    until_samples_stored(&proxy.db).await;
    cut.send_modify(|n| *n += 1);
    tokio::time::sleep(Duration::from_millis(1200)).await;
    cut.send_modify(|n| *n += 1);
    let out = tokio::task::spawn_blocking(move || wait(client)).await.unwrap();

    // Assert
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "draw failed: {stderr}");
    assert_eq!(stderr.matches("connection lost; resuming").count(), 2, "{stderr}");
    let stored = stored_strokes(&proxy.db).await;
    assert_eq!(stored.len(), 1);
    assert_stored_complete(&stored[0]);
    assert_eq!(stored[0].raw, expected_resampled(drawn.samples()));
}
