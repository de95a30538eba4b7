//! Reads of strokes, simplified strokes and meshes through the pool. A stroke in progress ends
//! where its entries in the append log end.

use std::collections::HashSet;

use anyhow::Context;
use penmesh::protocol::StrokeStatus;
use sqlx::Row;
use uuid::Uuid;

use super::{
    MeshRow, STROKE_SELECT, Simplified, Store, StrokeRow, decode_indices, decode_samples, log,
    stroke_from_row,
};

impl Store {
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

    /// The strokes of `session`, oldest first; the removed ones (taken back) only with
    /// `include_removed`.
    pub async fn list_strokes(
        &self,
        session: Uuid,
        include_removed: bool,
    ) -> anyhow::Result<Vec<StrokeRow>> {
        let removed = if include_removed { "" } else { " AND s.removed_at IS NULL" };
        let rows = sqlx::query(&format!(
            "{STROKE_SELECT} WHERE s.session_id = $1{removed} ORDER BY s.created_at, s.id"
        ))
        .bind(session.to_string())
        .fetch_all(&self.pool)
        .await?;
        let mut rows = rows.iter().map(stroke_from_row).collect::<anyhow::Result<Vec<_>>>()?;
        self.add_log_ends(&mut rows).await?;
        Ok(rows)
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

    /// The simplified strokes of `strokes` (done ones; others are absent), in one query: a
    /// scene export reads a thousand at once.
    pub async fn simplified_many(
        &self,
        strokes: &[Uuid],
    ) -> anyhow::Result<std::collections::HashMap<Uuid, Simplified>> {
        if strokes.is_empty() {
            return Ok(Default::default());
        }
        let places: Vec<String> = (1..=strokes.len()).map(|i| format!("${i}")).collect();
        let sql = format!(
            "SELECT stroke_id, indices, layout, data FROM simplified \
             WHERE upto IS NULL AND stroke_id IN ({})",
            places.join(", ")
        );
        let mut query = sqlx::query(&sql);
        for stroke in strokes {
            query = query.bind(stroke.to_string());
        }
        let rows = query.fetch_all(&self.pool).await?;
        rows.iter()
            .map(|row| {
                let stroke = super::parse_uuid(&row.try_get::<String, _>("stroke_id")?)?;
                let indices: Vec<u8> = row.try_get("indices")?;
                let data: Vec<u8> = row.try_get("data")?;
                let samples = decode_samples(row.try_get("layout")?, &data)
                    .with_context(|| format!("stroke {stroke}: simplified samples"))?;
                Ok((stroke, Simplified { indices: decode_indices(&indices), samples }))
            })
            .collect()
    }

    /// The size in bytes of a stroke's mesh (a duplicate's: its source's), without reading it.
    pub async fn mesh_bytes(&self, stroke: Uuid) -> anyhow::Result<Option<u64>> {
        let bytes: Option<i64> = sqlx::query_scalar(
            "SELECT CAST(length(glb) AS BIGINT) FROM meshes WHERE stroke_id = \
             COALESCE((SELECT mesh_of FROM strokes WHERE id = $1), $1)",
        )
        .bind(stroke.to_string())
        .fetch_optional(&self.pool)
        .await?;
        Ok(bytes.map(|b| b as u64))
    }

    /// The strokes not taken back that show `stroke`'s mesh row (its duplicates sharing it,
    /// `mesh_of`), with their drawers.
    pub async fn mesh_sharers(&self, stroke: Uuid) -> anyhow::Result<Vec<(Uuid, Uuid)>> {
        let rows = sqlx::query(
            "SELECT id, participant FROM strokes WHERE mesh_of = $1 AND removed_at IS NULL \
             ORDER BY id",
        )
        .bind(stroke.to_string())
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|row| {
                let id = super::parse_uuid(&row.try_get::<String, _>("id")?)?;
                Ok((id, super::parse_uuid(&row.try_get::<String, _>("participant")?)?))
            })
            .collect()
    }

    /// A stroke's mesh: a duplicate's is its source's (`mesh_of`), shared, never copied.
    pub async fn mesh(&self, stroke: Uuid) -> anyhow::Result<Option<MeshRow>> {
        let row = sqlx::query(
            "SELECT glb, vertices, triangles, uploader, created_at FROM meshes WHERE stroke_id = \
             COALESCE((SELECT mesh_of FROM strokes WHERE id = $1), $1)",
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
}

/// Where the stored samples of `stroke` end: `n_points` from its chunks, extended by its
/// entries in `log`.
pub(super) fn end_with_log(n_points: u64, stroke: Uuid, log: &log::StrokeEntries) -> u64 {
    let entries = log::pieces_of(log, stroke);
    let mut end = n_points;
    for (seq, n) in entries {
        if seq <= end {
            end = end.max(seq + n);
        }
    }
    end
}
