//! Sweep definitions (README, "Sweeps"; docs/experiments.md): axes over any config field, Cartesian or zipped, and the
//! multi-experiment suites (`[experiment.NAME]`) that `reproduce` runs.

use robokey::Config;
use robokey::config::{Reconciliation, Sizing, set_path};

use crate::error::LabError;

/// How axes combine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Every combination; the first axis varies slowest.
    Cartesian,
    /// The i-th values of all axes together (equal lengths).
    Zip,
}

/// One swept field and its values.
#[derive(Clone, Debug, PartialEq)]
pub struct Axis {
    /// Dotted field path, e.g. `protocol.delta_v`.
    pub field: String,
    /// Values in order.
    pub values: Vec<toml::Value>,
}

/// One grid point: the axis values and the validated configuration.
#[derive(Clone, Debug)]
pub struct Point {
    /// `(field, value)` per axis.
    pub params: Vec<(String, toml::Value)>,
    /// The configuration at this point.
    pub config: Config,
}

/// A named experiment: a base configuration, a sweep over it, and its grid.
#[derive(Clone, Debug)]
pub struct Experiment {
    /// Name (the output subfolder of a suite; empty for a single sweep).
    pub name: String,
    /// Axes (none: a single point).
    pub axes: Vec<Axis>,
    /// How axes combine.
    pub mode: Mode,
    /// Whether replicate 0 of each point also writes its trace.
    pub traces: bool,
    /// The grid, in order.
    pub points: Vec<Point>,
    /// What `robokey secrecy` uses unless told otherwise (`[secrecy]`).
    pub secrecy: SecrecyDefaults,
}

/// `[secrecy]` of a sweep file: the block size, ε, reconciliation and sizing a map is
/// computed with, so that they are written beside the grid they belong to (each one a default
/// the matching `robokey secrecy` flag overrides).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SecrecyDefaults {
    /// Least pooled raw bits per privacy-amplification block, 64 to 10⁷.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub block_bits: Option<u64>,
    /// ε per term, in (0, 1).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub epsilon: Option<f64>,
    /// How `complete` pooling reconciles: `cascade` or `ldpc` (private sensing only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reconciliation: Option<Reconciliation>,
    /// What sizes private sensing's key: `configured`, `measured` or `world`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sizing: Option<Sizing>,
}

/// What `[secrecy] reconciliation` allows.
const RECONCILIATIONS: [Reconciliation; 2] = [Reconciliation::Cascade, Reconciliation::Ldpc];
/// What `[secrecy] sizing` allows.
const SIZINGS: [Sizing; 3] = [Sizing::Configured, Sizing::Measured, Sizing::World];

