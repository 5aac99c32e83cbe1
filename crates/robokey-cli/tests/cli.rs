//! Runs the `robokey` binary as a user would.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn robokey(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_robokey"))
        .args(args)
        .output()
        .expect("the robokey binary runs")
}

fn ok(args: &[&str]) -> String {
    let out = robokey(args);
    assert!(
        out.status.success(),
        "robokey {args:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn fails(args: &[&str]) -> String {
    let out = robokey(args);
    assert!(!out.status.success(), "robokey {args:?} should fail");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Runs a command that must fail with exit code `code`; its stderr.
fn fails_with(code: i32, args: &[&str]) -> String {
    let out = robokey(args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(code), "robokey {args:?}: {stderr}");
    stderr
}

/// Every file under `dir` by relative path, with its bytes.
fn files(dir: &Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    fn walk(root: &Path, dir: &Path, out: &mut std::collections::BTreeMap<PathBuf, Vec<u8>>) {
        for entry in dir.read_dir().unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                walk(root, &path, out);
            } else {
                let bytes = std::fs::read(&path).unwrap();
                out.insert(path.strip_prefix(root).unwrap().to_path_buf(), bytes);
            }
        }
    }
    let mut out = std::collections::BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

/// Asserts two folders hold the same files with the same bytes, except that the
/// manifests may differ in their `shards` (a merge lists the shards it was made of) and
/// PDF figures are only checked to be PDFs: svg2pdf orders their objects differently from
/// one process to the next (the SVG, PNG and CSV of each figure are compared).
fn assert_same_files(a: &Path, b: &Path) {
    let (a_files, b_files) = (files(a), files(b));
    assert_eq!(
        a_files.keys().collect::<Vec<_>>(),
        b_files.keys().collect::<Vec<_>>(),
        "{} and {} hold different files",
        a.display(),
        b.display()
    );
    for (path, bytes) in &a_files {
        if path.extension().is_some_and(|e| e == "pdf") {
            assert!(
                bytes.starts_with(b"%PDF") && b_files[path].starts_with(b"%PDF"),
                "{}",
                path.display()
            );
        } else if path.ends_with("manifest.json") {
            let without_shards = |bytes: &[u8]| {
                let mut json: serde_json::Value = serde_json::from_slice(bytes).unwrap();
                json.as_object_mut().unwrap().remove("shards");
                json
            };
            assert_eq!(
                without_shards(bytes),
                without_shards(&b_files[path]),
                "{}",
                path.display()
            );
        } else {
            assert!(bytes == &b_files[path], "{} differs", path.display());
        }
    }
}

/// A fresh scratch folder for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("robokey-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn run_prints_metrics_and_writes_its_files() {
    let dir = scratch("run");
    let out = ok(&["run", "--delta-v", "0.035", "--seed", "7", "--out", s(&dir)]);
    assert!(out.contains("accepted %") && out.contains("J_x"), "{out}");
    let metrics: serde_json::Value =
        serde_json::from_str(&read(&dir.join("metrics.json"))).unwrap();
    assert_eq!(metrics["codewords_sent"], 340);
    assert!(metrics["accepted_pct"].as_f64().unwrap() > 50.0);
    assert_eq!(read(&dir.join("trace.csv")).lines().count(), 1022);
    assert!(read(&dir.join("trajectory.svg")).contains("<svg"));
    assert!(dir.join("trajectory.png").exists());
    // A second run into the same folder: refused, then rewritten with --force, which
    // removes robokey's files (a stale one of another command too) and keeps the user's.
    std::fs::write(dir.join("secrecy.md"), "stale").unwrap();
    std::fs::create_dir_all(dir.join("notes")).unwrap();
    std::fs::write(dir.join("notes/analysis.csv"), "mine").unwrap();
    std::fs::write(dir.join("plot.py"), "mine").unwrap();
    let refused = fails(&["run", "--out", s(&dir)]);
    assert!(
        refused.contains("not empty") && refused.contains("--force"),
        "{refused}"
    );
    let forced = robokey(&["run", "--force", "--out", s(&dir)]);
    assert!(forced.status.success());
    let said = String::from_utf8_lossy(&forced.stderr);
    assert!(
        said.contains("kept 2 it did not write: notes/analysis.csv, plot.py"),
        "{said}"
    );
    assert!(!dir.join("secrecy.md").exists());
    assert_eq!(read(&dir.join("notes/analysis.csv")), "mine");
    assert_eq!(read(&dir.join("plot.py")), "mine");
    assert!(dir.join("trace.csv").exists() && dir.join("metrics.json").exists());
}

#[test]
fn frames_prints_what_dumpcap_and_tcpdump_recorded_as_it_prints_the_relays_capture() {
    // One session recorded by the relay and by the tools at once (robokey-net's tests/captures).
    let fixture = |name: &str| {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../robokey-net/tests/captures")
            .join(name)
            .display()
            .to_string()
    };
    let relay = ok(&["frames", &fixture("relay-after-faults.pcap")]);
    assert_eq!(relay.lines().count(), 91);
    for name in ["dumpcap-lo.pcapng", "tcpdump-lo.pcap", "tcpdump-any.pcap"] {
        assert_eq!(ok(&["frames", &fixture(name)]), relay, "{name}");
    }
}

