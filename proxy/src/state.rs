//! The state every handler shares: settings, store, writer, shutdown signal, the session
//! fan-out, the per-session connection counts, the WebSocket slots (per replica and per client
//! address) and the registry of strokes held by live connections (with PostgreSQL backed by
//! advisory locks, so it holds across replicas).

use std::collections::{HashMap, HashSet};
use std::net::IpAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use metrics_exporter_prometheus::PrometheusHandle;
use penmesh::protocol::StrokeId;
use tokio::sync::Notify;
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use uuid::Uuid;

use crate::cluster::StrokeLocks;
use crate::config::Config;
use crate::fanout::Fanout;
use crate::store::{Store, Writer};

/// An HTTP body larger than this needs one of `max_large_bodies` permits
/// ([`AppState::large_body`]).
pub const LARGE_BODY_BYTES: u64 = 1 << 20;

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
    /// The per-batch counters, looked up once.
    pub counters: crate::metrics::HotCounters,
    /// Where committed session events reach this replica's connections.
    pub fanout: Fanout,
    /// Live connections per session on this replica.
    hubs: Mutex<HashMap<Uuid, usize>>,
    /// The rate limit of `POST /v1/sessions`.
    pub session_limiter: crate::rate::SessionLimiter,
    /// The rate limits of moves, solid changes and duplicates.
    pub rates: crate::rate::Rates,
    /// One permit per WebSocket connection on this replica (`max_connections`).
    connections: Arc<tokio::sync::Semaphore>,
    /// Live WebSocket connections per client address on this replica (with a limit only).
    addresses: Mutex<HashMap<IpAddr, usize>>,
    /// One permit per large HTTP body being handled (`max_large_bodies`).
    large_bodies: Arc<tokio::sync::Semaphore>,
    /// One permit per print being made (`crate::export::MAX_PRINTS`).
    prints: Arc<tokio::sync::Semaphore>,
    /// One permit per scene being made (`crate::export::MAX_SCENES`): its own bound, so a
    /// print that takes seconds never holds up a scene that takes a fraction of one.
    scenes: Arc<tokio::sync::Semaphore>,
    /// Exports whose work (on the blocking pool) is running: each holds its export permit
    /// until its work has stopped (`crate::export`).
    pub exports_working: Arc<std::sync::atomic::AtomicUsize>,
    /// The prints being made or kept on this replica, by model (`crate::kept_prints`).
    pub kept_prints: Arc<crate::kept_prints::KeptPrints>,
    /// One permit per duplicate being made (`crate::placement::MAX_DUPLICATES`).
    duplicates: Arc<tokio::sync::Semaphore>,
    /// One permit per page of a stroke's history (placements, solids) being read
    /// (`crate::change_history::MAX_HISTORY_READS`).
    history_reads: Arc<tokio::sync::Semaphore>,
    next_connection: AtomicU64,
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
        fanout: Fanout,
        locks: Option<Arc<StrokeLocks>>,
    ) -> AppState {
        let connections = Arc::new(tokio::sync::Semaphore::new(
            config.max_connections.min(tokio::sync::Semaphore::MAX_PERMITS),
        ));
        let large_bodies = Arc::new(tokio::sync::Semaphore::new(
            config.max_large_bodies.min(tokio::sync::Semaphore::MAX_PERMITS),
        ));
        let session_limiter = crate::rate::SessionLimiter::new(
            config.session_rate_per_minute,
            config.session_burst,
            config.trust_forwarded_for,
        );
        let rates = crate::rate::Rates::new(&config);
        AppState {
            inner: Arc::new(Inner {
                config,
                store,
                writer,
                shutdown,
                tracker: TaskTracker::new(),
                claims: Claims::new(locks),
                metrics,
                counters: crate::metrics::HotCounters::register(),
                fanout,
                hubs: Mutex::new(HashMap::new()),
                connections,
                addresses: Mutex::new(HashMap::new()),
                large_bodies,
                prints: Arc::new(tokio::sync::Semaphore::new(crate::export::MAX_PRINTS)),
                scenes: Arc::new(tokio::sync::Semaphore::new(crate::export::MAX_SCENES)),
                exports_working: Arc::default(),
                kept_prints: Arc::default(),
                duplicates: Arc::new(tokio::sync::Semaphore::new(crate::placement::MAX_DUPLICATES)),
                history_reads: Arc::new(tokio::sync::Semaphore::new(
                    crate::change_history::MAX_HISTORY_READS,
                )),
                session_limiter,
                rates,
                next_connection: AtomicU64::new(1),
            }),
        }
    }

    pub fn next_connection_id(&self) -> u64 {
        self.next_connection.fetch_add(1, Ordering::Relaxed)
    }

    /// A WebSocket connection's slot on this replica for a client at `address`, unless
    /// `max_connections` are open, or `max_connections_per_address` from that address; the
    /// slot frees when it is dropped.
    pub fn connection_slot(&self, address: IpAddr) -> Result<ConnectionSlot, NoSlot> {
        let per_address = self.config.max_connections_per_address;
        let mut addresses = self.addresses.lock().expect("addresses lock");
        if per_address > 0 && addresses.get(&address).is_some_and(|&n| n >= per_address) {
            return Err(NoSlot::Address);
        }
        let permit = self.connections.clone().try_acquire_owned().map_err(|_| NoSlot::Replica)?;
        let address = (per_address > 0).then(|| {
            *addresses.entry(address).or_default() += 1;
            address
        });
        Ok(ConnectionSlot { state: self.clone(), address, _permit: permit })
    }

    /// The permit to make a print (`scene` false) or a scene, or `None` while
    /// [`crate::export::MAX_PRINTS`] prints or [`crate::export::MAX_SCENES`] scenes are being
    /// made; it frees when dropped.
    pub fn export_permit(&self, scene: bool) -> Option<tokio::sync::OwnedSemaphorePermit> {
        let slots = if scene { &self.scenes } else { &self.prints };
        slots.clone().try_acquire_owned().ok()
    }

    /// The permit to make a duplicate, waiting up to `wait` while
    /// [`crate::placement::MAX_DUPLICATES`] are being made (`None` then); it frees when
    /// dropped.
    pub async fn duplicate_permit(
        &self,
        wait: Duration,
    ) -> Option<tokio::sync::OwnedSemaphorePermit> {
        let permit = self.duplicates.clone().acquire_owned();
        tokio::time::timeout(wait, permit).await.ok()?.ok()
    }

    /// The permit to read a page of a stroke's history (placements, solids), waiting up to
    /// `wait` while [`crate::change_history::MAX_HISTORY_READS`] are being read (`None` then).
    pub async fn history_read_permit(
        &self,
        wait: Duration,
    ) -> Option<tokio::sync::OwnedSemaphorePermit> {
        let permit = self.history_reads.clone().acquire_owned();
        tokio::time::timeout(wait, permit).await.ok()?.ok()
    }

    /// The permit to handle an HTTP body of about `bytes` (sent or received): none needed up
    /// to [`LARGE_BODY_BYTES`]; past `max_large_bodies` such bodies at once, `None`. The
    /// permit frees when it is dropped, with the body.
    pub fn large_body(&self, bytes: u64) -> Option<Option<tokio::sync::OwnedSemaphorePermit>> {
        if bytes <= LARGE_BODY_BYTES {
            return Some(None);
        }
        self.large_bodies.clone().try_acquire_owned().ok().map(Some)
    }

    /// Like [`AppState::large_body`], but waiting up to `wait` for a permit: for a body many
    /// clients ask for at once (a session's mesh bundle when a class opens one board), which
    /// then take turns instead of being refused.
    pub async fn large_body_within(
        &self,
        bytes: u64,
        wait: Duration,
    ) -> Option<Option<tokio::sync::OwnedSemaphorePermit>> {
        if bytes <= LARGE_BODY_BYTES {
            return Some(None);
        }
        let permit = self.large_bodies.clone().acquire_owned();
        tokio::time::timeout(wait, permit).await.ok()?.ok().map(Some)
    }

    /// Counts a new connection in its session, unless the session is full.
    pub fn join_session(&self, session: Uuid) -> Option<SessionGuard> {
        let mut hubs = self.hubs.lock().expect("hubs lock");
        let connections = hubs.entry(session).or_default();
        if *connections >= self.config.max_connections_per_session {
            return None;
        }
        *connections += 1;
        Some(SessionGuard { state: self.clone(), session })
    }
}

