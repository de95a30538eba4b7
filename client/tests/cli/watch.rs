//! `penmesh draw --watch` prints what the others do, a stroke taken back and brought back
//! included.

use std::io::{BufRead, BufReader};
use std::process::Stdio;
use std::sync::mpsc;

use penmesh::Shape;
use penmesh::protocol::KEY_HEADER;
use penmesh_client::draw_options::DrawOptions;
use penmesh_client::endpoint::Endpoint;
use penmesh_client::input::{Pacing, ReplaySource};

use crate::helpers::{Proxy, TIMEOUT, penmesh, synth};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_watcher_prints_a_stroke_taken_back_and_brought_back() {
    let dir = tempfile::tempdir().unwrap();
    let proxy = Proxy::start(&dir.path().join("p.db"), 0);
    let mut watcher = penmesh()
        .args(["draw", "--watch", "--server", &proxy.url, "--session", &proxy.session])
        .args(["--token", &proxy.token, "--name", "w"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let (lines, seen) = mpsc::channel();
    let stdout = watcher.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = lines.send(line);
        }
    });
    let wait_for = |piece: &str| {
        let deadline = std::time::Instant::now() + TIMEOUT;
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            match seen.recv_timeout(left) {
                Ok(line) if line.contains(piece) => return line,
                Ok(_) => {}
                Err(_) => panic!("the watcher never printed {piece:?}"),
            }
        }
    };
    wait_for("up to date");

    // Ada draws a stroke with a key the test knows, then takes it back and brings it back.
    let session = proxy.session.parse().unwrap();
    let endpoint = Endpoint::new(&proxy.url, session, proxy.token.clone()).unwrap();
    let options = DrawOptions::new("Ada");
    let stroke = synth(Shape::Leaf, 300.0, 200.0, 3);
    let source = Box::new(ReplaySource::new("synth:leaf", vec![stroke], Pacing::Fast));
    let reports = penmesh_client::live::draw(&endpoint, source, &options).await.unwrap();
    let id = reports[0].stroke;
    let short = &id.to_string()[..8];
    wait_for(&format!("Ada's mesh of stroke {short}"));
    let http = reqwest::Client::new();
    for (request, printed) in [
        (http.delete(endpoint.url(&format!("/v1/strokes/{id}"))), "Ada took back stroke"),
        (http.post(endpoint.url(&format!("/v1/strokes/{id}/restore"))), "Ada brought back stroke"),
    ] {
        let response = request
            .bearer_auth(&proxy.token)
            .header(KEY_HEADER, &options.key)
            .send()
            .await
            .unwrap();
        assert_eq!(response.status(), 204);
        assert!(wait_for(printed).ends_with(short));
    }
    let _ = watcher.kill();
    let _ = watcher.wait();
}

// `draw --placement` draws onto that work plane (its strokes listed with it), a bad matrix is
// refused before anything is sent, and the watcher prints each placement: the plane a stroke
// was begun on, and a move.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn strokes_are_drawn_onto_a_placement_and_the_watcher_prints_moves() {
    let dir = tempfile::tempdir().unwrap();
    let proxy = Proxy::start(&dir.path().join("p.db"), 0);
    let mut watcher = penmesh()
        .args(["draw", "--watch", "--server", &proxy.url, "--session", &proxy.session])
        .args(["--token", &proxy.token, "--name", "w"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let (lines, seen) = mpsc::channel();
    let stdout = watcher.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = lines.send(line);
        }
    });
    let wait_for = |piece: &str| {
        let deadline = std::time::Instant::now() + TIMEOUT;
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            match seen.recv_timeout(left) {
                Ok(line) if line.contains(piece) => return line,
                Ok(_) => {}
                Err(_) => panic!("the watcher never printed {piece:?}"),
            }
        }
    };
    wait_for("up to date");

    let standing = "1,0,0,0,0,0,1,0,0,-1,0,0,0,0,0,1";
    let bad = crate::helpers::run(proxy.draw().args([
        "--synth",
        "leaf",
        "--name",
        "Bo",
        "--placement",
        "2,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1",
    ]));
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("not a similarity"));
    let drawn = crate::helpers::run(proxy.draw().args([
        "--synth",
        "leaf",
        "--name",
        "Bo",
        "--placement",
        standing,
    ]));
    assert!(drawn.status.success(), "{}", String::from_utf8_lossy(&drawn.stderr));
    let printed = wait_for("Bo placed stroke");
    assert!(
        printed.ends_with("at 1.0,0.0,0.0,0.0,0.0,0.0,1.0,0.0,0.0,-1.0,0.0,0.0,0.0,0.0,0.0,1.0"),
        "{printed}"
    );
    let http = reqwest::Client::new();
    let list: penmesh::protocol::StrokeList = http
        .get(format!("{}/v1/sessions/{}/strokes", proxy.url, proxy.session))
        .bearer_auth(&proxy.token)
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(list.strokes.len(), 1);
    assert_eq!(list.strokes[0].placement, penmesh::Placement::parse_list(standing).unwrap());

    // Ada draws on the board, then mirrors her stroke over HTTP: the watcher prints it.
    let session = proxy.session.parse().unwrap();
    let endpoint = Endpoint::new(&proxy.url, session, proxy.token.clone()).unwrap();
    let options = DrawOptions::new("Ada");
    let stroke = synth(Shape::Leaf, 300.0, 200.0, 3);
    let source = Box::new(ReplaySource::new("synth:leaf", vec![stroke], Pacing::Fast));
    let reports = penmesh_client::live::draw(&endpoint, source, &options).await.unwrap();
    let id = reports[0].stroke;
    let short = &id.to_string()[..8];
    wait_for(&format!("Ada's mesh of stroke {short}"));
    let response = http
        .put(endpoint.url(&format!("/v1/strokes/{id}/placement")))
        .bearer_auth(&proxy.token)
        .header(KEY_HEADER, &options.key)
        .json(&serde_json::json!({ "matrix": [-1,0,0,0, 0,1,0,0, 0,0,1,0, 5,0,0,1] }))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 204);
    let printed = wait_for(&format!("Ada placed stroke {short}"));
    assert!(printed.ends_with("(mirrored)"), "{printed}");
    let _ = watcher.kill();
    let _ = watcher.wait();
}
