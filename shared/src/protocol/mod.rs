//! The wire protocol between client and proxy: the message enums of `docs/protocol.md`.
//!
//! One serde definition serves both encodings:
//! - **JSON text frames**: serde's externally tagged form with snake_case names, e.g.
//!   `{"points":{"stroke":"…","seq":0,"points":[[x,y,t,p],…]}}`.
//! - **Binary frames**: a version byte, then bincode 2 of the same enums (see [`codec`]); the
//!   samples of a `Points` batch are quantised and delta-encoded there ([`PointBatch`]).
//!
//! **Only this module knows the wire encoding.** Everything else passes typed messages.
//!
//! Authentication is outside the messages: the session's token as `Authorization: Bearer` on
//! the upgrade (never `?token=`: URLs reach logs), or, for a browser, which cannot set headers on a WebSocket and
//! must keep the token out of URLs, as the offered subprotocol `penmesh.token.TOKEN` next to
//! `penmesh`, which the proxy selects (`docs/web.md`). A client that cannot run LRPDP (the
//! browser) asks the proxy to build a done stroke's mesh: `POST /v1/strokes/{id}/mesh/build`,
//! announced with `PeerMesh` like an upload. Neither changes the binary layout.
//!
//! **What the proxy refuses** beyond the encoding: text a client sends (`Hello.client`,
//! `Hello.name`, `StrokeBegin.device`) holding a NUL byte or longer than its limit
//! ([`MAX_NAME_CHARS`] = 200 characters; the device's is the proxy's `--max-device-chars`, 200
//! by default), with `Error {malformed}` naming the field ([`check_text`]); a sample with a
//! non-finite value, a coordinate beyond ±[`crate::MAX_COORDINATE`] = 10⁶, pressure outside
//! [0, 1] or time going backwards, with `Error {bad_sample}` naming the sample
//! ([`crate::validate_sample`]). Nothing of a stroke is acknowledged before its `StrokeBegin`
//! is stored: batches sent after a begin that fails are refused with it.

mod codec;
mod http;
mod mesh_bundle;
mod v4;
mod v5;

use serde::{Deserialize, Serialize};
use uuid::Uuid;

use crate::acuts::AcutsParams;
use crate::model::{Brush, Sample};
use crate::placement::Placement;
use crate::solid::Solid;

pub use codec::{
    CodecError, MAX_BATCH_SAMPLES, MAX_FRAME_BYTES_DEFAULT, MAX_STEPS, OLDEST_PROTOCOL_VERSION,
    POSITION_STEP, PRESSURE_STEP, PROTOCOL_VERSION, TIME_STEP, decode_client, decode_client_json,
    decode_client_json_limited, decode_client_limited, decode_point_batch, decode_server,
    decode_server_json, encode_client, encode_client_json, encode_point_batch, encode_server,
    encode_server_json, quantize_sample,
};
pub use codec::{
    binary_frame_version, encode_client_as, encode_server_as, encode_server_json_as,
    is_supported_version, server_message_exists_in,
};
pub use http::{
    DuplicateRequest, Duplicated, ErrorBody, Imported, ImportedStroke, MeshInfo, NewSession,
    PlacementChange, PlacementHistory, Removal, SolidChange, SolidHistory, StrokeInfo, StrokeList,
    StrokeSamples,
};
pub use mesh_bundle::{
    BUNDLED_STROKE_BYTES, BundledMesh, BundledStroke, MESH_BUNDLE_CONTENT_TYPE, MESH_BUNDLE_MAGIC,
    MESH_BUNDLE_PLACED_MAGIC, MESH_BUNDLE_TABLE_MAGIC, MeshBundleError, MeshTableBundle,
    PlacedMesh, decode_mesh_bundle, decode_mesh_table_bundle, decode_placed_mesh_bundle,
    encode_mesh_bundle, encode_mesh_table_bundle, encode_placed_mesh_bundle, mesh_bundle_head,
    mesh_table_bundle_head, push_bundled_mesh, push_bundled_stroke, push_table_mesh,
};

