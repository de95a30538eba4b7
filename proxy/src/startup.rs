//! Building and running the application: bind first (so port 0 works and [`Application::port`]
//! tells the real one), then serve until a signal or the test handle asks to stop.
//!
//! Shutdown, all within `shutdown_grace_secs`: new upgrades get 503 and the listener stops;
//! every WebSocket task commits what it has, marks its open strokes `interrupted`, sends
//! `Error {shutting_down}` and Close 1001; then the writer commits what is left and stops.
//!
//! With SQLite the proxy is the only replica (it says so at start). With PostgreSQL it starts
//! the session-event listener and the stroke-lock connection ([`crate::cluster`]), so any
//! number of replicas can serve one database.

use axum::serve::ListenerExt;
use std::time::Duration;

use anyhow::Context;
use axum::Router;
use axum::extract::DefaultBodyLimit;
use axum::routing::{get, post, put};
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;
use tower_http::trace::TraceLayer;
use utoipa::OpenApi;

use crate::cluster::{StrokeLocks, start_listener, start_reaper};
use crate::config::Config;
use crate::fanout::Fanout;
use crate::state::AppState;
use crate::store::{Backend, Store, WriterTask, redact, start_checkpointer};
use crate::{http, mesh_build, metrics, web, ws};

/// A bound, ready-to-run proxy.
#[derive(Debug)]
pub struct Application {
    listener: TcpListener,
    port: u16,
    state: AppState,
    writer: WriterTask,
    /// The background tasks, and what stops them: the session-event listener and the presence
    /// reaper (PostgreSQL), or the log checkpointer (SQLite).
    listener_task: Option<(Vec<tokio::task::JoinHandle<()>>, CancellationToken)>,
}

impl Application {
    /// Connects to the database (migrating it), starts the writer and binds the listener.
    pub async fn build(config: Config) -> anyhow::Result<Application> {
        Application::build_with_faults(config, None).await
    }

    /// [`Application::build`] with failures injected into the writer's transactions: for the
    /// tests of the write path's failure handling only.
    pub async fn build_with_faults(
        config: Config,
        faults: Option<std::sync::Arc<crate::store::CommitFaults>>,
    ) -> anyhow::Result<Application> {
        config.check()?;
        let metrics = metrics::install();
        let store = Store::connect(&config).await?;
        let orphans = store.interrupt_orphans().await?;
        if orphans > 0 {
            tracing::info!(orphans, "strokes left open by an earlier run are now interrupted");
        }
        let fanout = Fanout::default();
        let (listener, locks) = match store.backend() {
            Backend::Sqlite => {
                tracing::info!(
                    "SQLite: this proxy is the only replica of its database; to run several \
                     replicas behind a load balancer, use PostgreSQL (see docs/deploy.md)"
                );
                let stop = CancellationToken::new();
                let checkpointer = start_checkpointer(store.clone(), stop.clone());
                (Some((vec![checkpointer], stop)), None)
            }
            Backend::Postgres => {
                let stop = CancellationToken::new();
                // Both need a session of their own: past a transaction pooler, the direct URL.
                let direct = config.direct_database_url();
                let deadline = store.deadline();
                let heartbeat = Duration::from_millis(config.listener_heartbeat_ms);
                let task =
                    start_listener(direct, fanout.clone(), stop.clone(), heartbeat, deadline)
                        .await?;
                let locks = StrokeLocks::connect(direct, deadline).await?;
                let reaper = start_reaper(store.clone(), stop.clone());
                tracing::info!(
                    "PostgreSQL: replicas share session events (LISTEN/NOTIFY) and stroke \
                     ownership (advisory locks)"
                );
                (Some((vec![task, reaper], stop)), Some(locks))
            }
        };
        let (writer, writer_task) = WriterTask::start(
            &store,
            Duration::from_millis(config.commit_interval_ms),
            config.commit_max_requests,
            config.writer_queue,
            fanout.clone(),
            faults,
        )
        .await?;
        let tcp = TcpListener::bind((config.host.as_str(), config.port))
            .await
            .with_context(|| format!("binding {}:{}", config.host, config.port))?;
        let port = tcp.local_addr()?.port();
        tracing::info!(
            address = %tcp.local_addr()?,
            database = %redact(&config.database_url),
            "penmesh proxy listening"
        );
        let state =
            AppState::new(config, store, writer, CancellationToken::new(), metrics, fanout, locks);
        Ok(Application { listener: tcp, port, state, writer: writer_task, listener_task: listener })
    }

