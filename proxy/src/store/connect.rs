//! Connecting: the pool with its SQLite settings, the migrations, and the writer's own
//! connection; the handle every other part of the store goes through ([`Store`]).

use std::str::FromStr;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use sqlx::any::{AnyConnectOptions, AnyPoolOptions};
use sqlx::{AnyConnection, AnyPool, Connection, Executor};

use crate::config::{Config, SqliteSync};

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
    pub(super) pool: AnyPool,
    pub(super) backend: Backend,
    /// How the pool's connections are opened, for the writer's own (see `open_write_connection`).
    options: AnyConnectOptions,
    synchronous: &'static str,
    /// SQLite: the file's page size (`--sqlite-page-size` when this proxy made the file).
    page_size: i64,
    /// The longest one database round trip may take (`--db-timeout-ms`): taking a pool
    /// connection, and the writer's transactions.
    deadline: Duration,
    /// One permit per replay of a long stroke at once (`--max-replays`, [`Store::replay`]).
    pub(super) replays: Arc<tokio::sync::Semaphore>,
}

/// How large the SQLite write-ahead log grows before the writer checkpoints it itself (64 MB,
/// 16,384 pages of 4 KB).
const WRITER_CHECKPOINT_BYTES: i64 = 64 << 20;

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
    /// - the log is copied into the database by the checkpointer ([`start_checkpointer`](super::start_checkpointer)), off
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
}
