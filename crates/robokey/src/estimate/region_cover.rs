//! A cover of the slip region by cells of its minimal members, each cell with a matrix below
//! every member it holds (docs/estimation.md, "Per-wheel slip", *A cover of the region*).
//!
//! The region at one point of σ² is `{Q ⪰ 0, Q ⪰ Q_c, Q ⪯ U}` (robot frame; m², m², rad²),
//! `Q_c` the corner with two positive eigenvalues `A₊` (eigenvectors `V`) and one negative,
//! `−c` on `n`. In the frame `T = [V·A₊^½, n·√c]` (`Q = T·Q̃·Tᵀ`) the corner is
//! `D = diag(1, 1, −1)` and the region's **minimal members** are
//!
//! `M(v) = D + x·xᵀ`,  `x = (v, s)`,  `s = √(1 + |v|²)`,  `|v|² ≤ μ`,
//!
//! `v ∈ ℝ²` and μ the upper bound's excess (`worst_case::below_the_region`): every member
//! lies above one of them. Proof: the members below a member `Q` form a compact set; one of
//! least trace, `M`, is minimal. `M` is singular (else `M − ε(M − D)` is a member below it:
//! `M ≠ D`, as `D` is not above 0); `M − D` has rank one (else its range and `M`'s, each of
//! dimension at least 2 in ℝ³, share a direction `d` and `M − ε·ddᵀ` is a member below it);
//! so `M = D + xxᵀ` with `det M = −(1 + xᵀD⁻¹x) = 0`, i.e. `s² = 1 + |v|²`; and `M ⪯ Q ⪯ U`
//! gives `I + vvᵀ ⪯ (1 + μ)I` on the positive block, `|v|² ≤ μ`.
//!
//! A **cell** is a box of `v`; its members are the region's members above an `M(v)` with `v`
//! in the box, so the boxes of a cover of the disc `|v|² ≤ μ` hold every member. Below each
//! of the cell's minimal members lies `L = T·(M(v_c) − κ·I)·Tᵀ`, `v_c` the box's centre:
//! `κ ≥ max_v −λ_min(M(v) − M(v_c))` over the box, certified on a grid of `G × G` points
//! `v_i`, each the centre of a sub-box of half-diagonal `h`, by
//! `λ_min(M(v) − M(v_c)) ≥ λ_min(M(v_i) − M(v_c)) − ‖M(v) − M(v_i)‖₂` and
//! `‖xxᵀ − x_i·x_iᵀ‖₂ ≤ |x − x_i|·(|x| + |x_i|) ≤ √2·h·2√(1 + 2R²)` (`|∇s| < 1`, so
//! `|x − x_i| ≤ √2·|v − v_i|`; `|x|² = 1 + 2|v|²`, R the box's largest `|v|`). So `L` lies
//! below every member of its cell, and Eve's view at `L` is at least as sharp as at each of
//! them. Unlike a share of the corner (`below_the_region`, below the whole region), `L` stays
//! close to the cell's members: in a small cell around `v = 0` it is nearly the corner's
//! positive part, whose heading entry is 0 rather than below it.

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// Points per side of the grid that certifies a cell's κ (`G` of the module's doc).
const CERTIFYING_GRID: usize = 16;

/// A box `[low, high]` of the minimal members' parameter `v` (dimensionless, the corner's
/// frame of the module's doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    /// The box's lower corner `(v₁, v₂)`.
    pub low: [f64; 2],
    /// The box's upper corner.
    pub high: [f64; 2],
}

impl Cell {
    fn centre(&self) -> [f64; 2] {
        [0, 1].map(|k| 0.5 * (self.low[k] + self.high[k]))
    }

    /// The box's point `(v₁, v₂)` at fractions `(f₁, f₂)` of its sides.
    fn at(&self, f: [f64; 2]) -> [f64; 2] {
        [0, 1].map(|k| self.low[k] + f[k] * (self.high[k] - self.low[k]))
    }

    /// Largest `|v|` over the box.
    fn farthest(&self) -> f64 {
        let far = |k: usize| self.low[k].abs().max(self.high[k].abs());
        far(0).hypot(far(1))
    }

