//! Checks an uploaded GLB (binary glTF 2.0) with the `gltf` crate and reads its vertex and
//! triangle counts from the accessors its meshes use. A count is believed only when the bytes
//! behind it are in the file: every counted accessor must lie inside its buffer view, the view
//! inside its buffer, and the buffer inside the GLB's BIN chunk, all in checked arithmetic, so a
//! small file cannot claim a huge mesh or overflow the totals.
//!
//! The file may require exactly the extensions penmesh writes ([`ACCEPTED_EXTENSIONS`]:
//! `KHR_mesh_quantization` and `EXT_meshopt_compression`); any other required extension is
//! refused by name, and the rest of the document gets the `gltf` crate's validation (which
//! would refuse every required extension it does not implement itself). A view compressed with
//! `EXT_meshopt_compression` is believed once its compressed bytes, inside the BIN chunk, decode
//! with meshoptimizer's decoders to exactly the view (`count` elements of `byteStride` bytes):
//! the layouts penmesh writes, 12-byte quantised vertices (`ATTRIBUTES`, the vertex codec's
//! version 0 the extension specifies) and 2- or 4-byte indices (`TRIANGLES`). What the views
//! decode to is bounded by `max_decoded` bytes over the file, checked before decoding.

use penmesh::{EXT_MESHOPT_COMPRESSION, KHR_MESH_QUANTIZATION};

/// The extensions an uploaded GLB may require: those penmesh writes.
pub const ACCEPTED_EXTENSIONS: [&str; 2] = [KHR_MESH_QUANTIZATION, EXT_MESHOPT_COMPRESSION];

/// What an uploaded mesh holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MeshCounts {
    pub vertices: u64,
    pub triangles: u64,
}

/// Validates the GLB container and its JSON, and counts vertices (POSITION accessors) and
/// triangles (index accessors / 3, or vertices / 3 for unindexed triangle lists) over every
/// primitive, each count checked against the data behind it; compressed views may decode to at
/// most `max_decoded` bytes in all.
pub fn inspect(bytes: &[u8], max_decoded: usize) -> Result<MeshCounts, String> {
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
    let gltf = validated(bytes)?;
    let bin = gltf.blob.as_deref().unwrap_or_default();
    let meshopt = gltf.extensions_used().any(|name| name == EXT_MESHOPT_COMPRESSION);
    let mut budget = max_decoded;
    let (mut vertices, mut triangles) = (0u64, 0u64);
    for mesh in gltf.meshes() {
        for primitive in mesh.primitives() {
            let positions = primitive
                .get(&gltf::Semantic::Positions)
                .ok_or_else(|| format!("mesh {}: a primitive has no POSITION", mesh.index()))?;
            let n_vertices = backed_count(&positions, bin, meshopt, &mut budget)?;
            vertices = vertices.checked_add(n_vertices).ok_or("vertex count overflows")?;
            if primitive.mode() == gltf::mesh::Mode::Triangles {
                let n_triangles = match primitive.indices() {
                    Some(indices) => backed_count(&indices, bin, meshopt, &mut budget)? / 3,
                    None => n_vertices / 3,
                };
                triangles = triangles.checked_add(n_triangles).ok_or("triangle count overflows")?;
            }
        }
    }
    Ok(MeshCounts { vertices, triangles })
}

/// Parses the GLB and validates it with the `gltf` crate, once the required extensions are
/// known to be ones penmesh writes.
fn validated(bytes: &[u8]) -> Result<gltf::Gltf, String> {
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| format!("not a valid GLB: {e}"))?;
    let mut json = document.into_json();
    if let Some(name) =
        json.extensions_required.iter().find(|name| !ACCEPTED_EXTENSIONS.contains(&name.as_str()))
    {
        return Err(format!(
            "it requires the extension {name}; the proxy accepts {}",
            ACCEPTED_EXTENSIONS.join(" and ")
        ));
    }
    // The crate refuses any required extension it does not implement; these are checked here.
    let required = std::mem::take(&mut json.extensions_required);
    let mut document =
        gltf::Document::from_json(json).map_err(|e| format!("not a valid GLB: {e}"))?.into_json();
    document.extensions_required = required;
    Ok(gltf::Gltf { document: gltf::Document::from_json_without_validation(document), blob })
}

