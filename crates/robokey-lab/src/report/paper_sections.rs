//! The sections of the paper's report that render the stages `reproduce` computed: how many
//! of the bits are secret, the adversaries that try harder, and private sensing.

use std::fmt::Write as _;
use std::path::Path;

use robokey::config::EveStrategy;

use super::adversary::{campaign_body, campaigns_summary, write_campaign};
use super::private::{break_even_text, pooled_leak_text};
use super::rate_map::{RATES_STEM, rates_table};
use super::secrecy::{secrecy_markdown, write_secrecy};
use crate::adversary::Campaign;
use crate::error::LabError;
use crate::experiment::Experiment;
use crate::parquet_table::TableFormat;
use crate::progress::thousands;
use crate::reproduce::EVE_DIR;
use crate::reproduce::private_suite::BUDGET_SECONDS;
use crate::secrecy::Secrecy;
use crate::secrecy::rate_map::rate_map;

/// The secrecy section: the Δv sweep and the α sweep against the paper's and the oracle Eve,
/// each with its heading, rendered into its folder in `out`; markdown and terminal lines.
pub(super) fn secrecy_section(
    out: &Path,
    experiments: &[(&Experiment, &Secrecy, &str)],
) -> Result<(String, String), LabError> {
    let block_bits = experiments.first().map_or(0, |(_, s, _)| s.block_bits);
    let mut terminal = String::new();
    let mut md = String::from("## How many of these bits are secret?\n\n");
    md.push_str(&format!(
        "The paper measures Eve only by her disagreement. Here every point is re-simulated until the sessions \
         today's agents would keep (both key tags matched) fill a block of at least {} raw bits; every tag \
         published over a pooled key is charged (two directional 128-bit key tags per session), and the block's secret length \
         follows from the finite-key bound (docs/secrecy.md), against the oracle Eve (strongest: the exact \
         model), the identifying Eve (learns r and D from the traffic) and the paper's Eve (restricted: she \
         never learns them, so a figure against her holds only if nobody does).\n\n",
        thousands(block_bits)
    ));
    for &(experiment, secrecy, title) in experiments {
        let results = &secrecy.results;
        write_secrecy(
            &out.join(&experiment.name),
            experiment,
            secrecy,
            TableFormat::Csv,
        )?;
        md.push_str(&format!("### {title}\n\n"));
        md.push_str(&secrecy_markdown(secrecy));
        md.push_str(&format!(
            "\n![secret bits]({}/secrecy-bits-per-step.svg)\n\n",
            experiment.name
        ));
        let total: u64 = results.iter().map(|r| r.secret_bits).sum();
        let _ = writeln!(
            terminal,
            "secret bits, {}: {}",
            experiment.name,
            if total == 0 {
                "0 at every point, against every adversary".to_owned()
            } else {
                format!("{total} over all points (by structure the rate is still 0)")
            }
        );
        let worst_eve = results
            .iter()
            .filter_map(|r| r.eve_error_accepted.map(|e| e.rate))
            .fold(0.0, f64::max);
        let best_h = results
            .iter()
            .flat_map(|r| r.blocks.iter().map(|b| b.h_min))
            .fold(0.0, f64::max);
        md.push_str(&if total == 0 {
            format!(
                "**Zero secret bits at every point, against every adversary.** Eve is wrong on at most {:.2} % of the \
                 accepted bits, so the min-entropy bound of a block is at most {best_h:.1} bits — less than the tags \
                 published over its keys and the 2·log2(1/ε) cost. The paper's security claim does not survive this \
                 accounting.\n\n",
                100.0 * worst_eve
            )
        } else {
            let mut against: Vec<&str> = results
                .iter()
                .filter(|r| r.secret_bits > 0)
                .map(|r| r.adversary_class.name())
                .collect();
            against.sort_unstable();
            against.dedup();
            format!(
                "{total} secret bits over all points, against {} adversaries only; by structure the rate is still \
                 zero (above).\n\n",
                against.join("/")
            )
        });
    }
    Ok((md, terminal))
}

