#!/usr/bin/env python3
"""The most a camera eavesdropper can learn of a v-bit on a straight doublet in a world with
per-wheel slip (docs/world.md, "Where they disagree"), computed independently of robokey's
code: the exact Bayes-optimal view with the bit-dependent covariance, by Monte-Carlo.

The robot drives straight (along x) at v + sΔv for T, then v − sΔv, s = ±1. Each wheel's
travel in a step is multiplied by 1 + σ·z (z ~ N(0, 1) per wheel and step), so the step's
speed is v_k·(1 + σ(z_r + z_l)/2) and its turn rate v_k·σ(z_r − z_l)/D: the slip's variance
follows the hypothesis' speeds. Additive white motion noise per step; the Euler map. Her
view: the controller's samples at the doublet's boundaries (the commands carry them) and her
camera at the three instants, every pose component; the start pose unknown (flat prior).
Linearised about the straight path, given s the view is Gaussian, `y = A_s·p₀ + μ_s + ε`,
`ε ~ N(0, Σ_s)`, and the flat prior integrates to

    ln p(y | s) = −½·ln det Σ_s − ½·ln det(A_sᵀΣ_s⁻¹A_s) − ½·rᵀ(Σ_s⁻¹ − Σ_s⁻¹A_s(A_sᵀΣ_s⁻¹A_s)⁻¹A_sᵀΣ_s⁻¹)r.

Doublets are drawn from the reference's speed profile on a side (v = (L/Ts)·6(u − u²),
u uniform), simulated with the nonlinear Euler map, and her information 1 − h(posterior) is
averaged; the printout gives it with its 95 % interval, beside the linear-Gaussian estimate.

    scripts/slip-doublet-optimum.py [SLIP] [MOTION_MM] [DOUBLETS]
"""

import math
import random
import sys

T = 0.2  # s
DELTA_V = 0.035  # m/s
AXLE = 0.1047  # m
SIDE, SIDE_TIME = 1.0, 17.0  # m, s: the reference's square
SIGMA_C = [0.0005] * 3  # the controller's sensor (m, m, rad)
SIGMA_E = [0.008] * 3  # Eve's camera per instant


def inverse_and_log_det(a):
    n = len(a)
    m = [row[:] + [1.0 if i == j else 0.0 for j in range(n)] for i, row in enumerate(a)]
    log_det = 0.0
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(m[r][c]))
        m[c], m[p] = m[p], m[c]
        pivot = m[c][c]
        log_det += math.log(abs(pivot))
        m[c] = [x / pivot for x in m[c]]
        for r in range(n):
            if r != c and m[r][c] != 0.0:
                f = m[r][c]
                m[r] = [x - f * y for x, y in zip(m[r], m[c])]
    return [row[n:] for row in m], log_det


def matmul(a, b):
    bt = list(zip(*b))
    return [[sum(x * y for x, y in zip(row, col)) for col in bt] for row in a]


def transpose(a):
    return [list(r) for r in zip(*a)]


def model(v, s, slip, motion):
    """(A, μ, Σ) of her 15 observations [c0, e0, e1, c2, e2] given the start pose."""
    v1, v2 = v + s * DELTA_V, v - s * DELTA_V
    # Latents: a1, b1, a2, b2 (slip: a = (z_r + z_l)/2 ~ var ½, b = z_r − z_l ~ var 2),
    # w1 (3), w2 (3).
    lat_var = [0.5, 2.0, 0.5, 2.0] + [m * m for m in motion] * 2
    # Linear maps of the latents to the pose deviations at instants 1 and 2 (x, y, θ).
    def zeros():
        return [[0.0] * 10 for _ in range(3)]
    p1 = zeros()
    p1[0][0] = T * v1 * slip
    p1[0][4] = 1.0
    p1[1][5] = 1.0
    p1[2][1] = T * v1 * slip / AXLE
    p1[2][6] = 1.0
    p2 = [row[:] for row in p1]
    p2[0][2] += T * v2 * slip
    p2[0][7] += 1.0
    for j in range(10):  # y2 = y1 + T·v2·θ1 + w2y
        p2[1][j] += T * v2 * p1[2][j]
    p2[1][8] += 1.0
    p2[2][3] += T * v2 * slip / AXLE
    p2[2][9] += 1.0
    zero = zeros()
    blocks = [(zero, SIGMA_C), (zero, SIGMA_E), (p1, SIGMA_E), (p2, SIGMA_C), (p2, SIGMA_E)]
    g = [row for b, _ in blocks for row in b]
    noise = [s_ * s_ for _, sig in blocks for s_ in sig]
    sigma = [
        [sum(g[i][k] * g[j][k] * lat_var[k] for k in range(10)) + (noise[i] if i == j else 0.0)
         for j in range(15)]
        for i in range(15)
    ]
    # Means given the start pose p0 = (x0, y0, θ0): A·p0 + μ.
    a_rows, mu = [], []
    for instant in (0, 0, 1, 2, 2):
        travel = {0: 0.0, 1: T * v1, 2: T * (v1 + v2)}[instant]
        a_rows += [[1.0, 0.0, 0.0], [0.0, 1.0, travel], [0.0, 0.0, 1.0]]
        mu += [travel, 0.0, 0.0]
    return a_rows, mu, sigma


