//! Which value of each controller setting a run uses, and where it came from: the command
//! line, then the scenario file, then the robot file, then the built-in default.
//!
//! One precedence for every layered setting (`K_P`, `K_D`, `p1`, `p2`, and for `simulate`
//! the control period, duration, set point, filter, safety mode, record period and plant
//! robot):
//!
//! | source | example |
//! |---|---|
//! | command line | `softcbf simulate --p 20`, `softcbf run --kp 8` |
//! | scenario file | `[gains] p1 = 3` in `scenarios/x.toml` |
//! | robot file | `[barrier] p1 = 20`, `[gains] kp = 5` in `robots/x.toml` |
//! | built-in | the paper's `K_P = 5·I`, `K_D = 1·I`, `p1 = p2 = 10` |
//!
//! The first that gives a value wins; [`Sourced`] keeps which one it was, and
//! `summary.json` records both ([`SettingsReport`]).

use std::fmt;
use std::path::Path;

use serde::Serialize;
use softcbf_description::gains::{
    DEFAULT_BARRIER_GAINS, GainForm, PAPER_GAINS, scaled_identity, written_form,
};
use softcbf_description::limits::{self, Limit};
use softcbf_description::robot::Robot;

use crate::control::{ControllerSettings, SafetyMode};

/// Checks a number given for option `name` against its [`Limit`] (the same rule as the
/// description files): `--rate: must be ≥ 1 and ≤ 10000 Hz, got -33`.
pub fn check_number(name: &str, value: f64, limit: &Limit) -> Result<f64, String> {
    limit
        .check(value)
        .map_err(|message| format!("{name}: {message}"))
}

/// Where a setting's value came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// An option on the command line.
    CommandLine,
    /// The scenario file.
    Scenario,
    /// The robot file.
    RobotFile,
    /// The built-in default.
    BuiltIn,
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(match self {
            Source::CommandLine => "command line",
            Source::Scenario => "scenario",
            Source::RobotFile => "robot file",
            Source::BuiltIn => "built-in",
        })
    }
}

/// A value and where it came from.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Sourced<T> {
    /// The value used.
    pub value: T,
    /// Where it came from.
    pub source: Source,
}

impl<T> Sourced<T> {
    /// `value` from `source`.
    pub fn new(value: T, source: Source) -> Sourced<T> {
        Sourced { value, source }
    }
}

/// The first of `layers` that holds a value (they are given in precedence order), else
/// `default` as [`Source::BuiltIn`].
pub fn first<T, const N: usize>(layers: [(Option<T>, Source); N], default: T) -> Sourced<T> {
    layers
        .into_iter()
        .find_map(|(value, source)| value.map(|value| Sourced::new(value, source)))
        .unwrap_or(Sourced::new(default, Source::BuiltIn))
}

/// Gains given on the command line, each a number (`K_P`, `K_D` times the identity),
/// checked against the same ranges as the files'.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GainOptions {
    /// `--kp` \[N/m\].
    pub kp: Option<f64>,
    /// `--kd` \[N·s/m\].
    pub kd: Option<f64>,
    /// `--p1` (or `--p`) \[1/s\].
    pub p1: Option<f64>,
    /// `--p2` (or `--p`) \[1/s\].
    pub p2: Option<f64>,
}

impl GainOptions {
    /// Checks the options `--kp`, `--kd`, `--p` (both class-K gains), `--p1` and `--p2`;
    /// `--p` together with `--p1` or `--p2` is refused as ambiguous.
    pub fn checked(
        kp: Option<f64>,
        kd: Option<f64>,
        p: Option<f64>,
        p1: Option<f64>,
        p2: Option<f64>,
    ) -> Result<GainOptions, String> {
        GainOptions::checked_as(kp, kd, p, p1, p2, &|name| format!("--{name}"))
    }

