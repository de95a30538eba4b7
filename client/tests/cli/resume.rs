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
    std::thread::sleep(Duration::from_millis(1500));
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
    assert!(stored[0].chunks.len() > 1);
}
