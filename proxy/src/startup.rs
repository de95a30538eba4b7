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

use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use axum::Router;
use axum::extract::{ConnectInfo, DefaultBodyLimit};
use axum::http::{Request, StatusCode};
use axum::routing::{delete, get, post, put};
use hyper::body::Incoming;
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;
use tower_http::classify::{ServerErrorsAsFailures, SharedClassifier};
use tower_http::timeout::TimeoutLayer;
use tower_http::trace::TraceLayer;
use utoipa::OpenApi;

use crate::cluster::{StrokeLocks, start_listener, start_lock_keeper, start_reaper};
use crate::config::Config;
use crate::fanout::Fanout;
use crate::send_deadline::{DeadlineIo, SendDeadline};
use crate::state::AppState;
use crate::store::{Backend, InjectedFaults, Store, WriterTask, start_checkpointer};
use crate::{
    export, http, import, mesh_build, metrics, placement, removal, send_deadline, session_meshes,
    solid, web, ws,
};

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
        Application::build_injecting(config, None).await
    }

    /// [`Application::build`] with failures injected into the writer's transactions: for the
    /// tests of the write path's failure handling only (the `fault-injection` feature).
    #[cfg(feature = "fault-injection")]
    pub async fn build_with_faults(
        config: Config,
        faults: Option<std::sync::Arc<crate::store::CommitFaults>>,
    ) -> anyhow::Result<Application> {
        Application::build_injecting(config, faults).await
    }

    async fn build_injecting(
        config: Config,
        faults: InjectedFaults,
    ) -> anyhow::Result<Application> {
        config.check()?;
        let metrics = metrics::install();
        if config.stage_timing {
            crate::stages::enable();
        }
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
                let listener = start_listener(
                    direct.expose(),
                    fanout.clone(),
                    stop.clone(),
                    heartbeat,
                    deadline,
                );
                let task = listener.await?;
                let locks = Arc::new(StrokeLocks::connect(direct.expose(), deadline).await?);
                let keeper = start_lock_keeper(locks.clone(), stop.clone());
                let reaper = start_reaper(store.clone(), stop.clone());
                tracing::info!(
                    "PostgreSQL: replicas share session events (LISTEN/NOTIFY) and stroke \
                     ownership (advisory locks)"
                );
                (Some((vec![task, keeper, reaper], stop)), Some(locks))
            }
        };
        let (writer, writer_task) = WriterTask::start(
            &store,
            Duration::from_millis(config.commit_interval_ms),
            config.commit_max_requests,
            config.writer_queue,
            fanout.clone(),
            faults,
            locks.as_deref().map(StrokeLocks::replica_key),
        )
        .await?;
        let writer = writer.limit_bytes(config.writer_queue_bytes);
        let tcp = TcpListener::bind((config.host.as_str(), config.port))
            .await
            .with_context(|| format!("binding {}:{}", config.host, config.port))?;
        let port = tcp.local_addr()?.port();
        tracing::info!(
            address = %tcp.local_addr()?,
            database = %config.database_url,
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
        let header_timeout = Duration::from_secs(state.config.header_timeout_secs);
        let server =
            tokio::spawn(serve(listener, router(state.clone()), header_timeout, shutdown.clone()));
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

/// Serves `router` on `listener` until `stop`, then lets the open connections finish (the
/// caller bounds how long). HTTP/1.1 only, through hyper directly rather than `axum::serve`,
/// which sets no timer, so hyper's header-read timeout would not apply: a connection that
/// has not sent a whole request head within `header_timeout` of opening (or of its previous
/// request) is closed (slowloris). Each request carries the peer's address as `ConnectInfo`.
async fn serve(
    listener: TcpListener,
    router: Router,
    header_timeout: Duration,
    stop: CancellationToken,
) {
    use hyper_util::rt::{TokioIo, TokioTimer};
    use tower::ServiceExt;
    // hyper's HTTP/1 builder itself: hyper-util's `auto` one first waits, with no timeout, for
    // enough bytes to tell HTTP/1 from HTTP/2.
    let mut builder = hyper::server::conn::http1::Builder::new();
    builder.timer(TokioTimer::new()).header_read_timeout(header_timeout);
    let connections = tokio_util::task::TaskTracker::new();
    loop {
        let (tcp, peer) = tokio::select! {
            _ = stop.cancelled() => break,
            accepted = listener.accept() => match accepted {
                Ok(accepted) => accepted,
                Err(err) => {
                    // Out of file descriptors, say: wait instead of spinning.
                    tracing::warn!(error = %err, "accepting a connection failed");
                    tokio::time::sleep(Duration::from_millis(100)).await;
                    continue;
                }
            },
        };
        // Nagle's algorithm would hold small frames (Ack, StrokeDone) until the peer's
        // delayed ACK, adding tens of milliseconds to each answer.
        if let Err(err) = tcp.set_nodelay(true) {
            tracing::debug!("cannot set TCP_NODELAY: {err}");
        }
        let router = router.clone();
        let deadline = SendDeadline::default();
        let io = TokioIo::new(DeadlineIo::new(tcp, deadline.clone()));
        let service = hyper::service::service_fn(move |mut request: Request<Incoming>| {
            // The previous response is written: no deadline until a route sets one.
            deadline.set(None);
            request.extensions_mut().insert(ConnectInfo(peer));
            request.extensions_mut().insert(deadline.clone());
            router.clone().oneshot(request.map(axum::body::Body::new))
        });
        let connection = builder.serve_connection(io, service).with_upgrades();
        let stop = stop.clone();
        connections.spawn(async move {
            let mut connection = std::pin::pin!(connection);
            let result = tokio::select! {
                result = connection.as_mut() => result,
                _ = stop.cancelled() => {
                    // Finish the request in progress, then close.
                    connection.as_mut().graceful_shutdown();
                    connection.await
                }
            };
            if let Err(err) = result {
                tracing::debug!(error = %err, "HTTP connection ended");
            }
        });
    }
    drop(listener);
    connections.close();
    connections.wait().await;
}

/// The span of an HTTP request: method and path, never the query string, which may carry a
/// secret (`?token=` from a client that should not send one).
fn request_span(request: &Request<axum::body::Body>) -> tracing::Span {
    tracing::debug_span!(
        "request",
        method = %request.method(),
        path = %request.uri().path(),
        version = ?request.version(),
    )
}

type RequestSpan = fn(&Request<axum::body::Body>) -> tracing::Span;

/// The request log: spans from [`request_span`].
fn trace_layer() -> TraceLayer<SharedClassifier<ServerErrorsAsFailures>, RequestSpan> {
    TraceLayer::new_for_http().make_span_with(request_span as RequestSpan)
}

/// Every route of the proxy.
pub fn router(state: AppState) -> Router {
    let body_limit = state.config.max_body_bytes;
    let request_timeout = Duration::from_secs(state.config.request_timeout_secs);
    // The WebSocket lives as long as the connection: no request timeout on it.
    let websocket = Router::new().route("/v1/sessions/{session}/ws", get(ws::ws_handler));
    // The export keeps its own request timeout, whose 408 leaves a print going on for the
    // retry (`export::export_print`); the send deadline is the same.
    let export = Router::new()
        .route("/v1/sessions/{session}/export", get(export::export_print))
        .layer(axum::middleware::from_fn_with_state(request_timeout, send_deadline::arm));
    Router::new()
        .route("/v1/sessions", post(http::create_session))
        .route("/v1/sessions/{session}/strokes", get(http::list_strokes))
        .route("/v1/sessions/{session}/meshes", get(session_meshes::session_meshes))
        .route("/v1/sessions/{session}/import", post(import::import_scene))
        .route("/v1/strokes/{id}/simplified", get(http::simplified))
        .route("/v1/strokes/{id}/raw", get(http::raw))
        .route("/v1/strokes/{id}/mesh", put(http::put_mesh).get(http::get_mesh))
        .route("/v1/strokes/{id}/mesh/build", post(mesh_build::build_mesh))
        .route("/v1/strokes/{id}", delete(removal::remove_stroke))
        .route("/v1/strokes/{id}/restore", post(removal::restore_stroke))
        .route("/v1/strokes/{id}/placement", put(placement::put_placement))
        .route("/v1/strokes/{id}/placements", get(placement::placements))
        .route("/v1/strokes/{id}/solid", put(solid::put_solid))
        .route("/v1/strokes/{id}/solids", get(solid::solids))
        .route("/v1/strokes/{id}/duplicate", post(placement::duplicate))
        .route("/v1/openapi.json", get(openapi_json))
        .merge(web::routes())
        .route("/healthz", get(http::healthz))
        .route("/readyz", get(http::readyz))
        .route("/metrics", get(http::metrics))
        .layer(TimeoutLayer::with_status_code(StatusCode::REQUEST_TIMEOUT, request_timeout))
        .layer(axum::middleware::from_fn_with_state(request_timeout, send_deadline::arm))
        .merge(export)
        .merge(websocket)
        .layer(DefaultBodyLimit::max(body_limit))
        .layer(trace_layer())
        .with_state(state)
}

async fn openapi_json() -> axum::Json<utoipa::openapi::OpenApi> {
    axum::Json(crate::openapi::ApiDoc::openapi())
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};

    use axum::body::Body;
    use tower::ServiceExt;

    use super::*;

    /// Log lines, shared with the subscriber that writes them.
    #[derive(Clone, Default)]
    struct Captured(Arc<Mutex<Vec<u8>>>);

    impl std::io::Write for Captured {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    /// What a request to `/v1/x?token=secret` logs at the most verbose level through `layer`.
    fn logs_of<L>(layer: L) -> String
    where
        L: tower::Layer<axum::routing::Route> + Clone + Send + Sync + 'static,
        L::Service: tower::Service<Request<Body>, Error = std::convert::Infallible>
            + Clone
            + Send
            + Sync
            + 'static,
        <L::Service as tower::Service<Request<Body>>>::Response:
            axum::response::IntoResponse + 'static,
        <L::Service as tower::Service<Request<Body>>>::Future: Send + 'static,
    {
        let captured = Captured::default();
        let writer = captured.clone();
        let subscriber = tracing_subscriber::fmt()
            .with_max_level(tracing::Level::TRACE)
            .with_ansi(false)
            .with_writer(move || writer.clone())
            .finish();
        tracing::subscriber::with_default(subscriber, || {
            let runtime = tokio::runtime::Builder::new_current_thread().build().unwrap();
            runtime.block_on(async {
                let app = Router::new().route("/v1/x", get(|| async { "ok" })).layer(layer);
                let request = Request::get("/v1/x?token=secret").body(Body::empty()).unwrap();
                assert_eq!(app.oneshot(request).await.unwrap().status(), 200);
            });
        });
        String::from_utf8(captured.0.lock().unwrap().clone()).unwrap()
    }

    #[test]
    fn a_token_in_the_query_string_does_not_reach_the_logs() {
        // tower-http's default span logs the whole URI: the capture does see it.
        let default = logs_of(TraceLayer::new_for_http());
        assert!(default.contains("secret"), "the capture works: {default}");
        let ours = logs_of(trace_layer());
        assert!(ours.contains("/v1/x"), "the path is logged: {ours}");
        assert!(!ours.contains("secret") && !ours.contains("token="), "{ours}");
    }
}
