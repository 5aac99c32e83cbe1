//! Files that hold secrets (pairings, keys): written all or nothing, never over an existing
//! file, readable by their owner only.
//!
//! The steps, each durable before the next: a temporary file `.NAME.PID-N.tmp` in the same
//! folder (mode 0600, created exclusively), the text, `fsync`; a hard link to `NAME`, which
//! never replaces an existing name; `fsync` of the folder; the temporary name removed. A
//! crash between any two steps leaves either no `NAME` or a complete one; a temporary file
//! it leaves behind is removed by the next write of the same `NAME`.

use std::fs::{File, OpenOptions};
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use zeroize::Zeroizing;

use crate::error::NetError;

/// Refuses `path` when it exists, or when its folder does not: checked before a session
/// starts, so that a key is never agreed and then lost for want of a place to write it.
///
/// # Errors
/// A usage error naming the file.
pub fn check_writable(path: &Path, what: &str) -> Result<(), NetError> {
    if path.exists() {
        return Err(NetError::Usage(format!(
            "{what} {} exists: refusing to overwrite it (remove it, or choose another path)",
            path.display()
        )));
    }
    let folder = folder_of(path);
    if !folder.is_dir() {
        return Err(NetError::Usage(format!(
            "{what} {}: the folder {} does not exist",
            path.display(),
            folder.display()
        )));
    }
    Ok(())
}

/// Writes `text` as the new file `path` (see the module documentation).
///
/// # Errors
/// `path` exists, or a step fails (nothing is left under `path` then).
pub fn write_new(path: &Path, text: &[u8]) -> Result<(), NetError> {
    if create(path, text)? {
        return Ok(());
    }
    Err(NetError::Usage(format!(
        "{} appeared during the session: refusing to overwrite it",
        path.display()
    )))
}

/// Writes `text` as the new file `path` if the name is free (see the module documentation);
/// false, with nothing written, if anything has that name (a file, a link, a dangling link).
///
/// # Errors
/// A step fails (nothing is left under `path` then).
pub fn create(path: &Path, text: &[u8]) -> Result<bool, NetError> {
    let mut write = SecretWrite::begin(path)?;
    write.write(text)?;
    let linked = write.link()?;
    write.finish()?;
    Ok(linked)
}

/// Writes `text` as `path`, replacing what is there in one atomic step (a rename after the
/// text is durable; a link at `path` is replaced, never followed): a crash leaves the old
/// file or the new one, never a mix. Returns the new file, open for writing at its end.
///
/// # Errors
/// A step fails (the old file is then untouched).
pub fn replace(path: &Path, text: &[u8]) -> Result<File, NetError> {
    let mut write = SecretWrite::begin(path)?;
    write.write(text)?;
    std::fs::rename(&write.temp, &write.path)
        .and_then(|()| File::open(folder_of(&write.path))?.sync_all())
        .map_err(NetError::io(format!("replace {}", path.display())))?;
    Ok(write.file.take().expect("the file is open until linked"))
}

/// One write in progress, step by step (tests stop it between any two, as a crash would).
pub(crate) struct SecretWrite {
    path: PathBuf,
    temp: PathBuf,
    file: Option<File>,
}

impl SecretWrite {
    /// Removes the temporary files of earlier crashed writes of `path`, then creates a new one.
    pub(crate) fn begin(path: &Path) -> Result<Self, NetError> {
        let name = path
            .file_name()
            .ok_or_else(|| NetError::Usage(format!("{}: not a file name", path.display())))?
            .to_string_lossy()
            .into_owned();
        let folder = folder_of(path);
        let prefix = format!(".{name}.");
        if let Ok(entries) = std::fs::read_dir(&folder) {
            for entry in entries.flatten() {
                let other = entry.file_name().to_string_lossy().into_owned();
                if other.starts_with(&prefix) && other.ends_with(".tmp") {
                    let _ = std::fs::remove_file(entry.path());
                }
            }
        }
        static WRITES: AtomicU64 = AtomicU64::new(0);
        let unique = format!(
            "{}-{}",
            std::process::id(),
            WRITES.fetch_add(1, Ordering::Relaxed)
        );
        let temp = folder.join(format!("{prefix}{unique}.tmp"));
        let mut options = OpenOptions::new();
        options.write(true).create_new(true);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
        let file = options
            .open(&temp)
            .map_err(NetError::io(format!("create {}", temp.display())))?;
        Ok(Self {
            path: path.to_owned(),
            temp,
            file: Some(file),
        })
    }

