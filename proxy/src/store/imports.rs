//! What a scene export reads beside the strokes (issue 39): the names of a session's
//! participants and where its imported strokes came from (`stroke_imports`).

use std::collections::HashMap;

use penmesh::{Author, ImportedFrom};
use sqlx::Row;
use uuid::Uuid;

use super::{Store, parse_uuid};

/// Where an imported stroke came from, and the name its importer gave.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportRow {
    pub from: ImportedFrom,
    pub importer_name: String,
}

impl Store {
    /// The latest name each participant of `session` went by (its presence rows).
    pub async fn participant_names(&self, session: Uuid) -> anyhow::Result<HashMap<Uuid, String>> {
        let rows = sqlx::query(
            "SELECT participant, name FROM participants WHERE session_id = $1 ORDER BY joined_at",
        )
        .bind(session.to_string())
        .fetch_all(&self.pool)
        .await?;
        let mut names = HashMap::new();
        for row in rows {
            let participant: String = row.try_get("participant")?;
            // Rows from before participant ids were derived may hold no id.
            if let Ok(id) = Uuid::parse_str(&participant) {
                names.insert(id, row.try_get("name")?);
            }
        }
        Ok(names)
    }

    /// Where each imported stroke of `session` came from.
    pub async fn session_imports(&self, session: Uuid) -> anyhow::Result<HashMap<Uuid, ImportRow>> {
        let rows = sqlx::query(
            "SELECT i.stroke_id, i.source_stroke, i.author_id, i.author_name, i.drawn_at, \
             i.imported_at, i.importer_name FROM stroke_imports i \
             JOIN strokes s ON s.id = i.stroke_id WHERE s.session_id = $1",
        )
        .bind(session.to_string())
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|row| {
                let from = ImportedFrom {
                    stroke: parse_uuid(&row.try_get::<String, _>("source_stroke")?)?,
                    author: Author {
                        participant: parse_uuid(&row.try_get::<String, _>("author_id")?)?,
                        name: row.try_get("author_name")?,
                    },
                    drawn_at: row.try_get("drawn_at")?,
                    imported_at: row.try_get("imported_at")?,
                };
                let stroke = parse_uuid(&row.try_get::<String, _>("stroke_id")?)?;
                Ok((stroke, ImportRow { from, importer_name: row.try_get("importer_name")? }))
            })
            .collect()
    }

    /// Bytes of meshes the session's strokes hold now (what its quota counts).
    pub async fn session_mesh_bytes(&self, session: Uuid) -> anyhow::Result<u64> {
        let bytes: Option<i64> = sqlx::query_scalar(
            "SELECT CAST(SUM(length(m.glb)) AS BIGINT) FROM meshes m \
             JOIN strokes s ON s.id = m.stroke_id WHERE s.session_id = $1",
        )
        .bind(session.to_string())
        .fetch_one(&self.pool)
        .await?;
        Ok(bytes.unwrap_or(0).max(0) as u64)
    }
}
