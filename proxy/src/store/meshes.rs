//! A session's meshes for `GET /v1/sessions/{session}/meshes`: what is in the bundle, read
//! without the meshes (enough for its ETag and its size), then the meshes a few at a time.

use std::collections::HashMap;

use penmesh::protocol::{ParticipantId, StrokeId};
use penmesh::{Placement, Solid};
use sqlx::Row;
use uuid::Uuid;

use super::{Store, parse_uuid};

/// One mesh of a session's bundle, without its bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct BundleEntry {
    pub stroke: StrokeId,
    pub participant: ParticipantId,
    /// The stroke whose mesh it shows: its own, or for a duplicate its source's (a mesh is
    /// shared, never copied).
    pub mesh_stroke: StrokeId,
    /// The stroke's current placement.
    pub placement: Placement,
    /// The stroke's current solid (the rod when it has none stored).
    pub solid: Solid,
    /// The GLB's size in bytes.
    pub bytes: u64,
    /// When the mesh was stored (ms): a replacement has a later one.
    pub created_at: i64,
    pub vertices: i64,
    pub triangles: i64,
}

impl Store {
    /// What the bundle of `session` holds: every stored mesh of a stroke not taken back, with
    /// its stroke and drawer, in the order the strokes were begun (the order of the session's
    /// history). No mesh is read: `length` of a blob is its size in both SQLite and
    /// PostgreSQL, read from the row's header (SQLite) or the TOAST pointer (PostgreSQL).
    pub async fn session_bundle_entries(&self, session: Uuid) -> anyhow::Result<Vec<BundleEntry>> {
        // Sorted here, not by `ORDER BY`: SQLite's sorter loads the blob that `length` needs
        // only the size of (44 ms instead of 0.06 for 52 MB of meshes).
        let rows = sqlx::query(
            "SELECT s.id AS stroke_id, s.participant, s.created_at AS begun, \
             m.stroke_id AS mesh_stroke, CAST(length(m.glb) AS BIGINT) AS bytes, m.created_at, \
             m.vertices, m.triangles, (SELECT p.matrix FROM stroke_placements p \
             WHERE p.stroke_id = s.id ORDER BY p.id DESC LIMIT 1) AS matrix, \
             (SELECT q.solid FROM stroke_solids q WHERE q.stroke_id = s.id \
             ORDER BY q.id DESC LIMIT 1) AS solid \
             FROM strokes s JOIN meshes m ON m.stroke_id = COALESCE(s.mesh_of, s.id) \
             WHERE s.session_id = $1 AND s.removed_at IS NULL",
        )
        .bind(session.to_string())
        .fetch_all(&self.pool)
        .await?;
        let mut entries = rows
            .iter()
            .map(|row| {
                let begun: i64 = row.try_get("begun")?;
                let placement = match row.try_get::<Option<Vec<u8>>, _>("matrix")? {
                    Some(bytes) => Placement::from_bytes(&bytes)?,
                    None => Placement::IDENTITY,
                };
                let solid = match row.try_get::<Option<Vec<u8>>, _>("solid")? {
                    Some(bytes) => Solid::from_bytes(&bytes)?,
                    None => Solid::ROD,
                };
                let entry = BundleEntry {
                    stroke: parse_uuid(&row.try_get::<String, _>("stroke_id")?)?,
                    participant: parse_uuid(&row.try_get::<String, _>("participant")?)?,
                    mesh_stroke: parse_uuid(&row.try_get::<String, _>("mesh_stroke")?)?,
                    placement,
                    solid,
                    bytes: row.try_get::<i64, _>("bytes")? as u64,
                    created_at: row.try_get("created_at")?,
                    vertices: row.try_get("vertices")?,
                    triangles: row.try_get("triangles")?,
                };
                Ok((begun, entry))
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        // The history's order: when begun, then the id (a UUID orders as its text).
        entries.sort_by_key(|(begun, e)| (*begun, e.stroke));
        Ok(entries.into_iter().map(|(_, e)| e).collect())
    }

    /// The GLBs of `strokes`, in one query (a few at a time: the caller bounds their bytes).
    pub async fn mesh_glbs(
        &self,
        strokes: &[StrokeId],
    ) -> anyhow::Result<HashMap<StrokeId, Vec<u8>>> {
        if strokes.is_empty() {
            return Ok(HashMap::new());
        }
        let places: Vec<String> = (1..=strokes.len()).map(|i| format!("${i}")).collect();
        let sql =
            format!("SELECT stroke_id, glb FROM meshes WHERE stroke_id IN ({})", places.join(", "));
        let mut query = sqlx::query(&sql);
        for stroke in strokes {
            query = query.bind(stroke.to_string());
        }
        let rows = query.fetch_all(&self.pool).await?;
        rows.iter()
            .map(|row| {
                Ok((parse_uuid(&row.try_get::<String, _>("stroke_id")?)?, row.try_get("glb")?))
            })
            .collect()
    }
}
