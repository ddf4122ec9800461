//! What a simulation is told besides its scenario file, as the command line (`softcbf
//! simulate`'s options) or Python (`softcbf.simulate`'s keyword arguments) gives it, and its
//! checks: every number against the range of its scenario field, the set point against the
//! robot's coordinates and domain. Every error names the option as the caller spells it.

use std::path::PathBuf;

use softcbf_description::domain;
use softcbf_description::robot::Robot;

use crate::control::SafetyMode;
use crate::scenario::Overrides;
use crate::settings::{GainOptions, check_number};

/// What a simulation is told besides its scenario file, as given on the command line or as
/// Python keyword arguments, before any check. `None` keeps the scenario's value.
#[derive(Clone, Debug, Default)]
pub struct SimulateOptions {
    /// `K_P = kp·I` \[N/m\].
    pub kp: Option<f64>,
    /// `K_D = kd·I` \[N·s/m\].
    pub kd: Option<f64>,
    /// Both class-K gains \[1/s\].
    pub p: Option<f64>,
    /// Class-K gain `p1` \[1/s\].
    pub p1: Option<f64>,
    /// Class-K gain `p2` \[1/s\].
    pub p2: Option<f64>,
    /// The set point \[m\] replacing the scenario's reference.
    pub set_point: Option<Vec<f64>>,
    /// Simulated time \[s\].
    pub duration: Option<f64>,
    /// Control period \[s\].
    pub control_period: Option<f64>,
    /// Time between recorded rows \[s\].
    pub record_period: Option<f64>,
    /// The safety filter on or off.
    pub filter: Option<bool>,
    /// The safety mode.
    pub safety: Option<SafetyMode>,
    /// Also run plain PD+.
    pub compare: Option<bool>,
    /// The plant's robot file.
    pub plant: Option<PathBuf>,
}

/// Checks `options` for `robot`, each number against the range of its scenario field and
/// the set point against the robot's coordinates and domain, naming an option as `spell`
/// gives it (`--duration` on the command line, `duration` from Python).
pub fn check_simulate_options(
    options: SimulateOptions,
    robot: &Robot,
    spell: &dyn Fn(&str) -> String,
) -> Result<Overrides, String> {
    use softcbf_description::limits;
    let gains = GainOptions::checked_as(
        options.kp, options.kd, options.p, options.p1, options.p2, spell,
    )?;
    let check = |name: &str, value: Option<f64>, limit| {
        value
            .map(|v| check_number(&spell(name), v, limit))
            .transpose()
    };
    let set_point = match options.set_point {
        Some(values) => {
            let name = spell("set_point");
            let expected = 3 * robot.modules.len();
            if values.len() != expected {
                return Err(format!(
                    "{name}: {} values given, the robot has {expected} coordinates (3 per \
                     module: Δx, Δy, δL)",
                    values.len()
                ));
            }
            if let Some(k) = values.iter().position(|v| !v.is_finite()) {
                return Err(format!(
                    "{name}: entry {} is {}; values must be finite",
                    k + 1,
                    values[k]
                ));
            }
            if let Some(problem) = domain::coordinates_problem(robot, &values) {
                return Err(format!("{name}: {problem}"));
            }
            Some(values)
        }
        None => None,
    };
    Ok(Overrides {
        gains,
        set_point,
        duration: check("duration", options.duration, &limits::DURATION_S)?,
        control_period: check(
            "control_period",
            options.control_period,
            &limits::CONTROL_PERIOD_S,
        )?,
        record_period: check(
            "record_period",
            options.record_period,
            &limits::RECORD_PERIOD_S,
        )?,
        filter: options.filter,
        safety: options.safety,
        compare: options.compare,
        plant: options.plant,
    })
}
