//! Checks an uploaded GLB (binary glTF 2.0) with the `gltf` crate and reads its vertex and
//! triangle counts from the accessors its meshes use. A count is believed only when the bytes
//! behind it are in the file: every counted accessor must lie inside its buffer view, the view
//! inside its buffer, and the buffer inside the GLB's BIN chunk, all in checked arithmetic, so a
//! small file cannot claim a huge mesh or overflow the totals.

/// What an uploaded mesh holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MeshCounts {
    pub vertices: u64,
    pub triangles: u64,
}

/// Validates the GLB container and its JSON, and counts vertices (POSITION accessors) and
/// triangles (index accessors / 3, or vertices / 3 for unindexed triangle lists) over every
/// primitive, each count checked against the data behind it.
pub fn inspect(bytes: &[u8]) -> Result<MeshCounts, String> {
    if bytes.get(0..4) != Some(b"glTF".as_slice()) {
        return Err("magic is not 'glTF'".into());
    }
    // The header's length must be the body's: the gltf crate reads past neither end, but would
    // take a body with bytes after the GLB.
    let declared = bytes.get(8..12).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    if declared.is_some_and(|length| length as usize != bytes.len()) {
        return Err(format!(
            "header says {} bytes, body has {}",
            declared.unwrap_or(0),
            bytes.len()
        ));
    }
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| format!("not a valid GLB: {e}"))?;
    let bin_len = gltf.blob.as_ref().map_or(0, Vec::len);
    let (mut vertices, mut triangles) = (0u64, 0u64);
    for mesh in gltf.meshes() {
        for primitive in mesh.primitives() {
            let positions = primitive
                .get(&gltf::Semantic::Positions)
                .ok_or_else(|| format!("mesh {}: a primitive has no POSITION", mesh.index()))?;
            let n_vertices = backed_count(&positions, bin_len)?;
            vertices = vertices.checked_add(n_vertices).ok_or("vertex count overflows")?;
            if primitive.mode() == gltf::mesh::Mode::Triangles {
                let n_triangles = match primitive.indices() {
                    Some(indices) => backed_count(&indices, bin_len)? / 3,
                    None => n_vertices / 3,
                };
                triangles = triangles.checked_add(n_triangles).ok_or("triangle count overflows")?;
            }
        }
    }
    Ok(MeshCounts { vertices, triangles })
}

/// The accessor's element count, once its elements are known to lie inside the BIN chunk.
fn backed_count(accessor: &gltf::Accessor<'_>, bin_len: usize) -> Result<u64, String> {
    let index = accessor.index();
    let view = accessor.view().ok_or_else(|| {
        format!("accessor {index} has no buffer view: the mesh's data is missing")
    })?;
    let buffer = view.buffer();
    if !matches!(buffer.source(), gltf::buffer::Source::Bin) || buffer.length() > bin_len {
        return Err(format!(
            "accessor {index}: buffer {} is not inside the GLB's {bin_len}-byte BIN chunk",
            buffer.index()
        ));
    }
    let view_end = view.offset().checked_add(view.length());
    if view_end.is_none_or(|end| end > buffer.length()) {
        return Err(format!("buffer view {} overruns its buffer", view.index()));
    }
    let count = accessor.count();
    let element = accessor.size();
    let stride = view.stride().unwrap_or(element);
    let needed = match count {
        0 => Some(0),
        n => (n - 1)
            .checked_mul(stride)
            .and_then(|span| span.checked_add(element))
            .and_then(|span| span.checked_add(accessor.offset())),
    };
    if needed.is_none_or(|needed| needed > view.length()) {
        return Err(format!(
            "accessor {index} claims {count} elements, more than its {}-byte buffer view holds",
            view.length()
        ));
    }
    Ok(count as u64)
}

/// A GLB with one indexed triangle list of `vertices` positions and `indices` indices, its
/// buffers zero-filled: valid for [`inspect`].
#[cfg(test)]
pub(crate) fn tiny_glb(vertices: u64, indices: u64) -> Vec<u8> {
    glb_with(vertices, indices, vertices * 12 + indices * 4)
}

/// [`tiny_glb`] whose buffer holds `bin_len` bytes, whatever the accessors claim.
#[cfg(test)]
fn glb_with(vertices: u64, indices: u64, bin_len: u64) -> Vec<u8> {
    let positions = vertices.saturating_mul(12).min(bin_len);
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": bin_len}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": positions},
                        {"buffer": 0, "byteOffset": positions, "byteLength": bin_len - positions}],
        "accessors": [{"bufferView": 0, "count": vertices, "type": "VEC3", "componentType": 5126,
                       "min": [0.0, 0.0, 0.0], "max": [0.0, 0.0, 0.0]},
                      {"bufferView": 1, "count": indices, "type": "SCALAR", "componentType": 5125}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}]
    })
    .to_string();
    let mut json = json.into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let bin_padded = bin_len.next_multiple_of(4) as usize;
    let total = 12 + 8 + json.len() + 8 + bin_padded;
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(0x4E4F_534Au32.to_le_bytes());
    out.extend(json);
    out.extend((bin_padded as u32).to_le_bytes());
    out.extend(0x004E_4942u32.to_le_bytes());
    out.resize(total, 0);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_vertices_and_triangles() {
        assert_eq!(inspect(&tiny_glb(8, 36)).unwrap(), MeshCounts { vertices: 8, triangles: 12 });
    }

    #[test]
    fn refuses_broken_containers() {
        let good = tiny_glb(3, 3);
        let mut bad_magic = good.clone();
        bad_magic[0] = b'x';
        assert!(inspect(&bad_magic).unwrap_err().contains("magic"));
        let mut bad_version = good.clone();
        bad_version[4] = 1;
        assert!(inspect(&bad_version).unwrap_err().contains("version"));
        let mut truncated = good.clone();
        truncated.pop();
        assert!(inspect(&truncated).is_err());
    }

    #[test]
    fn counts_the_data_does_not_back_are_refused() {
        // A small file that claims far more elements than it carries, up to counts whose
        // sizes overflow.
        for (vertices, indices, bin_len) in
            [(1000, 3, 48), (3, 3_000_000, 48), (u64::MAX / 4, 3, 48)]
        {
            let err = inspect(&glb_with(vertices, indices, bin_len)).unwrap_err();
            assert!(err.contains("claims") || err.contains("not a valid GLB"), "{err}");
        }
        // Accessors with no buffer view (zeros of any count, by the glTF rules) count nothing.
        let json = br#"{"asset":{"version":"2.0"},"accessors":[{"count":4294967295,"type":"VEC3","componentType":5126,"min":[0,0,0],"max":[0,0,0]}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}]}"#;
        let mut glb = b"glTF".to_vec();
        let padded = json.len().next_multiple_of(4);
        glb.extend(2u32.to_le_bytes());
        glb.extend(((20 + padded) as u32).to_le_bytes());
        glb.extend((padded as u32).to_le_bytes());
        glb.extend(0x4E4F_534Au32.to_le_bytes());
        glb.extend(json);
        glb.resize(20 + padded, b' ');
        let err = inspect(&glb).unwrap_err();
        assert!(err.contains("bufferView") || err.contains("no buffer view"), "{err}");
    }
}
