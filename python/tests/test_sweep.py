"""``robokey.sweep`` against ``robokey sweep``: the same rows, whatever the threads."""

import pyarrow as pa
import pytest

import robokey

from conftest import assert_rows_equal, read_csv

SWEEP = """\
[trajectory]
laps = 1
[run]
replicates = 3
[sweep]
"protocol.delta_v" = [0.02, 0.035]
"eve.alpha" = { start = 0.0, stop = 0.1, step = 0.05 }
"""


def test_sweep_equals_runs_csv(cli, tmp_path):
    file = tmp_path / "sweep.toml"
    file.write_text(SWEEP)
    cli("sweep", str(file), "--set", "run.seed=9", "--out", str(tmp_path / "out"))
    table = robokey.sweep(SWEEP, seed=9, progress=False)
    assert isinstance(table, pa.Table)
    assert table.num_rows == 2 * 3 * 3
    assert table.column_names[:3] == ["protocol.delta_v", "eve.alpha", "replicate"]
    assert_rows_equal(table.to_pylist(), read_csv(tmp_path / "out" / "runs.csv"))
    resolved = table.schema.metadata[b"robokey.sweep"].decode()
    assert resolved == (tmp_path / "out" / "config.resolved.toml").read_text()


def test_threads_do_not_change_the_rows():
    one = robokey.sweep(SWEEP, jobs=1, progress=False)
    two = robokey.sweep(SWEEP, jobs=2, progress=False)
    assert one.equals(two)


def test_a_dict_sweep_and_typed_columns():
    table = robokey.sweep(
        {
            "trajectory.laps": 1,
            "run": {"replicates": 2},
            "sweep": {"protocol.enabled": [True, False], "trajectory.laps": [1]},
        },
        progress=False,
    )
    assert table.schema.field("protocol.enabled").type == pa.bool_()
    assert table.schema.field("trajectory.laps").type == pa.int64()
    assert table.schema.field("jx").metadata[b"unit"] == b"m"
    assert table.schema.field("trajectory.laps").metadata[b"description"] == b"laps of the path"
    off = table.filter(pa.compute.equal(table.column("protocol.enabled"), False))
    assert off.column("accepted_pct").null_count == off.num_rows


def test_progress_hears_every_run_and_its_exceptions_stop_the_sweep():
    heard = []
    robokey.sweep(SWEEP, progress=lambda done, total: heard.append((done, total)))
    assert heard[-1] == (18, 18)
    assert all(total == 18 and 0 <= done <= 18 for done, total in heard)

    def refuse(done, total):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        robokey.sweep(SWEEP, progress=refuse)


def test_bad_sweeps_raise_named_errors():
    with pytest.raises(robokey.SweepError, match="`controller.kp` is empty"):
        robokey.sweep({"sweep": {"controller.kp": []}}, progress=False)
    with pytest.raises(robokey.SweepError, match="a suite of"):
        robokey.sweep({"experiment": {"a": {}, "b": {}}}, progress=False)
    with pytest.raises(robokey.ConfigError) as raised:
        robokey.sweep({"sweep": {"protocol.delta_v": [0.0]}}, progress=False)
    assert raised.value.field == "protocol.delta_v"
    assert str(raised.value).startswith("config at protocol.delta_v = 0: ")
