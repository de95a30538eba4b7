//! The recorded pen data sets that the tests, the benches and `penmesh-lab eval` read in place:
//! SigComp2011 Dutch (`sigcomp2011_dutch/*.hwr`) and SVC2004 (`svc2004/*.TXT`), in
//! `../shared/data` beside the checkout, or wherever [`DATA_ENV`] points. They are never copied
//! into the repository. This is the one place that knows where they are and their tablet scale.

use std::path::{Path, PathBuf};

use crate::formats::{FormatError, read_strokes};
use crate::model::Stroke;

/// The environment variable that overrides where the data sets are.
pub const DATA_ENV: &str = "PENMESH_DATA";
/// Px per SVC2004 tablet unit (2540 lines per inch, at 96 px per inch).
pub const SVC2004_PX_PER_UNIT: f64 = 96.0 / 2540.0;
/// Px per SigComp2011 tablet unit (5080 lines per inch, at 96 px per inch).
pub const SIGCOMP2011_PX_PER_UNIT: f64 = 96.0 / 5080.0;

/// One recorded data set: its folder under [`data_root`], its files' extension and its scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DataSet {
    pub folder: &'static str,
    pub extension: &'static str,
    pub px_per_unit: f64,
}

pub const SIGCOMP2011_DUTCH: DataSet =
    DataSet { folder: "sigcomp2011_dutch", extension: "hwr", px_per_unit: SIGCOMP2011_PX_PER_UNIT };
pub const SVC2004: DataSet =
    DataSet { folder: "svc2004", extension: "TXT", px_per_unit: SVC2004_PX_PER_UNIT };
/// Every data set, SigComp2011 first.
pub const DATA_SETS: [DataSet; 2] = [SIGCOMP2011_DUTCH, SVC2004];

/// Where the data sets are: `$PENMESH_DATA`, else `../shared/data` beside the checkout (found
/// from this crate's source folder, so it serves tests and benches of every crate).
pub fn data_root() -> PathBuf {
    std::env::var_os(DATA_ENV)
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"))
}

/// The data set a tablet file belongs to, by its extension (`.hwr`, `.txt`, any case).
pub fn data_set_of(path: &Path) -> Option<DataSet> {
    let extension = path.extension().and_then(|e| e.to_str()).unwrap_or_default();
    DATA_SETS.into_iter().find(|set| set.extension.eq_ignore_ascii_case(extension))
}

/// Px per unit of a file: its data set's tablet scale, or 1 for a file in px (CSV, JSON).
pub fn px_per_unit(path: &Path) -> f64 {
    data_set_of(path).map_or(1.0, |set| set.px_per_unit)
}

/// One recording: its path, its text and its strokes in tablet units.
#[derive(Debug, Clone)]
pub struct Recording {
    pub path: PathBuf,
    pub text: String,
    pub strokes: Vec<Stroke>,
}

impl Recording {
    /// The file's name, e.g. `002_177_02.hwr`.
    pub fn name(&self) -> String {
        self.path.file_name().unwrap_or_default().to_string_lossy().into_owned()
    }
}

/// A data set that cannot be read, naming the folder or file.
#[derive(Debug, thiserror::Error)]
pub enum DataSetError {
    #[error("cannot list the data set {}: {source} (the data sets are read from ../shared/data beside the checkout, or ${DATA_ENV})", .dir.display())]
    List { dir: PathBuf, source: std::io::Error },
    #[error("cannot read {}: {source}", .path.display())]
    Read { path: PathBuf, source: std::io::Error },
    #[error("{}: {source}", .path.display())]
    Format { path: PathBuf, source: FormatError },
}

impl DataSet {
    /// The set's folder.
    pub fn dir(&self) -> PathBuf {
        data_root().join(self.folder)
    }

    /// The set's recordings' paths, sorted by name.
    pub fn files(&self) -> Result<Vec<PathBuf>, DataSetError> {
        let dir = self.dir();
        let list = |source| DataSetError::List { dir: dir.clone(), source };
        let mut files = Vec::new();
        for entry in std::fs::read_dir(&dir).map_err(list)? {
            let path = entry.map_err(list)?.path();
            let extension = path.extension().and_then(|e| e.to_str()).unwrap_or_default();
            if extension.eq_ignore_ascii_case(self.extension) {
                files.push(path);
            }
        }
        files.sort();
        Ok(files)
    }

    /// Every recording of the set, read with [`read_strokes`], sorted by name.
    pub fn read(&self) -> Result<Vec<Recording>, DataSetError> {
        self.files()?
            .into_iter()
            .map(|path| {
                let text = std::fs::read_to_string(&path)
                    .map_err(|source| DataSetError::Read { path: path.clone(), source })?;
                let name = path.file_name().unwrap_or_default().to_string_lossy().to_lowercase();
                let strokes = read_strokes(&name, &text)
                    .map_err(|source| DataSetError::Format { path: path.clone(), source })?;
                Ok(Recording { path, text, strokes })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tablet_file_is_scaled_by_its_extension_and_any_other_file_is_not() {
        assert_eq!(px_per_unit(Path::new("a/002_177_02.hwr")), SIGCOMP2011_PX_PER_UNIT);
        assert_eq!(px_per_unit(Path::new("U1S1.TXT")), SVC2004_PX_PER_UNIT);
        assert_eq!(px_per_unit(Path::new("u1s1.txt")), SVC2004_PX_PER_UNIT);
        assert_eq!(px_per_unit(Path::new("stroke.csv")), 1.0);
    }

    #[test]
    fn a_missing_folder_is_an_error_that_names_it() {
        let set = DataSet { folder: "no_such_set", extension: "hwr", px_per_unit: 1.0 };
        let message = set.files().unwrap_err().to_string();
        assert!(message.contains("no_such_set"), "{message}");
    }
}
