//! The database layer: one set of queries for SQLite and PostgreSQL through sqlx's `Any`
//! driver, the embedded migrations, and the group-commit [`writer`].
//!
//! **Only this module knows how samples are laid out in the database** (`encode_samples`, and
//! the append log's records, [`log`]). A stroke's samples are in `stroke_chunks` and, while it is
//! drawn, in `stroke_log`: every reader of raw samples reads both.

pub(crate) mod log;
mod meshes;
mod writer;

use std::collections::{HashMap, HashSet};
use std::str::FromStr;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use penmesh::Sample;
use penmesh::protocol::{StrokeStatus, decode_point_batch, encode_point_batch, quantize_sample};
use sqlx::any::{AnyConnectOptions, AnyPoolOptions};
use sqlx::{AnyConnection, AnyPool, Connection, Executor, Row};
use tokio_util::sync::CancellationToken;
use uuid::Uuid;

pub use writer::{CommitFaults, Committed, Fault, WriteError, WriteOp, Writer, WriterTask};

use crate::config::{Config, SqliteSync};
use crate::fanout::{EventKind, SessionEvent};

/// The `LISTEN/NOTIFY` channel that carries session events between replicas (PostgreSQL).
pub const EVENTS_CHANNEL: &str = "penmesh_events";

static SQLITE_MIGRATIONS: sqlx::migrate::Migrator = sqlx::migrate!("../migrations/sqlite");
static POSTGRES_MIGRATIONS: sqlx::migrate::Migrator = sqlx::migrate!("../migrations/postgres");

/// Which database engine is behind the URL.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backend {
    Sqlite,
    Postgres,
}

/// A pool of read connections plus what the writer needs to open its own.
#[derive(Debug, Clone)]
pub struct Store {
    pool: AnyPool,
    backend: Backend,
    /// How the pool's connections are opened, for the writer's own (see `open_write_connection`).
    options: AnyConnectOptions,
    synchronous: &'static str,
    /// SQLite: the file's page size (`--sqlite-page-size` when this proxy made the file).
    page_size: i64,
    /// The longest one database round trip may take (`--db-timeout-ms`): taking a pool
    /// connection, and the writer's transactions.
    deadline: Duration,
    /// One permit per replay of a long stroke at once (`--max-replays`, [`Store::replay`]).
    replays: Arc<tokio::sync::Semaphore>,
}

/// A stroke's row.
#[derive(Debug, Clone, PartialEq)]
pub struct StrokeRow {
    pub id: Uuid,
    pub session_id: Uuid,
    pub participant: Uuid,
    pub brush: penmesh::Brush,
    pub params: penmesh::AcutsParams,
    pub device: Option<String>,
    pub status: StrokeStatus,
    pub n_points: u64,
    pub n_retained: u64,
    pub created_at: i64,
    pub updated_at: i64,
    pub has_mesh: bool,
}

/// The simplified stroke: indices into the raw samples and the samples themselves.
#[derive(Debug, Clone, PartialEq)]
pub struct Simplified {
    pub indices: Vec<u64>,
    pub samples: Vec<Sample>,
}

/// What a newcomer to a session is owed ([`Store::session_history`]).
#[derive(Debug, Clone, Default)]
pub struct SessionHistory {
    /// The session's events, in order, without the unreadable strokes.
    pub events: Vec<SessionEvent>,
    /// The strokes that could not be read (`None`: not even its id), and why.
    pub unreadable: Vec<(Option<Uuid>, String)>,
    /// What the long unfinished strokes it replayed retain, for the caller to keep
    /// ([`WriteOp::KeepRetained`]), so that the next history reads it instead.
    pub keep: Vec<WriteOp>,
}

/// Stored samples of an unfinished stroke from which replaying it (to rebuild what ACUTS
/// retained: a session's history, a resume) counts as long: it waits for one of
/// `--max-replays` permits and runs on the blocking pool, and a history keeps what it retains
/// ([`WriteOp::KeepRetained`]). A shorter one is replayed on the spot (at most a few
/// milliseconds; see docs/reliability.md).
pub const LONG_STROKE_SAMPLES: u64 = 2048;

/// A stored mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshRow {
    pub glb: Vec<u8>,
    pub vertices: u64,
    pub triangles: u64,
    pub uploader: Option<String>,
    pub created_at: i64,
}

/// Milliseconds since the Unix epoch.
pub fn now_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_millis() as i64)
        .unwrap_or(0)
}

/// sha256 of a token, lowercase hex: what the sessions table stores.
pub fn hash_token(token: &str) -> String {
    use sha2::Digest;
    hex::encode(sha2::Sha256::digest(token.as_bytes()))
}

/// How a row's sample blob is laid out (its `layout` column).
const LAYOUT_F64: i64 = 0;
/// [`penmesh::protocol::encode_point_batch`]: exact for samples on the codec's grid, which is
/// every sample the proxy accepts since it puts them there on arrival (`ingest`).
const LAYOUT_POINT_BATCH: i64 = 1;

