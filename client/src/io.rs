//! Reading and writing files for the commands, with errors that name the file.

use std::path::Path;

use anyhow::Context;
use penmesh::Stroke;

/// Reads every stroke of a CSV, JSON, SVC2004 (`.txt`) or SigComp2011 (`.hwr`) file.
pub fn read_strokes(path: &Path) -> anyhow::Result<Vec<Stroke>> {
    let text = fs_err::read_to_string(path)?;
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
    let strokes =
        penmesh::read_strokes(name, &text).with_context(|| format!("{}", path.display()))?;
    anyhow::ensure!(!strokes.is_empty(), "{}: no strokes in the file", path.display());
    Ok(strokes)
}

/// Writes `bytes` to `path`, naming the file on failure.
pub fn write_file(path: &Path, bytes: impl AsRef<[u8]>) -> anyhow::Result<()> {
    Ok(fs_err::write(path, bytes)?)
}
