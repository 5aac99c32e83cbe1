#!/usr/bin/env python3
"""An independent camera eavesdropper for private sensing (docs/threat-model.md).

It shares no code with robokey's eavesdroppers: it reads the `trace.csv` files that
`robokey run` writes (the true poses, the controller's samples, her camera samples, the public
nominal commands, the bits) and the run's `config.resolved.toml` (the world's parameters), and
computes from first principles (docs/world.md for the plant, docs/secrecy.md for the bound)
each bit's posterior given a **genie-aided** view, then her realised smooth min-entropy.

The genie. For the bit of the doublet starting at step k (L = 2 steps, or 3 with a prior lag)
she is given the true pose at every sample instant outside the doublet's own instants
k … k + L, every other bit, and the world's parameters; at the doublet's instants she holds
her camera samples and, at its two boundaries, the controller's samples (`--boundaries
samples`, the default) or the true poses (`--boundaries true`, a stronger genie). That is at
least as much as the key's camera eavesdropper holds (her camera, the controller's boundary
samples, the public commands): everything else she observes is the true poses elsewhere plus
noise independent of the bit. She models the doublet's L steps, the step before (from the
given pose) and the one after (a delay, or a lag other than the prior, carries the bit into
it), each step with the world's plant (docs/world.md): the wheels' first-order lag τ and
transport delay D (a period's stretches [0, D) under the previous command, then the new one,
each with the lag's mean wheel speeds, moving along the heading the period starts with), the
command quantum, the per-wheel slip as a latent velocity error, the AR(1) motion noise
conditioned on the neighbouring steps' noise (which the given poses fix), the Euler map. The
poses are linearised about each hypothesis's noise-free run (forward differences in the noise,
exact but for the heading's turn of later travel: below 0.1 µm at the grid's noise), so her
observations are Gaussian under each value of the bit and her log-likelihood ratio is
ln N(o; μ₀, Σ₀) − ln N(o; μ₁, Σ₁): a Kalman smoother around each doublet, written as the batch
Gaussian. A sample's jitter j moves it by j·ẋ (ẋ the nominal rate): jitter²·ẋẋᵀ is added to
the controller sample's covariance. Checked on noise-free traces: the model reproduces the
simulator's poses to 4 µm under lag, delay and command quantum (and, with two bits per doublet,
to 10⁻⁹ without motion noise, a test).

Two bits per doublet (`protocol.bits_per_doublet = 2`: the v bit on Δv, the ω bit on Δω, each
with the doublet's shape, docs/private-sensing.md). She computes her likelihood under each of
the doublet's four patterns; her LLR of each bit is the Gaussian log-likelihood ratio under its
two values **with the doublet's other bit at its true value** — robokey's genie (docs/secrecy.md:
each bit's view with every other bit given), so her bits are sized as robokey's sizing sizes
them. That gives her the other bit, which robokey's camera eavesdropper marginalises over (a
binary doublet's bits are judged as they are, not chained): for bits B given her view E, the
chain rule and conditioning give Σ_i H(B_i | E, B_≠i) ≤ H(B | E), so counting the genie bits'
uncertainty errs on her side — for Shannon entropy; for the smooth min-entropy she reports
beside it the doublets' exact bound, which needs no genie inside the doublet: each doublet's
posterior over its four patterns (given its disclosed bit where the public sample holds
one), the Chernoff cut below taken over doublets.

The bound. With P_i her posterior of the true value of unit i (a bit, or a doublet's pair)
and S = −Σ log₂ P_i her surprisal of the true string (the units' views are independent given
the genie), Chernoff's bound gives for any λ > 0, P[S ≤ t] ≤ e^{λt·ln2} Π_i E[P_i^λ] with
E[P_i^λ] = Σ_x P_i(x)^{1+λ} (the true value drawn from her posterior; a bit's is
(1 − q_i)^{1+λ} + q_i^{1+λ}, q_i her error probability), so
H_min^ε ≥ t = max_λ (−Σ ln E[P_i^λ] − ln(1/ε)) / (λ·ln 2), and the key her view supports is
ℓ = ⌊t − leak_EC − 128 − 2·log₂(1/ε) + 2⌋⁺ (docs/secrecy.md).

Not covered (reported as such): multilevel symbols (`protocol.levels` 4 or 8), continuous
integration, cameras in frames (`world.camera_fps`), a delay of a period or more.

Usage (after `robokey sweep experiments/grid.toml -o G` and `robokey secrecy G` with each
sizing, docs/estimation.md "The grid"):

    python3 scripts/independent-eve.py G/measured --world G/world --configured G/configured \
        --robokey target/release/robokey --out G/grid.md

For every point it simulates the block's sessions again with `robokey run` (the sweep's seed,
replicates 0, 1, … are the sessions `robokey secrecy` pooled), runs her on them and prints per
point ℓ under each sizing, robokey's camera eavesdropper's realised H_min^ε and ℓ, hers, and
whether ℓ is within both (with two bits per doublet her doublets' exact bound beside it, in the
log and the .json rows). A sweep without experiments (`experiments/private.toml`): pass the
folder that holds its output folder.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

TAG_BITS = 128


@dataclass
class World:
    """What the independent eavesdropper knows of the world and of the public protocol."""

    period: float
    wheel_radius: float
    axle: float
    wheel_limit: float
    delta_v: float
    delta_omega: float
    bits: int
    steps: int
    settle: float
    process_std: np.ndarray
    rho: float
    slip_std: float
    lag: float
    delay: float
    command_quantum: float
    jitter: float
    controller_std: np.ndarray
    camera_std: np.ndarray

    @staticmethod
    def of(config: dict) -> "World":
        """Reads a resolved configuration; refuses what the model does not cover."""
        world = config.get("world", {})
        protocol = config["protocol"]
        refusals = []
        if world.get("integration", "euler") != "euler":
            refusals.append("world.integration")
        if "camera_fps" in world:
            refusals.append("world.camera_fps")
        if world.get("delay", 0.0) >= config["robot"]["T"]:
            refusals.append("world.delay of a period or more")
        if protocol.get("levels", 2) != 2:
            refusals.append("multilevel symbols")
        if refusals:
            raise NotCovered(", ".join(refusals))
        prior_lag = config.get("private", {}).get("prior_lag", 0.0)
        period = config["robot"]["T"]
        return World(
            period=period,
            wheel_radius=config["robot"]["r"],
            axle=config["robot"]["D"],
            wheel_limit=config["robot"]["wheel_limit"],
            delta_v=protocol["delta_v"],
            delta_omega=protocol.get("delta_omega", 0.0),
            bits=protocol.get("bits_per_doublet", 1),
            steps=3 if prior_lag > 0.0 else 2,
            settle=math.exp(-period / prior_lag) if prior_lag > 0.0 else 0.0,
            process_std=np.array(world.get("process_std", config["noise"]["process_std"])),
            rho=world.get("process_rho", 0.0),
            slip_std=world.get("slip_std", 0.0),
            lag=world.get("lag", 0.0),
            delay=world.get("delay", 0.0),
            command_quantum=world.get("command_quantum", 0.0),
            jitter=world.get("jitter", 0.0),
            controller_std=np.array(world.get("controller_std", config["sensing"]["controller_std"])),
            camera_std=np.array(world.get("camera_frame_std", config["eve"]["camera_std"])),
        )

    def wheels(self, v: float, omega: float) -> np.ndarray:
        """The wheel-speed command (rad/s) for (v, ω): quantised, then clipped."""
        half = omega * self.axle / 2.0
        wheels = np.array([(v + half) / self.wheel_radius, (v - half) / self.wheel_radius])
        if self.command_quantum > 0.0:
            wheels = self.command_quantum * np.round(wheels / self.command_quantum)
        return np.clip(wheels, -self.wheel_limit, self.wheel_limit)

    def stretch(self, speed: np.ndarray, command: np.ndarray, h: float):
        """A first-order lag over h from `speed` towards `command`: (mean, end) wheel speeds.

        ω(t) = c + (ω₀ − c)·e^(−t/τ); its mean over h is c + (ω₀ − c)·(τ/h)·(1 − e^(−h/τ)).
        """
        if self.lag == 0.0 or h == 0.0:
            return command, command
        decay = math.exp(-h / self.lag)
        mean = command + (speed - command) * (self.lag / h) * (1.0 - decay)
        return mean, command + (speed - command) * decay

    def period_pieces(self, speed: np.ndarray, previous: np.ndarray, command: np.ndarray):
        """One period's stretches [(h, mean wheel speeds)] and the wheels' speed at its end.

        A command acts after the transport delay D: [0, D) still under the previous one.
        """
        pieces = []
        for h, acting in ((self.delay, previous), (self.period - self.delay, command)):
            if h > 0.0:
                mean, speed = self.stretch(speed, acting, h)
                pieces.append((h, mean))
        return pieces, speed

    def move(self, pose: np.ndarray, pieces, noise: np.ndarray, slip: np.ndarray) -> np.ndarray:
        """Euler over each stretch at the period's starting heading, the slipped mean speeds,
        plus (h/T)·w (docs/world.md, "Motion"; with a delay the period's two stretches both
        move along the heading the period starts with, as the simulator does: checked on a
        noise-free trace to 4 µm)."""
        pose = pose.copy()
        heading = pose[2]
        for h, mean in pieces:
            wheels = mean * (1.0 + self.slip_std * slip)
            v = self.wheel_radius * (wheels[0] + wheels[1]) / 2.0
            omega = self.wheel_radius * (wheels[0] - wheels[1]) / self.axle
            pose = pose + h * np.array([v * math.cos(heading), v * math.sin(heading), omega])
            pose = pose + (h / self.period) * noise
        return pose


class NotCovered(Exception):
    """A world or protocol the independent model does not cover."""


@dataclass
class Trace:
    """The columns of one trace.csv the eavesdropper reads."""

    pose: np.ndarray
    measurement: np.ndarray
    camera: np.ndarray
    nominal: np.ndarray
    bit: np.ndarray
    bit_omega: np.ndarray
    robokey_eve: np.ndarray

    @staticmethod
    def read(path: Path) -> "Trace":
        """Reads trace.csv (docs/experiments.md); an empty cell is NaN (bits: −1)."""
        with path.open() as f:
            rows = list(csv.DictReader(f))

        def reals(*cols: str) -> np.ndarray:
            return np.array([[float(r[c]) if r[c] else math.nan for c in cols] for r in rows])

        def ints(col: str) -> np.ndarray:
            return np.array([int(r[col]) if r[col] else -1 for r in rows])

        return Trace(
            pose=reals("px", "py", "theta"),
            measurement=reals("meas_x", "meas_y", "meas_theta"),
            camera=reals("eve_x", "eve_y", "eve_theta"),
            nominal=reals("v_nom", "omega_nom"),
            bit=ints("b"),
            bit_omega=ints("b_omega"),
            robokey_eve=ints("bhat_eve"),
        )


def ar1_conditional(rho: float, hidden: int, before, after, std: np.ndarray):
    """Mean (hidden×3) and per-axis covariance (hidden×hidden) of `hidden` consecutive AR(1)
    noises given the one before and the one after them (either may be absent).

    Per axis the stationary AR(1) covariance is σ²ρ^|i−j|; conditioning is the Gaussian's.
    """
    size = hidden + 2
    idx = np.arange(size)
    corr = rho ** np.abs(idx[:, None] - idx[None, :]).astype(float)
    inner = list(range(1, hidden + 1))
    known = [i for i, w in ((0, before), (size - 1, after)) if w is not None]
    values = [w for w in (before, after) if w is not None]
    c_hh = corr[np.ix_(inner, inner)]
    if not known:
        return np.zeros((hidden, 3)), [c_hh * s**2 for s in std]
    c_hk = corr[np.ix_(inner, known)]
    gain = c_hk @ np.linalg.inv(corr[np.ix_(known, known)])
    return gain @ np.array(values), [(c_hh - gain @ c_hk.T) * s**2 for s in std]


class Session:
    """One session's public commands and the genie's knowledge: every bit and true pose."""

    def __init__(self, world: World, trace: Trace):
        self.world, self.trace = world, trace
        self.last = len(trace.pose) - 1
        # The wheels start at rest; the genie's bits give every step's applied command.
        self.command = [np.zeros(2)]
        self.entry = []
        speed = np.zeros(2)
        for k in range(self.last):
            self.entry.append(speed)
            self.command.append(self.applied(k, self.pattern(k)))
            _, speed = world.period_pieces(speed, self.command[k], self.command[k + 1])

    def pattern(self, k: int) -> tuple[int, ...]:
        """The true bits of step k's doublet, its v bit then (two bits per doublet) its ω bit;
        () where the doublet carries none."""
        if self.trace.bit[k] < 0:
            return ()
        return (int(self.trace.bit[k]), int(self.trace.bit_omega[k]))[: self.world.bits]

    def offset(self, k: int, pattern: tuple[int, ...]) -> np.ndarray:
        """Step k's (v, ω) offset for its doublet's bits: (+1, −1)·s∘Δ, or (+1, −(1 + α), +α)·s∘Δ
        with three steps, Δ = (Δv, Δω), s = 1 − 2b per carried bit (0 on ω with one bit per
        doublet; docs/private-sensing.md)."""
        if not pattern:
            return np.zeros(2)
        signs = np.zeros(2)
        signs[: len(pattern)] = [1.0 - 2.0 * b for b in pattern]
        within = k % self.world.steps
        if self.world.steps == 2:
            shape = 1.0 if within == 0 else -1.0
        else:
            shape = (1.0, -(1.0 + self.world.settle), self.world.settle)[within]
        return shape * signs * np.array([self.world.delta_v, self.world.delta_omega])

    def applied(self, k: int, pattern: tuple[int, ...]) -> np.ndarray:
        """Step k's wheel command under `pattern` for its doublet (`command[k + 1]`)."""
        nominal = self.trace.nominal[k]
        if math.isnan(nominal[0]):
            return np.zeros(2)
        offset = self.offset(k, pattern)
        return self.world.wheels(nominal[0] + offset[0], nominal[1] + offset[1])

    def run(self, doublet: int, first: int, count: int, pattern: tuple[int, ...], latent: np.ndarray) -> np.ndarray:
        """Poses x(first + 1 … first + count) from the true x(first), the steps of the doublet
        starting at `doublet` under `pattern`, latent = [w (3), z (2)] per step."""
        world, pose = self.world, self.trace.pose[first]
        speed = self.entry[first]
        previous = self.command[first]
        out = []
        for i, k in enumerate(range(first, first + count)):
            same_doublet = k - k % world.steps == doublet
            command = self.applied(k, pattern) if same_doublet else self.command[k + 1]
            pieces, speed = world.period_pieces(speed, previous, command)
            pose = world.move(pose, pieces, latent[5 * i : 5 * i + 3], latent[5 * i + 3 : 5 * i + 5])
            previous = command
            out.append(pose)
        return np.concatenate(out)

    def noise(self, k: int) -> np.ndarray | None:
        """w_k as the given poses fix it (slip-free worlds): x(k+1) − F(x(k), no noise)."""
        if k < 0 or k + 1 > self.last:
            return None
        return self.trace.pose[k + 1] - self.run(k - k % self.world.steps, k, 1, self.pattern(k), np.zeros(5))


