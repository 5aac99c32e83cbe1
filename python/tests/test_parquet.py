"""``--format parquet``: the runs table, a trace and the secrecy table as Parquet equal their CSV
cell for cell, with each column's unit (and meaning) in the schema; robokey's readers of
``runs.csv`` refuse a Parquet folder by name."""

from pathlib import Path

import pyarrow.parquet as pq
import pytest

import robokey

from conftest import assert_rows_equal, read_csv

SWEEP = """\
[trajectory]
laps = 1
[run]
replicates = 2
[sweep]
traces = true
"protocol.delta_v" = [0.02, 0.035]
"noise.process_std" = [[0.004, 0.004, 0.004]]
"""


@pytest.fixture(scope="module")
def folders(cli, tmp_path_factory):
    """The same sweep written as CSV and as Parquet, each with its secrecy table."""
    root = tmp_path_factory.mktemp("parquet")
    (root / "sweep.toml").write_text(SWEEP)
    for name, extra in (("csv", []), ("parquet", ["--format", "parquet"])):
        cli("sweep", str(root / "sweep.toml"), "--out", str(root / name), *extra)
        cli("secrecy", str(root / name), "--block", "2000", *extra)
    return root / "csv", root / "parquet"


def test_the_runs_table_equals_runs_csv_cell_for_cell(folders):
    csv_dir, parquet_dir = folders
    assert not (parquet_dir / "runs.csv").exists()
    table = pq.read_table(parquet_dir / "runs.parquet")
    assert_rows_equal(table.to_pylist(), read_csv(csv_dir / "runs.csv"))
    assert table.equals(robokey.read_sweep(csv_dir))
    assert robokey.read_sweep(parquet_dir).equals(table)
    assert table.schema.metadata[b"robokey.sweep"].decode() == (csv_dir / "config.resolved.toml").read_text()


def test_every_column_has_its_unit_and_meaning(folders):
    schema = pq.read_schema(folders[1] / "runs.parquet")
    for name, unit in robokey.METRIC_UNITS.items():
        metadata = schema.field(name).metadata
        assert metadata[b"unit"].decode() == unit, name
        assert metadata[b"description"], name
    assert schema.field("jx").metadata[b"unit"] == b"m"
    assert b"J_x" in schema.field("jx").metadata[b"description"]
    assert schema.field("protocol.delta_v").metadata[b"description"]
    trace = pq.read_schema(folders[1] / "traces" / "point-0.parquet")
    assert trace.field("px").metadata[b"unit"] == b"m"
    assert trace.field("omega_nom").metadata[b"unit"] == b"rad/s"
    assert trace.field("b").metadata[b"description"].startswith(b"the bit b(k)")


def test_sweep_traces_equal_their_csv(folders):
    csv_dir, parquet_dir = folders
    for point in (0, 1):
        assert not (parquet_dir / "traces" / f"point-{point}.csv").exists()
        table = robokey.read_trace(parquet_dir / "traces" / f"point-{point}.parquet")
        assert_rows_equal(table.to_pylist(), read_csv(csv_dir / "traces" / f"point-{point}.csv"))


def test_a_runs_trace_equals_trace_csv(cli, tmp_path):
    cli("run", "--delta-v", "0.035", "--out", str(tmp_path / "csv"))
    cli("run", "--delta-v", "0.035", "--out", str(tmp_path / "parquet"), "--format", "parquet")
    assert not (tmp_path / "parquet" / "trace.csv").exists()
    table = pq.read_table(tmp_path / "parquet" / "trace.parquet")
    assert_rows_equal(table.to_pylist(), read_csv(tmp_path / "csv" / "trace.csv"))
    assert table.equals(robokey.run({"protocol": {"delta_v": 0.035}})["trace"])


def test_the_secrecy_table_equals_secrecy_csv(folders):
    csv_dir, parquet_dir = folders
    assert not (parquet_dir / "secrecy.csv").exists()
    table = pq.read_table(parquet_dir / "secrecy.parquet")
    assert_rows_equal(table.to_pylist(), read_csv(csv_dir / "secrecy.csv"))
    assert table.schema.field("secret_bits").metadata[b"unit"] == b"bit"
    assert table.schema.metadata[b"robokey.block_bits"] == b"2000"
    assert table.equals(robokey.secrecy(csv_dir, block_bits=2000)["table"])


def test_readers_of_runs_csv_refuse_a_parquet_folder(cli, folders):
    parquet_dir = folders[1]
    done = cli("report", str(parquet_dir), check=False)
    assert done.returncode == 2, done.stderr
    assert "runs.parquet (swept with --format parquet)" in done.stderr
    done = cli("merge", str(parquet_dir), "--out", str(parquet_dir.parent / "merged"), check=False)
    assert "runs.parquet" in done.stderr and done.returncode != 0


def test_shards_swept_in_csv_merge_into_parquet(cli, folders, tmp_path):
    sweep = folders[0].parent / "sweep.toml"
    done = cli("sweep", str(sweep), "--shard", "1/2", "--format", "parquet", "--out", str(tmp_path / "x"), check=False)
    assert done.returncode == 2 and "--shard with --format parquet" in done.stderr
    for shard in (1, 2):
        cli("sweep", str(sweep), "--shard", f"{shard}/2", "--out", str(tmp_path / f"shard{shard}"))
    cli("merge", str(tmp_path / "shard1"), str(tmp_path / "shard2"), "--out", str(tmp_path / "merged"),
        "--format", "parquet")
    for name in ("runs.parquet", "traces/point-0.parquet", "traces/point-1.parquet"):
        assert (tmp_path / "merged" / name).read_bytes() == (folders[1] / name).read_bytes(), name
