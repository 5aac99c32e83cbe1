#!/usr/bin/env python3
"""The most a camera eavesdropper can learn of a v-bit on a straight doublet (docs/world.md,
"Where they disagree"), computed independently of robokey's code.

Along the track of a straight doublet the bit moves only the mid pose: the robot drives
T·(v + sΔv) then T·(v − sΔv), s = ±1, so the two hypotheses differ by 2TΔv at the mid instant
and not at all at the boundaries. Her view: the controller's boundary samples (noise σ_c, the
commands carry them) and her camera at every instant (noise σ_e); each step adds white motion
noise σ_w; the start pose is unknown (a flat prior). Everything is linear and Gaussian, so
the Bayes-optimal log-likelihood ratio is Gaussian with separation

    d² = Δμᵀ (Σ⁻¹ − Σ⁻¹1 (1ᵀΣ⁻¹1)⁻¹ 1ᵀΣ⁻¹) Δμ

(Σ the observations' covariance given the start, Δμ the hypotheses' mean difference; the
projection removes the unknown start). With her doublet alone this is
d = 2TΔv / √(σ_e² + (σ_c² + σ_w²)/2) to within her boundary frames; with N neighbouring
straight doublets each side, their bits known, the neighbours' samples pin the boundaries.
A Monte-Carlo of the same model checks the closed form. Per bit it prints her information
I(d) = 1 − E[h(posterior)] and her min-entropy E[−log₂ max posterior], and, from the
parties' assumed separation, the over-claim in min-entropy per bit and the camera an
over-claim would need.

    scripts/straight-doublet-optimum.py            # the defaults of robokey's parties
"""

import math
import random

T = 0.2  # s, sample time
DELTA_V = 0.035  # m/s, the doublet's speed offset
SIGMA_C = 0.0005  # m, the controller's sensor
SIGMA_E = 0.008  # m, Eve's camera per instant
D_ASSUMED = 1.665  # the parties' separation (8 mm camera, 4 mm motion noise: `robokey secrecy`)


def solve(a, b):
    """x with a·x = b (Gauss-Jordan with partial pivoting; a square, b a list of columns)."""
    n = len(a)
    m = [row[:] + [col[i] for col in b] for i, row in enumerate(a)]
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(m[r][c]))
        m[c], m[p] = m[p], m[c]
        for r in range(n):
            if r != c:
                f = m[r][c] / m[c][c]
                m[r] = [x - f * y for x, y in zip(m[r], m[c])]
    return [[m[i][n + j] / m[i][i] for i in range(n)] for j in range(len(b))]


def view(sigma_w, neighbours, sigma_e=SIGMA_E):
    """(Σ, Δμ, observation rows) of her view of the middle doublet of 2·neighbours + 1."""
    doublets = 2 * neighbours + 1
    instants = 2 * doublets + 1
    target = neighbours
    rows = []  # (instant, noise std)
    for k in range(instants):
        if k % 2 == 0:
            rows.append((k, SIGMA_C))
        rows.append((k, sigma_e))
    # x_k − x_0 is the sum of the first k steps' noise: cov = σ_w²·min(k, k').
    sigma = [
        [sigma_w**2 * min(ka, kb) + (sa**2 if i == j else 0.0) for j, (kb, sb) in enumerate(rows)]
        for i, (ka, sa) in enumerate(rows)
    ]
    mid = 2 * target + 1
    delta = [2 * T * DELTA_V if k == mid else 0.0 for k, _ in rows]
    return sigma, delta, rows


def separation(sigma_w, neighbours, sigma_e=SIGMA_E):
    """Her Bayes-optimal separation d, the start unknown."""
    sigma, delta, _ = view(sigma_w, neighbours, sigma_e)
    ones = [1.0] * len(delta)
    s_delta, s_ones = solve(sigma, [delta, ones])
    a = sum(x * y for x, y in zip(delta, s_delta))
    b = sum(x * y for x, y in zip(ones, s_delta))
    c = sum(x * y for x, y in zip(ones, s_ones))
    return math.sqrt(a - b * b / c)


