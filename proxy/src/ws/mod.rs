//! The WebSocket connection: decoding, the per-connection protocol state, acks after commit,
//! and the wind-down when a connection ends.
//!
//! One file per job:
//! - `adapter.rs`: `GET /v1/sessions/{session}/ws` ([`ws_handler`]): authenticate, upgrade,
//!   and axum's WebSocket turned into a `Sink`/`Stream` of [`Frame`]s.
//! - `serve.rs`: [`serve`], the connection loop, written against a generic `Sink`/`Stream`
//!   of frames (so a test drives it with channels): decode, `Hello`, the heartbeat, the hello
//!   deadline, the idle timeout (which only work resets, not pings), the wind-down.
//! - `connection.rs`: one connection's state and what every part uses to answer (`send`,
//!   `fail`, how it ends).
//! - `outgoing.rs`: the outgoing queue (bounded in frames and bytes), its overflow of answers already owed, and the
//!   task that writes frames to the socket.
//! - `strokes.rs`: the stroke lifecycle: begin, points, end, resume, acks after commit.
//! - `peers.rs`: the session's events to this client, and the resync after a gap.
//! - `removals.rs`: a stroke taken back or brought back by its drawer (`crate::removal`).
//! - `solids.rs`: a stroke's solid set by its drawer (`crate::solid`, protocol 6).
//! - `error.rs`: [`ConnError`](error::ConnError), why a message was not carried out; every one
//!   is answered and logged in one place (`Connection::fail`).
//!
//! Protocol decisions (see also `docs/storage.md`):
//! - Every bad input is answered with `Error {code, message, stroke}` and the connection goes
//!   on. The connection is closed only for: a first message that is not `Hello` or a protocol
//!   version this proxy does not speak (close 1002), a message past the hard size limit (1009),
//!   a full session (1008), no `Hello` by the hello deadline (1008), the idle timeout (1000),
//!   shutdown (1001), a reader too slow for its outgoing queue (dropped without a close frame,
//!   since the queue is full), and a peer that answers nothing, not even the heartbeat's pings
//!   (dropped: it is gone).
//! - Answers go out in the form (binary or JSON) of the client's latest frame.
//! - `StrokeBegin` is acknowledged with `Ack {upto_seq}` once the stroke row is committed.
//! - Resume: a stroke named in `Hello.resume` (or begun again with `StrokeBegin`) that is
//!   `open` or `interrupted` is rebuilt by replaying its committed samples through a fresh
//!   simplifier. Every sample retained so far is then sent again as one `Retained {first: 0}`
//!   (split in batches), so a client that lost some in the drop has them all; `first` lets a
//!   client that kept them drop the repeat.
//! - The strokes a connection holds are let go however it ends, a panic included: the claims
//!   are held through a guard ([`crate::state::ConnectionClaims`]) that releases them on drop.
//!
//! Sessions (see [`crate::fanout`]): after `Welcome`, the connection joins its session's
//! fan-out **before** it reads the session's history from the database, sends the history,
//! then `Synced`, then the live events that queued meanwhile and after. Every peer event goes
//! through the connection's [`PeerView`](crate::fanout::PeerView) (per stroke: begun, how many
//! retained samples, done, mesh time), which drops what the client already has and trims
//! overlaps, so history and live events neither overlap nor leave a gap. Peer events leave a
//! quarter of the outgoing queue (frames and bytes) to the connection's own answers; when the socket is too slow,
//! events wait in the fan-out queue, and when that overflows the client gets `Error {lagged}`
//! and the same resync (only what it lacks; past 3 overflows a minute it is dropped instead).
//! Stroke events are published once committed (by the writer), in order.

mod adapter;
mod connection;
mod error;
mod hello;
mod outgoing;
mod peers;
mod placements;
mod removals;
mod serve;
mod solids;
mod strokes;
mod versions;

pub use adapter::{split, ws_handler};
pub use error::ReadError;
pub use outgoing::forward;
pub use serve::serve;

/// A WebSocket frame, independent of the WebSocket library.
#[derive(Debug, Clone, PartialEq)]
pub enum Frame {
    Text(String),
    Binary(Vec<u8>),
    Ping(Vec<u8>),
    Pong(Vec<u8>),
    Close(Option<(u16, String)>),
}

/// Close codes this proxy sends.
pub mod close_code {
    pub const NORMAL: u16 = 1000;
    pub const GOING_AWAY: u16 = 1001;
    pub const PROTOCOL: u16 = 1002;
    pub const POLICY: u16 = 1008;
    pub const TOO_BIG: u16 = 1009;
    /// The token does not open the session (a browser's WebSocket cannot see an HTTP 401).
    pub const UNAUTHORIZED: u16 = 4401;
}