/// Stroke ids are chosen by the client (UUID v4), so a resent stroke is recognised.
pub type StrokeId = Uuid;
/// A participant of a session: the person behind one or more WebSocket connections. The proxy
/// derives it from the session and the participant's key ([`Hello::key`]), so the same key is
/// the same participant on every connection and replica; without a key, a fresh one per
/// connection.
pub type ParticipantId = Uuid;

/// The HTTP header that carries a participant's key ([`Hello::key`]) on the calls only a
/// stroke's drawer may make: storing or building its mesh.
pub const KEY_HEADER: &str = "x-penmesh-key";
/// Fewest characters of a participant key: 32 hex digits are 128 bits.
pub const KEY_MIN_CHARS: usize = 32;
/// Most characters of a participant key.
pub const KEY_MAX_CHARS: usize = 128;

/// Most characters of `Hello.name` and `Hello.client`.
pub const MAX_NAME_CHARS: usize = 200;

/// Checks a text field a client sends, which the proxy stores or shows to others: at most
/// `max_chars` characters, and no NUL byte (PostgreSQL cannot store one in text). The error
/// says what is wrong, for the caller to prefix with the field's name.
pub fn check_text(text: &str, max_chars: usize) -> Result<(), String> {
    let n = text.chars().count();
    if n > max_chars {
        return Err(format!("is {n} characters, more than the limit of {max_chars}"));
    }
    if let Some(at) = text.chars().position(|c| c == '\0') {
        return Err(format!("holds a NUL byte (character {at}), which text may not hold"));
    }
    Ok(())
}

/// Checks the form of a participant key: [`KEY_MIN_CHARS`] to [`KEY_MAX_CHARS`] characters of
/// the base64url alphabet (`A-Z a-z 0-9 - _`, which holds lowercase hex). The error says what
/// is wrong, for the caller to prefix with the field's name.
pub fn check_participant_key(key: &str) -> Result<(), String> {
    let n = key.chars().count();
    if !(KEY_MIN_CHARS..=KEY_MAX_CHARS).contains(&n) {
        return Err(format!(
            "is {n} characters; a participant key has {KEY_MIN_CHARS} to {KEY_MAX_CHARS} \
             (at least 128 random bits, e.g. 32 hex digits)"
        ));
    }
    if let Some(c) = key.chars().find(|c| !(c.is_ascii_alphanumeric() || *c == '-' || *c == '_')) {
        return Err(format!(
            "holds {c:?}; a participant key is made of A-Z, a-z, 0-9, '-' and '_'"
        ));
    }
    Ok(())
}

/// A batch of samples. In JSON it is a plain array of `[x, y, t, p]`; in the binary encoding it
/// is quantised and delta-encoded (see the codec module), so decoded samples lie on the
/// quantisation grid ([`quantize_sample`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PointBatch(pub Vec<Sample>);

/// Client to proxy.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, strum::VariantNames)]
#[serde(rename_all = "snake_case")]
#[strum(serialize_all = "snake_case")]
pub enum ClientMessage {
    /// First message on a connection. `resume` lists strokes the client was drawing when its
    /// last connection dropped; the proxy answers with how far it has committed each.
    Hello(Hello),
    StrokeBegin(StrokeBegin),
    Points(Points),
    StrokeEnd(StrokeEnd),
    Ping(Ping),
    /// Takes back a done stroke of this participant's (undo, the eraser): answered with
    /// `StrokeRemoved` once the mark is stored, and told to every connection of the session.
    /// Idempotent. Only the stroke's drawer may (`not_owner`); a stroke not of this session is
    /// `unknown_stroke`; one still being drawn is `stroke_open`.
    RemoveStroke(StrokeRef),
    /// Brings a taken-back stroke back (redo): answered with `StrokeRestored`, the same rules.
    RestoreStroke(StrokeRef),
    /// The participant's new display name ([`check_text`], [`MAX_NAME_CHARS`]): the session's
    /// other connections hear `PeerRenamed`, and newcomers see it in their history.
    Rename(Rename),
    /// Version 5. Places a done stroke of this participant's anew (move, turn, scale, mirror;
    /// undo sends the previous placement back): answered with `PeerPlacement` once the change
    /// is stored, and told to every other connection of the session. Only the stroke's drawer
    /// may (`not_owner`); a stroke not of this session is `unknown_stroke`; one still being
    /// drawn is `stroke_open`. A matrix that is not a placement does not decode (`malformed`
    /// or `bad_json`, naming what is wrong).
    SetPlacement(SetPlacement),
    /// Version 6. Sets what a done stroke of this participant's becomes (its kind and depth;
    /// undo sends the previous solid back): answered with `PeerSolid` once the change is
    /// stored, and told to every other connection of the session; the stroke's mesh is then
    /// built anew where meshes are built (`POST /v1/strokes/{id}/mesh/build` for a client
    /// that cannot run LRPDP, an upload otherwise). Only the stroke's drawer may
    /// (`not_owner`); a stroke not of this session is `unknown_stroke`; one still being drawn
    /// is `stroke_open`; a `filled` solid of an open stroke is `bad_solid`. A solid that is not
    /// valid (a negative or huge depth, a `filled` with none) does not decode.
    SetSolid(SetSolid),
}

