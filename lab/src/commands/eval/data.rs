//! The data sets: tablet files under the inputs, in px, and the generated strokes.

use super::*;

/// One file's strokes, in px.
#[derive(Debug)]
pub struct DataFile {
    pub name: String,
    pub strokes: Vec<Vec<Sample>>,
}

/// A named collection of files.
#[derive(Debug)]
pub struct DataSet {
    pub name: String,
    pub files: Vec<DataFile>,
}

impl DataSet {
    pub(super) fn strokes(&self) -> impl Iterator<Item = &[Sample]> + '_ {
        self.files.iter().flat_map(|f| f.strokes.iter().map(Vec::as_slice))
    }

    pub(super) fn n_strokes(&self) -> usize {
        self.files.iter().map(|f| f.strokes.len()).sum()
    }
}

/// Reads every file under the inputs, grouped into data sets by their folder's name.
pub fn load_data_sets(
    inputs: &[PathBuf],
    px_per_unit: Option<f64>,
) -> anyhow::Result<Vec<DataSet>> {
    let mut files = Vec::new();
    for input in inputs {
        collect_files(input, &mut files)?;
    }
    files.sort();
    files.dedup();
    let mut by_folder: BTreeMap<String, Vec<DataFile>> = BTreeMap::new();
    for path in files {
        let folder = path
            .parent()
            .and_then(|p| p.file_name())
            .and_then(|n| n.to_str())
            .unwrap_or("data")
            .to_string();
        // A tablet file is scaled to px (by --px-per-unit, else by its data set); others are px.
        let scale = penmesh::data_sets::data_set_of(&path)
            .map_or(1.0, |set| px_per_unit.unwrap_or(set.px_per_unit));
        let strokes = io::read_strokes(&path)?
            .into_iter()
            .map(|stroke| {
                stroke
                    .samples()
                    .iter()
                    .map(|s| Sample::new(s.x * scale, s.y * scale, s.t, s.p))
                    .collect()
            })
            .collect();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default().to_string();
        by_folder.entry(folder).or_default().push(DataFile { name, strokes });
    }
    Ok(by_folder.into_iter().map(|(name, files)| DataSet { name, files }).collect())
}

pub(super) fn extension(path: &Path) -> String {
    path.extension().and_then(|e| e.to_str()).unwrap_or_default().to_ascii_lowercase()
}

pub(super) fn collect_files(path: &Path, out: &mut Vec<PathBuf>) -> anyhow::Result<()> {
    if path.is_dir() {
        let entries = fs_err::read_dir(path)?;
        for entry in entries {
            let entry = entry.with_context(|| format!("cannot list {}", path.display()))?;
            let child = entry.path();
            if child.is_dir() || ["txt", "hwr", "csv", "json"].contains(&extension(&child).as_str())
            {
                collect_files(&child, out)?;
            }
        }
    } else {
        out.push(path.to_path_buf());
    }
    Ok(())
}

/// The generated strokes: the five shapes at 200, 300, 400 and 500 px/s, two seeds each.
pub fn synthetic_data_set() -> anyhow::Result<DataSet> {
    let mut files = Vec::new();
    for shape in penmesh::Shape::ALL {
        for speed in [200.0, 300.0, 400.0, 500.0] {
            for seed in 0..2 {
                let params = penmesh::GeneratorParams {
                    shape,
                    speed,
                    seed,
                    ..penmesh::GeneratorParams::default()
                };
                let stroke = penmesh::generate_stroke(&params)
                    .map_err(|e| anyhow::anyhow!("generator: {e}"))?;
                files.push(DataFile {
                    name: format!("{shape}-{speed}-{seed}"),
                    strokes: vec![stroke.into_samples()],
                });
            }
        }
    }
    Ok(DataSet { name: "synthetic".into(), files })
}
