//! A session's meshes in one read, for `GET /v1/sessions/{session}/meshes`.

use penmesh::Placement;
use penmesh::protocol::{BundledMesh, PlacedMesh};
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

    /// [`Store::session_meshes`] with each stroke's current placement (the `PMB2` bundle).
    pub async fn session_placed_meshes(&self, session: Uuid) -> anyhow::Result<Vec<PlacedMesh>> {
        let rows = sqlx::query(
            "SELECT s.id AS stroke_id, s.participant, m.glb, (SELECT p.matrix FROM \
             stroke_placements p WHERE p.stroke_id = s.id ORDER BY p.id DESC LIMIT 1) AS matrix \
             FROM strokes s JOIN meshes m ON m.stroke_id = COALESCE(s.mesh_of, s.id) \
             WHERE s.session_id = $1 AND s.removed_at IS NULL ORDER BY s.created_at, s.id",
        )
        .bind(session.to_string())
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|row| {
                let placement = match row.try_get::<Option<Vec<u8>>, _>("matrix")? {
                    Some(bytes) => Placement::from_bytes(&bytes)?,
                    None => Placement::IDENTITY,
                };
                let mesh = BundledMesh {
                    stroke: parse_uuid(&row.try_get::<String, _>("stroke_id")?)?,
                    participant: parse_uuid(&row.try_get::<String, _>("participant")?)?,
                    glb: row.try_get("glb")?,
                };
                Ok(PlacedMesh { mesh, placement })
            })
            .collect()
    }
}