    /// Least `|v|` over the box.
    fn nearest(&self) -> f64 {
        let near = |k: usize| {
            if self.low[k] <= 0.0 && self.high[k] >= 0.0 {
                0.0
            } else {
                self.low[k].abs().min(self.high[k].abs())
            }
        };
        near(0).hypot(near(1))
    }
}

/// The minimal members of one point's region `{Q ⪰ 0, Q ⪰ Q_c, Q ⪯ U}` (the module's doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MinimalMembers {
    /// `T`: the corner's frame (columns `V·A₊^½` and `n·√c`).
    frame: Matrix3<f64>,
    /// The bound on `|v|²` over the minimal members (μ or `Ũ_hh`).
    excess: f64,
}

impl MinimalMembers {
    /// The minimal members of the region of `corner` `Q_c` and `upper` `U` (robot frame; m²,
    /// m², rad²): `|v|² ≤ μ` and, `M(v)`'s heading entry being `|v|²`, `|v|² ≤ Ũ_hh` (`U` in
    /// the corner's frame), the least of the two kept. None unless `Q_c` has two positive
    /// eigenvalues and one negative and `U` leaves minimal members.
    #[must_use]
    pub fn new(corner: &Matrix3<f64>, upper: &Matrix3<f64>) -> Option<Self> {
        let eigen = SymmetricEigen::new(*corner);
        let negative: Vec<usize> = (0..3).filter(|&k| eigen.eigenvalues[k] < 0.0).collect();
        let positive: Vec<usize> = (0..3).filter(|&k| eigen.eigenvalues[k] > 0.0).collect();
        if negative.len() != 1 || positive.len() != 2 {
            return None;
        }
        let scaled = |k: usize| eigen.eigenvectors.column(k) * eigen.eigenvalues[k].abs().sqrt();
        let frame = Matrix3::from_columns(&[
            scaled(positive[0]),
            scaled(positive[1]),
            scaled(negative[0]),
        ]);
        let inverse = frame.try_inverse()?;
        let relative = inverse * upper * inverse.transpose();
        let block = relative.fixed_view::<2, 2>(0, 0).into_owned();
        let excess = (SymmetricEigen::new(block).eigenvalues.max() - 1.0).min(relative[(2, 2)]);
        (excess.is_finite() && excess >= 0.0).then_some(Self { frame, excess })
    }

    /// The box `[−√μ, √μ]²` around the disc of minimal members.
    #[must_use]
    pub fn whole(&self) -> Cell {
        let r = self.excess.sqrt();
        Cell {
            low: [-r, -r],
            high: [r, r],
        }
    }

    /// `cell` cut into `3 × 3` boxes, those without a minimal member (wholly outside the disc
    /// `|v|² ≤ μ`) left out.
    #[must_use]
    pub fn split(&self, cell: &Cell) -> Vec<Cell> {
        let third =
            |k: usize, i: usize| cell.low[k] + i as f64 / 3.0 * (cell.high[k] - cell.low[k]);
        (0..9)
            .map(|j| {
                let (a, b) = (j % 3, j / 3);
                Cell {
                    low: [third(0, a), third(1, b)],
                    high: [third(0, a + 1), third(1, b + 1)],
                }
            })
            .filter(|c| c.nearest() * c.nearest() <= self.excess)
            .collect()
    }

