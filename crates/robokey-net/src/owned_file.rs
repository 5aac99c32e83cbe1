//! Files and folders only this user controls. A store (`--store`) and a pairing file hold
//! secrets and decide what an agent reports as committed, so whoever can write beside them
//! must not redirect, plant or cut anything: every file is opened without following a link in
//! its last component (`O_NOFOLLOW`, and `O_NONBLOCK` so that a planted FIFO cannot hang the
//! open), and a folder or file that another user owns, or that group or others may write, is
//! refused, naming it, its mode, its owner and the fix. Refused rather than repaired: a
//! `chmod` cannot undo what others may already have planted.

use std::fs::{File, Metadata, OpenOptions};
use std::os::unix::fs::{MetadataExt as _, OpenOptionsExt as _};
use std::path::Path;

use crate::error::NetError;

/// Mode bits that let group or others write.
pub const WRITABLE_BY_OTHERS: u32 = 0o022;

/// Mode bits that let group or others read, write or search.
pub const ANY_ACCESS_BY_OTHERS: u32 = 0o077;

/// The effective user of this process.
#[must_use]
pub fn current_user() -> u32 {
    nix::unistd::geteuid().as_raw()
}

/// Opens `path` with `options` without following a link in its last component; a link is
/// an error naming it.
///
/// # Errors
/// The open fails, or `path` is a symbolic link.
pub fn open(path: &Path, options: &mut OpenOptions, what: &str) -> Result<File, NetError> {
    options.custom_flags(nix::libc::O_NOFOLLOW | nix::libc::O_NONBLOCK);
    options.open(path).map_err(|e| {
        if e.raw_os_error() == Some(nix::libc::ELOOP) {
            NetError::Usage(format!(
                "{what} {} is a symbolic link: refusing to follow it (remove it)",
                path.display()
            ))
        } else {
            NetError::io(format!("open {what} {}", path.display()))(e)
        }
    })
}

/// Refuses the open file `file` (at `path`) unless it is a regular file this user owns
/// whose mode grants others none of `forbidden`.
///
/// # Errors
/// A usage error naming the file, what is wrong and the fix.
pub fn check_file(file: &File, path: &Path, what: &str, forbidden: u32) -> Result<(), NetError> {
    let metadata = file
        .metadata()
        .map_err(NetError::io(format!("stat {what} {}", path.display())))?;
    if !metadata.is_file() {
        return Err(NetError::Usage(format!(
            "{what} {} is not a regular file: refusing it (remove it)",
            path.display()
        )));
    }
    check_owner_and_mode(&metadata, path, what, forbidden, "600")
}

/// Refuses the folder `path` (a link to a folder is followed: it is the user's own path)
/// unless this user owns it and group and others cannot write it.
///
/// # Errors
/// `path` is missing or not a folder, or the usage error of a bad owner or mode.
pub fn check_folder(path: &Path, what: &str) -> Result<(), NetError> {
    let metadata =
        std::fs::metadata(path).map_err(NetError::io(format!("stat {what} {}", path.display())))?;
    if !metadata.is_dir() {
        return Err(NetError::Usage(format!(
            "{what} {} is not a folder",
            path.display()
        )));
    }
    check_owner_and_mode(&metadata, path, what, WRITABLE_BY_OTHERS, "700")
}

/// Refuses the folder `path` if it is a symbolic link, then checks it as [`check_folder`]
/// does: a folder inside a store is never a link.
///
/// # Errors
/// As [`check_folder`], or `path` is a link.
pub fn check_inner_folder(path: &Path, what: &str) -> Result<(), NetError> {
    let metadata = std::fs::symlink_metadata(path)
        .map_err(NetError::io(format!("stat {what} {}", path.display())))?;
    if metadata.file_type().is_symlink() {
        return Err(NetError::Usage(format!(
            "{what} {} is a symbolic link: refusing to follow it (remove it)",
            path.display()
        )));
    }
    check_folder(path, what)
}

fn check_owner_and_mode(
    metadata: &Metadata,
    path: &Path,
    what: &str,
    forbidden: u32,
    fix_mode: &str,
) -> Result<(), NetError> {
    let user = current_user();
    if metadata.uid() != user {
        return Err(NetError::Usage(format!(
            "{what} {} is owned by user {}, not by this user ({user}): refusing it (another \
             user could have written it; chown it to this user, or use another path)",
            path.display(),
            metadata.uid()
        )));
    }
    let mode = metadata.mode() & 0o7777;
    if mode & forbidden != 0 {
        return Err(NetError::Usage(format!(
            "{what} {} has mode {mode:03o}: group or others may {} it; refusing it (check \
             what it holds, then chmod {fix_mode} it)",
            path.display(),
            if forbidden & 0o044 == 0 {
                "write"
            } else {
                "read or write"
            }
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt as _;

    #[test]
    fn links_fifos_foreign_and_open_files_and_folders_are_refused_by_name() {
        let dir = crate::journal::tests::tempdir("owned-file");
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700)).unwrap();
        check_folder(&dir, "store").unwrap();
        let target = dir.join("target");
        std::fs::write(&target, b"keep").unwrap();
        let link = dir.join("link");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let error = open(&link, OpenOptions::new().read(true), "lock")
            .unwrap_err()
            .to_string();
        assert!(error.contains("is a symbolic link"), "{error}");
        // A dangling link is refused too, and nothing is created at its target.
        let dangling = dir.join("dangling");
        std::os::unix::fs::symlink(dir.join("nowhere"), &dangling).unwrap();
        let error = open(
            &dangling,
            OpenOptions::new().write(true).create(true),
            "lock",
        )
        .unwrap_err()
        .to_string();
        assert!(error.contains("is a symbolic link"), "{error}");
        assert!(!dir.join("nowhere").exists());
        // A FIFO opens at once (no hang) and is refused as not a regular file.
        let fifo = dir.join("fifo");
        nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::S_IRWXU).unwrap();
        let file = open(&fifo, OpenOptions::new().read(true).write(true), "journal").unwrap();
        let error = check_file(&file, &fifo, "journal", WRITABLE_BY_OTHERS)
            .unwrap_err()
            .to_string();
        assert!(error.contains("not a regular file"), "{error}");
        // Modes that let others write are refused, naming the mode and the fix.
        std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o666)).unwrap();
        let file = open(&target, OpenOptions::new().read(true), "key file").unwrap();
        let error = check_file(&file, &target, "key file", WRITABLE_BY_OTHERS)
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("mode 666") && error.contains("chmod 600"),
            "{error}"
        );
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o777)).unwrap();
        let error = check_folder(&dir, "store").unwrap_err().to_string();
        assert!(
            error.contains("mode 777") && error.contains("chmod 700"),
            "{error}"
        );
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700)).unwrap();
        let error = check_inner_folder(&link, "key folder")
            .unwrap_err()
            .to_string();
        assert!(error.contains("symbolic link"), "{error}");
        // Another owner (only root can make one).
        if current_user() == 0 {
            nix::unistd::chown(&dir, Some(nix::unistd::Uid::from_raw(65_534)), None).unwrap();
            let error = check_folder(&dir, "store").unwrap_err().to_string();
            assert!(error.contains("owned by user 65534"), "{error}");
        } else {
            eprintln!("not root: the foreign-owner case is not exercised");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
