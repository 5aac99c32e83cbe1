//! Binary entropy, binary convolution, and plug-in information measures from the joint
//! per-step table of (b, b̂c, b̂a) with seeded bootstrap intervals (docs/secrecy.md).

use rand::Rng;
use rand_distr::{Binomial, Distribution};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::interval::Interval;

/// Binary entropy h(p) = −p log₂ p − (1 − p) log₂(1 − p) in bits, with h(0) = h(1) = 0.
/// NaN for p outside [0, 1].
#[must_use]
pub fn binary_entropy(p: f64) -> f64 {
    if !(0.0..=1.0).contains(&p) {
        return f64::NAN;
    }
    let term = |x: f64| if x > 0.0 { -x * x.log2() } else { 0.0 };
    term(p) + term(1.0 - p)
}

/// Binary convolution a ⋆ b = a(1 − b) + b(1 − a): the error rate of two independent
/// binary symmetric channels in series.
#[must_use]
pub fn binary_convolution(a: f64, b: f64) -> f64 {
    a * (1.0 - b) + b * (1.0 - a)
}

/// Errors of the plug-in estimates and the bootstrap.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EntropyError {
    /// The count table is empty.
    #[error("the joint count table is empty")]
    NoSteps,
    /// The bootstrap was asked for zero resamples.
    #[error("the bootstrap needs at least one resample")]
    NoResamples,
    /// A confidence level outside the open interval (0, 1).
    #[error("confidence {0} must lie strictly between 0 and 1")]
    InvalidConfidence(f64),
}

/// Joint counts of per-step bits: `n[b][b̂c][b̂a]` counts the steps whose robot bit is b,
/// controller decision b̂c and Eve's decision b̂a (index 0 = bit 0, 1 = bit 1).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct JointCounts {
    /// Counts indexed (b, b̂c, b̂a).
    pub n: [[[u64; 2]; 2]; 2],
}

/// I(X;Y) = Σ p(x,y) log₂(p(x,y)/(p(x)p(y))) from a 2×2 count table; the table is non-empty.
fn plug_in_information(t: [[u64; 2]; 2]) -> f64 {
    let total: u64 = t.iter().flatten().sum();
    let total = total as f64;
    let row = [t[0][0] + t[0][1], t[1][0] + t[1][1]];
    let col = [t[0][0] + t[1][0], t[0][1] + t[1][1]];
    let mut info = 0.0;
    for x in 0..2 {
        for y in 0..2 {
            let nxy = t[x][y];
            if nxy > 0 {
                let nxy = nxy as f64;
                info += nxy / total * (nxy * total / (row[x] as f64 * col[y] as f64)).log2();
            }
        }
    }
    info.max(0.0)
}

impl JointCounts {
    /// Counts one step with robot bit `b`, controller decision `b_c` and Eve decision `b_a`.
    pub fn record(&mut self, b: bool, b_c: bool, b_a: bool) {
        let cell = &mut self.n[usize::from(b)][usize::from(b_c)][usize::from(b_a)];
        *cell = cell.saturating_add(1);
    }

