//! The body of a mesh bundle (`session_meshes.rs`), streamed: planned from what the bundle
//! holds ([`BundleEntry`], no mesh read) as pieces of about [`PIECE_BYTES`], then each piece's
//! meshes read and written as it is sent, gzipped piece by piece when asked. A request holds a
//! piece, never the whole bundle; in `PMB3` each stored mesh is read and sent once, however
//! many strokes show it (`penmesh::protocol::MeshTableBundle`).

use std::collections::HashMap;
use std::collections::VecDeque;
use std::io::Write;

use axum::body::{Body, Bytes};
use flate2::write::GzEncoder;
use penmesh::protocol::{
    BUNDLED_STROKE_BYTES, BundledStroke, StrokeId, mesh_bundle_head, mesh_table_bundle_head,
    push_bundled_mesh, push_bundled_stroke, push_table_mesh,
};
use tokio::sync::OwnedSemaphorePermit;

use crate::state::AppState;
use crate::store::BundleEntry;

/// Meshes read from storage at once for a bundle: about this many bytes (a larger mesh alone).
pub const PIECE_BYTES: u64 = 1 << 20;

/// A bundle's layout (`docs/protocol.md`, "The HTTP side"; `shared/src/protocol/mesh_bundle.rs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, utoipa::ToSchema)]
pub enum Layout {
    /// Per stroke its ids and its mesh.
    #[serde(rename = "PMB1")]
    Pmb1,
    /// `PMB1` with each stroke's placement.
    #[serde(rename = "PMB2")]
    Pmb2,
    /// Each distinct mesh once, then per stroke its ids, placement, solid and mesh's index.
    #[serde(rename = "PMB3")]
    Pmb3,
}

impl Layout {
    /// Its magic, the name a query gives it.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Pmb1 => "PMB1",
            Layout::Pmb2 => "PMB2",
            Layout::Pmb3 => "PMB3",
        }
    }
}

/// One piece of a bundle's body, about [`PIECE_BYTES`] (a larger mesh alone).
#[derive(Debug, PartialEq)]
enum Piece {
    /// `PMB1`, `PMB2` (`placed`): strokes, each with its mesh (a shared one again for each).
    Listed { entries: Vec<BundleEntry>, placed: bool },
    /// `PMB3`: meshes of the table, each by the stroke that stores it.
    Meshes(Vec<StrokeId>),
    /// `PMB3`: stroke entries, no mesh read.
    Strokes(Vec<BundledStroke>),
}

/// A bundle's body before any mesh is read: its head and its pieces.
#[derive(Debug, PartialEq)]
pub struct Plan {
    head: Vec<u8>,
    pieces: VecDeque<Piece>,
    /// Its size in bytes, at the meshes' sizes when their entries were read: what its
    /// large-body permit counts.
    pub bytes: u64,
}