    /// The port actually bound.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// Cancelling this token shuts the application down, as SIGTERM does.
    pub fn shutdown_handle(&self) -> CancellationToken {
        self.state.shutdown.clone()
    }

    pub fn state(&self) -> &AppState {
        &self.state
    }

    /// Serves until SIGTERM, Ctrl-C or the shutdown handle, then shuts down gracefully.
    pub async fn run_until_stopped(self) -> anyhow::Result<()> {
        let Application { listener, state, writer, listener_task, .. } = self;
        let shutdown = state.shutdown.clone();
        // SIGTERM is caught from here on, before the first request is served: a platform may
        // stop an instance the moment it is ready.
        #[cfg(unix)]
        let term = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate());
        #[cfg(not(unix))]
        let term = ();
        let signals = tokio::spawn(cancel_on_signal(shutdown.clone(), term));
        let server = tokio::spawn(
            // Nagle's algorithm would hold small frames (Ack, StrokeDone) until the peer's
            // delayed ACK, adding tens of milliseconds to each answer.
            axum::serve(
                listener.tap_io(|tcp| {
                    if let Err(err) = tcp.set_nodelay(true) {
                        tracing::debug!("cannot set TCP_NODELAY: {err}");
                    }
                }),
                router(state.clone()),
            )
            .with_graceful_shutdown(shutdown.clone().cancelled_owned())
            .into_future(),
        );
        shutdown.cancelled().await;
        signals.abort();
        let grace = Duration::from_secs(state.config.shutdown_grace_secs);
        let deadline = tokio::time::Instant::now() + grace;
        tracing::info!(grace_secs = grace.as_secs(), "shutting down");
        state.tracker.close();
        if tokio::time::timeout_at(deadline, state.tracker.wait()).await.is_err() {
            tracing::warn!(left = state.tracker.len(), "WebSocket tasks outlived the grace period");
        }
        let mut server = server;
        match tokio::time::timeout_at(deadline, &mut server).await {
            Ok(Ok(Err(err))) => tracing::error!(error = %err, "server failed"),
            Ok(_) => {}
            Err(_) => {
                tracing::warn!("HTTP connections outlived the grace period");
                server.abort();
            }
        }
        writer.stop().await;
        if let Some((tasks, stop)) = listener_task {
            stop.cancel();
            for task in tasks {
                let _ = task.await;
            }
        }
        state.store.pool().close().await;
        tracing::info!("stopped");
        Ok(())
    }
}

#[cfg(unix)]
async fn cancel_on_signal(
    shutdown: CancellationToken,
    term: std::io::Result<tokio::signal::unix::Signal>,
) {
    let ctrl_c = tokio::signal::ctrl_c();
    match term {
        Ok(mut term) => {
            tokio::select! {
                _ = ctrl_c => {}
                _ = term.recv() => {}
            }
        }
        Err(err) => {
            tracing::warn!(error = %err, "cannot listen for SIGTERM");
            let _ = ctrl_c.await;
        }
    }
    shutdown.cancel();
}

#[cfg(not(unix))]
async fn cancel_on_signal(shutdown: CancellationToken, _term: ()) {
    let _ = tokio::signal::ctrl_c().await;
    shutdown.cancel();
}

/// Every route of the proxy.
pub fn router(state: AppState) -> Router {
    let body_limit = state.config.max_body_bytes;
    Router::new()
        .route("/v1/sessions", post(http::create_session))
        .route("/v1/sessions/{session}/strokes", get(http::list_strokes))
        .route("/v1/sessions/{session}/ws", get(ws::ws_handler))
        .route("/v1/strokes/{id}/simplified", get(http::simplified))
        .route("/v1/strokes/{id}/raw", get(http::raw))
        .route("/v1/strokes/{id}/mesh", put(http::put_mesh).get(http::get_mesh))
        .route("/v1/strokes/{id}/mesh/build", post(mesh_build::build_mesh))
        .route("/v1/openapi.json", get(openapi_json))
        .merge(web::routes())
        .route("/healthz", get(http::healthz))
        .route("/readyz", get(http::readyz))
        .route("/metrics", get(http::metrics))
        .layer(DefaultBodyLimit::max(body_limit))
        .layer(TraceLayer::new_for_http())
        .with_state(state)
}

async fn openapi_json() -> axum::Json<utoipa::openapi::OpenApi> {
    axum::Json(crate::openapi::ApiDoc::openapi())
}
