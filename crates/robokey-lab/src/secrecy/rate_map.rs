//! The rate map of private sensing (docs/private-sensing.md, "Maps"): every point's secret
//! rate against its tracking cost, one series per alphabet (levels × dimensions), each
//! beside its limit `Σ_dims C × kept fraction / steps per doublet` — `C` the alphabet's
//! secrecy margin through the controller's and the stated camera's views at the
//! configuration ([`robokey_secrecy::wiretap_limit`]). Computed from the results of
//! [`super::analyze()`] and the points' configurations; rendered by
//! [`crate::report::rate_map`].

use robokey::Config;
use robokey::config::{EveStrategy, SensingMode};
use robokey::model::{Pose, Unicycle};
use robokey::private::likelihood::{
    DoubletView, PoseObservation, doublet_model, stated_camera_view,
};
use robokey::private::{DoubletInputs, Perturbation};
use robokey_secrecy::wiretap_limit::{Alphabet, secrecy_margin, snr_of_separation};

use super::PointSecrecy;
use crate::experiment::Experiment;

/// One point of the map: its rate and tracking cost against the camera eavesdropper, and
/// the limit its alphabet sets at its configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct RatePoint {
    /// The point's parameters, `field = value, …`.
    pub point: String,
    /// Amplitude levels per dimension.
    pub levels: u8,
    /// Dimensions carrying a symbol (1: v, 2: v and ω).
    pub dimensions: u8,
    /// `[Δv (m/s), Δω (rad/s)]` (Δω 0 with one dimension).
    pub delta: [f64; 2],
    /// Secret bits ℓ over the blocks, under the camera statement.
    pub secret_bits: u64,
    /// ℓ the camera eavesdropper's realised view would support (her bound).
    pub realised_bits: u64,
    /// Every reconciliation bit revealed over the blocks, leak_EC.
    pub leak_ec: u64,
    /// Secret bits per robot step.
    pub secret_bits_per_step: f64,
    /// Mean tracking error J_x (mm).
    pub jx_mm: f64,
    /// J_x with the protocol off, same seeds (mm).
    pub jx_off_mm: f64,
    /// Fraction of the doublets the turn gate kept.
    pub kept_fraction: f64,
    /// Steps per doublet (2, or 3 with a prior lag).
    pub steps_per_doublet: u32,
    /// Per dimension (v, ω): the controller's and the stated camera's SNR of a unit-power
    /// symbol, `(d/2)²` of their binary separations on a straight doublet.
    pub snr: [[f64; 2]; 2],
    /// Per dimension (v, ω): the margin `C = I(X; Y_c) − I(X; Y_e)` (bits per doublet; 0 for
    /// a dimension that carries nothing).
    pub margin: [f64; 2],
    /// The limit, `max(0, Σ_dims C) × kept fraction / steps per doublet` (bits per step).
    pub limit_per_step: f64,
}

impl RatePoint {
    /// The alphabet's name, e.g. "4-level, 2 dims".
    #[must_use]
    pub fn alphabet(&self) -> String {
        format!(
            "{}-level, {} dim{}",
            self.levels,
            self.dimensions,
            if self.dimensions == 1 { "" } else { "s" }
        )
    }

    /// The rate over its limit (NaN without a limit).
    #[must_use]
    pub fn ratio(&self) -> f64 {
        if self.limit_per_step > 0.0 {
            self.secret_bits_per_step / self.limit_per_step
        } else {
            f64::NAN
        }
    }
}

/// The rate map of an experiment: its points, by alphabet, then Δv and Δω.
#[derive(Clone, Debug, PartialEq)]
pub struct RateMap {
    /// Every point, against the camera eavesdropper.
    pub points: Vec<RatePoint>,
    /// The stated assumption that sizes the keys (of the first point).
    pub assumption: String,
}

impl RateMap {
    /// The mean protocol-off J_x over the points (mm): the tracking cost's reference.
    #[must_use]
    pub fn jx_off_mm(&self) -> f64 {
        self.points.iter().map(|p| p.jx_off_mm).sum::<f64>() / self.points.len().max(1) as f64
    }
}

/// The controller's and the stated camera eavesdropper's SNR per dimension `[[v_c, v_e],
/// [ω_c, ω_e]]` for a unit-power symbol at `config`: `(d/2)²` of their binary separations
/// ([`robokey::private::DoubletModel::separations`]) on a straight doublet at the
/// trajectory's mean reference speed — the controller seeing its own samples, Eve the view
/// the key is sized with ([`stated_camera_view`]).
#[must_use]
pub fn view_snrs(config: &Config) -> [[f64; 2]; 2] {
    let mut model = doublet_model(config);
    let perturbation = Perturbation::of(config);
    let delta = perturbation.delta;
    model.perturbation = Perturbation::binary(delta, 2, perturbation.settle);
    let steps = model.perturbation.steps();
    let trajectory = config.trajectory();
    let instants = trajectory.steps(config.robot.sample_time).max(1);
    let speed = (0..instants)
        .map(|k| {
            trajectory
                .at(k as f64 * config.robot.sample_time)
                .velocity
                .norm()
        })
        .sum::<f64>()
        / instants as f64;
    let nominal = Unicycle::new(speed, 0.0);
    let inputs = DoubletInputs {
        first: nominal,
        second: nominal,
    };
    let start = Pose::zeros();
    let path = inputs.propagate_steps(
        &start,
        [Unicycle::zeros(); 3],
        steps,
        config.robot.sample_time,
    );
    let samples: Vec<Pose> = std::iter::once(start)
        .chain(path.into_iter().take(steps as usize))
        .collect();
    let controller_std = config.sensing.controller_std;
    let own = |k: usize| PoseObservation::new(samples[k], controller_std);
    let controller = DoubletView {
        start: own(0),
        middle: Some(own(1)),
        late: (steps == 3).then(|| own(2)),
        end: Some(own(steps as usize)),
        entry: None,
    };
    let eve = stated_camera_view(&samples, controller_std, config.modelled_camera_std());
    let c = model.separations(&inputs, &controller);
    let e = model.sizing_separations(&inputs, &eve);
    std::array::from_fn(|dim| {
        if delta[dim] > 0.0 {
            [snr_of_separation(c[dim]), snr_of_separation(e[dim])]
        } else {
            [0.0; 2]
        }
    })
}