/// A sample blob and its layout: the compact point batch when that is exact (every sample on
/// the grid, bit for bit), else `f64` quadruples (samples stored by an earlier version).
pub(crate) fn encode_samples(samples: &[Sample]) -> (i64, Vec<u8>) {
    let same = |a: f64, b: f64| a.to_bits() == b.to_bits();
    let on_grid = samples.iter().all(|s| {
        let q = quantize_sample(s);
        same(q.x, s.x) && same(q.y, s.y) && same(q.t, s.t) && same(q.p, s.p)
    });
    if on_grid {
        return (LAYOUT_POINT_BATCH, encode_point_batch(samples));
    }
    let mut out = Vec::with_capacity(samples.len() * 32);
    for s in samples {
        for v in [s.x, s.y, s.t, s.p] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    (LAYOUT_F64, out)
}

/// The samples of a stored blob of the given `layout` (a row's `layout` column). Public for
/// tests that read a database file directly.
pub fn decode_samples(layout: i64, bytes: &[u8]) -> anyhow::Result<Vec<Sample>> {
    match layout {
        LAYOUT_POINT_BATCH => Ok(decode_point_batch(bytes)?),
        LAYOUT_F64 => {
            anyhow::ensure!(
                bytes.len() % 32 == 0,
                "sample blob of {} bytes is not a multiple of 32",
                bytes.len()
            );
            Ok(bytes
                .chunks_exact(32)
                .map(|c| {
                    let f = |i: usize| f64::from_le_bytes(c[i * 8..i * 8 + 8].try_into().unwrap());
                    Sample::new(f(0), f(1), f(2), f(3))
                })
                .collect())
        }
        other => anyhow::bail!("unknown sample layout {other}"),
    }
}

pub(crate) fn encode_indices(indices: &[u64]) -> Vec<u8> {
    indices.iter().flat_map(|i| i.to_le_bytes()).collect()
}

fn decode_indices(bytes: &[u8]) -> Vec<u64> {
    bytes.chunks_exact(8).map(|c| u64::from_le_bytes(c.try_into().unwrap())).collect()
}

fn parse_uuid(s: &str) -> anyhow::Result<Uuid> {
    Uuid::parse_str(s).with_context(|| format!("bad uuid {s:?} in the database"))
}

impl Store {
    /// Connects (creating a SQLite file if missing) and applies the migrations.
    pub async fn connect(config: &Config) -> anyhow::Result<Store> {
        sqlx::any::install_default_drivers();
        let url = config.database_url.expose().trim();
        let (backend, url) = if url.starts_with("sqlite:") {
            create_parent_dir(url)?;
            let url = if url.contains("mode=") {
                url.to_string()
            } else if url.contains('?') {
                format!("{url}&mode=rwc")
            } else {
                format!("{url}?mode=rwc")
            };
            (Backend::Sqlite, url)
        } else if url.starts_with("postgres:") || url.starts_with("postgresql:") {
            (Backend::Postgres, url.to_string())
        } else {
            anyhow::bail!(
                "database URL must start with sqlite:// or postgres://, got {}",
                config.database_url
            );
        };
        let options = AnyConnectOptions::from_str(&url).context("parsing the database URL")?;
        let synchronous = match config.sqlite_synchronous {
            SqliteSync::Normal => "NORMAL",
            SqliteSync::Full => "FULL",
        };
        let page_size = config.sqlite_page_size;
        let deadline = Duration::from_millis(config.db_timeout_ms);
        let pool = AnyPoolOptions::new()
            .max_connections(config.db_max_connections.max(1))
            .acquire_timeout(deadline)
            .after_connect(move |conn, _meta| {
                Box::pin(async move {
                    if backend == Backend::Sqlite {
                        conn.execute(sqlite_settings(synchronous, page_size).as_str()).await?;
                    }
                    Ok(())
                })
            })
            .connect_with(options.clone())
            .await
            .with_context(|| format!("connecting to {}", config.database_url))?;
        match backend {
            Backend::Sqlite => SQLITE_MIGRATIONS.run(&pool).await,
            // The migrator holds a session-level advisory lock, which a transaction pooler
            // would leave behind on a pooled server connection: the direct URL, as the locks.
            Backend::Postgres => {
                let direct = config.direct_database_url();
                // One connection: the migrator's lock and its migrations share it.
                let direct_pool = sqlx::postgres::PgPoolOptions::new()
                    .max_connections(1)
                    .connect(direct.expose())
                    .await
                    .with_context(|| format!("connecting to {direct} to migrate"))?;
                let applied = POSTGRES_MIGRATIONS.run(&direct_pool).await;
                direct_pool.close().await;
                applied
            }
        }
        .context("applying migrations")?;
        let file_page_size = match backend {
            Backend::Sqlite => sqlx::query_scalar("PRAGMA page_size").fetch_one(&pool).await?,
            Backend::Postgres => i64::from(page_size),
        };
        if file_page_size != i64::from(page_size) {
            tracing::info!(
                file = file_page_size,
                setting = page_size,
                "the SQLite file keeps the page size it was made with; \
                 --sqlite-page-size applies to new files"
            );
        }
        let page_size = file_page_size;
        let replays = Arc::new(tokio::sync::Semaphore::new(config.max_replays.max(1)));
        Ok(Store { pool, backend, options, synchronous, page_size, deadline, replays })
    }

    /// Opens the group-commit writer's connection, outside the pool. With SQLite, sqlx runs each
    /// connection on a thread it starts when it opens it, and that thread takes the priority of
    /// the thread that opens it: the writer's, higher than the connection workers' (see
    /// [`crate::run`]).
    ///
    /// Its SQLite settings beyond the pool's were found with `perf` on the writer under 500 pens:
    /// - a multi-row `INSERT` inside the group's transaction keeps a statement journal (to undo
    ///   itself alone if it fails half-way), by default in a temporary file: in memory it costs
    ///   no write at all;
    /// - a commit touches hundreds of pages, more than the default 2 MB page cache holds without
    ///   spilling mid-transaction;
    /// - the log is copied into the database by the checkpointer ([`start_checkpointer`]), off
    ///   the writer's path; the writer checkpoints only when the log has grown to 64 MB (only a
    ///   writer can restart the log from its beginning, once every page in it is copied).
    pub async fn open_write_connection(&self) -> anyhow::Result<AnyConnection> {
        let mut conn = AnyConnection::connect_with(&self.options).await?;
        if self.backend == Backend::Sqlite {
            let settings = format!(
                "{} PRAGMA temp_store = MEMORY; PRAGMA cache_size = -32768; \
                 PRAGMA wal_autocheckpoint = {};",
                sqlite_settings(self.synchronous, self.page_size),
                WRITER_CHECKPOINT_BYTES / self.page_size
            );
            conn.execute(settings.as_str()).await?;
        }
        Ok(conn)
    }

    /// The longest one database round trip may take (`--db-timeout-ms`).
    pub fn deadline(&self) -> Duration {
        self.deadline
    }

    pub fn backend(&self) -> Backend {
        self.backend
    }

    pub fn pool(&self) -> &AnyPool {
        &self.pool
    }

    /// The statement that opens a write transaction: SQLite takes the write lock up front.
    pub fn begin_statement(&self) -> &'static str {
        match self.backend {
            Backend::Sqlite => "BEGIN IMMEDIATE",
            Backend::Postgres => "BEGIN",
        }
    }

    /// Is the database reachable?
    pub async fn ping(&self) -> anyhow::Result<()> {
        sqlx::query("SELECT 1").execute(&self.pool).await?;
        Ok(())
    }

    /// At start, with SQLite (one process owns the file), strokes left in the append log by a
    /// crash are moved out of it ([`Store::recover_log`]), strokes left `open` are
    /// `interrupted` and participants left present have left. With PostgreSQL other replicas
    /// may be drawing them, so they stay.
    pub async fn interrupt_orphans(&self) -> anyhow::Result<u64> {
        if self.backend != Backend::Sqlite {
            return Ok(0);
        }
        let moved = self.recover_log().await?;
        if moved > 0 {
            tracing::info!(moved, "strokes left in the append log are moved to stroke_chunks");
        }
        sqlx::query("UPDATE participants SET left_at = $1 WHERE left_at IS NULL")
            .bind(now_ms())
            .execute(&self.pool)
            .await?;
        let done = sqlx::query(
            "UPDATE strokes SET status = 'interrupted', updated_at = $1 WHERE status = 'open'",
        )
        .bind(now_ms())
        .execute(&self.pool)
        .await?;
        Ok(done.rows_affected())
    }

    pub async fn create_session(&self, id: Uuid, token_hash: &str) -> anyhow::Result<()> {
        let mut conn = self.pool.acquire().await?;
        let mut tx = sqlx::Connection::begin_with(&mut *conn, self.begin_statement()).await?;
        sqlx::query("INSERT INTO sessions (id, token_hash, created_at) VALUES ($1, $2, $3)")
            .bind(id.to_string())
            .bind(token_hash)
            .bind(now_ms())
            .execute(&mut *tx)
            .await?;
        tx.commit().await?;
        Ok(())
    }

    /// The session a token belongs to.
    pub async fn session_for_token_hash(&self, token_hash: &str) -> anyhow::Result<Option<Uuid>> {
        let row = sqlx::query("SELECT id FROM sessions WHERE token_hash = $1")
            .bind(token_hash)
            .fetch_optional(&self.pool)
            .await?;
        row.map(|r| parse_uuid(&r.try_get::<String, _>("id")?)).transpose()
    }

    pub async fn stroke(&self, id: Uuid) -> anyhow::Result<Option<StrokeRow>> {
        let row = sqlx::query(&format!("{STROKE_SELECT} WHERE s.id = $1"))
            .bind(id.to_string())
            .fetch_optional(&self.pool)
            .await?;
        let mut rows: Vec<StrokeRow> =
            row.map(|r| stroke_from_row(&r)).transpose()?.into_iter().collect();
        self.add_log_ends(&mut rows).await?;
        Ok(rows.pop())
    }

    pub async fn list_strokes(&self, session: Uuid) -> anyhow::Result<Vec<StrokeRow>> {
        let rows = sqlx::query(&format!(
            "{STROKE_SELECT} WHERE s.session_id = $1 ORDER BY s.created_at, s.id"
        ))
        .bind(session.to_string())
        .fetch_all(&self.pool)
        .await?;
        let mut rows = rows.iter().map(stroke_from_row).collect::<anyhow::Result<Vec<_>>>()?;
        self.add_log_ends(&mut rows).await?;
        Ok(rows)
    }

    /// Every stored raw sample of a stroke, in order.
    pub async fn raw_samples(&self, stroke: Uuid) -> anyhow::Result<Vec<Sample>> {
        self.raw(stroke).await?.collect_all()
    }

    /// The stored raw samples of a stroke, read with one pool connection (given back before
    /// this returns) and decoded one stored piece at a time ([`RawSamples`]).
    pub async fn raw(&self, stroke: Uuid) -> anyhow::Result<RawSamples> {
        let mut conn = self.pool.acquire().await?;
        let status: Option<String> = sqlx::query_scalar("SELECT status FROM strokes WHERE id = $1")
            .bind(stroke.to_string())
            .fetch_optional(&mut *conn)
            .await?;
        // A finished stroke is all in `stroke_chunks` (moved by the commit that finished it).
        let in_log = status.is_some_and(|s| s != StrokeStatus::Done.as_str());
        let log = if in_log {
            log::read_log(&mut conn, Some(&HashSet::from([stroke])), None).await?
        } else {
            log::StrokeEntries::new()
        };
        read_raw(&mut conn, stroke, &log).await
    }

    /// A stroke's raw samples from its chunks and its entries in `log` (read by the caller).
    async fn raw_samples_with(
        &self,
        conn: &mut AnyConnection,
        stroke: Uuid,
        log: &log::StrokeEntries,
    ) -> anyhow::Result<Vec<Sample>> {
        read_raw(conn, stroke, log).await?.collect_all()
    }

    /// Where the samples of the strokes in progress among `rows` end: `n_points` from the
    /// chunks, extended by their entries in the log (one scan of the log for all of them).
    async fn add_log_ends(&self, rows: &mut [StrokeRow]) -> anyhow::Result<()> {
        let open: HashSet<Uuid> =
            rows.iter().filter(|r| r.status != StrokeStatus::Done).map(|r| r.id).collect();
        if open.is_empty() {
            return Ok(());
        }
        let mut conn = self.pool.acquire().await?;
        let log = log::read_log(&mut conn, Some(&open), None).await?;
        for row in rows.iter_mut() {
            row.n_points = end_with_log(row.n_points, row.id, &log);
        }
        Ok(())
    }

    /// Replays the stored samples of `stroke` (`n_points` of them, as far as the caller
    /// knows) through a fresh simplifier ([`crate::ingest::StrokeState::replay`]). A long
    /// stroke ([`LONG_STROKE_SAMPLES`]) first waits for one of `--max-replays` permits, before
    /// it takes a pool connection, and is replayed on the blocking pool: however many ask, the
    /// replica replays that many long strokes at once, holding that many of them in memory.
    pub async fn replay(
        &self,
        stroke: Uuid,
        params: penmesh::AcutsParams,
        n_points: u64,
    ) -> anyhow::Result<crate::ingest::StrokeState> {
        use crate::ingest::StrokeState;
        if n_points < LONG_STROKE_SAMPLES {
            let samples = self.raw_samples(stroke).await?;
            return Ok(StrokeState::replay(params, &samples));
        }
        let _permit = self.replays.acquire().await.context("the replay permits are closed")?;
        let samples = self.raw_samples(stroke).await?;
        metrics::counter!("penmesh_replayed_samples_total").increment(samples.len() as u64);
        tokio::task::spawn_blocking(move || StrokeState::replay(params, &samples))
            .await
            .context("replaying a stroke")
    }

    /// SQLite, at start: strokes left in the log by a process that stopped without moving them
    /// (killed) go into `stroke_chunks`, and the log is emptied; what cannot go there is set
    /// aside (`log::move_or_set_aside`), so that one bad record does not stop the start. (With
    /// PostgreSQL another replica may be writing; readers read the log, so nothing is lost
    /// either way.)
    pub async fn recover_log(&self) -> anyhow::Result<u64> {
        if self.backend != Backend::Sqlite {
            return Ok(0);
        }
        let mut conn = self.pool.acquire().await?;
        let mut tx = sqlx::Connection::begin_with(&mut *conn, self.begin_statement()).await?;
        let log = log::read_log_to_move(&mut tx, None).await?;
        let mut moved = 0;
        for (stroke, entries) in log {
            moved += u64::from(log::move_or_set_aside(&mut tx, stroke, entries).await?);
        }
        sqlx::query("DELETE FROM stroke_log").execute(&mut *tx).await?;
        tx.commit().await?;
        Ok(moved)
    }

    /// The simplified stroke of a done stroke.
    pub async fn simplified(&self, stroke: Uuid) -> anyhow::Result<Option<Simplified>> {
        let row = sqlx::query(
            "SELECT indices, layout, data FROM simplified WHERE stroke_id = $1 AND upto IS NULL",
        )
        .bind(stroke.to_string())
        .fetch_optional(&self.pool)
        .await?;
        let Some(row) = row else { return Ok(None) };
        let indices: Vec<u8> = row.try_get("indices")?;
        let data: Vec<u8> = row.try_get("data")?;
        let samples = decode_samples(row.try_get("layout")?, &data)
            .with_context(|| format!("stroke {stroke}: simplified samples"))?;
        Ok(Some(Simplified { indices: decode_indices(&indices), samples }))
    }

    /// The size in bytes of a stroke's mesh, without reading it.
    pub async fn mesh_bytes(&self, stroke: Uuid) -> anyhow::Result<Option<u64>> {
        let bytes: Option<i64> = sqlx::query_scalar(
            "SELECT CAST(length(glb) AS BIGINT) FROM meshes WHERE stroke_id = $1",
        )
        .bind(stroke.to_string())
        .fetch_optional(&self.pool)
        .await?;
        Ok(bytes.map(|b| b as u64))
    }

    pub async fn mesh(&self, stroke: Uuid) -> anyhow::Result<Option<MeshRow>> {
        let row = sqlx::query(
            "SELECT glb, vertices, triangles, uploader, created_at FROM meshes WHERE stroke_id = $1",
        )
        .bind(stroke.to_string())
        .fetch_optional(&self.pool)
        .await?;
        let Some(row) = row else { return Ok(None) };
        Ok(Some(MeshRow {
            glb: row.try_get("glb")?,
            vertices: row.try_get::<i64, _>("vertices")? as u64,
            triangles: row.try_get::<i64, _>("triangles")? as u64,
            uploader: row.try_get("uploader")?,
            created_at: row.try_get("created_at")?,
        }))
    }

    /// What a newcomer to `session` is owed: the participants present, then every stroke
    /// (finished ones with their simplified samples and mesh, open ones with the samples
    /// retained from what is committed so far), as events in order.
    /// A stroke that cannot be read is left out and named in `unreadable`; it does not hide
    /// the others.
    ///
    /// What an unfinished stroke retains is read where a history before kept it for as many
    /// samples as are stored (an interrupted stroke, or one not drawn since), else rebuilt by
    /// replaying its samples: a short stroke on the spot, a long one ([`LONG_STROKE_SAMPLES`])
    /// through [`Store::replay`] after the connection is given back, and what it retains goes
    /// into `keep`.
    ///
    /// It reads through one pooled connection, taken once and given back before a long
    /// replay: a reader that holds a connection while it waits for a second one deadlocks the
    /// pool when as many newcomers arrive at once as the pool has connections (issue 25's join
    /// storm). Its queries are a fixed few, whatever the number of strokes.
    pub async fn session_history(&self, session: Uuid) -> anyhow::Result<SessionHistory> {
        let mut conn = self.pool.acquire().await?;
        let mut history = SessionHistory::default();
        let present = sqlx::query(
            "SELECT connection, participant, name FROM participants \
             WHERE session_id = $1 AND left_at IS NULL ORDER BY joined_at, connection",
        )
        .bind(session.to_string())
        .fetch_all(&mut *conn)
        .await?;
        for row in present {
            history.events.push(SessionEvent::new(
                session,
                EventKind::Joined {
                    participant: parse_uuid(&row.try_get::<String, _>("participant")?)?,
                    connection: parse_uuid(&row.try_get::<String, _>("connection")?)?,
                    name: row.try_get("name")?,
                },
            ));
        }
        let strokes = sqlx::query(&format!(
            "{STROKE_SELECT} WHERE s.session_id = $1 ORDER BY s.created_at, s.id"
        ))
        .bind(session.to_string())
        .fetch_all(&mut *conn)
        .await?;
        let meshes = sqlx::query(
            "SELECT m.stroke_id, m.created_at FROM meshes m JOIN strokes s ON s.id = m.stroke_id \
             WHERE s.session_id = $1",
        )
        .bind(session.to_string())
        .fetch_all(&mut *conn)
        .await?;
        let mut mesh_at = HashMap::new();
        for row in meshes {
            let stroke = parse_uuid(&row.try_get::<String, _>("stroke_id")?)?;
            mesh_at.insert(stroke, row.try_get::<i64, _>("created_at")?);
        }
        // The log, once, for the strokes in progress (a stroke whose row cannot be read is
        // reported below).
        let open: HashSet<Uuid> = strokes
            .iter()
            .filter_map(|r| stroke_from_row(r).ok())
            .filter(|r| r.status != StrokeStatus::Done)
            .map(|r| r.id)
            .collect();
        let log = if open.is_empty() {
            log::StrokeEntries::new()
        } else {
            log::read_log(&mut conn, Some(&open), None).await?
        };
        let simplified = simplified_rows(&mut conn, session).await?;
        let unreadable = |row: &sqlx::any::AnyRow, err: anyhow::Error| {
            let id = row.try_get::<String, _>("id").ok().and_then(|id| id.parse().ok());
            tracing::error!(error = %err, stroke = ?id, "a stroke of a session's history is unreadable");
            (id, format!("{err:#}"))
        };
        // Each readable stroke and what it retains (`None`: a long replay, below).
        let mut parts: Vec<(StrokeRow, Option<Vec<Sample>>)> = Vec::with_capacity(strokes.len());
        for row in &strokes {
            match self.stroke_points(&mut conn, row, &log, &simplified).await {
                Ok(part) => parts.push(part),
                Err(err) => history.unreadable.push(unreadable(row, err)),
            }
        }
        drop(conn);
        for (row, points) in parts {
            let points = match points {
                Some(points) => points,
                None => match self.replay(row.id, row.params, row.n_points).await {
                    Ok(state) => {
                        let kept = state.kept().to_vec();
                        let points = kept.iter().map(|k| k.sample).collect();
                        let upto = state.next_seq();
                        history.keep.push(WriteOp::KeepRetained { stroke: row.id, upto, kept });
                        points
                    }
                    Err(err) => {
                        tracing::error!(error = %err, stroke = %row.id, "a stroke of a session's history is unreadable");
                        history.unreadable.push((Some(row.id), format!("{err:#}")));
                        continue;
                    }
                },
            };
            history.events.extend(stroke_events(session, &row, points, &mesh_at));
        }
        Ok(history)
    }

    /// What one stroke of [`Store::session_history`] retains: its simplified samples when it is
    /// done; else what a history kept for as many samples as are stored, or a replay of a short
    /// stroke; `None` for a long one to replay.
    async fn stroke_points(
        &self,
        conn: &mut AnyConnection,
        row: &sqlx::any::AnyRow,
        log: &log::StrokeEntries,
        simplified: &HashMap<Uuid, SimplifiedRow>,
    ) -> anyhow::Result<(StrokeRow, Option<Vec<Sample>>)> {
        let mut row = stroke_from_row(row)?;
        let stroke = row.id;
        if row.status == StrokeStatus::Done {
            let points = match simplified.get(&stroke) {
                Some(found) => decode_samples(found.layout, &found.data)
                    .with_context(|| format!("stroke {stroke}: simplified samples"))?,
                None => Vec::new(),
            };
            return Ok((row, Some(points)));
        }
        row.n_points = end_with_log(row.n_points, stroke, log);
        let kept =
            simplified.get(&stroke).filter(|k| k.upto.is_some_and(|upto| upto >= row.n_points));
        if let Some(SimplifiedRow { layout, data, .. }) = kept {
            let points = decode_samples(*layout, data)
                .with_context(|| format!("stroke {stroke}: the samples it retained"))?;
            return Ok((row, Some(points)));
        }
        if row.n_points >= LONG_STROKE_SAMPLES {
            return Ok((row, None));
        }
        let raw = self.raw_samples_with(conn, stroke, log).await?;
        let kept = crate::ingest::StrokeState::replay(row.params, &raw);
        let points = kept.kept().iter().map(|k| k.sample).collect();
        Ok((row, Some(points)))
    }
}