/// The body of the bundle of `entries` (in the history's order) in `layout`.
pub fn plan(entries: Vec<BundleEntry>, layout: Layout) -> Plan {
    let mut pieces = VecDeque::new();
    if layout != Layout::Pmb3 {
        let placed = layout == Layout::Pmb2;
        let head = mesh_bundle_head(entries.len(), placed).to_vec();
        let per_stroke = if placed { 164 } else { 36 };
        let bytes = 8 + entries.iter().map(|e| per_stroke + e.bytes).sum::<u64>();
        let mut entries = entries.into_iter().peekable();
        while entries.peek().is_some() {
            let mut group = Vec::new();
            let mut size = 0;
            while size < PIECE_BYTES
                && let Some(entry) = entries.next()
            {
                size += entry.bytes;
                group.push(entry);
            }
            pieces.push_back(Piece::Listed { entries: group, placed });
        }
        return Plan { head, pieces, bytes };
    }
    // The table: each mesh once, in the order of the first stroke showing it.
    let mut index = HashMap::new();
    let mut meshes: Vec<(StrokeId, u64)> = Vec::new();
    let strokes: Vec<BundledStroke> = entries
        .into_iter()
        .map(|e| {
            let next = meshes.len() as u32;
            let mesh = *index.entry(e.mesh_stroke).or_insert_with(|| {
                meshes.push((e.mesh_stroke, e.bytes));
                next
            });
            BundledStroke {
                stroke: e.stroke,
                participant: e.participant,
                placement: e.placement,
                solid: e.solid,
                mesh,
            }
        })
        .collect();
    let head = mesh_table_bundle_head(meshes.len(), strokes.len()).to_vec();
    let bytes = 12
        + meshes.iter().map(|(_, bytes)| 4 + bytes).sum::<u64>()
        + (strokes.len() * BUNDLED_STROKE_BYTES) as u64;
    let mut group = Vec::new();
    let mut size = 0;
    for (stroke, bytes) in meshes {
        group.push(stroke);
        size += bytes;
        if size >= PIECE_BYTES {
            pieces.push_back(Piece::Meshes(std::mem::take(&mut group)));
            size = 0;
        }
    }
    if !group.is_empty() {
        pieces.push_back(Piece::Meshes(group));
    }
    let per_piece = PIECE_BYTES as usize / BUNDLED_STROKE_BYTES;
    for chunk in strokes.chunks(per_piece) {
        pieces.push_back(Piece::Strokes(chunk.to_vec()));
    }
    Plan { head, pieces, bytes }
}

/// The bundle `plan`, streamed: its head, then its pieces, each piece's meshes read as it goes (each at its size as read, should it have been replaced since the
/// entries were read), gzipped on the blocking pool when `gzip`. `permit` is held until the
/// last piece is taken. A mesh that cannot be read ends the body with an error: the client sees
/// a broken body, never a short one.
pub fn bundle_body(
    state: AppState,
    plan: Plan,
    gzip: bool,
    permit: Option<OwnedSemaphorePermit>,
) -> Body {
    struct Sending {
        state: AppState,
        plan: Plan,
        gzip: Option<GzEncoder<Vec<u8>>>,
        done: bool,
        _permit: Option<OwnedSemaphorePermit>,
    }
    let start = Sending {
        plan,
        state,
        gzip: gzip.then(|| GzEncoder::new(Vec::new(), flate2::Compression::fast())),
        done: false,
        _permit: permit,
    };
    let pieces = futures_util::stream::try_unfold(start, |mut sending| async move {
        if sending.done {
            return Ok::<_, std::io::Error>(None);
        }
        let mut out = std::mem::take(&mut sending.plan.head);
        if let Some(piece) = sending.plan.pieces.pop_front() {
            write_piece(&sending.state, piece, &mut out).await?;
        }
        let last = sending.plan.pieces.is_empty();
        sending.done = last;
        let Some(mut encoder) = sending.gzip.take() else {
            return Ok(Some((Bytes::from(out), sending)));
        };
        // The fastest level: most of what gzip saves here, for a fraction of the default's time.
        let (encoder, out) = tokio::task::spawn_blocking(move || {
            encoder.write_all(&out)?;
            if last {
                return Ok::<_, std::io::Error>((None, encoder.finish()?));
            }
            let out = std::mem::take(encoder.get_mut());
            Ok((Some(encoder), out))
        })
        .await
        .map_err(std::io::Error::other)??;
        sending.gzip = encoder;
        Ok(Some((Bytes::from(out), sending)))
    });
    Body::from_stream(pieces)
}

