//! The database layer: one set of queries for SQLite and PostgreSQL through sqlx's `Any`
//! driver, the embedded migrations, and the group-commit [`writer`].
//!
//! **Only this module knows how samples are laid out in the database** (`encode_samples`, and
//! the append log's records, [`log`]). A stroke's samples are in `stroke_chunks` and, while it is
//! drawn, in `stroke_log`: every reader of raw samples reads both.

pub(crate) mod log;
mod meshes;
mod writer;

use std::collections::HashSet;
use std::str::FromStr;
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
}

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
        Ok(Store { pool, backend, options, synchronous, page_size, deadline })
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
        self.raw_samples_with(&mut conn, stroke, &log).await
    }

    /// A stroke's raw samples from its chunks and its entries in `log` (read by the caller).
    async fn raw_samples_with(
        &self,
        conn: &mut AnyConnection,
        stroke: Uuid,
        log: &log::StrokeEntries,
    ) -> anyhow::Result<Vec<Sample>> {
        let rows =
            sqlx::query(CHUNKS_SELECT).bind(stroke.to_string()).fetch_all(&mut *conn).await?;
        let mut pieces = pieces_from_chunks(stroke, &rows)?;
        for (_, _, entry) in log.get(&stroke).into_iter().flatten() {
            pieces.push(log::Piece { seq: entry.seq, samples: entry.samples.clone() });
        }
        log::assemble(stroke, pieces)
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
            let mut entries: Vec<(u64, u64)> = log
                .get(&row.id)
                .into_iter()
                .flatten()
                .map(|(_, _, e)| (e.seq, e.samples.len() as u64))
                .collect();
            entries.sort_unstable();
            for (seq, n) in entries {
                if seq <= row.n_points {
                    row.n_points = row.n_points.max(seq + n);
                }
            }
        }
        Ok(())
    }

    /// SQLite, at start: strokes left in the log by a process that stopped without moving them
    /// (killed) go into `stroke_chunks`, and the log is emptied. (With PostgreSQL another
    /// replica may be writing; readers read the log, so nothing is lost either way.)
    pub async fn recover_log(&self) -> anyhow::Result<u64> {
        if self.backend != Backend::Sqlite {
            return Ok(0);
        }
        let mut conn = self.pool.acquire().await?;
        let mut tx = sqlx::Connection::begin_with(&mut *conn, self.begin_statement()).await?;
        let log = log::read_log(&mut tx, None, None).await?;
        let mut moved = 0;
        for (stroke, entries) in log {
            moved += u64::from(move_log_tail(&mut tx, stroke, entries).await?);
        }
        sqlx::query("DELETE FROM stroke_log").execute(&mut *tx).await?;
        tx.commit().await?;
        Ok(moved)
    }

    pub async fn simplified(&self, stroke: Uuid) -> anyhow::Result<Option<Simplified>> {
        let row = sqlx::query("SELECT indices, layout, data FROM simplified WHERE stroke_id = $1")
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

    /// Stores (or replaces) a stroke's mesh; with PostgreSQL `events` are notified in the same
    /// transaction (with SQLite the caller publishes them after).
    pub async fn put_mesh(
        &self,
        stroke: Uuid,
        mesh: &MeshRow,
        events: &[SessionEvent],
    ) -> anyhow::Result<()> {
        let mut conn = self.pool.acquire().await?;
        let mut tx = sqlx::Connection::begin_with(&mut *conn, self.begin_statement()).await?;
        if self.backend == Backend::Postgres {
            notify(&mut tx, events).await?;
        }
        sqlx::query(
            "INSERT INTO meshes (stroke_id, glb, vertices, triangles, uploader, created_at) \
             VALUES ($1, $2, $3, $4, $5, $6) \
             ON CONFLICT (stroke_id) DO UPDATE SET glb = excluded.glb, vertices = excluded.vertices, \
             triangles = excluded.triangles, uploader = excluded.uploader, created_at = excluded.created_at",
        )
        .bind(stroke.to_string())
        .bind(mesh.glb.clone())
        .bind(mesh.vertices as i64)
        .bind(mesh.triangles as i64)
        .bind(mesh.uploader.clone())
        .bind(mesh.created_at)
        .execute(&mut *tx)
        .await?;
        tx.commit().await?;
        Ok(())
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
    /// retained from what is committed so far, rebuilt by replaying it), as events in order.
    /// A stroke that cannot be read is left out and named in `unreadable`; it does not hide
    /// the others.
    pub async fn session_history(&self, session: Uuid) -> anyhow::Result<SessionHistory> {
        let mut history = SessionHistory::default();
        let present = sqlx::query(
            "SELECT connection, participant, name FROM participants \
             WHERE session_id = $1 AND left_at IS NULL ORDER BY joined_at, connection",
        )
        .bind(session.to_string())
        .fetch_all(&self.pool)
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
        .fetch_all(&self.pool)
        .await?;
        let meshes = sqlx::query(
            "SELECT m.stroke_id, m.created_at FROM meshes m JOIN strokes s ON s.id = m.stroke_id \
             WHERE s.session_id = $1",
        )
        .bind(session.to_string())
        .fetch_all(&self.pool)
        .await?;
        let mut mesh_at = std::collections::HashMap::new();
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
        let mut conn = self.pool.acquire().await?;
        let log = if open.is_empty() {
            log::StrokeEntries::new()
        } else {
            log::read_log(&mut conn, Some(&open), None).await?
        };
        for row in &strokes {
            match self.stroke_history(&mut conn, session, row, &mesh_at, &log).await {
                Ok(events) => history.events.extend(events),
                Err(err) => {
                    let id = row.try_get::<String, _>("id").ok().and_then(|id| id.parse().ok());
                    tracing::error!(error = %err, stroke = ?id, "a stroke of a session's history is unreadable");
                    history.unreadable.push((id, format!("{err:#}")));
                }
            }
        }
        Ok(history)
    }

    /// One stroke's part of [`Store::session_history`].
    async fn stroke_history(
        &self,
        conn: &mut AnyConnection,
        session: Uuid,
        row: &sqlx::any::AnyRow,
        mesh_at: &std::collections::HashMap<Uuid, i64>,
        log: &log::StrokeEntries,
    ) -> anyhow::Result<Vec<SessionEvent>> {
        let row = stroke_from_row(row)?;
        let (participant, stroke) = (row.participant, row.id);
        let mut events = vec![SessionEvent::new(
            session,
            EventKind::StrokeBegin { participant, stroke, brush: row.brush },
        )];
        let done = row.status == StrokeStatus::Done;
        let points: Vec<Sample> = if done {
            self.simplified(stroke).await?.map(|s| s.samples).unwrap_or_default()
        } else {
            let raw = self.raw_samples_with(conn, stroke, log).await?;
            crate::ingest::StrokeState::replay(row.params, &raw)
                .kept()
                .iter()
                .map(|k| k.sample)
                .collect()
        };
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
        Ok(events)
    }
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
