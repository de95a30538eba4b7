//! The `PMB3` layout of the mesh bundle (`GET …/meshes?layout=PMB3`): a table of the session's
//! distinct meshes, each sent once, then every stroke with its placement and solid and the
//! index of the mesh it shows. A duplicate shows its source's mesh (shared in the database,
//! never copied), so a stroke and its N duplicates cost one mesh and N + 1 stroke entries of
//! [`BUNDLED_STROKE_BYTES`], where `PMB1` and `PMB2` repeat the mesh for each (issue 49, item 10).
//!
//! ```text
//! "PMB3"                       4 bytes: magic and layout version
//! mesh count                   u32, little-endian
//! stroke count                 u32, little-endian
//! mesh count times:
//!   glb length                 u32, little-endian
//!   glb                        that many bytes
//! stroke count times (173 bytes each):
//!   stroke id                  16 bytes (UUID, RFC 9562 byte order)
//!   participant id             16 bytes (the stroke's drawer)
//!   placement                  128 bytes: glTF node.matrix, 16 f64 little-endian, column-major
//!   solid                      9 bytes: kind (0 line, 1 filled, 2 hole), depth f64 (NaN: none)
//!   mesh index                 u32, little-endian: which of the meshes above it shows
//! ```
//!
//! Nothing follows the last stroke. The meshes come in the order their first stroke has in the
//! session's history; the strokes in that order. A stroke names a mesh of the table (a
//! decoder refuses an index past it); a mesh no stroke names is allowed.

use super::{MeshBundleError, read_u32};
use crate::placement::Placement;
use crate::protocol::{ParticipantId, StrokeId};
use crate::solid::Solid;

/// The first four bytes of a bundle with a mesh table ([`encode_mesh_table_bundle`]).
pub const MESH_BUNDLE_TABLE_MAGIC: [u8; 4] = *b"PMB3";

/// The bytes of one stroke's entry in a `PMB3` bundle: two ids, a placement, a solid, an index.
pub const BUNDLED_STROKE_BYTES: usize = 16 + 16 + 128 + 9 + 4;

/// A `PMB3` bundle: each distinct mesh once, and the strokes that show them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MeshTableBundle {
    /// The GLBs, each once.
    pub meshes: Vec<Vec<u8>>,
    pub strokes: Vec<BundledStroke>,
}

/// One stroke of a `PMB3` bundle.
#[derive(Debug, Clone, PartialEq)]
pub struct BundledStroke {
    pub stroke: StrokeId,
    pub participant: ParticipantId,
    /// Its current placement.
    pub placement: Placement,
    /// Its current solid (what its mesh was built as).
    pub solid: Solid,
    /// The index in [`MeshTableBundle::meshes`] of the mesh it shows.
    pub mesh: u32,
}

/// The `PMB3` bundle of `bundle`.
///
/// # Panics
/// When a stroke names a mesh past the table, when there are more than `u32::MAX` meshes or
/// strokes, or a mesh is larger than `u32::MAX` bytes (the proxy's body limit keeps every
/// stored mesh far below).
pub fn encode_mesh_table_bundle(bundle: &MeshTableBundle) -> Vec<u8> {
    let MeshTableBundle { meshes, strokes } = bundle;
    let size = 12
        + meshes.iter().map(|glb| 4 + glb.len()).sum::<usize>()
        + strokes.len() * BUNDLED_STROKE_BYTES;
    let mut out = Vec::with_capacity(size);
    out.extend_from_slice(&mesh_table_bundle_head(meshes.len(), strokes.len()));
    for glb in meshes {
        push_table_mesh(&mut out, glb);
    }
    for stroke in strokes {
        assert!((stroke.mesh as usize) < meshes.len(), "stroke {} names no mesh", stroke.stroke);
        push_bundled_stroke(&mut out, stroke);
    }
    out
}

/// The first 12 bytes of a `PMB3` bundle (the magic and both counts): what a bundle written
/// piece by piece starts with, then each mesh by [`push_table_mesh`] and each stroke by
/// [`push_bundled_stroke`].
///
/// # Panics
/// When either count is more than `u32::MAX`.
pub fn mesh_table_bundle_head(meshes: usize, strokes: usize) -> [u8; 12] {
    let count = |n: usize| u32::try_from(n).expect("at most u32::MAX").to_le_bytes();
    let mut head = [0; 12];
    head[..4].copy_from_slice(&MESH_BUNDLE_TABLE_MAGIC);
    head[4..8].copy_from_slice(&count(meshes));
    head[8..].copy_from_slice(&count(strokes));
    head
}

