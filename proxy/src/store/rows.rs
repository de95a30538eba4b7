//! The rows the store hands out (strokes, simplified strokes, meshes) and how a stroke's row is
//! read, older stored forms included.

use anyhow::Context;
use penmesh::Sample;
use penmesh::protocol::StrokeStatus;
use sqlx::Row;
use uuid::Uuid;

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
    /// Set while the stroke is taken back (`WriteOp::SetRemoved`): who and when.
    pub removed: Option<penmesh::protocol::Removal>,
    /// Its current placement (the latest of `stroke_placements`; the identity when none).
    pub placement: penmesh::Placement,
    /// That placement's row id (`None` when it has none): what orders it among the stroke's
    /// placement events (`EventKind::Placed::id`).
    pub placement_id: Option<i64>,
    /// The stroke it is a duplicate of, if any.
    pub duplicate_of: Option<Uuid>,
    /// What it becomes (the latest of `stroke_solids`; the rod when none).
    pub solid: penmesh::Solid,
}

/// The simplified stroke: indices into the raw samples and the samples themselves.
#[derive(Debug, Clone, PartialEq)]
pub struct Simplified {
    pub indices: Vec<u64>,
    pub samples: Vec<Sample>,
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

pub(super) fn parse_uuid(s: &str) -> anyhow::Result<Uuid> {
    Uuid::parse_str(s).with_context(|| format!("bad uuid {s:?} in the database"))
}

/// `n_points` is where the last stored chunk ends (a stroke's chunks are contiguous from 0): the
/// appends of the group commit write nothing but their chunk, so that a commit touches as few
/// pages as it can.
pub(super) const STROKE_SELECT: &str = "SELECT s.id, s.session_id, s.participant, s.brush, s.params, s.device, \
     s.status, s.n_retained, s.created_at, s.updated_at, s.removed_at, s.removed_by, \
     s.duplicate_of, (SELECT p.matrix FROM stroke_placements p WHERE p.stroke_id = s.id \
     ORDER BY p.id DESC LIMIT 1) AS placement, \
     (SELECT MAX(p.id) FROM stroke_placements p WHERE p.stroke_id = s.id) AS placement_id, \
     (SELECT q.solid FROM stroke_solids q WHERE q.stroke_id = s.id ORDER BY q.id DESC LIMIT 1) \
     AS solid, \
     COALESCE((SELECT c.seq + c.n FROM stroke_chunks c WHERE c.stroke_id = s.id \
     ORDER BY c.seq DESC LIMIT 1), 0) AS n_points, \
     (SELECT COUNT(*) FROM meshes m WHERE m.stroke_id = COALESCE(s.mesh_of, s.id)) AS n_meshes FROM strokes s";

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

pub(super) fn stroke_from_row(row: &sqlx::any::AnyRow) -> anyhow::Result<StrokeRow> {
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
        removed: match (
            row.try_get::<Option<i64>, _>("removed_at")?,
            row.try_get::<Option<String>, _>("removed_by")?,
        ) {
            (Some(at), Some(by)) => Some(penmesh::protocol::Removal { by: parse_uuid(&by)?, at }),
            _ => None,
        },
        placement: match row.try_get::<Option<Vec<u8>>, _>("placement")? {
            Some(bytes) => penmesh::Placement::from_bytes(&bytes).context("stored placement")?,
            None => penmesh::Placement::IDENTITY,
        },
        placement_id: row.try_get("placement_id")?,
        duplicate_of: row
            .try_get::<Option<String>, _>("duplicate_of")?
            .map(|id| parse_uuid(&id))
            .transpose()?,
        solid: match row.try_get::<Option<Vec<u8>>, _>("solid")? {
            Some(bytes) => penmesh::Solid::from_bytes(&bytes).context("stored solid")?,
            None => penmesh::Solid::ROD,
        },
    })
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
}