#[test]
fn protocol_off_leaves_key_metrics_null() {
    let dir = scratch("off");
    ok(&["run", "--protocol-off", "--out", s(&dir)]);
    let metrics: serde_json::Value =
        serde_json::from_str(&read(&dir.join("metrics.json"))).unwrap();
    assert!(metrics["accepted_pct"].is_null() && metrics["key_match"].is_null());
    assert!(metrics["jx"].as_f64().unwrap() > 0.0);
}

#[test]
fn bad_input_gets_named_errors() {
    let err = fails(&["run", "--delta-v", "0"]);
    assert!(
        err.contains("protocol.delta_v") && err.contains("> 0"),
        "{err}"
    );
    let err = fails(&["run", "--set", "controller.gain=2"]);
    assert!(err.contains("gain"), "{err}");
    // Offered wheel speeds the robot would refuse: named, with the largest Δv that fits.
    for (flag, value) in [
        ("--delta-v", "1"),
        ("--delta-v", "35"),
        ("--set", "protocol.delta_v=1e308"),
    ] {
        let err = fails_with(2, &["run", flag, value]);
        assert!(
            err.contains("`protocol.delta_v`")
                && err.contains("≤ 0.6285 m/s")
                && err.contains("above robot.wheel_limit = 38 rad/s"),
            "{err}"
        );
    }
    // A logging filter that does not parse, from the flag or the environment.
    let err = fails_with(2, &["config", "--log", "rustdds=loud"]);
    assert!(
        err.contains("--log rustdds=loud") && err.contains("warn,rustdds=debug"),
        "{err}"
    );
    let out = Command::new(env!("CARGO_BIN_EXE_robokey"))
        .arg("config")
        .env("RUST_LOG", "debug,rustdds=loud")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("RUST_LOG debug,rustdds=loud"));
    let dir = scratch("bad");
    let file = dir.join("bad.toml");
    std::fs::write(
        &file,
        "[sweep]\nmode = \"zip\"\n\"controller.kp\" = [1.0]\n\"controller.kd\" = [0.7, 0.8]\n",
    )
    .unwrap();
    let err = fails(&["sweep", s(&file), "--out", s(&dir.join("o"))]);
    assert!(
        err.contains("bad.toml") && err.contains("zip axes differ"),
        "{err}"
    );
    std::fs::write(&file, "[sweep]\n\"robot.mass\" = [1.0]\n").unwrap();
    let err = fails(&["sweep", s(&file), "--out", s(&dir.join("o"))]);
    assert!(err.contains("bad.toml") && err.contains("mass"), "{err}");
    std::fs::write(&file, "[sweep]\n\"robot.r\" = []\n").unwrap();
    let err = fails(&["sweep", s(&file), "--out", s(&dir.join("o"))]);
    assert!(err.contains("`robot.r` is empty"), "{err}");
}

#[test]
fn pairing_is_required_written_once_and_checked() {
    let dir = scratch("pair");
    let out = ok(&["pair", "--out", s(&dir)]);
    let fingerprint = out
        .split("fingerprint ")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .unwrap_or_else(|| panic!("no fingerprint in {out}"));
    assert_eq!(fingerprint.len(), 16, "{out}");
    let file = dir.join("pairing.key");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&file).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o600);
    }
    let before = read(&file);
    let err = fails(&["pair", "--out", s(&dir)]);
    assert!(err.contains("refusing to overwrite"), "{err}");
    assert_eq!(read(&file), before);
    // No pairing and no --unauthenticated: the agents refuse to run, naming the way out.
    let err = fails(&["robot", "--listen", "127.0.0.1:0"]);
    assert!(
        err.contains("no --pairing FILE") && err.contains("robokey pair --out DIR"),
        "{err}"
    );
    let err = fails(&[
        "controller",
        "--robot",
        "127.0.0.1:9",
        "--pairing",
        s(&dir.join("nope")),
    ]);
    assert!(err.contains("nope: missing"), "{err}");
    std::fs::write(dir.join("short.key"), "robokey-pairing-v1 00ff\n").unwrap();
    #[cfg(unix)]
    {
        // Private, as the agents require of a pairing file, so that its format is checked.
        use std::os::unix::fs::PermissionsExt;
        let private = std::fs::Permissions::from_mode(0o600);
        std::fs::set_permissions(dir.join("short.key"), private).unwrap();
    }
    let err = fails(&[
        "controller",
        "--robot",
        "127.0.0.1:9",
        "--pairing",
        s(&dir.join("short.key")),
    ]);
    assert!(
        err.contains("short.key") && err.contains("expected 64 hex digits"),
        "{err}"
    );
    let err = fails(&[
        "robot",
        "--listen",
        "127.0.0.1:0",
        "--pairing",
        s(&file),
        "--unauthenticated",
    ]);
    assert!(err.contains("cannot be used with"), "{err}");
}

const SMALL_SWEEP: &str = "[run]\nreplicates = 3\n[sweep]\n\"protocol.delta_v\" = [0.02, 0.035]\n\"eve.alpha\" = [0.0, 0.1]\n";

