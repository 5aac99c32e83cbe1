//! The command-quantum check (docs/estimation.md, "Command quantum"), one implementation for
//! the simulator and the agents: after reconciliation, does the robot round its wheel
//! commands more coarsely than the parties state (`robot.command_quantum`)? An understated
//! quantum over-claims — the bit's rounding moves the robot, Eve reads it from the public
//! commands, and the stated model credits her too little — so a block that shows one is
//! refused, naming the candidate quantum, the slope and its error.
//!
//! **Coordinates.** The check reads every coordinate of the controller's samples that the
//! rounding moves ([`COORDINATES`]): the heading at the doublet's end, the heading at its
//! middle sample (after the first step), and the end's lateral position along the normal of
//! the start sample's heading. For a quantum `q`, each doublet's **rounding signature** in
//! coordinate `c` is what the rounding adds to the bits' effect on it:
//! `x_c(q) = Σ_b s_b·(h_b,c(q) − h_b,c(0))`, with `h_b,c(q)` half the difference of bit `b`'s
//! two values' coordinate `c` under rounding at `q` (the doublet's other bits as reconciled)
//! and `s_b = ±1` its sign. Under the model's Euler map both headings are linear in the steps'
//! rounded commanded offsets `c_k` (`θ_end − θ₀ = T·Σ_j Σ_k M_jk·c_k,ω`, `θ_mid − θ₀ =
//! T·M_00·c_0,ω`, `M_jk = ∂mean_j/∂c_k` the model's lag), so their signatures are exact
//! arithmetic on the public commands and the bits; the lateral position
//! `Σ_j T·v̄_j·sin φ_j` (`φ_j` the model's heading before step `j` less the start's) is
//! taken to first order about the reconciled pattern's means:
//! `δlat = Σ_j T·sin φ_j·δv̄_j + Σ_i (Σ_{j>i} T²·v̄_j·cos φ_j)·δω̄_i`, `δū = M·δc`. Every
//! signature is a function of public data and the bits, whatever its accuracy.
//!
//! **The statistic.** The residual the stated model leaves, `rᵢ = y_c(samples) − ŷ(stated)`
//! per coordinate, holds `x(q_w) − x(q_s)` when the world rounds at `q_w`. Each doublet's
//! residual vector and every signature are whitened by `A = Λ^(−½)·Vᵀ` from the residuals'
//! sample covariance `Σ̂ = V·Λ·Vᵀ` (eigenvalues below `10⁻¹²·λ_max` dropped), so that the
//! regression is generalised least squares in the metric `Σ̂⁺`. For a candidate `q_c`
//! coarser than the stated `q_s`, `r` is regressed on `x(q_c)` — one slope common to the
//! coordinates — with `x(q_s)` regressed out of both (so a statement coarser than the
//! world, which leaves `−x(q_s)`, is not read as a coarser world): the slope is 1 where the
//! world rounds at `q_c`, 0 where the statement is right. Its standard error is the
//! doublets' sandwich, each doublet's score `x'ᵢᵀeᵢ` scaled by its leverage
//! (`√(Σ (x'ᵢᵀeᵢ)²/(1 − hᵢ)²) / Σ x'ᵢᵀx'ᵢ`), so a few doublets carrying the whole
//! signature cannot shrink it. Its level rests on no model of the noise: the bits are
//! independent of the noise and of every earlier doublet, and each `x_c` has mean 0 over
//! its own signs `s_b` (`h_b` does not depend on bit `b`), so the doublets' scores are
//! uncorrelated with mean 0 under a right statement whatever the noise's law, correlation
//! between coordinates or between doublets; `Σ̂` only weights them (a wrong one costs power,
//! not level).
//!
//! **Candidates.** Rounding errors at two quanta agree only while the wheel speeds `w` span
//! less than about a cycle of their difference: `w·|1/q₁ − 1/q₂| ≲ ¼`. The candidates are
//! therefore evenly spaced in `1/q`, `1/(4·w_max)` apart (`w_max` the block's largest wheel
//! command, rad/s), from the stated quantum (or [`FINEST_CANDIDATE`] when finer, or none
//! stated) up to [`MAX_COMMAND_QUANTUM`]: a world quantum between two candidates is at most
//! ⅛ of a cycle from one at the fastest wheel. The block is refused when some candidate's
//! `b̂/SE` exceeds `z(ε_est / N)` — one-sided (a coarser world gives a positive slope),
//! Bonferroni over the `N` candidates tested — at level ε_est, as the commands check and
//! the dead-time test: a refusal gives no key, so the level is the rate of false refusals,
//! not a term of the key's ε. Rounding finer than [`FINEST_CANDIDATE`] is not tested.

use super::half_away::{product_bound, round_product};
use super::normal_tail::normal_upper_quantile;
use crate::Config;
use crate::config::MAX_COMMAND_QUANTUM;
use crate::model::{DiffDrive, Unicycle, WheelSpeeds};
use crate::private::doublet::sign;
use crate::private::{DoubletModel, DoubletSamples, doublet_model};
use crate::world::quantise;
use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// The finest candidate quantum tested (rad/s per wheel): a finer rounding than stated is
/// not looked for. Below the TurtleBot3's Dynamixel XL430 (0.02398 rad/s), which the check
/// refuses unstated at the defaults (docs/estimation.md, "The quantum check").
pub const FINEST_CANDIDATE: f64 = 0.02;

/// Blocks with fewer doublets are not tested (the regression's normal approximation).
pub const MIN_CHECK_DOUBLETS: usize = 200;