    /// Writes the text and makes it durable.
    pub(crate) fn write(&mut self, text: &[u8]) -> Result<(), NetError> {
        let file = self.file.as_mut().expect("written once, before link");
        file.write_all(text)
            .and_then(|()| file.sync_all())
            .map_err(NetError::io(format!("write {}", self.temp.display())))
    }

    /// Gives the complete file its name durably, unless the name is taken (false): `link(2)`
    /// never replaces an existing name and never follows a link there.
    pub(crate) fn link(&mut self) -> Result<bool, NetError> {
        self.file = None;
        match std::fs::hard_link(&self.temp, &self.path) {
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(false),
            linked => linked
                .and_then(|()| File::open(folder_of(&self.path))?.sync_all())
                .map(|()| true)
                .map_err(NetError::io(format!("write {}", self.path.display()))),
        }
    }

    /// Removes the temporary name.
    pub(crate) fn finish(self) -> Result<(), NetError> {
        std::fs::remove_file(&self.temp).map_err(NetError::io(format!(
            "remove the temporary {}",
            self.temp.display()
        )))
    }
}

impl Drop for SecretWrite {
    /// A write that failed (or was abandoned) leaves no temporary file when the process lives.
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.temp);
    }
}

/// The folder of `path` (`.` for a bare file name).
fn folder_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.to_owned(),
        _ => PathBuf::from("."),
    }
}

/// Reads a secret file into memory that is zeroized when dropped.
///
/// # Errors
/// The file cannot be read (names it).
pub fn read(path: &Path, what: &str) -> Result<Zeroizing<String>, NetError> {
    std::fs::read_to_string(path)
        .map(Zeroizing::new)
        .map_err(NetError::io(format!("read {what} {}", path.display())))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn listing(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    /// Stops a write after `steps` steps without running any destructor, as `kill -9` would.
    fn crash_after(path: &Path, text: &[u8], steps: usize) {
        let mut write = SecretWrite::begin(path).unwrap();
        if steps >= 2 {
            write.write(text).unwrap();
        }
        if steps >= 3 {
            assert!(write.link().unwrap());
        }
        std::mem::forget(write);
    }

    #[test]
    fn a_crash_at_any_step_leaves_no_file_or_the_whole_file_and_the_next_write_recovers() {
        let dir = std::env::temp_dir().join(format!("robokey-secret-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("key.txt");
        for steps in 1..=3 {
            crash_after(&path, b"secret\n", steps);
            let names = listing(&dir);
            assert_eq!(names.len(), 1 + usize::from(steps == 3), "{names:?}");
            assert!(
                names.iter().any(|n| n.starts_with(".key.txt.")),
                "{names:?}"
            );
            if steps == 3 {
                assert_eq!(std::fs::read(&path).unwrap(), b"secret\n");
                assert!(check_writable(&path, "key file").is_err());
                std::fs::remove_file(&path).unwrap();
            } else {
                // No key file: the next session may run; a half-written temporary is not it.
                check_writable(&path, "key file").unwrap();
            }
            write_new(&path, b"next\n").unwrap();
            assert_eq!(listing(&dir), ["key.txt"], "the stale temporary is removed");
            std::fs::remove_file(&path).unwrap();
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn existing_files_and_missing_folders_are_refused_by_name() {
        let dir = std::env::temp_dir().join(format!("robokey-secret-x-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("k");
        write_new(&path, b"one").unwrap();
        let again = write_new(&path, b"two").unwrap_err().to_string();
        assert!(again.contains("refusing to overwrite"), "{again}");
        assert_eq!(std::fs::read(&path).unwrap(), b"one");
        assert_eq!(listing(&dir), ["k"]);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode();
            assert_eq!(mode & 0o777, 0o600);
        }
        let missing = check_writable(&dir.join("nope/k"), "key file")
            .unwrap_err()
            .to_string();
        assert!(missing.contains("does not exist"), "{missing}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
