"""scripts/pooled-sessions.py finds a block's sessions by the IDs its report names, not by
their place among the session folders."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from types import ModuleType
from typing import Any, Dict

ROOT = Path(__file__).resolve().parents[2]


def _script() -> ModuleType:
    spec = importlib.util.spec_from_file_location(
        "pooled_sessions", ROOT / "scripts" / "pooled-sessions.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _session(folder: Path, role: str, session: str, extra: Dict[str, Any]) -> None:
    folder.mkdir(exist_ok=True)
    (folder / f"{role}.json").write_text(json.dumps({"session": session, **extra}))


def test_a_block_is_the_sessions_its_report_names_in_its_order(tmp_path: Path) -> None:
    script = _script()
    # Session 2 pooled after the block (as session 022 did once): the block is 0, 1 and 3.
    for i in range(4):
        _session(tmp_path / f"session-{i:03}", "robot", f"0000000{i}", {})
    folders = [str(tmp_path / f"session-{i:03}") for i in range(4)]
    named = script.session_folders(folders)
    block = {"session_ids": ["00000001", "00000000", "00000003"]}
    members, why = script.block_members(block, named)
    assert why is None
    assert members == [folders[1], folders[0], folders[3]]


def test_a_block_that_names_no_sessions_or_unknown_ones_is_not_checked(tmp_path: Path) -> None:
    script = _script()
    _session(tmp_path / "session-000", "controller", "0000000a", {})
    named = script.session_folders([str(tmp_path / "session-000")])
    members, why = script.block_members({"block": 0}, named)
    assert members is None and "does not name its sessions" in why
    members, why = script.block_members({"session_ids": ["0000000a", "0000000b"]}, named)
    assert members is None and why == "sessions 0000000b have no folder here"
