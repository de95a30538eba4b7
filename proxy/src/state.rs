//! The state every handler shares: settings, store, writer, shutdown signal, the per-session
//! hubs and the registry of strokes held by live connections.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use metrics_exporter_prometheus::PrometheusHandle;
use penmesh::protocol::{ServerMessage, StrokeId};
use tokio::sync::{Notify, broadcast};
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use uuid::Uuid;

use crate::config::Config;
use crate::store::{Store, Writer};

/// Cheap to clone: everything lives behind one `Arc`.
#[derive(Debug, Clone)]
pub struct AppState {
    inner: Arc<Inner>,
}

#[derive(Debug)]
pub struct Inner {
    pub config: Config,
    pub store: Store,
    pub writer: Writer,
    /// Cancelled when the proxy begins to shut down.
    pub shutdown: CancellationToken,
    /// Every WebSocket task, so shutdown can wait for them.
    pub tracker: TaskTracker,
    pub claims: Claims,
    pub metrics: PrometheusHandle,
    hubs: Mutex<HashMap<Uuid, SessionHub>>,
    next_connection: AtomicU64,
}

/// A session's live connections. The event channel is where the multi-user issue fans
/// `Peer*` events out (and where `LISTEN/NOTIFY` will feed events from other replicas).
#[derive(Debug)]
pub struct SessionHub {
    pub connections: usize,
    pub events: broadcast::Sender<ServerMessage>,
}

impl std::ops::Deref for AppState {
    type Target = Inner;
    fn deref(&self) -> &Inner {
        &self.inner
    }
}

impl AppState {
    pub fn new(
        config: Config,
        store: Store,
        writer: Writer,
        shutdown: CancellationToken,
        metrics: PrometheusHandle,
    ) -> AppState {
        AppState {
            inner: Arc::new(Inner {
                config,
                store,
                writer,
                shutdown,
                tracker: TaskTracker::new(),
                claims: Claims::default(),
                metrics,
                hubs: Mutex::new(HashMap::new()),
                next_connection: AtomicU64::new(1),
            }),
        }
    }

    pub fn next_connection_id(&self) -> u64 {
        self.next_connection.fetch_add(1, Ordering::Relaxed)
    }

    /// Counts a new connection in its session, unless the session is full.
    pub fn join_session(&self, session: Uuid) -> Option<SessionGuard> {
        let mut hubs = self.hubs.lock().expect("hubs lock");
        let hub = hubs
            .entry(session)
            .or_insert_with(|| SessionHub { connections: 0, events: broadcast::channel(1024).0 });
        if hub.connections >= self.config.max_connections_per_session {
            return None;
        }
        hub.connections += 1;
        Some(SessionGuard { state: self.clone(), session })
    }
}

/// A connection's place in its session; leaving is dropping it.
#[derive(Debug)]
pub struct SessionGuard {
    state: AppState,
    session: Uuid,
}

impl SessionGuard {
    pub fn events(&self) -> broadcast::Sender<ServerMessage> {
        let hubs = self.state.hubs.lock().expect("hubs lock");
        hubs[&self.session].events.clone()
    }
}

impl Drop for SessionGuard {
    fn drop(&mut self) {
        let mut hubs = self.state.hubs.lock().expect("hubs lock");
        if let Some(hub) = hubs.get_mut(&self.session) {
            hub.connections -= 1;
            if hub.connections == 0 {
                hubs.remove(&self.session);
            }
        }
    }
}

/// Which connection holds which stroke: a stroke is drawn on one connection at a time.
#[derive(Debug, Default)]
pub struct Claims {
    held: Mutex<HashMap<StrokeId, u64>>,
    released: Notify,
}

impl Claims {
    /// Takes `stroke` for connection `conn`, waiting up to `wait` for another holder to let go
    /// (a client that reconnects faster than its old connection is noticed gone).
    pub async fn claim(&self, stroke: StrokeId, conn: u64, wait: Duration) -> bool {
        let deadline = tokio::time::Instant::now() + wait;
        loop {
            let notified = self.released.notified();
            tokio::pin!(notified);
            notified.as_mut().enable();
            {
                let mut held = self.held.lock().expect("claims lock");
                match held.get(&stroke) {
                    None => {
                        held.insert(stroke, conn);
                        return true;
                    }
                    Some(&holder) if holder == conn => return true,
                    Some(_) => {}
                }
            }
            if tokio::time::timeout_at(deadline, notified).await.is_err() {
                return false;
            }
        }
    }

    pub fn release(&self, stroke: StrokeId, conn: u64) {
        let mut held = self.held.lock().expect("claims lock");
        if held.get(&stroke) == Some(&conn) {
            held.remove(&stroke);
        }
        drop(held);
        self.released.notify_waiters();
    }
}
