//! Reading a scene back, for an import: every node's pen data and placement.

use serde_json::Value;

use super::container::{node_matrix, parse_glb};
use super::{EXTRAS_KEY, ReadStroke, SCENE_FORMAT_VERSION, SceneError, StrokeExtras};

/// Reads every stroke of a scene [`scene_glb`] wrote (or another tool edited): each node with
/// `extras.penmesh`, in node order, with its node's own transform as its placement.
pub fn read_scene(bytes: &[u8]) -> Result<Vec<ReadStroke>, SceneError> {
    let (json, _) = parse_glb(bytes)?;
    let nodes = json.get("nodes").and_then(Value::as_array).map(Vec::as_slice).unwrap_or(&[]);
    let mut strokes = Vec::new();
    for (index, node) in nodes.iter().enumerate() {
        let Some(data) = node.get("extras").and_then(|e| e.get(EXTRAS_KEY)) else {
            continue;
        };
        let bad = |why: String| SceneError::BadExtras {
            node: index,
            name: node
                .get("name")
                .and_then(Value::as_str)
                .map(|n| format!(" ({n:?})"))
                .unwrap_or_default(),
            why,
        };
        let format = data.get("format").and_then(Value::as_u64);
        if format != Some(u64::from(SCENE_FORMAT_VERSION)) {
            return Err(bad(format!(
                "format {}, this penmesh reads format {SCENE_FORMAT_VERSION}",
                data.get("format").map(Value::to_string).unwrap_or_else(|| "missing".into())
            )));
        }
        let extras: StrokeExtras =
            serde_json::from_value(data.clone()).map_err(|e| bad(e.to_string()))?;
        strokes.push(ReadStroke { node: index, extras, placement: node_matrix(node, index)? });
    }
    if strokes.is_empty() {
        return Err(SceneError::NoStrokes);
    }
    Ok(strokes)
}
