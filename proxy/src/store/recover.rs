//! What a process that stopped without moving its strokes out of the append log left behind:
//! moved at the next start (SQLite), or by another replica's reaper (PostgreSQL,
//! `cluster::reap_log`, through [`move_log_tail`]).

use sqlx::AnyConnection;
use uuid::Uuid;

use super::{Backend, CHUNKS_SELECT, Store, encode_samples, log, now_ms, pieces_from_chunks};

impl Store {
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
