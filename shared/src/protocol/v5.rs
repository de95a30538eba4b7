//! Protocol version 5, which the proxy still serves beside the current one (`docs/protocol.md`,
//! "Versions"). bincode is not self-describing, so a message whose layout changed in version 6
//! keeps its version-5 shape here, for the codec to read and write version-5 frames:
//!
//! - client to proxy: `StrokeBegin` had no `solid` (a version-5 stroke is the rod);
//!   `SetSolid` did not exist.
//! - proxy to client: `HistoryStroke` had no `placement` nor `solid` (a version-5 client
//!   learns a placement from `PeerPlacement` alone, and no solid); `PeerSolid` did not exist.
//!   Every other message is laid out as in version 6. Version 4's `PeerStrokes` is this one.

use serde::{Deserialize, Serialize};

use super::{
    ClientMessage, Hello, HistoryStroke, ParticipantId, PeerStrokes, Ping, PointBatch, Points,
    Rename, ServerMessage, SetPlacement, StrokeBegin, StrokeEnd, StrokeId, StrokeRef,
};
use crate::acuts::AcutsParams;
use crate::model::Brush;
use crate::placement::Placement;

/// The version this module describes.
pub(super) const VERSION: u16 = 5;

/// Messages a version-5 client sends, in their variant order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, strum::VariantNames)]
#[serde(rename_all = "snake_case")]
#[strum(serialize_all = "snake_case")]
pub(super) enum ClientMessageV5 {
    Hello(Hello),
    StrokeBegin(StrokeBeginV5),
    Points(Points),
    StrokeEnd(StrokeEnd),
    Ping(Ping),
    RemoveStroke(StrokeRef),
    RestoreStroke(StrokeRef),
    Rename(Rename),
    SetPlacement(SetPlacement),
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) struct StrokeBeginV5 {
    pub stroke: StrokeId,
    #[serde(default)]
    pub brush: Brush,
    #[serde(default)]
    pub device: Option<String>,
    #[serde(default)]
    pub params: Option<AcutsParams>,
    #[serde(default)]
    pub placement: Option<Placement>,
}

/// Variants of [`ServerMessage`] a version-5 client knows: all but `PeerSolid`.
pub(super) const N_SERVER_MESSAGES: usize = 18;

/// The variant index of `PeerStrokes` in every version (bincode's first varint of its frame).
pub(super) const PEER_STROKES_INDEX: u32 = 16;

/// `PeerStrokes` as versions 5 and 4 have it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) struct PeerStrokesV5 {
    pub strokes: Vec<HistoryStrokeV5>,
}

/// `HistoryStroke` as versions 5 and 4 have it: no placement, no solid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) struct HistoryStrokeV5 {
    pub participant: ParticipantId,
    pub stroke: StrokeId,
    pub brush: Brush,
    pub points: PointBatch,
    pub done: bool,
    pub mesh: bool,
}

impl From<&PeerStrokes> for PeerStrokesV5 {
    fn from(current: &PeerStrokes) -> PeerStrokesV5 {
        let strokes = current
            .strokes
            .iter()
            .map(|s| HistoryStrokeV5 {
                participant: s.participant,
                stroke: s.stroke,
                brush: s.brush,
                points: s.points.clone(),
                done: s.done,
                mesh: s.mesh,
            })
            .collect();
        PeerStrokesV5 { strokes }
    }
}

impl From<PeerStrokesV5> for PeerStrokes {
    fn from(old: PeerStrokesV5) -> PeerStrokes {
        let strokes = old
            .strokes
            .into_iter()
            .map(|s| HistoryStroke {
                participant: s.participant,
                stroke: s.stroke,
                brush: s.brush,
                points: s.points,
                done: s.done,
                mesh: s.mesh,
                placement: Placement::IDENTITY,
                solid: crate::solid::Solid::ROD,
            })
            .collect();
        PeerStrokes { strokes }
    }
}

/// A version-5 or version-4 JSON frame of the one message whose shape changed.
#[derive(Serialize)]
#[serde(rename_all = "snake_case")]
pub(super) enum OldServerJson {
    PeerStrokes(PeerStrokesV5),
}

impl From<ClientMessageV5> for ClientMessage {
    fn from(msg: ClientMessageV5) -> ClientMessage {
        match msg {
            ClientMessageV5::Hello(m) => ClientMessage::Hello(m),
            ClientMessageV5::StrokeBegin(StrokeBeginV5 {
                stroke,
                brush,
                device,
                params,
                placement,
            }) => ClientMessage::StrokeBegin(StrokeBegin {
                stroke,
                brush,
                device,
                params,
                placement,
                solid: None,
            }),
            ClientMessageV5::Points(m) => ClientMessage::Points(m),
            ClientMessageV5::StrokeEnd(m) => ClientMessage::StrokeEnd(m),
            ClientMessageV5::Ping(m) => ClientMessage::Ping(m),
            ClientMessageV5::RemoveStroke(m) => ClientMessage::RemoveStroke(m),
            ClientMessageV5::RestoreStroke(m) => ClientMessage::RestoreStroke(m),
            ClientMessageV5::Rename(m) => ClientMessage::Rename(m),
            ClientMessageV5::SetPlacement(m) => ClientMessage::SetPlacement(m),
        }
    }
}

impl ClientMessageV5 {
    /// The message as a version-5 client sends it; `None` when version 5 cannot say it (a
    /// solid).
    pub(super) fn from_current(msg: &ClientMessage) -> Option<ClientMessageV5> {
        Some(match msg.clone() {
            ClientMessage::Hello(m) => ClientMessageV5::Hello(m),
            ClientMessage::StrokeBegin(StrokeBegin {
                stroke,
                brush,
                device,
                params,
                placement,
                solid,
            }) => {
                if solid.is_some_and(|s| !s.is_rod()) {
                    return None;
                }
                ClientMessageV5::StrokeBegin(StrokeBeginV5 {
                    stroke,
                    brush,
                    device,
                    params,
                    placement,
                })
            }
            ClientMessage::Points(m) => ClientMessageV5::Points(m),
            ClientMessage::StrokeEnd(m) => ClientMessageV5::StrokeEnd(m),
            ClientMessage::Ping(m) => ClientMessageV5::Ping(m),
            ClientMessage::RemoveStroke(m) => ClientMessageV5::RemoveStroke(m),
            ClientMessage::RestoreStroke(m) => ClientMessageV5::RestoreStroke(m),
            ClientMessage::Rename(m) => ClientMessageV5::Rename(m),
            ClientMessage::SetPlacement(m) => ClientMessageV5::SetPlacement(m),
            ClientMessage::SetSolid(_) => return None,
        })
    }
}

/// Whether a version-5 client can be sent `msg` (`PeerStrokes` in its own shape).
pub(super) fn server_message_exists(msg: &ServerMessage) -> bool {
    !matches!(msg, ServerMessage::PeerSolid(_))
}
