//! What a connection asks the writer to do ([`WriteOp`]) and how a request can fail
//! ([`WriteError`]).

use penmesh::protocol::{Removal, StrokeStatus};
use penmesh::{AcutsParams, Brush, Kept, Placement, Sample, Solid};
use uuid::Uuid;

use crate::store::MeshRow;

/// One change to the database.
#[derive(Debug, Clone)]
pub enum WriteOp {
    /// Creates a stroke (nothing if it exists already).
    BeginStroke {
        stroke: Uuid,
        session: Uuid,
        participant: Uuid,
        brush: Brush,
        params: AcutsParams,
        device: Option<String>,
    },
    /// Appends the samples `seq..seq + samples.len()` of a stroke.
    Append { stroke: Uuid, seq: u64, samples: Vec<Sample> },
    /// Stores the simplified stroke and marks it `done`.
    Finish { stroke: Uuid, kept: Vec<Kept> },
    /// Sets a stroke's status (`open` when resumed, `interrupted` when its connection ends).
    SetStatus { stroke: Uuid, status: StrokeStatus },
    /// A participant said hello in a session on `connection` (its presence row).
    /// `replica` is the key of the lock the replica holds while it lives (PostgreSQL).
    Join { connection: Uuid, participant: Uuid, session: Uuid, name: String, replica: Option<i64> },
    /// A participant's connection ended.
    Leave { connection: Uuid },
    /// A participant present in a session took another name (every presence row of it).
    Rename { participant: Uuid, session: Uuid, name: String },
    /// Stores (or replaces) a done stroke's mesh, a mesh of `solid`, unless the meshes of
    /// `session` would then hold more than `quota` bytes (refused: [`WriteError::Quota`]). A
    /// request of its own: it is written where it is planned, as only the write tells whether
    /// it fits. The duplicates that shared the replaced mesh and are another solid keep it
    /// (`writer/sharing.rs`).
    PutMesh { stroke: Uuid, session: Uuid, mesh: MeshRow, solid: Solid, quota: u64 },
    /// Keeps what ACUTS retains of a stroke's first `upto` samples before its end (`kept`), so
    /// that the next history of its session need not replay them (`Store::session_history`).
    /// Never replaces the simplified stroke of a stroke that is done.
    KeepRetained { stroke: Uuid, upto: u64, kept: Vec<Kept> },
    /// Takes a stroke back (`Some`: who and when; a stroke already taken back keeps its first
    /// mark) or brings it back (`None`). Nothing of the stroke is deleted.
    SetRemoved { stroke: Uuid, removed: Option<Removal> },
    /// A stroke's new placement, set by `by` at `at` (`cause`: `begin`, `set` or `duplicate`):
    /// a row of its own, never an overwrite (`stroke_placements`).
    Place { stroke: Uuid, placement: Placement, by: Uuid, at: i64, cause: &'static str },
    /// A stroke's new solid, set by `by` at `at` (`cause`: `begin`, `set`, `duplicate` or
    /// `import`): a row of its own, never an overwrite (`stroke_solids`). A duplicate given a
    /// solid of its own stops sharing its source's mesh (`mesh_of`): its own is built.
    SetSolid { stroke: Uuid, solid: Solid, by: Uuid, at: i64, cause: &'static str },
    /// Records that `stroke` is a duplicate of `source`. `shares: Some(solid)` (a duplicate
    /// made here, of that solid): it shows the mesh its source shows, shared, never copied;
    /// refused ([`WriteError::Refused`]) when the source is no longer `solid` (changed since it
    /// was read), as that mesh would not be the duplicate's solid. `None` (an import): it has
    /// its own mesh.
    MarkDuplicate { stroke: Uuid, source: Uuid, shares: Option<Solid> },
    /// Records where an imported stroke came from (`stroke_imports`), and the name its
    /// importer gave.
    MarkImported { stroke: Uuid, from: Box<penmesh::ImportedFrom>, importer_name: String },
    /// Claims `stroke` as a new id: the request is refused ([`WriteError::Taken`]) when a
    /// stroke of that id exists or an earlier request of the transaction creates one. Before
    /// the `BeginStroke` of a stroke the client named (a duplicate), so that of two requests
    /// naming the same new id exactly one is written.
    Claim { stroke: Uuid },
    /// Counts `samples` more stored samples toward `session`'s quota: the request is refused
    /// ([`WriteError::Quota`]) when the session's stored samples (and those counted by earlier
    /// requests of the transaction) would pass `quota`. Writes nothing.
    CountSamples { session: Uuid, samples: u64, quota: u64 },
    /// Copies the stored samples and the simplified stroke of the done stroke `source` into
    /// the new stroke `stroke` (begun in the same request) and marks it `done`: in the
    /// database, row by row as stored, never decoded in the proxy (a duplicate).
    CopySamples { stroke: Uuid, source: Uuid },
}

impl WriteOp {
    /// Bytes of samples the op holds while it waits for the writer.
    pub(super) fn sample_bytes(&self) -> usize {
        match self {
            WriteOp::Append { samples, .. } => std::mem::size_of_val(samples.as_slice()),
            WriteOp::Finish { kept, .. } | WriteOp::KeepRetained { kept, .. } => {
                std::mem::size_of_val(kept.as_slice())
            }
            _ => 0,
        }
    }

    /// Bytes of mesh the op writes.
    pub(super) fn mesh_bytes(&self) -> usize {
        match self {
            WriteOp::PutMesh { mesh, .. } => mesh.glb.len(),
            _ => 0,
        }
    }

    pub(super) fn n_samples(&self) -> usize {
        match self {
            WriteOp::Append { samples, .. } => samples.len(),
            _ => 0,
        }
    }

    /// Samples the op copies in the database (what [`WriteOp::CountSamples`] counts of a copy).
    pub(super) fn copied_samples(&self) -> u64 {
        match self {
            WriteOp::CountSamples { samples, .. } => *samples,
            _ => 0,
        }
    }
}

/// The writer failed to commit a request.
#[derive(Debug, Clone, thiserror::Error)]
pub enum WriteError {
    #[error("the writer has stopped")]
    Closed,
    /// The database failed; its own words, for the log.
    #[error("database write failed: {0}")]
    Database(String),
    /// The database could not write for want of space or a failing disk (its own words, for
    /// the log): the one database failure a client is told the cause of.
    #[error("the database cannot write to its disk: {0}")]
    Storage(String),
    /// The writer refused the request: storing it would break a stroke's stored samples (a
    /// hole, samples after its end, a stroke that does not exist). The message is the
    /// writer's own, fit for the client.
    #[error("{0}")]
    Refused(String),
    /// The write would pass a storage quota (the message names it); nothing was written.
    #[error("{0}")]
    Quota(String),
    /// A [`WriteOp::Claim`]ed stroke id is taken (the message names it); nothing was written.
    #[error("{0}")]
    Taken(String),
}
