//! The writer's statements: a stroke's samples into `stroke_chunks` in as few statements as can
//! be, a finish, a mesh within its session's quota, and the other ops.

use std::collections::HashMap;

use penmesh::{Kept, Sample, Solid};
use sqlx::AnyConnection;
use uuid::Uuid;

use super::known::Known;
use super::{WriteError, WriteOp, sharing};
use crate::store::{Backend, MeshRow, encode_indices, encode_samples};

/// Stores the simplified stroke, marks it `done`, and moves the rest of its samples (those
/// after its chunks: in the log, and this transaction's) into `stroke_chunks` as one row. A
/// stroke is one row when drawn in under [`MOVE_AFTER`](crate::store::log::MOVE_AFTER), one more per `MOVE_AFTER` of
/// drawing otherwise. The rows already stored are not read back and rewritten into one: that
/// wrote every sample of a longer stroke twice, for a few bytes of row header saved.
pub(super) async fn finish(
    conn: &mut AnyConnection,
    backend: Backend,
    stroke: Uuid,
    base: &Known,
    tail: &[Sample],
    kept: &[Kept],
    now: i64,
) -> anyhow::Result<()> {
    let mut samples = base.pending.clone();
    samples.extend_from_slice(tail);
    if !samples.is_empty() {
        insert_chunks(conn, backend, &[(stroke, base.chunk_end, &samples)]).await?;
    }
    let indices: Vec<u64> = kept.iter().map(|k| k.index as u64).collect();
    let kept_samples: Vec<Sample> = kept.iter().map(|k| k.sample).collect();
    let (layout, data) = encode_samples(&kept_samples);
    sqlx::query(
        "INSERT INTO simplified (stroke_id, indices, layout, data) VALUES ($1, $2, $3, $4) \
         ON CONFLICT (stroke_id) DO UPDATE SET indices = excluded.indices, \
         layout = excluded.layout, data = excluded.data, upto = NULL",
    )
    .bind(stroke.to_string())
    .bind(encode_indices(&indices))
    .bind(layout)
    .bind(data)
    .execute(&mut *conn)
    .await?;
    sqlx::query(
        "UPDATE strokes SET status = 'done', n_retained = $1, updated_at = $2 WHERE id = $3",
    )
    .bind(kept.len() as i64)
    .bind(now)
    .bind(stroke.to_string())
    .execute(&mut *conn)
    .await?;
    Ok(())
}

/// Most rows per multi-row `INSERT`. A group commit is a chain of round trips to the database
/// (with SQLite, to sqlx's worker thread), and when the cores are busy each round trip waits
/// for the scheduler, twice: under 500 pens a commit of 14 statements took 13 ms while SQLite
/// itself was busy a quarter of that. So a commit's moves go in as few statements as SQLite's
/// parameter limit allows (5 parameters per row, at most 32,766 per statement).
pub(super) const MAX_ROWS_PER_STATEMENT: usize = 1024;

/// Statements of up to this many rows (and of exactly [`MAX_ROWS_PER_STATEMENT`]) stay in the
/// connection's prepared-statement cache: the shapes of a lightly loaded proxy. Other sizes are
/// prepared for one use, so that they do not push the common shapes out of the cache.
pub(super) const CACHED_ROWS: usize = 16;

/// Rows of `stroke_chunks` (stroke, seq of the first sample, samples) as multi-row `INSERT`s
/// (see [`MAX_ROWS_PER_STATEMENT`]); pieces of one stroke that follow each other become one row.
///
/// SQLite gets positional `?` placeholders: sqlx's SQLite driver looks each numbered `$N` up by
/// name among all the statement's parameters, which is quadratic in their number.
pub(super) async fn insert_chunks(
    conn: &mut AnyConnection,
    backend: Backend,
    appends: &[(Uuid, u64, &[Sample])],
) -> anyhow::Result<()> {
    use std::fmt::Write;
    // (stroke, seq of the first sample, samples), and where each stroke's last row is.
    let mut rows: Vec<(Uuid, u64, Vec<Sample>)> = Vec::new();
    let mut last_row: HashMap<Uuid, usize> = HashMap::new();
    for &(stroke, seq, samples) in appends {
        match last_row.get(&stroke) {
            Some(&i) if rows[i].1 + rows[i].2.len() as u64 == seq => {
                rows[i].2.extend_from_slice(samples)
            }
            _ => {
                last_row.insert(stroke, rows.len());
                rows.push((stroke, seq, samples.to_vec()));
            }
        }
    }
    for chunk in rows.chunks(MAX_ROWS_PER_STATEMENT) {
        let mut sql =
            String::from("INSERT INTO stroke_chunks (stroke_id, seq, n, layout, data) VALUES ");
        for k in 0..chunk.len() {
            let sep = if k == 0 { "" } else { ", " };
            match backend {
                Backend::Sqlite => {
                    let _ = write!(sql, "{sep}(?, ?, ?, ?, ?)");
                }
                Backend::Postgres => {
                    let p = 5 * k;
                    let _ = write!(
                        sql,
                        "{sep}(${}, ${}, ${}, ${}, ${})",
                        p + 1,
                        p + 2,
                        p + 3,
                        p + 4,
                        p + 5
                    );
                }
            }
        }
        // No `ON CONFLICT`: the writer only writes what is not stored (`WriterLoop::strokes`), so
        // a conflict is a wrong end, and failing makes the retry read the ends again.
        let cached = chunk.len() <= CACHED_ROWS || chunk.len() == MAX_ROWS_PER_STATEMENT;
        let mut query = sqlx::query(&sql).persistent(cached);
        for (stroke, seq, samples) in chunk {
            let (layout, data) = encode_samples(samples);
            query = query
                .bind(stroke.to_string())
                .bind(*seq as i64)
                .bind(samples.len() as i64)
                .bind(layout)
                .bind(data);
        }
        query.execute(&mut *conn).await?;
    }
    Ok(())
}

