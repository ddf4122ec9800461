//! The `[verify]` table of a scenario file: how many runs, the seed, the boxes set points
//! and initial states are drawn from, parameter errors, sensor noise, and the safety modes
//! and control periods compared; read and checked once, errors naming file, line and field.

use softcbf_description::limits::{self, Limit};
use softcbf_description::uncertainty::ModuleFactors;
use toml::Spanned;

use crate::control::SafetyMode;
use crate::model::Model;
use crate::noise::{SEED, SENSOR_NOISE_M, SENSOR_NOISE_M_PER_S};
use crate::scenario::{
    Overrides, RawVector, RawVerify, Scenario, ScenarioError, ScenarioFile, state_vector,
};
use crate::start::StartSet;

/// Default number of runs.
pub const DEFAULT_RUNS: usize = 1000;
/// Default time between the rows the lowest barrier is taken over \[s\]: every
/// millisecond, and at every tick of a faster loop.
pub const DEFAULT_RECORD_PERIOD: f64 = 1e-3;
/// Default threshold: a run whose lowest barrier falls below it is unsafe (m or rad): the
/// tolerance within which a barrier counts as held at zero, the figures' too
/// ([`softcbf_description::limits::BARRIER_TOLERANCE_M`]).
pub const DEFAULT_THRESHOLD: f64 = softcbf_description::limits::DEFAULT_SIMULATION_THRESHOLD;
/// Draws of an initial state before giving up on finding one the guarantee covers
/// ([`StartSet`]).
pub const INITIAL_STATE_TRIES: usize = 1000;

/// A box `min ≤ x ≤ max`, per coordinate.
#[derive(Clone, Debug, PartialEq)]
pub struct Bounds {
    /// Lower corner.
    pub min: Vec<f64>,
    /// Upper corner.
    pub max: Vec<f64>,
}

/// One safety mode at one control period, and the scenario its runs start from.
#[derive(Clone, Debug)]
pub struct Group {
    /// The filter's safety mode.
    pub safety: SafetyMode,
    /// The control period \[s\].
    pub control_period: f64,
    /// The scenario with this mode and period (reference, initial state and plant are
    /// replaced per run).
    pub scenario: Scenario,
}

impl Group {
    /// `sampled @ 33.3 Hz`: how figures and the report name the group.
    pub fn name(&self) -> String {
        group_name(self.safety.name(), self.control_period)
    }
}

/// `mode @ rate`, the rate in Hz with as many digits as it needs.
pub fn group_name(safety: &str, control_period: f64) -> String {
    let hz = 1.0 / control_period;
    let rate = if (hz - hz.round()).abs() < 1e-6 * hz {
        format!("{hz:.0}")
    } else {
        format!("{hz:.1}")
    };
    format!("{safety} @ {rate} Hz")
}

/// A checked `[verify]` table with the scenario it belongs to.
#[derive(Clone, Debug)]
pub struct VerifySpec {
    /// The scenario file as given (for replay commands and shard manifests).
    pub file: String,
    /// A fingerprint of the scenario and robot files (shards of one batch share it).
    pub fingerprint: String,
    /// Runs in the batch.
    pub runs: usize,
    /// The batch's seed.
    pub seed: u64,
    /// Where set points are drawn (`None`: the scenario's reference for every run).
    pub set_point: Option<Bounds>,
    /// Where initial `q` and `q̇` are drawn (`None`: the scenario's).
    pub initial_q: Option<Bounds>,
    pub initial_qd: Option<Bounds>,
    /// Whether the plant's stiffness, damping and mass are drawn in the robot file's
    /// `[uncertainty]` box.
    pub parameter_errors: bool,
    /// Standard deviation of the noise on the sampled `q` \[m\] and `q̇` \[m/s\].
    pub sensor_noise: [f64; 2],
    /// A run whose lowest barrier falls below this is unsafe (m or rad).
    pub threshold: f64,
    /// The safety modes × control periods; run `i` belongs to group `i mod groups`.
    pub groups: Vec<Group>,
    /// The initial states the guarantee covers: every drawn start lies in it.
    pub start: StartSet,
}

/// What the command line changes in `[verify]`.
#[derive(Clone, Debug, Default)]
pub struct VerifyOverrides {
    /// `--runs`.
    pub runs: Option<usize>,
    /// `--seed`.
    pub seed: Option<u64>,
    /// `--duration` \[s\].
    pub duration: Option<f64>,
}

/// Number of runs in a batch.
pub const RUNS: Limit = Limit::integer(1, 100_000_000);