/// The accessor's element count, once its elements are known to lie inside the BIN chunk (or
/// to be decoded from it, for a compressed view).
fn backed_count(
    accessor: &gltf::Accessor<'_>,
    bin: &[u8],
    meshopt: bool,
    budget: &mut usize,
) -> Result<u64, String> {
    let index = accessor.index();
    let view = accessor.view().ok_or_else(|| {
        format!("accessor {index} has no buffer view: the mesh's data is missing")
    })?;
    let buffer = view.buffer();
    match view.extension_value(EXT_MESHOPT_COMPRESSION) {
        Some(_) if !meshopt => {
            return Err(format!(
                "buffer view {} is compressed with {EXT_MESHOPT_COMPRESSION}, which the file does \
                 not declare",
                view.index()
            ));
        }
        Some(compressed) => decode_view(&view, compressed, bin, budget)?,
        // Only buffer 0 may be the BIN chunk.
        None if buffer.index() != 0
            || !matches!(buffer.source(), gltf::buffer::Source::Bin)
            || buffer.length() > bin.len() =>
        {
            return Err(format!(
                "accessor {index}: buffer {} is not inside the GLB's {}-byte BIN chunk",
                buffer.index(),
                bin.len()
            ));
        }
        None => {}
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

/// Checks that an `EXT_meshopt_compression` view's compressed bytes lie inside the BIN chunk and
/// decode to exactly the view, within the budget of decoded bytes.
fn decode_view(
    view: &gltf::buffer::View<'_>,
    compressed: &serde_json::Value,
    bin: &[u8],
    budget: &mut usize,
) -> Result<(), String> {
    let at = view.index();
    let field = |key: &str| -> Result<usize, String> {
        let value = compressed.get(key).and_then(serde_json::Value::as_u64);
        let value = if key == "byteOffset" { Some(value.unwrap_or(0)) } else { value };
        value
            .and_then(|v| usize::try_from(v).ok())
            .ok_or_else(|| format!("buffer view {at}: {EXT_MESHOPT_COMPRESSION} has no {key}"))
    };
    let (buffer, offset, length) = (field("buffer")?, field("byteOffset")?, field("byteLength")?);
    let (stride, count) = (field("byteStride")?, field("count")?);
    let mode = compressed.get("mode").and_then(serde_json::Value::as_str).unwrap_or_default();
    let filter = compressed.get("filter").and_then(serde_json::Value::as_str).unwrap_or("NONE");
    let data = offset
        .checked_add(length)
        .filter(|_| buffer == 0)
        .and_then(|end| bin.get(offset..end))
        .ok_or_else(|| {
            format!("buffer view {at}: its compressed bytes are not inside the GLB's BIN chunk")
        })?;
    let decoded = stride.checked_mul(count).filter(|&n| n == view.length()).ok_or_else(|| {
        format!(
            "buffer view {at}: {count} elements of {stride} bytes are not its {} bytes",
            view.length()
        )
    })?;
    if view.stride().is_some_and(|s| s != stride) {
        return Err(format!("buffer view {at}: byteStride differs from the compressed one"));
    }
    // The codecs' smallest streams: two header bits per 16 bytes of vertices, one byte per
    // triangle. A claim beyond that cannot be in the file.
    let bound = match mode {
        "TRIANGLES" => length.saturating_mul(3).saturating_mul(stride),
        _ => length.saturating_mul(64),
    };
    if decoded > bound {
        return Err(format!(
            "buffer view {at}: {length} compressed bytes cannot hold {decoded} bytes"
        ));
    }
    *budget = budget.checked_sub(decoded).ok_or_else(|| {
        format!(
            "buffer view {at}: the compressed views decode to more than {max} bytes in all",
            max = decoded + *budget
        )
    })?;
    let header = data.first().copied();
    let ok = match (mode, stride, filter, header) {
        ("ATTRIBUTES", 12, "NONE", Some(0xa0)) => {
            meshopt::decode_vertex_buffer::<[u8; 12]>(data, count).is_ok()
        }
        ("TRIANGLES", 2 | 4, "NONE", Some(0xe1)) if count % 3 == 0 => {
            if stride == 2 {
                meshopt::decode_index_buffer::<u16>(data, count).is_ok()
            } else {
                meshopt::decode_index_buffer::<u32>(data, count).is_ok()
            }
        }
        _ => {
            return Err(format!(
                "buffer view {at}: {mode} of {stride}-byte elements (filter {filter}) is not a \
                 layout penmesh writes (12-byte vertices, 2- or 4-byte triangle indices)"
            ));
        }
    };
    if !ok {
        return Err(format!(
            "buffer view {at}: its compressed bytes do not decode to {count} elements"
        ));
    }
    Ok(())
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
    use penmesh::{GlbEncoding, GlbOptions};
    use serde_json::Value;

    /// The proxy's default body limit.
    const LIMIT: usize = 16 << 20;

    /// A penmesh stroke's GLB in `encoding`, and its mesh's counts.
    fn penmesh_glb(encoding: GlbEncoding) -> (Vec<u8>, MeshCounts) {
        let samples: Vec<penmesh::Sample> = (0..80)
            .map(|i| {
                let a = f64::from(i) * 0.1;
                penmesh::Sample::new(
                    40.0 * a.cos() + f64::from(i),
                    30.0 * a.sin(),
                    f64::from(i),
                    0.6,
                )
            })
            .collect();
        let brush = penmesh::Brush::default();
        let mesh = penmesh::stroke_mesh(
            &samples,
            &brush,
            &penmesh::OutlineOptions::default(),
            &penmesh::SolidOptions::default(),
        );
        let meta = penmesh::GlbMeta { stroke: uuid::Uuid::nil(), author: "ada".into(), brush };
        let glb = penmesh::stroke_glb(&mesh, &meta, &GlbOptions::default().encoding(encoding));
        let stats = mesh.stats();
        (glb, MeshCounts { vertices: stats.vertices as u64, triangles: stats.triangles as u64 })
    }

    /// `glb` with its JSON changed by `change` (the BIN chunk kept).
    fn with_json(glb: &[u8], change: impl FnOnce(&mut Value)) -> Vec<u8> {
        let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        let mut json: Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
        change(&mut json);
        let mut json = serde_json::to_vec(&json).unwrap();
        json.resize(json.len().next_multiple_of(4), b' ');
        let bin = &glb[20 + json_len..];
        let mut out = glb[..8].to_vec();
        out.extend(((20 + json.len() + bin.len()) as u32).to_le_bytes());
        out.extend((json.len() as u32).to_le_bytes());
        out.extend(0x4E4F_534Au32.to_le_bytes());
        out.extend(json);
        out.extend(bin);
        out
    }

    #[test]
    fn accepts_and_counts_what_penmesh_writes_in_every_encoding() {
        // Plain, KHR_mesh_quantization, and EXT_meshopt_compression over it (both required):
        // accepted, with the mesh's own counts.
        for encoding in [GlbEncoding::Plain, GlbEncoding::Quantized, GlbEncoding::Meshopt] {
            let (glb, counts) = penmesh_glb(encoding);
            assert_eq!(inspect(&glb, LIMIT), Ok(counts), "{encoding:?}");
        }
    }

    #[test]
    fn refuses_a_required_extension_penmesh_does_not_write() {
        // Named in the error; the same file without it is accepted.
        let (glb, _) = penmesh_glb(GlbEncoding::Meshopt);
        let draco = with_json(&glb, |json| {
            for list in ["extensionsUsed", "extensionsRequired"] {
                json[list].as_array_mut().unwrap().push("KHR_draco_mesh_compression".into());
            }
        });
        let err = inspect(&draco, LIMIT).unwrap_err();
        assert!(err.contains("KHR_draco_mesh_compression"), "{err}");
        assert!(inspect(&glb, LIMIT).is_ok());
    }

    #[test]
    fn compressed_views_must_decode_to_what_they_claim() {
        let (glb, _) = penmesh_glb(GlbEncoding::Meshopt);
        let view = |json: &mut Value, k: usize| -> Value {
            json["bufferViews"][k]["extensions"][EXT_MESHOPT_COMPRESSION].take()
        };
        // A count the compressed bytes cannot hold, with the view and accessor to match.
        let inflated = with_json(&glb, |json| {
            let mut ext = view(json, 0);
            ext["count"] = Value::from(10_000_000u64);
            json["bufferViews"][0]["byteLength"] = Value::from(120_000_000u64);
            json["bufferViews"][0]["extensions"][EXT_MESHOPT_COMPRESSION] = ext;
            json["buffers"][1]["byteLength"] = Value::from(130_000_000u64);
            json["accessors"][0]["count"] = Value::from(10_000_000u64);
        });
        let err = inspect(&inflated, LIMIT).unwrap_err();
        assert!(err.contains("cannot hold"), "{err}");
        // Compressed bytes that do not decode (the vertex stream cut short by one byte).
        let cut = with_json(&glb, |json| {
            let mut ext = view(json, 0);
            ext["byteLength"] = Value::from(ext["byteLength"].as_u64().unwrap() - 1);
            json["bufferViews"][0]["extensions"][EXT_MESHOPT_COMPRESSION] = ext;
        });
        let err = inspect(&cut, LIMIT).unwrap_err();
        assert!(err.contains("do not decode"), "{err}");
        // Bytes outside the BIN chunk.
        let outside = with_json(&glb, |json| {
            let mut ext = view(json, 1);
            ext["byteOffset"] = Value::from(1u64 << 20);
            json["bufferViews"][1]["extensions"][EXT_MESHOPT_COMPRESSION] = ext;
        });
        let err = inspect(&outside, LIMIT).unwrap_err();
        assert!(err.contains("not inside the GLB's BIN chunk"), "{err}");
        // The compression used without being declared.
        let undeclared = with_json(&glb, |json| {
            for list in ["extensionsUsed", "extensionsRequired"] {
                json[list] = Value::from(vec![KHR_MESH_QUANTIZATION]);
            }
        });
        let err = inspect(&undeclared, LIMIT).unwrap_err();
        assert!(err.contains("does not declare"), "{err}");
        // More decoded bytes than the limit.
        let err = inspect(&glb, 100).unwrap_err();
        assert!(err.contains("more than"), "{err}");
    }

    #[test]
    fn counts_vertices_and_triangles() {
        assert_eq!(
            inspect(&tiny_glb(8, 36), LIMIT).unwrap(),
            MeshCounts { vertices: 8, triangles: 12 }
        );
    }

    #[test]
    fn refuses_broken_containers() {
        let good = tiny_glb(3, 3);
        let mut bad_magic = good.clone();
        bad_magic[0] = b'x';
        assert!(inspect(&bad_magic, LIMIT).unwrap_err().contains("magic"));
        let mut bad_version = good.clone();
        bad_version[4] = 1;
        assert!(inspect(&bad_version, LIMIT).unwrap_err().contains("version"));
        let mut truncated = good.clone();
        truncated.pop();
        assert!(inspect(&truncated, LIMIT).is_err());
    }

    #[test]
    fn counts_the_data_does_not_back_are_refused() {
        // A small file that claims far more elements than it carries, up to counts whose
        // sizes overflow.
        for (vertices, indices, bin_len) in
            [(1000, 3, 48), (3, 3_000_000, 48), (u64::MAX / 4, 3, 48)]
        {
            let err = inspect(&glb_with(vertices, indices, bin_len), LIMIT).unwrap_err();
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
        let err = inspect(&glb, LIMIT).unwrap_err();
        assert!(err.contains("bufferView") || err.contains("no buffer view"), "{err}");
    }
}
