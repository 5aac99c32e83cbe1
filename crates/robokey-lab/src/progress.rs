//! What a long computation shows while it runs: a progress bar on a terminal, rates and
//! counts written as people write them.

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressState, ProgressStyle};

/// A progress bar on a terminal, hidden otherwise: `label [=====>   ] done/len units, rate,
/// eta`.
#[must_use]
pub fn progress_bar(len: usize, label: &str, unit: &'static str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len as u64).with_message(label.to_owned());
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{{msg:>12}} [{{bar:40}}] {{pos}}/{{len}} {unit}s, {{rate}}, eta {{eta}}"
        ))
        .expect("a valid template")
        .with_key(
            "rate",
            move |state: &ProgressState, out: &mut dyn std::fmt::Write| {
                let _ = out.write_str(&rate_text(state.per_sec(), unit));
            },
        )
        .progress_chars("=> "),
    );
    bar
}

/// A rate for people: three significant figures at most, e.g. "46,700 runs/s", "12.3 runs/s";
/// below one per second, the seconds each takes ("4.2 s/run").
#[must_use]
pub fn rate_text(per_second: f64, unit: &str) -> String {
    if !(per_second.is_finite() && per_second > 0.0) {
        return format!("– {unit}s/s");
    }
    if per_second < 1.0 {
        return format!("{} s/{unit}", significant(1.0 / per_second));
    }
    format!("{} {unit}s/s", significant(per_second))
}

/// Three significant figures; thousands separated by commas.
fn significant(x: f64) -> String {
    if x < 100.0 {
        let decimals = if x < 10.0 { 2 } else { 1 };
        return format!("{x:.decimals$}");
    }
    let magnitude = 10f64.powi(x.log10().floor() as i32 - 2);
    let rounded = ((x / magnitude).round() * magnitude) as u64;
    thousands(rounded)
}

/// An integer with its thousands separated by commas: `10,000`.
pub(crate) fn thousands(n: impl ToString) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_read_as_people_write_them() {
        assert_eq!(rate_text(46_698.136_3, "run"), "46,700 runs/s");
        assert_eq!(rate_text(1_234_567.0, "run"), "1,230,000 runs/s");
        assert_eq!(rate_text(123.4, "session"), "123 sessions/s");
        assert_eq!(rate_text(12.345, "run"), "12.3 runs/s");
        assert_eq!(rate_text(1.5, "run"), "1.50 runs/s");
        assert_eq!(rate_text(0.25, "run"), "4.00 s/run");
        assert_eq!(rate_text(0.0, "run"), "– runs/s");
    }
}
