"""scripts/independent-eve.py, the independent camera eavesdropper, on seeded sessions of
`robokey run`: her model reproduces noise-free poses, her posteriors are calibrated, and her
decisions agree with robokey's camera eavesdropper's where the doublets are screened (the
parties' world), within tolerances from the number of bits; her bound holds against a Monte
Carlo of the surprisal."""

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
    per_bit = script.smooth_min_entropy(script.bit_posteriors(q), 1e-6) / len(q)
    assert 0.3 < per_bit < 0.8, per_bit


def test_with_two_bits_per_doublet_noise_free_poses_are_reproduced_and_the_omega_bit_turns(
    cli: Cli, tmp_path: Path
) -> None:
    # Without motion noise (`robokey run` takes about 12 s of CPU there: one session).
    script = _script()
    sets = ["world.process_std=[0,0,0]", "world.lag=0.05", "world.delay=0.02", "world.command_quantum=0.01"]
    args = ["run", "--set", "sensing.mode=private", "--set", "protocol.bits_per_doublet=2", "--no-eve"]
    for s in [*sets, "private.prior_lag=0.05"]:
        args += ["--set", s]
    cli(*args, "--seed", "41", "-o", str(tmp_path))
    world = script.World.of(tomllib.loads((tmp_path / "config.resolved.toml").read_text()))
    trace = script.Trace.read(tmp_path / "trace.csv")
    session = script.Session(world, trace)
    assert world.bits == 2 and world.steps == 3
    for k in range(session.last):
        pose = session.run(k - k % world.steps, k, 1, session.pattern(k), np.zeros(5))
        assert np.max(np.abs(pose - trace.pose[k + 1])) < 1e-9, k
    # The ω bit's other value turns the doublet's first step by 2·Δω less or more, through
    # the delay (none over [0, D)) and the lag (over h = T − D the offset's mean share is
    # 1 − (τ/h)·(1 − e^(−h/τ))): 2·T·Δω·(h/T)·that, with the sign of the bit. Each wheel's
    # command is rounded to the quantum q, the two values' wheel commands Δω·D_axle/r apart:
    # the turn's relative error is at most q·r/(Δω·D_axle) (5.7 % here).
    h = world.period - world.delay
    share = (h / world.period) * (1.0 - (world.lag / h) * (1.0 - math.exp(-h / world.lag)))
    spread = world.command_quantum * world.wheel_radius / (world.delta_omega * world.axle)
    carrying = [k for k in range(0, session.last - 2, 3) if trace.bit[k] >= 0]
    assert len(carrying) > 250
    for k in carrying:
        v_bit, omega_bit = session.pattern(k)
        turned = session.run(k, k, 1, (v_bit, 1 - omega_bit), np.zeros(5))[2] - trace.pose[k + 1][2]
        ratio = turned / (2.0 * world.period * world.delta_omega * (2 * omega_bit - 1))
        assert abs(ratio - share) <= share * spread, (k, ratio, share, spread)


def test_with_two_bits_per_doublet_she_is_calibrated_on_each_bit(cli: Cli, tmp_path: Path) -> None:
    script = _script()
    truth, llr, robokey = _views(cli, tmp_path, "protocol.bits_per_doublet=2")
    assert len(truth) > 3000
    # Bits alternate v, ω per doublet: each dimension on its own.
    for bit in (0, 1):
        _calibrated(script, truth[bit::2], llr[bit::2])
        # And informative: about 21 % wrong each (a rate's standard deviation ≈ 0.01 here).
        assert np.mean((llr[bit::2] < 0) != (truth[bit::2] == 1)) < 0.3
    # Given the doublet's ω bit she knows more of its v bit than robokey's camera
    # eavesdropper, who marginalises it: she errs no more often, up to 4 standard
    # deviations of the paired difference (robokey's trace holds no ω decision).
    assert np.all(robokey[1::2] == -1)
    mine = (llr[::2] < 0) != (truth[::2] == 1)
    theirs = robokey[::2] != truth[::2]
    only_mine, only_theirs = int(np.sum(mine & ~theirs)), int(np.sum(~mine & theirs))
    assert only_mine - only_theirs <= 4.0 * math.sqrt(only_mine + only_theirs + 1), (only_mine, only_theirs)


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
    bound = script.smooth_min_entropy(script.bit_posteriors(q), 1e-6)
    # Σ −log₂(1 − q) is the least surprisal any string can have: no smoothing goes below it
    # by construction of the Chernoff cut, and the cut stays below the mean surprisal n·h(q).
    plain = float(np.sum(-np.log2(1.0 - q)))
    mean = 10_000 * (-(0.2 * math.log2(0.2) + 0.8 * math.log2(0.8)))
    assert plain <= bound < mean
    assert script.smooth_min_entropy(script.bit_posteriors(np.full(10_000, 0.3)), 1e-6) > bound


