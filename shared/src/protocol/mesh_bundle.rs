//! The body of `GET /v1/sessions/{session}/meshes`: every stored mesh of a session in one
//! response, [`MESH_BUNDLE_CONTENT_TYPE`]. Binary, since a mesh is a binary GLB and base64 in
//! JSON would add a third to it (`docs/performance-log.md`, "A busy board", measures both):
//!
//! ```text
//! "PMB1"                       4 bytes: magic and layout version
//! count                        u32, little-endian
//! count times:
//!   stroke id                  16 bytes (UUID, RFC 9562 byte order)
//!   participant id             16 bytes (the stroke's drawer)
//!   glb length                 u32, little-endian
//!   glb                        that many bytes
//! ```
//!
//! Nothing follows the last mesh. The page (`client/web/src/api.js`) reads the same layout.
//!
//! **With placements** (protocol 5, `GET …/meshes?placements=true`): layout `"PMB2"`, the same
//! but each mesh's header holds its stroke's current placement after the participant id:
//!
//! ```text
//!   stroke id, participant id  16 + 16 bytes
//!   placement                  128 bytes: glTF node.matrix, 16 f64 little-endian, column-major
//!   glb length, glb            u32 little-endian, that many bytes
//! ```
//!
//! A page reads `PMB2` as `PMB1` with the 128 bytes after the two ids as a `Float64Array`
//! (copy them out first: they are not 8-byte aligned in the body), the stroke's node matrix
//! (`Matrix4.fromArray`, with the mesh's winding flipped when its determinant is negative). The
//! default stays `PMB1`, so a page that does not ask keeps working. A duplicate's mesh is its
//! source's bytes, under the duplicate's stroke id and placement: in `PMB1` and `PMB2` once per
//! stroke that shows it.
//!
//! **With a mesh table** (protocol 6, `GET …/meshes?layout=PMB3`, [`table`]): each distinct
//! mesh once, then every stroke with its placement, its solid and the index of its mesh, so a
//! stroke and its duplicates cost one mesh. What the page asks for.

mod table;

use uuid::Uuid;

use super::{ParticipantId, StrokeId};
use crate::placement::{Placement, PlacementError};
use crate::solid::SolidError;

pub use table::{
    BUNDLED_STROKE_BYTES, BundledStroke, MESH_BUNDLE_TABLE_MAGIC, MeshTableBundle,
    decode_mesh_table_bundle, encode_mesh_table_bundle, mesh_table_bundle_head,
    push_bundled_stroke, push_table_mesh,
};

/// The first four bytes of a bundle with placements ([`encode_placed_mesh_bundle`]).
pub const MESH_BUNDLE_PLACED_MAGIC: [u8; 4] = *b"PMB2";

/// A mesh of a bundle with its stroke's placement.
#[derive(Debug, Clone, PartialEq)]
pub struct PlacedMesh {
    pub mesh: BundledMesh,
    pub placement: Placement,
}

/// The `PMB2` bundle of `meshes`, in their order.
///
/// # Panics
/// As [`encode_mesh_bundle`].
pub fn encode_placed_mesh_bundle(meshes: &[PlacedMesh]) -> Vec<u8> {
    let size = 8 + meshes.iter().map(|m| 164 + m.mesh.glb.len()).sum::<usize>();
    let mut out = Vec::with_capacity(size);
    out.extend_from_slice(&mesh_bundle_head(meshes.len(), true));
    for PlacedMesh { mesh, placement } in meshes {
        push_bundled_mesh(&mut out, mesh.stroke, mesh.participant, Some(placement), &mesh.glb);
    }
    out
}

/// The meshes of a `PMB2` bundle.
pub fn decode_placed_mesh_bundle(bytes: &[u8]) -> Result<Vec<PlacedMesh>, MeshBundleError> {
    if bytes.get(..4) != Some(&MESH_BUNDLE_PLACED_MAGIC[..]) {
        return Err(MeshBundleError::Magic("PMB2"));
    }
    let mut at = 4;
    let count =
        read_u32(bytes, &mut at).ok_or(MeshBundleError::Truncated { index: 0, at })? as usize;
    let mut meshes = Vec::with_capacity(count.min(bytes.len() / 164));
    for index in 0..count {
        let truncated = MeshBundleError::Truncated { index, at };
        let stroke = read_uuid(bytes, &mut at).ok_or(truncated.clone())?;
        let participant = read_uuid(bytes, &mut at).ok_or(truncated.clone())?;
        let matrix = bytes.get(at..at + 128).ok_or(truncated.clone())?;
        let placement = Placement::from_bytes(matrix)
            .map_err(|error| MeshBundleError::Placement { stroke: index, error })?;
        at += 128;
        let len = read_u32(bytes, &mut at).ok_or(truncated.clone())? as usize;
        let glb = bytes.get(at..at.saturating_add(len)).ok_or(truncated)?.to_vec();
        at += len;
        meshes.push(PlacedMesh { mesh: BundledMesh { stroke, participant, glb }, placement });
    }
    if at != bytes.len() {
        return Err(MeshBundleError::Trailing { count, extra: bytes.len() - at });
    }
    Ok(meshes)
}

