"""``robokey.run`` against ``robokey run``: the same metrics, table and trace."""

import json

import pyarrow as pa
import pytest

import robokey

from conftest import assert_rows_equal, read_csv


def test_run_equals_the_cli_run(cli, tmp_path):
    for config, flags in [
        ({"protocol": {"delta_v": 0.035}}, ["--delta-v", "0.035"]),
        ({"protocol": {"enabled": False}}, ["--protocol-off", "--seed", "5", "--replicate", "2"]),
        ({"sensing": {"mode": "private"}}, ["--set", "sensing.mode=private"]),
    ]:
        seed = 5 if "--seed" in flags else None
        replicate = 2 if "--replicate" in flags else 0
        ours = robokey.run(config, seed=seed, replicate=replicate)
        out = tmp_path / "-".join(flags).replace("=", "").replace(".", "")
        printed = cli("run", *flags, "--out", str(out)).stdout
        theirs = json.loads((out / "metrics.json").read_text())
        assert theirs.pop("replicate") == ours["replicate"] == replicate
        assert theirs.pop("seed") == ours["seed"]
        assert ours["metrics"] == theirs
        assert list(ours["metrics"]) == list(robokey.METRIC_UNITS)
        assert ours["table"] in printed
        assert ours["config"] == (out / "config.resolved.toml").read_text()
        trace = ours["trace"]
        assert isinstance(trace, pa.Table)
        assert_rows_equal(trace.to_pylist(), read_csv(out / "trace.csv"))


def test_the_trace_carries_units_and_undefined_cells_are_null():
    result = robokey.run({"trajectory": {"laps": 1}})
    trace = result["trace"]
    schema = trace.schema
    assert schema.field("t").metadata[b"unit"] == b"s"
    assert schema.field("omega_nom").metadata[b"unit"] == b"rad/s"
    assert schema.field("b").metadata[b"unit"] == b""
    assert schema.field("k").type == pa.uint64()
    assert b"robokey.config" in schema.metadata
    # Row 0 has no decision yet; the odometry run has no camera.
    assert trace.column("bhat")[0].as_py() is None
    assert trace.column("eve_x").null_count == trace.num_rows
    assert trace.column("px").null_count == 0
    k = trace.column("k").to_numpy()
    assert (k == range(trace.num_rows)).all()
    assert result["metrics"]["codewords_sent"] > 0
    assert robokey.METRIC_UNITS["jx"] == "m"


def test_world_presets_are_configurations_as_on_the_cli(cli, tmp_path):
    assert robokey.WORLD_PRESETS[0] == "ideal" and "khepera-iv" in robokey.WORLD_PRESETS
    for preset in robokey.WORLD_PRESETS:
        ours = robokey.run({"world": {"preset": preset}, "trajectory": {"laps": 1}})
        out = tmp_path / preset
        flags = ["--set", f"world.preset={preset}", "--set", "trajectory.laps=1"]
        cli("run", *flags, "--out", str(out))
        theirs = json.loads((out / "metrics.json").read_text())
        del theirs["replicate"], theirs["seed"]
        assert ours["metrics"] == theirs, preset
    with pytest.raises(robokey.ConfigError, match="unknown variant `mars`, expected one of `ideal`"):
        robokey.run({"world": {"preset": "mars"}})
