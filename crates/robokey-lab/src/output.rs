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

/// The names of the files robokey writes into its output folders, at any depth.
const OUTPUT_FILES: [&str; 23] = [
    "manifest.json",
    "config.resolved.toml",
    "report.md",
    "metrics.json",
    "secrecy.json",
    "secrecy.csv",
    "secrecy.parquet",
    "secrecy.md",
    "private-map.json",
    "turn-rates.csv",
    "runs.csv",
    "runs.parquet",
    "summary.json",
    "periods.csv",
    "sessions.csv",
    "campaigns.csv",
    "campaign.json",
    "reproduce.json",
    "trace.csv",
    "trace.parquet",
    "eve.json",
    "eve.md",
    "capture.json",
];

/// The figures robokey draws outside a `figures` folder, by base name.
const FIGURES: [&str; 8] = [
    "trajectory",
    "secrecy-bits-per-step",
    "private-rate-vs-camera",
    "private-pareto",
    "private-leak",
    "eve-error-rate",
    "eve-excess-error",
    "eve-parameters",
];

/// What a figure is written as: its drawings and its data.
const FIGURE_EXTENSIONS: [&str; 4] = ["svg", "png", "pdf", "csv"];

/// Whether robokey writes a file at `relative` (a path inside an output folder): one of
/// its file names, a figure (in a `figures` folder, or by its name), or a trace
/// (`traces/point-N.csv` or `.parquet`). Anything else is someone else's.
fn written_by_robokey(relative: &Path) -> bool {
    let Some(name) = relative.file_name().and_then(|n| n.to_str()) else {
        return false;
    };
    if OUTPUT_FILES.contains(&name) {
        return true;
    }
    let Some((stem, extension)) = name.rsplit_once('.') else {
        return false;
    };
    let folder = relative
        .parent()
        .and_then(Path::file_name)
        .and_then(|n| n.to_str());
    let trace = folder == Some("traces")
        && (extension == "csv" || extension == "parquet")
        && stem
            .strip_prefix("point-")
            .is_some_and(|n| n.parse::<usize>().is_ok());
    trace
        || (FIGURE_EXTENSIONS.contains(&extension)
            && (folder == Some("figures") || FIGURES.contains(&stem)))
}

/// Removes robokey's files under `dir` (`relative` from the output folder), then the
/// folders that leaves empty; returns what it kept (relative paths): files, and folders
/// that were empty already.
fn remove_robokey_files(dir: &Path, relative: &Path) -> Result<Vec<PathBuf>, LabError> {
    let mut kept = Vec::new();
    let mut entries: Vec<PathBuf> = dir
        .read_dir()
        .map_err(io_at(dir))?
        .map(|e| e.map(|e| e.path()).map_err(io_at(dir)))
        .collect::<Result<_, _>>()?;
    entries.sort();
    for path in entries {
        let name = relative.join(path.file_name().unwrap_or_default());
        if path.is_dir() && !path.is_symlink() {
            let was_empty = path.read_dir().map_err(io_at(&path))?.next().is_none();
            let inside = remove_robokey_files(&path, &name)?;
            if was_empty {
                kept.push(name);
            } else if inside.is_empty() {
                std::fs::remove_dir(&path).map_err(io_at(&path))?;
            }
            kept.extend(inside);
        } else if written_by_robokey(&name) {
            std::fs::remove_file(&path).map_err(io_at(&path))?;
        } else {
            kept.push(name);
        }
    }
    Ok(kept)
}

/// Prepares an output folder: creates it; a non-empty one is refused, or with `force`
/// rid of robokey's files — so no stale file of an earlier run survives beside the new
/// ones — but only if it holds robokey's output (never an arbitrary folder). Files robokey
/// does not write (by name: a figure, a trace, one of its data files) are kept: returned,
/// as paths relative to `dir`, for the command to say so.
///
/// # Errors
/// The folder is not empty (without `force`), is not robokey's output (with `force`), or
/// cannot be cleared or created.
pub fn prepare_output(dir: &Path, force: bool) -> Result<Vec<PathBuf>, LabError> {
    let non_empty = dir
        .read_dir()
        .is_ok_and(|mut entries| entries.next().is_some());
    let mut kept = Vec::new();
    if non_empty {
        if !force {
            return Err(LabError::NotEmpty(dir.to_path_buf()));
        }
        if !is_robokey_output(dir) {
            return Err(LabError::NotOutput(dir.to_path_buf()));
        }
        kept = remove_robokey_files(dir, Path::new(""))?;
    }
    std::fs::create_dir_all(dir).map_err(io_at(dir))?;
    Ok(kept)
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
    fn force_removes_robokey_files_and_keeps_everything_else() {
        let dir = std::env::temp_dir().join(format!("robokey-files-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        for folder in ["point/traces", "figures", "notes", "empty"] {
            std::fs::create_dir_all(dir.join(folder)).unwrap();
        }
        let robokey = [
            "point/manifest.json",
            "point/runs.csv",
            "point/traces/point-3.csv",
            "point/traces/point-4.parquet",
            "point/runs.parquet",
            "point/secrecy-bits-per-step.pdf",
            "figures/dv-sweep-accepted.png",
            "report.md",
        ];
        let theirs = [
            "notes/thesis.tex",
            "point/analysis.csv",
            "point/traces/point-3.csv.bak",
            "plot.py",
        ];
        for file in robokey.iter().chain(&theirs) {
            std::fs::write(dir.join(file), "x").unwrap();
        }
        assert!(matches!(
            prepare_output(&dir, false),
            Err(LabError::NotEmpty(_))
        ));
        let kept = prepare_output(&dir, true).unwrap();
        let mut expected: Vec<PathBuf> =
            theirs.iter().chain(&["empty"]).map(PathBuf::from).collect();
        expected.sort();
        assert_eq!(kept, expected);
        for file in robokey {
            assert!(!dir.join(file).exists(), "{file} survived");
        }
        for file in theirs {
            assert!(dir.join(file).exists(), "{file} was removed");
        }
        // The folder robokey's files left empty is gone; the others stay.
        assert!(!dir.join("figures").exists());
        // A folder with nothing of robokey's is refused, whatever it holds.
        for file in ["report.md", "point/manifest.json", "point/runs.csv"] {
            assert!(!dir.join(file).exists());
        }
        assert!(matches!(
            prepare_output(&dir, true),
            Err(LabError::NotOutput(_))
        ));
        assert!(dir.join("notes/thesis.tex").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