/// A candidate is tested only where its signature is spread over at least this many
/// doublets' worth, `(Σ‖xᵢ‖²)² / Σ‖xᵢ‖⁴ ≥ 100` (the regression's normal approximation; at a
/// quantum that divides the bit's wheel offset `2Δv/r` the bit's two values round alike and
/// the signature vanishes but in a few doublets: nothing to regress on, and little for Eve
/// to read).
pub const MIN_SIGNED_DOUBLETS: f64 = 100.0;

/// The coordinates the check reads, in order: the end heading (rad), the middle sample's
/// heading (rad), the end's lateral position along the start heading's normal (m).
const COORDINATES: usize = 3;

/// One step's wheel commands of a doublet for one value of one bit, with their weights in the
/// doublet's rounding signature: the signature at `q` in coordinate `c` sums
/// `weights[c]·(w_q,1, w_q,2)`, the wheels rounded to `q`.
#[derive(Clone, Copy, Debug)]
struct SignatureTerm {
    /// Per coordinate (whitened), each wheel's weight: `s_b · ±½` (the bit's sign, the half
    /// difference's side) times the coordinate's derivative in the wheel's rounded speed.
    weights: [[f64; 2]; COORDINATES],
    /// The wheels' speeds `H⁻¹(u_k + o_k)` the step commands for that value of the bit (rad/s).
    wheels: WheelSpeeds,
}

/// A doublet's value in every coordinate.
type Coordinates = [f64; COORDINATES];

/// A block's doublets as the check reads them, whitened: each one's residual under the
/// stated model, with every signature term, doublet after doublet, `per_doublet` each.
struct CheckData {
    residuals: Vec<Coordinates>,
    terms: Vec<SignatureTerm>,
    per_doublet: usize,
}

/// The stated model's part of the regression: its signature `x_s = Σ_b s_b·(h_b(q_s) −
/// h_b(0))` per doublet (0 when none is stated), the unrounded signature `Σ_b s_b·h_b(0)`,
/// and the residuals with `x_s` regressed out.
struct Stated {
    signature: Vec<Coordinates>,
    squares: f64,
    leverage: Vec<f64>,
    unrounded: Vec<Coordinates>,
    residuals: Vec<Coordinates>,
}
/// The regression of the stated model's residuals on one candidate's signature.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuantumSlope {
    /// The candidate quantum `q_c` (rad/s per wheel).
    pub candidate: f64,
    /// The slope `b̂`: 1 where the world rounds at `q_c`, 0 where the statement is right.
    pub slope: f64,
    /// Its standard error.
    pub std_error: f64,
}

impl QuantumSlope {
    /// `b̂ / SE`.
    #[must_use]
    pub fn statistic(&self) -> f64 {
        self.slope / self.std_error
    }
}

/// The outcome of the check on a block: every candidate's slope and the threshold.
#[derive(Clone, Debug, PartialEq)]
pub struct QuantumCheck {
    /// The stated quantum `q_s` (rad/s per wheel; 0: none).
    pub stated: f64,
    /// Each candidate's regression, finest first.
    pub slopes: Vec<QuantumSlope>,
    /// The one-sided threshold `z(level / N)` on `b̂/SE`.
    pub limit: f64,
    /// The level it was run at.
    pub level: f64,
}

impl QuantumCheck {
    /// The candidate whose statistic is largest.
    #[must_use]
    pub fn largest(&self) -> Option<&QuantumSlope> {
        self.slopes
            .iter()
            .max_by(|a, b| a.statistic().total_cmp(&b.statistic()))
    }

    /// The reason for refusing the block, naming the candidate, the slope and its error; none
    /// when every candidate's statistic stays within the threshold.
    #[must_use]
    pub fn refusal(&self) -> Option<String> {
        let worst = self.largest()?;
        (worst.statistic() > self.limit).then(|| {
            let [finest, coarsest] =
                [self.slopes[0], self.slopes[self.slopes.len() - 1]].map(|s| s.candidate);
            format!(
                "command quantum: the headings and lateral position the stated model leaves \
                 at the doublets' middles and ends (robot.command_quantum = {}) regress on \
                 the bits' rounding signature at \
                 {:.4} rad/s per wheel with slope {:.3} (standard error {:.3}, {:.1} of them; \
                 allowed: within {:.1} at level {:.0e} over {} candidate quanta {finest:.4}–\
                 {coarsest:.4} rad/s): the wheels round their commands more coarsely than \
                 stated",
                self.stated,
                worst.candidate,
                worst.slope,
                worst.std_error,
                worst.statistic(),
                self.limit,
                self.level,
                self.slopes.len(),
            )
        })
    }
}

/// The lag's matrix `M_jk = ∂mean_j/∂c_k` of a doublet's steps under `model`: how much of
/// step `k`'s commanded offset step `j`'s mean speed carries through the model's first-order
/// lag (the identity without lag; rows and columns beyond the doublet's steps zero).
fn lag_matrix(model: &DoubletModel) -> [[f64; 3]; 3] {
    let steps = model.perturbation.steps() as usize;
    let columns: [[f64; 3]; 3] = std::array::from_fn(|k| {
        if k >= steps {
            return [0.0; 3];
        }
        let mut unit = [Unicycle::zeros(); 3];
        unit[k] = Unicycle::new(0.0, 1.0);
        let means = model
            .perturbation
            .mean_offsets(unit, model.lag, model.sample_time);
        std::array::from_fn(|j| if j < steps { means[j].y } else { 0.0 })
    });
    std::array::from_fn(|j| std::array::from_fn(|k| columns[k][j]))
}