impl VerifySpec {
    /// Reads and checks `file`'s `[verify]` table for `model` (a file without one verifies
    /// its own scenario with the defaults), the command line's `overrides` winning.
    pub fn from_file(
        file: &ScenarioFile,
        model: &Model,
        overrides: &VerifyOverrides,
        robot_text: &str,
    ) -> Result<VerifySpec, ScenarioError> {
        let c = file.checker();
        let empty = RawVerify::default();
        let raw = file.verify_table().unwrap_or(&empty);
        let number = |v: &Option<Spanned<f64>>, field: &str, limit: &Limit| {
            v.as_ref()
                .map(|v| c.within(v, &format!("verify.{field}"), limit))
                .transpose()
        };
        let integer = |v: &Option<Spanned<i64>>, field: &str, limit: &Limit| {
            v.as_ref()
                .map(|v| c.integer_within(v, &format!("verify.{field}"), limit))
                .transpose()
        };
        // Every value of the file is checked, also one the command line replaces.
        let file_runs = integer(&raw.runs, "runs", &RUNS)?;
        let file_seed = integer(&raw.seed, "seed", &SEED)?;
        let file_duration = number(&raw.duration, "duration", &limits::DURATION_S)?;
        let runs = overrides
            .runs
            .unwrap_or_else(|| file_runs.map_or(DEFAULT_RUNS, |n| n as usize));
        let seed = overrides
            .seed
            .unwrap_or_else(|| file_seed.map_or(1, |n| n as u64));
        let duration = overrides.duration.or(file_duration);
        let record_period = number(
            &raw.record_period,
            "record_period",
            &limits::RECORD_PERIOD_S,
        )?
        .unwrap_or(DEFAULT_RECORD_PERIOD);
        let threshold = number(&raw.threshold, "threshold", &limits::BARRIER_THRESHOLD_M)?
            .unwrap_or(DEFAULT_THRESHOLD);
        let sensor_noise = [
            number(&raw.sensor_noise_q, "sensor_noise_q", &SENSOR_NOISE_M)?.unwrap_or(0.0),
            number(
                &raw.sensor_noise_qd,
                "sensor_noise_qd",
                &SENSOR_NOISE_M_PER_S,
            )?
            .unwrap_or(0.0),
        ];

        let robot = &model.robot;
        let bounds = |min: &Option<RawVector>, max: &Option<RawVector>, name: &str, coordinates| {
            let (min_field, max_field) =
                (format!("verify.{name}_min"), format!("verify.{name}_max"));
            match (min, max) {
                (None, None) => Ok(None),
                (Some(v), None) => Err(c.invalid(
                    &v.span(),
                    &min_field,
                    format!("has no `{name}_max`: give both corners of the box"),
                )),
                (None, Some(v)) => Err(c.invalid(
                    &v.span(),
                    &max_field,
                    format!("has no `{name}_min`: give both corners of the box"),
                )),
                (Some(lo), Some(hi)) => {
                    let low = state_vector(&c, lo, &min_field, robot, coordinates)?;
                    let high = state_vector(&c, hi, &max_field, robot, coordinates)?;
                    for (k, (a, b)) in low.iter().zip(&high).enumerate() {
                        if a > b {
                            let span = hi.get_ref().get(k).map_or(hi.span(), Spanned::span);
                            return Err(c.invalid(
                                &span,
                                &max_field,
                                format!(
                                    "entry {} is {b}, below `{name}_min`'s {a}: the upper \
                                     corner must not lie below the lower one",
                                    k + 1
                                ),
                            ));
                        }
                    }
                    let bounds = Bounds {
                        min: low,
                        max: high,
                    };
                    if coordinates && let Some(problem) = corner_outside(robot, &bounds) {
                        return Err(c.invalid(&hi.span(), &max_field, problem));
                    }
                    Ok(Some(bounds))
                }
            }
        };
        let set_point = bounds(&raw.set_point_min, &raw.set_point_max, "set_point", true)?;
        let initial_q = bounds(&raw.initial_q_min, &raw.initial_q_max, "initial_q", true)?;
        let initial_qd = bounds(
            &raw.initial_qd_min,
            &raw.initial_qd_max,
            "initial_qd",
            false,
        )?;

        let parameter_errors = match &raw.parameter_errors {
            Some(flag) if *flag.get_ref() => {
                if !robot.uncertainty.is_declared() {
                    return Err(c
                        .invalid(
                            &flag.span(),
                            "verify.parameter_errors",
                            format!(
                                "the robot file {} declares no [uncertainty] to draw the \
                                 plant's numbers from; add one (docs/model.md §5) or set \
                                 this to false",
                                robot.source.display()
                            ),
                        )
                        .into());
                }
                true
            }
            _ => false,
        };

        let base = file.resolve(model)?;
        let safeties = match &raw.safety {
            None => vec![base.controller.safety],
            Some(list) => {
                if list.get_ref().is_empty() {
                    return Err(c
                        .invalid(
                            &list.span(),
                            "verify.safety",
                            "is empty: name at least one mode".into(),
                        )
                        .into());
                }
                let mut modes = Vec::new();
                for (k, name) in list.get_ref().iter().enumerate() {
                    let mode = SafetyMode::parse(name.get_ref()).map_err(|message| {
                        c.invalid(
                            &name.span(),
                            "verify.safety",
                            format!("entry {}: {message}", k + 1),
                        )
                    })?;
                    if modes.contains(&mode) {
                        return Err(c
                            .invalid(
                                &name.span(),
                                "verify.safety",
                                format!("entry {} repeats `{}`", k + 1, mode.name()),
                            )
                            .into());
                    }
                    modes.push(mode);
                }
                modes
            }
        };
        let periods = match &raw.control_periods {
            None => vec![base.control_period],
            Some(list) => {
                if list.get_ref().is_empty() {
                    return Err(c
                        .invalid(
                            &list.span(),
                            "verify.control_periods",
                            "is empty: give at least one period".into(),
                        )
                        .into());
                }
                let periods = c.list_within(
                    list.get_ref(),
                    "verify.control_periods",
                    &limits::CONTROL_PERIOD_S,
                )?;
                for (k, p) in periods.iter().enumerate() {
                    if periods[..k].contains(p) {
                        let span = list.get_ref()[k].span();
                        return Err(c
                            .invalid(
                                &span,
                                "verify.control_periods",
                                format!("entry {} repeats {p} s", k + 1),
                            )
                            .into());
                    }
                }
                periods
            }
        };
        let mut groups = Vec::new();
        for &control_period in &periods {
            for &safety in &safeties {
                let overrides = Overrides {
                    control_period: Some(control_period),
                    safety: Some(safety),
                    duration,
                    filter: Some(true),
                    record_period: (record_period < control_period).then_some(record_period),
                    ..Overrides::default()
                };
                let scenario = file.resolve_with(model, &overrides)?;
                groups.push(Group {
                    safety,
                    control_period,
                    scenario,
                });
            }
        }
        let start = StartSet::new(model, &base.controller).map_err(|message| {
            ScenarioError::Option(format!("the scenario's controller: {message}"))
        })?;
        Ok(VerifySpec {
            file: file.path().display().to_string(),
            fingerprint: fingerprint(&[file.text(), robot_text]),
            runs,
            seed,
            set_point,
            initial_q,
            initial_qd,
            parameter_errors,
            sensor_noise,
            threshold,
            groups,
            start,
        })
    }

