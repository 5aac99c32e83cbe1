//! Windowed error rates and when an eavesdropper comes to decide as well as the controller.

use super::period::PeriodRecord;

/// Error rates (%) over the last `window` decided periods, for her and the controller, at
/// every period from the first full window on.
#[must_use]
pub fn windowed_error_rates(periods: &[PeriodRecord], window: usize) -> Vec<(u64, f64, f64)> {
    if window == 0 || periods.len() < window {
        return Vec::new();
    }
    let (mut eve, mut controller) = (0usize, 0usize);
    let mut rates = Vec::with_capacity(periods.len() + 1 - window);
    for (i, p) in periods.iter().enumerate() {
        eve += usize::from(p.eve != p.bit);
        controller += usize::from(p.controller != p.bit);
        if i >= window {
            let old = &periods[i - window];
            eve -= usize::from(old.eve != old.bit);
            controller -= usize::from(old.controller != old.bit);
        }
        if i + 1 >= window {
            let pct = |count: usize| 100.0 * count as f64 / window as f64;
            rates.push((p.period, pct(eve), pct(controller)));
        }
    }
    rates
}

/// The first period from which every windowed error rate of hers is within `tolerance_pp`
/// percentage points above the controller's (`None`: the last window is not).
#[must_use]
pub fn match_period(periods: &[PeriodRecord], window: usize, tolerance_pp: f64) -> Option<u64> {
    let rates = windowed_error_rates(periods, window);
    let within = |&(_, eve, controller): &(u64, f64, f64)| eve - controller <= tolerance_pp + 1e-9;
    let first_after_last_miss = rates.iter().rposition(|r| !within(r)).map_or(0, |i| i + 1);
    rates.get(first_after_last_miss).map(|&(period, ..)| period)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn period(period: u64, eve_wrong: bool, controller_wrong: bool) -> PeriodRecord {
        PeriodRecord {
            session: 0,
            step: period as u32 - 1,
            period,
            bit: 1,
            controller: u8::from(!controller_wrong),
            eve: u8::from(!eve_wrong),
            r_error: 0.0,
            d_error: 0.0,
        }
    }

    #[test]
    fn windows_and_the_match_period() {
        // Eve is wrong on periods 1–4, the controller on 2; windows of 4.
        let periods: Vec<PeriodRecord> = (1..=10).map(|p| period(p, p <= 4, p == 2)).collect();
        let rates = windowed_error_rates(&periods, 4);
        assert_eq!(rates.len(), 7);
        assert_eq!(rates[0], (4, 100.0, 25.0));
        assert_eq!(rates[1], (5, 75.0, 25.0));
        assert_eq!(rates[4], (8, 0.0, 0.0));
        // Windows ending at 4–7 hold one of her errors more than the controller's or worse;
        // from 8 on they are equal.
        assert_eq!(match_period(&periods, 4, 0.5), Some(8));
        assert_eq!(match_period(&periods, 4, 25.0), Some(7));
        assert_eq!(match_period(&periods, 4, 100.0), Some(4));
        let late: Vec<PeriodRecord> = (1..=10).map(|p| period(p, p == 10, false)).collect();
        assert_eq!(match_period(&late, 4, 0.5), None);
        assert!(windowed_error_rates(&periods, 11).is_empty());
    }
}
