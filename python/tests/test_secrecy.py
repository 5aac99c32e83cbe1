"""``robokey.secrecy`` against ``robokey secrecy``: the same rows, from a folder or a
definition."""

from pathlib import Path

import pyarrow as pa
import pytest

import robokey

from conftest import assert_rows_equal, read_csv

SWEEP = """\
[trajectory]
laps = 1
[run]
replicates = 2
[sweep]
"protocol.delta_v" = [0.02, 0.035]
"""


@pytest.fixture(scope="module")
def swept(cli, tmp_path_factory) -> Path:
    """A sweep folder and its secrecy analysis by the command line (blocks of 2,000 bits)."""
    root = tmp_path_factory.mktemp("secrecy")
    (root / "sweep.toml").write_text(SWEEP)
    cli("sweep", str(root / "sweep.toml"), "--out", str(root / "out"))
    cli("secrecy", str(root / "out"), "--block", "2000")
    return root / "out"


def test_secrecy_of_a_folder_equals_secrecy_csv(swept):
    result = robokey.secrecy(swept, block_bits=2000)
    table = result["table"]
    assert isinstance(table, pa.Table)
    assert table.num_rows == 2 * 3
    assert table.column("adversary").to_pylist()[:3] == ["oracle", "identify", "mismatch"]
    assert_rows_equal(table.to_pylist(), read_csv(swept / "secrecy.csv"))
    assert (result["epsilon"], result["block_bits"], result["pooling"]) == (1e-6, 2000, "confirmed")
    assert result["map"] is None
    # The odometry mode's key is zero by structure, and says why.
    assert all(r["secret_bits"] == 0 and r["structural_zero"] for r in result["results"])


def test_a_definition_gives_the_folders_analysis(swept):
    from_folder = robokey.secrecy(swept, block_bits=2000)
    from_definition = robokey.secrecy(SWEEP, block_bits=2000)
    assert from_definition["table"].equals(from_folder["table"])
    assert from_definition["results"] == from_folder["results"]


def test_blocks_list_each_block_with_its_leak_and_realised_view(swept):
    result = robokey.secrecy(swept, block_bits=2000, adversaries=["oracle"])
    blocks = result["blocks"]
    assert blocks.num_rows == sum(len(r["blocks"]) for r in result["results"]) >= 2
    row = blocks.to_pylist()[0]
    assert row["adversary"] == "oracle" and row["bits"] >= 2000
    assert row["leak"] == row["leak_ec"] + row["leak_confirmation"]
    assert "realised_h_min" in row and "realised_secret_bits" in row


def test_options_out_of_range_are_named_as_the_cli_names_them(cli, swept):
    with pytest.raises(robokey.OptionError) as raised:
        robokey.secrecy(swept, epsilon=2.0)
    error = raised.value
    assert (error.option, error.value, error.allowed) == ("epsilon", "2", "(0, 1)")
    done = cli("secrecy", str(swept), "--eps", "2", check=False)
    assert done.returncode == 2
    assert str(error) == "epsilon=2 is not allowed (allowed: (0, 1))"
    assert done.stderr.strip() == "error: --eps 2 is not allowed (allowed: (0, 1))"
    with pytest.raises(robokey.OptionError, match=r"block_bits=10 is not allowed \(allowed: 64 to"):
        robokey.secrecy(swept, block_bits=10)
    with pytest.raises(robokey.InputError, match='adversary "eve" is not allowed'):
        robokey.secrecy(swept, adversaries=["eve"])
    with pytest.raises(robokey.InputError, match='pooling "all" is not allowed'):
        robokey.secrecy(swept, pooling="all")


def test_folders_and_sweeps_without_keys_are_refused(tmp_path):
    with pytest.raises(OSError, match="config.resolved.toml: No such file"):
        robokey.secrecy(tmp_path)
    with pytest.raises(robokey.InputError, match="protocol.enabled = false"):
        robokey.secrecy({"protocol": {"enabled": False}, "sweep": {"run.seed": [1]}})