/// A doublet's residual under the stated `model` in every coordinate: the end heading
/// `θ_c(end) − θ̂(end)`, the middle heading `θ_c(mid) − θ̂(mid)` (rad), and the end position's
/// `n·(p_c(end) − p̂(end))` along the start sample's normal `n = (−sin θ₀, cos θ₀)` (m),
/// `ŷ` the stated model's means for the reconciled pattern from the start sample; with the
/// applied mean inputs of its steps.
fn residual(model: &DoubletModel, samples: &DoubletSamples) -> (Coordinates, [Unicycle; 3]) {
    let inputs = &samples.inputs;
    let [start, middle, end] = &samples.samples;
    let offsets = model.mean_offsets(inputs, Some(samples.pattern));
    let steps = model.perturbation.steps();
    let poses = inputs.propagate_steps(start, offsets, steps, model.sample_time);
    let predicted_end = poses[steps as usize - 1];
    let normal = [-start.z.sin(), start.z.cos()];
    let lateral = normal[0] * (end.x - predicted_end.x) + normal[1] * (end.y - predicted_end.y);
    (
        [end.z - predicted_end.z, middle.z - poses[0].z, lateral],
        inputs.applied_steps(model.mean_offsets(inputs, None)),
    )
}

/// Each coordinate's derivatives in step `k`'s commanded offset `(c_k,v, c_k,ω)`, for a
/// doublet whose steps' applied mean inputs are `applied` (the module's doc): the end
/// heading's `(0, T·Σ_j M_jk)`, the middle heading's `(0, T·M_0k)`, the lateral position's
/// `(Σ_j T·sin φ_j·M_jk, Σ_i Σ_{j>i} T²·v̄_j·cos φ_j·M_ik)`, `φ_j = T·Σ_{i<j} ω̄_i`.
fn derivatives(
    lag: &[[f64; 3]; 3],
    applied: &[Unicycle; 3],
    steps: usize,
    t: f64,
) -> [[[f64; 2]; COORDINATES]; 3] {
    let mut turned = [0.0; 3];
    for j in 1..steps {
        turned[j] = turned[j - 1] + t * applied[j - 1].y;
    }
    let by_speed: [f64; 3] = std::array::from_fn(|j| t * turned[j].sin());
    let by_turn: [f64; 3] = std::array::from_fn(|i| {
        (i + 1..steps)
            .map(|j| t * t * applied[j].x * turned[j].cos())
            .sum()
    });
    std::array::from_fn(|k| {
        let through =
            |per_step: &[f64; 3]| -> f64 { (0..steps).map(|j| per_step[j] * lag[j][k]).sum() };
        [
            [0.0, t * through(&[1.0; 3])],
            [0.0, t * lag[0][k]],
            [through(&by_speed), through(&by_turn)],
        ]
    })
}

/// The whitening `A = Λ^(−½)·Vᵀ` of `residuals` (their sample covariance `V·Λ·Vᵀ`; an
/// eigenvalue below `10⁻¹²·λ_max` gives a row of zeros): `A·r` has the identity's
/// covariance on the residuals' span.
fn whitening(residuals: &[Coordinates]) -> Matrix3<f64> {
    let n = residuals.len().max(1) as f64;
    let mean = residuals
        .iter()
        .fold(Vector3::zeros(), |sum, r| sum + Vector3::from(*r))
        / n;
    let covariance = residuals.iter().fold(Matrix3::zeros(), |sum, r| {
        let d = Vector3::from(*r) - mean;
        sum + d * d.transpose()
    }) / n;
    let eigen = SymmetricEigen::new(covariance);
    let largest = eigen.eigenvalues.max();
    let mut whitening = Matrix3::zeros();
    for (i, &value) in eigen.eigenvalues.iter().enumerate() {
        if value > 1e-12 * largest && value > 0.0 {
            whitening.set_row(
                i,
                &(eigen.eigenvectors.column(i).transpose() / value.sqrt()),
            );
        }
    }
    whitening
}

/// `A·c` for a doublet's coordinates `c`.
fn whiten(a: &Matrix3<f64>, c: Coordinates) -> Coordinates {
    (a * Vector3::from(c)).into()
}

/// The check's view of a block's `sessions` under the stated `model`, whitened.
fn check_data(model: &DoubletModel, drive: DiffDrive, sessions: &[&[DoubletSamples]]) -> CheckData {
    let perturbation = &model.perturbation;
    let [radius, axle] = [drive.wheel_radius, drive.axle_length];
    let lag = lag_matrix(model);
    let steps = perturbation.steps() as usize;
    let per_doublet = perturbation.key_bits() * 2 * steps;
    let doublets: usize = sessions.iter().map(|session| session.len()).sum();
    let mut residuals = Vec::with_capacity(doublets);
    let mut terms = Vec::with_capacity(doublets * per_doublet);
    for samples in sessions.iter().flat_map(|session| session.iter()) {
        let inputs = &samples.inputs;
        let (r, applied) = residual(model, samples);
        residuals.push(r);
        let slopes = derivatives(&lag, &applied, steps, model.sample_time);
        let nominal = [inputs.first, inputs.second, inputs.second];
        for bit in 0..perturbation.key_bits() {
            let s = sign((samples.pattern >> bit & 1) as u8);
            for (value, side) in [(0, 0.5), (1, -0.5)] {
                let pattern = (samples.pattern & !(1 << bit)) | (value << bit);
                let offsets = perturbation.step_offsets(perturbation.offset(pattern));
                for k in 0..steps {
                    // v = r·(w₁ + w₂)/2, ω = r·(w₁ − w₂)/D.
                    terms.push(SignatureTerm {
                        weights: slopes[k].map(|[by_v, by_omega]| {
                            let [v, omega] = [by_v * radius / 2.0, by_omega * radius / axle];
                            [s * side * (v + omega), s * side * (v - omega)]
                        }),
                        wheels: drive.to_wheels(nominal[k] + offsets[k]),
                    });
                }
            }
        }
    }
    let a = whitening(&residuals);
    for r in &mut residuals {
        *r = whiten(&a, *r);
    }
    for term in &mut terms {
        let [left, right] = [0, 1].map(|w| whiten(&a, term.weights.map(|c| c[w])));
        term.weights = std::array::from_fn(|c| [left[c], right[c]]);
    }
    CheckData {
        residuals,
        terms,
        per_doublet,
    }
}

