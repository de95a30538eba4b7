//! The penmesh simplification proxy: WebSocket ingest with streaming ACUTS, an HTTP API,
//! SQLite or PostgreSQL storage with group commit, multi-user sessions (fan-out with history
//! and live events, `fanout`) and, on PostgreSQL, any number of replicas (`cluster`).
//!
//! Entry points: [`Config`] (settings), [`Application`] (bind, run, shut down) and [`router`].

mod cluster;
mod config;
mod fanout;
mod glb;
mod http;
mod ingest;
mod metrics;
mod openapi;
mod startup;
mod state;
mod store;
mod ws;

pub use crate::cluster::{LISTENER_APPLICATION, LOCKS_APPLICATION, lock_key};
pub use crate::config::{Config, SqliteSync};
pub use crate::fanout::{
    Admit, EventKind, Fanout, Lag, PeerView, Published, SessionEvent, Subscription,
};
pub use crate::glb::{MeshCounts, inspect as inspect_glb};
pub use crate::http::{
    AppError, ErrorBody, MeshInfo, NewSession, StrokeInfo, StrokeList, StrokeSamples,
};
pub use crate::ingest::{Accepted, Finished, Refusal, StrokeLimits, StrokeState};
pub use crate::openapi::ApiDoc;
pub use crate::startup::{Application, router};
pub use crate::state::AppState;
pub use crate::store::{Backend, Store, hash_token};
pub use crate::ws::{Frame, close_code, serve};

/// Logs to stderr, filtered by `RUST_LOG` (default `info`).
pub fn init_tracing() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    let _ =
        tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).try_init();
}