    /// `L = T·(M(v_c) − κ·I)·Tᵀ` (robot frame; m², m², rad²): below every member of the
    /// region whose minimal member below it has `v` in `cell` (the module's doc).
    #[must_use]
    pub fn below(&self, cell: &Cell) -> Matrix3<f64> {
        let centre = minimal(cell.centre());
        let g = CERTIFYING_GRID as f64;
        let half = [0, 1].map(|k| (cell.high[k] - cell.low[k]) / (2.0 * g));
        let lipschitz = 2.0
            * std::f64::consts::SQRT_2
            * half[0].hypot(half[1])
            * (1.0 + 2.0 * cell.farthest().powi(2)).sqrt();
        let deficit = (0..CERTIFYING_GRID * CERTIFYING_GRID)
            .map(|i| {
                let f = [i % CERTIFYING_GRID, i / CERTIFYING_GRID]
                    .map(|j| (2 * j + 1) as f64 / (2.0 * g));
                -SymmetricEigen::new(minimal(cell.at(f)) - centre)
                    .eigenvalues
                    .min()
            })
            .fold(0.0_f64, f64::max);
        // The eigenvalues of 3 × 3 matrices of order 1, each within ~10⁻¹⁵: a margin of 10⁻¹².
        let kappa = deficit + lipschitz + 1e-12;
        self.frame * (centre - kappa * Matrix3::identity()) * self.frame.transpose()
    }

    /// `T·M(v)·Tᵀ` (robot frame): the minimal member at `v`.
    #[cfg(test)]
    pub(crate) fn member(&self, v: [f64; 2]) -> Matrix3<f64> {
        self.frame * minimal(v) * self.frame.transpose()
    }
}

