//! What several replicas on one PostgreSQL share: the session events (`LISTEN/NOTIFY`) and
//! the ownership of the strokes being drawn (session-level advisory locks).
//!
//! - [`start_listener`]: one `LISTEN` connection per replica hands every notification of
//!   [`EVENTS_CHANNEL`] to the local [`Fanout`]. Notifications sent while that connection is
//!   down are lost for good, so when it drops (`PgListener::try_recv` gives `Ok(None)` or an
//!   error) the listener listens again first and then marks every local subscriber with a gap:
//!   each connection resyncs its client from the database, filtered by what the client has.
//!   A connection cut off by a partition is not dropped: it stays silent forever (nothing is
//!   owed to it, so TCP never notices). So the listener notifies itself on a channel of its
//!   own every `--listener-heartbeat-ms`, on the same connection; a heartbeat that does not
//!   come back in time counts as that drop.
//! - [`StrokeLocks`]: a replica holds `pg_advisory_lock(key(stroke))` on one connection of its
//!   own for every stroke drawn on it. A replica that dies loses its connection, PostgreSQL
//!   frees its locks at once, and another replica can take the strokes over (resume). Its
//!   queries have a deadline (`--db-timeout-ms`): one that passes drops the connection, and
//!   the next use opens a new one and takes the held locks again.
//! - Presence: the same connection holds a lock on the replica's own random key
//!   ([`StrokeLocks::replica_key`]), stored with each participant. [`start_reaper`] closes the
//!   participants whose replica's lock is gone (it died) and tells their sessions (`PeerLeft`).

use std::collections::{HashMap, HashSet};
use std::time::{Duration, Instant};

use anyhow::Context;
use sqlx::postgres::{PgConnectOptions, PgListener};
use sqlx::{Connection, PgConnection, Row};
use tokio::sync::Mutex;
use tokio_util::sync::CancellationToken;
use uuid::Uuid;

use crate::events::{EventKind, SessionEvent};
use crate::fanout::Fanout;
use crate::store::{EVENTS_CHANNEL, Store, notify};

/// The `application_name` of the listener's connection (so an operator, or a test, finds it).
pub const LISTENER_APPLICATION: &str = "penmesh-listener";
/// The `application_name` of the connection that holds the stroke locks.
pub const LOCKS_APPLICATION: &str = "penmesh-locks";

fn options(url: &str, application: &str) -> anyhow::Result<PgConnectOptions> {
    let options: PgConnectOptions = url.parse().context("parsing the PostgreSQL URL")?;
    Ok(options.application_name(application))
}

/// Listens on the events channel and on `beat`, within `deadline`.
async fn listen(
    options: &PgConnectOptions,
    beat: &str,
    deadline: Duration,
) -> anyhow::Result<PgListener> {
    let pool = sqlx::postgres::PgPoolOptions::new()
        .max_connections(1)
        .acquire_timeout(deadline)
        .connect_lazy_with(options.clone());
    let listening = async {
        let mut listener = PgListener::connect_with(&pool).await?;
        // A dropped connection is reconnected here, with a deadline, and followed by a resync;
        // sqlx reconnecting inside `try_recv` would do neither.
        listener.eager_reconnect(false);
        listener.listen_all([EVENTS_CHANNEL, beat]).await?;
        anyhow::Ok(listener)
    };
    tokio::time::timeout(deadline, listening).await.unwrap_or_else(|_| {
        anyhow::bail!("PostgreSQL did not answer within {} ms", deadline.as_millis())
    })
}

/// When the listener's next heartbeat is due, or since when the one sent is awaited.
#[derive(Debug, Clone, Copy)]
enum Beat {
    Due(Instant),
    Sent(Instant),
}

/// At most one resync of every local session per this time for unreadable notifications: a
/// replica of another release (a rolling deploy) notifies every commit, and resyncing for each
/// would read every watcher's history from the database over and over while the deploy lasts.
const UNREADABLE_RESYNC_INTERVAL: Duration = Duration::from_secs(1);

/// Notifications this replica could not read, and when it last resynced for them: the first
/// resyncs at once, the ones after within [`UNREADABLE_RESYNC_INTERVAL`] together at its end
/// (after the last of them, so nothing they told is missed).
#[derive(Debug, Default)]
struct Unreadable {
    pending: u64,
    last_resync: Option<Instant>,
}

