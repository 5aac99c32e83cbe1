//! Sweeping into a folder: interruptible, and resumable to the same bytes.

use std::path::{Path, PathBuf};

use robokey::interrupt::Interrupt;

use super::layout::{experiment_dirs, folder_name, read_rows, write_folder};
use super::manifest::{planned, read_manifest, sha256_hex};
use super::rows::Rows;
use crate::error::LabError;
use crate::experiment::Experiment;
use crate::output::read;
use crate::parquet_table::TableFormat;
use crate::run::sessions::KeptSessions;
use crate::run::{Shard, run_experiment};
use crate::trace::point_trace_path;

/// Which runs a sweep does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SweepPlan {
    /// Only this shard (`None`: all runs, or on resume the shard the folder holds).
    pub shard: Option<Shard>,
    /// Continue the folder of an interrupted sweep: run only what it does not hold yet.
    pub resume: bool,
    /// The format of the runs table and traces of a complete folder (an incomplete one is
    /// kept in CSV, which `--resume` reads).
    pub format: TableFormat,
}

/// What one experiment of a sweep is about to do, for the caller to announce.
#[derive(Clone, Copy, Debug)]
pub struct Start<'a> {
    /// The experiment.
    pub experiment: &'a Experiment,
    /// Its folder.
    pub dir: &'a Path,
    /// The shards it runs.
    pub shards: &'a [Shard],
    /// Runs its folder holds already.
    pub done: usize,
    /// Runs of its shards.
    pub planned: usize,
}

/// How far one experiment's folder got.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Progress {
    /// The experiment's name (empty for a single sweep).
    pub name: String,
    /// Its folder.
    pub dir: PathBuf,
    /// Runs it holds.
    pub done: usize,
    /// Runs of its shards.
    pub planned: usize,
}

impl Progress {
    /// Whether it holds every run of its shards.
    #[must_use]
    pub fn complete(&self) -> bool {
        self.done == self.planned
    }
}

/// How a sweep ended.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Swept {
    /// Each experiment's folder, in the suite's order.
    pub experiments: Vec<Progress>,
    /// The signal that stopped it before every folder was complete.
    pub interrupted: Option<usize>,
}

/// One experiment's folder and what it holds.
struct Folder {
    dir: PathBuf,
    shards: Vec<Shard>,
    rows: Rows,
}

/// Sweeps `experiments` into `out` (a single experiment into `out` itself, a suite's into
/// `out/NAME`) on the current rayon pool.
///
/// Every folder is written, with a manifest saying how much it holds, before the first run
/// starts. Once `stop` is requested no new run starts; the runs that finished are written
/// (their `runs.csv` rows and traces) with a manifest marking the folder incomplete, and
/// [`Swept::interrupted`] names the signal. With [`SweepPlan::resume`] the folders must hold
/// a sweep of the same experiments (same resolved configuration, same robokey commit); only
/// their missing runs run, and the folders end byte-identical to an uninterrupted sweep.
/// `on_start` is called before each experiment runs; `finished` after each run.
///
/// # Errors
/// A folder that cannot be resumed with these experiments (nothing is written then), a
/// run that aborts, a file that cannot be read or written.
pub fn sweep(
    out: &Path,
    experiments: &[Experiment],
    plan: SweepPlan,
    stop: &Interrupt,
    on_start: &mut (dyn FnMut(&Start) + Send),
    finished: &(dyn Fn() + Sync),
) -> Result<Swept, LabError> {
    sweep_keeping(out, experiments, plan, stop, on_start, finished, None)
}