/// `M(v) = D + xxᵀ` in the corner's frame (the module's doc).
fn minimal(v: [f64; 2]) -> Matrix3<f64> {
    let s = (1.0 + v[0] * v[0] + v[1] * v[1]).sqrt();
    let x = Vector3::new(v[0], v[1], s);
    Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0)) + x * x.transpose()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::motion_noise::Corner;
    use crate::estimate::motion_noise::tests::weights_of;
    use crate::estimate::worst_case::tests::{
        assert_blunter, exponents, member, turning_two_bit_doublet,
    };
    use crate::estimate::worst_case::{below_the_region, slip_pairs};
    use crate::rng::{Purpose, stream};
    use nalgebra::Rotation3;
    use rand::RngExt;

    fn least(m: Matrix3<f64>) -> f64 {
        SymmetricEigen::new(m).eigenvalues.min()
    }

    /// The whole box cut into nine, its centre cell into nine, and that one's centre into
    /// nine: 27 cells, three of them around `v = 0`.
    fn three_levels(members: &MinimalMembers) -> Vec<Cell> {
        let mut cells = Vec::new();
        let mut centre = members.whole();
        for _ in 0..3 {
            let split = members.split(&centre);
            centre = split[4];
            cells.extend(split);
        }
        cells
    }

    #[test]
    fn every_cells_matrix_lies_below_the_members_it_holds() {
        // The grid's 5 %, 4 mm corner at σ²'s upper end (m², m², rad²) in a seeded frame, an
        // upper bound 1.31 times its positive part and 2.3 c along the heading.
        let (a, b, c) = (13.7e-6, 14.3e-6, 9.6e-6);
        let mut rng = stream(61, Purpose::Public, 0);
        let axis = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0));
        let frame = *Rotation3::from_scaled_axis(axis).matrix();
        let turn = |m: Vector3<f64>| frame * Matrix3::from_diagonal(&m) * frame.transpose();
        let corner = turn(Vector3::new(a, b, -c));
        let upper = turn(Vector3::new(1.31 * a, 1.31 * b, 2.3 * c));
        let members = MinimalMembers::new(&corner, &upper).unwrap();
        assert!((members.excess - 0.31).abs() < 1e-9, "{}", members.excess);
        let cells = three_levels(&members);
        // The cover holds every minimal member: each v of the disc lies in a cell of the
        // first cut (the cells left out lie wholly outside it).
        let first = members.split(&members.whole());
        for _ in 0..2000 {
            let v = [0, 1].map(|_| rng.random_range(-0.56..0.56));
            if v[0] * v[0] + v[1] * v[1] <= members.excess {
                assert!(
                    first
                        .iter()
                        .any(|cell| (0..2).all(|k| cell.low[k] <= v[k] && v[k] <= cell.high[k])),
                    "{v:?} in no cell"
                );
            }
        }
        // Each cell's matrix lies below its members: its minimal members and members above
        // them, drawn in the box.
        let tolerance = 1e-12 * c;
        let mut closest = f64::INFINITY;
        for cell in &cells {
            let below = members.below(cell);
            for _ in 0..300 {
                let v = [0, 1].map(|k| rng.random_range(cell.low[k]..=cell.high[k]));
                let g = Matrix3::from_fn(|_, _| rng.random_range(-0.2..0.2)) * a.sqrt();
                let minimal = members.member(v);
                assert!(least(minimal - corner) >= -tolerance && least(minimal) >= -tolerance);
                for m in [minimal, minimal + g * g.transpose()] {
                    let gap = least(m - below);
                    assert!(gap >= -tolerance, "{cell:?} {v:?}: {gap:e}");
                }
                closest = closest.min(least(minimal - below));
            }
        }
        // Not vacuous: some member comes within 2 % of c of its cell's matrix.
        assert!(closest < 0.02 * c, "{closest:e}");
        // Near v = 0 the matrix is near the corner's positive part: along n at least −0.1 c
        // (the raised shares take −λc, λ in ¼ … 1, wherever they keep more than half of A₊),
        // and at least 0.9 of A₊ on the positive eigenvectors.
        let inner = members.below(&cells[22]);
        let n = frame * Vector3::z();
        assert!(cells[22].nearest() == 0.0 && cells[22].farthest() < 0.05);
        assert!((n.transpose() * inner * n)[0] > -0.1 * c, "{inner:?}");
        for (k, x) in [(0, a), (1, b)] {
            let e = frame.column(k).into_owned();
            assert!((e.transpose() * inner * e)[0] > 0.9 * x, "{inner:?}");
        }
    }

    #[test]
    fn the_cells_bound_what_their_members_show_her() {
        let (config, model, inputs, view) = turning_two_bit_doublet();
        let (slip, axle) = (2.85e-3, config.robot.axle_length);
        let (a, b, c) = (12e-6, 12.5e-6, 26e-6);
        let corner_motion = Matrix3::from_diagonal(&Vector3::new(a, b, -c));
        let upper = Matrix3::from_diagonal(&Vector3::new(1.3 * a, 1.3 * b, 5.0 * c));
        let members = MinimalMembers::new(&corner_motion, &upper).unwrap();
        let sum = |bits: &[robokey_secrecy::covariance_pair::PairedBit]| {
            exponents(bits, 0.5).iter().sum::<f64>()
        };
        let mut rng = stream(67, Purpose::Public, 0);
        let cells = three_levels(&members);
        for cell_rho in [[0.0, 0.0], [0.3, 0.5]] {
            let corner = Corner {
                correlation: cell_rho,
                motion: corner_motion,
                step_weights: weights_of(cell_rho),
            };
            let pairs_at = |motion: Matrix3<f64>| {
                slip_pairs(
                    &model,
                    &Corner { motion, ..corner },
                    slip,
                    axle,
                    &inputs,
                    &view,
                )
            };
            // The cell around v = 0 tells her less than every raised share does.
            let shares = below_the_region(&corner_motion, Some(&upper))
                .into_iter()
                .filter_map(pairs_at)
                .map(|bits| sum(&bits))
                .fold(f64::MIN, f64::max);
            let inner = sum(&pairs_at(members.below(&cells[22])).unwrap());
            assert!(inner > shares, "{inner} ≤ {shares}");
            for cell in cells.iter().step_by(2) {
                let bound = pairs_at(members.below(cell)).unwrap();
                for _ in 0..4 {
                    let v = [0, 1].map(|k| rng.random_range(cell.low[k]..=cell.high[k]));
                    let g = Matrix3::from_fn(|_, _| rng.random_range(-0.2..0.2)) * a.sqrt();
                    let motion = members.member(v) + g * g.transpose();
                    let rho = rng.random_range(cell_rho[0]..=cell_rho[1]);
                    let seen = slip_pairs(&model, &member(motion, rho), slip, axle, &inputs, &view)
                        .unwrap();
                    for lambda in [0.25, 0.5, 1.0] {
                        let truth = exponents(&seen, lambda);
                        assert_blunter(&bound, &truth, lambda, &format!("{cell:?} {v:?}"));
                    }
                }
            }
        }
    }
}