impl Unreadable {
    /// When the pending ones are to be resynced for, if any are.
    fn due(&self) -> Option<Instant> {
        (self.pending > 0)
            .then(|| self.last_resync.map_or_else(Instant::now, |t| t + UNREADABLE_RESYNC_INTERVAL))
    }

    /// Resyncs every local session if the pending notifications are due.
    fn resync_if_due(&mut self, fanout: &Fanout) {
        if self.due().is_some_and(|at| Instant::now() >= at) {
            tracing::warn!(
                unreadable = self.pending,
                "session events: notifications this replica cannot read (another release?); resyncing"
            );
            fanout.gap_all();
            metrics::counter!("penmesh_listener_resyncs_total").increment(1);
            self.pending = 0;
            self.last_resync = Some(Instant::now());
        }
    }
}

/// Starts listening (returns once `LISTEN` is in place) and dispatches until `stop`, checking
/// the connection with a heartbeat every `heartbeat`; `deadline` bounds each (re)connection.
pub async fn start_listener(
    url: &str,
    fanout: Fanout,
    stop: CancellationToken,
    heartbeat: Duration,
    deadline: Duration,
) -> anyhow::Result<tokio::task::JoinHandle<()>> {
    let options = options(url, LISTENER_APPLICATION)?;
    // This listener's own channel: no other replica listens to it.
    let beat_channel = format!("penmesh_heartbeat_{}", Uuid::new_v4().simple());
    let listener =
        listen(&options, &beat_channel, deadline).await.context("listening for session events")?;
    let heartbeat = heartbeat.max(Duration::from_millis(1));
    let notify_beat = format!("NOTIFY {beat_channel}");
    Ok(tokio::spawn(async move {
        let mut listener = Some(listener);
        let mut beat = Beat::Due(Instant::now() + heartbeat);
        let mut unreadable = Unreadable::default();
        loop {
            unreadable.resync_if_due(&fanout);
            let Some(current) = listener.as_mut() else {
                // Listen again before resyncing, so nothing falls between the two.
                match listen(&options, &beat_channel, deadline).await {
                    Ok(new) => {
                        tracing::warn!(
                            "session events: listening again; resyncing every local session"
                        );
                        listener = Some(new);
                        beat = Beat::Due(Instant::now() + heartbeat);
                        fanout.gap_all();
                        metrics::counter!("penmesh_listener_resyncs_total").increment(1);
                    }
                    Err(err) => {
                        tracing::error!(error = %err, "session events: cannot listen; retrying");
                        tokio::select! {
                            _ = stop.cancelled() => return,
                            _ = tokio::time::sleep(Duration::from_millis(500)) => {}
                        }
                    }
                }
                continue;
            };
            if let Beat::Due(at) = beat
                && Instant::now() >= at
            {
                // On this very connection: it is the one whose silence would go unnoticed.
                let sent = sqlx::query(&notify_beat).execute(&mut *current);
                match tokio::time::timeout(deadline, sent).await {
                    Ok(Ok(_)) => beat = Beat::Sent(Instant::now()),
                    Ok(Err(err)) => {
                        tracing::warn!(error = %err, "session events: the heartbeat failed");
                        metrics::counter!("penmesh_listener_heartbeat_failures_total").increment(1);
                        listener = None;
                        continue;
                    }
                    Err(_) => {
                        tracing::warn!("session events: the heartbeat could not be sent in time");
                        metrics::counter!("penmesh_listener_heartbeat_failures_total").increment(1);
                        listener = None;
                        continue;
                    }
                }
            }
            let beat_at = match beat {
                Beat::Due(at) => at,
                Beat::Sent(at) => at + heartbeat,
            };
            let wake = unreadable.due().map_or(beat_at, |at| at.min(beat_at));
            let received = tokio::select! {
                _ = stop.cancelled() => return,
                received = tokio::time::timeout_at(wake.into(), current.try_recv()) => received,
            };
            let Ok(received) = received else {
                if let Beat::Sent(at) = beat
                    && Instant::now() >= beat_at
                {
                    tracing::warn!(
                        waited_ms = at.elapsed().as_millis() as u64,
                        "session events: a heartbeat did not come back; listening again"
                    );
                    metrics::counter!("penmesh_listener_heartbeat_failures_total").increment(1);
                    listener = None;
                }
                continue;
            };
            match received {
                Ok(Some(notification)) if notification.channel() == beat_channel => {
                    beat = Beat::Due(Instant::now() + heartbeat);
                }
                Ok(Some(notification)) => {
                    match SessionEvent::from_payload(notification.payload()) {
                        Ok(events) => {
                            let tag = fanout.tag();
                            events.into_iter().for_each(|event| fanout.dispatch(event.arrived(tag)))
                        }
                        Err(err) => {
                            // An event this replica cannot read is an event its clients miss:
                            // resync them from the database rather than lose it in silence.
                            tracing::debug!(error = %err, "session events: unreadable payload");
                            unreadable.pending += 1;
                        }
                    }
                }
                Ok(None) => {
                    // The connection dropped (sqlx does not reconnect by itself, see `listen`):
                    // what is notified until a new one listens is lost.
                    tracing::warn!("session events: the listener's connection dropped");
                    listener = None;
                }
                Err(err) => {
                    tracing::warn!(error = %err, "session events: the listener failed");
                    listener = None;
                }
            }
        }
    }))
}

