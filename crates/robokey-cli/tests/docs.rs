//! What the README and docs/ show is what robokey takes. Every command shown with
//! configuration options (in a code block, or inline) loads: `robokey config` with the same
//! `--config` and `--set`s succeeds. Every configuration field named in backticks exists.
//! Every error a console block shows after a `$ robokey …` line is the error that command
//! prints.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The repository's root.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// README.md and every docs/*.md, with their names.
fn documents() -> Vec<(String, String)> {
    let mut paths = vec![root().join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    paths.extend(docs);
    paths
        .into_iter()
        .map(|p| {
            let name = p.strip_prefix(root()).unwrap_or(&p).display().to_string();
            (name, std::fs::read_to_string(&p).unwrap())
        })
        .collect()
}

/// Runs `robokey args…` in a scratch folder (a command that succeeded by mistake writes
/// there, not into the repository).
fn robokey(args: &[String]) -> Output {
    let dir = std::env::temp_dir().join(format!("robokey-docs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    Command::new(env!("CARGO_BIN_EXE_robokey"))
        .args(args)
        .current_dir(&dir)
        .env_remove("RUST_LOG")
        .output()
        .unwrap()
}

/// A command as a document shows it, with what the document shows it printing on stderr
/// when that is an error.
#[derive(Debug)]
struct Shown {
    place: String,
    words: Vec<String>,
    error: Option<String>,
}

/// Splits a shell command line into words: spaces separate, quotes group, a backslash at
/// the end of a line continues it, `#` after a space starts a comment.
fn words(line: &str) -> Vec<String> {
    let mut words = Vec::new();
    let mut word = String::new();
    let mut quote = None;
    let mut started = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (quote, c) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), c) => word.push(c),
            (None, '\'' | '"') => {
                quote = Some(c);
                started = true;
            }
            (None, '#') if !started => break,
            (None, c) if c.is_whitespace() => {
                if started {
                    words.push(std::mem::take(&mut word));
                    started = false;
                }
            }
            (None, '\\') if chars.peek().is_none_or(|n| n.is_whitespace()) => {}
            (None, c) => {
                word.push(c);
                started = true;
            }
        }
    }
    if started {
        words.push(word);
    }
    words
}

/// The commands of `text`'s shell and console blocks (continuation lines joined, `$ `
/// prompts removed) and of its inline code spans that start with `robokey ` or hold a
/// `--set`.
fn commands(name: &str, text: &str) -> Vec<Shown> {
    let mut shown = Vec::new();
    let mut in_block = None;
    let mut pending = String::new();
    let mut pending_line = 0;
    let lines: Vec<&str> = text.lines().collect();
    for (number, line) in lines.iter().enumerate() {
        if let Some(fence) = line.trim_start().strip_prefix("```") {
            in_block = match in_block {
                None => Some(fence.trim() == "console"),
                Some(_) => None,
            };
            continue;
        }
        let Some(console) = in_block else {
            for span in line.split('`').skip(1).step_by(2) {
                if span.starts_with("robokey ") || span.contains("--set") {
                    shown.push(Shown {
                        place: format!("{name}:{}", number + 1),
                        words: words(span),
                        error: None,
                    });
                }
            }
            continue;
        };
        let command = if console {
            match line.strip_prefix("$ ") {
                Some(command) => command,
                None if !pending.is_empty() => line,
                None => continue,
            }
        } else {
            line
        };
        if pending.is_empty() {
            pending_line = number + 1;
        }
        pending.push_str(command.trim_end().trim_end_matches('\\'));
        pending.push(' ');
        if command.trim_end().ends_with('\\') {
            continue;
        }
        let error = console
            .then(|| lines.get(number + 1))
            .flatten()
            .filter(|next| next.starts_with("error: "))
            .map(|next| (*next).to_owned());
        shown.push(Shown {
            place: format!("{name}:{pending_line}"),
            words: words(&pending),
            error,
        });
        pending.clear();
    }
    shown
}

/// The `robokey` arguments of a shown command (after `robokey` or `cargo run … --`).
fn robokey_args(words: &[String]) -> Option<Vec<String>> {
    let start = words
        .iter()
        .position(|w| w == "robokey" || w.ends_with("/robokey"))
        .map(|i| i + 1)
        .or_else(|| {
            (words.first()? == "cargo" && words.get(1)? == "run")
                .then(|| words.iter().position(|w| w == "--").map(|i| i + 1))?
        })?;
    Some(words[start..].to_vec())
}

