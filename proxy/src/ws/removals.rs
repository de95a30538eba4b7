//! `RemoveStroke` and `RestoreStroke`: a stroke taken back or brought back by its drawer, under
//! the rule of [`crate::removal`]; answered with `StrokeRemoved` or `StrokeRestored` once the
//! mark is committed, in order with the connection's other answers.

use penmesh::protocol::{ErrorCode, ServerMessage, StrokeId, StrokeRef, StrokeRemoval};

use super::connection::{AfterCommit, Connection};
use super::error::ConnError;
use crate::removal;
use crate::store::StrokeRow;

impl Connection {
    /// Takes back (`remove`) or brings back the stroke of `request`.
    pub(super) async fn on_set_removed(
        &mut self,
        StrokeRef { stroke }: StrokeRef,
        remove: bool,
    ) -> Result<(), ConnError> {
        let row = self.stroke_of_session(stroke, "reading a stroke to take back").await?;
        removal::check(&row, self.participant)
            .map_err(|refused| ConnError::refused(refused.code, refused.message, Some(stroke)))?;
        let (op, event) = removal::request(&row, self.participant, remove, Some(self.id));
        let committed = self.state.writer.submit_with(vec![op], vec![event]).await;
        let removal = StrokeRemoval { participant: row.participant, stroke, by: self.participant };
        let answer = if remove {
            ServerMessage::StrokeRemoved(removal)
        } else {
            ServerMessage::StrokeRestored(removal)
        };
        self.pending.push(committed, AfterCommit::Answer { stroke, answer });
        Ok(())
    }

    /// The row of `stroke` when it is a stroke of this connection's session; `unknown_stroke`
    /// otherwise, `internal` (logged as `doing`) when it cannot be read. What a request about a
    /// finished stroke (take back, bring back, place) looks up first.
    pub(super) async fn stroke_of_session(
        &self,
        stroke: StrokeId,
        doing: &'static str,
    ) -> Result<StrokeRow, ConnError> {
        match self.state.store.stroke(stroke).await {
            Ok(Some(row)) if row.session_id == self.session => Ok(row),
            Ok(_) => Err(ConnError::refused(
                ErrorCode::UnknownStroke,
                format!("unknown stroke {stroke}: no such stroke in this session"),
                Some(stroke),
            )),
            Err(err) => Err(ConnError::internal(
                doing,
                err,
                "could not read the stroke; try again",
                Some(stroke),
            )),
        }
    }
}