/// Session-level advisory locks on one connection of this replica, one per stroke drawn here.
#[derive(Debug)]
pub struct StrokeLocks {
    options: PgConnectOptions,
    /// The longest one query (or a reconnection) may take.
    deadline: Duration,
    inner: Mutex<LockConnection>,
    replica_key: i64,
}

#[derive(Debug, Default)]
struct LockConnection {
    conn: Option<PgConnection>,
    /// How many times each key is locked on `conn` (advisory locks stack).
    held: HashMap<LockKey, u32>,
}

/// An advisory-lock key: a stroke's (the two-`int4` form) or the replica's (one `bigint`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum LockKey {
    Stroke(i32, i32),
    Replica(i64),
}

/// The advisory-lock key of a stroke: 64 bits of SHA-256 of its id, in the two-`int4` key
/// space. Stroke ids are chosen by clients: a key they could compute (the old `hi ^ lo`) let a
/// client pick an id whose key is another stroke's, a replica's or sqlx's migration lock (all
/// `bigint` keys, which PostgreSQL keeps apart from the two-`int4` ones) and block it.
pub fn lock_key(stroke: Uuid) -> (i32, i32) {
    use sha2::Digest;
    let digest = sha2::Sha256::new_with_prefix(b"penmesh stroke lock\0")
        .chain_update(stroke.as_bytes())
        .finalize();
    let half = |i: usize| i32::from_be_bytes(digest[i..i + 4].try_into().expect("4 bytes"));
    (half(0), half(4))
}

impl LockKey {
    /// Takes this lock on `conn` if no other session holds it.
    async fn try_lock(self, conn: &mut PgConnection) -> Result<bool, sqlx::Error> {
        match self {
            LockKey::Stroke(a, b) => {
                sqlx::query_scalar("SELECT pg_try_advisory_lock($1, $2)")
                    .bind(a)
                    .bind(b)
                    .fetch_one(conn)
                    .await
            }
            LockKey::Replica(k) => {
                sqlx::query_scalar("SELECT pg_try_advisory_lock($1)").bind(k).fetch_one(conn).await
            }
        }
    }

    async fn unlock(self, conn: &mut PgConnection) -> Result<(), sqlx::Error> {
        match self {
            LockKey::Stroke(a, b) => {
                sqlx::query("SELECT pg_advisory_unlock($1, $2)").bind(a).bind(b).execute(conn).await
            }
            LockKey::Replica(k) => {
                sqlx::query("SELECT pg_advisory_unlock($1)").bind(k).execute(conn).await
            }
        }
        .map(|_| ())
    }
}

impl StrokeLocks {
    pub async fn connect(url: &str, deadline: Duration) -> anyhow::Result<StrokeLocks> {
        let options = options(url, LOCKS_APPLICATION)?;
        // Positive and below 2^62, so that pg_locks splits it in two plain halves.
        let replica_key = (rand::random::<u64>() >> 2).max(1) as i64;
        let connected = async {
            let mut conn =
                PgConnection::connect_with(&options).await.context("the lock connection")?;
            sqlx::query("SELECT pg_advisory_lock($1)")
                .bind(replica_key)
                .execute(&mut conn)
                .await
                .context("taking the replica's lock")?;
            anyhow::Ok(conn)
        };
        let conn = within(deadline, connected).await?;
        let held = HashMap::from([(LockKey::Replica(replica_key), 1)]);
        Ok(StrokeLocks {
            options,
            deadline,
            inner: Mutex::new(LockConnection { conn: Some(conn), held }),
            replica_key,
        })
    }

    /// The key of the advisory lock this replica holds while it lives.
    pub fn replica_key(&self) -> i64 {
        self.replica_key
    }