/// Appends `piece` to `out`, reading its meshes (each stored mesh once per piece).
async fn write_piece(state: &AppState, piece: Piece, out: &mut Vec<u8>) -> std::io::Result<()> {
    let read = |strokes: Vec<StrokeId>| async move {
        state.store.mesh_glbs(&strokes).await.map_err(|err| {
            tracing::error!(error = %err, "reading the meshes of a bundle");
            std::io::Error::other("the session's meshes cannot be read")
        })
    };
    let gone =
        |stroke: StrokeId| std::io::Error::other(format!("the mesh of stroke {stroke} is gone"));
    match piece {
        Piece::Listed { entries, placed } => {
            let mut strokes: Vec<_> = entries.iter().map(|e| e.mesh_stroke).collect();
            strokes.sort_unstable();
            strokes.dedup();
            let glbs = read(strokes).await?;
            for entry in &entries {
                let glb = glbs.get(&entry.mesh_stroke).ok_or_else(|| gone(entry.stroke))?;
                let placement = placed.then_some(&entry.placement);
                push_bundled_mesh(out, entry.stroke, entry.participant, placement, glb);
            }
        }
        Piece::Meshes(strokes) => {
            let glbs = read(strokes.clone()).await?;
            for stroke in strokes {
                push_table_mesh(out, glbs.get(&stroke).ok_or_else(|| gone(stroke))?);
            }
        }
        Piece::Strokes(strokes) => {
            for stroke in &strokes {
                push_bundled_stroke(out, stroke);
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use penmesh::{Placement, Solid, SolidKind};
    use uuid::Uuid;

    use super::*;

    fn entry(n: u8, mesh_of: u8, bytes: u64) -> BundleEntry {
        BundleEntry {
            stroke: Uuid::from_bytes([n; 16]),
            participant: Uuid::from_bytes([9; 16]),
            mesh_stroke: Uuid::from_bytes([mesh_of; 16]),
            placement: Placement::IDENTITY,
            solid: if n == 5 {
                Solid::new(SolidKind::Hole, Some(4.0)).unwrap()
            } else {
                Solid::ROD
            },
            bytes,
            created_at: 0,
            vertices: 3,
            triangles: 1,
        }
    }

    /// A 2 MiB mesh shown by its stroke (1) and three duplicates (2, 3, 4), and a hole (5)
    /// with a small mesh of its own.
    fn session() -> Vec<BundleEntry> {
        let big = 2 << 20;
        vec![
            entry(1, 1, big),
            entry(2, 1, big),
            entry(3, 1, big),
            entry(4, 1, big),
            entry(5, 5, 10),
        ]
    }

    #[test]
    fn a_table_bundle_plans_each_mesh_once_and_counts_its_bytes() {
        let plan = plan(session(), Layout::Pmb3);
        assert_eq!(plan.head, mesh_table_bundle_head(2, 5));
        assert_eq!(plan.bytes, 12 + (4 + (2 << 20)) + (4 + 10) + 5 * BUNDLED_STROKE_BYTES as u64);
        let pieces: Vec<_> = plan.pieces.into_iter().collect();
        assert_eq!(pieces.len(), 3, "{pieces:?}");
        assert_eq!(pieces[0], Piece::Meshes(vec![Uuid::from_bytes([1; 16])]));
        assert_eq!(pieces[1], Piece::Meshes(vec![Uuid::from_bytes([5; 16])]));
        let Piece::Strokes(strokes) = &pieces[2] else { panic!("{:?}", pieces[2]) };
        let meshes: Vec<u32> = strokes.iter().map(|s| s.mesh).collect();
        assert_eq!(meshes, [0, 0, 0, 0, 1]);
        assert_eq!(strokes[4].solid.kind(), SolidKind::Hole);
    }

    #[test]
    fn the_older_layouts_plan_a_mesh_per_stroke() {
        for (layout, per_stroke) in [(Layout::Pmb1, 36), (Layout::Pmb2, 164)] {
            let plan = plan(session(), layout);
            assert_eq!(plan.bytes, 8 + 5 * per_stroke + 4 * (2 << 20) + 10);
            // A piece per large mesh (each a copy of the shared one), then the small one.
            let sizes: Vec<usize> = plan
                .pieces
                .iter()
                .map(|p| match p {
                    Piece::Listed { entries, placed } => {
                        assert_eq!(*placed, layout == Layout::Pmb2);
                        entries.len()
                    }
                    other => panic!("{other:?}"),
                })
                .collect();
            assert_eq!(sizes, [1, 1, 1, 1, 1]);
        }
        assert_eq!(plan(vec![], Layout::Pmb3).pieces.len(), 0);
    }
}
