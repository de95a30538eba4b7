//! The database layer: one set of queries for SQLite and PostgreSQL through sqlx's `Any`
//! driver, the embedded migrations, and the group-commit [`writer`].
//!
//! **Only this module knows how samples are laid out in the database** (`encode_samples`, and
//! the append log's records, [`log`]). A stroke's samples are in `stroke_chunks` and, while it is
//! drawn, in `stroke_log`: every reader of raw samples reads both.
//!
//! One file per job: `connect.rs` (the pool, the SQLite settings, the migrations: [`Store`]),
//! `rows.rs` (the rows handed out), `blob.rs` (the sample blob layouts), `sessions.rs`,
//! `reads.rs` (strokes, simplified strokes, meshes), `imports.rs` (participants' names and
//! imported strokes' origins, for a scene export), `raw.rs` (a stroke's raw samples, chunks
//! and log together), `replay.rs`, `history.rs` (a session's history), `recover.rs` (the log a
//! stopped process left behind), `notify.rs` (events as PostgreSQL notifications),
//! `checkpoint.rs` (SQLite's checkpointer), `log.rs` (the append log) and `writer/` (the group
//! commit).

mod blob;
mod checkpoint;
mod connect;
mod history;
mod imports;
pub(crate) mod log;
mod meshes;
mod notify;
mod raw;
mod reads;
mod recover;
mod replay;
mod rows;
mod sessions;
mod writer;

use blob::decode_indices;
pub use blob::decode_samples;
pub(crate) use blob::{encode_indices, encode_samples};
pub use checkpoint::start_checkpointer;
pub use connect::{Backend, Store};
pub use imports::ImportRow;
pub use meshes::BundleEntry;
pub use notify::EVENTS_CHANNEL;
pub(crate) use notify::notify;
#[cfg(feature = "fault-injection")]
pub use raw::stored_pieces;
pub(crate) use raw::{CHUNKS_SELECT, pieces_from_chunks};
pub use raw::{RawPiece, RawSamples};
use reads::end_with_log;
pub(crate) use recover::move_log_tail;
pub use replay::LONG_STROKE_SAMPLES;
pub use rows::{MeshRow, Simplified, StrokeRow, now_ms};
use rows::{STROKE_SELECT, parse_uuid, stroke_from_row};
pub use sessions::hash_token;
#[cfg(feature = "fault-injection")]
pub use writer::{CommitFaults, Fault};
pub use writer::{
    Committed, InjectedFaults, PlacementIds, WriteError, WriteOp, Writer, WriterTask,
};