/// Why a WebSocket connection gets no slot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoSlot {
    /// `max_connections` are open on this replica.
    Replica,
    /// `max_connections_per_address` are open from the client's address.
    Address,
}

/// A WebSocket connection's slot on this replica (and under its client address's limit);
/// dropping it frees both.
#[derive(Debug)]
pub struct ConnectionSlot {
    state: AppState,
    /// The address counted (none without a per-address limit).
    address: Option<IpAddr>,
    _permit: tokio::sync::OwnedSemaphorePermit,
}

impl Drop for ConnectionSlot {
    fn drop(&mut self) {
        let Some(address) = self.address else { return };
        let mut addresses = self.state.addresses.lock().expect("addresses lock");
        if let Some(n) = addresses.get_mut(&address) {
            *n -= 1;
            if *n == 0 {
                addresses.remove(&address);
            }
        }
    }
}

/// A connection's place in its session; leaving is dropping it.
#[derive(Debug)]
pub struct SessionGuard {
    state: AppState,
    session: Uuid,
}

impl Drop for SessionGuard {
    fn drop(&mut self) {
        let mut hubs = self.state.hubs.lock().expect("hubs lock");
        if let Some(connections) = hubs.get_mut(&self.session) {
            *connections -= 1;
            if *connections == 0 {
                hubs.remove(&self.session);
            }
        }
    }
}