/// The events of one stroke of a session's history, `points` being what it retains.
fn stroke_events(
    session: Uuid,
    row: &StrokeRow,
    points: Vec<Sample>,
    mesh_at: &HashMap<Uuid, i64>,
) -> Vec<SessionEvent> {
    let (participant, stroke) = (row.participant, row.id);
    let mut events = vec![SessionEvent::new(
        session,
        EventKind::StrokeBegin { participant, stroke, brush: row.brush },
    )];
    let done = row.status == StrokeStatus::Done;
    let n_retained = points.len() as u64;
    if !points.is_empty() {
        events.push(SessionEvent::new(
            session,
            EventKind::Retained { participant, stroke, first: 0, points },
        ));
    }
    if done {
        events.push(SessionEvent::new(
            session,
            EventKind::StrokeDone { participant, stroke, n_retained },
        ));
        if let Some(&created_at) = mesh_at.get(&stroke) {
            events.push(SessionEvent::new(
                session,
                EventKind::Mesh { participant, stroke, created_at },
            ));
        }
    }
    events
}

/// A `simplified` row of a session's history ([`simplified_rows`]): a finished stroke's
/// simplified samples, or what a history kept of an unfinished one ([`WriteOp::KeepRetained`]).
struct SimplifiedRow {
    /// For a kept row, how many stored samples it covers.
    upto: Option<u64>,
    layout: i64,
    data: Vec<u8>,
}