    /// Takes the stroke's lock if no other replica holds it.
    pub async fn try_lock(&self, stroke: Uuid) -> anyhow::Result<bool> {
        let (a, b) = lock_key(stroke);
        let key = LockKey::Stroke(a, b);
        let mut inner = self.inner.lock().await;
        let conn = self.connection(&mut inner).await?;
        let result = within(self.deadline, key.try_lock(conn)).await;
        match result {
            Ok(true) => {
                *inner.held.entry(key).or_default() += 1;
                Ok(true)
            }
            Ok(false) => Ok(false),
            Err(err) => {
                inner.conn = None;
                Err(err)
            }
        }
    }

    /// Lets go of one hold of the stroke's lock.
    pub async fn unlock(&self, stroke: Uuid) {
        let (a, b) = lock_key(stroke);
        let key = LockKey::Stroke(a, b);
        let mut inner = self.inner.lock().await;
        match inner.held.get_mut(&key) {
            Some(n) if *n > 1 => *n -= 1,
            Some(_) => {
                inner.held.remove(&key);
            }
            None => return,
        }
        let Ok(conn) = self.connection(&mut inner).await else { return };
        let unlocked = within(self.deadline, key.unlock(conn));
        if let Err(err) = unlocked.await {
            tracing::warn!(error = %err, "releasing a stroke lock");
            inner.conn = None;
        }
    }

    /// Asks the lock connection whether it lives, and opens it again (taking the held locks
    /// again) if it broke: a broken one holds no lock, the replica's included.
    pub async fn check(&self) -> anyhow::Result<()> {
        let mut inner = self.inner.lock().await;
        if let Some(conn) = inner.conn.as_mut() {
            let answered = within(self.deadline, sqlx::query("SELECT 1").execute(conn)).await;
            if let Err(err) = answered {
                tracing::warn!(error = %err, "the stroke-lock connection does not answer");
                inner.conn = None;
            }
        }
        self.connection(&mut inner).await.map(|_| ())
    }

    /// The lock connection, reconnected (taking the held locks again) if it broke.
    async fn connection<'a>(
        &self,
        inner: &'a mut LockConnection,
    ) -> anyhow::Result<&'a mut PgConnection> {
        if inner.conn.is_none() {
            let held = &inner.held;
            let relocked = async {
                let mut conn = PgConnection::connect_with(&self.options).await?;
                tracing::warn!(n = held.len(), "the stroke-lock connection broke; relocking");
                let mut lost = Vec::new();
                for (&key, &n) in held {
                    for _ in 0..n {
                        if !key.try_lock(&mut conn).await? {
                            lost.push(key);
                            break;
                        }
                    }
                }
                anyhow::Ok((conn, lost))
            };
            let (conn, lost) = within(self.deadline, relocked).await?;
            for key in lost {
                tracing::error!(?key, "a stroke lock was taken by another replica meanwhile");
                inner.held.remove(&key);
            }
            inner.conn = Some(conn);
        }
        Ok(inner.conn.as_mut().expect("connected"))
    }
}

/// `work`, or an error once `deadline` has passed (a silent connection would wait forever).
async fn within<T, E: Into<anyhow::Error>>(
    deadline: Duration,
    work: impl Future<Output = Result<T, E>>,
) -> anyhow::Result<T> {
    match tokio::time::timeout(deadline, work).await {
        Ok(result) => result.map_err(Into::into),
        Err(_) => anyhow::bail!("PostgreSQL did not answer within {} ms", deadline.as_millis()),
    }
}

/// How often a replica looks for participants of replicas that died.
pub const REAP_INTERVAL: Duration = Duration::from_secs(2);

/// How often a replica checks its lock connection ([`start_lock_keeper`]): well within
/// [`REAP_INTERVAL`], as a replica whose lock is free in two reaping rounds in a row is taken
/// for dead.
pub const LOCK_CHECK: Duration = Duration::from_millis(500);

/// Every [`LOCK_CHECK`]: checks the lock connection and opens it again if it broke, taking
/// the replica's lock and the strokes' locks again. Without it the connection would be opened
/// again only by the next stroke claimed, and a replica whose strokes were all begun would
/// look dead to the reapers: its participants closed, its strokes marked interrupted and its
/// append log moved while it draws on.
pub fn start_lock_keeper(
    locks: std::sync::Arc<StrokeLocks>,
    stop: CancellationToken,
) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        loop {
            tokio::select! {
                _ = stop.cancelled() => return,
                _ = tokio::time::sleep(LOCK_CHECK) => {}
            }
            if let Err(err) = locks.check().await {
                tracing::warn!(error = %err, "the stroke-lock connection cannot be opened again");
            }
        }
    })
}

