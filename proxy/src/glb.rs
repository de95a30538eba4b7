//! Checks an uploaded GLB (binary glTF 2.0) and reads its vertex and triangle counts from the
//! JSON chunk's accessors, without decoding the buffers.

/// What an uploaded mesh holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MeshCounts {
    pub vertices: u64,
    pub triangles: u64,
}

/// Validates the GLB container (magic `glTF`, version 2, consistent lengths, a JSON chunk
/// first) and counts vertices (POSITION accessors) and triangles (index accessors / 3, or
/// vertices / 3 for unindexed triangle lists) over every primitive.
pub fn inspect(bytes: &[u8]) -> Result<MeshCounts, String> {
    let u32_at = |at: usize| -> Result<u32, String> {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
            .ok_or_else(|| format!("truncated at byte {at}"))
    };
    if bytes.len() < 20 {
        return Err(format!("{} bytes is too short for a GLB", bytes.len()));
    }
    if &bytes[0..4] != b"glTF" {
        return Err("magic is not 'glTF'".into());
    }
    let version = u32_at(4)?;
    if version != 2 {
        return Err(format!("version {version}, expected 2"));
    }
    let length = u32_at(8)? as usize;
    if length != bytes.len() {
        return Err(format!("header says {length} bytes, body has {}", bytes.len()));
    }
    let json_len = u32_at(12)? as usize;
    if u32_at(16)? != 0x4E4F_534A {
        return Err("first chunk is not JSON".into());
    }
    let json = bytes
        .get(20..20 + json_len)
        .ok_or_else(|| format!("JSON chunk of {json_len} bytes overruns the file"))?;
    let doc: serde_json::Value =
        serde_json::from_slice(json).map_err(|e| format!("JSON chunk: {e}"))?;
    let count_of = |accessor: &serde_json::Value| -> Result<u64, String> {
        let index = accessor.as_u64().ok_or("accessor index is not a number")? as usize;
        doc["accessors"][index]["count"]
            .as_u64()
            .ok_or_else(|| format!("accessor {index} has no count"))
    };
    let (mut vertices, mut triangles) = (0, 0);
    for mesh in doc["meshes"].as_array().into_iter().flatten() {
        for primitive in mesh["primitives"].as_array().into_iter().flatten() {
            let n_vertices = count_of(&primitive["attributes"]["POSITION"])?;
            vertices += n_vertices;
            let mode = primitive["mode"].as_u64().unwrap_or(4);
            if mode == 4 {
                triangles += match primitive.get("indices") {
                    Some(indices) => count_of(indices)? / 3,
                    None => n_vertices / 3,
                };
            }
        }
    }
    Ok(MeshCounts { vertices, triangles })
}

#[cfg(test)]
pub(crate) fn tiny_glb(vertices: u64, indices: u64) -> Vec<u8> {
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "accessors": [{"count": vertices, "type": "VEC3", "componentType": 5126},
                      {"count": indices, "type": "SCALAR", "componentType": 5125}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}]
    })
    .to_string();
    let mut json = json.into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len();
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(0x4E4F_534Au32.to_le_bytes());
    out.extend(json);
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
        assert!(inspect(&truncated).unwrap_err().contains("header says"));
    }
}