def patterns(bits: int) -> list[tuple[int, ...]]:
    """A doublet's bit patterns, pattern p's bit i being bit i of p: (v,) or (v, ω)."""
    return [tuple((p >> i) & 1 for i in range(bits)) for p in range(1 << bits)]


def doublet_likelihoods(
    world: World, trace: Trace, boundaries: str = "samples"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per carrying doublet: its true bits (doublets × bits: v, then ω), her log-likelihood
    ln p(o | pattern) of her observations under each of its `patterns` (doublets × 2^bits),
    and robokey's camera eavesdropper's decision of its v bit.

    She models the doublet's L steps and the one after it (a delay or a lag other than the
    prior carries the bit into it), linearised about each hypothesis's noise-free run. The
    genie gives her the true pose at every instant but the doublet's own; she observes her
    camera at the doublet's instants and, at its two boundaries, the controller's samples
    (`boundaries = "samples"`: the key's camera eavesdropper's view of the doublet) or the
    true poses (`"true"`: a stronger genie). A sample's jitter j moves it by j·ẋ: its
    covariance jitter²·ẋẋᵀ (ẋ the step's nominal rate) is added to the sample's.
    """
    session = Session(world, trace)
    steps, last = world.steps, session.last
    count = steps + 1
    truth, loglik, robokey = [], [], []
    for first in range(0, last - count + 1, steps):
        if trace.bit[first] < 0:
            continue
        start = first - 1 if boundaries == "samples" and first > 0 else first
        n = first + count - start
        mean_w, cov_w = ar1_conditional(
            world.rho, n, session.noise(start - 1), session.noise(start + n), world.process_std
        )
        if world.rho == 0.0:
            mean_w = np.zeros((n, 3))
        latent_mean = np.zeros(5 * n)
        latent_cov = np.zeros((5 * n, 5 * n))
        for i in range(n):
            latent_mean[5 * i : 5 * i + 3] = mean_w[i]
            latent_cov[5 * i + 3 : 5 * i + 5, 5 * i + 3 : 5 * i + 5] = np.eye(2)
            for j in range(n):
                for axis in range(3):
                    latent_cov[5 * i + axis, 5 * j + axis] = cov_w[axis][i, j]
        # What she observes: (instant, value, covariance) — every camera sample of the
        # doublet, the boundaries' controller samples or true poses, the true pose at the end.
        observed = []
        for instant in range(start + 1, first + count + 1):
            if instant == first + count:
                observed.append((instant, trace.pose[instant], np.zeros((3, 3))))
                continue
            observed.append((instant, trace.camera[instant], np.diag(world.camera_std**2)))
            if instant in (first, first + steps):
                if boundaries == "samples":
                    v, omega = trace.nominal[instant - 1]
                    heading = trace.camera[instant][2]
                    rate = np.array([v * math.cos(heading), v * math.sin(heading), omega])
                    spread = np.diag(world.controller_std**2) + world.jitter**2 * np.outer(rate, rate)
                    observed.append((instant, trace.measurement[instant], spread))
                else:
                    observed.append((instant, trace.pose[instant], np.zeros((3, 3))))
        rows = [3 * (instant - start - 1) + a for instant, _, _ in observed for a in range(3)]
        obs = np.concatenate([value for _, value, _ in observed])
        noise = np.zeros((len(rows), len(rows)))
        for o, (_, _, cov) in enumerate(observed):
            noise[3 * o : 3 * o + 3, 3 * o : 3 * o + 3] = cov
        logp = []
        jac = np.zeros((3 * n, 5 * n))
        for index, pattern in enumerate(patterns(world.bits)):
            mean = session.run(first, start, n, pattern, latent_mean)
            # Forward differences (the map is linear in w but for the heading's turn of the
            # next steps' travel). Only slip makes the Jacobian depend on the bits (its
            # columns scale with the wheel speeds); otherwise the first pattern's serves.
            if index == 0 or world.slip_std > 0.0:
                for c in range(5 * n):
                    if c % 5 >= 3 and world.slip_std == 0.0:
                        continue  # without slip its latent moves nothing
                    h = 1e-7
                    step = np.zeros(5 * n)
                    step[c] = h
                    jac[:, c] = (session.run(first, start, n, pattern, latent_mean + step) - mean) / h
            g = jac[rows]
            sigma = g @ latent_cov @ g.T + noise
            r = obs - mean[rows]
            _, logdet = np.linalg.slogdet(sigma)
            logp.append(-0.5 * (r @ np.linalg.solve(sigma, r) + logdet))
        truth.append(session.pattern(first))
        loglik.append(logp)
        robokey.append(trace.robokey_eve[first + steps - 1])
    return np.array(truth).reshape(-1, world.bits), np.array(loglik), np.array(robokey)


def genie_llrs(truth: np.ndarray, loglik: np.ndarray) -> np.ndarray:
    """Each bit's LLR ln p(o | b = 0, b_≠) − ln p(o | b = 1, b_≠), the doublet's other bit b_≠
    at its true value (robokey's genie, docs/secrecy.md): doublets × bits, like `truth`."""
    weights = 1 << np.arange(truth.shape[1])
    index = truth @ weights
    rows = np.arange(len(truth))
    llr = np.empty(truth.shape)
    for i, weight in enumerate(weights):
        zero = index & ~weight
        llr[:, i] = loglik[rows, zero] - loglik[rows, zero | weight]
    return llr


def doublet_llrs(
    world: World, trace: Trace, boundaries: str = "samples"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per carried bit (a doublet's v bit, then its ω bit): the true bit, her genie LLR
    ln p(o|b=0)/p(o|b=1) and robokey's camera eavesdropper's decision (−1 where the trace
    holds none: its ω bits)."""
    truth, loglik, robokey = doublet_likelihoods(world, trace, boundaries)
    decisions = np.full(truth.shape, -1)
    decisions[:, 0] = robokey
    return truth.reshape(-1), genie_llrs(truth, loglik).reshape(-1), decisions.reshape(-1)


def error_probabilities(truth: np.ndarray, llr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Her posterior error probability q_i = P(wrong | view) and P_i = P(true bit | view)."""
    q = 1.0 / (1.0 + np.exp(np.abs(llr)))
    true_llr = np.where(truth == 0, llr, -llr)
    p_true = 1.0 / (1.0 + np.exp(-true_llr))
    return q, p_true


def smooth_min_entropy(posteriors: np.ndarray, epsilon: float) -> float:
    """t = max_λ (−Σ_u ln Σ_x P_u(x)^{1+λ} − ln(1/ε)) / (λ ln 2), in bits (module doc), for
    independent units u (bits or doublets), P_u her posterior over unit u's values: rows of
    `posteriors` (a bit's is (1 − q, q)). E[P_u(X)^λ | view] = Σ_x P_u(x)^{1+λ}."""
    best = 0.0
    for lam in np.exp(np.linspace(math.log(1e-4), math.log(50.0), 400)):
        moment = np.sum(np.log(np.sum(posteriors ** (1.0 + lam), axis=1)))
        best = max(best, (-moment - math.log(1.0 / epsilon)) / (lam * math.log(2.0)))
    return best


def bit_posteriors(q: np.ndarray) -> np.ndarray:
    """Independent bits' posteriors (1 − q, q) for `smooth_min_entropy`."""
    return np.column_stack([1.0 - q, q])


def pair_posteriors(truth: np.ndarray, loglik: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """Her exact posterior over each two-bit doublet's kept bits (`kept`: doublets × bits, the
    bits not disclosed): over its four patterns where both are kept, over the kept bit's two
    values (0, 1, then zeros) with the disclosed one at its true value where one is; doublets
    with no kept bit left out."""
    posteriors = np.exp(loglik - loglik.max(axis=1, keepdims=True))
    posteriors /= posteriors.sum(axis=1, keepdims=True)
    llr = genie_llrs(truth, loglik)
    for i in range(truth.shape[1]):
        alone = kept[:, i] & ~kept[:, 1 - i]
        zero = 1.0 / (1.0 + np.exp(-llr[alone, i]))
        posteriors[alone] = 0.0
        posteriors[alone, 0], posteriors[alone, 1] = zero, 1.0 - zero
    return posteriors[kept.any(axis=1)]


def output_length(h_min: float, leak_ec: int, epsilon: float) -> int:
    """ℓ = ⌊H − leak_EC − 128 − 2·log₂(1/ε) + 2⌋⁺ (docs/secrecy.md)."""
    return max(0, math.floor(h_min - leak_ec - TAG_BITS - 2.0 * math.log2(1.0 / epsilon) + 2.0))


def simulate(robokey: str, config: Path, sets: list[str], replicate: int, out: Path) -> Path:
    """One session through `robokey run` (robokey's own eavesdropper off); returns its folder."""
    folder = out / f"replicate-{replicate}"
    args = [robokey, "run", "-c", str(config), "--no-eve", "--replicate", str(replicate), "-o", str(folder)]
    for s in sets:
        args += ["--set", s]
    subprocess.run(args, check=True, capture_output=True)
    return folder


def point_sets(point: str) -> list[str]:
    """`world.lag = 0.02, private.prior_lag = 0.02` → ['world.lag=0.02', 'private.prior_lag=0.02']."""
    parts = re.split(r",\s*(?=[a-z_]+\.[a-z_]+ = )", point)
    return [p.replace(" ", "") for p in parts if p]


def point_config(folder: Path, out: Path) -> Path:
    """The experiment's resolved configuration without its sweep and secrecy tables."""
    text = (folder / "config.resolved.toml").read_text()
    kept, skipping = [], False
    for line in text.splitlines():
        if line.startswith("["):
            skipping = line.strip() in ("[sweep]", "[secrecy]")
        if not skipping:
            kept.append(line)
    path = out / "config.toml"
    path.write_text("\n".join(kept) + "\n")
    return path


def collect(robokey: str, config: Path, sets: list[str], bits: int, out: Path, boundaries: str):
    """Sessions until `bits` carried bits: per doublet the truth and her log-likelihoods of
    its patterns (`doublet_likelihoods`)."""
    truth, loglik = [], []
    replicate, carried = 0, 0
    while carried < bits:
        folder = simulate(robokey, config, sets, replicate, out)
        world = World.of(tomllib.loads((folder / "config.resolved.toml").read_text()))
        t, l, _ = doublet_likelihoods(world, Trace.read(folder / "trace.csv"), boundaries)
        truth.append(t)
        loglik.append(l)
        carried += t.size
        replicate += 1
    doublets = bits // truth[0].shape[1]
    return np.concatenate(truth)[:doublets], np.concatenate(loglik)[:doublets]


def blocks(folder: Path) -> dict[tuple[str, str], dict]:
    """(experiment, point) → the camera adversary's first block and ε, from secrecy.json."""
    found = {}
    for path in sorted(folder.glob("*/secrecy.json")):
        report = json.loads(path.read_text())
        for result in report["results"]:
            if result["adversary"] == "camera":
                found[(path.parent.name, result["point"])] = {
                    "block": result["blocks"][0],
                    "epsilon": report["epsilon"],
                }
    return found


def grid(
    folder: Path, robokey: str, world: Path | None, configured: Path | None, boundaries: str
) -> list[dict]:
    """Every point of every experiment under `folder` (measured sizing), beside the same
    points sized at the true world and as configured when their folders are given."""
    at_world = blocks(world) if world else {}
    as_configured = blocks(configured) if configured else {}
    rows = []
    for (experiment, point), found in blocks(folder).items():
        block, epsilon = found["block"], found["epsilon"]
        row = {
            "experiment": experiment,
            "point": point,
            "n": block["reconciled_bits"],
            "leak_ec": block["leak_ec"],
            "ell": block["secret_bits"],
            "robokey_h_min": block["realised"]["h_min"],
            "robokey_ell": block["realised"]["secret_bits"],
            "reason": block.get("reason"),
            "world_ell": at_world.get((experiment, point), {}).get("block", {}).get("secret_bits"),
            "configured_ell": as_configured.get((experiment, point), {}).get("block", {}).get("secret_bits"),
        }
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp)
            try:
                truth, loglik = collect(robokey, point_config(folder / experiment, out), point_sets(point), block["bits"], out, boundaries)
            except NotCovered as why:
                row["not_covered"] = str(why)
                rows.append(row)
                continue
        # The block's sessions are `robokey run`'s replicates 0, 1, … at the sweep's seed, so
        # these are the block's raw bits; the disclosed sample's positions are not exported:
        # a seeded random choice of the kept count stands in for them.
        kept = np.zeros(truth.size, dtype=bool)
        kept[np.random.default_rng(0).choice(truth.size, size=row["n"], replace=False)] = True
        kept = kept.reshape(truth.shape)
        bits, llr = truth[kept], genie_llrs(truth, loglik)[kept]
        q, _ = error_probabilities(bits, llr)
        h = smooth_min_entropy(bit_posteriors(q), epsilon)
        row["independent_h_min"] = h
        row["independent_error"] = float(np.mean((llr < 0) != (bits == 1)))
        row["independent_ell"] = output_length(h, row["leak_ec"], epsilon)
        pair = ""
        if truth.shape[1] == 2:
            row["pair_h_min"] = smooth_min_entropy(pair_posteriors(truth, loglik, kept), epsilon)
            row["pair_ell"] = output_length(row["pair_h_min"], row["leak_ec"], epsilon)
            pair = f"; the doublets' exact pairs: H {row['pair_h_min']:.0f}, ℓ {row['pair_ell']}"
        rows.append(row)
        print(
            f"{experiment}: {point}: ℓ {row['ell']}; robokey's camera Eve: H {row['robokey_h_min']:.0f}, "
            f"ℓ {row['robokey_ell']}; independent: H {h:.0f}, ℓ {row['independent_ell']}, "
            f"errs {row['independent_error']:.3f} on {len(q)} bits{pair}",
            file=sys.stderr,
        )
    return rows


def table(rows: list[dict]) -> str:
    """The grid as a markdown table."""
    lines = [
        "| experiment | point | ℓ measured | configured | truth-configured | measured / truth "
        "| robokey's camera Eve: H_min^ε, ℓ | independent Eve: H_min^ε, ℓ | ℓ ≤ both | refusal |",
        "|---|---|---:|---:|---:|---:|---:|---:|---|---|",
    ]

    def count(value: int | None) -> str:
        return "—" if value is None else f"{value:,}"

    for r in rows:
        ratio = f"{100.0 * r['ell'] / r['world_ell']:.1f} %" if r.get("world_ell") else "—"
        robokey = f"{r['robokey_h_min']:,.0f}, {r['robokey_ell']:,}"
        if "not_covered" in r:
            independent, bound = f"not covered ({r['not_covered']})", r["robokey_ell"]
        else:
            independent = f"{r['independent_h_min']:,.0f}, {r['independent_ell']:,}"
            bound = min(r["robokey_ell"], r["independent_ell"])
        within = "yes" if r["ell"] <= bound else "**no**"
        refused = r["reason"].split(" (")[0] if r["reason"] and r["reason"].startswith("block refused") else ""
        lines.append(
            f"| {r['experiment']} | {r['point']} | {r['ell']:,} | {count(r.get('configured_ell'))} | "
            f"{count(r.get('world_ell'))} | {ratio} | {robokey} | {independent} | {within} | {refused} |"
        )
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("folder", type=Path, help="a sweep folder after `robokey secrecy --sizing measured`")
    parser.add_argument("--world", type=Path, help="the same sweep after `robokey secrecy --sizing world`")
    parser.add_argument("--configured", type=Path, help="the same sweep after `--sizing configured`")
    parser.add_argument(
        "--boundaries",
        choices=("samples", "true"),
        default="samples",
        help="what she holds at each doublet's boundaries: the controller's samples, or the true poses",
    )
    parser.add_argument("--robokey", default=os.environ.get("ROBOKEY_BIN", "robokey"))
    parser.add_argument("--out", type=Path, help="write the table (markdown) here, its rows beside it (.json)")
    args = parser.parse_args()
    rows = grid(args.folder, args.robokey, args.world, args.configured, args.boundaries)
    text = table(rows)
    print(text)
    if args.out:
        args.out.write_text(text)
        args.out.with_suffix(".json").write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
