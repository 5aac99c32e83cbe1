"""scripts/independent-eve.py, the independent camera eavesdropper, on seeded sessions of
`robokey run`: her posteriors are calibrated, and her decisions agree with robokey's camera
eavesdropper's where the doublets are screened (the parties' world), within tolerances from
the number of bits."""

from __future__ import annotations

import importlib.util
import math
import sys
import tomllib
from pathlib import Path
from types import ModuleType
from typing import Any, List, Tuple

import numpy as np

from conftest import Cli

ROOT = Path(__file__).resolve().parents[2]
SESSIONS = 4


def _script() -> ModuleType:
    spec = importlib.util.spec_from_file_location("independent_eve", ROOT / "scripts" / "independent-eve.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["independent_eve"] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def _views(cli: Cli, tmp_path: Path, *sets: str) -> Tuple[Any, Any, Any]:
    """The truth, her LLRs and robokey's camera eavesdropper's decisions over SESSIONS sessions."""
    script = _script()
    parts: List[Tuple[Any, Any, Any]] = []
    for replicate in range(SESSIONS):
        out = tmp_path / f"replicate-{replicate}"
        args = ["run", "--set", "sensing.mode=private", "--seed", "41", "--replicate", str(replicate)]
        for s in sets:
            args += ["--set", s]
        cli(*args, "-o", str(out))
        world = script.World.of(tomllib.loads((out / "config.resolved.toml").read_text()))
        parts.append(script.doublet_llrs(world, script.Trace.read(out / "trace.csv")))
    truth, llr, robokey = (np.concatenate([p[i] for p in parts]) for i in range(3))
    return truth, llr, robokey


def _calibrated(script: ModuleType, truth: Any, llr: Any) -> None:
    """Her errors are what her posteriors predict: within 4.5 standard deviations of Σq."""
    q, _ = script.error_probabilities(truth, llr)
    errors = int(np.sum((llr < 0) != (truth == 1)))
    predicted = float(np.sum(q))
    spread = math.sqrt(float(np.sum(q * (1.0 - q))))
    assert abs(errors - predicted) <= 4.5 * spread, (errors, predicted, spread)


def test_in_the_parties_world_she_is_calibrated_and_agrees_with_robokeys(cli: Cli, tmp_path: Path) -> None:
    script = _script()
    truth, llr, robokey = _views(cli, tmp_path)
    assert len(truth) > 1500
    _calibrated(script, truth, llr)
    # Paired on the same bits (McNemar): the bits only she gets right and only robokey's
    # camera eavesdropper gets right balance within 4 standard deviations of their sum.
    mine = (llr < 0) != (truth == 1)
    theirs = robokey != truth
    only_mine, only_theirs = int(np.sum(mine & ~theirs)), int(np.sum(~mine & theirs))
    assert abs(only_mine - only_theirs) <= 4.0 * math.sqrt(only_mine + only_theirs + 1), (only_mine, only_theirs)
    # Her realised bound: the information per bit of a 20 % error rate, not a degenerate one.
    q, _ = script.error_probabilities(truth, llr)
    per_bit = script.smooth_min_entropy(q, 1e-6) / len(q)
    assert 0.3 < per_bit < 0.8, per_bit


def test_under_a_lag_with_three_step_doublets_she_is_calibrated(cli: Cli, tmp_path: Path) -> None:
    script = _script()
    truth, llr, robokey = _views(
        cli, tmp_path, "world.lag=0.05", "private.prior_lag=0.05", "world.process_std=[0.001,0.001,0.001]"
    )
    assert len(truth) > 1000
    _calibrated(script, truth, llr)
    # The genie holds at least what robokey's camera eavesdropper holds: she errs no more
    # often, up to 4 standard deviations of the paired difference.
    mine = (llr < 0) != (truth == 1)
    theirs = robokey != truth
    only_mine, only_theirs = int(np.sum(mine & ~theirs)), int(np.sum(~mine & theirs))
    assert only_mine - only_theirs <= 4.0 * math.sqrt(only_mine + only_theirs + 1), (only_mine, only_theirs)


def test_the_bound_is_below_the_plain_min_entropy_and_grows_with_her_errors() -> None:
    script = _script()
    q = np.full(10_000, 0.2)
    bound = script.smooth_min_entropy(q, 1e-6)
    # Σ −log₂(1 − q) is the least surprisal any string can have: no smoothing goes below it
    # by construction of the Chernoff cut, and the cut stays below the mean surprisal n·h(q).
    plain = float(np.sum(-np.log2(1.0 - q)))
    mean = 10_000 * (-(0.2 * math.log2(0.2) + 0.8 * math.log2(0.8)))
    assert plain <= bound < mean
    assert script.smooth_min_entropy(np.full(10_000, 0.3), 1e-6) > bound