/// Every [`REAP_INTERVAL`]: closes the participants whose replica no longer holds its lock,
/// and notifies their `PeerLeft` in the same transaction (one replica wins each row); and
/// clears the append log of the writers of replicas that died ([`reap_log`]).
pub fn start_reaper(store: Store, stop: CancellationToken) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        let mut suspects = HashSet::new();
        loop {
            tokio::select! {
                _ = stop.cancelled() => return,
                _ = tokio::time::sleep(REAP_INTERVAL) => {}
            }
            match reap(&store).await {
                Ok(0) => {}
                Ok(n) => tracing::info!(n, "participants of a replica that died have left"),
                Err(err) => {
                    tracing::warn!(error = %err, "looking for participants of dead replicas")
                }
            }
            match reap_log(&store, &mut suspects).await {
                Ok((0, 0)) => {}
                Ok((strokes, records)) => tracing::info!(
                    strokes,
                    records,
                    "the append log of a replica that died is cleared: its strokes' samples \
                     are in stroke_chunks"
                ),
                Err(err) => tracing::warn!(error = %err, "clearing the log of dead replicas"),
            }
        }
    })
}

async fn reap(store: &Store) -> anyhow::Result<usize> {
    let mut tx = store.pool().begin().await?;
    let rows = sqlx::query(&format!(
        "UPDATE participants SET left_at = $1 WHERE left_at IS NULL \
             AND replica_key IS NOT NULL AND NOT {} \
             RETURNING connection, participant, session_id",
        replica_alive("participants.replica_key")
    ))
    .bind(crate::store::now_ms())
    .fetch_all(&mut *tx)
    .await?;
    let mut events = Vec::with_capacity(rows.len());
    let mut drawers = HashSet::new();
    for row in &rows {
        let uuid = |column| anyhow::Ok(Uuid::parse_str(&row.try_get::<String, _>(column)?)?);
        let (session, participant) = (uuid("session_id")?, uuid("participant")?);
        drawers.insert((session, participant));
        events.push(SessionEvent::new(
            session,
            EventKind::Left { participant, connection: uuid("connection")? },
        ));
    }
    for (session, participant) in drawers {
        interrupt_undrawn(&mut tx, session, participant).await?;
    }
    if !events.is_empty() {
        notify(&mut tx, &events).await?;
    }
    tx.commit().await?;
    Ok(events.len())
}

/// Takes `stroke`'s lock until the end of the transaction on `conn`, if no replica holds it,
/// i.e. nobody is drawing the stroke; `false` when one does.
async fn nobody_draws(conn: &mut sqlx::AnyConnection, stroke: Uuid) -> anyhow::Result<bool> {
    let (a, b) = lock_key(stroke);
    let free = sqlx::query_scalar("SELECT pg_try_advisory_xact_lock($1, $2)")
        .bind(a)
        .bind(b)
        .fetch_one(&mut *conn)
        .await?;
    Ok(free)
}

/// Marks `interrupted` the strokes of `participant` in `session` left `open` by a replica that
/// died (as a connection that ends marks its own, and SQLite all of them at start), except
/// those being drawn: this transaction takes each stroke's lock, which the replica drawing it
/// holds (the participant may be on another replica too, and have resumed it there). Their
/// samples still in the dead replica's append log stay readable there until [`reap_log`]
/// moves them.
async fn interrupt_undrawn(
    conn: &mut sqlx::AnyConnection,
    session: Uuid,
    participant: Uuid,
) -> anyhow::Result<()> {
    let open: Vec<String> = sqlx::query_scalar(
        "SELECT id FROM strokes WHERE session_id = $1 AND participant = $2 AND status = 'open'",
    )
    .bind(session.to_string())
    .bind(participant.to_string())
    .fetch_all(&mut *conn)
    .await?;
    for id in open {
        if nobody_draws(conn, Uuid::parse_str(&id)?).await? {
            let marked = sqlx::query(
                "UPDATE strokes SET status = 'interrupted', updated_at = $1 \
                 WHERE id = $2 AND status = 'open'",
            )
            .bind(crate::store::now_ms())
            .bind(&id)
            .execute(&mut *conn)
            .await?;
            metrics::counter!("penmesh_strokes_total", "event" => "interrupted")
                .increment(marked.rows_affected());
        }
    }
    Ok(())
}

