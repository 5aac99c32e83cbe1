//! A wheel's rounding across a sweep of quanta, computed at its events: the command-quantum
//! check (`quantum_check`) rounds every wheel command `w` at several hundred candidate
//! quanta `q₀ < q₁ < …`, but the rounded multiple `n(q) = round(w/q)` changes only where
//! `w/q` crosses a half-integer — at most once per candidate when the candidates lie at most
//! a quarter cycle apart at the fastest wheel, and far less often at slower ones. A
//! [`WheelRounding`] holds one wheel's multiple at the current candidate and the index of the
//! first later candidate where it changes, so that a sweep rounds each wheel only at its
//! events (the multiples in between are the same number, bit for bit).
//!
//! Exactness: `fl(w/q)` is monotone in `q` (division is correctly rounded), and so is
//! `f64::round` of it (half away from zero), so the candidates where a wheel's multiple stays
//! `n` are consecutive. The next event is predicted from the candidates' even spacing in
//! `1/q` and then confirmed by rounding exactly as the world's actuator does (`(w/q).round()`):
//! the multiple has changed at the event and not at the candidate before it. A prediction
//! off by some candidates costs a rounding per candidate, never a different number.

/// The candidate quanta of a sweep, increasing (rad/s per wheel), and the spacing of their
/// inverses that predicts each wheel's next event.
pub(super) struct QuantumSweep<'a> {
    quanta: &'a [f64],
    /// `1/q₀` (s/rad).
    first_inverse: f64,
    /// `(1/q₀ − 1/q_last)/(N − 1)`: the mean decrease of `1/q` from one candidate to the next
    /// (s/rad; 0 with a single candidate).
    spacing: f64,
}

/// One wheel's rounding at the sweep's current candidate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct WheelRounding {
    /// The wheel's command `w` (rad/s).
    wheel: f64,
    /// `round(w/q)` at the current candidate, as the actuator computes it.
    multiple: f64,
    /// The first later candidate whose multiple differs (the candidates' count: none).
    next: usize,
}

impl<'a> QuantumSweep<'a> {
    /// A sweep of `quanta`, increasing.
    pub(super) fn new(quanta: &'a [f64]) -> Self {
        let (first_inverse, spacing) = match quanta {
            [] => (0.0, 0.0),
            [only] => (1.0 / only, 0.0),
            [first, .., last] => (
                1.0 / first,
                (1.0 / first - 1.0 / last) / (quanta.len() - 1) as f64,
            ),
        };
        Self {
            quanta,
            first_inverse,
            spacing,
        }
    }

    /// `wheel`'s multiple of candidate `index`: `round(w/q)`, exactly as [`crate::world::quantise`]
    /// rounds (its multiple times `q` is the rounded command, bit for bit).
    fn multiple(&self, wheel: f64, index: usize) -> f64 {
        (wheel / self.quanta[index]).round()
    }

    /// The rounding of `wheel` (rad/s) at the first candidate; none without candidates.
    pub(super) fn start(&self, wheel: f64) -> Option<WheelRounding> {
        (!self.quanta.is_empty()).then(|| {
            let multiple = self.multiple(wheel, 0);
            WheelRounding {
                wheel,
                multiple,
                next: self.next_change(wheel, multiple, 0),
            }
        })
    }

    /// The first candidate after `from` where `wheel`'s multiple is no longer `multiple` (its
    /// multiple at `from`); the candidates' count when it never changes. `|w|/q` decreases
    /// along the sweep, so the multiple leaves `n` where `|w|·(1/q)` falls below `|n| − ½`:
    /// predicted from the spacing of `1/q`, then moved until the multiple differs there and
    /// not at the candidate before.
    fn next_change(&self, wheel: f64, multiple: f64, from: usize) -> usize {
        let count = self.quanta.len();
        if multiple == 0.0 || !multiple.is_finite() || from + 1 >= count {
            return count;
        }
        let changed = |index: usize| self.multiple(wheel, index) != multiple;
        let threshold = (multiple.abs() - 0.5) / wheel.abs();
        let predicted = ((self.first_inverse - threshold) / self.spacing).floor() + 1.0;
        // A prediction outside the candidates (or not a number) starts at an end.
        let mut index = if predicted.is_nan() || predicted <= (from + 1) as f64 {
            from + 1
        } else if predicted >= count as f64 {
            count
        } else {
            predicted as usize
        };
        while index > from + 1 && changed(index - 1) {
            index -= 1;
        }
        while index < count && !changed(index) {
            index += 1;
        }
        index
    }

