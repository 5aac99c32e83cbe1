//! The pairing file: one 256-bit secret installed on the robot and its controller
//! (`robokey pair`), as text `robokey-pairing-v1 <64 hex digits>`, mode 0600.

use std::path::{Path, PathBuf};

use rand::CryptoRng;
use robokey::protocol::auth::{PairingSecret, SECRET_BYTES};
use zeroize::Zeroizing;

use crate::error::NetError;

/// File name `robokey pair` writes in its output folder.
pub const FILE_NAME: &str = "pairing.key";
const HEADER: &str = "robokey-pairing-v1";

/// Writes a fresh secret from `rng` (the OS CSPRNG) to `dir/pairing.key`, atomically (a
/// temporary file in `dir`, synced, then linked to its name, which fails if the name
/// exists) and with mode 0600. Refuses to overwrite.
///
/// # Errors
/// `dir/pairing.key` exists, or the folder cannot be written.
pub fn write_pairing<R: CryptoRng + ?Sized>(
    dir: &Path,
    rng: &mut R,
) -> Result<(PathBuf, PairingSecret), NetError> {
    let path = dir.join(FILE_NAME);
    if path.exists() {
        return Err(NetError::Usage(format!(
            "{} exists: refusing to overwrite a pairing (remove it first to re-pair both sides)",
            path.display()
        )));
    }
    std::fs::create_dir_all(dir).map_err(NetError::io(format!("create {}", dir.display())))?;
    let secret = PairingSecret::generate(rng);
    let hex: Zeroizing<String> =
        Zeroizing::new(secret.expose().iter().map(|b| format!("{b:02x}")).collect());
    let text = Zeroizing::new(format!("{HEADER} {}\n", hex.as_str()));
    crate::secret_file::write_new(&path, text.as_bytes())?;
    Ok((path, secret))
}

/// Reads a pairing file. Also returns a warning when the file is readable by others.
///
/// # Errors
/// The file is missing, unreadable, or not a pairing file (naming what is wrong).
pub fn read_pairing(path: &Path) -> Result<(PairingSecret, Option<String>), NetError> {
    let bad = |why: String| NetError::Usage(format!("pairing file {}: {why}", path.display()));
    let text = Zeroizing::new(std::fs::read_to_string(path).map_err(|e| {
        bad(match e.kind() {
            std::io::ErrorKind::NotFound => {
                "missing (create one with `robokey pair --out DIR`)".into()
            }
            _ => format!("cannot be read: {e}"),
        })
    })?);
    let hex = text
        .trim_end()
        .strip_prefix(HEADER)
        .and_then(|rest| rest.strip_prefix(' '))
        .ok_or_else(|| {
            bad(format!(
                "not a pairing file (expected `{HEADER} <64 hex digits>`)"
            ))
        })?;
    if hex.len() != 2 * SECRET_BYTES || !hex.is_ascii() {
        return Err(bad(format!(
            "the secret has {} characters, expected {} hex digits ({} bits)",
            hex.chars().count(),
            2 * SECRET_BYTES,
            8 * SECRET_BYTES
        )));
    }
    let mut bytes = Zeroizing::new([0u8; SECRET_BYTES]);
    for (i, byte) in bytes.iter_mut().enumerate() {
        *byte = u8::from_str_radix(&hex[2 * i..2 * i + 2], 16)
            .map_err(|_| bad("the secret is not hex".into()))?;
    }
    Ok((PairingSecret::from_bytes(&bytes), permission_warning(path)))
}

#[cfg(unix)]
fn permission_warning(path: &Path) -> Option<String> {
    use std::os::unix::fs::PermissionsExt;
    let mode = std::fs::metadata(path).ok()?.permissions().mode() & 0o777;
    (mode & 0o077 != 0).then(|| {
        format!(
            "warning: pairing file {} has mode {mode:03o}: others may read the secret (chmod 600 it)",
            path.display()
        )
    })
}

#[cfg(not(unix))]
fn permission_warning(_: &Path) -> Option<String> {
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn written_pairings_read_back_and_are_never_overwritten() {
        let dir = std::env::temp_dir().join(format!("robokey-pairing-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let mut rng = rand::rngs::ChaCha20Rng::seed_from_u64(1);
        let (path, secret) = write_pairing(&dir, &mut rng).unwrap();
        let (read, warning) = read_pairing(&path).unwrap();
        assert_eq!(read.fingerprint(), secret.fingerprint());
        assert_eq!(warning, None);
        let again = write_pairing(&dir, &mut rng).unwrap_err().to_string();
        assert!(again.contains("refusing to overwrite"), "{again}");
        assert_eq!(
            read_pairing(&path).unwrap().0.fingerprint(),
            secret.fingerprint()
        );
        assert_eq!(
            std::fs::read_dir(&dir).unwrap().count(),
            1,
            "no temporary file left"
        );
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
            assert!(read_pairing(&path).unwrap().1.unwrap().contains("mode 644"));
        }
        std::fs::write(&path, "robokey-pairing-v1 abcd\n").unwrap();
        let short = read_pairing(&path).unwrap_err().to_string();
        assert!(short.contains("4 characters, expected 64"), "{short}");
        std::fs::write(&path, "hello").unwrap();
        assert!(
            read_pairing(&path)
                .unwrap_err()
                .to_string()
                .contains("not a pairing file")
        );
        let missing = read_pairing(&dir.join("nope")).unwrap_err().to_string();
        assert!(missing.contains("nope: missing"), "{missing}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
