//! A mesh shared by duplicates (`strokes.mesh_of`): who shows which `meshes` row when one is
//! replaced. A duplicate shares the row its source shows (never a copy) while it is the solid
//! that row is of; the one rule, applied where every mesh is stored ([`super::sql::put_mesh`]):
//!
//! - a stroke whose mesh is stored gets its own row (it stops sharing another's);
//! - the strokes sharing the replaced row that are the solid the new mesh is of follow it;
//! - the others keep the row they showed: it moves to one of them (the *keeper*, no bytes
//!   copied) and the rest point at the keeper. A stroke with a row of its own (stored while it
//!   shared, before this rule) shows that one instead.
//!
//! So a source's solid changed never changes what its duplicates show, whatever the number of
//! duplicates, and `mesh_of` always names a stroke that shows its own row.

use penmesh::Solid;
use sqlx::AnyConnection;
use uuid::Uuid;

/// `stroke`'s current solid in SQL (the latest of `stroke_solids`; none: the rod) for the
/// stroke `s` of the enclosing query, compared with a solid's stored form.
const SOLID_OF_S: &str = "COALESCE((SELECT q.solid FROM stroke_solids q WHERE q.stroke_id = s.id \
     ORDER BY q.id DESC LIMIT 1), $2) <> $3";

/// The current solid of `stroke` (the rod when it never had another).
pub(super) async fn current_solid(conn: &mut AnyConnection, stroke: Uuid) -> anyhow::Result<Solid> {
    let stored: Option<Vec<u8>> = sqlx::query_scalar(
        "SELECT solid FROM stroke_solids WHERE stroke_id = $1 ORDER BY id DESC LIMIT 1",
    )
    .bind(stroke.to_string())
    .fetch_optional(&mut *conn)
    .await?;
    Ok(match stored {
        Some(bytes) => Solid::from_bytes(&bytes)?,
        None => Solid::ROD,
    })
}

/// What [`leave_row`] did, for [`settle`] (or [`undo`] when the new mesh is refused).
pub(super) struct Left {
    /// The stroke the replaced row moved to, if any stroke keeps it.
    keeper: Option<Uuid>,
}

/// Before `stroke`'s row is replaced by a mesh of `solid`: moves the row to the keeper, the
/// first (by id) of the strokes sharing it that are another solid and have no row of their
/// own. Nothing moves when no stroke needs it (or `stroke` has no row).
pub(super) async fn leave_row(
    conn: &mut AnyConnection,
    stroke: Uuid,
    solid: Solid,
) -> anyhow::Result<Left> {
    let keeper: Option<String> = sqlx::query_scalar(&format!(
        "SELECT s.id FROM strokes s WHERE s.mesh_of = $1 AND {SOLID_OF_S} \
         AND EXISTS (SELECT 1 FROM meshes m WHERE m.stroke_id = $1) \
         AND NOT EXISTS (SELECT 1 FROM meshes m WHERE m.stroke_id = s.id) ORDER BY s.id LIMIT 1"
    ))
    .bind(stroke.to_string())
    .bind(Solid::ROD.to_bytes().to_vec())
    .bind(solid.to_bytes().to_vec())
    .fetch_optional(&mut *conn)
    .await?;
    let keeper = keeper.map(|id| Uuid::parse_str(&id)).transpose()?;
    if let Some(keeper) = keeper {
        move_row(conn, stroke, keeper).await?;
    }
    Ok(Left { keeper })
}

/// Once `stroke`'s new row (of `solid`) is stored: `stroke` shows its own row, and the strokes
/// that shared its old one and are another solid show the keeper's (or their own).
pub(super) async fn settle(
    conn: &mut AnyConnection,
    stroke: Uuid,
    solid: Solid,
    left: Left,
) -> anyhow::Result<()> {
    sqlx::query(&format!(
        "UPDATE strokes SET mesh_of = CASE WHEN EXISTS (SELECT 1 FROM meshes m \
         WHERE m.stroke_id = strokes.id) THEN NULL ELSE $4 END \
         WHERE mesh_of = $1 AND id IN (SELECT s.id FROM strokes s WHERE s.mesh_of = $1 \
         AND {SOLID_OF_S})"
    ))
    .bind(stroke.to_string())
    .bind(Solid::ROD.to_bytes().to_vec())
    .bind(solid.to_bytes().to_vec())
    .bind(left.keeper.map(|k| k.to_string()))
    .execute(&mut *conn)
    .await?;
    sqlx::query("UPDATE strokes SET mesh_of = NULL WHERE id = $1 AND mesh_of IS NOT NULL")
        .bind(stroke.to_string())
        .execute(&mut *conn)
        .await?;
    Ok(())
}

/// The new mesh was refused (its session's quota): the replaced row goes back to `stroke`.
pub(super) async fn undo(conn: &mut AnyConnection, stroke: Uuid, left: Left) -> anyhow::Result<()> {
    if let Some(keeper) = left.keeper {
        move_row(conn, keeper, stroke).await?;
    }
    Ok(())
}

async fn move_row(conn: &mut AnyConnection, from: Uuid, to: Uuid) -> anyhow::Result<()> {
    sqlx::query("UPDATE meshes SET stroke_id = $1 WHERE stroke_id = $2")
        .bind(to.to_string())
        .bind(from.to_string())
        .execute(&mut *conn)
        .await?;
    Ok(())
}
