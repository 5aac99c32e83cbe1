"""Shared fixtures: the ``robokey`` command line, to check that the package's numbers are its
numbers."""

from __future__ import annotations

import csv
import os
import subprocess
from pathlib import Path
from typing import Any, Dict, List, Optional

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _binary() -> Path:
    """The ``robokey`` binary: ``$ROBOKEY_BIN``, else the workspace's release or debug build."""
    if "ROBOKEY_BIN" in os.environ:
        return Path(os.environ["ROBOKEY_BIN"]).resolve()
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    for profile in ("release", "debug"):
        if (target / profile / "robokey").exists():
            return target / profile / "robokey"
    raise RuntimeError(
        f"no robokey binary under {target}: build it (cargo build -p robokey-cli) or set ROBOKEY_BIN"
    )


class Cli:
    """Runs ``robokey`` subcommands."""

    def __init__(self, binary: Path) -> None:
        self.binary = binary

    def __call__(self, *args: str, check: bool = True) -> subprocess.CompletedProcess:
        done = subprocess.run(
            [str(self.binary), *args], capture_output=True, text=True, cwd=ROOT
        )
        if check and done.returncode != 0:
            raise AssertionError(f"robokey {' '.join(args)} exited {done.returncode}: {done.stderr}")
        return done


@pytest.fixture(scope="session")
def cli() -> Cli:
    return Cli(_binary())


def cell_value(text: str, like: Any) -> Any:
    """A CSV cell read as the type of ``like`` (the package's value): empty is None."""
    if isinstance(like, str):
        return text
    if text == "":
        return None
    if isinstance(like, bool):
        return {"true": True, "false": False}[text]
    if isinstance(like, int):
        return int(text)
    if isinstance(like, float):
        return float(text)
    return text


def read_csv(path: Path) -> List[Dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def assert_rows_equal(table_rows: List[Dict[str, Any]], csv_rows: List[Dict[str, str]]) -> None:
    """Every cell of a table equals the CSV's, exactly (reals are written in their shortest
    round-trip form); undefined is an empty cell."""
    assert len(table_rows) == len(csv_rows)
    for i, (ours, theirs) in enumerate(zip(table_rows, csv_rows)):
        assert list(ours) == list(theirs), f"row {i}: columns differ"
        for column, value in ours.items():
            expected: Optional[Any] = cell_value(theirs[column], value)
            if value is None:
                assert theirs[column] == "", f"row {i}, {column}: None against {theirs[column]!r}"
            else:
                assert value == expected, f"row {i}, {column}: {value!r} against {theirs[column]!r}"
