//! The pairing file: one 256-bit secret installed on the robot and its controller
//! (`robokey pair`), as text `robokey-pairing-v1 <64 hex digits>`, mode 0600. Like ssh with a
//! private key, the agents refuse a pairing file that group or others may read or write, or
//! that another user owns, unless told otherwise (`--insecure-pairing-file`).

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
    // Hex without data-dependent branches or table look-ups (base16ct): it is the secret.
    let mut hex = Zeroizing::new([0u8; 2 * SECRET_BYTES]);
    let hex = base16ct::lower::encode_str(secret.expose(), hex.as_mut_slice())
        .expect("the buffer holds two digits per byte");
    let text = Zeroizing::new(format!("{HEADER} {hex}\n"));
    crate::secret_file::write_new(&path, text.as_bytes())?;
    Ok((path, secret))
}

/// The flag that lets an agent use a pairing file others may access.
pub const INSECURE_FLAG: &str = "--insecure-pairing-file";

/// Reads a pairing file. A file that group or others may access, or that another user owns,
/// is refused — unless `insecure`, when the refusal becomes the returned warning.
///
/// # Errors
/// The file is missing, unreadable, open to others or another user's (without `insecure`),
/// or not a pairing file (naming what is wrong and the fix).
pub fn read_pairing(
    path: &Path,
    insecure: bool,
) -> Result<(PairingSecret, Option<String>), NetError> {
    use std::io::Read as _;
    let bad = |why: String| NetError::Usage(format!("pairing file {}: {why}", path.display()));
    let mut file = std::fs::File::open(path).map_err(|e| {
        bad(match e.kind() {
            std::io::ErrorKind::NotFound => {
                "missing (create one with `robokey pair --out DIR`)".into()
            }
            _ => format!("cannot be read: {e}"),
        })
    })?;
    let warning = match crate::owned_file::check_file(
        &file,
        path,
        "pairing file",
        crate::owned_file::ANY_ACCESS_BY_OTHERS,
    ) {
        Ok(()) => None,
        Err(NetError::Usage(why)) if insecure => Some(format!(
            "warning: {why}; using it anyway ({INSECURE_FLAG}): whoever read it can \
             impersonate either side"
        )),
        Err(NetError::Usage(why)) => {
            return Err(NetError::Usage(format!(
                "{why}: the pairing secret must be private to this user, as ssh requires of a \
                 private key (or pass {INSECURE_FLAG} to use it anyway)"
            )));
        }
        Err(other) => return Err(other),
    };
    let mut text = Zeroizing::new(String::new());
    file.read_to_string(&mut text)
        .map_err(|e| bad(format!("cannot be read: {e}")))?;
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
    base16ct::mixed::decode(hex, bytes.as_mut_slice())
        .map_err(|_| bad("the secret is not hex".into()))?;
    Ok((PairingSecret::from_bytes(&bytes), warning))
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
        let (read, warning) = read_pairing(&path, false).unwrap();
        assert_eq!(read.fingerprint(), secret.fingerprint());
        assert_eq!(warning, None);
        let again = write_pairing(&dir, &mut rng).unwrap_err().to_string();
        assert!(again.contains("refusing to overwrite"), "{again}");
        assert_eq!(
            read_pairing(&path, false).unwrap().0.fingerprint(),
            secret.fingerprint()
        );
        assert_eq!(
            std::fs::read_dir(&dir).unwrap().count(),
            1,
            "no temporary file left"
        );
        std::fs::write(&path, "robokey-pairing-v1 abcd\n").unwrap();
        let short = read_pairing(&path, false).unwrap_err().to_string();
        assert!(short.contains("4 characters, expected 64"), "{short}");
        std::fs::write(&path, "hello").unwrap();
        assert!(
            read_pairing(&path, false)
                .unwrap_err()
                .to_string()
                .contains("not a pairing file")
        );
        let missing = read_pairing(&dir.join("nope"), false)
            .unwrap_err()
            .to_string();
        assert!(missing.contains("nope: missing"), "{missing}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Modes that let group or others read or write the secret, and another owner, are
    /// refused by default, naming the file, its mode and the fix; the flag lets it through
    /// with a warning.
    #[test]
    fn a_pairing_file_others_can_access_is_refused_unless_told() {
        use std::os::unix::fs::PermissionsExt as _;
        let dir = std::env::temp_dir().join(format!("robokey-pairing-mode-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let mut rng = rand::rngs::ChaCha20Rng::seed_from_u64(2);
        let (path, secret) = write_pairing(&dir, &mut rng).unwrap();
        for mode in [0o644, 0o666, 0o604, 0o640, 0o620] {
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).unwrap();
            let error = read_pairing(&path, false).unwrap_err().to_string();
            assert!(error.contains(&format!("mode {mode:03o}")), "{error}");
            assert!(
                error.contains("chmod 600") && error.contains(INSECURE_FLAG),
                "{error}"
            );
            let (read, warning) = read_pairing(&path, true).unwrap();
            assert_eq!(read.fingerprint(), secret.fingerprint());
            assert!(warning.unwrap().contains(&format!("mode {mode:03o}")));
        }
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
        if crate::owned_file::current_user() == 0 {
            nix::unistd::chown(&path, Some(nix::unistd::Uid::from_raw(65_534)), None).unwrap();
            let error = read_pairing(&path, false).unwrap_err().to_string();
            assert!(error.contains("owned by user 65534"), "{error}");
            assert!(read_pairing(&path, true).is_ok());
        } else {
            eprintln!("not root: the foreign-owner case is not exercised");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