/// A stroke's new solid ([`ClientMessage::SetSolid`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SetSolid {
    pub stroke: StrokeId,
    pub solid: Solid,
}

impl ClientMessage {
    /// The protocol version that brought this message as it stands, and what to call it in a
    /// refusal: a field of a later version counts (a `stroke_begin` with a `placement` is a
    /// version-5 message). A connection of an older version is refused it with
    /// `unknown_message`, in one place (the proxy's `ws/serve.rs`, `Connection::speaks`). A new
    /// version adds its messages and fields here; everything else is of the oldest version
    /// served.
    pub fn introduced_in(&self) -> (u16, &'static str) {
        match self {
            ClientMessage::SetSolid(_) => (6, "set_solid"),
            ClientMessage::StrokeBegin(begin) if begin.solid.is_some() => (6, "stroke_begin.solid"),
            ClientMessage::SetPlacement(_) => (5, "set_placement"),
            ClientMessage::StrokeBegin(begin) if begin.placement.is_some() => {
                (5, "stroke_begin.placement")
            }
            _ => (OLDEST_PROTOCOL_VERSION, "this message"),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Rename {
    pub name: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Hello {
    pub protocol: u16,
    /// Free-form client name and version, for logs ([`check_text`], [`MAX_NAME_CHARS`]).
    pub client: String,
    /// Display name shown to the session's other participants ([`check_text`],
    /// [`MAX_NAME_CHARS`]).
    #[serde(default)]
    pub name: Option<String>,
    #[serde(default)]
    pub resume: Vec<StrokeId>,
    /// The participant's secret ([`check_participant_key`]: at least 128 random bits), made
    /// once by the client and sent on every connection: the proxy derives the participant id
    /// from it and the session, so a client that reconnects with the same key is the same
    /// participant and may resume its strokes, and only it may ([`KEY_HEADER`] for HTTP).
    /// Never stored or logged. Without one the connection gets a fresh identity: it can draw
    /// and watch, but not resume after a reconnect nor store a mesh.
    #[serde(default)]
    pub key: Option<String>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StrokeBegin {
    pub stroke: StrokeId,
    #[serde(default)]
    pub brush: Brush,
    /// Input device description, e.g. `"wacom ctl-671"` or `"synth:figure8"` ([`check_text`];
    /// the proxy's `--max-device-chars` is its limit).
    #[serde(default)]
    pub device: Option<String>,
    /// ACUTS stage 2 parameters; the proxy's defaults when absent.
    #[serde(default)]
    pub params: Option<AcutsParams>,
    /// Version 5: the placement of the work plane the stroke is drawn on; absent: the
    /// identity (the board). Not in a version-4 frame ([`OLDEST_PROTOCOL_VERSION`]).
    #[serde(default)]
    pub placement: Option<Placement>,
    /// Version 6: what the stroke becomes (e.g. drawn as a filled plate or a hole); absent:
    /// the rod. Not in a version-5 or version-4 frame.
    #[serde(default)]
    pub solid: Option<Solid>,
}

/// A stroke's new placement ([`ClientMessage::SetPlacement`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SetPlacement {
    pub stroke: StrokeId,
    pub placement: Placement,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Points {
    pub stroke: StrokeId,
    /// Index in the stroke of the first sample of this batch.
    pub seq: u64,
    pub points: PointBatch,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StrokeEnd {
    pub stroke: StrokeId,
    /// Total samples the client sent for this stroke; the proxy checks it has them all.
    pub n_points: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Ping {
    pub nonce: u64,
}

/// Proxy to client.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, strum::VariantNames)]
#[serde(rename_all = "snake_case")]
#[strum(serialize_all = "snake_case")]
pub enum ServerMessage {
    Welcome(Welcome),
    /// Every sample of `stroke` with `seq < upto_seq` is committed to the database: the client
    /// may forget them, and after a reconnect resumes from `upto_seq`.
    Ack(Ack),
    /// Simplified samples as soon as ACUTS decides them. `first` is the index of `points[0]` in
    /// the simplified stroke, so a receiver can spot a gap or a repeat.
    Retained(Retained),
    StrokeDone(StrokeDone),
    Pong(Ping),
    Error(ErrorMessage),
    PeerJoined(PeerJoined),
    PeerLeft(PeerLeft),
    PeerStrokeBegin(PeerStrokeBegin),
    PeerRetained(PeerRetained),
    PeerStrokeDone(PeerStrokeDone),
    PeerMesh(PeerMesh),
    /// The end of the session's history: every `Peer…` event before it (since `Welcome`, or
    /// since an `Error {lagged}`) came from storage, every one after it is live. History and
    /// live events never overlap or leave a gap.
    Synced(Synced),
    /// A stroke was taken back by its drawer (`RemoveStroke`, or `DELETE /v1/strokes/{id}`):
    /// hide it. Sent to every connection of the session, the drawer's own included. A late
    /// joiner's history leaves a removed stroke out.
    StrokeRemoved(StrokeRemoval),
    /// A taken-back stroke is back (`RestoreStroke`, or `POST /v1/strokes/{id}/restore`): show
    /// it again. A client that never had the stroke (it joined while the stroke was removed)
    /// gets the stroke's events instead, as in a history.
    StrokeRestored(StrokeRemoval),
    /// A participant present chose another display name (`Rename`).
    PeerRenamed(PeerJoined),
    /// Strokes of the session's history that the client lacks entirely, several in one
    /// message: each says what its `PeerStrokeBegin`, `PeerRetained {first: 0}`,
    /// `PeerStrokeDone` and `PeerMesh` would ([`PeerStrokes::messages`]). Only before `Synced`;
    /// a stroke the client has in part, and every live event, come one message each.
    PeerStrokes(PeerStrokes),
    /// Version 5. A stroke's placement: set by its drawer (`SetPlacement`, `PUT
    /// /v1/strokes/{id}/placement`), or, in a history and after a `PeerStrokeBegin` (or a
    /// `PeerStrokes`) of a stroke drawn on a work plane, its current one. Only for a stroke
    /// that is not at the identity or whose placement changed; a client applies it as the
    /// stroke's node transform. Never sent to a version-4 connection.
    PeerPlacement(PeerPlacement),
    /// Version 6. A stroke's solid: set by its drawer (`SetSolid`, `PUT
    /// /v1/strokes/{id}/solid`), or, after a `PeerStrokeBegin` of a stroke begun as one, its
    /// current one. Only for a stroke that is not the rod or whose solid changed. Never sent
    /// to a version-5 or version-4 connection.
    PeerSolid(PeerSolid),
}

/// A stroke's solid ([`ServerMessage::PeerSolid`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PeerSolid {
    /// The stroke's drawer (who set it).
    pub participant: ParticipantId,
    pub stroke: StrokeId,
    pub solid: Solid,
}

/// A stroke's placement ([`ServerMessage::PeerPlacement`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PeerPlacement {
    /// The stroke's drawer (who set it).
    pub participant: ParticipantId,
    pub stroke: StrokeId,
    pub placement: Placement,
}

/// The strokes of a [`ServerMessage::PeerStrokes`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PeerStrokes {
    pub strokes: Vec<HistoryStroke>,
}

/// One stroke of a session's history, whole.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HistoryStroke {
    pub participant: ParticipantId,
    pub stroke: StrokeId,
    pub brush: Brush,
    /// Every sample retained so far (of a done stroke: its simplified samples).
    pub points: PointBatch,
    pub done: bool,
    /// It has a mesh, at [`mesh_url`].
    pub mesh: bool,
    /// Version 6: its current placement (the identity when it was never placed).
    #[serde(default)]
    pub placement: Placement,
    /// Version 6: its current solid (the rod when it never had another).
    #[serde(default)]
    pub solid: Solid,
}

impl PeerStrokes {
    /// The messages this one stands for, in order: per stroke its begin, its placement and its
    /// solid (unless the identity and the rod), its retained samples (if any), and when done
    /// its end and (if any) its mesh.
    pub fn messages(&self) -> Vec<ServerMessage> {
        let mut out = Vec::with_capacity(4 * self.strokes.len());
        for s in &self.strokes {
            let (participant, stroke) = (s.participant, s.stroke);
            out.push(ServerMessage::PeerStrokeBegin(PeerStrokeBegin {
                participant,
                stroke,
                brush: s.brush,
            }));
            if !s.placement.is_identity() {
                let placement = s.placement;
                out.push(ServerMessage::PeerPlacement(PeerPlacement {
                    participant,
                    stroke,
                    placement,
                }));
            }
            if !s.solid.is_rod() {
                let solid = s.solid;
                out.push(ServerMessage::PeerSolid(PeerSolid { participant, stroke, solid }));
            }
            if !s.points.0.is_empty() {
                out.push(ServerMessage::PeerRetained(PeerRetained {
                    participant,
                    stroke,
                    first: 0,
                    points: s.points.clone(),
                }));
            }
            if s.done {
                out.push(ServerMessage::PeerStrokeDone(PeerStrokeDone {
                    participant,
                    stroke,
                    n_retained: s.points.0.len() as u64,
                    url: simplified_url(stroke),
                }));
                if s.mesh {
                    let url = mesh_url(stroke);
                    out.push(ServerMessage::PeerMesh(PeerMesh { participant, stroke, url }));
                }
            }
        }
        out
    }
}

/// Where a done stroke's simplified samples are: `/v1/strokes/{stroke}/simplified`.
pub fn simplified_url(stroke: StrokeId) -> String {
    format!("/v1/strokes/{stroke}/simplified")
}

/// Where a stroke's mesh is: `/v1/strokes/{stroke}/mesh`.
pub fn mesh_url(stroke: StrokeId) -> String {
    format!("/v1/strokes/{stroke}/mesh")
}

/// The stroke a `RemoveStroke` or `RestoreStroke` is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct StrokeRef {
    pub stroke: StrokeId,
}

/// A stroke taken back or brought back: `participant` drew it, `by` asked (its drawer).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct StrokeRemoval {
    pub participant: ParticipantId,
    pub stroke: StrokeId,
    pub by: ParticipantId,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Welcome {
    pub protocol: u16,
    pub session: Uuid,
    pub participant: ParticipantId,
    /// For each stroke named in `Hello.resume`: how far the proxy has it.
    #[serde(default)]
    pub resume: Vec<ResumeState>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResumeState {
    pub stroke: StrokeId,
    /// The next sample index the proxy expects (every earlier one is committed).
    pub next_seq: u64,
    /// `open` (resumable), `interrupted` (resumable), `done`, or `unknown` (never seen).
    pub status: StrokeStatus,
}

#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Serialize,
    Deserialize,
    strum::IntoStaticStr,
    strum::EnumString,
    utoipa::ToSchema,
)]
#[serde(rename_all = "snake_case")]
#[strum(serialize_all = "snake_case")]
pub enum StrokeStatus {
    Open,
    Done,
    Interrupted,
    Unknown,
}

impl StrokeStatus {
    /// The name on the wire and in the database (`open`, `done`, ...).
    pub fn as_str(self) -> &'static str {
        self.into()
    }

