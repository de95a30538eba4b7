//! `SetPlacement` (protocol version 5): a stroke placed anew by its drawer, under the rule of
//! [`crate::placement`]; answered with `PeerPlacement` once the change is committed, in order
//! with the connection's other answers. Also what a version-4 connection is sent of the
//! session's events: the same frames, with its version byte, and no placements.

use penmesh::protocol::{
    PeerPlacement, ServerMessage, SetPlacement, encode_server_as, encode_server_json_as,
};

use super::Frame;
use super::connection::{AfterCommit, Connection};
use super::error::ConnError;
use super::outgoing::Form;
use crate::fanout::Published;
use crate::placement;

impl Connection {
    /// Places the stroke of `set` anew.
    pub(super) async fn on_set_placement(&mut self, set: SetPlacement) -> Result<(), ConnError> {
        // Past the participant's rate of moves, the connection waits its turn (`crate::rate`).
        self.state.rates.moves.wait(&self.participant).await;
        let stroke = set.stroke;
        let row = self.stroke_of_session(stroke, "reading a stroke to place").await?;
        placement::check(&row, self.participant)
            .map_err(|refused| ConnError::refused(refused.code, refused.message, Some(stroke)))?;
        let (op, event) = placement::request(
            (row.session_id, row.participant, stroke),
            set.placement,
            "set",
            Some(self.id),
        );
        let committed = self.state.writer.submit_with(vec![op], vec![event]).await;
        let answer =
            PeerPlacement { participant: row.participant, stroke, placement: set.placement };
        self.pending.push(committed, AfterCommit::Placed { answer });
        Ok(())
    }

    /// The answer to the client's own placement `id`, in order with the stroke's other
    /// placements: those committed before it that the client does not hold yet (their events
    /// can be behind the answer: queued, or another replica's notification still on its way)
    /// are read and told first, and each is told once (the view then skips their events); so
    /// is the stroke itself, if the client lacks it. A
    /// client that holds a newer placement already (set elsewhere at the same moment, and
    /// committed after) is not told this older one.
    pub(super) async fn answer_placement(&mut self, id: i64, answer: PeerPlacement) {
        let stroke = answer.stroke;
        // A stroke the client was not told of yet (made over HTTP, its events still on their
        // way): sent whole first, with its current placement, as a history sends it.
        if !self.own.contains(&stroke) && !self.view.has_stroke(&stroke) {
            self.send_whole_stroke(stroke).await;
        }
        let held = self.view.placement_held(&stroke);
        if id <= held {
            return;
        }
        match self.state.store.placements_between(stroke, held, id).await {
            Ok(earlier) => {
                for (earlier_id, placement) in earlier {
                    if self.view.tell_placement(stroke, earlier_id) {
                        let participant = answer.participant;
                        let told = PeerPlacement { participant, stroke, placement };
                        self.send(ServerMessage::PeerPlacement(told));
                    }
                }
            }
            // Its answer all the same: the client misses the placements in between, not the
            // current one.
            Err(err) => {
                tracing::warn!(connection = self.id, %stroke, error = %err, "reading the placements before an answer");
            }
        }
        self.view.tell_placement(stroke, id);
        self.send(ServerMessage::PeerPlacement(answer));
    }

    /// The frame of a published event for this connection: encoded once for the session in
    /// the current version; for a version-4 connection its frame again with its version byte
    /// (the layout is the same), or none for a message version 4 lacks (`PeerPlacement`).
    pub(super) fn published_frame(&self, published: &Published) -> Option<Frame> {
        if self.outgoing.version == penmesh::protocol::PROTOCOL_VERSION {
            return Some(match self.outgoing.form {
                Form::Binary => Frame::Binary(published.binary().to_vec()),
                Form::Json => Frame::Text(published.json().to_string()),
            });
        }
        let msg = published.event.message();
        match self.outgoing.form {
            Form::Binary => encode_server_as(&msg, self.outgoing.version).map(Frame::Binary),
            Form::Json => encode_server_json_as(&msg, self.outgoing.version).map(Frame::Text),
        }
    }
}