#[test]
fn jobs_and_shards_give_byte_identical_results() {
    let dir = scratch("shards");
    let file = dir.join("small.toml");
    std::fs::write(&file, SMALL_SWEEP).unwrap();
    let (one, two) = (dir.join("one"), dir.join("two"));
    ok(&["sweep", s(&file), "--jobs", "1", "--out", s(&one)]);
    ok(&["sweep", s(&file), "--jobs", "2", "--out", s(&two)]);
    let runs = read(&one.join("runs.csv"));
    assert_eq!(runs, read(&two.join("runs.csv")));
    assert_eq!(runs.lines().count(), 1 + 12);
    assert!(runs.starts_with("protocol.delta_v,eve.alpha,replicate,codewords_sent,accepted,"));
    let (a, b, merged) = (dir.join("a"), dir.join("b"), dir.join("merged"));
    ok(&["sweep", s(&file), "--shard", "1/2", "--out", s(&a)]);
    ok(&["sweep", s(&file), "--shard", "2/2", "--out", s(&b)]);
    ok(&["merge", s(&a), s(&b), "--out", s(&merged)]);
    assert_eq!(read(&merged.join("runs.csv")), runs);
    assert_eq!(
        read(&merged.join("summary.json")),
        read(&one.join("summary.json"))
    );
    // A shard alone is not a complete sweep.
    let err = fails(&["merge", s(&a), "--out", s(&dir.join("partial"))]);
    assert!(err.contains("in none of the shards"), "{err}");
    // Refuses to overwrite without --force.
    let err = fails(&["sweep", s(&file), "--out", s(&one)]);
    assert!(err.contains("--force"), "{err}");
}

#[test]
fn reproduce_quick_writes_a_parseable_report_and_a_cluster_run_the_same_files() {
    let dir = scratch("reproduce");
    let out = dir.join("r");
    let printed = ok(&["reproduce", "--quick", "--out", s(&out)]);
    assert!(printed.contains("report:"), "{printed}");
    let report = read(&out.join("report.md"));
    assert!(
        report.contains("Spearman") && report.contains("does **not** reproduce"),
        "{report}"
    );
    for name in ["dv-sweep", "eve-sweep", "baseline", "trajectory"] {
        let folder = out.join(name);
        let summary: serde_json::Value =
            serde_json::from_str(&read(&folder.join("summary.json"))).unwrap();
        assert!(summary["points"].as_array().is_some_and(|p| !p.is_empty()));
        let _: serde_json::Value =
            serde_json::from_str(&read(&folder.join("manifest.json"))).unwrap();
        let mut csv = csv::Reader::from_path(folder.join("runs.csv")).unwrap();
        assert!(csv.records().all(|r| r.is_ok()));
        let _: toml::Table = read(&folder.join("config.resolved.toml")).parse().unwrap();
    }
    for figure in [
        "dv-acceptance",
        "dv-correct",
        "dv-jx",
        "eve-error-accepted",
        "trajectory",
    ] {
        let base = out.join("figures").join(figure);
        assert!(read(&base.with_extension("svg")).contains("<svg"));
        assert!(base.with_extension("png").exists());
        assert!(
            std::fs::read(base.with_extension("pdf"))
                .unwrap()
                .starts_with(b"%PDF")
        );
        assert!(
            read(&base.with_extension("csv")).lines().count() > 1,
            "{figure}"
        );
    }
    // The private-sensing section: sentences from the numbers, each figure with its CSV.
    assert!(
        report.contains("## Private sensing") && report.contains("secret bits per second"),
        "{report}"
    );
    assert!(report.contains("Eve's camera noise ≥ 8 mm"), "{report}");
    for (folder, figure) in [
        ("camera", "private-rate-vs-camera"),
        ("pareto-v", "private-pareto"),
        ("pareto-v", "private-leak"),
    ] {
        let base = out.join("private-sensing").join(folder).join(figure);
        assert!(read(&base.with_extension("svg")).contains("<svg"));
        assert!(
            read(&base.with_extension("csv")).lines().count() > 2,
            "{figure}"
        );
    }
    assert!(printed.contains("break-even camera noise"), "{printed}");
    // Golden value: replicate 0 at Δv = 0.035 accepts this many codewords of 340.
    let runs = read(&out.join("dv-sweep/runs.csv"));
    let row = runs
        .lines()
        .find(|l| l.starts_with("0.035,0,"))
        .expect("Δv = 0.035, replicate 0");
    assert_eq!(row.split(',').nth(3), Some(GOLDEN_ACCEPTED));

    // Its terminal summary states the headline findings.
    for finding in [
        "accepted share rises with Δv",
        "agrees with the paper",
        "Eve's disagreement: the same at every α; the paper's trend does not reproduce",
        "secret bits, dv-sweep: 0 at every point, against every adversary",
        "eavesdroppers that came to decide as well as the controller, of 5 campaigns:\n  oracle",
        "private sensing:",
    ] {
        assert!(printed.contains(finding), "{finding}: {printed}");
    }

    // A cluster run of the paper: shards of experiments/paper.toml, merged, reported — the
    // same files as `reproduce`, byte for byte.
    let paper = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../experiments/paper.toml");
    let shards: Vec<PathBuf> = (1..=2).map(|i| dir.join(format!("shard-{i}"))).collect();
    for (i, shard) in shards.iter().enumerate() {
        let printed = ok(&[
            "sweep",
            s(&paper),
            "--set",
            "run.replicates=3",
            "--shard",
            &format!("{}/2", i + 1),
            "--out",
            s(shard),
        ]);
        assert!(
            printed.contains("dv-sweep: 11 points × 3 replicates (shard"),
            "{printed}"
        );
    }
    let merged = dir.join("merged");
    let printed = ok(&["merge", s(&shards[0]), s(&shards[1]), "--out", s(&merged)]);
    assert!(printed.contains("dv-sweep: 33 runs"), "{printed}");
    // The paper's report renders the stages `reproduce` computes: a merge has none yet, and
    // `reproduce --resume` computes them.
    let err = fails_with(2, &["report", s(&merged)]);
    let resume = format!("robokey reproduce --resume {} --quick", merged.display());
    assert!(err.contains(&resume), "{err}");
    ok(&["reproduce", "--resume", s(&merged), "--quick"]);
    assert_same_files(&out, &merged);
    // A report is a function of its folder: rendered again, every file is the same.
    let printed = ok(&["report", s(&out)]);
    assert!(printed.contains("private sensing:"), "{printed}");
    assert_same_files(&out, &merged);
}