    /// [`GainOptions::checked`] with the options spelled by `spell` in messages (`kp` as
    /// `--kp` on the command line, as the keyword `kp` from Python).
    pub fn checked_as(
        kp: Option<f64>,
        kd: Option<f64>,
        p: Option<f64>,
        p1: Option<f64>,
        p2: Option<f64>,
        spell: &dyn Fn(&str) -> String,
    ) -> Result<GainOptions, String> {
        if p.is_some() && (p1.is_some() || p2.is_some()) {
            return Err(format!(
                "{} sets both class-K gains; give either {} or {}/{}, not both",
                spell("p"),
                spell("p"),
                spell("p1"),
                spell("p2")
            ));
        }
        let check = |name: &str, value: Option<f64>, limit| {
            value
                .map(|v| check_number(&spell(name), v, limit))
                .transpose()
        };
        let p = check("p", p, &limits::BARRIER_GAIN_PER_S)?;
        Ok(GainOptions {
            kp: check("kp", kp, &limits::KP_N_PER_M)?,
            kd: check("kd", kd, &limits::KD_N_S_PER_M)?,
            p1: p.or(check("p1", p1, &limits::BARRIER_GAIN_PER_S)?),
            p2: p.or(check("p2", p2, &limits::BARRIER_GAIN_PER_S)?),
        })
    }
}

/// Gains a scenario file gives (checked; `K_P`, `K_D` as `nq × nq` row-major matrices).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ScenarioGains {
    /// `gains.kp`.
    pub kp: Option<Vec<f64>>,
    /// `gains.kd`.
    pub kd: Option<Vec<f64>>,
    /// `gains.p1`.
    pub p1: Option<f64>,
    /// `gains.p2`.
    pub p2: Option<f64>,
}

/// The gains a run uses, each with its source.
#[derive(Clone, Debug, PartialEq)]
pub struct Gains {
    /// `K_P`, `nq × nq` row-major \[N/m\].
    pub kp: Sourced<Vec<f64>>,
    /// `K_D`, `nq × nq` row-major \[N·s/m\].
    pub kd: Sourced<Vec<f64>>,
    /// HOCBF class-K gain `p1` \[1/s\].
    pub p1: Sourced<f64>,
    /// HOCBF class-K gain `p2` \[1/s\].
    pub p2: Sourced<f64>,
}

/// The gains for `robot` by the one precedence: `command_line`, `scenario`, the robot
/// file, the built-in paper gains.
pub fn resolve_gains(command_line: &GainOptions, scenario: &ScenarioGains, robot: &Robot) -> Gains {
    let nq = 3 * robot.modules.len();
    let identity = |k: Option<f64>| k.map(|k| scaled_identity(nq, k));
    let (kp, kd) = PAPER_GAINS;
    let [p1, p2] = DEFAULT_BARRIER_GAINS;
    Gains {
        kp: first(
            [
                (identity(command_line.kp), Source::CommandLine),
                (scenario.kp.clone(), Source::Scenario),
                (robot.gains.kp.clone(), Source::RobotFile),
            ],
            scaled_identity(nq, kp),
        ),
        kd: first(
            [
                (identity(command_line.kd), Source::CommandLine),
                (scenario.kd.clone(), Source::Scenario),
                (robot.gains.kd.clone(), Source::RobotFile),
            ],
            scaled_identity(nq, kd),
        ),
        p1: first(
            [
                (command_line.p1, Source::CommandLine),
                (scenario.p1, Source::Scenario),
                (robot.barrier[0], Source::RobotFile),
            ],
            p1,
        ),
        p2: first(
            [
                (command_line.p2, Source::CommandLine),
                (scenario.p2, Source::Scenario),
                (robot.barrier[1], Source::RobotFile),
            ],
            p2,
        ),
    }
}

impl Gains {
    /// Controller settings with these gains, every other field at its default
    /// ([`ControllerSettings::new`]); a run sets its filter, safety mode and hold over them.
    pub fn controller_settings(&self) -> ControllerSettings {
        ControllerSettings::new(
            self.kp.value.clone(),
            self.kd.value.clone(),
            [self.p1.value, self.p2.value],
        )
    }

    /// The gains as `summary.json` records them (`K_P`, `K_D` in their shortest form).
    pub fn report(&self, nq: usize) -> GainsReport {
        let form = |k: &Sourced<Vec<f64>>| Sourced::new(written_form(&k.value, nq), k.source);
        GainsReport {
            kp: form(&self.kp),
            kd: form(&self.kd),
            p1: self.p1.clone(),
            p2: self.p2.clone(),
        }
    }
}