/// `Σᵢ Σ_c aᵢ,c·bᵢ,c`, doublet after doublet, coordinate after coordinate.
fn dot(a: &[Coordinates], b: &[Coordinates]) -> f64 {
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .map(|(x, y)| x * y)
        .sum()
}

/// `values` less their projection on `on`, in place (`on_squares = dot(on, on)`; unchanged
/// when 0).
fn regress_out(values: &mut [Coordinates], on: &[Coordinates], on_squares: f64) {
    let coefficient = if on_squares > 0.0 {
        dot(values, on) / on_squares
    } else {
        0.0
    };
    for (v, o) in values.iter_mut().flatten().zip(on.iter().flatten()) {
        *v -= coefficient * o;
    }
}

/// Consecutive candidates regressed together: each doublet's signatures at this many
/// candidates sit side by side, so that every sum over the doublets runs as this many
/// independent lanes (each lane's sum in the doublets' order, as one candidate alone).
const LANES: usize = 16;

/// The start of a sum as [`Iterator::sum`] starts one for `f64` (−0), so that a lane's sum
/// is the iterator's, bit for bit, even where it is zero.
const SUM_START: f64 = -0.0;

/// A doublet's signature in every coordinate at each lane's candidate.
type LaneCoordinates = [[f64; LANES]; COORDINATES];

impl CheckData {
    /// Each doublet's signature `Σ weights_c·(w_q,1, w_q,2)` at quantum `q` (0: unrounded)
    /// in every coordinate, the wheels rounded by the world actuator's own [`quantise`];
    /// each doublet's terms summed in order.
    fn signatures(&self, quantum: f64) -> Vec<Coordinates> {
        self.terms
            .chunks_exact(self.per_doublet.max(1))
            .map(|terms| {
                terms.iter().fold([0.0; COORDINATES], |mut acc, term| {
                    let rounded = quantise(term.wheels, quantum);
                    for (sum, [left, right]) in acc.iter_mut().zip(term.weights) {
                        *sum += left * rounded.x + right * rounded.y;
                    }
                    acc
                })
            })
            .collect()
    }

    /// The stated quantum's part of the regression.
    fn stated(&self, quantum: f64) -> Stated {
        let unrounded = self.signatures(0.0);
        let mut signature = self.signatures(quantum);
        for (q, u) in signature
            .iter_mut()
            .flatten()
            .zip(unrounded.iter().flatten())
        {
            *q -= u;
        }
        let squares = dot(&signature, &signature);
        let leverage = signature
            .iter()
            .map(|on| {
                if squares > 0.0 {
                    on.iter().map(|o| o * o).sum::<f64>() / squares
                } else {
                    0.0
                }
            })
            .collect();
        let mut residuals = self.residuals.clone();
        regress_out(&mut residuals, &signature, squares);
        Stated {
            residuals,
            signature,
            squares,
            leverage,
            unrounded,
        }
    }

    /// The regression of the residuals on the signature at each of the `quanta` (increasing),
    /// `x_c = Σ_b s_b·(h_b(q_c) − h_b(0))`, with the stated signature regressed out of both
    /// (Frisch–Waugh), the coordinates whitened: the slope `b̂ = Σ x'ᵢᵀr'ᵢ / Σ x'ᵢᵀx'ᵢ` and
    /// its standard error `√(Σ (x'ᵢᵀeᵢ)²/(1 − hᵢ)²) / Σ x'ᵢᵀx'ᵢ`, `e = r' − b̂x'`, each
    /// doublet's score scaled by its leverage `hᵢ = x_s,ᵢᵀx_s,ᵢ/Σx_sᵀx_s + x'ᵢᵀx'ᵢ/Σx'ᵀx'`
    /// (so that a few doublets carrying the whole signature cannot shrink the error). A
    /// candidate whose signature is spread over fewer than [`MIN_SIGNED_DOUBLETS`] doublets'
    /// worth, or whose error vanishes, gives none.
    ///
    /// `LANES` candidates are computed at once, each lane's arithmetic that of its
    /// candidate alone in the same order — the wheels rounded as [`quantise`] rounds them
    /// (`signature_lanes`: the same numbers, bit for bit, from products by `1/q` but near
    /// a half-integer), each sum over the doublets and their coordinates in their order —
    /// so every slope and error is the one-candidate computation's, bit for bit.
    ///
    /// On an x86-64 CPU with AVX2 (x86-64-v3, detected at run time) the same code runs in a
    /// function compiled for it (`pulp`'s `vectorize`), four lanes to a vector instead of
    /// two: the same operations on each lane (plain IEEE products, sums, comparisons and bit
    /// operations, never fused), so the same bits.
    fn slopes(&self, stated: &Stated, quanta: &[f64]) -> Vec<QuantumSlope> {
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = pulp::x86::V3::try_new() {
            return simd.vectorize(Slopes {
                data: self,
                stated,
                quanta,
            });
        }
        self.slopes_in_order(stated, quanta)
    }