/// The eavesdroppers of docs/threat-model.md: every strategy on the default configuration's
/// sessions, in order, over independent campaigns (`robokey eve`), rendered into `dir`;
/// markdown and a terminal line.
pub(super) fn adversary_section(
    dir: &Path,
    campaign: &Campaign,
) -> Result<(String, String), LabError> {
    write_campaign(dir, campaign)?;
    let campaigns = campaign.campaigns();
    let matched: Vec<String> = campaign
        .runs
        .iter()
        .map(|run| {
            let s = run.strategy;
            let count = campaign
                .all
                .iter()
                .filter(|r| r.strategy == s && r.match_period.is_some())
                .count();
            format!("{} {count}", s.name())
        })
        .collect();
    let terminal = format!(
        "eavesdroppers that came to decide as well as the controller, of {campaigns} \
         campaigns:\n  {}\n",
        matched.join(", ")
    );
    let md = format!(
        "\n## Adversaries that try harder\n\n### One campaign\n\n{}{}",
        campaign_body(campaign, &format!("{EVE_DIR}/")),
        campaigns_summary(campaign, "###")
    );
    Ok((md, terminal))
}

/// The experiment of one folder of the private-sensing map, and its secrecy.
pub(super) struct MapPart {
    /// The experiment.
    pub experiment: Experiment,
    /// Its secrecy stage.
    pub secrecy: Secrecy,
}

/// The private-sensing section (docs/private-sensing.md): the secret rate against Eve's
/// camera noise with its break-even and the rate against tracking cost over Δv, rendered
/// into `out` (their folders by name); markdown and the terminal summary, whose sentences
/// come from the computed numbers.
pub(super) fn private_section(
    out: &Path,
    camera: &MapPart,
    front: &MapPart,
) -> Result<(String, String), LabError> {
    for part in [camera, front] {
        write_secrecy(
            &out.join(&part.experiment.name),
            &part.experiment,
            &part.secrecy,
            TableFormat::Csv,
        )?;
    }
    let mut md = String::from("\n## Private sensing: a key that is secret, and against whom\n\n");
    let mut terminal = String::new();
    // The defaults: Δv = 0.035 on the front experiment, camera adversary.
    let default = front.secrecy.results.iter().find(|r| {
        r.adversary == EveStrategy::Camera.name()
            && (front.experiment.points[r.point_index]
                .config
                .protocol
                .delta_v
                - 0.035)
                .abs()
                < 1e-12
    });
    let paper_jx = front
        .secrecy
        .map
        .as_ref()
        .map_or(f64::NAN, |m| m.paper_jx_mm);
    if let Some(d) = default {
        let jx = d.private.as_ref().map_or(f64::NAN, |p| p.jx_mm);
        let _ = writeln!(
            md,
            "The paper's scheme yields **0** secret bits by structure (everything the controller \
             decides from is public but r and D, which an eavesdropper learns). With private \
             sensing at the defaults (Δv = 0.035 m/s, one bit per doublet, motion noise 4 mm, \
             controller sensor 0.5 mm), robokey makes **{:.3} secret bits per second** \
             ({:.4} per step; blocks of {} bits, ε = {:e} per term) with J_x = {jx:.1} mm \
             (the paper's scheme: {paper_jx:.1} mm). This holds under the stated physical \
             assumption: {}.\n",
            d.secret_bits_per_second,
            d.secret_bits_per_step,
            front.secrecy.block_bits,
            front.secrecy.epsilon,
            d.assumption
        );
        let _ = writeln!(
            terminal,
            "private sensing: {:.3} secret bits/s at the defaults (Eve's camera ≥ 8 mm; the \
             paper's scheme: 0)",
            d.secret_bits_per_second
        );
    }
    if let Some(map) = &camera.secrecy.map {
        let _ = writeln!(
            md,
            "The key exists only while Eve's camera is worse than a break-even noise, which \
             depends on the motion noise (a calibration):\n"
        );
        for curve in &map.camera {
            let _ = writeln!(md, "- {}: {}", curve.label, break_even_text(curve));
            let _ = writeln!(
                terminal,
                "  break-even camera noise, {}: {}",
                curve.label,
                break_even_text(curve)
            );
        }
        let _ = writeln!(
            md,
            "\n![rate against camera noise](private-sensing/camera/private-rate-vs-camera.svg)\n"
        );
    }
    if let Some(map) = &front.secrecy.map {
        let (inside, bins) = map.leak.iter().fold((0, 0), |(inside, all), b| {
            (
                inside + usize::from(b.measured[1] <= b.predicted && b.predicted <= b.measured[2]),
                all + 1,
            )
        });
        let _ = writeln!(
            md,
            "![Pareto front](private-sensing/pareto-v/private-pareto.svg)\n\n\
             What the public commands leak is charged as the model predicts it, not assumed \
             away. Bin by bin, the commands eavesdropper's measured information lies within its \
             95 % interval of the prediction in {inside} of {bins} turn-rate bins.{}\n\n\
             ![leak](private-sensing/pareto-v/private-leak.svg)\n",
            map.pooled_leak()
                .map_or_else(String::new, |p| format!(" {}", pooled_leak_text(&p)))
        );
    }
    if let Some(rates) = rate_map(&front.experiment, &front.secrecy.results) {
        let _ = writeln!(
            md,
            "Each point of the front beside its limit — Σ_dims C × kept fraction ÷ steps per \
             doublet, C = I(X; Y_c) − I(X; Y_e) its alphabet's secrecy margin per doublet and \
             dimension through the controller's and the stated camera's views (against the \
             camera eavesdropper; binary symbols on v only here: the map of every alphabet is \
             `experiments/private-rates.toml`):\n\n![rate map](private-sensing/{}/{RATES_STEM}.svg)\n\n{}",
            front.experiment.name,
            rates_table(&rates)
        );
    }
    let _ = writeln!(
        md,
        "A coarse map, computed within a budget of about {BUDGET_SECONDS} s on 2 cores. The \
         full one is `robokey sweep experiments/private-sensing.toml` followed by \
         `robokey secrecy` on its folder. Tables: `private-sensing/*/secrecy.md`; how it \
         works: docs/private-sensing.md.\n"
    );
    Ok((md, terminal))
}