    /// Each candidate's multiple of `rounding`'s wheel from candidate `first` on, one per
    /// element of `out` (at most up to the last candidate; the elements after it are left as
    /// they are), advancing `rounding` to the last candidate written.
    pub(super) fn fill(&self, rounding: &mut WheelRounding, first: usize, out: &mut [f64]) {
        let end = (first + out.len()).min(self.quanta.len());
        let mut written = first;
        while rounding.next < end {
            out[written - first..rounding.next - first].fill(rounding.multiple);
            written = rounding.next;
            rounding.multiple = self.multiple(rounding.wheel, written);
            rounding.next = self.next_change(rounding.wheel, rounding.multiple, written);
        }
        out[written - first..end - first].fill(rounding.multiple);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{Purpose, stream};
    use rand::RngExt;

    /// Every wheel's multiples along a sweep, filled in blocks of `width` candidates, equal
    /// `(w/q).round()` at every candidate, bit for bit.
    fn assert_exact(quanta: &[f64], wheels: &[f64], width: usize) {
        let sweep = QuantumSweep::new(quanta);
        let mut out = vec![f64::NAN; width];
        for &wheel in wheels {
            let mut rounding = sweep.start(wheel).expect("candidates");
            for first in (0..quanta.len()).step_by(width) {
                sweep.fill(&mut rounding, first, &mut out);
                for (k, &multiple) in out.iter().enumerate() {
                    let Some(q) = quanta.get(first + k) else {
                        break;
                    };
                    let direct = (wheel / q).round();
                    assert_eq!(
                        multiple.to_bits(),
                        direct.to_bits(),
                        "w = {wheel}, q = {q} (candidate {})",
                        first + k
                    );
                }
            }
        }
    }

    /// Seeded random wheels, positive and negative, over the check's candidates at several
    /// fastest wheels, in blocks of several widths (one candidate at a time included).
    #[test]
    fn the_multiples_equal_direct_rounding_on_random_wheels() {
        let mut rng = stream(7, Purpose::Process, 0);
        for fastest in [0.5, 3.0, 7.0, 40.0] {
            let quanta = super::super::quantum_check::candidates(0.0, fastest);
            let wheels: Vec<f64> = (0..400)
                .map(|_| rng.random_range(-fastest..fastest))
                .collect();
            for width in [1, 5, 16] {
                assert_exact(&quanta, &wheels, width);
            }
        }
    }

    /// Zero (both signs), wheels at exact half-integers of a candidate (where `round` goes
    /// away from zero), the fastest wheel itself, and a wheel that never crosses: the same
    /// multiples as direct rounding. Irregular quanta (not evenly spaced in `1/q`) only cost
    /// the prediction, never a different multiple.
    #[test]
    fn the_multiples_equal_direct_rounding_at_the_edges() {
        let quanta = super::super::quantum_check::candidates(0.0, 7.0);
        let mut wheels = vec![0.0, -0.0, 7.0, -7.0, 1e-12, -1e-12];
        for (i, &q) in quanta.iter().enumerate().step_by(17) {
            for half in [0.5, 1.5, 2.5, 7.5, 20.5] {
                // Exactly representable halves of q: w/q is the half-integer itself.
                let w = half * q;
                if (w / q) == half && w.abs() <= 7.0 {
                    wheels.extend([w, -w]);
                }
            }
            assert!(i < quanta.len());
        }
        assert!(
            wheels.iter().any(|w| (w / quanta[0]).fract().abs() == 0.5),
            "an exact half"
        );
        for width in [1, 3, 16] {
            assert_exact(&quanta, &wheels, width);
        }
        let irregular = [0.03, 0.031, 0.05, 0.0501, 0.2, 0.21, 0.9, 1.0];
        assert_exact(&irregular, &[0.0, 0.9, -2.5, 3.3, 0.1005, -0.07], 3);
        assert_exact(&[0.25], &[0.125, -0.375, 1.0], 4);
        assert!(QuantumSweep::new(&[]).start(1.0).is_none());
    }
}