/// Every `simplified` row of the session's strokes, in one query.
async fn simplified_rows(
    conn: &mut AnyConnection,
    session: Uuid,
) -> anyhow::Result<HashMap<Uuid, SimplifiedRow>> {
    let rows = sqlx::query(
        "SELECT f.stroke_id, f.upto, f.layout, f.data FROM simplified f \
         JOIN strokes s ON s.id = f.stroke_id WHERE s.session_id = $1",
    )
    .bind(session.to_string())
    .fetch_all(&mut *conn)
    .await?;
    let mut found = HashMap::with_capacity(rows.len());
    for row in rows {
        let stroke = parse_uuid(&row.try_get::<String, _>("stroke_id")?)?;
        let upto = row.try_get::<Option<i64>, _>("upto")?.map(|n| n as u64);
        found.insert(
            stroke,
            SimplifiedRow { upto, layout: row.try_get("layout")?, data: row.try_get("data")? },
        );
    }
    Ok(found)
}

/// Where the stored samples of `stroke` end: `n_points` from its chunks, extended by its
/// entries in `log`.
fn end_with_log(n_points: u64, stroke: Uuid, log: &log::StrokeEntries) -> u64 {
    let mut entries: Vec<(u64, u64)> = log
        .get(&stroke)
        .into_iter()
        .flatten()
        .map(|(_, _, e)| (e.seq, e.samples.len() as u64))
        .collect();
    entries.sort_unstable();
    let mut end = n_points;
    for (seq, n) in entries {
        if seq <= end {
            end = end.max(seq + n);
        }
    }
    end
}