/// The gains of a run as recorded: `K_P`, `K_D` as a number (times the identity), a
/// diagonal or rows.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GainsReport {
    /// `K_P` \[N/m\].
    pub kp: Sourced<GainForm>,
    /// `K_D` \[N·s/m\].
    pub kd: Sourced<GainForm>,
    /// `p1` \[1/s\].
    pub p1: Sourced<f64>,
    /// `p2` \[1/s\].
    pub p2: Sourced<f64>,
}

/// A description file by its name and where it was read from.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Described {
    /// The name the file gives (else its stem).
    pub name: String,
    /// The path as given, or `<embedded …>` for a built-in file.
    pub file: String,
}

/// Integrator tolerances as recorded.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IntegratorReport {
    /// Relative tolerance.
    pub rtol: f64,
    /// Absolute tolerance \[m, m/s\].
    pub atol: f64,
    /// First step tried \[s\].
    pub h_initial: f64,
    /// Most step attempts within one tick.
    pub max_steps: usize,
}

/// Every setting a run used, with its source: what `summary.json` records under
/// `settings` and the `settings:` line shows.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SettingsReport {
    /// `softcbf` and its version.
    pub software: String,
    /// The robot.
    pub robot: Described,
    /// The scenario (`None` for a hardware run).
    pub scenario: Option<Described>,
    /// Whether the safety filter ran.
    pub filter: Sourced<bool>,
    /// `K_P`, `K_D`, `p1`, `p2`.
    #[serde(flatten)]
    pub gains: GainsReport,
    /// Which rows kept the barriers: the paper's, the hold correction or the sampled-data
    /// guarantee (docs/model.md §5).
    pub safety: Sourced<SafetyMode>,
    /// Control period \[s\] (for a hardware run: one over the loop rate asked for).
    pub control_period: Sourced<f64>,
    /// Duration asked for \[s\] (`None`: until stopped).
    pub duration: Option<Sourced<f64>>,
    /// The set point or waypoints, and where they came from.
    pub reference: Sourced<String>,
    /// Integrator tolerances (simulation only).
    pub integrator: Option<IntegratorReport>,
    /// Time between recorded rows \[s\] of a simulation that records between ticks
    /// (`None`: one row per tick, and for a hardware run).
    pub record_period: Option<Sourced<f64>>,
    /// The robot whose physics a simulation integrates, when it is not the controller's
    /// (`None`: the plant is the robot above).
    pub plant: Option<Sourced<Described>>,
    /// The noise on the state the controller samples (not written without noise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sensor_noise: Option<NoiseReport>,
}

/// The sensor noise of a simulation: standard deviations on `q` \[m\] and `q̇` \[m/s\]
/// and the seed of its draws.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct NoiseReport {
    pub q: f64,
    pub qd: f64,
    pub seed: u64,
}

/// How a settings report names a file: its absolute path, so that a later `softcbf plot`
/// from another folder finds it; a built-in file (`<embedded …>`) by that name.
pub fn file_name(path: &Path) -> String {
    if path.to_string_lossy().starts_with('<') {
        return path.display().to_string();
    }
    std::path::absolute(path)
        .unwrap_or_else(|_| path.to_path_buf())
        .display()
        .to_string()
}

/// `softcbf <version>`.
pub fn software() -> String {
    format!("softcbf {}", env!("CARGO_PKG_VERSION"))
}