    pub fn parse(s: &str) -> Option<StrokeStatus> {
        s.parse().ok()
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Ack {
    pub stroke: StrokeId,
    pub upto_seq: u64,
}

/// Samples `first..first + points.len()` of the simplified stroke, decided by a batch: sent
/// once that batch is committed, just before its `Ack` (in the same write to the socket).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Retained {
    pub stroke: StrokeId,
    pub first: u64,
    pub points: PointBatch,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StrokeDone {
    pub stroke: StrokeId,
    pub n_retained: u64,
    /// Path of the simplified stroke on the proxy, e.g. `/v1/strokes/{id}/simplified`.
    pub url: String,
}

/// Machine-readable error codes; the message says the rest in words.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, strum::IntoStaticStr)]
#[serde(rename_all = "snake_case")]
#[strum(serialize_all = "snake_case")]
pub enum ErrorCode {
    /// A binary frame that does not decode, or a field the proxy cannot take: text with a NUL
    /// byte or longer than its limit, a participant key of the wrong form.
    Malformed,
    /// A text frame that is not valid JSON for any message.
    BadJson,
    /// Valid framing, but not a message this protocol knows.
    UnknownMessage,
    /// The first message was not `Hello`, or a `Hello` came twice, or versions differ.
    Protocol,
    /// A non-finite value, a coordinate beyond ±10⁶, pressure outside [0, 1], time going
    /// backwards.
    BadSample,
    BadBrush,
    /// ACUTS parameters out of range.
    BadParams,
    UnknownStroke,
    /// The stroke was begun by another participant of the session: only its drawer (the same
    /// `Hello.key`) may resume it or append to it.
    NotOwner,
    StrokeFinished,
    /// A `StrokeBegin` for a stroke id already in use by someone else.
    StrokeConflict,
    SeqGap,
    /// `StrokeEnd.n_points` differs from what was received.
    CountMismatch,
    FrameTooLarge,
    BatchTooLarge,
    StrokeTooLong,
    TooManyOpenStrokes,
    TooManyConnections,
    IdleTimeout,
    /// This connection fell too far behind the session's events; resync from history.
    Lagged,
    ShuttingDown,
    /// The proxy failed (storing, or reading a stroke). With the id of a stroke this client
    /// draws: resume it from the last ack. With another's (a stroke of the session's history
    /// that cannot be read): that stroke is missing, the others are sent.
    Internal,
    /// A `RemoveStroke` or `RestoreStroke` of a stroke still being drawn (open or interrupted):
    /// only a finished stroke can be taken back.
    StrokeOpen,
    /// Version 6: a `SetSolid` the stroke cannot take (a `filled` solid of an open stroke); the
    /// message says why (how far apart its ends are).
    BadSolid,
}

impl ErrorCode {
    /// The code's name on the wire (`bad_sample`, ...).
    pub fn as_str(self) -> &'static str {
        self.into()
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ErrorMessage {
    pub code: ErrorCode,
    pub message: String,
    /// The stroke the error is about, when there is one.
    #[serde(default)]
    pub stroke: Option<StrokeId>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PeerJoined {
    pub participant: ParticipantId,
    pub name: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PeerLeft {
    pub participant: ParticipantId,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PeerStrokeBegin {
    pub participant: ParticipantId,
    pub stroke: StrokeId,
    pub brush: Brush,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PeerRetained {
    pub participant: ParticipantId,
    pub stroke: StrokeId,
    pub first: u64,
    pub points: PointBatch,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PeerStrokeDone {
    pub participant: ParticipantId,
    pub stroke: StrokeId,
    pub n_retained: u64,
    pub url: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PeerMesh {
    pub participant: ParticipantId,
    pub stroke: StrokeId,
    pub url: String,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Synced {
    /// Strokes of other participants the client now knows of.
    pub n_strokes: u64,
}