const GOLDEN_ACCEPTED: &str = "298";

#[test]
fn secrecy_sizes_keys_by_the_assumption_labels_adversaries_and_ignores_jobs() {
    let dir = scratch("secrecy");
    let config = dir.join("weak.toml");
    std::fs::write(
        &config,
        "[code]\nn_c = 1\n[eve]\nalpha = 0.95\n[run]\nreplicates = 1\n[sweep]\n\"protocol.delta_v\" = [0.035]\n",
    )
    .unwrap();
    let sweep = dir.join("sweep");
    ok(&["sweep", s(&config), "--out", s(&sweep)]);
    let mut json = Vec::new();
    for jobs in ["1", "2"] {
        let out = ok(&[
            "secrecy",
            s(&sweep),
            "--adversary",
            "mismatch",
            "--adversary",
            "oracle",
            "--pooling",
            "complete",
            "--block",
            "20000",
            "--assume-eve-error",
            "0.2",
            "--jobs",
            jobs,
        ]);
        assert!(
            out.contains("secret key rate 0: zero by structure"),
            "{out}"
        );
        assert!(
            out.contains("(restricted)") && out.contains("(strongest)"),
            "{out}"
        );
        // The oracle Eve knows the key: an assumption that credits bits is loudly violated.
        assert!(
            out.contains("WARNING: the assumption credits") && out.contains("oracle Eve"),
            "{out}"
        );
        json.push(read(&sweep.join("secrecy.json")));
    }
    assert_eq!(json[0], json[1], "--jobs changed the results");
    let v: serde_json::Value = serde_json::from_str(&json[0]).unwrap();
    let rows = v["results"].as_array().unwrap();
    assert_eq!(rows[0]["adversary_class"], "strongest");
    assert_eq!(rows[0]["realised_secret_bits"], 0);
    assert_eq!(rows[0]["assumption_exceeds_realised"], true);
    let restricted = &rows[1];
    assert_eq!(restricted["adversary"], "mismatch");
    assert_eq!(restricted["adversary_class"], "restricted");
    assert!(
        restricted["q_source"]
            .as_str()
            .unwrap()
            .contains("disclosed")
    );
    let block = &restricted["blocks"][0];
    for field in [
        "leak_ec",
        "leak_confirmation",
        "h_min_method",
        "bits",
        "errors_before",
        "h_min",
        "leak",
        "secret_bits",
        "messages",
        "realised",
    ] {
        assert!(
            !block[field].is_null(),
            "block field {field} missing: {block}"
        );
    }
    assert_eq!(block["leak_confirmation"], 128);
    assert!(restricted["secret_bits"].as_u64().unwrap() > 0);
    assert!(restricted["zero_reason"].is_null());
    assert!(restricted["assumption"].as_str().unwrap().contains("0.2"));
    // Without a stated assumption the key length is zero by structure.
    ok(&[
        "secrecy",
        s(&sweep),
        "--pooling",
        "complete",
        "--block",
        "20000",
    ]);
    let v: serde_json::Value = serde_json::from_str(&read(&sweep.join("secrecy.json"))).unwrap();
    for row in v["results"].as_array().unwrap() {
        assert_eq!(row["secret_bits"], 0, "{row}");
        assert!(
            row["zero_reason"]
                .as_str()
                .unwrap()
                .contains("zero by structure")
        );
    }
    let err = fails(&["secrecy", s(&sweep), "--assume-eve-error", "0.7"]);
    assert!(err.contains("--assume-eve-error 0.7"), "{err}");
    let err = fails(&["secrecy", s(&sweep), "--block", "10"]);
    assert!(
        err.contains("--block 10") && err.contains("allowed"),
        "{err}"
    );
}

