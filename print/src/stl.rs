//! Binary STL: an 80-byte header, the triangle count, then per triangle its unit normal, its
//! three corners (f32, little-endian) and a zero attribute word. STL has no unit: slicers read
//! millimetres, which is what [`crate::PrintMesh`] holds.

use glam::Vec3;

use crate::solid::PrintMesh;

const HEADER: &[u8] = b"penmesh print: one closed manifold, millimetres";

/// The mesh as a binary STL file.
pub fn write_stl(mesh: &PrintMesh) -> Vec<u8> {
    let triangles = mesh.indices.len() / 3;
    let mut out = Vec::with_capacity(84 + 50 * triangles);
    let mut header = [0u8; 80];
    header[..HEADER.len()].copy_from_slice(HEADER);
    out.extend_from_slice(&header);
    out.extend_from_slice(&(triangles as u32).to_le_bytes());
    for [a, b, c] in mesh.triangles() {
        let [a, b, c] = [a, b, c].map(|i| Vec3::from(mesh.positions[i as usize]));
        let normal = (b - a).cross(c - a).normalize_or_zero();
        for v in [normal, a, b, c] {
            for x in v.to_array() {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
        out.extend_from_slice(&0u16.to_le_bytes());
    }
    out
}