/// Refuses `[secrecy] field` unless it is absent or one of `allowed`, naming the field, its
/// value and the allowed names.
fn check_name(table: &toml::Value, field: &str, allowed: &[&str]) -> Result<(), String> {
    match table.get(field) {
        None => Ok(()),
        Some(toml::Value::String(name)) if allowed.contains(&name.as_str()) => Ok(()),
        Some(value) => Err(format!(
            "[secrecy] {field} = {value} is not allowed (allowed: {})",
            allowed
                .iter()
                .map(|name| format!("{name:?}"))
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

/// Smallest block `[secrecy] block_bits` and `--block` allow.
pub const MIN_BLOCK_BITS: u64 = 64;
/// Largest block `[secrecy] block_bits` and `--block` allow.
pub const MAX_BLOCK_BITS: u64 = 10_000_000;

impl SecrecyDefaults {
    fn from_value(value: toml::Value) -> Result<Self, String> {
        check_name(
            &value,
            "reconciliation",
            &RECONCILIATIONS.map(Reconciliation::name),
        )?;
        check_name(&value, "sizing", &SIZINGS.map(Sizing::name))?;
        let defaults: Self = value
            .try_into()
            .map_err(|e: toml::de::Error| format!("[secrecy]: {}", e.message()))?;
        if let Some(b) = defaults.block_bits
            && !(MIN_BLOCK_BITS..=MAX_BLOCK_BITS).contains(&b)
        {
            return Err(format!(
                "[secrecy] block_bits = {b} is not allowed (allowed: {MIN_BLOCK_BITS} to \
                 {MAX_BLOCK_BITS})"
            ));
        }
        if let Some(e) = defaults.epsilon
            && !(e > 0.0 && e < 1.0)
        {
            return Err(format!(
                "[secrecy] epsilon = {e} is not allowed (allowed: (0, 1))"
            ));
        }
        Ok(defaults)
    }
}

impl Experiment {
    /// Replicates per point (`run.replicates`, the same at every point).
    #[must_use]
    pub fn replicates(&self) -> u32 {
        self.points[0].config.run.replicates
    }

    /// Total number of runs.
    #[must_use]
    pub fn runs(&self) -> usize {
        self.points.len() * self.replicates() as usize
    }

    /// Builds an experiment from a configuration table with an optional `[sweep]` table.
    ///
    /// # Errors
    /// Named errors for bad axes (unknown field, empty, unequal zip lengths, bad range)
    /// and for any point whose configuration is invalid.
    pub fn from_table(name: &str, mut table: toml::Table, origin: &str) -> Result<Self, LabError> {
        let sweep_error = |message: String| LabError::Sweep {
            origin: origin.to_owned(),
            message,
        };
        let sweep = match table.remove("sweep") {
            None => toml::Table::new(),
            Some(toml::Value::Table(t)) => t,
            Some(other) => return Err(sweep_error(format!("must be a table, found {other}"))),
        };
        let secrecy = table
            .remove("secrecy")
            .map(SecrecyDefaults::from_value)
            .transpose()
            .map_err(sweep_error)?
            .unwrap_or_default();
        let mut mode = Mode::Cartesian;
        let mut traces = false;
        let mut axes = Vec::new();
        for (key, value) in sweep {
            match (key.as_str(), value) {
                ("mode", toml::Value::String(m)) => {
                    mode = match m.as_str() {
                        "cartesian" => Mode::Cartesian,
                        "zip" => Mode::Zip,
                        _ => {
                            return Err(sweep_error(format!(
                                "mode = {m:?} (allowed: \"cartesian\", \"zip\")"
                            )));
                        }
                    }
                }
                ("traces", toml::Value::Boolean(b)) => traces = b,
                ("mode" | "traces", v) => {
                    return Err(sweep_error(format!("`{key}` = {v} has the wrong type")));
                }
                (_, value) => axes.push(Axis {
                    values: axis_values(&key, value).map_err(sweep_error)?,
                    field: key,
                }),
            }
        }
        if let (Mode::Zip, Some(first)) = (mode, axes.first())
            && let Some(other) = axes.iter().find(|a| a.values.len() != first.values.len())
        {
            return Err(sweep_error(format!(
                "zip axes differ in length: `{}` has {}, `{}` has {}",
                first.field,
                first.values.len(),
                other.field,
                other.values.len()
            )));
        }
        let points = grid(&axes, mode)
            .into_iter()
            .map(|params| {
                let mut point_table = table.clone();
                for (field, value) in &params {
                    set_path(&mut point_table, field, value.clone())
                        .map_err(|e| sweep_error(format!("axis `{field}`: {e}")))?;
                }
                let where_ = if params.is_empty() {
                    origin.to_owned()
                } else {
                    format!("{origin} at {}", describe(&params))
                };
                let config = Config::from_table(point_table, &where_)?;
                Ok(Point { params, config })
            })
            .collect::<Result<Vec<_>, LabError>>()?;
        let replicates = points[0].config.run.replicates;
        if points.iter().any(|p| p.config.run.replicates != replicates) {
            return Err(sweep_error(
                "run.replicates must be the same at every point".into(),
            ));
        }
        Ok(Self {
            name: name.to_owned(),
            axes,
            mode,
            traces,
            points,
            secrecy,
        })
    }

    /// The resolved definition as TOML: every config field explicit (at point 0), and the
    /// sweep with explicit value lists. Loading it gives the same grid.
    #[must_use]
    pub fn resolved_toml(&self) -> String {
        let mut out = self.points[0].config.to_toml();
        if !self.axes.is_empty() || self.traces {
            let mut sweep = toml::Table::new();
            if self.mode == Mode::Zip {
                sweep.insert("mode".into(), "zip".into());
            }
            if self.traces {
                sweep.insert("traces".into(), true.into());
            }
            for axis in &self.axes {
                sweep.insert(axis.field.clone(), toml::Value::Array(axis.values.clone()));
            }
            let mut wrapper = toml::Table::new();
            wrapper.insert("sweep".into(), toml::Value::Table(sweep));
            out.push('\n');
            out.push_str(&toml::to_string(&wrapper).expect("a sweep table serializes"));
        }
        if self.secrecy != SecrecyDefaults::default() {
            let mut wrapper = toml::Table::new();
            wrapper.insert(
                "secrecy".into(),
                toml::Value::try_from(self.secrecy).expect("secrecy defaults serialize"),
            );
            out.push('\n');
            out.push_str(&toml::to_string(&wrapper).expect("a secrecy table serializes"));
        }
        out
    }
}

/// How people read a swept field: its name, its unit, and the factor from config units.
struct Reading {
    name: &'static str,
    unit: &'static str,
    scale: f64,
}

fn reading(field: &str) -> Option<Reading> {
    let (name, unit, scale) = match field {
        "protocol.delta_v" => ("Δv", "m/s", 1.0),
        "protocol.delta_omega" => ("Δω", "rad/s", 1.0),
        "protocol.bits_per_doublet" => ("bits per doublet", "", 1.0),
        "protocol.levels" => ("levels per dimension", "", 1.0),
        "eve.alpha" => ("Eve's model error α", "%", 100.0),
        "eve.camera_std" => ("Eve's camera noise", "mm", 1e3),
        "eve.camera_fps" => ("Eve's stated camera rate", "frames/s", 1.0),
        "eve.camera_frame_std" => ("Eve's stated noise per frame", "mm", 1e3),
        "noise.process_std" => ("motion noise", "mm", 1e3),
        "sensing.controller_std" => ("controller sensor noise", "mm", 1e3),
        "world.process_std" => ("true motion noise", "mm", 1e3),
        "world.process_rho" => ("motion noise correlation ρ", "", 1.0),
        "world.slip_std" => ("wheel slip", "%", 100.0),
        "world.lag" => ("actuator lag", "ms", 1e3),
        "world.delay" => ("transport delay", "ms", 1e3),
        "world.jitter" => ("sample jitter", "ms", 1e3),
        "world.command_quantum" => ("command resolution", "rad/s", 1.0),
        "world.encoder_quantum" => ("encoder resolution", "mrad", 1e3),
        "world.controller_std" => ("true controller sensor noise", "mm", 1e3),
        "world.camera_fps" => ("Eve's camera rate", "frames/s", 1.0),
        "world.camera_frame_std" => ("Eve's noise per frame", "mm", 1e3),
        _ => return None,
    };
    Some(Reading { name, unit, scale })
}

/// A parameter value as a number in the units people read (`field`'s scale; the first
/// component of an array), if numeric.
#[must_use]
pub fn param_number(field: &str, value: &toml::Value) -> Option<f64> {
    let first = match value {
        toml::Value::Array(a) => a.first()?,
        other => other,
    };
    let x = first
        .as_float()
        .or_else(|| first.as_integer().map(|i| i as f64))?;
    Some(x * reading(field).map_or(1.0, |r| r.scale))
}

/// An axis label with its unit, e.g. "Δv (m/s)"; the field itself when unknown.
#[must_use]
pub fn axis_label(field: &str) -> String {
    match reading(field) {
        Some(r) if r.unit.is_empty() => r.name.to_owned(),
        Some(r) => format!("{} ({})", r.name, r.unit),
        None => field.to_owned(),
    }
}

/// A parameter for a legend, e.g. "motion noise 4 mm"; `field = value` when unknown.
#[must_use]
pub fn param_label(field: &str, value: &toml::Value) -> String {
    match (reading(field), param_number(field, value)) {
        (Some(r), Some(x)) if r.unit.is_empty() => format!("{x} {}", r.name),
        (Some(r), Some(x)) => format!("{} {x} {}", r.name, r.unit),
        _ => format!("{field} = {}", value_text(value)),
    }
}

/// `field = value, …` for messages.
#[must_use]
pub fn describe(params: &[(String, toml::Value)]) -> String {
    params
        .iter()
        .map(|(f, v)| format!("{f} = {}", value_text(v)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A parameter value as plain text (strings unquoted, floats in shortest round-trip form).
#[must_use]
pub fn value_text(value: &toml::Value) -> String {
    match value {
        toml::Value::String(s) => s.clone(),
        toml::Value::Float(x) => x.to_string(),
        other => other.to_string(),
    }
}

fn axis_values(field: &str, value: toml::Value) -> Result<Vec<toml::Value>, String> {
    let values = match value {
        toml::Value::Array(values) => values,
        toml::Value::Table(range) => range_values(field, &range)?,
        other => {
            return Err(format!(
                "axis `{field}` = {other}: expected a list of values or {{ start, stop, step }}"
            ));
        }
    };
    if values.is_empty() {
        return Err(format!("axis `{field}` is empty"));
    }
    Ok(values)
}

/// Expands `{ start, stop, step }` (stop included within rounding); all-integer ranges
/// stay integers, float values are rounded to 12 decimals so 0.02 + 6·0.0025 = 0.035.
fn range_values(field: &str, range: &toml::Table) -> Result<Vec<toml::Value>, String> {
    let bad = |why: &str| {
        format!(
            "axis `{field}`: {why} (expected {{ start, stop, step }} with step > 0, stop ≥ start)"
        )
    };
    if let Some(extra) = range
        .keys()
        .find(|k| !["start", "stop", "step"].contains(&k.as_str()))
    {
        return Err(bad(&format!("unknown key `{extra}`")));
    }
    let get = |key: &str| {
        range
            .get(key)
            .ok_or_else(|| bad(&format!("missing `{key}`")))
    };
    let (start, stop, step) = (get("start")?, get("stop")?, get("step")?);
    let as_f64 = |v: &toml::Value| v.as_float().or_else(|| v.as_integer().map(|i| i as f64));
    let (Some(a), Some(b), Some(s)) = (as_f64(start), as_f64(stop), as_f64(step)) else {
        return Err(bad("non-numeric bound"));
    };
    if !(s > 0.0 && b >= a && a.is_finite() && b.is_finite()) {
        return Err(bad("bad bounds"));
    }
    let count = ((b - a) / s + 1e-9).floor() as usize + 1;
    if count > 1_000_000 {
        return Err(bad("more than 1,000,000 values"));
    }
    let integers = [start, stop, step].iter().all(|v| v.is_integer());
    Ok((0..count)
        .map(|i| {
            let x = a + i as f64 * s;
            if integers {
                toml::Value::Integer(x.round() as i64)
            } else {
                toml::Value::Float((x * 1e12).round() / 1e12)
            }
        })
        .collect())
}

fn grid(axes: &[Axis], mode: Mode) -> Vec<Vec<(String, toml::Value)>> {
    match mode {
        Mode::Zip => {
            let len = axes.first().map_or(1, |a| a.values.len());
            (0..len)
                .map(|i| {
                    axes.iter()
                        .map(|a| (a.field.clone(), a.values[i].clone()))
                        .collect()
                })
                .collect()
        }
        Mode::Cartesian => axes.iter().fold(vec![Vec::new()], |acc, axis| {
            acc.iter()
                .flat_map(|prefix| {
                    axis.values.iter().map(move |v| {
                        let mut point = prefix.clone();
                        point.push((axis.field.clone(), v.clone()));
                        point
                    })
                })
                .collect()
        }),
    }
}

/// A file of experiments: either one experiment (config + optional `[sweep]`) or a suite
/// of `[experiment.NAME]` tables sharing the file's top-level config fields.
///
/// # Errors
/// As [`Experiment::from_table`], per experiment.
pub fn experiments_from_table(
    mut table: toml::Table,
    origin: &str,
) -> Result<Vec<Experiment>, LabError> {
    let Some(suite) = table.remove("experiment") else {
        return Ok(vec![Experiment::from_table("", table, origin)?]);
    };
    let toml::Value::Table(suite) = suite else {
        return Err(LabError::Sweep {
            origin: origin.to_owned(),
            message: "`experiment` must hold tables [experiment.NAME]".into(),
        });
    };
    suite
        .into_iter()
        .map(|(name, body)| {
            let toml::Value::Table(body) = body else {
                return Err(LabError::Sweep {
                    origin: origin.to_owned(),
                    message: format!("[experiment.{name}] must be a table"),
                });
            };
            let mut merged = table.clone();
            deep_merge(&mut merged, body);
            Experiment::from_table(&name, merged, &format!("{origin} [experiment.{name}]"))
        })
        .collect()
}

fn deep_merge(base: &mut toml::Table, overlay: toml::Table) {
    for (key, value) in overlay {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => deep_merge(b, o),
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn experiment(text: &str) -> Result<Experiment, LabError> {
        Experiment::from_table("t", text.parse().unwrap(), "test.toml")
    }

    #[test]
    fn ranges_include_the_stop_and_land_on_round_values() {
        let e = experiment(
            "[sweep]\n\"protocol.delta_v\" = { start = 0.02, stop = 0.045, step = 0.0025 }\n",
        )
        .unwrap();
        let values: Vec<f64> = e.points.iter().map(|p| p.config.protocol.delta_v).collect();
        assert_eq!(values.len(), 11);
        assert_eq!(values[6], 0.035);
        assert_eq!(values[10], 0.045);
    }

    #[test]
    fn cartesian_and_zip_grids() {
        let e = experiment(
            "[sweep]\n\"controller.kp\" = [1.0, 1.1]\n\"controller.kd\" = [0.7, 0.8, 0.9]\n",
        )
        .unwrap();
        assert_eq!(e.points.len(), 6);
        assert_eq!(
            (
                e.points[1].config.controller.kp,
                e.points[1].config.controller.kd
            ),
            (1.0, 0.8)
        );
        let z = experiment("[sweep]\nmode = \"zip\"\n\"controller.kp\" = [1.0, 1.1]\n\"controller.kd\" = [0.7, 0.8]\n").unwrap();
        assert_eq!(z.points.len(), 2);
        assert_eq!(z.points[1].config.controller.kd, 0.8);
    }

    #[test]
    fn the_secrecy_table_states_reconciliation_and_sizing_or_is_refused_by_name() {
        let e =
            experiment("[secrecy]\nreconciliation = \"ldpc\"\nsizing = \"measured\"\n").unwrap();
        assert_eq!(e.secrecy.reconciliation, Some(Reconciliation::Ldpc));
        assert_eq!(e.secrecy.sizing, Some(Sizing::Measured));
        let resolved = e.resolved_toml();
        assert!(
            resolved.contains("reconciliation = \"ldpc\"")
                && resolved.contains("sizing = \"measured\""),
            "{resolved}"
        );
        assert_eq!(experiment("").unwrap().secrecy.reconciliation, None);
        let err = experiment("[secrecy]\nreconciliation = \"turbo\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("test.toml")
                && err.contains("[secrecy] reconciliation = \"turbo\" is not allowed")
                && err.contains("(allowed: \"cascade\", \"ldpc\")"),
            "{err}"
        );
        let err = experiment("[secrecy]\nsizing = 1\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("[secrecy] sizing = 1 is not allowed")
                && err.contains("\"configured\", \"measured\", \"world\""),
            "{err}"
        );
    }

    #[test]
    fn bad_sweeps_have_named_errors() {
        let err = experiment("[sweep]\n\"controller.gain\" = [1.0]\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("test.toml") && err.contains("controller.gain") && err.contains("gain"),
            "{err}"
        );
        let err = experiment("[sweep]\n\"controller.kp\" = []\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("`controller.kp` is empty"), "{err}");
        let err = experiment(
            "[sweep]\nmode = \"zip\"\n\"controller.kp\" = [1.0]\n\"controller.kd\" = [0.7, 0.8]\n",
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("zip axes differ in length"), "{err}");
        let err = experiment("[sweep]\n\"protocol.delta_v\" = [0.0]\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("protocol.delta_v = 0") && err.contains("> 0"),
            "{err}"
        );
    }

    #[test]
    fn resolved_toml_reloads_to_the_same_grid() {
        let e = experiment("[run]\nreplicates = 2\n[sweep]\n\"eve.alpha\" = { start = 0, stop = 0.1, step = 0.05 }\n").unwrap();
        let again = experiment(&e.resolved_toml()).unwrap();
        assert_eq!(again.points.len(), 3);
        assert_eq!(again.resolved_toml(), e.resolved_toml());
        assert_eq!(again.replicates(), 2);
    }

    #[test]
    fn suites_share_top_level_fields() {
        let text = "[run]\nreplicates = 3\n[experiment.a]\nprotocol.delta_v = 0.02\n[experiment.b.sweep]\n\"eve.alpha\" = [0.0, 0.1]\n";
        let suite = experiments_from_table(text.parse().unwrap(), "s.toml").unwrap();
        assert_eq!(suite.len(), 2);
        assert_eq!(suite[0].points[0].config.protocol.delta_v, 0.02);
        assert_eq!(suite[1].points.len(), 2);
        assert!(suite.iter().all(|e| e.replicates() == 3));
    }
}