#[test]
fn private_sensing_runs_end_to_end_from_the_command_line() {
    let dir = scratch("private");
    let run = ok(&[
        "run",
        "--set",
        "sensing.mode=private",
        "--out",
        s(&dir.join("run")),
    ]);
    assert!(
        run.contains("doublets") && run.contains("raw key bits"),
        "{run}"
    );
    let trace = read(&dir.join("run/trace.csv"));
    assert!(
        trace
            .lines()
            .next()
            .unwrap()
            .ends_with("eve_x,eve_y,eve_theta")
    );

    // A sweep file's [secrecy] table sets the block size; the defaults are the private
    // adversaries and complete pooling.
    let file = dir.join("private.toml");
    std::fs::write(
        &file,
        "[sensing]\nmode = \"private\"\n[run]\nreplicates = 2\n[secrecy]\nblock_bits = 3000\n\
         [sweep]\n\"eve.camera_std\" = [[0.008, 0.008, 0.008], [0.001, 0.001, 0.001]]\n",
    )
    .unwrap();
    let sweep = dir.join("sweep");
    ok(&["sweep", s(&file), "--out", s(&sweep)]);
    let printed = ok(&["secrecy", s(&sweep)]);
    assert!(printed.contains("key sized under"), "{printed}");
    assert!(
        printed.contains("camera") && printed.contains("commands"),
        "{printed}"
    );
    assert!(printed.contains("break-even camera noise"), "{printed}");
    let json: serde_json::Value = serde_json::from_str(&read(&sweep.join("secrecy.json"))).unwrap();
    assert_eq!(json["block_bits"], 3000);
    assert_eq!(json["pooling"], "complete");
    let rows = json["results"].as_array().unwrap();
    let rate = |camera: &str| {
        rows.iter()
            .find(|r| r["adversary"] == "camera" && r["point"].as_str().unwrap().contains(camera))
            .unwrap()["secret_bits"]
            .as_u64()
            .unwrap()
    };
    assert!(rate("0.008") > 0 && rate("0.001") == 0, "{json}");
    for file in [
        "turn-rates.csv",
        "private-rate-vs-camera.csv",
        "private-rate-vs-camera.svg",
    ] {
        assert!(sweep.join(file).exists(), "{file}");
    }

    let refused = fails(&["secrecy", s(&sweep), "--adversary", "oracle"]);
    assert!(
        refused.contains("oracle") && refused.contains("private"),
        "{refused}"
    );

    // Cascade reads no LLRs: a model to compute them with is refused where it reconciles
    // (here by default), before anything is computed or written.
    let before = read(&sweep.join("secrecy.json"));
    let refused = fails_with(2, &["secrecy", s(&sweep), "--llrs", "measured"]);
    assert!(
        refused.contains("--llrs measured is not allowed")
            && refused.contains("prior with reconciliation cascade (the default)"),
        "{refused}"
    );
    assert_eq!(read(&sweep.join("secrecy.json")), before);

    // The file may state the reconciliation and the sizing; a flag overrides the file; a value
    // outside the vocabulary is refused, naming the file, the field, the value and what is
    // allowed.
    let stated = dir.join("private-ldpc.toml");
    std::fs::write(
        &stated,
        "[sensing]\nmode = \"private\"\n[run]\nreplicates = 2\n[secrecy]\nblock_bits = 3000\n\
         reconciliation = \"ldpc\"\nsizing = \"world\"\n",
    )
    .unwrap();
    let stated_sweep = dir.join("sweep-ldpc");
    ok(&["sweep", s(&stated), "--out", s(&stated_sweep)]);
    let settings = |args: &[&str]| {
        ok(&[&["secrecy", s(&stated_sweep)], args].concat());
        let json: serde_json::Value =
            serde_json::from_str(&read(&stated_sweep.join("secrecy.json"))).unwrap();
        (json["reconciliation"].clone(), json["sizing"].clone())
    };
    assert_eq!(settings(&[]), ("ldpc".into(), "world".into()));
    assert_eq!(
        settings(&["--reconciliation", "cascade", "--sizing", "configured"]),
        (serde_json::Value::Null, serde_json::Value::Null)
    );
    let refused = fails_with(
        2,
        &[
            "secrecy",
            s(&stated_sweep),
            "--reconciliation",
            "cascade",
            "--llrs",
            "world",
        ],
    );
    assert!(
        refused.contains("--llrs world is not allowed")
            && refused.contains("reconciliation cascade (asked for)"),
        "{refused}"
    );
    std::fs::write(&stated, "[secrecy]\nreconciliation = \"turbo\"\n").unwrap();
    let refused = fails_with(2, &["sweep", s(&stated), "--out", s(&dir.join("turbo"))]);
    assert!(
        refused.contains("private-ldpc.toml")
            && refused.contains("[secrecy] reconciliation = \"turbo\" is not allowed")
            && refused.contains("(allowed: \"cascade\", \"ldpc\")"),
        "{refused}"
    );

    let eve = ok(&[
        "eve",
        "--set",
        "sensing.mode=private",
        "--sessions",
        "3",
        "--out",
        s(&dir.join("eve")),
    ]);
    assert!(eve.contains("camera") && eve.contains("predicted"), "{eve}");
    assert!(read(&dir.join("eve/eve.md")).contains("by public turn rate"));
    let refused = fails_with(
        2,
        &[
            "eve",
            "--set",
            "sensing.mode=private",
            "--strategy",
            "identify",
        ],
    );
    assert!(refused.contains("identify"), "{refused}");
    let refused = fails_with(2, &["eve", "--capture", "no.pcap", "--errors", "0.1,x,0,0"]);
    assert!(refused.contains("\"x\" is not a number"), "{refused}");
}

/// A suite of two small experiments, one keeping traces.
const SMALL_SUITE: &str = "[trajectory]\nlaps = 1\n[run]\nreplicates = 3\n\
    [experiment.gains.sweep]\ntraces = true\n\"controller.kp\" = [1.0, 1.2]\n\
    \"protocol.delta_v\" = [0.02, 0.035]\n[experiment.alpha.sweep]\n\"eve.alpha\" = [0.0, 0.1]\n";