/// Stores a done stroke's mesh, a mesh of `solid`, unless the meshes of its session would then
/// hold more than `quota` bytes: one statement, which sees the meshes this transaction wrote
/// before it (the replaced row too when a duplicate keeps it: [`sharing`]). `Err`: refused,
/// nothing written.
pub(super) async fn put_mesh(
    conn: &mut AnyConnection,
    (stroke, session): (Uuid, Uuid),
    mesh: &MeshRow,
    solid: Solid,
    quota: u64,
) -> anyhow::Result<Result<(), WriteError>> {
    let left = sharing::leave_row(conn, stroke, solid).await?;
    // `length` of a blob is its size in bytes in both SQLite and PostgreSQL, read without
    // loading the blob.
    const OTHERS: &str = "SELECT COALESCE(SUM(length(m.glb)), 0) FROM meshes m \
         JOIN strokes s ON s.id = m.stroke_id WHERE s.session_id = $1 AND m.stroke_id <> $2";
    let written = sqlx::query(&format!(
        "INSERT INTO meshes (stroke_id, glb, vertices, triangles, uploader, created_at) \
         SELECT $2, $3, $4, $5, $6, $7 WHERE ({OTHERS}) + $8 <= $9 \
         ON CONFLICT (stroke_id) DO UPDATE SET glb = excluded.glb, vertices = excluded.vertices, \
         triangles = excluded.triangles, uploader = excluded.uploader, \
         created_at = excluded.created_at"
    ))
    .bind(session.to_string())
    .bind(stroke.to_string())
    .bind(mesh.glb.as_slice())
    .bind(mesh.vertices as i64)
    .bind(mesh.triangles as i64)
    .bind(mesh.uploader.clone())
    .bind(mesh.created_at)
    .bind(mesh.glb.len() as i64)
    .bind(i64::try_from(quota).unwrap_or(i64::MAX))
    .execute(&mut *conn)
    .await?;
    if written.rows_affected() > 0 {
        sharing::settle(conn, stroke, solid, left).await?;
        return Ok(Ok(()));
    }
    sharing::undo(conn, stroke, left).await?;
    let others: i64 = sqlx::query_scalar(OTHERS)
        .bind(session.to_string())
        .bind(stroke.to_string())
        .fetch_one(&mut *conn)
        .await?;
    Ok(Err(WriteError::Quota(format!(
        "the meshes of this session hold {others} bytes (this stroke's own not counted); with \
         this one of {} bytes they would pass the session's quota of {quota} bytes",
        mesh.glb.len()
    ))))
}

/// The samples stored in `stroke_chunks` for the strokes of `session` (what its sample quota
/// counts), read without reading the samples.
pub(super) async fn session_samples(
    conn: &mut AnyConnection,
    session: Uuid,
) -> anyhow::Result<u64> {
    // PostgreSQL sums BIGINTs as NUMERIC, which the `Any` driver does not read.
    let n: i64 = sqlx::query_scalar(
        "SELECT CAST(COALESCE(SUM(c.n), 0) AS BIGINT) FROM stroke_chunks c \
         JOIN strokes s ON s.id = c.stroke_id WHERE s.session_id = $1",
    )
    .bind(session.to_string())
    .fetch_one(&mut *conn)
    .await?;
    Ok(n.max(0) as u64)
}