/// [`sweep`], filing each run simulated alone in `kept` (if given) for a later consumer of
/// the same sessions ([`KeptSessions`]: `reproduce` hands a stage's sweep runs to its
/// secrecy analysis).
///
/// # Errors
/// As [`sweep`].
pub fn sweep_keeping(
    out: &Path,
    experiments: &[Experiment],
    plan: SweepPlan,
    stop: &Interrupt,
    on_start: &mut (dyn FnMut(&Start) + Send),
    finished: &(dyn Fn() + Sync),
    kept: Option<&KeptSessions>,
) -> Result<Swept, LabError> {
    let single = matches!(experiments, [e] if e.name.is_empty());
    let dir_of = |e: &Experiment| {
        if single {
            out.to_path_buf()
        } else {
            out.join(&e.name)
        }
    };
    // Everything is checked before anything is written.
    if plan.resume && !single {
        refuse_strangers(out, experiments)?;
    }
    let mut folders = experiments
        .iter()
        .map(|e| {
            let dir = dir_of(e);
            if plan.resume {
                resumable(dir, e, plan.shard)
            } else {
                Ok(Folder {
                    dir,
                    shards: vec![plan.shard.unwrap_or(Shard::ALL)],
                    rows: Rows::new(),
                })
            }
        })
        .collect::<Result<Vec<_>, _>>()?;
    for (e, f) in experiments.iter().zip(&folders) {
        write_folder(&f.dir, e, &f.rows, &f.shards, plan.format)?;
    }
    let mut progress = Vec::new();
    for (e, f) in experiments.iter().zip(&mut folders) {
        let planned: Vec<usize> = planned(e, &f.shards).collect();
        if !stop.is_requested() {
            let to_run: Vec<usize> = planned
                .iter()
                .copied()
                .filter(|r| !f.rows.contains_key(r))
                .collect();
            on_start(&Start {
                experiment: e,
                dir: &f.dir,
                shards: &f.shards,
                done: f.rows.len(),
                planned: planned.len(),
            });
            // Traces (written as the runs go) before the rows that vouch for them, the
            // manifest last.
            let rows = run_experiment(e, &f.dir, &to_run, stop, finished, kept)?;
            f.rows.extend(rows.into_iter().map(|r| (r.run, r)));
            write_folder(&f.dir, e, &f.rows, &f.shards, plan.format)?;
        }
        progress.push(Progress {
            name: e.name.clone(),
            dir: f.dir.clone(),
            done: f.rows.len(),
            planned: planned.len(),
        });
    }
    let interrupted = if progress.iter().all(Progress::complete) {
        None
    } else {
        stop.signal()
    };
    Ok(Swept {
        experiments: progress,
        interrupted,
    })
}

/// A suite's folder may hold only the suite's experiments.
fn refuse_strangers(out: &Path, experiments: &[Experiment]) -> Result<(), LabError> {
    let Some(subs) = experiment_dirs(out).map_err(|_| LabError::Resume {
        dir: out.to_path_buf(),
        message: "it holds no experiment folder of this suite".into(),
    })?
    else {
        return Err(LabError::Resume {
            dir: out.to_path_buf(),
            message: "it holds a single sweep, and this file is a suite of experiments".into(),
        });
    };
    match subs
        .iter()
        .map(|d| folder_name(d))
        .find(|name| !experiments.iter().any(|e| &e.name == name))
    {
        Some(stranger) => Err(LabError::Resume {
            dir: out.to_path_buf(),
            message: format!(
                "it holds an experiment `{stranger}` that this sweep file does not define: it \
                 was swept from another file"
            ),
        }),
        None => Ok(()),
    }
}