    /// `slopes`, inlined where it is called.
    #[inline(always)]
    fn slopes_in_order(&self, stated: &Stated, quanta: &[f64]) -> Vec<QuantumSlope> {
        let per_doublet = self.per_doublet.max(1);
        let fastest = self.fastest_wheel();
        let mut rows: Vec<LaneCoordinates> =
            vec![[[0.0; LANES]; COORDINATES]; self.residuals.len()];
        let mut slopes = Vec::new();
        for first in (0..quanta.len()).step_by(LANES) {
            let lanes = (quanta.len() - first).min(LANES);
            let mut q = [quanta[quanta.len() - 1]; LANES];
            q[..lanes].copy_from_slice(&quanta[first..first + lanes]);
            let reciprocal = q.map(|q| 1.0 / q);
            let bound = reciprocal.map(|r| product_bound(fastest, r));
            // x = signature at q − unrounded; Σ‖x‖², Σ‖x‖⁴; Σ xᵀx_s.
            let mut squares = [SUM_START; LANES];
            let mut fourths = [SUM_START; LANES];
            let mut along = [SUM_START; LANES];
            for ((row, terms), (unrounded, on)) in rows
                .iter_mut()
                .zip(self.terms.chunks_exact(per_doublet))
                .zip(stated.unrounded.iter().zip(&stated.signature))
            {
                let sum = signature_lanes(terms, &q, &reciprocal, &bound);
                let mut norm = [SUM_START; LANES];
                for c in 0..COORDINATES {
                    for k in 0..LANES {
                        row[c][k] = sum[c][k] - unrounded[c];
                        norm[k] += row[c][k] * row[c][k];
                        along[k] += row[c][k] * on[c];
                    }
                }
                for k in 0..LANES {
                    squares[k] += norm[k];
                    fourths[k] += norm[k] * norm[k];
                }
            }
            let tested: [bool; LANES] = std::array::from_fn(|k| {
                k < lanes
                    && squares[k] > 0.0
                    && squares[k] * squares[k] >= MIN_SIGNED_DOUBLETS * fourths[k]
            });
            if !tested.contains(&true) {
                continue;
            }
            // x' = x − (Σ xᵀx_s / Σ x_sᵀx_s)·x_s; Σ x'ᵀx', Σ x'ᵀr'.
            let coefficient: [f64; LANES] = std::array::from_fn(|k| {
                if stated.squares > 0.0 {
                    along[k] / stated.squares
                } else {
                    0.0
                }
            });
            let mut sxx = [SUM_START; LANES];
            let mut sxr = [SUM_START; LANES];
            for (row, (on, r)) in rows
                .iter_mut()
                .zip(stated.signature.iter().zip(&stated.residuals))
            {
                for c in 0..COORDINATES {
                    for k in 0..LANES {
                        row[c][k] -= coefficient[k] * on[c];
                        sxx[k] += row[c][k] * row[c][k];
                        sxr[k] += row[c][k] * r[c];
                    }
                }
            }
            let slope: [f64; LANES] = std::array::from_fn(|k| sxr[k] / sxx[k]);
            let mut spread = [SUM_START; LANES];
            for (row, (r, fitted)) in rows
                .iter()
                .zip(stated.residuals.iter().zip(&stated.leverage))
            {
                let mut score = [SUM_START; LANES];
                let mut norm = [SUM_START; LANES];
                for c in 0..COORDINATES {
                    for k in 0..LANES {
                        let a = row[c][k];
                        score[k] += a * (r[c] - slope[k] * a);
                        norm[k] += a * a;
                    }
                }
                for k in 0..LANES {
                    let leverage = (fitted + norm[k] / sxx[k]).min(1.0 - 1e-9);
                    spread[k] += (score[k] / (1.0 - leverage)).powi(2);
                }
            }
            slopes.extend((0..lanes).filter_map(|k| {
                let std_error = spread[k].sqrt() / sxx[k];
                (tested[k] && std_error > 0.0 && slope[k].is_finite()).then_some(QuantumSlope {
                    candidate: q[k],
                    slope: slope[k],
                    std_error,
                })
            }));
        }
        slopes
    }

    /// The largest wheel command of the block (rad/s).
    fn fastest_wheel(&self) -> f64 {
        self.terms
            .iter()
            .map(|t| t.wheels.abs().max())
            .fold(0.0, f64::max)
    }
}

/// `CheckData::slopes`'s operands, run by `pulp` in a function compiled for x86-64-v3.
#[cfg(target_arch = "x86_64")]
struct Slopes<'a> {
    data: &'a CheckData,
    stated: &'a Stated,
    quanta: &'a [f64],
}

#[cfg(target_arch = "x86_64")]
impl pulp::NullaryFnOnce for Slopes<'_> {
    type Output = Vec<QuantumSlope>;

    #[inline(always)]
    fn call(self) -> Vec<QuantumSlope> {
        self.data.slopes_in_order(self.stated, self.quanta)
    }
}