def expect(d, f, points=4001):
    """E[f(L)] over her LLR L ~ N(d²/2, d²) for the true bit (Simpson's rule, ±10 σ)."""
    lo, hi = d * d / 2 - 10 * d, d * d / 2 + 10 * d
    h = (hi - lo) / (points - 1)
    total = 0.0
    for i in range(points):
        x = lo + i * h
        w = 1 if i in (0, points - 1) else (4 if i % 2 else 2)
        z = (x - d * d / 2) / d
        total += w * f(x) * math.exp(-z * z / 2) / (d * math.sqrt(2 * math.pi))
    return total * h / 3


def entropy_bits(llr):
    p = 1 / (1 + math.exp(-abs(llr)))
    return -(p * math.log2(p) + (1 - p) * math.log2(1 - p)) if p < 1 else 0.0


def information(d):
    return 1 - expect(d, entropy_bits)


def min_entropy(d):
    return expect(d, lambda llr: math.log2(1 + math.exp(-abs(llr))))


def monte_carlo(sigma_w, neighbours, n, rng):
    """Her information measured on simulated doublets with the exact GLS log-likelihood."""
    sigma, delta, rows = view(sigma_w, neighbours)
    ones = [1.0] * len(delta)
    s_delta, s_ones = solve(sigma, [delta, ones])
    c = sum(s_ones)
    b = sum(s_delta)
    # The LLR of s = +1 against −1 is Δμᵀ P (y − μ₀), P the projected precision; with the
    # start's flat prior it does not depend on x_0.
    weights = [sd - b / c * so for sd, so in zip(s_delta, s_ones)]
    total = 0.0
    instants = max(k for k, _ in rows) + 1
    for _ in range(n):
        bit = rng.choice((1.0, -1.0))
        x = [rng.uniform(-1.0, 1.0)]
        for k in range(1, instants):
            x.append(x[-1] + rng.gauss(0.0, sigma_w))
        y = [x[k] + rng.gauss(0.0, s) + bit * dm / 2 for (k, s), dm in zip(rows, delta)]
        llr = sum(w * v for w, v in zip(weights, y))
        total += 1 - entropy_bits(llr if bit > 0 else -llr)
    return total / n


def main():
    rng = random.Random(2023)
    h_assumed = min_entropy(D_ASSUMED)
    print(f"parties' separation {D_ASSUMED}: information {information(D_ASSUMED):.4f}, "
          f"min-entropy {h_assumed:.4f} bit per bit")
    print("sigma_w mm | d alone | I alone | d N=12 | I N=12 | Monte-Carlo I (N=12, 20000) "
          "| over-claim alone | over-claim N=12")
    for sigma_w in (0.00005, 0.0005, 0.001, 0.002, 0.004, 0.008):
        d0 = separation(sigma_w, 0)
        dn = separation(sigma_w, 12)
        mc = monte_carlo(sigma_w, 12, 20000, rng)
        print(f"{sigma_w * 1e3:10.2f} | {d0:.4f} | {information(d0):.4f} | {dn:.4f} | "
              f"{information(dn):.4f} | {mc:.4f} | {h_assumed - min_entropy(d0):+.4f} | "
              f"{h_assumed - min_entropy(dn):+.4f}")
    for target in (0.047, 0.091):
        lo, hi = D_ASSUMED, 6.0
        for _ in range(60):
            mid = (lo + hi) / 2
            if h_assumed - min_entropy(mid) < target:
                lo = mid
            else:
                hi = mid
        camera = math.sqrt((2 * T * DELTA_V / lo) ** 2 - (SIGMA_C**2) / 2)
        print(f"an over-claim of {target:+.3f} per bit on straight doublets needs d = {lo:.3f}: "
              f"a camera of {camera * 1e3:.2f} mm per instant with no motion noise")


if __name__ == "__main__":
    main()