impl SettingsReport {
    /// The one line that says what ran, e.g. `settings: softcbf 0.1.0; robot paper-sim
    /// (<embedded robots/paper-sim.toml>); … K_P = 5 (built-in), … p1 = 20 (robot file) …`.
    pub fn line(&self) -> String {
        let g = &self.gains;
        let mut parts = vec![self.software.clone()];
        parts.push(format!("robot {} ({})", self.robot.name, self.robot.file));
        if let Some(scenario) = &self.scenario {
            parts.push(format!("scenario {} ({})", scenario.name, scenario.file));
        }
        let on = |b: bool| if b { "on" } else { "off" };
        parts.push(format!(
            "filter {} ({})",
            on(self.filter.value),
            self.filter.source
        ));
        parts.push(format!(
            "K_P = {} ({}), K_D = {} ({}), p1 = {} ({}), p2 = {} ({})",
            g.kp.value,
            g.kp.source,
            g.kd.value,
            g.kd.source,
            limits::short(g.p1.value),
            g.p1.source,
            limits::short(g.p2.value),
            g.p2.source
        ));
        parts.push(format!(
            "safety {} ({})",
            self.safety.value, self.safety.source
        ));
        parts.push(format!(
            "control period {} s ({})",
            limits::short(self.control_period.value),
            self.control_period.source
        ));
        if let Some(duration) = &self.duration {
            parts.push(format!(
                "duration {} s ({})",
                limits::short(duration.value),
                duration.source
            ));
        }
        parts.push(format!(
            "reference {} ({})",
            self.reference.value, self.reference.source
        ));
        if let Some(period) = &self.record_period {
            parts.push(format!(
                "recorded every {} ({})",
                period_text(period.value),
                period.source
            ));
        }
        if let Some(plant) = &self.plant {
            parts.push(format!(
                "plant {} ({}) ({})",
                plant.value.name, plant.value.file, plant.source
            ));
        }
        if let Some(noise) = &self.sensor_noise {
            parts.push(format!(
                "sensor noise σ_q = {} m, σ_q̇ = {} m/s (seed {})",
                limits::short(noise.q),
                limits::short(noise.qd),
                noise.seed
            ));
        }
        if let Some(i) = &self.integrator {
            parts.push(format!(
                "rtol {}, atol {}",
                limits::short(i.rtol),
                limits::short(i.atol)
            ));
        }
        format!("settings: {}", parts.join("; "))
    }
}

/// A period \[s\] in milliseconds or, below one, microseconds, rounded to nine
/// significant digits: `1 ms`, `0.5 ms`… `250 µs`.
pub fn period_text(seconds: f64) -> String {
    let (value, unit) = if seconds >= 1e-3 {
        (seconds * 1e3, "ms")
    } else {
        (seconds * 1e6, "µs")
    };
    let rounded: f64 = format!("{value:.9e}").parse().unwrap_or(value);
    format!("{} {unit}", limits::short(rounded))
}