    /// Number of steps N = Σ n.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.n.iter().flatten().flatten().sum()
    }

    fn nonempty(&self) -> Result<f64, EntropyError> {
        match self.total() {
            0 => Err(EntropyError::NoSteps),
            t => Ok(t as f64),
        }
    }

    /// Marginal table of (b, b̂c).
    fn controller_table(&self) -> [[u64; 2]; 2] {
        let n = &self.n;
        [
            [n[0][0][0] + n[0][0][1], n[0][1][0] + n[0][1][1]],
            [n[1][0][0] + n[1][0][1], n[1][1][0] + n[1][1][1]],
        ]
    }

    /// Marginal table of (b, b̂a).
    fn eve_table(&self) -> [[u64; 2]; 2] {
        let n = &self.n;
        [
            [n[0][0][0] + n[0][1][0], n[0][0][1] + n[0][1][1]],
            [n[1][0][0] + n[1][1][0], n[1][0][1] + n[1][1][1]],
        ]
    }

    /// Controller error rate p_c = P̂(b̂c ≠ b).
    pub fn controller_error_rate(&self) -> Result<f64, EntropyError> {
        let total = self.nonempty()?;
        let t = self.controller_table();
        Ok((t[0][1] + t[1][0]) as f64 / total)
    }

    /// Eve's error rate p_e = P̂(b̂a ≠ b).
    pub fn eve_error_rate(&self) -> Result<f64, EntropyError> {
        let total = self.nonempty()?;
        let t = self.eve_table();
        Ok((t[0][1] + t[1][0]) as f64 / total)
    }

    /// Plug-in I(B; B̂c) in bits per step.
    pub fn information_controller(&self) -> Result<f64, EntropyError> {
        self.nonempty()?;
        Ok(plug_in_information(self.controller_table()))
    }

    /// Plug-in I(B; B̂a) in bits per step.
    pub fn information_eve(&self) -> Result<f64, EntropyError> {
        self.nonempty()?;
        Ok(plug_in_information(self.eve_table()))
    }

    /// Plug-in I(B; B̂c) − I(B; B̂a): the one-way secret-key rate per step when positive
    /// (Csiszár–Körner with the empirical joint law).
    pub fn information_advantage(&self) -> Result<f64, EntropyError> {
        Ok(self.information_controller()? - self.information_eve()?)
    }

    /// Plug-in I(B; B̂c | B̂a) = Σ_a p(a) I(B; B̂c | B̂a = a) in bits per step: an upper bound on
    /// the secret-key rate (the intrinsic-information bound with Eve's decision as her view).
    pub fn information_controller_given_eve(&self) -> Result<f64, EntropyError> {
        let total = self.nonempty()?;
        let mut info = 0.0;
        for a in 0..2 {
            let slice = [
                [self.n[0][0][a], self.n[0][1][a]],
                [self.n[1][0][a], self.n[1][1][a]],
            ];
            let na: u64 = slice.iter().flatten().sum();
            if na > 0 {
                info += na as f64 / total * plug_in_information(slice);
            }
        }
        Ok(info)
    }
}

/// Point estimates and bootstrap percentile intervals of the two key-rate figures.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BootstrapIntervals {
    /// Plug-in I(B; B̂c) − I(B; B̂a).
    pub advantage: f64,
    /// Percentile interval of I(B; B̂c) − I(B; B̂a).
    pub advantage_interval: Interval,
    /// Plug-in I(B; B̂c | B̂a).
    pub conditional: f64,
    /// Percentile interval of I(B; B̂c | B̂a).
    pub conditional_interval: Interval,
    /// Number of bootstrap resamples.
    pub resamples: usize,
    /// Two-sided confidence level of the intervals.
    pub confidence: f64,
}

/// Seeded multinomial bootstrap: `resamples` tables of N steps drawn from the empirical joint
/// law (by conditional binomials over the 8 cells), giving percentile intervals (linear
/// interpolation between order statistics) at two-sided `confidence` for
/// I(B;B̂c) − I(B;B̂a) and I(B;B̂c|B̂a). Deterministic for a seeded `rng`.
pub fn bootstrap<R: Rng + ?Sized>(
    counts: &JointCounts,
    resamples: usize,
    confidence: f64,
    rng: &mut R,
) -> Result<BootstrapIntervals, EntropyError> {
    let total = counts.total();
    if total == 0 {
        return Err(EntropyError::NoSteps);
    }
    if resamples == 0 {
        return Err(EntropyError::NoResamples);
    }
    if !(confidence > 0.0 && confidence < 1.0) {
        return Err(EntropyError::InvalidConfidence(confidence));
    }
    let cells: Vec<u64> = counts.n.iter().flatten().flatten().copied().collect();
    let mut advantages = Vec::with_capacity(resamples);
    let mut conditionals = Vec::with_capacity(resamples);
    for _ in 0..resamples {
        let resampled = resample_multinomial(&cells, total, rng);
        let mut table = JointCounts::default();
        for (i, &c) in resampled.iter().enumerate() {
            table.n[i >> 2][(i >> 1) & 1][i & 1] = c;
        }
        advantages.push(table.information_advantage()?);
        conditionals.push(table.information_controller_given_eve()?);
    }
    let alpha = 1.0 - confidence;
    Ok(BootstrapIntervals {
        advantage: counts.information_advantage()?,
        advantage_interval: percentile_interval(&mut advantages, alpha),
        conditional: counts.information_controller_given_eve()?,
        conditional_interval: percentile_interval(&mut conditionals, alpha),
        resamples,
        confidence,
    })
}