/// A `CopySamples` op: the stored rows of `source` (its chunks, as stored, and its simplified
/// stroke) copied to `stroke` inside the database, and `stroke` marked `done`. The source is
/// done, so all its samples are in `stroke_chunks`.
async fn copy_samples(
    conn: &mut AnyConnection,
    stroke: Uuid,
    source: Uuid,
    now: i64,
) -> anyhow::Result<()> {
    let (stroke, source) = (stroke.to_string(), source.to_string());
    sqlx::query(
        "INSERT INTO stroke_chunks (stroke_id, seq, n, layout, data) \
         SELECT $1, seq, n, layout, data FROM stroke_chunks WHERE stroke_id = $2",
    )
    .bind(&stroke)
    .bind(&source)
    .execute(&mut *conn)
    .await?;
    let simplified = sqlx::query(
        "INSERT INTO simplified (stroke_id, indices, layout, data) \
         SELECT $1, indices, layout, data FROM simplified WHERE stroke_id = $2 AND upto IS NULL",
    )
    .bind(&stroke)
    .bind(&source)
    .execute(&mut *conn)
    .await?;
    anyhow::ensure!(simplified.rows_affected() == 1, "stroke {source} has no simplified stroke");
    sqlx::query(
        "UPDATE strokes SET status = 'done', updated_at = $1, \
         n_retained = (SELECT n_retained FROM strokes WHERE id = $2) WHERE id = $3",
    )
    .bind(now)
    .bind(&source)
    .bind(&stroke)
    .execute(&mut *conn)
    .await?;
    Ok(())
}

/// Inserts a `Place` op's row of `stroke_placements`: its id, which orders the stroke's
/// placements (the fan-out skips one not newer than what a client was told).
pub(super) async fn place(conn: &mut AnyConnection, op: &WriteOp) -> anyhow::Result<i64> {
    let WriteOp::Place { stroke, placement, by, at, cause } = op else {
        anyhow::bail!("not a placement: {op:?}");
    };
    let id = sqlx::query_scalar(
        "INSERT INTO stroke_placements (stroke_id, matrix, set_by, set_at, cause) \
         VALUES ($1, $2, $3, $4, $5) RETURNING id",
    )
    .bind(stroke.to_string())
    .bind(placement.to_bytes())
    .bind(by.to_string())
    .bind(*at)
    .bind(*cause)
    .fetch_one(&mut *conn)
    .await?;
    Ok(id)
}