/// Appends one mesh of the table to `out`: its length, then its bytes.
///
/// # Panics
/// When `glb` is larger than `u32::MAX` bytes.
pub fn push_table_mesh(out: &mut Vec<u8>, glb: &[u8]) {
    let len = u32::try_from(glb.len()).expect("a mesh of at most u32::MAX bytes");
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(glb);
}

/// Appends one stroke's entry to `out` ([`BUNDLED_STROKE_BYTES`]).
pub fn push_bundled_stroke(out: &mut Vec<u8>, stroke: &BundledStroke) {
    out.extend_from_slice(stroke.stroke.as_bytes());
    out.extend_from_slice(stroke.participant.as_bytes());
    out.extend_from_slice(&stroke.placement.to_bytes());
    out.extend_from_slice(&stroke.solid.to_bytes());
    out.extend_from_slice(&stroke.mesh.to_le_bytes());
}

/// Reads a `PMB3` bundle: every length and index checked against the bytes there are, each
/// placement and solid validated; an error names the mesh or stroke where reading stopped.
pub fn decode_mesh_table_bundle(bytes: &[u8]) -> Result<MeshTableBundle, MeshBundleError> {
    if bytes.get(..4) != Some(&MESH_BUNDLE_TABLE_MAGIC[..]) {
        return Err(MeshBundleError::Magic("PMB3"));
    }
    let mut at = 4;
    let head = MeshBundleError::Head { at: bytes.len() };
    let n_meshes = read_u32(bytes, &mut at).ok_or(head.clone())? as usize;
    let n_strokes = read_u32(bytes, &mut at).ok_or(head)? as usize;
    // The counts are the sender's word: room is made for what the bytes can hold, at most.
    let mut meshes = Vec::with_capacity(n_meshes.min(bytes.len() / 4));
    for index in 0..n_meshes {
        let truncated = MeshBundleError::Truncated { index, at };
        let len = read_u32(bytes, &mut at).ok_or(truncated.clone())? as usize;
        meshes.push(bytes.get(at..at.saturating_add(len)).ok_or(truncated)?.to_vec());
        at += len;
    }
    let mut strokes = Vec::with_capacity(n_strokes.min(bytes.len() / BUNDLED_STROKE_BYTES));
    for index in 0..n_strokes {
        let entry = bytes
            .get(at..at + BUNDLED_STROKE_BYTES)
            .ok_or(MeshBundleError::TruncatedStroke { index, at })?;
        let id = |from: usize| {
            uuid::Uuid::from_slice(&entry[from..from + 16]).expect("16 bytes are a UUID")
        };
        let placement = Placement::from_bytes(&entry[32..160])
            .map_err(|error| MeshBundleError::Placement { stroke: index, error })?;
        let solid = Solid::from_bytes(&entry[160..169])
            .map_err(|error| MeshBundleError::Solid { stroke: index, error })?;
        let mesh = u32::from_le_bytes(entry[169..].try_into().expect("4 bytes"));
        if mesh as usize >= n_meshes {
            return Err(MeshBundleError::MeshIndex { stroke: index, mesh, meshes: n_meshes });
        }
        strokes.push(BundledStroke { stroke: id(0), participant: id(16), placement, solid, mesh });
        at += BUNDLED_STROKE_BYTES;
    }
    if at != bytes.len() {
        return Err(MeshBundleError::Trailing { count: n_strokes, extra: bytes.len() - at });
    }
    Ok(MeshTableBundle { meshes, strokes })
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;
    use uuid::Uuid;

    use super::*;
    use crate::solid::SolidKind;

    fn stroke(n: u8, mesh: u32, solid: Solid) -> BundledStroke {
        let mut matrix = *Placement::IDENTITY.matrix();
        matrix[12] = f64::from(n) * 0.1;
        BundledStroke {
            stroke: Uuid::from_bytes([n; 16]),
            participant: Uuid::from_bytes([n.wrapping_add(100); 16]),
            placement: Placement::new(matrix).unwrap(),
            solid,
            mesh,
        }
    }

    /// A stroke and two duplicates sharing mesh 0, and a hole with a mesh of its own.
    fn sample() -> MeshTableBundle {
        let hole = Solid::new(SolidKind::Hole, Some(0.1 + 0.2)).unwrap();
        MeshTableBundle {
            meshes: vec![(0..300).map(|i| i as u8).collect(), vec![7; 5]],
            strokes: vec![
                stroke(1, 0, Solid::ROD),
                stroke(2, 0, Solid::ROD),
                stroke(3, 1, hole),
                stroke(4, 0, Solid::ROD),
            ],
        }
    }

    #[test]
    fn a_table_bundle_reads_back_as_written_each_mesh_once() {
        let bundle = sample();
        let bytes = encode_mesh_table_bundle(&bundle);
        assert_eq!(&bytes[..4], b"PMB3");
        assert_eq!(bytes.len(), 12 + (4 + 300) + (4 + 5) + 4 * BUNDLED_STROKE_BYTES);
        assert_eq!(decode_mesh_table_bundle(&bytes), Ok(bundle));
        let empty = MeshTableBundle::default();
        assert_eq!(decode_mesh_table_bundle(&encode_mesh_table_bundle(&empty)), Ok(empty));
        // The other layouts' readers refuse it by its magic, and it theirs.
        assert_eq!(super::super::decode_mesh_bundle(&bytes), Err(MeshBundleError::Magic("PMB1")));
        let pmb1 = super::super::encode_mesh_bundle(&[]);
        assert_eq!(decode_mesh_table_bundle(&pmb1), Err(MeshBundleError::Magic("PMB3")));
    }

    #[test]
    fn a_bad_table_bundle_is_refused_naming_where() {
        let bytes = encode_mesh_table_bundle(&sample());
        let strokes_at = 12 + 304 + 9;
        assert_eq!(decode_mesh_table_bundle(&bytes[..10]), Err(MeshBundleError::Head { at: 10 }));
        // Cut inside the second mesh, and inside the last stroke.
        assert_eq!(
            decode_mesh_table_bundle(&bytes[..12 + 304 + 6]),
            Err(MeshBundleError::Truncated { index: 1, at: 12 + 304 })
        );
        assert_eq!(
            decode_mesh_table_bundle(&bytes[..bytes.len() - 1]),
            Err(MeshBundleError::TruncatedStroke {
                index: 3,
                at: strokes_at + 3 * BUNDLED_STROKE_BYTES
            })
        );
        let mut longer = bytes.clone();
        longer.push(0);
        assert_eq!(
            decode_mesh_table_bundle(&longer),
            Err(MeshBundleError::Trailing { count: 4, extra: 1 })
        );
        // Stroke 2's mesh index past the table of 2.
        let mut bad = bytes.clone();
        let index_at = strokes_at + 2 * BUNDLED_STROKE_BYTES + 169;
        bad[index_at..index_at + 4].copy_from_slice(&2u32.to_le_bytes());
        assert_eq!(
            decode_mesh_table_bundle(&bad),
            Err(MeshBundleError::MeshIndex { stroke: 2, mesh: 2, meshes: 2 })
        );
        // Stroke 1's solid of an unknown kind, and its placement sheared.
        let mut bad = bytes.clone();
        bad[strokes_at + BUNDLED_STROKE_BYTES + 160] = 9;
        let error = decode_mesh_table_bundle(&bad).unwrap_err();
        assert!(matches!(error, MeshBundleError::Solid { stroke: 1, .. }), "{error:?}");
        assert!(error.to_string().contains("stroke 1") && error.to_string().contains("\"9\""));
        let mut bad = bytes.clone();
        let m4 = strokes_at + BUNDLED_STROKE_BYTES + 32 + 4 * 8;
        bad[m4..m4 + 8].copy_from_slice(&0.25f64.to_le_bytes());
        let error = decode_mesh_table_bundle(&bad).unwrap_err();
        assert!(matches!(error, MeshBundleError::Placement { stroke: 1, .. }), "{error:?}");
        assert!(error.to_string().contains("not a similarity"), "{error}");
        // A count far past the bytes: refused, no room made for it.
        let mut huge = bytes[..12].to_vec();
        huge[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
        assert_eq!(
            decode_mesh_table_bundle(&huge),
            Err(MeshBundleError::Truncated { index: 0, at: 12 })
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        /// Any bytes after the magic: a bundle or a named error, never a panic.
        #[test]
        fn any_bytes_read_or_are_refused(tail in proptest::collection::vec(any::<u8>(), 0..600)) {
            let mut bytes = b"PMB3".to_vec();
            bytes.extend_from_slice(&tail);
            let _ = decode_mesh_table_bundle(&bytes);
        }

        /// A real bundle with bytes flipped or cut: a bundle or a named error, never a panic.
        #[test]
        fn a_damaged_bundle_reads_or_is_refused(
            flips in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..8),
            cut in any::<prop::sample::Index>(),
        ) {
            let mut bytes = encode_mesh_table_bundle(&sample());
            for (at, byte) in flips {
                let at = at.index(bytes.len());
                bytes[at] = byte;
            }
            let len = cut.index(bytes.len() + 1);
            let _ = decode_mesh_table_bundle(&bytes[..len]);
        }
    }
}
