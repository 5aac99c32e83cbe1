//! Helpers shared by the process-level tests: start `robokey` processes on loopback, read
//! their reports. (Each test binary uses a subset, hence `dead_code` is allowed here.)
#![allow(dead_code)]

pub mod kme;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A running `robokey` process whose first stdout line announced its address.
pub struct Process {
    pub child: Child,
    pub address: String,
}

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts `robokey args…` and reads the address from its first line (`… on ADDR[, …]`).
pub fn start(args: &[&str]) -> Process {
    start_lines(args, 1).0
}

/// Starts `robokey args…`, reads its first `lines` stdout lines and the address from the
/// last one (`… on ADDR[, …]`).
pub fn start_lines(args: &[&str], lines: usize) -> (Process, Vec<String>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_robokey"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("robokey starts");
    let mut read = Vec::new();
    // Byte by byte, so that nothing after the last line is buffered away from `wait`.
    let stdout = child.stdout.as_mut().unwrap();
    for _ in 0..lines {
        let mut line = Vec::new();
        let mut byte = [0u8];
        while std::io::Read::read(stdout, &mut byte).unwrap() == 1 && byte[0] != b'\n' {
            line.push(byte[0]);
        }
        read.push(String::from_utf8_lossy(&line).into_owned());
    }
    let last = read.last().cloned().unwrap_or_default();
    let address = address_after(&last, " on ");
    (Process { child, address }, read)
}

/// The address after `marker` in `line`, up to a comma or the end.
pub fn address_after(line: &str, marker: &str) -> String {
    line.split(marker)
        .nth(1)
        .and_then(|rest| rest.split([',', '\n']).next())
        .unwrap_or_else(|| panic!("no address after {marker:?} in {line:?}"))
        .trim()
        .to_owned()
}

/// Runs `robokey args…` to completion; returns (success, stdout + stderr).
pub fn run(args: &[&str]) -> (bool, String) {
    let (code, text) = run_code(args);
    (code == 0, text)
}

/// Runs `robokey args…` to completion; returns (exit code, stdout + stderr).
pub fn run_code(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_robokey"))
        .args(args)
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    (out.status.code().unwrap_or(-1), text)
}

/// Waits for a process that must succeed; returns the rest of its stdout.
pub fn wait(process: Process) -> String {
    let (code, rest) = wait_code(process);
    assert_eq!(code, 0, "process failed: {rest}");
    rest
}

/// Waits for a process; returns (exit code, the rest of its stdout).
pub fn wait_code(mut process: Process) -> (i32, String) {
    let status = process.child.wait().unwrap();
    let mut rest = String::new();
    if let Some(out) = process.child.stdout.as_mut() {
        let _ = std::io::Read::read_to_string(out, &mut rest);
    }
    (status.code().unwrap_or(-1), rest)
}

pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("robokey-net-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

pub fn s(path: &Path) -> String {
    path.to_str().unwrap().to_owned()
}

/// Writes a pairing into `dir` with `robokey pair`; returns the file.
pub fn pairing(dir: &Path) -> String {
    let (ok, text) = run(&["pair", "--out", &s(dir)]);
    assert!(ok, "{text}");
    s(&dir.join("pairing.key"))
}

pub fn report(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Asserts that every key of a `keys list --json` rests on the plant the controller measured
/// (its record's `basis.plant`), not on the configured motion noise.
pub fn assert_sized_from_the_measured_plant(keys: &[serde_json::Value]) {
    for key in keys {
        let plant = key["basis"]["plant"].as_str().unwrap();
        assert!(
            plant.starts_with("Gaussian motion noise measured by the controller"),
            "{key}"
        );
    }
}

/// Set in the re-executed test: the body runs.
const INSIDE: &str = "ROBOKEY_TEST_NETNS";
/// Longest a namespaced test may take.
const TEST_TIMEOUT: Duration = Duration::from_secs(180);

/// Returns true inside the namespace. Outside, runs `test` of this binary in a new network
/// namespace (set up by `setup`, a shell snippet run as root of the namespace), checks it
/// passed, and returns false; or skips when `unshare` is unavailable.
pub fn in_namespace(test: &str, setup: &str) -> bool {
    if std::env::var_os(INSIDE).is_some() {
        return true;
    }
    let works = Command::new("unshare")
        .args(["-rn", "true"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|status| status.success());
    if !works {
        eprintln!(
            "SKIPPED {test}: `unshare -rn` is unavailable here (util-linux and user namespaces are \
             needed); this test never runs on the machine's own interfaces"
        );
        return false;
    }
    let script = format!(
        "set -e; ip link set lo up; ip link set lo multicast on; {setup}; exec \"$0\" \"$@\""
    );
    let mut child = Command::new("unshare")
        .args(["-rn", "sh", "-c", &script])
        .arg(std::env::current_exe().unwrap())
        .args([test, "--exact", "--nocapture", "--test-threads=1"])
        .env(INSIDE, "1")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("unshare starts");
    let deadline = Instant::now() + TEST_TIMEOUT;
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if Instant::now() >= deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{test} took more than {TEST_TIMEOUT:?} in its namespace");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let output = child.wait_with_output().unwrap();
    let text = String::from_utf8_lossy(&output.stdout).into_owned()
        + &String::from_utf8_lossy(&output.stderr);
    // Shown with `cargo test -- --nocapture`: what ran in the namespace and what it printed.
    println!("{text}");
    assert!(status.success(), "{test} failed in its namespace:\n{text}");
    assert!(text.contains("1 passed"), "{test} did not run:\n{text}");
    false
}