/// The worlds section: in sentences made from the numbers, which of the coarse worlds the
/// parties' key over-claims against the eavesdroppers who know them (docs/world.md); empty
/// for a reproduction made before worlds existed; each world's tables rendered into its
/// folder in `out`. Markdown and terminal lines.
pub(super) fn world_section(out: &Path, worlds: &[MapPart]) -> Result<(String, String), LabError> {
    if worlds.is_empty() {
        return Ok((String::new(), String::new()));
    }
    for world in worlds {
        write_secrecy(
            &out.join(&world.experiment.name),
            &world.experiment,
            &world.secrecy,
            TableFormat::Csv,
        )?;
    }
    let rows: Vec<super::world::OverClaim> = worlds
        .iter()
        .flat_map(|w| super::world::over_claims(&w.experiment, &w.secrecy.results))
        .collect();
    // Each world by its experiment's name, whether the camera eavesdropper's view shows the
    // assumption over-claimed, and whether a key was committed at all (a block the commands
    // check refuses keeps none: nothing of it is over-claimed).
    let judged: Vec<(&str, bool, bool)> = worlds
        .iter()
        .filter_map(|w| {
            let rows = super::world::over_claims(&w.experiment, &w.secrecy.results);
            let camera = rows.iter().find(|r| r.adversary == "camera")?;
            Some((
                w.experiment.name.as_str(),
                camera.per_raw_bit > 0.0,
                camera.secret_bits > 0,
            ))
        })
        .collect();
    let over: Vec<&str> = judged
        .iter()
        .filter(|(_, o, keyed)| *o && *keyed)
        .map(|(n, ..)| *n)
        .collect();
    let keyless: Vec<&str> = judged
        .iter()
        .filter(|(_, o, keyed)| *o && !*keyed)
        .map(|(n, ..)| *n)
        .collect();
    let mut md = String::from(
        "\n## The world is not the configuration\n\nThe parties at their defaults (private \
         sensing: 4 mm of white motion noise, a 0.5 mm controller sensor, Eve's camera of 8 mm \
         per sample instant), each in a world that differs in one way; the `camera` and \
         `commands` eavesdroppers know the world and smooth over a window of doublets \
         (docs/world.md). The over-claim is ℓ minus the ℓ the camera eavesdropper's realised \
         view supports, before clamping at zero, per raw bit amplified.\n\n",
    );
    for sentence in super::world::over_claim_sentences(&rows) {
        let _ = writeln!(md, "- {sentence}");
    }
    let mut verdict = if over.is_empty() {
        "no world of the coarse grid is over-claimed".to_owned()
    } else {
        format!(
            "{} of {} worlds are over-claimed ({})",
            over.len(),
            judged.len(),
            over.join(", ")
        )
    };
    if !keyless.is_empty() {
        verdict.push_str(&format!(
            "; where the assumption over-claims in {} the parties commit no key (their \
             blocks are refused: see their secrecy.md)",
            keyless.join(", ")
        ));
    }
    let _ = writeln!(
        md,
        "\nIn short, {verdict}. The full map is `robokey sweep experiments/worlds.toml` \
         followed by `robokey secrecy` on its folder; tables: `worlds/*/secrecy.md`."
    );
    Ok((md, format!("worlds: {verdict}\n")))
}