/// Applies an op other than an append, a finish or a placement. `true`: it created a stroke.
pub(super) async fn apply(
    conn: &mut AnyConnection,
    op: &WriteOp,
    now: i64,
) -> anyhow::Result<bool> {
    match op {
        WriteOp::BeginStroke { stroke, session, participant, brush, params, device } => {
            let created = sqlx::query(
                "INSERT INTO strokes (id, session_id, participant, brush, params, device, status, \
                 n_retained, created_at, updated_at) \
                 VALUES ($1, $2, $3, $4, $5, $6, 'open', 0, $7, $7) ON CONFLICT (id) DO NOTHING",
            )
            .bind(stroke.to_string())
            .bind(session.to_string())
            .bind(participant.to_string())
            .bind(serde_json::to_string(brush)?)
            .bind(serde_json::to_string(params)?)
            .bind(device.clone())
            .bind(now)
            .execute(&mut *conn)
            .await?;
            return Ok(created.rows_affected() == 1);
        }
        WriteOp::Append { .. } => anyhow::bail!("an append goes into the log record"),
        WriteOp::PutMesh { .. } => anyhow::bail!("a mesh is written where it is planned"),
        WriteOp::KeepRetained { stroke, upto, kept } => {
            let indices: Vec<u64> = kept.iter().map(|k| k.index as u64).collect();
            let samples: Vec<Sample> = kept.iter().map(|k| k.sample).collect();
            let (layout, data) = encode_samples(&samples);
            // Never over the simplified stroke of a done stroke (`upto` NULL), nor over what
            // covers more samples.
            sqlx::query(
                "INSERT INTO simplified (stroke_id, indices, layout, data, upto) \
                 VALUES ($1, $2, $3, $4, $5) ON CONFLICT (stroke_id) DO UPDATE SET \
                 indices = excluded.indices, layout = excluded.layout, data = excluded.data, \
                 upto = excluded.upto \
                 WHERE simplified.upto IS NOT NULL AND simplified.upto < excluded.upto",
            )
            .bind(stroke.to_string())
            .bind(encode_indices(&indices))
            .bind(layout)
            .bind(data)
            .bind(*upto as i64)
            .execute(&mut *conn)
            .await?;
        }
        WriteOp::Finish { .. } => anyhow::bail!("a finish goes through `finish`"),
        WriteOp::Join { connection, participant, session, name, replica } => {
            sqlx::query(
                "INSERT INTO participants (connection, participant, session_id, name, joined_at, \
                 replica_key) VALUES ($1, $2, $3, $4, $5, $6) ON CONFLICT (connection) DO NOTHING",
            )
            .bind(connection.to_string())
            .bind(participant.to_string())
            .bind(session.to_string())
            .bind(name.clone())
            .bind(now)
            .bind(*replica)
            .execute(&mut *conn)
            .await?;
        }
        WriteOp::Leave { connection } => {
            sqlx::query(
                "UPDATE participants SET left_at = $1 WHERE connection = $2 AND left_at IS NULL",
            )
            .bind(now)
            .bind(connection.to_string())
            .execute(&mut *conn)
            .await?;
        }
        WriteOp::SetRemoved { stroke, removed: Some(removal) } => {
            sqlx::query(
                "UPDATE strokes SET removed_at = $1, removed_by = $2 \
                 WHERE id = $3 AND removed_at IS NULL",
            )
            .bind(removal.at)
            .bind(removal.by.to_string())
            .bind(stroke.to_string())
            .execute(&mut *conn)
            .await?;
        }
        WriteOp::Place { .. } => anyhow::bail!("a placement goes through `place`"),
        WriteOp::SetSolid { stroke, solid, by, at, cause } => {
            sqlx::query(
                "INSERT INTO stroke_solids (stroke_id, solid, set_by, set_at, cause) \
                 VALUES ($1, $2, $3, $4, $5)",
            )
            .bind(stroke.to_string())
            .bind(solid.to_bytes().to_vec())
            .bind(by.to_string())
            .bind(*at)
            .bind(*cause)
            .execute(&mut *conn)
            .await?;
            if *cause == "set" {
                sqlx::query(
                    "UPDATE strokes SET mesh_of = NULL WHERE id = $1 AND mesh_of IS NOT NULL",
                )
                .bind(stroke.to_string())
                .execute(&mut *conn)
                .await?;
            }
        }
        WriteOp::MarkDuplicate { stroke, source, shares } => {
            // The row its source shows as this transaction commits (the source's own, or the
            // one it shares), not as it was read before.
            sqlx::query(
                "UPDATE strokes SET duplicate_of = $1, mesh_of = CASE WHEN $2 THEN \
                 (SELECT COALESCE(s.mesh_of, s.id) FROM strokes s WHERE s.id = $1) END \
                 WHERE id = $3",
            )
            .bind(source.to_string())
            .bind(shares.is_some())
            .bind(stroke.to_string())
            .execute(&mut *conn)
            .await?;
        }
        WriteOp::MarkImported { stroke, from, importer_name } => {
            sqlx::query(
                "INSERT INTO stroke_imports (stroke_id, source_stroke, author_id, author_name, \
                 drawn_at, imported_at, importer_name) VALUES ($1, $2, $3, $4, $5, $6, $7)",
            )
            .bind(stroke.to_string())
            .bind(from.stroke.to_string())
            .bind(from.author.participant.to_string())
            .bind(from.author.name.clone())
            .bind(from.drawn_at)
            .bind(from.imported_at)
            .bind(importer_name.clone())
            .execute(&mut *conn)
            .await?;
        }
        // Checked when planned; nothing to write.
        WriteOp::Claim { .. } | WriteOp::CountSamples { .. } => {}
        WriteOp::CopySamples { stroke, source } => {
            copy_samples(conn, *stroke, *source, now).await?
        }
        WriteOp::SetRemoved { stroke, removed: None } => {
            sqlx::query("UPDATE strokes SET removed_at = NULL, removed_by = NULL WHERE id = $1")
                .bind(stroke.to_string())
                .execute(&mut *conn)
                .await?;
        }
        WriteOp::Rename { participant, session, name } => {
            sqlx::query(
                "UPDATE participants SET name = $1 \
                 WHERE session_id = $2 AND participant = $3 AND left_at IS NULL",
            )
            .bind(name.clone())
            .bind(session.to_string())
            .bind(participant.to_string())
            .execute(&mut *conn)
            .await?;
        }
        WriteOp::SetStatus { stroke, status } => {
            sqlx::query(
                "UPDATE strokes SET status = $1, updated_at = $2 WHERE id = $3 AND status <> 'done'",
            )
            .bind(status.as_str())
            .bind(now)
            .bind(stroke.to_string())
            .execute(&mut *conn)
            .await?;
        }
    }
    Ok(false)
}