/// One doublet's signature sums `Σ weights_c·(w_q,1, w_q,2)` over its `terms` in every
/// coordinate at each lane's quantum `q` (rad/s per wheel; `reciprocal` holds each `1/q`
/// and `bound` each `product_bound` for the block's fastest wheel), the terms in order,
/// each wheel's multiple `(w / q).round()` as [`quantise`] forms it, bit for bit: from the
/// product `w·(1/q)` where `round_product` accepts it (the bound and its argument at
/// `product_bound`), and in a lane where some wheel's is not accepted — in practice at
/// exact ties `w = (k + ½)·q` and their nearest neighbours only — the lane's sums again,
/// dividing.
#[inline(always)]
fn signature_lanes(
    terms: &[SignatureTerm],
    q: &[f64; LANES],
    reciprocal: &[f64; LANES],
    bound: &[f64; LANES],
) -> LaneCoordinates {
    let mut sum = [[0.0; LANES]; COORDINATES];
    let mut refused = [0_u64; LANES];
    for term in terms {
        let [left, right] = [term.wheels.x, term.wheels.y];
        let mut rounded = [[0.0; LANES]; 2];
        for k in 0..LANES {
            let (left_multiple, left_accepted) = round_product(left * reciprocal[k], bound[k]);
            let (right_multiple, right_accepted) = round_product(right * reciprocal[k], bound[k]);
            refused[k] |= u64::from(!(left_accepted & right_accepted));
            rounded[0][k] = left_multiple * q[k];
            rounded[1][k] = right_multiple * q[k];
        }
        for (sum, [by_left, by_right]) in sum.iter_mut().zip(term.weights) {
            for k in 0..LANES {
                sum[k] += by_left * rounded[0][k] + by_right * rounded[1][k];
            }
        }
    }
    if refused.iter().fold(0, |any, lane| any | lane) != 0 {
        for k in (0..LANES).filter(|&k| refused[k] != 0) {
            let mut lane = [0.0; COORDINATES];
            for term in terms {
                let rounded = [term.wheels.x, term.wheels.y].map(|w| (w / q[k]).round() * q[k]);
                for (sum, [by_left, by_right]) in lane.iter_mut().zip(term.weights) {
                    *sum += by_left * rounded[0] + by_right * rounded[1];
                }
            }
            for (sum, value) in sum.iter_mut().zip(lane) {
                sum[k] = value;
            }
        }
    }
    sum
}

/// The candidate quanta for a stated quantum `stated` and a block whose fastest wheel
/// command is `fastest` (rad/s): evenly spaced in `1/q`, `1/(4·fastest)` apart, every one
/// coarser than `stated` and [`FINEST_CANDIDATE`], the coarsest [`MAX_COMMAND_QUANTUM`];
/// finest first.
#[must_use]
pub fn candidates(stated: f64, fastest: f64) -> Vec<f64> {
    let finest = stated.max(FINEST_CANDIDATE);
    let step = 1.0 / (4.0 * fastest.max(1.0));
    let top = 1.0 / MAX_COMMAND_QUANTUM;
    let count = ((1.0 / finest - top) / step).floor() as usize;
    // From just coarser than `finest` to the coarsest.
    (0..=count)
        .rev()
        .map(|i| 1.0 / (top + step * i as f64))
        .filter(|&q| q > finest || (stated < FINEST_CANDIDATE && q >= finest))
        .collect()
}

/// The check of a block's `sessions` (the controller's samples of each carrying doublet
/// with the robot's bits) under the parties' `config`, its lag at `lag` (s; the measured τ̂
/// of a three-step block, else the prior), at level `level`; none for a block too small to
/// test ([`MIN_CHECK_DOUBLETS`]).
#[must_use]
pub fn quantum_check(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    lag: f64,
    level: f64,
) -> Option<QuantumCheck> {
    let model = DoubletModel {
        lag,
        ..doublet_model(config)
    };
    let data = check_data(&model, config.robot.drive(), sessions);
    if data.residuals.len() < MIN_CHECK_DOUBLETS {
        return None;
    }
    let stated_quantum = config.robot.command_quantum;
    let stated = data.stated(stated_quantum);
    let slopes = data.slopes(&stated, &candidates(stated_quantum, data.fastest_wheel()));
    if slopes.is_empty() {
        return None;
    }
    Some(QuantumCheck {
        stated: stated_quantum,
        limit: normal_upper_quantile(level / slopes.len() as f64),
        level,
        slopes,
    })
}

