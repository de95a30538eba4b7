//! Protocol version 4, which the proxy still serves beside the current one (`docs/protocol.md`,
//! "Versions"). bincode is not self-describing, so a message whose layout changed in version 5
//! keeps its version-4 shape here, for the codec to read and write version-4 frames:
//!
//! - client to proxy: `StrokeBegin` had no `placement` (a version-4 stroke lies at the
//!   identity, the board); `SetPlacement` did not exist.
//! - proxy to client: every message of version 4 is laid out as in version 5 (`v5.rs`, which
//!   keeps `PeerStrokes` as both had it); version 5 only appended `PeerPlacement`, which a
//!   version-4 connection is never sent.

use serde::{Deserialize, Serialize};

use super::{
    ClientMessage, Hello, Ping, Points, Rename, ServerMessage, StrokeBegin, StrokeEnd, StrokeId,
    StrokeRef,
};
use crate::acuts::AcutsParams;
use crate::model::Brush;

/// The version this module describes.
pub(super) const VERSION: u16 = 4;

/// Messages a version-4 client sends, in their variant order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, strum::VariantNames)]
#[serde(rename_all = "snake_case")]
#[strum(serialize_all = "snake_case")]
pub(super) enum ClientMessageV4 {
    Hello(Hello),
    StrokeBegin(StrokeBeginV4),
    Points(Points),
    StrokeEnd(StrokeEnd),
    Ping(Ping),
    RemoveStroke(StrokeRef),
    RestoreStroke(StrokeRef),
    Rename(Rename),
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) struct StrokeBeginV4 {
    pub stroke: StrokeId,
    #[serde(default)]
    pub brush: Brush,
    #[serde(default)]
    pub device: Option<String>,
    #[serde(default)]
    pub params: Option<AcutsParams>,
}

/// Variants of [`ServerMessage`] a version-4 client knows: all but `PeerPlacement` and
/// `PeerSolid`.
pub(super) const N_SERVER_MESSAGES: usize = 17;

impl From<ClientMessageV4> for ClientMessage {
    fn from(msg: ClientMessageV4) -> ClientMessage {
        match msg {
            ClientMessageV4::Hello(m) => ClientMessage::Hello(m),
            ClientMessageV4::StrokeBegin(StrokeBeginV4 { stroke, brush, device, params }) => {
                ClientMessage::StrokeBegin(StrokeBegin {
                    stroke,
                    brush,
                    device,
                    params,
                    placement: None,
                    solid: None,
                })
            }
            ClientMessageV4::Points(m) => ClientMessage::Points(m),
            ClientMessageV4::StrokeEnd(m) => ClientMessage::StrokeEnd(m),
            ClientMessageV4::Ping(m) => ClientMessage::Ping(m),
            ClientMessageV4::RemoveStroke(m) => ClientMessage::RemoveStroke(m),
            ClientMessageV4::RestoreStroke(m) => ClientMessage::RestoreStroke(m),
            ClientMessageV4::Rename(m) => ClientMessage::Rename(m),
        }
    }
}

impl ClientMessageV4 {
    /// The message as a version-4 client sends it; `None` when version 4 cannot say it (a
    /// placement).
    pub(super) fn from_current(msg: &ClientMessage) -> Option<ClientMessageV4> {
        Some(match msg.clone() {
            ClientMessage::Hello(m) => ClientMessageV4::Hello(m),
            ClientMessage::StrokeBegin(StrokeBegin {
                stroke,
                brush,
                device,
                params,
                placement,
                solid,
            }) => {
                if placement.is_some_and(|p| !p.is_identity()) || solid.is_some_and(|s| !s.is_rod())
                {
                    return None;
                }
                ClientMessageV4::StrokeBegin(StrokeBeginV4 { stroke, brush, device, params })
            }
            ClientMessage::Points(m) => ClientMessageV4::Points(m),
            ClientMessage::StrokeEnd(m) => ClientMessageV4::StrokeEnd(m),
            ClientMessage::Ping(m) => ClientMessageV4::Ping(m),
            ClientMessage::RemoveStroke(m) => ClientMessageV4::RemoveStroke(m),
            ClientMessage::RestoreStroke(m) => ClientMessageV4::RestoreStroke(m),
            ClientMessage::Rename(m) => ClientMessageV4::Rename(m),
            ClientMessage::SetPlacement(_) | ClientMessage::SetSolid(_) => return None,
        })
    }
}

/// Whether a version-4 client can be sent `msg` (as it is: its layout did not change).
pub(super) fn server_message_exists(msg: &ServerMessage) -> bool {
    !matches!(msg, ServerMessage::PeerPlacement(_) | ServerMessage::PeerSolid(_))
}