/// SQL that is true while the replica whose lock key is `key` (an SQL expression) holds its
/// lock, i.e. lives: its session holds the advisory lock, which PostgreSQL frees when the
/// session ends.
fn replica_alive(key: &str) -> String {
    format!(
        "EXISTS (SELECT 1 FROM pg_locks l WHERE l.locktype = 'advisory' AND l.granted \
         AND l.objsubid = 1 \
         AND l.database = (SELECT oid FROM pg_database WHERE datname = current_database()) \
         AND l.classid::bigint = (({key}) >> 32) AND l.objid::bigint = (({key}) & 4294967295))"
    )
}

/// Clears the append log of writers whose replica died (a writer's records carry its
/// replica's lock key, `WriterTask::start`): a replica killed mid-stroke leaves the appends
/// it acknowledged there, which every reader then scans for ever. A writer counts as dead when
/// its lock was free in two rounds in a row (`suspects` carries the first), so a replica whose
/// lock connection is only being reopened is left alone. For each of its strokes that nobody
/// is drawing (this transaction takes the stroke's lock, which conflicts with a drawing
/// replica's), the samples only the log holds go into `stroke_chunks`; then its records read
/// are deleted (never one it committed after the read, should it live after all), except
/// those holding a stroke that is being drawn again (its new writer moves it; a later round
/// deletes them). What cannot be moved (a stroke with no row, a record that does
/// not decode) is set aside first (`log::set_aside`). Returns the strokes moved and the
/// records deleted.
async fn reap_log(store: &Store, suspects: &mut HashSet<i64>) -> anyhow::Result<(u64, u64)> {
    let mut tx = store.pool().begin().await?;
    let dead: HashSet<i64> = sqlx::query_scalar(&format!(
        "SELECT DISTINCT writer FROM stroke_log WHERE NOT {}",
        replica_alive("stroke_log.writer")
    ))
    .fetch_all(&mut *tx)
    .await?
    .into_iter()
    .collect();
    let confirmed: Vec<i64> = dead.intersection(suspects).copied().collect();
    *suspects = dead;
    if confirmed.is_empty() {
        return Ok((0, 0));
    }
    // Writer keys and record ids are integers read from the database: safe to write into the
    // statements.
    fn list<'a>(ids: impl IntoIterator<Item = &'a i64>) -> String {
        ids.into_iter().map(i64::to_string).collect::<Vec<_>>().join(", ")
    }
    // Only what is read here may be deleted: a writer taken for dead may live (its lock
    // connection was down for two rounds), and a record it commits after this read holds
    // samples it acknowledged that nobody moved. A writer commits one transaction after the
    // other, so its records read are those up to the last id it had before the read.
    let read_upto: Vec<(i64, i64)> = sqlx::query_as(&format!(
        "SELECT writer, MAX(id) FROM stroke_log WHERE writer IN ({}) GROUP BY writer",
        list(&confirmed)
    ))
    .fetch_all(&mut *tx)
    .await?;
    // The whole log, read once: a dead writer's stroke may continue another writer's entries.
    // What does not decode is set aside, not moved.
    let log = crate::store::log::read_log_to_move(&mut tx, None).await?;
    let (mut moved, mut kept_records) = (0, HashSet::new());
    for (stroke, entries) in log {
        let is_dead = |(_, writer, _): &(i64, i64, _)| confirmed.contains(writer);
        if !entries.iter().any(is_dead) {
            continue;
        }
        if nobody_draws(&mut tx, stroke).await? {
            // One that cannot be moved is set aside, not tried again every round.
            moved +=
                u64::from(crate::store::log::move_or_set_aside(&mut tx, stroke, entries).await?);
        } else {
            kept_records.extend(entries.iter().filter(|e| is_dead(e)).map(|(id, _, _)| *id));
        }
    }
    let mut deleted = 0;
    if !read_upto.is_empty() {
        let read: Vec<String> = read_upto
            .iter()
            .map(|(writer, upto)| format!("(writer = {writer} AND id <= {upto})"))
            .collect();
        let mut sql = format!("DELETE FROM stroke_log WHERE ({})", read.join(" OR "));
        if !kept_records.is_empty() {
            sql += &format!(" AND id NOT IN ({})", list(&kept_records));
        }
        deleted = sqlx::query(&sql).execute(&mut *tx).await?.rows_affected();
    }
    tx.commit().await?;
    Ok((moved, deleted))
}
