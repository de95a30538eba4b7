//! The penmesh simplification proxy: WebSocket ingest with streaming ACUTS, an HTTP API,
//! SQLite or PostgreSQL storage with group commit, multi-user sessions (fan-out with history
//! and live events, `fanout`) and, on PostgreSQL, any number of replicas (`cluster`).
//!
//! Entry points: [`Config`] (settings), [`Application`] (bind, run, shut down) and [`router`].

mod bundle_body;
mod change_history;
mod cluster;
mod config;
mod events;
mod export;
mod fanout;
mod flight;
mod glb;
mod http;
mod identity;
mod import;
mod ingest;
mod kept_prints;
mod mesh_build;
mod metrics;
mod openapi;
mod placement;
mod query;
mod rate;
mod removal;
mod scene;
mod send_deadline;
mod session_meshes;
mod solid;
mod stages;
mod startup;
mod state;
mod store;
mod web;
mod ws;

// The surface the binaries, the client's in-process demo and the end-to-end tests use; the
// rest of the crate is private to it.
pub use crate::change_history::{MAX_HISTORY_PAGE, MAX_HISTORY_READS};
pub use crate::cluster::{LISTENER_APPLICATION, LOCKS_APPLICATION, REAP_INTERVAL};
pub use crate::config::{Config, SqliteSync};
pub use crate::http::READY_DB_DEADLINE;
pub use crate::identity::participant_id;
pub use crate::kept_prints::{KEPT_FOR, KeptPrints, MAX_KEPT_PRINT_BYTES, MAX_KEPT_PRINTS};
pub use crate::mesh_build::PROXY_UPLOADER;
pub use crate::placement::MAX_DUPLICATES;
pub use crate::scene::MAX_SCENE_SAMPLES;
pub use crate::startup::{Application, router};
pub use crate::state::AppState;
pub use crate::store::{decode_samples as decode_stored_samples, hash_token};
// Test-only: failures injected into the writer, and where a stroke's samples are stored.
#[cfg(feature = "fault-injection")]
pub use crate::store::{CommitFaults, Fault, stored_pieces};
pub use crate::ws::{Frame, ReadError, forward as forward_frames, serve, split as split_socket};

/// Runs the proxy with `config` until it is stopped (SIGTERM, Ctrl-C), on a runtime of its own
/// whose threads run [`Config::worker_nice`] steps below the priority of the calling thread,
/// which the group-commit writer keeps: past the knee every connection waits for the writer,
/// and on a busy machine each of the writer's round trips to the database otherwise waited for
/// a connection thread's time slice (at 350 pens on 2 cores: p99 442 ms, 148 ms with nice 10).
pub fn run(config: Config) -> anyhow::Result<()> {
    let nice = config.worker_nice;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .on_thread_start(move || lower_priority(nice))
        .build()?;
    runtime.block_on(async { Application::build(config).await?.run_until_stopped().await })
}

/// Lowers the calling thread's priority by `steps` nice steps (best effort: it only logs).
fn lower_priority(steps: i32) {
    #[cfg(target_os = "linux")]
    if steps > 0 {
        // On Linux the nice value belongs to each thread, and `None` means the calling one.
        let current = rustix::process::getpriority_process(None).unwrap_or(0);
        if let Err(err) = rustix::process::setpriority_process(None, (current + steps).min(19)) {
            tracing::debug!("cannot lower the priority of a worker thread: {err}");
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = steps;
}

/// Logs to stderr, filtered by `RUST_LOG` (default `info`).
pub fn init_tracing() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    let _ =
        tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).try_init();
}