/// Moves the samples of `stroke` that only its log `entries` hold into `stroke_chunks`, as one
/// more row after its last chunk; false when the chunks held them all. The caller makes sure
/// nobody is drawing the stroke (SQLite at start; a stroke lock with PostgreSQL) and deletes
/// the records afterwards.
pub(crate) async fn move_log_tail(
    conn: &mut AnyConnection,
    stroke: Uuid,
    entries: Vec<(i64, i64, log::Entry)>,
) -> anyhow::Result<bool> {
    let rows = sqlx::query(CHUNKS_SELECT).bind(stroke.to_string()).fetch_all(&mut *conn).await?;
    let chunks = log::assemble(stroke, pieces_from_chunks(stroke, &rows)?)?;
    let pieces = entries.into_iter().map(|(_, _, e)| log::Piece { seq: e.seq, samples: e.samples });
    let tail = log::assemble_from(stroke, chunks.len() as u64, pieces.collect())?;
    if tail.is_empty() {
        return Ok(false);
    }
    let (layout, data) = encode_samples(&tail);
    sqlx::query(
        "INSERT INTO stroke_chunks (stroke_id, seq, n, layout, data) VALUES ($1, $2, $3, $4, $5)",
    )
    .bind(stroke.to_string())
    .bind(chunks.len() as i64)
    .bind(tail.len() as i64)
    .bind(layout)
    .bind(data)
    .execute(&mut *conn)
    .await?;
    Ok(true)
}