def likelihood(a, mu, sigma):
    """The flat-prior log-likelihood of y under one hypothesis, as a function."""
    inv, log_det = inverse_and_log_det(sigma)
    at_inv = matmul(transpose(a), inv)
    fisher = matmul(at_inv, a)
    fisher_inv, fisher_log_det = inverse_and_log_det(fisher)
    proj = matmul(transpose(at_inv), matmul(fisher_inv, at_inv))
    p = [[inv[i][j] - proj[i][j] for j in range(15)] for i in range(15)]
    const = -0.5 * log_det - 0.5 * fisher_log_det

    def ll(y):
        r = [yi - mi for yi, mi in zip(y, mu)]
        q = sum(r[i] * sum(p[i][j] * r[j] for j in range(15)) for i in range(15))
        return const - 0.5 * q

    return ll


def simulate(v, s, slip, motion, rng):
    """Her 15 observations of a simulated doublet (nonlinear Euler map)."""
    pose = [rng.uniform(-1, 1), rng.uniform(-1, 1), rng.gauss(0.0, 0.01)]
    poses = [pose[:]]
    for vk in (v + s * DELTA_V, v - s * DELTA_V):
        zr, zl = rng.gauss(0, 1), rng.gauss(0, 1)
        speed = vk * (1 + slip * (zr + zl) / 2)
        turn = vk * slip * (zr - zl) / AXLE
        x, y, th = pose
        pose = [x + T * speed * math.cos(th) + rng.gauss(0, motion[0]),
                y + T * speed * math.sin(th) + rng.gauss(0, motion[1]),
                th + T * turn + rng.gauss(0, motion[2])]
        poses.append(pose[:])
    out = []
    for instant, sig in ((0, SIGMA_C), (0, SIGMA_E), (1, SIGMA_E), (2, SIGMA_C), (2, SIGMA_E)):
        out += [poses[instant][i] + rng.gauss(0, sig[i]) for i in range(3)]
    return out


def entropy_bits(llr):
    p = 1 / (1 + math.exp(-abs(llr)))
    return -(p * math.log2(p) + (1 - p) * math.log2(1 - p)) if p < 1 else 0.0


def main():
    slip = float(sys.argv[1]) if len(sys.argv) > 1 else 0.05
    motion = [float(sys.argv[2]) / 1e3 if len(sys.argv) > 2 else 0.002] * 3
    doublets = int(sys.argv[3]) if len(sys.argv) > 3 else 20000
    rng = random.Random(2023)
    grid = 40
    infos = []
    for g in range(grid):
        u = (g + 0.5) / grid
        v = SIDE / SIDE_TIME * 6 * (u - u * u)
        ll = {s: likelihood(*model(v, s, slip, motion)) for s in (1, -1)}
        for _ in range(doublets // grid):
            s = rng.choice((1, -1))
            y = simulate(v, s, slip, motion, rng)
            llr = ll[s](y) - ll[-s](y)
            infos.append(1 - entropy_bits(llr))
    n = len(infos)
    mean = sum(infos) / n
    se = math.sqrt(sum((i - mean) ** 2 for i in infos) / (n - 1) / n)
    print(f"slip {slip:.0%}, motion {motion[0] * 1e3:g} mm, {n} straight doublets over a side's "
          f"speed profile: her Bayes-optimal information {mean:.4f} "
          f"[{mean - 1.96 * se:.4f}, {mean + 1.96 * se:.4f}] bit per bit")


if __name__ == "__main__":
    main()