/// A short form of a vector for the settings line: `[0.08, 0, -0.05, …]`.
pub fn vector_text(values: &[f64]) -> String {
    let items: Vec<String> = values.iter().map(|v| limits::short(*v)).collect();
    format!("[{}]", items.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn robot(text: &str) -> Robot {
        let base = "[[module]]\n[[module]]\n";
        Robot::parse(&format!("{text}\n{base}"), "r.toml".as_ref()).unwrap()
    }

    #[test]
    fn the_built_in_gains_are_the_papers_and_build_the_paper_controller() {
        // The paper's simulation gains: K_P = 5·I, K_D = 1·I; p1 = p2 = 10 by default.
        let robot = robot("");
        let gains = resolve_gains(&GainOptions::default(), &ScenarioGains::default(), &robot);
        let nq = 6;
        let identity = |k: f64| {
            (0..nq * nq)
                .map(|i| if i % (nq + 1) == 0 { k } else { 0.0 })
                .collect::<Vec<_>>()
        };
        assert_eq!(gains.kp, Sourced::new(identity(5.0), Source::BuiltIn));
        assert_eq!(gains.kd, Sourced::new(identity(1.0), Source::BuiltIn));
        assert_eq!(
            (gains.p1.value, gains.p2.value),
            (10.0, 10.0),
            "the robot's default barrier gains"
        );
        // The paper's robot (two modules, as `robot("")`) writes the same gains.
        let model = crate::model::Model::new(crate::robot_file::load_robot(None).unwrap()).unwrap();
        assert_eq!(
            gains.controller_settings(),
            ControllerSettings::paper(&model)
        );
    }

    #[test]
    fn the_first_layer_that_gives_a_value_wins() {
        let chosen = first(
            [(None, Source::CommandLine), (Some(3.0), Source::Scenario)],
            1.0,
        );
        assert_eq!(chosen, Sourced::new(3.0, Source::Scenario));
        let none: Sourced<f64> = first([(None, Source::CommandLine)], 1.0);
        assert_eq!(none, Sourced::new(1.0, Source::BuiltIn));
    }

    #[test]
    fn command_line_then_scenario_then_robot_then_built_in() {
        let robot = robot("[barrier]\np1 = 20.0\np2 = 20.0\n[gains]\nkp = 7.0\n");
        let nq = 6;
        let none = resolve_gains(&GainOptions::default(), &ScenarioGains::default(), &robot);
        assert_eq!(none.p1, Sourced::new(20.0, Source::RobotFile));
        assert_eq!(none.kp.source, Source::RobotFile);
        assert_eq!(none.kp.value[0], 7.0);
        assert_eq!(
            none.kd,
            Sourced::new(scaled_identity(nq, 1.0), Source::BuiltIn)
        );

        let scenario = ScenarioGains {
            p1: Some(3.0),
            kd: Some(scaled_identity(nq, 2.0)),
            ..ScenarioGains::default()
        };
        let from_scenario = resolve_gains(&GainOptions::default(), &scenario, &robot);
        assert_eq!(from_scenario.p1, Sourced::new(3.0, Source::Scenario));
        assert_eq!(from_scenario.p2, Sourced::new(20.0, Source::RobotFile));
        assert_eq!(from_scenario.kd.source, Source::Scenario);

        let options = GainOptions::checked(Some(9.0), None, Some(4.0), None, None).unwrap();
        let from_options = resolve_gains(&options, &scenario, &robot);
        assert_eq!(from_options.p1, Sourced::new(4.0, Source::CommandLine));
        assert_eq!(from_options.p2, Sourced::new(4.0, Source::CommandLine));
        assert_eq!(from_options.kp.value[7], 9.0);
        assert_eq!(from_options.kp.source, Source::CommandLine);
        assert_eq!(from_options.kd.source, Source::Scenario);

        let plain = robot_without_gains();
        let built_in = resolve_gains(&GainOptions::default(), &ScenarioGains::default(), &plain);
        assert_eq!(built_in.p1, Sourced::new(10.0, Source::BuiltIn));
        assert_eq!(built_in.kp.source, Source::BuiltIn);
    }

    fn robot_without_gains() -> Robot {
        robot("")
    }

    #[test]
    fn options_are_checked_against_the_files_ranges() {
        let error = GainOptions::checked(None, None, Some(-1.0), None, None).unwrap_err();
        assert!(error.starts_with("--p: must be"), "{error}");
        let error = GainOptions::checked(Some(2e6), None, None, None, None).unwrap_err();
        assert!(error.starts_with("--kp: must be"), "{error}");
        let error = GainOptions::checked(None, None, Some(1.0), Some(2.0), None).unwrap_err();
        assert!(error.contains("either --p or --p1/--p2"), "{error}");
        let split = GainOptions::checked(None, None, None, Some(2.0), None).unwrap();
        assert_eq!((split.p1, split.p2), (Some(2.0), None));
    }

    #[test]
    fn periods_are_written_in_milliseconds_or_microseconds() {
        assert_eq!(period_text(1e-3), "1 ms");
        assert_eq!(period_text(0.0303), "30.3 ms");
        assert_eq!(period_text(3e-4), "300 µs");
        assert_eq!(period_text(1e-6), "1 µs");
        assert_eq!(period_text(1.0), "1000 ms");
    }

    #[test]
    fn gains_are_recorded_in_the_shortest_written_form() {
        let robot = robot(
            "[gains]\nkp = [1, 2, 3, 4, 5, 6]\nkd = [[1, 0, 0, 0, 0, 0], [0.5, 1, 0, 0, 0, 0], [0, 0, 1, 0, 0, 0], [0, 0, 0, 1, 0, 0], [0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1]]\n",
        );
        let gains = resolve_gains(&GainOptions::default(), &ScenarioGains::default(), &robot);
        let report = gains.report(6);
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(
            json["kp"]["value"],
            serde_json::json!([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
        );
        assert_eq!(json["kp"]["source"], "robot_file");
        assert_eq!(json["kd"]["value"][1][0], 0.5);
        assert_eq!(json["p1"]["value"], 10.0);
        assert_eq!(json["p1"]["source"], "built_in");
        assert_eq!(report.kp.value.to_string(), "diag[1, 2, 3, 4, 5, 6]");
    }
}
