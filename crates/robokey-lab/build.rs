//! Records the git commit and the versions of the crates that affect numbers, for
//! `manifest.json`.

use std::process::Command;

fn main() {
    let commit = Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map_or_else(
            || "unknown".to_owned(),
            |o| String::from_utf8_lossy(&o.stdout).trim().to_owned(),
        );
    let dirty = Command::new("git")
        // Without optional locks git does not refresh (rewrite) the index, which would make
        // the next build rerun this script and rebuild the crate for nothing.
        .args([
            "--no-optional-locks",
            "status",
            "--porcelain",
            "--untracked-files=no",
        ])
        .output()
        .ok()
        .is_some_and(|o| !o.stdout.is_empty());
    println!(
        "cargo:rustc-env=ROBOKEY_GIT_COMMIT={commit}{}",
        if dirty { "-dirty" } else { "" }
    );
    // Where git keeps them: `../../.git/…` in a clone, elsewhere in a worktree (whose .git is
    // a file). A path that does not exist would rerun this script, and rebuild, every time.
    for file in ["HEAD", "index"] {
        if let Some(path) = Command::new("git")
            .args(["rev-parse", "--git-path", file])
            .output()
            .ok()
            .filter(|o| o.status.success())
        {
            println!(
                "cargo:rerun-if-changed={}",
                String::from_utf8_lossy(&path.stdout).trim()
            );
        }
    }

    let lock = std::fs::read_to_string("../../Cargo.lock").unwrap_or_default();
    let mut versions = Vec::new();
    for name in ["nalgebra", "rand", "rand_distr", "chacha20", "sha2", "libm"] {
        let needle = format!("name = \"{name}\"\nversion = \"");
        if let Some(start) = lock.find(&needle) {
            let rest = &lock[start + needle.len()..];
            let version = &rest[..rest.find('"').unwrap_or(0)];
            versions.push(format!("{name}={version}"));
        }
    }
    println!(
        "cargo:rustc-env=ROBOKEY_NUMERIC_CRATES={}",
        versions.join(",")
    );
    println!("cargo:rerun-if-changed=../../Cargo.lock");
}