#[test]
fn a_suite_merges_and_reports_the_same_as_on_one_machine() {
    let dir = scratch("suite");
    let file = dir.join("suite.toml");
    std::fs::write(&file, SMALL_SUITE).unwrap();
    let local = dir.join("local");
    ok(&["sweep", s(&file), "--out", s(&local)]);
    let printed = ok(&["report", s(&local)]);
    assert!(
        printed.contains("gains: 4 points × 3 replicates"),
        "{printed}"
    );
    let report = read(&local.join("report.md"));
    assert!(
        report.contains("## gains") && report.contains("| controller.kp | Δv (m/s) | accepted (%)"),
        "{report}"
    );
    for figure in [
        "gains-accepted",
        "gains-jx",
        "gains-trajectory",
        "alpha-eve-disagreement",
    ] {
        assert!(read(&local.join("figures").join(figure).with_extension("svg")).contains("<svg"));
    }
    let shards: Vec<PathBuf> = (1..=3).map(|i| dir.join(format!("shard-{i}"))).collect();
    for (i, shard) in shards.iter().enumerate() {
        ok(&[
            "sweep",
            s(&file),
            "--shard",
            &format!("{}/3", i + 1),
            "--out",
            s(shard),
        ]);
    }
    let merged = dir.join("merged");
    let dirs: Vec<&str> = shards.iter().map(|d| s(d)).collect();
    ok(&[&["merge"], dirs.as_slice(), &["--out", s(&merged)]].concat());
    ok(&["report", s(&merged)]);
    assert_same_files(&local, &merged);
    // Shards of different suites, a lone shard, an experiment missing: named errors.
    let err = fails_with(
        1,
        &[
            "merge",
            s(&shards[0]),
            s(&local.join("gains")),
            "--out",
            s(&dir.join("x")),
        ],
    );
    assert!(err.contains("shards of different suites"), "{err}");
    let err = fails_with(2, &["report", s(&shards[0])]);
    assert!(err.contains("merge the shards first"), "{err}");
}

