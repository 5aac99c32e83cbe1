//! Renders the private-sensing figures of one or more (point, adversary) rows: a markdown
//! section and `turn-rates.csv` (docs/private-sensing.md).

use super::Rate;
use super::private::{Calibration, PrivateFigures};

/// One row to render: where it comes from and its figures.
pub struct PrivateRow<'a> {
    /// The grid point, `field = value, …` (empty for a single configuration).
    pub point: &'a str,
    /// The adversary's name.
    pub adversary: &'a str,
    /// Its figures.
    pub figures: &'a PrivateFigures,
}

fn percent(rate: Option<&Rate>) -> String {
    rate.map_or("–".into(), |r| {
        format!(
            "{:.2} [{:.2}, {:.2}]",
            100.0 * r.rate,
            100.0 * r.low,
            100.0 * r.high
        )
    })
}

fn interval(x: &[f64; 3]) -> String {
    format!("{:.5} [{:.5}, {:.5}]", x[0], x[1], x[2])
}

fn calibrated(c: &Calibration) -> String {
    format!(
        "{} (worst p {:.3})",
        if c.passed { "pass" } else { "**FAIL**" },
        c.worst_p
    )
}

/// The markdown section: one summary row per (point, adversary), then each row's
/// information by the public turn rate against what the model predicts.
#[must_use]
pub fn private_markdown(rows: &[PrivateRow]) -> String {
    let mut md = String::from(
        "## Private sensing\n\n\
         | point | adversary | bits/doublet | doublets | turn-gated % | controller error % | Eve error % | Eve information per bit | predicted | calibration: controller / Eve | J_x mm (protocol off) |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for row in rows {
        let f = row.figures;
        md.push_str(&format!(
            "| {} | {} | {} | {} | {:.2} | {} | {} | {} | {:.5} | {} / {} | {:.2} ({:.2}) |\n",
            row.point,
            row.adversary,
            f.bits_per_doublet,
            f.doublets,
            100.0 * f.gated_fraction,
            percent(f.controller_error.as_ref()),
            percent(f.eve_error.as_ref()),
            interval(&f.eve_information),
            f.eve_information_predicted,
            calibrated(&f.controller_calibration),
            calibrated(&f.eve_calibration),
            f.jx_mm,
            f.jx_off_mm,
        ));
    }
    md.push_str(
        "\nEve's information per bit is 1 − E[surprisal of the true bit] under her calibrated \
         posterior (95 % normal interval); predicted is the mean of I(d) over the model's \
         separations d of the same bits. Error rates: 95 % Clopper–Pearson intervals. \
         Calibration: 10 equal-count bins, exact Poisson-binomial tails, family-wise \
         α = 10⁻³. See docs/private-sensing.md.\n",
    );
    for row in rows {
        md.push_str(&format!(
            "\n### {} Eve by public turn rate{}\n\n\
             | turn rate (rad/s) | bits | Eve error % | information per bit | predicted |\n\
             |---|---|---|---|---|\n",
            row.adversary,
            if row.point.is_empty() {
                String::new()
            } else {
                format!(" ({})", row.point)
            }
        ));
        for bin in &row.figures.turn_bins {
            md.push_str(&format!(
                "| {:.2}–{} | {} | {} | {} | {:.5} |\n",
                bin.from,
                if bin.to.is_finite() {
                    format!("{:.2}", bin.to)
                } else {
                    "∞".into()
                },
                bin.bits,
                percent(bin.error.as_ref()),
                interval(&bin.information),
                bin.predicted,
            ));
        }
    }
    md
}

/// `turn-rates.csv`: one line per (point, adversary, turn-rate bin).
#[must_use]
pub fn turn_rates_csv(rows: &[PrivateRow]) -> String {
    let mut out = String::from(
        "point,adversary,turn_from,turn_to,bits,eve_error,eve_error_low,eve_error_high,information,information_low,information_high,predicted\n",
    );
    for row in rows {
        for bin in &row.figures.turn_bins {
            let error = bin
                .error
                .map_or(",,".into(), |e| format!("{},{},{}", e.rate, e.low, e.high));
            out.push_str(&format!(
                "\"{}\",{},{},{},{},{},{},{},{},{}\n",
                row.point.replace('"', "\"\""),
                row.adversary,
                bin.from,
                if bin.to.is_finite() {
                    bin.to.to_string()
                } else {
                    String::new()
                },
                bin.bits,
                error,
                bin.information[0],
                bin.information[1],
                bin.information[2],
                bin.predicted,
            ));
        }
    }
    out
}