/// The map of `results` (of `experiment`'s points): when the experiment is private sensing
/// and sweeps the perturbation (a `protocol.*` axis), every point against the camera
/// eavesdropper with its limit; none otherwise.
#[must_use]
pub fn rate_map(experiment: &Experiment, results: &[PointSecrecy]) -> Option<RateMap> {
    let private = experiment
        .points
        .first()
        .is_some_and(|p| p.config.sensing.mode == SensingMode::Private);
    let over_delta = experiment
        .axes
        .iter()
        .any(|a| a.field.starts_with("protocol."));
    if !(private && over_delta) {
        return None;
    }
    let mut points: Vec<RatePoint> = results
        .iter()
        .filter(|r| r.adversary == EveStrategy::Camera.name())
        .filter_map(|r| {
            let figures = r.private.as_ref()?;
            let config = &experiment.points.get(r.point_index)?.config;
            Some(rate_point(r, figures, config))
        })
        .collect();
    if points.is_empty() {
        return None;
    }
    points.sort_by(|a, b| {
        (a.dimensions, a.levels)
            .cmp(&(b.dimensions, b.levels))
            .then(a.delta[0].total_cmp(&b.delta[0]))
            .then(a.delta[1].total_cmp(&b.delta[1]))
    });
    let assumption = results
        .iter()
        .find(|r| r.adversary == EveStrategy::Camera.name())
        .map(|r| r.assumption.clone())
        .unwrap_or_default();
    Some(RateMap { points, assumption })
}

fn rate_point(r: &PointSecrecy, figures: &super::PrivateFigures, config: &Config) -> RatePoint {
    let perturbation = Perturbation::of(config);
    let alphabet = Alphabet::Pam {
        levels: perturbation.levels,
    };
    let snr = view_snrs(config);
    let margin = snr.map(|[c, e]| {
        if c > 0.0 {
            secrecy_margin(alphabet, c, e)
        } else {
            0.0
        }
    });
    let kept_fraction = 1.0 - figures.gated_fraction;
    let steps_per_doublet = perturbation.steps();
    RatePoint {
        point: r.point.clone(),
        levels: perturbation.levels,
        dimensions: perturbation.bits_per_doublet,
        delta: [perturbation.delta.x, perturbation.delta.y],
        secret_bits: r.secret_bits,
        realised_bits: r.realised_secret_bits,
        leak_ec: r.blocks.iter().map(|b| b.leak_ec).sum(),
        secret_bits_per_step: r.secret_bits_per_step,
        jx_mm: figures.jx_mm,
        jx_off_mm: figures.jx_off_mm,
        kept_fraction,
        steps_per_doublet,
        snr,
        margin,
        limit_per_step: margin.iter().sum::<f64>().max(0.0) * kept_fraction
            / f64::from(steps_per_doublet),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(text: &str) -> Config {
        Config::from_toml(&format!("[sensing]\nmode = \"private\"\n{text}"), "test").unwrap()
    }

    /// At the defaults the views are the ones the closed forms describe: the controller's
    /// v-noise N_c = 1.5σ_c² + σ_w²/2 and the stated camera's N_e = σ_e² + σ_w²/2 + σ_c²/2
    /// for an amplitude ΔT (within 10 %: the model's exact covariances, not the
    /// approximation), and Eve's view is the worse one in both dimensions.
    #[test]
    fn the_defaults_views_are_the_closed_forms() {
        let c = config("[protocol]\nbits_per_doublet = 2\n");
        let [[vc, ve], [wc, we]] = view_snrs(&c);
        let a = c.protocol.delta_v * c.robot.sample_time;
        let (sc, sw) = (c.sensing.controller_std[0], c.noise.process_std[0]);
        let se = c.modelled_camera_std()[0];
        let nc = 1.5 * sc * sc + sw * sw / 2.0;
        let ne = se * se + sw * sw / 2.0 + sc * sc / 2.0;
        assert!(
            (vc / (a * a / nc) - 1.0).abs() < 0.1,
            "{vc} vs {}",
            a * a / nc
        );
        assert!(
            (ve / (a * a / ne) - 1.0).abs() < 0.1,
            "{ve} vs {}",
            a * a / ne
        );
        assert!(vc > ve && wc > we && we > 0.0, "{vc} {ve} {wc} {we}");
        let one = view_snrs(&config(""));
        assert_eq!(one[1], [0.0, 0.0]);
        assert!((one[0][0] / vc - 1.0).abs() < 0.01, "{} vs {vc}", one[0][0]);
    }
}