#[test]
fn sigint_keeps_the_finished_runs_and_resume_ends_as_an_uninterrupted_sweep() {
    use std::io::BufRead;
    let dir = scratch("sigint");
    // `long` takes seconds on one thread, so the signal sent once it starts lands in it.
    let file = dir.join("suite.toml");
    std::fs::write(
        &file,
        "[trajectory]\nlaps = 1\n[run]\nreplicates = 2\n[experiment.first.sweep]\n\
         \"protocol.delta_v\" = [0.02, 0.035]\n[experiment.long]\nrun.replicates = 5000\n\
         [experiment.last]\n",
    )
    .unwrap();
    let out = dir.join("out");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_robokey"))
        .args(["sweep", s(&file), "--jobs", "1", "--out", s(&out)])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = std::io::BufReader::new(child.stdout.take().unwrap()).lines();
    // The header of each experiment comes before its runs.
    let header = lines.next().unwrap().unwrap();
    assert!(
        header.starts_with("first: 2 points × 2 replicates →"),
        "{header}"
    );
    let header = lines.next().unwrap().unwrap();
    assert!(header.starts_with("long: 1 point"), "{header}");
    // Give `long` a moment to finish some runs (on a loaded machine it may finish none: both
    // cases are checked below).
    std::thread::sleep(std::time::Duration::from_millis(300));
    let killed = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let ended = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&ended.stderr).into_owned();
    assert_eq!(ended.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("interrupted by SIGINT"), "{stderr}");
    assert!(
        stderr.contains("  first: complete") && stderr.contains("  last: not started"),
        "{stderr}"
    );
    let manifest = |name: &str| -> serde_json::Value {
        serde_json::from_str(&read(&out.join(name).join("manifest.json"))).unwrap()
    };
    assert_eq!(manifest("first")["complete"], true);
    assert_eq!(manifest("long")["complete"], false);
    assert_eq!(manifest("last")["runs_done"], 0);
    let long_runs = manifest("long")["runs_done"].as_u64().unwrap();
    assert!(long_runs < 5000, "{long_runs}");
    assert_eq!(
        read(&out.join("long/runs.csv")).lines().count() as u64,
        1 + long_runs
    );
    assert!(!out.join("long/summary.json").exists());
    // An incomplete folder is refused by merge and report, naming the way out.
    let err = fails_with(2, &["report", s(&out)]);
    assert!(
        err.contains("interrupted sweep") && err.contains("--resume"),
        "{err}"
    );
    // The printed command continues it.
    let again = stderr
        .lines()
        .find_map(|l| l.strip_prefix("continue with: robokey "))
        .unwrap_or_else(|| panic!("no way to continue in {stderr}"));
    let again: Vec<&str> = again.split_whitespace().collect();
    assert_eq!(again.last(), Some(&s(&out)));
    let printed = ok(&[again.as_slice(), &["--jobs", "2"]].concat());
    // The resumed header counts the runs kept; none kept, it starts `long` afresh.
    assert_eq!(
        printed.contains(&format!("(resumed: {long_runs} of 5000 runs done)")),
        long_runs > 0,
        "{printed}"
    );
    let whole = dir.join("whole");
    ok(&["sweep", s(&file), "--out", s(&whole)]);
    assert_same_files(&whole, &out);
    assert!(read(&out.join("long/manifest.json")) == read(&whole.join("long/manifest.json")));
    // Another sweep file cannot continue it.
    let err = fails_with(
        2,
        &[
            "sweep",
            s(&file),
            "--set",
            "run.seed=1",
            "--resume",
            s(&out),
        ],
    );
    assert!(
        err.contains("cannot resume") && err.contains("different configuration"),
        "{err}"
    );

    // SIGTERM: 143.
    let single = dir.join("single.toml");
    std::fs::write(&single, "[run]\nreplicates = 100000\n").unwrap();
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_robokey"))
        .args([
            "sweep",
            s(&single),
            "--jobs",
            "1",
            "--out",
            s(&dir.join("term")),
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut lines = std::io::BufReader::new(child.stdout.take().unwrap()).lines();
    assert!(lines.next().unwrap().unwrap().starts_with("sweep: 1 point"));
    std::process::Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert_eq!(child.wait().unwrap().code(), Some(143));
}

#[test]
fn force_leaves_nothing_of_the_previous_sweep() {
    let dir = scratch("stale");
    let file = dir.join("traces.toml");
    std::fs::write(
        &file,
        "[trajectory]\nlaps = 1\n[run]\nreplicates = 1\n[sweep]\ntraces = true\n\"eve.alpha\" = [0.0, 0.1]\n",
    )
    .unwrap();
    let out = dir.join("out");
    ok(&["sweep", s(&file), "--out", s(&out)]);
    assert!(out.join("traces/point-1.csv").exists());
    // What `robokey secrecy` and `robokey report` would have added.
    for stale in ["secrecy.csv", "secrecy.json", "secrecy.md", "report.md"] {
        std::fs::write(out.join(stale), "old").unwrap();
    }
    std::fs::write(&file, "[trajectory]\nlaps = 1\n[run]\nreplicates = 1\n").unwrap();
    ok(&["sweep", s(&file), "--force", "--out", s(&out)]);
    let left: Vec<PathBuf> = files(&out).into_keys().collect();
    assert_eq!(
        left,
        [
            "config.resolved.toml",
            "manifest.json",
            "runs.csv",
            "summary.json"
        ]
        .map(PathBuf::from)
    );
}

#[test]
fn arguments_read_as_users_write_them() {
    // Negative numbers are values, refused by name and range.
    let err = fails_with(2, &["run", "--delta-v", "-1"]);
    assert_eq!(
        err.trim(),
        "error: --delta-v -1: `protocol.delta_v` = -1.0 is not allowed (allowed: ≥ 0, finite)"
    );
    let err = fails_with(2, &["run", "--set", "controller.kp=abc"]);
    assert!(
        err.contains("--set controller.kp=abc: invalid type") && !err.contains("TOML parse error"),
        "{err}"
    );
    let err = fails_with(2, &["run", "--seed", "-3"]);
    assert!(err.contains("invalid value '-3' for '--seed"), "{err}");
    let sweep = scratch("args");
    std::fs::write(sweep.join("config.resolved.toml"), "").unwrap();
    let err = fails_with(2, &["secrecy", s(&sweep), "--blocks", "0"]);
    assert!(
        err.contains("--blocks 0 is not allowed (allowed: 1 to 1000)"),
        "{err}"
    );
    let err = fails_with(2, &["secrecy", s(&sweep), "--eps", "-0.1"]);
    assert!(err.contains("--eps -0.1 is not allowed"), "{err}");
    let robot = ["robot", "--listen", "127.0.0.1:0", "--unauthenticated"];
    let err = fails_with(2, &[&robot[..], &["--block-timeout", "0"]].concat());
    assert!(
        err.contains("--block-timeout 0 is not allowed (allowed: 0.001 to 86400 seconds)"),
        "{err}"
    );
    let help = ok(&["robot", "--help"]);
    assert!(
        help.contains("--block-timeout") && help.contains("[default: 30]"),
        "{help}"
    );
    let help = ok(&["secrecy", "--help"]);
    assert!(
        help.contains("<SWEEP_DIR>") && !help.contains("RUN_DIR"),
        "{help}"
    );
    let help = ok(&["sweep", "--help"]);
    assert!(help.contains("--resume <DIR>"), "{help}");
    let help = ok(&["--help"]);
    assert!(
        help.contains("Exit codes: 0 success") && help.contains("--resume"),
        "{help}"
    );
    let version = ok(&["--version"]);
    assert!(
        version.starts_with("robokey 0.") && version.contains("(commit "),
        "{version}"
    );
    // `robokey config`: units as comments, and still a config robokey reads.
    let printed = ok(&["config", "--set", "protocol.delta_v=0.03"]);
    assert!(printed.contains("delta_v = 0.03  # m/s: Δv"), "{printed}");
    let file = sweep.join("printed.toml");
    std::fs::write(&file, &printed).unwrap();
    assert_eq!(ok(&["config", "--config", s(&file)]), printed);
    let err = fails_with(
        2,
        &["sweep", s(&file), "--out", s(&sweep), "--resume", s(&sweep)],
    );
    assert!(err.contains("cannot be used with"), "{err}");
}

#[test]
fn a_reader_that_goes_away_ends_the_output_without_a_panic() {
    use std::os::unix::process::ExitStatusExt;
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_robokey"))
        .arg("config")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // As `robokey config | true` does: the reader is gone before robokey writes.
    drop(child.stdout.take());
    let ended = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&ended.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(
        ended.status.success() || ended.status.signal() == Some(13),
        "{:?}: {stderr}",
        ended.status
    );
}

/// Without the `ros2` feature every ROS 2 entry point is a usage error saying how to build.
#[cfg(not(feature = "ros2"))]
#[test]
fn ros2_without_the_feature_says_how_to_build() {
    let built = "built without ROS 2 support: build it with `cargo build --release --features \
                 robokey-cli/ros2`";
    let text = fails_with(
        2,
        &[
            "controller",
            "--robot",
            "127.0.0.1:9",
            "--unauthenticated",
            "--pace",
            "lockstep",
            "--set",
            "sensing.mode=private",
            "--sensor",
            "ros2:/mocap/robot/pose",
        ],
    );
    assert!(
        text.contains("--sensor ros2:/mocap/robot/pose") && text.contains(built),
        "{text}"
    );
    let text = fails_with(2, &["ros2-sim"]);
    assert!(text.contains(built), "{text}");
}

/// `robokey threat`: a camera per instant and in frames, the break-even, and named errors.
#[test]
fn threat_prints_each_cameras_rate_and_the_break_even() {
    let small = ["--set", "postprocess.block_bits=2000"];
    let mut args = vec![
        "threat",
        "--camera-std",
        "8",
        "--fps",
        "5",
        "--frame-std",
        "8",
    ];
    args.extend(small);
    let text = ok(&args);
    assert!(
        text.contains("8 mm, 8 mm, 8 mrad per sample instant"),
        "{text}"
    );
    // 5 frames/s at T = 0.2 s: one frame at each mid instant is worth itself.
    let frames = text
        .lines()
        .find(|l| l.starts_with("8 mm, 8 mm, 8 mrad per frame at 5 frames/s"))
        .unwrap_or_else(|| panic!("{text}"));
    assert!(frames.contains(" 8.00 "), "{frames}");
    assert!(text.contains("break-even camera: between "), "{text}");
    assert!(text.contains("at 5 frames/s: between "), "{text}");
    let error = fails_with(2, &["threat", "--camera-std", "0"]);
    assert!(
        error.contains("--camera-std 0: 0 is not allowed (allowed: > 0)"),
        "{error}"
    );
    let error = fails_with(2, &["threat", "--fps", "30"]);
    assert!(error.contains("--frame-std"), "{error}");
    let error = fails_with(2, &["threat", "--fps", "2000", "--frame-std", "8"]);
    assert!(
        error.contains("eve.camera_fps") && error.contains("at most 1000"),
        "{error}"
    );
}

/// `robokey prior`: a calibration run's reports become the configuration to state — a
/// two-step block refused for a lag (its unmeasured noise written as `null`) names the lag,
/// a later three-step block the noise and the lag; the output loads as a configuration; a
/// robot's report and reports without an estimate are usage errors naming the file.
#[test]
fn prior_states_what_the_controllers_last_block_estimate_measured() {
    let dir = scratch("prior");
    let report = |name: &str, role: &str, estimates: &str| {
        let path = dir.join(name);
        let text = format!(r#"{{"role": "{role}", "post": {{"estimates": [{estimates}]}}}}"#);
        std::fs::write(&path, text).unwrap();
        path.display().to_string()
    };
    let common = r#""lower_std_mm": [null, null, null], "correlation": null,
        "correlation_interval": [null, null], "epsilon": 1e-6, "separation": 1000000.0,
        "largest": 1000000.0"#;
    let refused = report(
        "refused.json",
        "controller",
        &format!(
            r#"{{"doublets": 4187, "point_std_mm": [null, null, null], {common},
            "refused": "actuator lag: …", "unmodelled_lag": [0.0498, 0.0446, 0.0551]}}"#
        ),
    );
    let measured = report(
        "measured.json",
        "controller",
        r#"{"doublets": 2212, "point_std_mm": [0.9632, 1.0114, 0.9514],
        "lower_std_mm": [0.844, 0.897, 0.832], "correlation": 0.022,
        "correlation_interval": [-0.1, 0.124], "epsilon": 1e-6, "separation": 1.40234375,
        "largest": 1.62109375, "refused": null, "lag": [0.04965, 0.04759, 0.05173]}"#,
    );
    let text = ok(&["prior", &refused]);
    assert!(
        text.contains("private.prior_lag = 0.0498 (was 0): the two-step block was refused"),
        "{text}"
    );
    assert!(!text.contains("noise.process_std ="), "unmeasured: {text}");
    assert!(
        text.contains("That block was refused: actuator lag"),
        "{text}"
    );
    // The last estimate of the reports given, oldest first.
    let text = ok(&["prior", &refused, &measured]);
    let stated = dir.join("prior.toml");
    std::fs::write(&stated, &text).unwrap();
    let loaded = ok(&["config", "-c", &stated.display().to_string()]);
    for line in [
        "mode = \"private\"",
        "prior_lag = 0.0497",
        "process_std = [0.000963, 0.001011, 0.000951]",
    ] {
        assert!(loaded.contains(line), "{line}: {loaded}");
    }
    let robot = report("robot.json", "robot", "");
    let error = fails_with(2, &["prior", &robot]);
    assert!(error.contains("robot.json: role \"robot\""), "{error}");
    let empty = report("empty.json", "controller", "");
    let error = fails_with(2, &["prior", &empty]);
    assert!(
        error.contains("no block estimate in") && error.contains("empty.json"),
        "{error}"
    );
}
