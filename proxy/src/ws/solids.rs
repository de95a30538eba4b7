//! `SetSolid` (protocol version 6): what a done stroke becomes, set by its drawer under the
//! rule of [`crate::solid`]; answered with `PeerSolid` once the change is committed, in order
//! with the connection's other answers, then the stroke's mesh stored anew (`peer_mesh`). A
//! connection of an older version has no such message (`unknown_message`, refused where every
//! message's version is checked: `ClientMessage::introduced_in`, `Connection::speaks`).

use penmesh::protocol::{ErrorCode, PROTOCOL_VERSION, PeerSolid, SetSolid};

use super::connection::{AfterCommit, Connection};
use super::error::ConnError;
use crate::http::AppError;
use crate::mesh_build::built_glb;
use crate::store::StrokeRow;

/// The first protocol version with solids (and a `HistoryStroke` that carries its placement
/// and solid).
pub(super) const SOLIDS_VERSION: u16 = 6;
const _: () = assert!(SOLIDS_VERSION == PROTOCOL_VERSION);

impl Connection {
    /// Sets the solid of the stroke of `set`: checked, its mesh built (refused with
    /// `bad_solid` when the stroke cannot be that solid), then committed.
    pub(super) async fn on_set_solid(&mut self, set: SetSolid) -> Result<(), ConnError> {
        // Past the participant's rate of solid changes, the connection waits its turn.
        self.state.rates.solids.wait(&self.participant).await;
        let stroke = set.stroke;
        let row = self.stroke_of_session(stroke, "reading a stroke to set its solid").await?;
        crate::solid::check(&row, self.participant)
            .map_err(|refused| ConnError::refused(refused.code, refused.message, Some(stroke)))?;
        let glb = built_glb(&self.state, &row, set.solid).await.map_err(|err| match err {
            AppError::Conflict(why) => ConnError::refused(ErrorCode::BadSolid, why, Some(stroke)),
            err => ConnError::internal(
                "building a stroke's mesh as its new solid",
                err,
                "the solid was not set; try again",
                Some(stroke),
            ),
        })?;
        let (op, event) = crate::solid::request(
            (row.session_id, row.participant, stroke),
            set.solid,
            "set",
            Some(self.id),
        );
        let committed = self.state.writer.submit_with(vec![op], vec![event]).await;
        let answer = PeerSolid { participant: row.participant, stroke, solid: set.solid };
        self.pending.push(committed, AfterCommit::Solid { answer, row: Box::new(row), glb });
        Ok(())
    }

    /// After the commit: the answer, then the stroke's new mesh stored and announced, off the
    /// connection's loop.
    pub(super) fn answer_solid(&mut self, answer: PeerSolid, row: StrokeRow, glb: Vec<u8>) {
        let answer_solid = answer.solid;
        self.send(penmesh::protocol::ServerMessage::PeerSolid(answer));
        let state = self.state.clone();
        tokio::spawn(async move {
            if let Err(err) = crate::solid::store_solid_mesh(&state, &row, answer_solid, glb).await
            {
                tracing::warn!(stroke = %row.id, error = %err, "storing the mesh of a stroke's new solid");
            }
        });
    }
}