def test_the_bound_on_correlated_pairs_holds_against_a_monte_carlo_of_the_surprisal() -> None:
    """Two bits per unit seen through y = s_v·h_v + s_ω·h_ω + N(0, I), h_v·h_ω = 0.6: her genie
    LLRs are the closed form, and for one block of views both her pairs' bound and her genie
    bits' bound t keep P[S ≤ t] ≤ ε for the pairs' exact surprisal S of the true string, drawn
    from her posteriors (the true bits given the views). M = 4,000 draws: the fraction's
    standard deviation at ε = 0.05 is √(ε(1 − ε)/M) = 0.0034, the tolerance three of it."""
    script = _script()
    rng = np.random.default_rng(7)
    units, draws, epsilon = 400, 4000, 0.05
    h = np.array([[1.0, 0.0], [0.6, 0.8]])  # rows: the v bit's and the ω bit's signal
    signs = 1.0 - 2.0 * np.array(script.patterns(2))
    truth = rng.integers(0, 2, size=(units, 2))
    y = (1.0 - 2.0 * truth) @ h + rng.standard_normal((units, 2))
    loglik = -0.5 * np.sum((y[:, None, :] - (signs @ h)[None]) ** 2, axis=2)
    genie = script.genie_llrs(truth, loglik)
    s_v, s_omega = 1.0 - 2.0 * truth[:, :1], 1.0 - 2.0 * truth[:, 1:]
    assert np.allclose(genie[:, 0], 2.0 * (y - s_omega * h[1]) @ h[0], atol=1e-9)
    assert np.allclose(genie[:, 1], 2.0 * (y - s_v * h[0]) @ h[1], atol=1e-9)
    pairs = script.pair_posteriors(truth, loglik, np.ones((units, 2), dtype=bool))
    q, _ = script.error_probabilities(truth.reshape(-1), genie.reshape(-1))
    t_pairs = script.smooth_min_entropy(pairs, epsilon)
    t_genie = script.smooth_min_entropy(script.bit_posteriors(q), epsilon)
    drawn = (rng.random((draws, units))[:, :, None] > np.cumsum(pairs, axis=1)[None]).sum(axis=2)
    surprisal = -np.log2(pairs[np.arange(units), np.minimum(drawn, 3)]).sum(axis=1)
    tolerance = 3.0 * math.sqrt(epsilon * (1.0 - epsilon) / draws)
    assert np.mean(surprisal <= t_pairs) <= epsilon + tolerance, np.mean(surprisal <= t_pairs)
    assert np.mean(surprisal <= t_genie) <= epsilon + tolerance, np.mean(surprisal <= t_genie)
    # Not degenerate: 10 % above the pairs' bound is above the surprisal's ε-quantile.
    assert np.mean(surprisal <= 1.1 * t_pairs) > epsilon + tolerance
    # One disclosed bit leaves the other's genie posterior.
    kept = np.ones((units, 2), dtype=bool)
    kept[0, 1] = kept[1] = False
    rows = script.pair_posteriors(truth, loglik, kept)
    assert len(rows) == units - 1
    assert np.isclose(rows[0, 0], 1.0 / (1.0 + math.exp(-genie[0, 0]))) and rows[0, 2:].sum() == 0.0
