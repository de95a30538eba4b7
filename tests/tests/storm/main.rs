//! A join storm (issue 25): thirty native clients, each replaying ten real strokes, join one
//! session at the same moment on the default proxy (SQLite, or PostgreSQL with
//! `PENMESH_TEST_POSTGRES_URL`). Every stroke is stored with its mesh, no client gives up, and
//! the proxy answers no request with a 5xx.
//!
//! A test binary of its own: the proxy's metrics are one process-wide recorder, so the count of
//! internal errors read here is this test's alone.

use penmesh_client::draw_options::DrawOptions;
use penmesh_client::endpoint::Endpoint;
use penmesh_client::input::{Pacing, ReplaySource};
use penmesh_e2e::spawn_proxy;

/// Native clients in the storm, and the real strokes each replays.
const N_CLIENTS: usize = 30;
const STROKES_PER_CLIENT: usize = 10;
/// Strokes in the session before the storm, so that every newcomer's history has some.
const N_EARLY: usize = 5;

/// Every real stroke of the recordings beside the checkout (`../shared/data`: SigComp2011,
/// then SVC2004).
fn real_strokes() -> Vec<penmesh::Stroke> {
    penmesh::data_sets::DATA_SETS
        .iter()
        .flat_map(|set| set.read().unwrap_or_else(|err| panic!("{err}")))
        .flat_map(|recording| recording.strokes)
        .collect()
}

/// Draws `strokes` as one person through the native client's live path.
async fn draw(
    endpoint: &Endpoint,
    name: String,
    strokes: Vec<penmesh::Stroke>,
) -> anyhow::Result<Vec<penmesh_client::reconstruct::StrokeReport>> {
    let source = ReplaySource::new(name.clone(), strokes, Pacing::Fast);
    penmesh_client::live::draw(endpoint, Box::new(source), &DrawOptions::new(name)).await
}

/// The answers with a 5xx status: `penmesh_http_errors_total` of the codes that have one.
fn internal_errors(metrics: &str) -> f64 {
    let server_error = |l: &str| {
        ["internal", "busy", "shutting_down"].iter().any(|c| l.contains(&format!("code=\"{c}\"")))
    };
    metrics
        .lines()
        .filter(|l| l.starts_with("penmesh_http_errors_total") && server_error(l))
        .filter_map(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
        .sum()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn thirty_native_clients_joining_at_once_store_every_stroke_with_its_mesh() {
    // Arrange: a session that already holds strokes with meshes, and the real strokes.
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let endpoint = Endpoint::new(&proxy.address, session.session, session.token.clone()).unwrap();
    let strokes = real_strokes();
    let early = draw(&endpoint, "early".into(), strokes[..N_EARLY].to_vec()).await;
    let early = early.expect("the early strokes");
    assert_eq!(early.len(), N_EARLY);
    let errors_before = internal_errors(&proxy.metrics().await);

    // Act: every client starts at the same moment.
    let start = std::sync::Arc::new(tokio::sync::Barrier::new(N_CLIENTS));
    let mut clients = tokio::task::JoinSet::new();
    for i in 0..N_CLIENTS {
        // Each client its own ten strokes while there are enough (a person may replay a file
        // another replays too).
        let mine: Vec<_> = (0..STROKES_PER_CLIENT)
            .map(|j| strokes[(N_EARLY + i * STROKES_PER_CLIENT + j) % strokes.len()].clone())
            .collect();
        let (endpoint, start) = (endpoint.clone(), start.clone());
        clients.spawn(async move {
            start.wait().await;
            (i, draw(&endpoint, format!("person {i}"), mine).await)
        });
    }
    let mut reports = early;
    while let Some(joined) = clients.join_next().await {
        let (i, drawn) = joined.expect("a client task panicked");
        let drawn = drawn.unwrap_or_else(|e| panic!("client {i} gave up: {e:#}"));
        assert_eq!(drawn.len(), STROKES_PER_CLIENT, "client {i}: a report per stroke");
        reports.extend(drawn);
    }

    // Assert: the proxy holds every stroke, done, with the mesh its client built; no 5xx.
    let listed =
        proxy.get_json(&format!("/v1/sessions/{}/strokes", session.session), &session).await;
    let listed = listed["strokes"].as_array().expect("a list of strokes");
    assert_eq!(listed.len(), N_EARLY + N_CLIENTS * STROKES_PER_CLIENT, "every stroke stored");
    for stroke in listed {
        assert_eq!(stroke["status"], "done", "{stroke}");
        assert_eq!(stroke["has_mesh"], true, "{stroke}");
    }
    for report in &reports {
        assert!(report.exact, "stroke {}: stored as drawn", report.stroke);
    }
    let errors = internal_errors(&proxy.metrics().await) - errors_before;
    assert_eq!(errors, 0.0, "the proxy answered {errors} requests with a 5xx");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn native_clients_behind_the_sessions_events_go_on_drawing() {
    // Arrange: a proxy that keeps very little of the session's events for each connection,
    // so that every client drawing at full speed falls behind the others' events.
    let proxy = penmesh_e2e::spawn_proxy_with(|c| {
        c.outgoing_queue = 4;
        c.outgoing_queue_bytes = 2048;
    })
    .await;
    let session = proxy.create_session().await;
    let endpoint = Endpoint::new(&proxy.address, session.session, session.token.clone()).unwrap();
    let strokes = real_strokes();

    // Act: six people draw twenty real strokes each at once, as fast as the proxy takes them.
    let mut clients = tokio::task::JoinSet::new();
    for i in 0..6 {
        let mine: Vec<_> = (0..20).map(|j| strokes[(i * 20 + j) % strokes.len()].clone()).collect();
        let endpoint = endpoint.clone();
        clients.spawn(async move { (i, draw(&endpoint, format!("fast {i}"), mine).await) });
    }

    // Assert: nobody gives up, every stroke is stored with its mesh.
    while let Some(joined) = clients.join_next().await {
        let (i, drawn) = joined.expect("a client task panicked");
        let drawn = drawn.unwrap_or_else(|e| panic!("client {i} gave up: {e:#}"));
        assert_eq!(drawn.len(), 20, "client {i}");
    }
    let listed =
        proxy.get_json(&format!("/v1/sessions/{}/strokes", session.session), &session).await;
    let listed = listed["strokes"].as_array().expect("a list of strokes");
    assert_eq!(listed.len(), 6 * 20);
    assert!(listed.iter().all(|s| s["status"] == "done" && s["has_mesh"] == true));
}

mod model;
