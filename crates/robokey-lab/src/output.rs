//! Output folders: made ready for a command's files (never emptying a folder that is not
//! robokey's output), and files written with their path in errors.

use std::path::{Path, PathBuf};

use crate::error::{LabError, io_at};

/// Files by which a folder is recognised as robokey's output (at its top, or in a
/// subfolder of a suite).
const OUTPUT_MARKERS: [&str; 5] = [
    "manifest.json",
    "config.resolved.toml",
    "report.md",
    "metrics.json",
    "secrecy.json",
];

/// Whether `dir` holds robokey's output: a marker file at its top or one level down.
fn is_robokey_output(dir: &Path) -> bool {
    let has_marker = |d: &Path| OUTPUT_MARKERS.iter().any(|m| d.join(m).is_file());
    has_marker(dir)
        || dir.read_dir().is_ok_and(|entries| {
            entries
                .flatten()
                .any(|e| e.path().is_dir() && has_marker(&e.path()))
        })
}

/// Prepares an output folder: creates it; a non-empty one is refused, or with `force`
/// emptied first — so no stale file of an earlier run survives beside the new ones — but
/// only if it holds robokey's output (never an arbitrary folder).
///
/// # Errors
/// The folder is not empty (without `force`), is not robokey's output (with `force`), or
/// cannot be emptied or created.
pub fn prepare_output(dir: &Path, force: bool) -> Result<(), LabError> {
    let non_empty = dir
        .read_dir()
        .is_ok_and(|mut entries| entries.next().is_some());
    if non_empty {
        if !force {
            return Err(LabError::NotEmpty(dir.to_path_buf()));
        }
        if !is_robokey_output(dir) {
            return Err(LabError::NotOutput(dir.to_path_buf()));
        }
        std::fs::remove_dir_all(dir).map_err(io_at(dir))?;
    }
    std::fs::create_dir_all(dir).map_err(io_at(dir))
}

/// Writes a file, naming it in the error.
///
/// # Errors
/// The file cannot be written.
pub fn write(path: &Path, contents: impl AsRef<[u8]>) -> Result<PathBuf, LabError> {
    std::fs::write(path, contents).map_err(io_at(path))?;
    Ok(path.to_path_buf())
}

/// Reads a file, naming it in the error.
///
/// # Errors
/// The file cannot be read (or is not UTF-8).
pub fn read(path: &Path) -> Result<String, LabError> {
    std::fs::read_to_string(path).map_err(io_at(path))
}

/// Reads a JSON file robokey wrote.
///
/// # Errors
/// The file cannot be read, or does not hold what `T` is.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, LabError> {
    serde_json::from_str(&read(path)?).map_err(|e| LabError::Malformed {
        place: path.display().to_string(),
        message: e.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn force_empties_robokey_output_and_nothing_else() {
        let dir = std::env::temp_dir().join(format!("robokey-files-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("point")).unwrap();
        std::fs::write(dir.join("point/manifest.json"), "{}").unwrap();
        std::fs::write(dir.join("stale.csv"), "old").unwrap();
        assert!(matches!(
            prepare_output(&dir, false),
            Err(LabError::NotEmpty(_))
        ));
        prepare_output(&dir, true).unwrap();
        assert!(
            dir.read_dir().unwrap().next().is_none(),
            "stale files survived"
        );
        std::fs::write(dir.join("thesis.tex"), "precious").unwrap();
        assert!(matches!(
            prepare_output(&dir, true),
            Err(LabError::NotOutput(_))
        ));
        assert!(dir.join("thesis.tex").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