/// The media type of a mesh bundle.
pub const MESH_BUNDLE_CONTENT_TYPE: &str = "application/vnd.penmesh.mesh-bundle";
/// The first four bytes of a bundle; the digit is the layout's version.
pub const MESH_BUNDLE_MAGIC: [u8; 4] = *b"PMB1";

/// One mesh of a bundle.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BundledMesh {
    pub stroke: StrokeId,
    pub participant: ParticipantId,
    pub glb: Vec<u8>,
}

/// Why bytes are not a mesh bundle. Each names where reading stopped.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum MeshBundleError {
    /// The layout expected (its magic).
    #[error("not a mesh bundle of layout {0}: it does not start with \"{0}\"")]
    Magic(&'static str),
    #[error("the mesh bundle ends inside its head (the magic and the counts): it has {at} bytes")]
    Head { at: usize },
    #[error("the mesh bundle ends inside mesh {index} (or its header), at byte {at}")]
    Truncated { index: usize, at: usize },
    #[error("the mesh bundle ends inside stroke {index}'s entry, at byte {at}")]
    TruncatedStroke { index: usize, at: usize },
    #[error("the mesh bundle's stroke {stroke} has a bad placement: {error}")]
    Placement { stroke: usize, error: PlacementError },
    #[error("the mesh bundle's stroke {stroke} has a bad solid: {error}")]
    Solid { stroke: usize, error: SolidError },
    #[error("the mesh bundle's stroke {stroke} shows mesh {mesh}, but the bundle has {meshes}")]
    MeshIndex { stroke: usize, mesh: u32, meshes: usize },
    /// `count`: the meshes (`PMB1`, `PMB2`) or strokes (`PMB3`) read before the extra bytes.
    #[error("the mesh bundle has {extra} bytes after its last entry (of {count})")]
    Trailing { count: usize, extra: usize },
}

/// The bundle of `meshes`, in their order.
///
/// # Panics
/// When there are more than `u32::MAX` meshes or one is larger than `u32::MAX` bytes (the
/// proxy's body limit keeps every stored mesh far below).
pub fn encode_mesh_bundle(meshes: &[BundledMesh]) -> Vec<u8> {
    let size = 8 + meshes.iter().map(|m| 36 + m.glb.len()).sum::<usize>();
    let mut out = Vec::with_capacity(size);
    out.extend_from_slice(&mesh_bundle_head(meshes.len(), false));
    for mesh in meshes {
        push_bundled_mesh(&mut out, mesh.stroke, mesh.participant, None, &mesh.glb);
    }
    out
}

/// The first 8 bytes of a bundle of `count` meshes (the magic and the count): what a bundle
/// written piece by piece starts with, each mesh then added by [`push_bundled_mesh`]. `placed`:
/// the `PMB2` layout, each mesh with its placement.
///
/// # Panics
/// When `count` is more than `u32::MAX`.
pub fn mesh_bundle_head(count: usize, placed: bool) -> [u8; 8] {
    let mut head = [0; 8];
    let magic = if placed { MESH_BUNDLE_PLACED_MAGIC } else { MESH_BUNDLE_MAGIC };
    head[..4].copy_from_slice(&magic);
    head[4..]
        .copy_from_slice(&u32::try_from(count).expect("at most u32::MAX meshes").to_le_bytes());
    head
}

/// Appends one mesh of a bundle to `out`: with its placement in a `PMB2` bundle, without in a
/// `PMB1` one (as its head says).
///
/// # Panics
/// When `glb` is larger than `u32::MAX` bytes.
pub fn push_bundled_mesh(
    out: &mut Vec<u8>,
    stroke: StrokeId,
    participant: ParticipantId,
    placement: Option<&Placement>,
    glb: &[u8],
) {
    out.extend_from_slice(stroke.as_bytes());
    out.extend_from_slice(participant.as_bytes());
    if let Some(placement) = placement {
        out.extend_from_slice(&placement.to_bytes());
    }
    let len = u32::try_from(glb.len()).expect("a mesh of at most u32::MAX bytes");
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(glb);
}

