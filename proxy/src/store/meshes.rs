//! A session's meshes in one read, for `GET /v1/sessions/{session}/meshes`.

use penmesh::protocol::BundledMesh;
use sqlx::Row;
use uuid::Uuid;

use super::{Store, parse_uuid};

impl Store {
    /// Every stored mesh of `session` with its stroke and drawer, in the order the strokes
    /// were begun (the order of the session's history).
    pub async fn session_meshes(&self, session: Uuid) -> anyhow::Result<Vec<BundledMesh>> {
        let rows = sqlx::query(
            "SELECT s.id AS stroke_id, s.participant, m.glb FROM strokes s \
             JOIN meshes m ON m.stroke_id = COALESCE(s.mesh_of, s.id) \
             WHERE s.session_id = $1 AND s.removed_at IS NULL ORDER BY s.created_at, s.id",
        )
        .bind(session.to_string())
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|row| {
                Ok(BundledMesh {
                    stroke: parse_uuid(&row.try_get::<String, _>("stroke_id")?)?,
                    participant: parse_uuid(&row.try_get::<String, _>("participant")?)?,
                    glb: row.try_get("glb")?,
                })
            })
            .collect()
    }
}