/// What an experiment's folder holds, if this sweep can continue it.
fn resumable(
    dir: PathBuf,
    experiment: &Experiment,
    shard: Option<Shard>,
) -> Result<Folder, LabError> {
    let refuse = |message: String| LabError::Resume {
        dir: dir.clone(),
        message,
    };
    let resolved = dir.join("config.resolved.toml");
    if !resolved.exists() {
        return Err(refuse(if experiment.name.is_empty() {
            "no config.resolved.toml: not the folder of a sweep (a suite's folder is resumed \
             with the suite's file)"
                .into()
        } else {
            format!(
                "no config.resolved.toml: [experiment.{}] was not swept into it",
                experiment.name
            )
        }));
    }
    let theirs = sha256_hex(&read(&resolved)?);
    let ours = sha256_hex(&experiment.resolved_toml());
    if theirs != ours {
        return Err(refuse(format!(
            "it was swept from a different configuration (config.resolved.toml digest {}…, \
             this sweep file with these --set options: {}…); resume with the file and --set \
             options that made it, or sweep into a new folder",
            &theirs[..12],
            &ours[..12]
        )));
    }
    let manifest = read_manifest(&dir)?;
    let commit = env!("ROBOKEY_GIT_COMMIT");
    if manifest.git_commit != commit {
        return Err(refuse(format!(
            "it was written by robokey commit {}, this is {commit}; numbers may differ between \
             versions, so finish it with that version or sweep anew",
            manifest.git_commit
        )));
    }
    if let Some(shard) = shard
        && manifest.shards != [shard]
    {
        return Err(refuse(format!(
            "it holds shard(s) {}, not --shard {shard}",
            manifest
                .shards
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let mut rows = read_rows(experiment, &dir, &manifest.shards)?;
    // A run whose trace did not reach the disk runs again.
    let replicates = experiment.replicates() as usize;
    rows.retain(|&run, _| {
        !(experiment.traces && run % replicates == 0)
            || point_trace_path(&dir, run / replicates).exists()
    });
    Ok(Folder {
        dir,
        shards: manifest.shards,
        rows,
    })
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;
    use std::sync::atomic::{AtomicUsize, Ordering};

    use super::*;
    use crate::experiment::experiments_from_table;
    use crate::folder::load::load;
    use crate::run::with_jobs;

    /// Two experiments, 6 + 2 short runs; `a` keeps traces.
    const SUITE: &str = "[trajectory]\nlaps = 1\n[run]\nreplicates = 3\n\
        [experiment.a.sweep]\ntraces = true\n\"protocol.delta_v\" = [0.02, 0.035]\n\
        [experiment.b]\nrun.replicates = 2\n";

    const FRESH: SweepPlan = SweepPlan {
        shard: None,
        resume: false,
        format: TableFormat::Csv,
    };
    const RESUME: SweepPlan = SweepPlan {
        shard: None,
        resume: true,
        format: TableFormat::Csv,
    };

    fn suite(text: &str) -> Vec<Experiment> {
        experiments_from_table(text.parse().unwrap(), "suite.toml").unwrap()
    }

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("robokey-folder-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    /// Every file under `dir` by relative path, with its bytes.
    fn files(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
        fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<PathBuf, Vec<u8>>) {
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
        let mut out = BTreeMap::new();
        walk(dir, dir, &mut out);
        out
    }

    /// Sweeps on one worker thread, asking to stop (as SIGINT would) once `k` runs finished,
    /// so exactly `k` finish.
    fn sweep_stopping_after(
        dir: &Path,
        experiments: &[Experiment],
        plan: SweepPlan,
        k: usize,
    ) -> Result<Swept, LabError> {
        let stop = Interrupt::new();
        if k == 0 {
            stop.request(2);
        }
        let count = AtomicUsize::new(0);
        let finished = || {
            if count.fetch_add(1, Ordering::SeqCst) + 1 == k {
                stop.request(2);
            }
        };
        with_jobs(1, || {
            sweep(dir, experiments, plan, &stop, &mut |_| {}, &finished)
        })
        .unwrap()
    }

    fn resume_on_two_threads(dir: &Path, experiments: &[Experiment], plan: SweepPlan) -> Swept {
        let stop = Interrupt::new();
        with_jobs(2, || {
            sweep(dir, experiments, plan, &stop, &mut |_| {}, &|| {})
        })
        .unwrap()
        .unwrap()
    }

    /// The cells of a CSV file robokey wrote, header first.
    fn csv_cells(path: &Path) -> Vec<Vec<String>> {
        let text = std::fs::read_to_string(path).unwrap();
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .from_reader(text.as_bytes());
        reader
            .records()
            .map(|r| r.unwrap().iter().map(str::to_owned).collect())
            .collect()
    }

    /// A Parquet table's cells as the CSV writes them, header first.
    fn parquet_cells(path: &Path) -> Vec<Vec<String>> {
        let table = crate::parquet_table::read_parquet(path).unwrap();
        let rows = table.columns[0].values.len();
        let header = table.columns.iter().map(|c| c.name.clone()).collect();
        std::iter::once(header)
            .chain((0..rows).map(|row| {
                table
                    .columns
                    .iter()
                    .map(|c| c.values.cell(row).unwrap())
                    .collect()
            }))
            .collect()
    }

    #[test]
    fn a_parquet_sweep_equals_its_csv_cell_for_cell_once_complete() {
        let experiments = suite(SUITE);
        let (csv_dir, parquet_dir) = (scratch("pq-csv"), scratch("pq-parquet"));
        sweep_stopping_after(&csv_dir, &experiments, FRESH, usize::MAX).unwrap();
        let parquet = |resume| SweepPlan {
            shard: None,
            resume,
            format: TableFormat::Parquet,
        };
        // Interrupted, it stays in CSV, and resumes.
        sweep_stopping_after(&parquet_dir, &experiments, parquet(false), 1).unwrap();
        assert!(parquet_dir.join("a/runs.csv").exists());
        assert!(!parquet_dir.join("a/runs.parquet").exists());
        resume_on_two_threads(&parquet_dir, &experiments, parquet(true));
        for name in ["a", "b"] {
            let (theirs, ours) = (csv_dir.join(name), parquet_dir.join(name));
            assert!(!ours.join("runs.csv").exists());
            assert_eq!(
                parquet_cells(&ours.join("runs.parquet")),
                csv_cells(&theirs.join("runs.csv")),
                "{name}"
            );
            for file in ["summary.json", "manifest.json", "config.resolved.toml"] {
                assert_eq!(
                    std::fs::read(ours.join(file)).unwrap(),
                    std::fs::read(theirs.join(file)).unwrap()
                );
            }
        }
        for point in 0..2 {
            let trace =
                |dir: &Path, extension| dir.join(format!("a/traces/point-{point}.{extension}"));
            assert!(!trace(&parquet_dir, "csv").exists());
            assert_eq!(
                parquet_cells(&trace(&parquet_dir, "parquet")),
                csv_cells(&trace(&csv_dir, "csv"))
            );
        }
        let table =
            crate::parquet_table::read_parquet(&parquet_dir.join("a/runs.parquet")).unwrap();
        let jx = table.columns.iter().find(|c| c.name == "jx").unwrap();
        assert_eq!(
            (jx.unit.as_str(), jx.description.starts_with("J_x")),
            ("m", true)
        );
        assert_eq!(
            table.metadata.get("robokey.sweep"),
            Some(&experiments[0].resolved_toml())
        );
        let err = load(&parquet_dir).unwrap_err();
        assert!(matches!(err, LabError::ParquetRuns(_)), "{err}");
        std::fs::remove_dir_all(&csv_dir).unwrap();
        std::fs::remove_dir_all(&parquet_dir).unwrap();
    }

    #[test]
    fn an_interrupted_sweep_keeps_its_runs_and_resumes_to_the_same_bytes() {
        let experiments = suite(SUITE);
        let reference = scratch("reference");
        let swept = sweep_stopping_after(&reference, &experiments, FRESH, usize::MAX).unwrap();
        assert_eq!(swept.interrupted, None);
        let expected = files(&reference);
        assert!(expected.contains_key(Path::new("a/traces/point-1.csv")));
        assert!(expected.contains_key(Path::new("b/summary.json")));
        for k in [0, 1, 5, 6, 7] {
            let dir = scratch(&format!("stopped-{k}"));
            let swept = sweep_stopping_after(&dir, &experiments, FRESH, k).unwrap();
            assert_eq!(swept.interrupted, Some(2), "k = {k}");
            let done: Vec<usize> = swept.experiments.iter().map(|p| p.done).collect();
            assert_eq!(done, [k.min(6), k.saturating_sub(6)], "k = {k}");
            // What finished is on disk, and the manifests say how much.
            for (name, done, planned) in [("a", k.min(6), 6), ("b", k.saturating_sub(6), 2)] {
                let folder = dir.join(name);
                let manifest = read_manifest(&folder).unwrap();
                assert_eq!(
                    (manifest.complete, manifest.runs_done),
                    (done == planned, done),
                    "{name}, k = {k}"
                );
                let rows = std::fs::read_to_string(folder.join("runs.csv")).unwrap();
                assert_eq!(rows.lines().count(), 1 + done, "{name}, k = {k}");
                assert_eq!(folder.join("summary.json").exists(), done == planned);
            }
            // Replicate 0 of point 0 is run 0: its trace is kept once it finished.
            assert_eq!(dir.join("a/traces/point-0.csv").exists(), k >= 1);
            let err = load(&dir).unwrap_err();
            assert!(matches!(err, LabError::Incomplete { .. }), "{err}");
            let swept = resume_on_two_threads(&dir, &experiments, RESUME);
            assert_eq!(swept.interrupted, None);
            assert!(swept.experiments.iter().all(Progress::complete));
            assert!(files(&dir) == expected, "k = {k}: resumed folder differs");
            std::fs::remove_dir_all(&dir).unwrap();
        }
        // A complete folder resumes to itself.
        resume_on_two_threads(&reference, &experiments, RESUME);
        assert!(files(&reference) == expected);
        let loaded = load(&reference).unwrap();
        assert_eq!(loaded.len(), 2);
        assert_eq!(loaded[0].rows.len(), 6);
        assert_eq!(
            loaded[0]
                .traces
                .get(&1)
                .map(|paths| paths.iter().map(Vec::len).collect::<Vec<_>>()),
            Some(vec![1 + 4 * 85])
        );
        std::fs::remove_dir_all(&reference).unwrap();
    }

    #[test]
    fn a_shard_resumes_to_the_same_bytes_as_when_it_ran_through() {
        let experiments = suite(SUITE);
        let shard = SweepPlan {
            shard: Some(Shard { index: 2, count: 3 }),
            resume: false,
            format: TableFormat::Csv,
        };
        let (whole, stopped) = (scratch("shard-whole"), scratch("shard-stopped"));
        sweep_stopping_after(&whole, &experiments, shard, usize::MAX).unwrap();
        let swept = sweep_stopping_after(&stopped, &experiments, shard, 1).unwrap();
        assert_eq!(swept.experiments[0].planned, 2);
        assert_eq!(swept.interrupted, Some(2));
        // The folder knows its shard: --resume needs no --shard, and refuses another.
        let err = sweep_stopping_after(
            &stopped,
            &experiments,
            SweepPlan {
                shard: Some(Shard { index: 1, count: 3 }),
                resume: true,
                format: TableFormat::Csv,
            },
            usize::MAX,
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("holds shard(s) 2/3, not --shard 1/3"), "{err}");
        resume_on_two_threads(&stopped, &experiments, RESUME);
        assert!(files(&stopped) == files(&whole));
        let err = load(&whole).unwrap_err().to_string();
        assert!(err.contains("merge the shards first"), "{err}");
        for dir in [whole, stopped] {
            std::fs::remove_dir_all(dir).unwrap();
        }
    }

    #[test]
    fn resume_refuses_a_folder_of_another_sweep_and_leaves_it_alone() {
        let experiments = suite(SUITE);
        let dir = scratch("other");
        sweep_stopping_after(&dir, &experiments, FRESH, 2).unwrap();
        let before = files(&dir);
        let refused = |experiments: &[Experiment]| {
            let err = sweep_stopping_after(&dir, experiments, RESUME, usize::MAX).unwrap_err();
            assert!(matches!(err, LabError::Resume { .. }), "{err}");
            assert!(files(&dir) == before, "a refused resume changed the folder");
            err.to_string()
        };
        let err = refused(&suite(&SUITE.replace("replicates = 3", "replicates = 4")));
        assert!(
            err.contains("/a: cannot resume") && err.contains("different configuration"),
            "{err}"
        );
        let err = refused(&suite(&SUITE.replace("[experiment.b]", "[experiment.c]")));
        assert!(
            err.contains("an experiment `b` that this sweep file does not define"),
            "{err}"
        );
        let single =
            experiments_from_table("[run]\nreplicates = 3\n".parse().unwrap(), "one.toml").unwrap();
        let err = refused(&single);
        assert!(err.contains("not the folder of a sweep"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