/// A stroke's stored samples as read: its chunk rows still encoded (a few bytes a sample),
/// and its log entries. As an iterator it gives the samples in order, one stored piece at a
/// time, decoding each piece only when it comes: the samples of a long stroke are never all
/// in memory at once. Where two pieces hold the same sample the copies must be equal, and
/// there must be no hole (as [`log::assemble`]); after an error it ends.
#[derive(Debug)]
pub struct RawSamples {
    stroke: Uuid,
    /// In `seq` order (chunks before log entries at the same seq).
    pieces: std::vec::IntoIter<Stored>,
    /// The piece that holds the last sample given (`seq`, samples), to check the copies in
    /// the pieces after it against.
    last: Option<(u64, Arc<Vec<Sample>>)>,
    /// Samples given so far.
    next: u64,
}

/// Samples `from..` of a decoded stored piece: the ones it adds to those before it.
#[derive(Debug, Clone)]
pub struct RawPiece {
    samples: Arc<Vec<Sample>>,
    from: usize,
}

impl std::ops::Deref for RawPiece {
    type Target = [Sample];
    fn deref(&self) -> &[Sample] {
        &self.samples[self.from..]
    }
}

#[derive(Debug)]
enum Stored {
    Chunk { seq: u64, n: u64, layout: i64, data: Vec<u8> },
    Log(log::Piece),
}

impl Stored {
    fn seq(&self) -> u64 {
        match self {
            Stored::Chunk { seq, .. } => *seq,
            Stored::Log(piece) => piece.seq,
        }
    }
}

impl RawSamples {
    /// Every sample, in one vector.
    pub fn collect_all(self) -> anyhow::Result<Vec<Sample>> {
        let mut samples = Vec::new();
        for piece in self {
            samples.extend_from_slice(&piece?);
        }
        Ok(samples)
    }

    fn next_piece(&mut self) -> anyhow::Result<Option<RawPiece>> {
        let stroke = self.stroke;
        for stored in self.pieces.by_ref() {
            let (seq, samples) = match stored {
                Stored::Chunk { seq, n, layout, data } => {
                    let samples = decode_samples(layout, &data)
                        .with_context(|| format!("stroke {stroke}: chunk at seq {seq}"))?;
                    anyhow::ensure!(
                        samples.len() as u64 == n,
                        "stroke {stroke}: chunk at seq {seq} has a bad length"
                    );
                    (seq, samples)
                }
                Stored::Log(piece) => (piece.seq, piece.samples),
            };
            let end = seq + samples.len() as u64;
            anyhow::ensure!(
                seq <= self.next,
                "stroke {stroke}: samples from {seq} follow {} samples",
                self.next
            );
            // The samples it holds that were given already lie in the last piece, which
            // begins at or before it (the order is by seq) and ends at `next`.
            let copies = (end.min(self.next) - seq) as usize;
            if let Some((last_seq, last)) = &self.last {
                let at = (seq - last_seq) as usize;
                anyhow::ensure!(
                    last[at..at + copies] == samples[..copies],
                    "stroke {stroke}: two stored copies of samples {seq}..{} differ",
                    seq + copies as u64
                );
            }
            if end <= self.next {
                continue;
            }
            let samples = Arc::new(samples);
            self.next = end;
            self.last = Some((seq, samples.clone()));
            return Ok(Some(RawPiece { samples, from: copies }));
        }
        Ok(None)
    }
}

/// Samples already in memory (a simplified stroke), as one piece.
impl From<Vec<Sample>> for RawSamples {
    fn from(samples: Vec<Sample>) -> RawSamples {
        let piece = Stored::Log(log::Piece { seq: 0, samples });
        RawSamples { stroke: Uuid::nil(), pieces: vec![piece].into_iter(), last: None, next: 0 }
    }
}

impl Iterator for RawSamples {
    type Item = anyhow::Result<RawPiece>;

    fn next(&mut self) -> Option<Self::Item> {
        match self.next_piece() {
            Ok(piece) => piece.map(Ok),
            Err(err) => {
                self.pieces = Vec::new().into_iter();
                Some(Err(err))
            }
        }
    }
}

/// A stroke's [`RawSamples`]: its chunk rows, and its entries in `log` (read by the caller).
async fn read_raw(
    conn: &mut AnyConnection,
    stroke: Uuid,
    log: &log::StrokeEntries,
) -> anyhow::Result<RawSamples> {
    let rows = sqlx::query(CHUNKS_SELECT).bind(stroke.to_string()).fetch_all(&mut *conn).await?;
    let mut pieces = Vec::with_capacity(rows.len());
    for row in rows {
        let seq = row.try_get::<i64, _>("seq")? as u64;
        let n = row.try_get::<i64, _>("n")? as u64;
        pieces.push(Stored::Chunk {
            seq,
            n,
            layout: row.try_get("layout")?,
            data: row.try_get("data")?,
        });
    }
    for (_, _, entry) in log.get(&stroke).into_iter().flatten() {
        pieces.push(Stored::Log(log::Piece { seq: entry.seq, samples: entry.samples.clone() }));
    }
    pieces.sort_by_key(Stored::seq); // stable: chunks before log entries at the same seq
    Ok(RawSamples { stroke, pieces: pieces.into_iter(), last: None, next: 0 })
}

/// A stroke's pieces from its `stroke_chunks` rows (`seq, n, layout, data`), decoded.
pub(crate) fn pieces_from_chunks(
    stroke: Uuid,
    rows: &[sqlx::any::AnyRow],
) -> anyhow::Result<Vec<log::Piece>> {
    let mut pieces = Vec::with_capacity(rows.len());
    for row in rows {
        let seq: i64 = row.try_get("seq")?;
        let n: i64 = row.try_get("n")?;
        let data: Vec<u8> = row.try_get("data")?;
        let layout: i64 = row.try_get("layout")?;
        let samples = decode_samples(layout, &data)
            .with_context(|| format!("stroke {stroke}: chunk at seq {seq}"))?;
        anyhow::ensure!(
            samples.len() as i64 == n,
            "stroke {stroke}: chunk at seq {seq} has a bad length"
        );
        pieces.push(log::Piece { seq: seq as u64, samples });
    }
    Ok(pieces)
}

