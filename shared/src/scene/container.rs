//! The GLB container, as the scene's writer and reader both read it: the JSON document and the
//! binary chunk of a file, and a node's local transform.

use serde_json::Value;

use super::SceneError;
use crate::glb::{CHUNK_BIN, CHUNK_JSON, GLB_MAGIC};
use crate::placement::IDENTITY_MATRIX;

/// A node's local transform, column-major: its `matrix`, or its translation, rotation and
/// scale composed (`T · R · S`), or the identity.
pub(super) fn node_matrix(node: &Value, index: usize) -> Result<[f64; 16], SceneError> {
    let bad = |why: String| SceneError::BadTransform { node: index, why };
    let numbers = |key: &str, n: usize| -> Result<Option<Vec<f64>>, SceneError> {
        match node.get(key) {
            None => Ok(None),
            Some(Value::Array(items)) if items.len() == n => items
                .iter()
                .map(|v| v.as_f64().ok_or_else(|| bad(format!("{key} holds {v}, not a number"))))
                .collect::<Result<Vec<_>, _>>()
                .map(Some),
            Some(other) => Err(bad(format!("{key} is {other}, not {n} numbers"))),
        }
    };
    if let Some(m) = numbers("matrix", 16)? {
        return Ok(m.try_into().expect("16 numbers"));
    }
    let t = numbers("translation", 3)?.unwrap_or_else(|| vec![0.0; 3]);
    let r = numbers("rotation", 4)?.unwrap_or_else(|| vec![0.0, 0.0, 0.0, 1.0]);
    let s = numbers("scale", 3)?.unwrap_or_else(|| vec![1.0; 3]);
    let (x, y, z, w) = (r[0], r[1], r[2], r[3]);
    let rotation = [
        1.0 - 2.0 * (y * y + z * z),
        2.0 * (x * y + z * w),
        2.0 * (x * z - y * w),
        2.0 * (x * y - z * w),
        1.0 - 2.0 * (x * x + z * z),
        2.0 * (y * z + x * w),
        2.0 * (x * z + y * w),
        2.0 * (y * z - x * w),
        1.0 - 2.0 * (x * x + y * y),
    ];
    let mut m = IDENTITY_MATRIX;
    for col in 0..3 {
        for row in 0..3 {
            m[4 * col + row] = rotation[3 * col + row] * s[col];
        }
        m[12 + col] = t[col];
    }
    Ok(m)
}

/// A GLB's JSON document and its binary chunk (empty when it has none).
pub(super) fn parse_glb(bytes: &[u8]) -> Result<(Value, &[u8]), SceneError> {
    let (json_chunk, bin) = glb_chunks(bytes)?;
    let json: Value = serde_json::from_slice(json_chunk).map_err(json_error)?;
    if !json.is_object() {
        return Err(SceneError::NotGlb("its JSON chunk is not a glTF object".into()));
    }
    Ok((json, bin))
}

/// Why a GLB's JSON chunk could not be read.
pub(super) fn json_error(e: serde_json::Error) -> SceneError {
    match e.classify() {
        serde_json::error::Category::Data => {
            SceneError::NotGlb(format!("its JSON chunk is not a glTF object: {e}"))
        }
        _ => SceneError::NotGlb(format!("its JSON chunk is not JSON: {e}")),
    }
}

/// A GLB's JSON chunk, unread, and its binary chunk (empty when it has none).
pub(super) fn glb_chunks(bytes: &[u8]) -> Result<(&[u8], &[u8]), SceneError> {
    let word = |at: usize| {
        bytes.get(at..at + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
    };
    if bytes.len() < 12 {
        return Err(SceneError::Truncated(format!(
            "{} bytes, less than a GLB's 12-byte header",
            bytes.len()
        )));
    }
    if &bytes[0..4] != GLB_MAGIC {
        return Err(SceneError::NotGlb("it does not start with 'glTF'".into()));
    }
    if word(4) != Some(2) {
        return Err(SceneError::NotGlb(format!("version {:?}, not 2", word(4).unwrap_or(0))));
    }
    let declared = word(8).unwrap_or(0);
    if declared > bytes.len() {
        return Err(SceneError::Truncated(format!(
            "its header says {declared} bytes, the file has {}",
            bytes.len()
        )));
    }
    if declared < bytes.len() {
        return Err(SceneError::NotGlb(format!(
            "its header says {declared} bytes, the file has {} (bytes after its end)",
            bytes.len()
        )));
    }
    let chunk = |at: usize, kind: u32, what: &str| -> Result<Option<&[u8]>, SceneError> {
        if at == bytes.len() {
            return Ok(None);
        }
        let (Some(length), Some(found)) = (word(at), word(at + 4)) else {
            return Err(SceneError::Truncated(format!("the {what} chunk's header is cut off")));
        };
        if found != kind as usize {
            return Err(SceneError::NotGlb(format!("the {what} chunk has type {found:#x}")));
        }
        let body = bytes.get(at + 8..at + 8 + length).ok_or_else(|| {
            SceneError::Truncated(format!(
                "the {what} chunk says {length} bytes, {} are left",
                bytes.len().saturating_sub(at + 8)
            ))
        })?;
        Ok(Some(body))
    };
    let json_chunk = chunk(12, CHUNK_JSON, "JSON")?
        .ok_or_else(|| SceneError::Truncated("it has no JSON chunk".into()))?;
    let bin = chunk(12 + 8 + json_chunk.len(), CHUNK_BIN, "BIN")?.unwrap_or_default();
    Ok((json_chunk, bin))
}
