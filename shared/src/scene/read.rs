//! Reading a scene back, for an import: every node's pen data and placement. The document is
//! read node by node, each node's pen data made into a [`StrokeExtras`] as soon as it is read,
//! so that the file's samples are never one `serde_json::Value` tree (about seven times their
//! text, and twice that with a copy); the rest of the document is skipped unread.

use std::fmt;

use serde::de::{DeserializeSeed, Deserializer, IgnoredAny, SeqAccess, Visitor};
use serde_json::{Map, Value};

use super::container::{glb_chunks, json_error, node_matrix};
use super::{EXTRAS_KEY, ReadStroke, SCENE_FORMAT_VERSION, SceneError, StrokeExtras};

/// Reads every stroke of a scene [`scene_glb`] wrote (or another tool edited): each node with
/// `extras.penmesh`, in node order, with its node's own transform as its placement.
pub fn read_scene(bytes: &[u8]) -> Result<Vec<ReadStroke>, SceneError> {
    let (json_chunk, _) = glb_chunks(bytes)?;
    let mut read = Read { strokes: Vec::new(), failed: None };
    let mut document = serde_json::Deserializer::from_slice(json_chunk);
    Document(&mut read).deserialize(&mut document).map_err(json_error)?;
    document.end().map_err(json_error)?;
    if let Some(err) = read.failed {
        return Err(err);
    }
    if read.strokes.is_empty() {
        return Err(SceneError::NoStrokes);
    }
    Ok(read.strokes)
}

/// What the nodes read so far hold: their strokes, or the first node that failed (the nodes
/// after it are skipped).
struct Read {
    strokes: Vec<ReadStroke>,
    failed: Option<SceneError>,
}

impl Read {
    /// The `index`th node, read whole (one node: at most one stroke's samples).
    fn node(&mut self, index: usize, node: Map<String, Value>) {
        let mut node = Value::Object(node);
        let Some(data) = node.get_mut("extras").and_then(|e| e.get_mut(EXTRAS_KEY)) else {
            return;
        };
        let data = data.take();
        let name = node.get("name").and_then(Value::as_str).map(|n| format!(" ({n:?})"));
        let bad = |why: String| SceneError::BadExtras {
            node: index,
            name: name.clone().unwrap_or_default(),
            why,
        };
        let format = data.get("format").and_then(Value::as_u64);
        if format != Some(u64::from(SCENE_FORMAT_VERSION)) {
            self.failed = Some(bad(format!(
                "format {}, this penmesh reads format {SCENE_FORMAT_VERSION}",
                data.get("format").map(Value::to_string).unwrap_or_else(|| "missing".into())
            )));
            return;
        }
        let extras = match serde_json::from_value::<StrokeExtras>(data) {
            Ok(extras) => extras,
            Err(e) => return self.failed = Some(bad(e.to_string())),
        };
        match node_matrix(&node, index) {
            Ok(placement) => self.strokes.push(ReadStroke { node: index, extras, placement }),
            Err(err) => self.failed = Some(err),
        }
    }
}

/// The glTF document: its `nodes` read one at a time into [`Read`], every other member
/// skipped.
struct Document<'a>(&'a mut Read);

impl<'de> DeserializeSeed<'de> for Document<'_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, deserializer: D) -> Result<(), D::Error> {
        deserializer.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for Document<'_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a glTF object")
    }

    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        while let Some(key) = map.next_key::<String>()? {
            if key == "nodes" {
                map.next_value_seed(Nodes(&mut *self.0))?;
            } else {
                map.next_value::<IgnoredAny>()?;
            }
        }
        Ok(())
    }
}

/// The document's `nodes`, each read and made into a stroke before the next is read.
struct Nodes<'a>(&'a mut Read);

impl<'de> DeserializeSeed<'de> for Nodes<'_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, deserializer: D) -> Result<(), D::Error> {
        deserializer.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for Nodes<'_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a list of glTF nodes")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let mut index = 0;
        while self.0.failed.is_none() {
            // A node that is not an object is none of penmesh's.
            let Some(node) = seq.next_element::<Value>()? else { return Ok(()) };
            if let Value::Object(node) = node {
                self.0.node(index, node);
            }
            index += 1;
        }
        while seq.next_element::<IgnoredAny>()?.is_some() {}
        Ok(())
    }
}
