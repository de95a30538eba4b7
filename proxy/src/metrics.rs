//! Prometheus metrics: one process-wide recorder, rendered at `/metrics`.
//!
//! Names: `penmesh_ws_connections` (gauge), `penmesh_ws_connections_total`,
//! `penmesh_ws_frames_total{direction,kind}`, `penmesh_samples_in_total`,
//! `penmesh_samples_retained_total`, `penmesh_strokes_total{event}`,
//! `penmesh_errors_total{code}`, `penmesh_http_errors_total{code}`,
//! `penmesh_ws_slow_reader_disconnects_total`, `penmesh_commit_seconds` (histogram),
//! `penmesh_commit_batch_requests` and `penmesh_commit_batch_samples` (histograms),
//! `penmesh_commit_failures_total`, `penmesh_sessions_total`, `penmesh_meshes_total`;
//! sessions: `penmesh_fanout_events_total` (peer events sent), `penmesh_fanout_syncs_total`
//! (history sent: joins and resyncs), `penmesh_fanout_lagged_total` (queues that overflowed),
//! `penmesh_listener_resyncs_total` (the `LISTEN` connection dropped); exports:
//! `penmesh_prints_total{answer}` (`made`: a print's work started; `existing`: a request
//! answered by a print kept or being made, `crate::kept_prints`).

use std::sync::OnceLock;

use metrics::Counter;
use metrics_exporter_prometheus::{Matcher, PrometheusBuilder, PrometheusHandle};

static HANDLE: OnceLock<PrometheusHandle> = OnceLock::new();

/// The counters a connection moves for every batch, looked up once: a `counter!` call hashes
/// its name and labels and searches the registry each time, about 1 % of the proxy's CPU under
/// load when it ran per frame. Handles are registered with the recorder installed when they are
/// made, so they are made after [`install`] ([`crate::state::AppState::new`]).
#[derive(Debug, Clone)]
pub struct HotCounters {
    pub frames_in_binary: Counter,
    pub frames_in_text: Counter,
    pub frames_out_binary: Counter,
    pub frames_out_text: Counter,
    pub samples_in: Counter,
    pub samples_retained: Counter,
    pub fanout_events: Counter,
}

impl HotCounters {
    pub fn register() -> HotCounters {
        let frames = |direction: &'static str, kind: &'static str| metrics::counter!("penmesh_ws_frames_total", "direction" => direction, "kind" => kind);
        HotCounters {
            frames_in_binary: frames("in", "binary"),
            frames_in_text: frames("in", "text"),
            frames_out_binary: frames("out", "binary"),
            frames_out_text: frames("out", "text"),
            samples_in: metrics::counter!("penmesh_samples_in_total"),
            samples_retained: metrics::counter!("penmesh_samples_retained_total"),
            fanout_events: metrics::counter!("penmesh_fanout_events_total"),
        }
    }
}

/// Installs the recorder on first use (several applications in one test process share it).
pub fn install() -> PrometheusHandle {
    HANDLE
        .get_or_init(|| {
            let recorder = PrometheusBuilder::new()
                .set_buckets_for_metric(
                    Matcher::Full("penmesh_commit_seconds".into()),
                    &[0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.25, 0.5, 1.0, 5.0],
                )
                .and_then(|b| {
                    b.set_buckets_for_metric(
                        Matcher::Prefix("penmesh_commit_batch_".into()),
                        &[1.0, 2.0, 5.0, 10.0, 50.0, 100.0, 500.0, 1000.0, 5000.0, 20000.0],
                    )
                })
                .expect("bucket lists are not empty")
                .build_recorder();
            let handle = recorder.handle();
            if metrics::set_global_recorder(recorder).is_err() {
                tracing::warn!("a metrics recorder was already installed; /metrics will be empty");
            }
            describe();
            handle
        })
        .clone()
}

fn describe() {
    use metrics::{describe_counter, describe_gauge, describe_histogram};
    describe_gauge!("penmesh_ws_connections", "WebSocket connections open now");
    describe_counter!("penmesh_ws_connections_total", "WebSocket connections accepted");
    describe_counter!("penmesh_ws_frames_total", "WebSocket frames by direction and kind");
    describe_counter!("penmesh_samples_in_total", "Samples received in points batches");
    describe_counter!("penmesh_samples_retained_total", "Samples sent back as retained");
    describe_counter!("penmesh_strokes_total", "Strokes begun, done, interrupted");
    describe_counter!("penmesh_errors_total", "Protocol errors sent, by code");
    describe_counter!("penmesh_http_errors_total", "HTTP error responses, by code");
    describe_counter!(
        "penmesh_ws_slow_reader_disconnects_total",
        "Connections dropped for a full outgoing queue"
    );
    describe_histogram!("penmesh_commit_seconds", metrics::Unit::Seconds, "Group commit latency");
    describe_histogram!("penmesh_commit_batch_requests", "Write requests per group commit");
    describe_histogram!("penmesh_commit_batch_samples", "Samples per group commit");
    describe_counter!("penmesh_commit_failures_total", "Write requests that failed to commit");
    describe_counter!(
        "penmesh_prints_total",
        "Print requests: made (the work started) or existing (a kept print, or one being made)"
    );
    describe_counter!(
        "penmesh_log_set_aside_total",
        "Append-log records set aside in stroke_log_set_aside: their entries cannot be moved"
    );
}
