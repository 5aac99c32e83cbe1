"""Reading what the command line wrote: sweep folders and traces."""

import pytest

import robokey

from test_sweep import SWEEP


def test_a_sweep_folder_reads_back_as_the_sweep(cli, tmp_path):
    (tmp_path / "sweep.toml").write_text(SWEEP)
    cli("sweep", str(tmp_path / "sweep.toml"), "--out", str(tmp_path / "out"))
    read = robokey.read_sweep(tmp_path / "out")
    assert read.equals(robokey.sweep(SWEEP, progress=False))
    assert read.schema.metadata[b"robokey.sweep"] == (tmp_path / "out" / "config.resolved.toml").read_bytes()


def test_a_suite_folder_reads_as_a_dict(cli, tmp_path):
    suite = "[trajectory]\nlaps = 1\n[experiment.a]\nrun.replicates = 2\n[experiment.b.sweep]\n\"eve.alpha\" = [0.0, 0.1]\n"
    (tmp_path / "suite.toml").write_text(suite)
    cli("sweep", str(tmp_path / "suite.toml"), "--out", str(tmp_path / "out"))
    read = robokey.read_sweep(tmp_path / "out")
    assert sorted(read) == ["a", "b"]
    assert read["a"].num_rows == 2 and read["b"].column_names[0] == "eve.alpha"


def test_a_trace_file_reads_as_the_runs_trace(cli, tmp_path):
    cli("run", "--seed", "4", "--out", str(tmp_path / "run"))
    read = robokey.read_trace(tmp_path / "run" / "trace.csv")
    assert read.equals(robokey.run(seed=4)["trace"].replace_schema_metadata(None))


def test_what_does_not_read_back_is_named(cli, tmp_path):
    (tmp_path / "trace.csv").write_text("k,t\n0,0\n")
    with pytest.raises(robokey.InputError, match="trace.csv:1: not a trace"):
        robokey.read_trace(tmp_path / "trace.csv")
    (tmp_path / "sweep.toml").write_text(SWEEP)
    cli("sweep", str(tmp_path / "sweep.toml"), "--out", str(tmp_path / "out"))
    runs = tmp_path / "out" / "runs.csv"
    runs.write_text(runs.read_text().replace("\n0.02,0,", "\n0.03,0,", 1))
    with pytest.raises(robokey.InputError, match="runs.csv:2: parameters"):
        robokey.read_sweep(tmp_path / "out")
    with pytest.raises(OSError):
        robokey.read_sweep(tmp_path / "nothing")