    /// The factors of a plant with the nominal numbers, one per module.
    pub fn nominal_factors(model: &Model) -> Vec<ModuleFactors> {
        vec![ModuleFactors::NOMINAL; model.robot.modules.len()]
    }
}

/// The first corner of a coordinate box (each module's 8 corners, the other modules at
/// the box's centre) outside the robot's state domain, in words. The domain of one module
/// is convex, so a box whose corners lie in it lies in it whole.
fn corner_outside(robot: &softcbf_description::robot::Robot, bounds: &Bounds) -> Option<String> {
    let centre: Vec<f64> = bounds
        .min
        .iter()
        .zip(&bounds.max)
        .map(|(a, b)| 0.5 * (a + b))
        .collect();
    for module in 0..robot.modules.len() {
        for corner in 0..8 {
            let mut q = centre.clone();
            for axis in 0..3 {
                let k = 3 * module + axis;
                q[k] = if corner >> axis & 1 == 0 {
                    bounds.min[k]
                } else {
                    bounds.max[k]
                };
            }
            if let Some(problem) = softcbf_description::domain::coordinates_problem(robot, &q) {
                return Some(format!(
                    "the box's corner {} of module {} lies outside the robot's state domain: \
                     {problem}",
                    vector(&q[3 * module..3 * module + 3]),
                    module + 1
                ));
            }
        }
    }
    None
}

fn vector(v: &[f64]) -> String {
    let parts: Vec<String> = v.iter().map(|x| format!("{x}")).collect();
    format!("[{}]", parts.join(", "))
}

/// FNV-1a (64 bit) over `parts`, each followed by a zero byte, in hex: equal files give an
/// equal fingerprint on every machine.
pub fn fingerprint(parts: &[&str]) -> String {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for part in parts {
        for &byte in part.as_bytes().iter().chain(&[0u8]) {
            hash ^= u64::from(byte);
            hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    format!("{hash:016x}")
}
