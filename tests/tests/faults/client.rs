//! The native client against a proxy that comes and goes: it waits for a proxy that is down
//! when it starts, keeps drawing through a proxy killed under it, and stores every stroke
//! with its mesh once the proxy is back (issue 25: it gave up the whole drawing after three
//! connection attempts, and on one failed upload).

use std::time::Duration;

use penmesh::GeneratorParams;
use penmesh_client::draw_options::DrawOptions;
use penmesh_client::endpoint::Endpoint;
use penmesh_client::input::{Pacing, ReplaySource};
use penmesh_e2e::TestDatabase;

use crate::child::ProxyChild;

/// Strokes the client draws in real time (about 1.2 s each, and a pause between two).
const N_STROKES: usize = 6;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_native_client_waits_for_the_proxy_and_stores_every_stroke_with_its_mesh() {
    // Arrange: a session, then the proxy down.
    let db = TestDatabase::fresh().await;
    let mut proxy = ProxyChild::start(&db.url, &[]).await;
    let session = proxy.create_session().await;
    let endpoint = Endpoint::new(&proxy.url(""), session.session, session.token.clone()).unwrap();
    proxy.kill();
    let params: Vec<GeneratorParams> = (0..N_STROKES)
        .map(|seed| GeneratorParams { seed: seed as u64, size: 120.0, ..Default::default() })
        .collect();
    let source = ReplaySource::synth(&params, Pacing::Realtime).unwrap();

    // Act: the client starts with the proxy down; the proxy comes back after 3 s, is killed
    // again mid-drawing (strokes open, meshes being fetched and stored) and back 3 s later.
    let drawing = tokio::spawn(async move {
        penmesh_client::live::draw(&endpoint, Box::new(source), &DrawOptions::new("pen")).await
    });
    tokio::time::sleep(Duration::from_secs(3)).await;
    proxy.restart().await;
    tokio::time::sleep(Duration::from_secs(3)).await;
    proxy.kill();
    tokio::time::sleep(Duration::from_secs(3)).await;
    proxy.restart().await;
    let reports = tokio::time::timeout(Duration::from_secs(90), drawing)
        .await
        .expect("the drawing ends")
        .expect("the client task")
        .expect("the client does not give up while the proxy comes back");

    // Assert: every stroke stored, done, with its mesh.
    assert_eq!(reports.len(), N_STROKES);
    let list: serde_json::Value = proxy
        .http()
        .get(proxy.url(&format!("/v1/sessions/{}/strokes", session.session)))
        .bearer_auth(&session.token)
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let listed = list["strokes"].as_array().unwrap();
    assert_eq!(listed.len(), N_STROKES, "{list}");
    for report in &reports {
        let info = listed.iter().find(|s| s["id"] == report.stroke.to_string()).unwrap();
        assert_eq!(info["status"], "done", "{info}");
        assert_eq!(info["has_mesh"], true, "{info}");
        assert_eq!(info["n_points"], report.n_resampled, "every streamed sample stored: {info}");
    }
}