/// Which connection holds which stroke: a stroke is drawn on one connection at a time. With
/// PostgreSQL a stroke held here is also locked in the database ([`StrokeLocks`]), so no other
/// replica draws it; the lock goes when this replica's lock connection does (it died).
#[derive(Debug)]
pub struct Claims {
    held: Mutex<HashMap<StrokeId, u64>>,
    released: Notify,
    locks: Option<Arc<StrokeLocks>>,
}

/// How often a claim waiting for another replica's stroke lock tries again.
const LOCK_RETRY: Duration = Duration::from_millis(50);

impl Claims {
    pub fn new(locks: Option<Arc<StrokeLocks>>) -> Claims {
        Claims { held: Mutex::default(), released: Notify::new(), locks }
    }

    /// Takes `stroke` for connection `conn`, waiting up to `wait` for another holder to let go
    /// (a client that reconnects faster than its old connection is noticed gone, here or on
    /// another replica).
    pub async fn claim(&self, stroke: StrokeId, conn: u64, wait: Duration) -> bool {
        let deadline = tokio::time::Instant::now() + wait;
        loop {
            let notified = self.released.notified();
            tokio::pin!(notified);
            notified.as_mut().enable();
            let taken = {
                let mut held = self.held.lock().expect("claims lock");
                match held.get(&stroke) {
                    None => {
                        held.insert(stroke, conn);
                        true
                    }
                    Some(&holder) if holder == conn => return true,
                    Some(_) => false,
                }
            };
            if taken {
                let Some(locks) = &self.locks else { return true };
                match locks.try_lock(stroke).await {
                    Ok(true) => return true,
                    Ok(false) => {}
                    Err(err) => tracing::warn!(error = %err, %stroke, "taking a stroke lock"),
                }
                // Another replica draws it (or the database is unreachable): let go, retry.
                self.forget(stroke, conn);
                if tokio::time::Instant::now() + LOCK_RETRY > deadline {
                    return false;
                }
                tokio::time::sleep(LOCK_RETRY).await;
                continue;
            }
            if tokio::time::timeout_at(deadline, notified).await.is_err() {
                return false;
            }
        }
    }

    /// The key of the lock this replica holds while it lives (PostgreSQL).
    pub fn replica_key(&self) -> Option<i64> {
        self.locks.as_ref().map(|l| l.replica_key())
    }

    fn forget(&self, stroke: StrokeId, conn: u64) -> bool {
        let mut held = self.held.lock().expect("claims lock");
        let mine = held.get(&stroke) == Some(&conn);
        if mine {
            held.remove(&stroke);
        }
        drop(held);
        self.released.notify_waiters();
        mine
    }

    pub fn release(&self, stroke: StrokeId, conn: u64) {
        if self.forget(stroke, conn) {
            self.unlock(stroke);
        }
    }

    /// Gives the stroke's database lock back (PostgreSQL), in the background.
    fn unlock(&self, stroke: StrokeId) {
        let Some(locks) = self.locks.clone() else { return };
        // Also called while a panicking task unwinds: only spawn where a runtime runs.
        if let Ok(runtime) = tokio::runtime::Handle::try_current() {
            runtime.spawn(async move { locks.unlock(stroke).await });
        }
    }
}

/// The strokes one connection holds: claimed through it, and all let go when it is dropped,
/// however the connection ends (a panic in its task included).
#[derive(Debug)]
pub struct ConnectionClaims {
    state: AppState,
    conn: u64,
    held: HashSet<StrokeId>,
}

impl ConnectionClaims {
    pub fn new(state: AppState, conn: u64) -> ConnectionClaims {
        ConnectionClaims { state, conn, held: HashSet::new() }
    }

    /// Takes `stroke` for this connection ([`Claims::claim`]).
    pub async fn claim(&mut self, stroke: StrokeId, wait: Duration) -> bool {
        let taken = self.state.claims.claim(stroke, self.conn, wait).await;
        if taken {
            self.held.insert(stroke);
        }
        taken
    }

    pub fn release(&mut self, stroke: StrokeId) {
        if self.held.remove(&stroke) {
            self.state.claims.release(stroke, self.conn);
        }
    }
}

impl Drop for ConnectionClaims {
    fn drop(&mut self) {
        for stroke in self.held.drain() {
            self.state.claims.release(stroke, self.conn);
        }
    }
}