/// Where a stroke's samples are stored, each piece as `(seq, n)` in `seq` order: its
/// `stroke_chunks` rows, and its entries in the append log. For tests that look at a database
/// directly.
pub async fn stored_pieces(
    pool: &AnyPool,
    stroke: Uuid,
) -> anyhow::Result<(Vec<(u64, u64)>, Vec<(u64, u64)>)> {
    let mut conn = pool.acquire().await?;
    let rows = sqlx::query("SELECT seq, n FROM stroke_chunks WHERE stroke_id = $1 ORDER BY seq")
        .bind(stroke.to_string())
        .fetch_all(&mut *conn)
        .await?;
    let mut chunks = Vec::new();
    for row in rows {
        chunks.push((row.try_get::<i64, _>("seq")? as u64, row.try_get::<i64, _>("n")? as u64));
    }
    let log = log::read_log(&mut conn, Some(&HashSet::from([stroke])), None).await?;
    let mut entries: Vec<(u64, u64)> = log
        .get(&stroke)
        .into_iter()
        .flatten()
        .map(|(_, _, e)| (e.seq, e.samples.len() as u64))
        .collect();
    entries.sort_unstable();
    Ok((chunks, entries))
}

/// The query of a stroke's chunks that [`samples_from_chunks`] reads.
pub(crate) const CHUNKS_SELECT: &str =
    "SELECT seq, n, layout, data FROM stroke_chunks WHERE stroke_id = $1 ORDER BY seq";

/// How large the SQLite write-ahead log grows before the writer checkpoints it itself (64 MB,
/// 16,384 pages of 4 KB).
const WRITER_CHECKPOINT_BYTES: i64 = 64 << 20;

/// How often the SQLite checkpointer copies the write-ahead log back into the database.
const CHECKPOINT_INTERVAL: Duration = Duration::from_millis(100);

/// SQLite: copies the write-ahead log into the database from a connection of the pool, so that
/// the group-commit writer does not do it on its own critical path. By default SQLite
/// checkpoints at the end of a commit once the log holds 1,000 pages; under 500 pens that was a
/// 4 MB copy and an fsync every tenth commit, delaying every request queued behind it. The
/// writer's connection raises that to [`WRITER_CHECKPOINT_BYTES`] ([`Store::open_write_connection`]) and still
/// checkpoints there (only it can restart the log from the beginning), but by then the pages
/// are already copied and what is left is short. Every 100 ms rather than every second: at 1 s
/// the SQLite threads spent 10 % less CPU under 500 pens, but p99 latency rose from 150 to
/// 225 ms behind the larger copies.
pub fn start_checkpointer(store: Store, stop: CancellationToken) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        loop {
            tokio::select! {
                _ = stop.cancelled() => return,
                _ = tokio::time::sleep(CHECKPOINT_INTERVAL) => {}
            }
            if let Err(err) =
                sqlx::query("PRAGMA wal_checkpoint(PASSIVE)").execute(store.pool()).await
            {
                tracing::warn!(error = %err, "checkpointing the SQLite log");
            }
        }
    })
}

/// Queues `events` as notifications of the current PostgreSQL transaction: they are delivered
/// to every listening replica when (and only if) it commits, in commit order.
pub(crate) async fn notify(
    conn: &mut sqlx::AnyConnection,
    events: &[SessionEvent],
) -> anyhow::Result<()> {
    let payloads = SessionEvent::notify_payloads(events);
    for chunk in payloads.chunks(500) {
        let values: Vec<String> = (1..=chunk.len()).map(|i| format!("(${i})")).collect();
        let sql = format!(
            "SELECT COUNT(pg_notify('{EVENTS_CHANNEL}', v)) AS n FROM (VALUES {}) AS t (v)",
            values.join(", ")
        );
        let mut query = sqlx::query(&sql);
        for payload in chunk {
            query = query.bind(payload.as_str());
        }
        query.fetch_one(&mut *conn).await?;
    }
    Ok(())
}

/// `n_points` is where the last stored chunk ends (a stroke's chunks are contiguous from 0): the
/// appends of the group commit write nothing but their chunk, so that a commit touches as few
/// pages as it can.
const STROKE_SELECT: &str = "SELECT s.id, s.session_id, s.participant, s.brush, s.params, s.device, \
     s.status, s.n_retained, s.created_at, s.updated_at, \
     COALESCE((SELECT c.seq + c.n FROM stroke_chunks c WHERE c.stroke_id = s.id \
     ORDER BY c.seq DESC LIMIT 1), 0) AS n_points, \
     (SELECT COUNT(*) FROM meshes m WHERE m.stroke_id = s.id) AS n_meshes FROM strokes s";

/// A stroke's stored ACUTS parameters: the current JSON form, or the form written before the
/// pressure gate was a choice, `{"tolerance", "angle_deg", "pressure_variance"}`, which meant the
/// paper's variance gate with the angle test near the anchor.
fn read_stored_params(json: &str) -> anyhow::Result<penmesh::AcutsParams> {
    #[derive(serde::Deserialize)]
    #[serde(untagged)]
    enum Stored {
        Current(penmesh::AcutsParams),
        BeforeTheGateChoice { tolerance: f64, angle_deg: f64, pressure_variance: f64 },
    }
    Ok(match serde_json::from_str(json).with_context(|| format!("stored params {json}"))? {
        Stored::Current(params) => params,
        Stored::BeforeTheGateChoice { tolerance, angle_deg, pressure_variance } => {
            penmesh::AcutsParams {
                tolerance,
                angle_deg,
                angle_near_anchor: true,
                pressure: penmesh::PressureGate::Variance(pressure_variance),
            }
        }
    })
}

fn stroke_from_row(row: &sqlx::any::AnyRow) -> anyhow::Result<StrokeRow> {
    let status: String = row.try_get("status")?;
    let brush: String = row.try_get("brush")?;
    let params: String = row.try_get("params")?;
    Ok(StrokeRow {
        id: parse_uuid(&row.try_get::<String, _>("id")?)?,
        session_id: parse_uuid(&row.try_get::<String, _>("session_id")?)?,
        participant: parse_uuid(&row.try_get::<String, _>("participant")?)?,
        brush: serde_json::from_str(&brush).context("stored brush")?,
        params: read_stored_params(&params)?,
        device: row.try_get("device")?,
        status: StrokeStatus::parse(&status)
            .with_context(|| format!("stored status {status:?}"))?,
        n_points: row.try_get::<i64, _>("n_points")? as u64,
        n_retained: row.try_get::<i64, _>("n_retained")? as u64,
        created_at: row.try_get("created_at")?,
        updated_at: row.try_get("updated_at")?,
        has_mesh: row.try_get::<i64, _>("n_meshes")? > 0,
    })
}