/// One multinomial draw of `total` items over cells with probabilities cells/total:
/// x_i ~ Bin(remaining items, c_i / remaining count).
fn resample_multinomial<R: Rng + ?Sized>(cells: &[u64], total: u64, rng: &mut R) -> Vec<u64> {
    let mut remaining_items = total;
    let mut remaining_count = total;
    let mut out = Vec::with_capacity(cells.len());
    for &c in cells {
        let x = if remaining_items == 0 || c == 0 {
            0
        } else if c >= remaining_count {
            remaining_items
        } else {
            let p = c as f64 / remaining_count as f64;
            // p ∈ (0, 1) here, so the constructor cannot fail; fall back to the mean if it did.
            Binomial::new(remaining_items, p)
                .map(|d| d.sample(rng))
                .unwrap_or((remaining_items as f64 * p).round() as u64)
        };
        out.push(x);
        remaining_items -= x;
        remaining_count -= c;
    }
    out
}

/// Percentile interval [q(α/2), q(1 − α/2)] with linear interpolation between order
/// statistics (R's type 7). `values` is non-empty.
fn percentile_interval(values: &mut [f64], alpha: f64) -> Interval {
    values.sort_by(f64::total_cmp);
    let quantile = |q: f64| {
        let h = (values.len() - 1) as f64 * q;
        let lo = h.floor() as usize;
        let hi = h.ceil() as usize;
        values[lo] + (h - lo as f64) * (values[hi] - values[lo])
    };
    Interval {
        lower: quantile(alpha / 2.0),
        upper: quantile(1.0 - alpha / 2.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand::rngs::ChaCha8Rng;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn binary_entropy_values() {
        assert_eq!(binary_entropy(0.0), 0.0);
        assert_eq!(binary_entropy(1.0), 0.0);
        assert!(close(binary_entropy(0.5), 1.0, 1e-15));
        assert!(close(binary_entropy(0.1), 0.468_995_593_589_281_2, 1e-15));
        assert!(close(binary_entropy(0.11), binary_entropy(0.89), 1e-15));
        assert!(binary_entropy(-0.1).is_nan());
        assert!(close(binary_convolution(0.1, 0.2), 0.26, 1e-15));
        assert!(close(binary_convolution(0.5, 0.2), 0.5, 1e-15));
    }

    /// Table of N steps with independent BSC errors of exactly known rates: fill by
    /// expected counts (N large, rates with short binary expansions).
    fn independent_table(pc: f64, pe: f64, n: f64) -> JointCounts {
        let mut t = JointCounts::default();
        for b in 0..2 {
            for c in 0..2 {
                for a in 0..2 {
                    let p = 0.5
                        * if c == b { 1.0 - pc } else { pc }
                        * if a == b { 1.0 - pe } else { pe };
                    t.n[b][c][a] = (p * n).round() as u64;
                }
            }
        }
        t
    }

    #[test]
    fn independent_errors_give_closed_forms() {
        let (pc, pe) = (0.125, 0.25);
        let t = independent_table(pc, pe, 1024.0 * 1024.0);
        assert!(close(t.controller_error_rate().unwrap(), pc, 1e-12));
        assert!(close(t.eve_error_rate().unwrap(), pe, 1e-12));
        let ic = 1.0 - binary_entropy(pc);
        let ie = 1.0 - binary_entropy(pe);
        assert!(close(t.information_controller().unwrap(), ic, 1e-12));
        assert!(close(t.information_eve().unwrap(), ie, 1e-12));
        assert!(close(t.information_advantage().unwrap(), ic - ie, 1e-12));
        // I(B;B̂c|B̂a) = h(pc ⋆ pe) − h(pc) for independent errors (docs/secrecy.md).
        let cond = binary_entropy(binary_convolution(pc, pe)) - binary_entropy(pc);
        assert!(close(
            t.information_controller_given_eve().unwrap(),
            cond,
            1e-12
        ));
    }

    #[test]
    fn identical_decisions_leave_nothing() {
        // Eve decides exactly as the controller: I(B;B̂c|B̂a) = 0, advantage 0.
        let mut t = JointCounts::default();
        t.n[0][0][0] = 400;
        t.n[1][1][1] = 380;
        t.n[0][1][1] = 20;
        t.n[1][0][0] = 25;
        assert!(close(
            t.information_controller_given_eve().unwrap(),
            0.0,
            1e-15
        ));
        assert!(close(t.information_advantage().unwrap(), 0.0, 1e-15));
    }

    #[test]
    fn empty_table_is_an_error() {
        let t = JointCounts::default();
        assert_eq!(t.information_controller(), Err(EntropyError::NoSteps));
        assert_eq!(t.controller_error_rate(), Err(EntropyError::NoSteps));
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        assert_eq!(
            bootstrap(&t, 10, 0.95, &mut rng),
            Err(EntropyError::NoSteps)
        );
        let mut t = JointCounts::default();
        t.record(true, true, false);
        assert_eq!(
            bootstrap(&t, 0, 0.95, &mut rng),
            Err(EntropyError::NoResamples)
        );
        assert!(matches!(
            bootstrap(&t, 10, 1.0, &mut rng),
            Err(EntropyError::InvalidConfidence(_))
        ));
    }

    #[test]
    fn multinomial_resample_preserves_total_and_mean() {
        let cells = [10, 0, 30, 60, 0, 0, 0, 900];
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut sums = [0.0; 8];
        let reps = 4000;
        for _ in 0..reps {
            let x = resample_multinomial(&cells, 1000, &mut rng);
            assert_eq!(x.iter().sum::<u64>(), 1000);
            assert_eq!(x[1], 0);
            for (s, v) in sums.iter_mut().zip(&x) {
                *s += *v as f64;
            }
        }
        for (s, &c) in sums.iter().zip(&cells) {
            let mean = s / reps as f64;
            // SE of the mean of Bin(1000, c/1000) over `reps` draws; 5 SE tolerance.
            let p = c as f64 / 1000.0;
            let se = (1000.0 * p * (1.0 - p) / reps as f64).sqrt();
            assert!(
                (mean - c as f64).abs() <= 5.0 * se + 1e-12,
                "cell {c}: {mean}"
            );
        }
    }

    #[test]
    fn bootstrap_is_seeded_and_covers_truth() {
        // 2000 steps of independent errors pc = 5 %, pe = 20 %.
        let t = independent_table(0.05, 0.2, 2000.0);
        let run = |seed| bootstrap(&t, 500, 0.95, &mut ChaCha8Rng::seed_from_u64(seed)).unwrap();
        let a = run(3);
        assert_eq!(a, run(3));
        let truth_adv = binary_entropy(0.2) - binary_entropy(0.05);
        let truth_cond = binary_entropy(binary_convolution(0.05, 0.2)) - binary_entropy(0.05);
        assert!(a.advantage_interval.contains(truth_adv), "{a:?}");
        assert!(a.conditional_interval.contains(truth_cond), "{a:?}");
        assert!(a.advantage_interval.contains(a.advantage));
        assert!(a.conditional_interval.lower < a.conditional_interval.upper);
    }

    #[test]
    fn percentile_interpolates() {
        let mut v: Vec<f64> = (0..=100).rev().map(f64::from).collect();
        let i = percentile_interval(&mut v, 0.05);
        assert!(
            close(i.lower, 2.5, 1e-12) && close(i.upper, 97.5, 1e-12),
            "{i:?}"
        );
    }
}