/// The configuration options of a shown command: its `--config FILE` (unless a sweep's)
/// and its `--set`s, or `None` when it holds a placeholder.
fn configuration(words: &[String]) -> Option<Vec<String>> {
    let mut options = Vec::new();
    let mut i = 0;
    while i < words.len() {
        let (flag, value) = match words[i].split_once('=') {
            Some((flag @ "--set", value)) => (flag, Some(value.to_owned())),
            _ => (words[i].as_str(), words.get(i + 1).cloned()),
        };
        match (flag, value) {
            ("--set", Some(value)) => options.extend(["--set".to_owned(), value]),
            ("--config" | "-c", Some(file)) if root().join(&file).is_file() => {
                let text = std::fs::read_to_string(root().join(&file)).unwrap();
                if !text.contains("[sweep]") && !text.contains("[experiment.") {
                    options.extend([
                        "--config".to_owned(),
                        root().join(file).display().to_string(),
                    ]);
                }
            }
            _ => {}
        }
        i += 1;
    }
    // `scripts/pooled-sessions.py` runs both agents in private sensing unless told
    // `--mode odometry`, after the `--set`s it is given.
    let pooled = words.iter().any(|w| w.ends_with("pooled-sessions.py"));
    if pooled
        && !words
            .windows(2)
            .any(|w| w[0] == "--mode" && w[1] == "odometry")
    {
        options.extend(["--set".to_owned(), "sensing.mode=private".to_owned()]);
    }
    let placeholder = options
        .iter()
        .any(|o| o.contains('…') || o.contains("FIELD") || o.contains('{'));
    (!options.is_empty() && !placeholder).then_some(options)
}

#[test]
fn every_configuration_a_document_shows_loads() {
    let mut checked = 0;
    let mut failures = Vec::new();
    for (name, text) in documents() {
        for shown in commands(&name, &text) {
            if shown.error.is_some() {
                continue; // shown failing: checked below
            }
            let Some(options) = configuration(&shown.words) else {
                continue;
            };
            let mut args = vec!["config".to_owned()];
            args.extend(options);
            let out = robokey(&args);
            checked += 1;
            if !out.status.success() {
                failures.push(format!(
                    "{}: `{}`: {}",
                    shown.place,
                    shown.words.join(" "),
                    String::from_utf8_lossy(&out.stderr).trim()
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert!(
        checked >= 15,
        "only {checked} commands with --set or --config were found"
    );
}

#[test]
fn every_error_a_console_block_shows_is_the_one_robokey_prints() {
    let mut checked = 0;
    for (name, text) in documents() {
        for shown in commands(&name, &text) {
            let Some(error) = &shown.error else {
                continue;
            };
            let args = robokey_args(&shown.words)
                .unwrap_or_else(|| panic!("{}: not a robokey command", shown.place));
            let out = robokey(&args);
            let printed = String::from_utf8_lossy(&out.stderr);
            assert_eq!(
                printed.trim_end(),
                error,
                "{}: `{}`",
                shown.place,
                shown.words.join(" ")
            );
            assert_eq!(out.status.code(), Some(2), "{}", shown.place);
            checked += 1;
        }
    }
    assert!(checked >= 3, "only {checked} shown errors were found");
}

/// Configuration sections, and names after them that are files, not fields.
const SECTIONS: [&str; 12] = [
    "robot",
    "noise",
    "sensing",
    "trajectory",
    "controller",
    "observer",
    "protocol",
    "code",
    "eve",
    "run",
    "postprocess",
    "private",
];
const FILE_EXTENSIONS: [&str; 12] = [
    "svg", "png", "pdf", "csv", "json", "key", "toml", "md", "rs", "pcap", "py", "sh",
];

/// Every `section.field` in `span` (a section name that starts a word, a field that is not
/// a file extension), with where it starts.
fn named_fields(span: &str) -> Vec<(String, usize)> {
    let identifier = |c: char| c.is_ascii_alphanumeric() || c == '_';
    let mut found = Vec::new();
    for section in SECTIONS {
        for (at, _) in span.match_indices(&format!("{section}.")) {
            if span[..at].chars().next_back().is_some_and(identifier) {
                continue;
            }
            let field: String = span[at + section.len() + 1..]
                .chars()
                .take_while(|&c| identifier(c))
                .collect();
            if !field.is_empty() && !FILE_EXTENSIONS.contains(&field.as_str()) {
                found.push((format!("{section}.{field}"), at));
            }
        }
    }
    found
}

#[test]
fn every_configuration_field_named_in_backticks_exists() {
    let mut fields = std::collections::BTreeMap::<String, String>::new();
    for (name, text) in documents() {
        for (number, line) in text.lines().enumerate() {
            for span in line.split('`').skip(1).step_by(2) {
                for (field, _) in named_fields(span) {
                    fields
                        .entry(field)
                        .or_insert_with(|| format!("{name}:{}", number + 1));
                }
            }
        }
    }
    assert!(
        fields.len() >= 30,
        "only {} fields named: {fields:?}",
        fields.len()
    );
    let unknown: Vec<String> = fields
        .iter()
        .filter(|(field, _)| {
            // Any value: a wrong type or range is another error than an unknown field.
            let out = robokey(&["config".into(), "--set".into(), format!("{field}=0")]);
            String::from_utf8_lossy(&out.stderr).contains("unknown field")
        })
        .map(|(field, place)| format!("{place}: `{field}` is no configuration field"))
        .collect();
    assert!(unknown.is_empty(), "{}", unknown.join("\n"));
}