/// The meshes of a bundle.
pub fn decode_mesh_bundle(bytes: &[u8]) -> Result<Vec<BundledMesh>, MeshBundleError> {
    if bytes.get(..4) != Some(&MESH_BUNDLE_MAGIC[..]) {
        return Err(MeshBundleError::Magic("PMB1"));
    }
    let mut at = 4;
    let count =
        read_u32(bytes, &mut at).ok_or(MeshBundleError::Truncated { index: 0, at })? as usize;
    let mut meshes = Vec::with_capacity(count.min(bytes.len() / 36));
    for index in 0..count {
        let truncated = MeshBundleError::Truncated { index, at };
        let stroke = read_uuid(bytes, &mut at).ok_or(truncated.clone())?;
        let participant = read_uuid(bytes, &mut at).ok_or(truncated.clone())?;
        let len = read_u32(bytes, &mut at).ok_or(truncated.clone())? as usize;
        let glb = bytes.get(at..at.saturating_add(len)).ok_or(truncated)?.to_vec();
        at += len;
        meshes.push(BundledMesh { stroke, participant, glb });
    }
    if at != bytes.len() {
        return Err(MeshBundleError::Trailing { count, extra: bytes.len() - at });
    }
    Ok(meshes)
}

fn read_u32(bytes: &[u8], at: &mut usize) -> Option<u32> {
    let word = bytes.get(*at..*at + 4)?;
    *at += 4;
    Some(u32::from_le_bytes(word.try_into().ok()?))
}

fn read_uuid(bytes: &[u8], at: &mut usize) -> Option<Uuid> {
    let id = Uuid::from_slice(bytes.get(*at..*at + 16)?).ok()?;
    *at += 16;
    Some(id)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mesh(n: u8, len: usize) -> BundledMesh {
        BundledMesh {
            stroke: Uuid::from_bytes([n; 16]),
            participant: Uuid::from_bytes([n + 100; 16]),
            glb: (0..len).map(|i| i as u8 ^ n).collect(),
        }
    }

    #[test]
    fn a_bundle_reads_back_as_written() {
        for meshes in [vec![], vec![mesh(1, 0)], vec![mesh(1, 7), mesh(2, 300), mesh(3, 1)]] {
            let bytes = encode_mesh_bundle(&meshes);
            assert_eq!(bytes.len(), 8 + meshes.iter().map(|m| 36 + m.glb.len()).sum::<usize>());
            assert_eq!(decode_mesh_bundle(&bytes), Ok(meshes));
        }
    }

    // A bundle with placements reads back as written, placements bit for bit.
    #[test]
    fn a_placed_bundle_reads_back_as_written() {
        let mut matrix = *Placement::IDENTITY.matrix();
        matrix[0] = -1.0;
        matrix[13] = 0.1;
        let placed = |n, len, placement| PlacedMesh { mesh: mesh(n, len), placement };
        let meshes =
            vec![placed(1, 7, Placement::IDENTITY), placed(2, 30, Placement::new(matrix).unwrap())];
        let bytes = encode_placed_mesh_bundle(&meshes);
        assert_eq!(&bytes[..4], b"PMB2");
        assert_eq!(decode_placed_mesh_bundle(&bytes), Ok(meshes));
        assert_eq!(decode_mesh_bundle(&bytes), Err(MeshBundleError::Magic("PMB1")));
        assert!(decode_placed_mesh_bundle(&bytes[..bytes.len() - 1]).is_err());
    }

    #[test]
    fn bad_bundles_are_refused_with_where() {
        let bytes = encode_mesh_bundle(&[mesh(1, 10), mesh(2, 10)]);
        assert_eq!(decode_mesh_bundle(b"PMB2\0\0\0\0"), Err(MeshBundleError::Magic("PMB1")));
        assert_eq!(decode_mesh_bundle(&bytes[..3]), Err(MeshBundleError::Magic("PMB1")));
        // Cut inside the second mesh's GLB: the error names it and where its header began.
        assert_eq!(
            decode_mesh_bundle(&bytes[..bytes.len() - 1]),
            Err(MeshBundleError::Truncated { index: 1, at: 8 + 46 })
        );
        let mut longer = bytes.clone();
        longer.push(0);
        assert_eq!(
            decode_mesh_bundle(&longer),
            Err(MeshBundleError::Trailing { count: 2, extra: 1 })
        );
    }
}