/// [`quantum_check`]'s refusal, if any.
#[must_use]
pub fn quantum_refusal(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    lag: f64,
    level: f64,
) -> Option<String> {
    quantum_check(config, sessions, lag, level)?.refusal()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Pose;
    use crate::private::DoubletInputs;
    use crate::private::doublet::CommandRounding;
    use crate::rng::{Purpose, stream};
    use rand::RngExt;
    use rand_distr::{Distribution, Normal};

    /// The parties at their defaults in private sensing, stating `stated`.
    fn stating(stated: f64) -> Config {
        let mut config = Config::default();
        config.sensing.mode = crate::config::SensingMode::Private;
        config.robot.command_quantum = stated;
        config
    }

    /// `n` doublets of a world whose wheels round at `world` (rad/s; 0: none): nominal speeds
    /// 0.08–0.12 m/s and turns of ±0.5 rad/s, each doublet's middle and end samples where the
    /// world's model puts them plus motion noise of 4 mm, 4 mm and 4.2 mrad per step,
    /// accumulated (the end heading's 6 mrad: what the default world's residual holds).
    fn block(config: &Config, world: f64, n: usize, seed: u64) -> Vec<DoubletSamples> {
        let mut rng = stream(seed, Purpose::Process, 0);
        let [position, heading] = [4e-3, 4.2e-3].map(|std| Normal::new(0.0, std).unwrap());
        let model = DoubletModel {
            rounding: CommandRounding::new(config.robot.drive(), world),
            ..doublet_model(config)
        };
        (0..n)
            .map(|j| {
                let mut input =
                    || Unicycle::new(rng.random_range(0.08..0.12), rng.random_range(-0.5..0.5));
                let inputs = DoubletInputs {
                    first: input(),
                    second: input(),
                };
                let pattern = usize::from(rng.random::<bool>());
                let start = Pose::new(0.0, 0.0, 0.3);
                let offsets = model.mean_offsets(&inputs, Some(pattern));
                let poses = inputs.propagate_steps(&start, offsets, 2, model.sample_time);
                let mut noise = Pose::new(0.0, 0.0, 0.0);
                let mut step = || {
                    noise += Pose::new(
                        position.sample(&mut rng),
                        position.sample(&mut rng),
                        heading.sample(&mut rng),
                    );
                    noise
                };
                let middle = poses[0] + step();
                let end = poses[1] + step();
                DoubletSamples {
                    doublet: j as u32,
                    inputs,
                    samples: [start, middle, end],
                    pattern,
                    late: None,
                }
            })
            .collect()
    }

    /// The regression at one candidate computed directly: every wheel rounded by
    /// [`quantise`] at `candidate`, the sums over the doublets one after the other (the
    /// reference the lane-wise `CheckData::slopes` must equal).
    fn direct_slope(data: &CheckData, stated: &Stated, candidate: f64) -> Option<QuantumSlope> {
        let mut x = data.signatures(candidate);
        for (c, u) in x
            .iter_mut()
            .flatten()
            .zip(stated.unrounded.iter().flatten())
        {
            *c -= u;
        }
        let norms: Vec<f64> = x.iter().map(|v| v.iter().map(|c| c * c).sum()).collect();
        let squares: f64 = norms.iter().sum();
        let fourths: f64 = norms.iter().map(|n| n * n).sum();
        if squares <= 0.0 || squares * squares < MIN_SIGNED_DOUBLETS * fourths {
            return None;
        }
        regress_out(&mut x, &stated.signature, stated.squares);
        let sxx = dot(&x, &x);
        let slope = dot(&x, &stated.residuals) / sxx;
        let spread: f64 = x
            .iter()
            .zip(&stated.residuals)
            .zip(&stated.leverage)
            .map(|((a, r), fitted)| {
                let score: f64 = a.iter().zip(r).map(|(a, r)| a * (r - slope * a)).sum();
                let norm: f64 = a.iter().map(|a| a * a).sum();
                let leverage = (fitted + norm / sxx).min(1.0 - 1e-9);
                (score / (1.0 - leverage)).powi(2)
            })
            .sum();
        let std_error = spread.sqrt() / sxx;
        (std_error > 0.0 && slope.is_finite()).then_some(QuantumSlope {
            candidate,
            slope,
            std_error,
        })
    }

    /// `data`'s slopes at every candidate for `fastest`, lane-wise and directly, stating
    /// `stated`: the same list, every number bit for bit.
    fn assert_slopes_exact(data: &CheckData, stated: f64, fastest: f64) {
        let quanta = candidates(stated, fastest);
        let part = data.stated(stated);
        let swept = data.slopes(&part, &quanta);
        let direct: Vec<QuantumSlope> = quanta
            .iter()
            .filter_map(|&q| direct_slope(data, &part, q))
            .collect();
        assert!(!direct.is_empty(), "stated {stated}: some candidate tested");
        let bits = |list: &[QuantumSlope]| -> Vec<[u64; 3]> {
            list.iter()
                .map(|s| [s.candidate, s.slope, s.std_error].map(f64::to_bits))
                .collect()
        };
        assert_eq!(bits(&swept), bits(&direct), "stated {stated}");
        // The code `slopes` dispatches to (x86-64-v3 where the CPU has it), compiled here
        // for the build's baseline: the same bits.
        let baseline = data.slopes_in_order(&part, &quanta);
        assert_eq!(bits(&swept), bits(&baseline), "stated {stated}");
    }

    /// Seeded random blocks of signature terms — wheels of either sign up to the fastest,
    /// zero wheels of both signs, wheels at exact half-integers of a candidate (where
    /// rounding goes away from zero) and a few units in the last place either side of one
    /// (where the product by `1/q` and the quotient can round apart), terms whose wheels
    /// round alike — with random residuals: the lane-wise regression equals the direct one
    /// at every candidate, bit for bit, stating none and stating a quantum.
    #[test]
    fn the_swept_slopes_equal_the_direct_ones_on_random_blocks() {
        let fastest = 7.0;
        let quanta = candidates(0.0, fastest);
        for seed in 0..6 {
            let mut rng = stream(40 + seed, Purpose::Process, 0);
            let per_doublet = if seed % 2 == 0 { 8 } else { 16 };
            let doublets = 300;
            let wheel = |rng: &mut rand::rngs::ChaCha8Rng| -> f64 {
                match rng.random_range(0..10) {
                    0 => 0.0,
                    1 => -0.0,
                    2 | 3 => {
                        let q = quanta[rng.random_range(0..quanta.len())];
                        let half = rng.random_range(-20..20) as f64 + 0.5;
                        let w = half * q;
                        if w / q == half && w.abs() <= fastest {
                            w
                        } else {
                            0.5 * q
                        }
                    }
                    // A few ulps below (4) or above (5) a half-integer's multiple.
                    side @ (4 | 5) => {
                        let q = quanta[rng.random_range(0..quanta.len())];
                        let half = rng.random_range(-20..20) as f64 + 0.5;
                        let mut w = half * q;
                        for _ in 0..rng.random_range(1..8) {
                            w = if (half > 0.0) == (side == 4) {
                                w.next_down()
                            } else {
                                w.next_up()
                            };
                        }
                        w.clamp(-fastest, fastest)
                    }
                    _ => rng.random_range(-fastest..fastest),
                }
            };
            let terms = (0..doublets * per_doublet)
                .map(|_| {
                    let left = wheel(&mut rng);
                    let right = if rng.random_range(0..8) == 0 {
                        left
                    } else {
                        wheel(&mut rng)
                    };
                    SignatureTerm {
                        weights: std::array::from_fn(|_| {
                            std::array::from_fn(|_| rng.random_range(-0.01..0.01))
                        }),
                        wheels: WheelSpeeds::new(left, right),
                    }
                })
                .collect();
            let residuals = (0..doublets)
                .map(|_| std::array::from_fn(|_| rng.random_range(-0.01..0.01)))
                .collect();
            let data = CheckData {
                residuals,
                terms,
                per_doublet,
            };
            for stated in [0.0, 0.0323, 0.2] {
                assert_slopes_exact(&data, stated, fastest);
            }
        }
    }

    /// A simulated block (a world rounding at 0.1 rad/s, the parties stating none or a finer
    /// quantum, one lag): the slopes the check reports are the direct ones, bit for bit.
    #[test]
    fn the_checked_slopes_equal_the_direct_ones_on_a_simulated_block() {
        for stated in [0.0, 0.0323] {
            let config = stating(stated);
            let doublets = block(&config, 0.1, 2_000, 3);
            let model = DoubletModel {
                lag: 0.05,
                ..doublet_model(&config)
            };
            let data = check_data(&model, config.robot.drive(), &[&doublets]);
            assert_slopes_exact(&data, stated, data.fastest_wheel());
            let check = quantum_check(&config, &[&doublets], 0.05, 1e-6).expect("tested");
            let part = data.stated(stated);
            let direct: Vec<QuantumSlope> = candidates(stated, data.fastest_wheel())
                .into_iter()
                .filter_map(|q| direct_slope(&data, &part, q))
                .collect();
            assert_eq!(check.slopes, direct, "stated {stated}");
        }
    }

    /// A world rounding at 0.1 rad/s where the parties state none, or 0.0323, is refused at
    /// ε_est = 10⁻⁶ on 10⁴ doublets, naming a candidate near 0.1 with a slope near 1; stated
    /// right it passes.
    #[test]
    fn an_understated_quantum_is_refused_and_a_right_one_passes() {
        for stated in [0.0, 0.0323] {
            let config = stating(stated);
            let doublets = block(&config, 0.1, 10_000, 1);
            let check = quantum_check(&config, &[&doublets], 0.0, 1e-6).expect("tested");
            let worst = check.largest().unwrap();
            assert!(
                (worst.candidate - 0.1).abs() < 0.003,
                "stated {stated}: {worst:?}"
            );
            assert!(
                (worst.slope - 1.0).abs() < 0.2,
                "stated {stated}: {worst:?}"
            );
            let why = check.refusal().expect("refused");
            assert!(why.contains("command quantum"), "{why}");
            assert!(
                why.contains(&format!("robot.command_quantum = {stated}")),
                "{why}"
            );
        }
        let config = stating(0.1);
        let doublets = block(&config, 0.1, 10_000, 1);
        assert_eq!(quantum_refusal(&config, &[&doublets], 0.0, 1e-6), None);
    }

    /// Power at a fine quantum: a world rounding at 0.025 rad/s (finer than the Khepera IV's
    /// 0.0323) that the parties do not state is refused at ε_est = 10⁻⁶ on 10⁴ doublets in
    /// each of three seeded blocks, naming a candidate within 0.5 % of it. The three
    /// coordinates' standard error there is ≈ 0.088 against ≈ 0.125 from the end heading
    /// alone, so the expected statistic is ≈ 0.9/0.088 ≈ 10 (the slope attenuated by the
    /// candidate's eighth of a cycle at most) against a threshold of 6.4 over ≈ 1,680
    /// candidates; the end heading alone would expect ≈ 7.
    #[test]
    fn an_unstated_fine_quantum_is_refused() {
        let config = stating(0.0);
        for seed in 0..3 {
            let doublets = block(&config, 0.025, 10_000, 7 + seed);
            let check = quantum_check(&config, &[&doublets], 0.0, 1e-6).expect("tested");
            let worst = check.largest().unwrap();
            assert!(
                (worst.candidate / 0.025 - 1.0).abs() < 0.005,
                "seed {seed}: {worst:?}"
            );
            let why = check.refusal().expect("refused");
            assert!(why.contains("0.0250 rad/s per wheel"), "{why}");
        }
    }

    /// False refusals at a right statement: over 200 seeded blocks of 1,000 doublets at
    /// level 0.05, a world rounding as stated (0 and 0.0323) is refused at most 5 % of the
    /// time plus 3 binomial deviations (√(200·0.05·0.95) ≈ 3.1: at most 19 refusals).
    #[test]
    fn a_right_statement_is_refused_no_more_often_than_the_level() {
        for stated in [0.0, 0.0323] {
            let config = stating(stated);
            let refused = (0..200)
                .filter(|&seed| {
                    let doublets = block(&config, stated, 1_000, 100 + seed);
                    quantum_refusal(&config, &[&doublets], 0.0, 0.05).is_some()
                })
                .count();
            eprintln!("stated {stated}: {refused} of 200 refused at level 0.05");
            assert!(refused <= 19, "stated {stated}: {refused} of 200 refused");
        }
    }

    /// The candidates are evenly spaced in 1/q, a quarter cycle of the fastest wheel apart,
    /// each coarser than the statement, up to the class's largest quantum.
    #[test]
    fn the_candidates_cover_the_class_above_the_statement() {
        let list = candidates(0.0323, 7.0);
        assert!(list[0] > 0.0323 && list[0] < 0.0323 * 1.01, "{list:?}");
        assert_eq!(*list.last().unwrap(), MAX_COMMAND_QUANTUM);
        for pair in list.windows(2) {
            let gap = 1.0 / pair[0] - 1.0 / pair[1];
            assert!((gap - 1.0 / 28.0).abs() < 1e-9, "{pair:?}");
        }
        let unstated = candidates(0.0, 7.0);
        assert!(
            unstated.iter().all(|&q| q >= FINEST_CANDIDATE),
            "{unstated:?}"
        );
        assert!(
            (unstated[0] - FINEST_CANDIDATE).abs() < 1e-3 && unstated[0] < 0.02398,
            "{unstated:?}"
        );
        assert!(candidates(MAX_COMMAND_QUANTUM, 7.0).is_empty());
    }
}