/// The settings of every SQLite connection.
fn sqlite_settings(synchronous: &str, page_size: impl std::fmt::Display) -> String {
    // The page size first: it has to be set before `journal_mode` writes a new file's header.
    format!(
        "PRAGMA page_size={page_size}; PRAGMA journal_mode=WAL; PRAGMA busy_timeout=5000; PRAGMA synchronous={synchronous}; \
         PRAGMA foreign_keys=ON;"
    )
}

/// Creates the folder of a SQLite file, so a fresh path works.
fn create_parent_dir(url: &str) -> anyhow::Result<()> {
    let path = url.trim_start_matches("sqlite:").trim_start_matches("//");
    let path = path.split('?').next().unwrap_or_default();
    if path.is_empty() || path == ":memory:" {
        return Ok(());
    }
    if let Some(parent) = std::path::Path::new(path).parent().filter(|p| !p.as_os_str().is_empty())
    {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating the database folder {}", parent.display()))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    // Parameters stored before the pressure gate was a choice read as the paper's gate.
    #[test]
    fn parameters_of_older_rows_are_read() {
        let old = r#"{"tolerance":0.74,"angle_deg":15.0,"pressure_variance":0.0015}"#;
        assert_eq!(read_stored_params(old).unwrap(), penmesh::AcutsParams::paper());
        let current = serde_json::to_string(&penmesh::AcutsParams::default()).unwrap();
        assert_eq!(read_stored_params(&current).unwrap(), penmesh::AcutsParams::default());
        assert!(
            read_stored_params(r#"{"tolerance":1}"#)
                .unwrap_err()
                .to_string()
                .contains("stored params")
        );
    }

    // The page size is the new file's; a file keeps the one it was made with.
    #[tokio::test]
    async fn a_database_is_made_with_the_page_size_set_and_keeps_it() {
        let dir = tempfile::tempdir().unwrap();
        let url = format!("sqlite://{}", dir.path().join("p.db").display());
        let config = |page_size| Config {
            database_url: url.clone().into(),
            sqlite_page_size: page_size,
            ..Config::defaults()
        };
        let page_size = |store: Store| async move {
            let mut conn = store.open_write_connection().await.unwrap();
            let size: i64 =
                sqlx::query_scalar("PRAGMA page_size").fetch_one(&mut conn).await.unwrap();
            let pages: i64 =
                sqlx::query_scalar("PRAGMA wal_autocheckpoint").fetch_one(&mut conn).await.unwrap();
            assert_eq!(size * pages, WRITER_CHECKPOINT_BYTES, "the writer's checkpoint in bytes");
            store.pool().close().await;
            size
        };
        assert_eq!(page_size(Store::connect(&config(2048)).await.unwrap()).await, 2048);
        assert_eq!(page_size(Store::connect(&config(1024)).await.unwrap()).await, 2048);
    }

    // The raw samples come piece by piece, each stored piece decoded when its turn comes:
    // copies of a sample in two pieces must agree, and a hole ends the samples with an error.
    #[test]
    fn raw_samples_come_in_order_from_overlapping_pieces() {
        let s: Vec<Sample> = (0..10).map(|i| Sample::new(i as f64, 0.0, i as f64, 0.5)).collect();
        let chunk = |seq: usize, n: usize| {
            let (layout, data) = encode_samples(&s[seq..seq + n]);
            Stored::Chunk { seq: seq as u64, n: n as u64, layout, data }
        };
        let entry = |seq: usize, n: usize| {
            Stored::Log(log::Piece { seq: seq as u64, samples: s[seq..seq + n].to_vec() })
        };
        let raw = |pieces: Vec<Stored>| RawSamples {
            stroke: Uuid::nil(),
            pieces: pieces.into_iter(),
            last: None,
            next: 0,
        };
        // Chunks [0, 6) and [2, 4) (moved twice), log entries [4, 8) and [8, 10).
        let pieces = raw(vec![chunk(0, 6), chunk(2, 2), entry(4, 4), entry(8, 2)]);
        let lengths: Vec<usize> = pieces.map(|p| p.unwrap().len()).collect();
        assert_eq!(lengths, vec![6, 2, 2], "each piece adds only what is new");
        let all = raw(vec![chunk(0, 6), chunk(2, 2), entry(4, 4), entry(8, 2)]);
        assert_eq!(all.collect_all().unwrap(), s);
        let hole = raw(vec![chunk(0, 4), entry(5, 5)]).collect_all().unwrap_err();
        assert!(hole.to_string().contains("from 5 follow 4"), "{hole}");
        let mut other = s[2..5].to_vec();
        other[1].x += 1.0;
        let differs = raw(vec![chunk(0, 4), Stored::Log(log::Piece { seq: 2, samples: other })]);
        assert!(differs.collect_all().unwrap_err().to_string().contains("differ"));
        let mut broken = raw(vec![chunk(0, 4), chunk(4, 6)]);
        if let Some(Stored::Chunk { data, .. }) = broken.pieces.as_mut_slice().get_mut(1) {
            data.truncate(2);
        }
        assert!(broken.next().unwrap().is_ok());
        assert!(broken.next().unwrap().is_err(), "a piece that cannot be decoded");
        assert!(broken.next().is_none(), "and then nothing");
    }

    #[test]
    fn samples_round_trip_through_the_blob() {
        // On the grid: the compact layout, at a few bytes a sample.
        let samples = vec![Sample::new(1.5, -2.0, 3.25, 0.5), Sample::new(0.0, 0.0, 4.0, 1.0)];
        let (layout, bytes) = encode_samples(&samples);
        assert_eq!(layout, LAYOUT_POINT_BATCH);
        assert!(bytes.len() < 16, "{} bytes, not a quarter of the f64 form", bytes.len());
        assert_eq!(decode_samples(layout, &bytes).unwrap(), samples);
        // Off it (stored by an earlier version): f64, exact.
        let old = vec![Sample::new(0.1, 0.2, 0.3, 0.4)];
        let (layout, bytes) = encode_samples(&old);
        assert_eq!(layout, LAYOUT_F64);
        assert_eq!(decode_samples(layout, &bytes).unwrap(), old);
        assert!(decode_samples(LAYOUT_F64, &[0; 31]).is_err());
        assert!(decode_samples(LAYOUT_POINT_BATCH, &[]).is_err());
        assert!(decode_samples(7, &bytes).unwrap_err().to_string().contains("layout 7"));
    }
}
