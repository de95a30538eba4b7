//! SQLite: the checkpointer that copies the write-ahead log into the database off the writer's
//! path.

use std::time::Duration;

use tokio_util::sync::CancellationToken;

use super::Store;

/// How often the SQLite checkpointer copies the write-ahead log back into the database.
const CHECKPOINT_INTERVAL: Duration = Duration::from_millis(100);

/// SQLite: copies the write-ahead log into the database from a connection of the pool, so that
/// the group-commit writer does not do it on its own critical path. By default SQLite
/// checkpoints at the end of a commit once the log holds 1,000 pages; under 500 pens that was a
/// 4 MB copy and an fsync every tenth commit, delaying every request queued behind it. The
/// writer's connection raises that to `WRITER_CHECKPOINT_BYTES` ([`Store::open_write_connection`]) and still
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
