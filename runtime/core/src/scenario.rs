//! Scenario files (`scenarios/*.toml`): what `softcbf simulate` runs — robot, initial
//! state, reference, gains, control period, duration, filter, integrator tolerances, how
//! densely the trajectory is recorded and, optionally, a separate plant robot.
//!
//! Parsing follows the robot files: serde reads values with their spans, then every value is
//! checked, and sizes are checked against the robot once it is known
//! ([`ScenarioFile::resolve`]); every error names the file, the line and the field. The
//! format is documented in `scenarios/README.md`.

use std::path::{Path, PathBuf};

use serde::Deserialize;
use softcbf_description::domain;
use softcbf_description::gains::{RawGain, gain};
use softcbf_description::limits::{self, Limit, short};
use softcbf_description::robot::Robot;
use softcbf_description::toml_file::{Checker, FileError};
use softcbf_description::uncertainty::{self, ModuleFactors, PlantError};
use toml::Spanned;

use crate::control::{ControllerSettings, SafetyMode};
use crate::integrator::Tolerances;
use crate::model::Model;
use crate::noise::SensorNoise;
use crate::reference::ReferenceSpec;
use crate::settings::{GainOptions, Gains, ScenarioGains, Source, Sourced, first, resolve_gains};

/// Text of `scenarios/paper-sim.toml`, compiled in as the default scenario.
pub const PAPER_SIM_SCENARIO: &str = include_str!("../../../scenarios/paper-sim.toml");
/// `scenarios/default.toml`: what a bare `softcbf simulate` runs (the paper's scenario with
/// the certified rows).
pub const DEFAULT_SCENARIO: &str = include_str!("../../../scenarios/default.toml");

/// A scenario ready to run against a model.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    /// Name (defaults to the file stem).
    pub name: String,
    /// Initial `q` \[m\].
    pub initial_q: Vec<f64>,
    /// Initial `q̇` \[m/s\].
    pub initial_qd: Vec<f64>,
    /// What the nominal controller tracks.
    pub reference: ReferenceSpec,
    /// Gains, barrier gains, filter and QP settings.
    pub controller: ControllerSettings,
    /// Control period \[s\].
    pub control_period: f64,
    /// Simulated time \[s\].
    pub duration: f64,
    /// Also run plain PD+ for comparison.
    pub compare: bool,
    /// Integrator tolerances between ticks.
    pub tolerances: Tolerances,
    /// Time between recorded rows \[s\] (`record_period`; `None`: one row per tick). Rows
    /// fall at every multiple of it after a tick and before the next ([`between_ticks`]),
    /// and at every tick.
    pub record_period: Option<f64>,
    /// The robot whose physics the plant integrates (`plant`; `None`: the controller's
    /// robot). Its structure is the controller's robot's, so both use one generated model;
    /// its numbers may differ (model mismatch).
    pub plant: Option<Robot>,
    /// Noise on the state the controller samples (`None`: it samples the plant's state
    /// exactly), independent per coordinate and tick: `position` on `q` \[m\], `velocity`
    /// on `q̇` \[m/s\]. The file's `[sensor_noise]`, or set by `softcbf verify` per run.
    pub sensor_noise: Option<SensorNoise>,
    /// The scenario file (`<embedded …>` for the built-in one).
    pub file: String,
    /// Where the layered settings came from.
    pub sources: Sources,
}

/// Where a scenario's layered settings came from ([`crate::settings`]): the command line,
/// the scenario file, the robot file (gains) or the built-in default.
#[derive(Clone, Debug, PartialEq)]
pub struct Sources {
    /// `K_P`, `K_D`, `p1`, `p2` with their sources.
    pub gains: Gains,
    /// Of the control period.
    pub control_period: Source,
    /// Of the duration.
    pub duration: Source,
    /// Of the reference (a `--set-point` replaces the file's).
    pub reference: Source,
    /// Of the filter switch.
    pub filter: Source,
    /// Of the safety mode.
    pub safety: Source,
    /// Of the comparison switch.
    pub compare: Source,
    /// Of the record period.
    pub record_period: Source,
    /// Of the plant robot.
    pub plant: Source,
}

/// What the command line changes in a scenario; each value is checked by the caller
/// against the same range as the file's field ([`softcbf_description::limits`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overrides {
    /// `--kp`, `--kd`, `--p`, `--p1`, `--p2`.
    pub gains: GainOptions,
    /// `--set-point` (replaces the file's reference; in the robot's state domain).
    pub set_point: Option<Vec<f64>>,
    /// `--duration` \[s\].
    pub duration: Option<f64>,
    /// `--control-period` \[s\].
    pub control_period: Option<f64>,
    /// `Some(false)` for `--no-filter`.
    pub filter: Option<bool>,
    /// `--safety`.
    pub safety: Option<SafetyMode>,
    /// `Some(true)` for `--compare`.
    pub compare: Option<bool>,
    /// `--record-period` \[s\].
    pub record_period: Option<f64>,
    /// `--plant`: the plant robot's file (as given, relative to the working directory).
    pub plant: Option<PathBuf>,
}

/// Why a scenario cannot run: a problem in its file, or in a command-line option.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// A field of the scenario file (file, line and field named).
    #[error(transparent)]
    File(#[from] FileError),
    /// A command-line option, named in the message.
    #[error("{0}")]
    Option(String),
    /// Something the run needs that neither the command line, the scenario nor the robot
    /// file gives; the message says what, and every way to give it.
    #[error("{0}")]
    Missing(String),
}

/// A parsed scenario file whose sizes are not yet checked against a robot.
#[derive(Clone, Debug)]
pub struct ScenarioFile {
    text: String,
    path: PathBuf,
    raw: RawScenario,
}

/// An array of numbers, each with its span.
pub type RawVector = Spanned<Vec<Spanned<f64>>>;

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    name: Option<String>,
    robot: Option<Spanned<String>>,
    duration: Option<Spanned<f64>>,
    control_period: Option<Spanned<f64>>,
    filter: Option<bool>,
    safety: Option<Spanned<String>>,
    /// The old switch: `true` is `safety = "hold-correction"`, `false` the paper's rows.
    hold_correction: Option<Spanned<bool>>,
    compare: Option<bool>,
    record_period: Option<Spanned<f64>>,
    plant: Option<Spanned<String>>,
    /// The plant's numbers as factors of the robot's (or of `plant`'s), one per module.
    plant_factors: Option<Spanned<Vec<Spanned<RawFactors>>>>,
    sensor_noise: Option<Spanned<RawSensorNoise>>,
    #[serde(default)]
    initial: RawInitial,
    reference: Option<Spanned<RawReference>>,
    #[serde(default)]
    gains: RawGains,
    #[serde(default)]
    integrator: RawIntegrator,
    /// `softcbf verify`'s ranges, read by `softcbf::verify::spec`.
    verify: Option<RawVerify>,
}

/// One module's `[[plant_factors]]`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFactors {
    /// Bending and axial stiffness.
    stiffness: [f64; 2],
    /// Bending and axial damping.
    damping: [f64; 2],
    /// The plate's mass and principal inertia.
    mass: f64,
}

/// `[sensor_noise]`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSensorNoise {
    q: Option<Spanned<f64>>,
    qd: Option<Spanned<f64>>,
    seed: Option<Spanned<i64>>,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawInitial {
    q: Option<RawVector>,
    qd: Option<RawVector>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawReference {
    set_point: Option<RawVector>,
    waypoints: Option<Spanned<Vec<Spanned<RawWaypoint>>>>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWaypoint {
    t: Spanned<f64>,
    q: RawVector,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGains {
    kp: Option<Spanned<RawGain>>,
    kd: Option<Spanned<RawGain>>,
    p1: Option<Spanned<f64>>,
    p2: Option<Spanned<f64>>,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawIntegrator {
    rtol: Option<Spanned<f64>>,
    atol: Option<Spanned<f64>>,
    h_initial: Option<Spanned<f64>>,
    max_steps: Option<Spanned<i64>>,
}

/// `[verify]` as serde reads it: kept by the scenario file, checked by
/// `softcbf::verify::spec`.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawVerify {
    pub runs: Option<Spanned<i64>>,
    pub seed: Option<Spanned<i64>>,
    pub duration: Option<Spanned<f64>>,
    pub record_period: Option<Spanned<f64>>,
    pub threshold: Option<Spanned<f64>>,
    pub safety: Option<Spanned<Vec<Spanned<String>>>>,
    pub control_periods: Option<RawVector>,
    pub set_point_min: Option<RawVector>,
    pub set_point_max: Option<RawVector>,
    pub initial_q_min: Option<RawVector>,
    pub initial_q_max: Option<RawVector>,
    pub initial_qd_min: Option<RawVector>,
    pub initial_qd_max: Option<RawVector>,
    pub parameter_errors: Option<Spanned<bool>>,
    pub sensor_noise_q: Option<Spanned<f64>>,
    pub sensor_noise_qd: Option<Spanned<f64>>,
}

/// Default control period \[s\] (the paper's simulation ticks at 1 kHz).
pub const DEFAULT_CONTROL_PERIOD: f64 = 1e-3;
/// Default duration \[s\].
pub const DEFAULT_DURATION: f64 = 10.0;
/// Most ticks a scenario may ask for (a guard against typos such as `duration = 1e9`).
pub const MAX_TICKS: f64 = 1e8;
/// Most rows a run may record, ticks and rows between them (the record is held in memory).
pub const MAX_RECORDED_ROWS: f64 = 1e8;

/// How many rows are recorded strictly between two ticks `control_period` apart when rows
/// are recorded every `record_period` (both \[s\], positive): one at every whole multiple
/// of `record_period` after a tick that falls before the next tick. A multiple within a
/// billionth of the period of the next tick is that tick (so that `0.03 / 0.001`, which
/// rounds to 29.999999999999996, records 29 rows between ticks, not 30 with the last one
/// on the tick). `record_period ≥ control_period` records none.
pub fn between_ticks(control_period: f64, record_period: f64) -> usize {
    let ratio = control_period / record_period;
    if !ratio.is_finite() || ratio <= 1.0 {
        return 0;
    }
    let nearest = ratio.round();
    if (ratio - nearest).abs() <= 1e-9 * ratio {
        nearest as usize - 1
    } else {
        ratio.floor() as usize
    }
}

impl ScenarioFile {
    /// Reads a scenario file.
    pub fn load(path: &Path) -> Result<ScenarioFile, FileError> {
        let text = softcbf_description::toml_file::read(path, "scenario file")?;
        ScenarioFile::parse(&text, path)
    }

    /// The embedded default scenario (`scenarios/default.toml`): the paper's scenario with
    /// the certified rows.
    pub fn default_scenario() -> ScenarioFile {
        ScenarioFile::parse(
            DEFAULT_SCENARIO,
            Path::new("<embedded scenarios/default.toml>"),
        )
        .expect("the embedded scenarios/default.toml is valid (tested)")
    }

    /// The embedded paper scenario, with the paper's rows.
    pub fn paper_sim() -> ScenarioFile {
        ScenarioFile::parse(
            PAPER_SIM_SCENARIO,
            Path::new("<embedded scenarios/paper-sim.toml>"),
        )
        .expect("the embedded scenarios/paper-sim.toml is valid (tested)")
    }

    /// Parses scenario text; `path` names it in messages and anchors a relative `robot`.
    pub fn parse(text: &str, path: &Path) -> Result<ScenarioFile, FileError> {
        let checker = Checker { text, path };
        let raw: RawScenario = checker.deserialize()?;
        Ok(ScenarioFile {
            text: text.to_string(),
            path: path.to_path_buf(),
            raw,
        })
    }

    /// The file this scenario was read from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The file's text.
    pub fn text(&self) -> &str {
        &self.text
    }

    /// The checker of this file's values (errors naming file, line and field).
    pub fn checker(&self) -> Checker<'_> {
        Checker {
            text: &self.text,
            path: &self.path,
        }
    }

    /// The `[verify]` table, if the file has one.
    pub fn verify_table(&self) -> Option<&RawVerify> {
        self.raw.verify.as_ref()
    }

    /// The robot file the scenario names, relative paths taken from the scenario's folder
    /// (`None`: the embedded paper robot).
    pub fn robot_path(&self) -> Option<PathBuf> {
        Some(self.beside(self.raw.robot.as_ref()?.get_ref()))
    }

    /// The plant robot file the scenario names (`plant`), relative paths taken from the
    /// scenario's folder (`None`: the plant is the controller's robot).
    pub fn plant_path(&self) -> Option<PathBuf> {
        Some(self.beside(self.raw.plant.as_ref()?.get_ref()))
    }

    /// A path the file gives, taken from the scenario's folder when relative.
    fn beside(&self, given: &str) -> PathBuf {
        let given = Path::new(given);
        if given.is_absolute() {
            given.to_path_buf()
        } else {
            self.path.parent().unwrap_or(Path::new(".")).join(given)
        }
    }

    /// Reads the robot file the scenario names (`None`: it names none, the caller uses the
    /// embedded paper robot). A file that cannot be read is reported at the scenario's
    /// `robot` field, with the path it was resolved to.
    pub fn load_robot(&self) -> Result<Option<Robot>, FileError> {
        let (Some(given), Some(path)) = (&self.raw.robot, self.robot_path()) else {
            return Ok(None);
        };
        match crate::robot_file::load_robot(Some(&path)) {
            Err(FileError::Io { source, .. }) => {
                let c = Checker {
                    text: &self.text,
                    path: &self.path,
                };
                let resolved = std::path::absolute(&path).unwrap_or(path);
                Err(c.invalid(
                    &given.span(),
                    "robot",
                    format!(
                        "cannot read the robot file {} (`{}`, taken from this scenario's \
                         folder): {source}",
                        resolved.display(),
                        given.get_ref()
                    ),
                ))
            }
            other => other.map(Some),
        }
    }

    /// Checks every value and every size against `model` and builds the scenario as the
    /// file (and the robot file, for the gains) says, without command-line overrides.
    pub fn resolve(&self, model: &Model) -> Result<Scenario, FileError> {
        self.resolve_with(model, &Overrides::default())
            .map_err(|error| match error {
                ScenarioError::File(error) => error,
                // Only an override yields an option error; there are none here.
                ScenarioError::Option(message) => FileError::Invalid {
                    path: self.path.clone(),
                    line: 0,
                    field: String::new(),
                    message,
                },
                ScenarioError::Missing(message) => FileError::Invalid {
                    path: self.path.clone(),
                    line: 0,
                    field: "reference".to_string(),
                    message,
                },
            })
    }

    /// Checks every value and every size against `model` and builds the scenario, with
    /// the command line's `overrides` taking precedence ([`crate::settings`]).
    pub fn resolve_with(
        &self,
        model: &Model,
        overrides: &Overrides,
    ) -> Result<Scenario, ScenarioError> {
        let c = Checker {
            text: &self.text,
            path: &self.path,
        };
        let raw = &self.raw;
        let number = |v: &Option<Spanned<f64>>, field: &str, limit: &Limit| {
            v.as_ref().map(|v| c.within(v, field, limit)).transpose()
        };
        let control_period = first(
            [
                (overrides.control_period, Source::CommandLine),
                (
                    number(
                        &raw.control_period,
                        "control_period",
                        &limits::CONTROL_PERIOD_S,
                    )?,
                    Source::Scenario,
                ),
            ],
            DEFAULT_CONTROL_PERIOD,
        );
        let duration = first(
            [
                (overrides.duration, Source::CommandLine),
                (
                    number(&raw.duration, "duration", &limits::DURATION_S)?,
                    Source::Scenario,
                ),
            ],
            DEFAULT_DURATION,
        );
        self.check_ticks(&c, &duration, &control_period)?;
        let period = control_period.value;
        let record_period = first(
            [
                (overrides.record_period.map(Some), Source::CommandLine),
                (
                    number(
                        &raw.record_period,
                        "record_period",
                        &limits::RECORD_PERIOD_S,
                    )?
                    .map(Some),
                    Source::Scenario,
                ),
            ],
            None,
        );
        self.check_record_period(&c, &record_period, &control_period, &duration)?;
        let plant = self.plant(&c, &model.robot, overrides)?;
        // Every value of the file is checked, also one the command line replaces (the file
        // may be run without the option another time), against the robot the file names
        // (the run's may be another one, given on the command line).
        let replaced = overrides.set_point.is_some() && self.raw.reference.is_some()
            || overrides.plant.is_some() && self.plant_path().is_some();
        let file_robot =
            match replaced {
                true => Some(self.load_robot().and_then(|robot| {
                    robot.map_or_else(|| crate::robot_file::load_robot(None), Ok)
                })?),
                false => None,
            };
        let own = file_robot.as_ref().unwrap_or(&model.robot);
        if overrides.plant.is_some() && self.plant_path().is_some() {
            self.plant(&c, own, &Overrides::default())?;
        }
        let plant = self.plant_factors(&c, model, plant)?;
        let sensor_noise = self.sensor_noise(&c)?;

        let robot = &model.robot;
        let initial_q = state(&c, raw.initial.q.as_ref(), "initial.q", robot, Coordinates)?;
        let initial_qd = state(&c, raw.initial.qd.as_ref(), "initial.qd", robot, Velocities)?;

        let reference = match (&overrides.set_point, &raw.reference, &robot.set_point) {
            (Some(point), file_reference, _) => {
                if let Some(table) = file_reference {
                    // At the file's own period (the spacing of its waypoints).
                    let file_period = number(
                        &raw.control_period,
                        "control_period",
                        &limits::CONTROL_PERIOD_S,
                    )?
                    .unwrap_or(DEFAULT_CONTROL_PERIOD);
                    self.reference(&c, table, own, file_period)?;
                }
                Sourced::new(ReferenceSpec::SetPoint(point.clone()), Source::CommandLine)
            }
            (None, Some(table), _) => {
                Sourced::new(self.reference(&c, table, robot, period)?, Source::Scenario)
            }
            (None, None, Some(point)) => {
                Sourced::new(ReferenceSpec::SetPoint(point.clone()), Source::RobotFile)
            }
            (None, None, None) => return Err(ScenarioError::Missing(self.no_set_point(robot))),
        };

        let nq = model.nq();
        let gains = &raw.gains;
        let matrix = |raw: &Option<Spanned<RawGain>>, field: &str, limit: &Limit| {
            raw.as_ref()
                .map(|raw| gain(&c, raw, field, nq, limit))
                .transpose()
        };
        let from_file = ScenarioGains {
            kp: matrix(&gains.kp, "gains.kp", &limits::KP_N_PER_M)?,
            kd: matrix(&gains.kd, "gains.kd", &limits::KD_N_S_PER_M)?,
            p1: number(&gains.p1, "gains.p1", &limits::BARRIER_GAIN_PER_S)?,
            p2: number(&gains.p2, "gains.p2", &limits::BARRIER_GAIN_PER_S)?,
        };
        let gains = resolve_gains(&overrides.gains, &from_file, robot);

        let mut tolerances = Tolerances::default();
        let integrator = &raw.integrator;
        let or = |value: Option<f64>, default: f64| value.unwrap_or(default);
        tolerances.rtol = or(
            number(&integrator.rtol, "integrator.rtol", &limits::RTOL)?,
            tolerances.rtol,
        );
        tolerances.atol = or(
            number(&integrator.atol, "integrator.atol", &limits::ATOL)?,
            tolerances.atol,
        );
        tolerances.h_initial = or(
            number(
                &integrator.h_initial,
                "integrator.h_initial",
                &limits::H_INITIAL_S,
            )?,
            tolerances.h_initial,
        );
        if let Some(max_steps) = &integrator.max_steps {
            let steps = c.integer_within(max_steps, "integrator.max_steps", &limits::MAX_STEPS)?;
            tolerances.max_steps = usize::try_from(steps).unwrap_or(1);
        }
        tolerances.h_max = period;
        tolerances.h_initial = tolerances.h_initial.min(period);
        if let Err(error) = tolerances.validate() {
            let span = integrator.h_initial.as_ref().map_or(0..0, Spanned::span);
            return Err(c.invalid(&span, "integrator", error.to_string()).into());
        }

        let name = raw.name.clone().unwrap_or_else(|| {
            self.path.file_stem().map_or_else(
                || "scenario".to_string(),
                |s| s.to_string_lossy().into_owned(),
            )
        });
        let filter = first(
            [
                (overrides.filter, Source::CommandLine),
                (raw.filter, Source::Scenario),
            ],
            true,
        );
        let safety = first(
            [
                (overrides.safety, Source::CommandLine),
                (self.safety_mode(&c)?, Source::Scenario),
            ],
            SafetyMode::default(),
        );
        let compare = first(
            [
                (overrides.compare, Source::CommandLine),
                (raw.compare, Source::Scenario),
            ],
            false,
        );
        let controller = ControllerSettings {
            filter: filter.value,
            safety: safety.value,
            hold: period,
            ..gains.controller_settings()
        };
        Ok(Scenario {
            name,
            file: self.path.display().to_string(),
            initial_q,
            initial_qd,
            reference: reference.value,
            controller,
            control_period: period,
            duration: duration.value,
            compare: compare.value,
            tolerances,
            record_period: record_period.value,
            plant: plant.value,
            sensor_noise,
            sources: Sources {
                gains,
                control_period: control_period.source,
                duration: duration.source,
                reference: reference.source,
                filter: filter.source,
                safety: safety.source,
                compare: compare.source,
                record_period: record_period.source,
                plant: plant.source,
            },
        })
    }

    /// Checks that a record period (checked against its range already) is at most the
    /// control period and that the rows it records number at most [`MAX_RECORDED_ROWS`];
    /// the error names the option or the field that gave it.
    fn check_record_period(
        &self,
        c: &Checker<'_>,
        record_period: &Sourced<Option<f64>>,
        period: &Sourced<f64>,
        duration: &Sourced<f64>,
    ) -> Result<(), ScenarioError> {
        let Some(record_s) = record_period.value else {
            return Ok(());
        };
        let period_s = period.value;
        let from = if period.source == Source::CommandLine {
            " (--control-period)"
        } else {
            ""
        };
        let ticks = (duration.value / period_s).round();
        let rows = ticks * (between_ticks(period_s, record_s) as f64 + 1.0) + 1.0;
        let problem = if record_s > period_s {
            format!(
                "{} s is longer than the control period ({} s{from}): rows are recorded at \
                 every tick already; give at most the control period",
                short(record_s),
                short(period_s)
            )
        } else if rows > MAX_RECORDED_ROWS {
            format!(
                "{} s over {} s of simulated time records {rows:.1e} rows, more than \
                 {MAX_RECORDED_ROWS:.0e}; record less densely or simulate less time",
                short(record_s),
                short(duration.value)
            )
        } else {
            return Ok(());
        };
        if record_period.source == Source::CommandLine {
            return Err(ScenarioError::Option(format!("--record-period: {problem}")));
        }
        let span = self.raw.record_period.as_ref().map_or(0..0, Spanned::span);
        Err(c.invalid(&span, "record_period", problem).into())
    }

    /// The plant robot the command line (`--plant`) or the file (`plant`) names, read and
    /// checked to have the structure of `model`'s robot; `None` when neither names one.
    /// Problems are reported at the option or at the file's field, naming both robot files
    /// and what differs.
    fn plant(
        &self,
        c: &Checker<'_>,
        controller: &Robot,
        overrides: &Overrides,
    ) -> Result<Sourced<Option<Robot>>, ScenarioError> {
        let (path, source) = match (&overrides.plant, self.plant_path()) {
            (Some(path), _) => (path.clone(), Source::CommandLine),
            (None, Some(path)) => (path, Source::Scenario),
            (None, None) => return Ok(Sourced::new(None, Source::BuiltIn)),
        };
        let span = self.raw.plant.as_ref().map_or(0..0, Spanned::span);
        let refuse = |message: String| -> ScenarioError {
            match source {
                Source::CommandLine => ScenarioError::Option(format!("--plant: {message}")),
                _ => c.invalid(&span, "plant", message).into(),
            }
        };
        let resolved = std::path::absolute(&path).unwrap_or_else(|_| path.clone());
        let robot = match crate::robot_file::load_robot(Some(&path)) {
            Ok(robot) => robot,
            Err(FileError::Io { source: error, .. }) => {
                let taken = match source {
                    Source::CommandLine => String::new(),
                    _ => format!(
                        " (`{}`, taken from this scenario's folder)",
                        self.raw.plant.as_ref().map_or("", |p| p.get_ref())
                    ),
                };
                return Err(refuse(format!(
                    "cannot read the plant robot file {}{taken}: {error}",
                    resolved.display()
                )));
            }
            Err(error) => return Err(error.into()),
        };
        if let Some(difference) = structure_difference(controller, &robot) {
            return Err(refuse(format!(
                "the plant robot {} differs in structure from the controller's robot {}: \
                 {difference}; a plant may differ only in its numbers (stiffness, damping, \
                 masses, lengths), so that both use one generated model",
                resolved.display(),
                crate::settings::file_name(&controller.source)
            )));
        }
        Ok(Sourced::new(Some(robot), source))
    }

    /// `plant` (the plant robot, `None`: the controller's robot) with its numbers
    /// multiplied by the file's `[[plant_factors]]`, if it gives them (one table per
    /// module; each factor finite and > 0, each scaled number within the range of its
    /// robot-file field).
    fn plant_factors(
        &self,
        c: &Checker<'_>,
        model: &Model,
        plant: Sourced<Option<Robot>>,
    ) -> Result<Sourced<Option<Robot>>, ScenarioError> {
        let Some(tables) = &self.raw.plant_factors else {
            return Ok(plant);
        };
        let modules = model.robot.modules.len();
        if tables.get_ref().len() != modules {
            return Err(c
                .invalid(
                    &tables.span(),
                    "plant_factors",
                    format!(
                        "has {} tables, the robot has {modules} modules: give one                          [[plant_factors]] per module",
                        tables.get_ref().len()
                    ),
                )
                .into());
        }
        let factors: Vec<ModuleFactors> = tables
            .get_ref()
            .iter()
            .map(|t| {
                let t = t.get_ref();
                ModuleFactors {
                    stiffness: t.stiffness,
                    damping: t.damping,
                    mass: t.mass,
                }
            })
            .collect();
        let base = plant.value.as_ref().unwrap_or(&model.robot);
        let mut scaled = uncertainty::scaled(base, &factors).map_err(|error| {
            let span = match &error {
                PlantError::Factor { module, .. } | PlantError::Range { module, .. } => tables
                    .get_ref()
                    .get(module - 1)
                    .map_or(tables.span(), Spanned::span),
                PlantError::Count { .. } => tables.span(),
            };
            c.invalid(&span, "plant_factors", error.to_string())
        })?;
        scaled.name = format!("{} × plant_factors", base.name);
        Ok(Sourced::new(Some(scaled), Source::Scenario))
    }

    /// The file's `[sensor_noise]` (standard deviations on `q` \[m\] and `q̇` \[m/s\],
    /// the seed of the draws), if given.
    fn sensor_noise(&self, c: &Checker<'_>) -> Result<Option<SensorNoise>, FileError> {
        let Some(table) = &self.raw.sensor_noise else {
            return Ok(None);
        };
        let t = table.get_ref();
        let number = |v: &Option<Spanned<f64>>, field: &str, limit: &Limit| {
            v.as_ref()
                .map(|v| c.within(v, &format!("sensor_noise.{field}"), limit))
                .transpose()
                .map(|v| v.unwrap_or(0.0))
        };
        let q = number(&t.q, "q", &crate::noise::SENSOR_NOISE_M)?;
        let qd = number(&t.qd, "qd", &crate::noise::SENSOR_NOISE_M_PER_S)?;
        let seed = match &t.seed {
            Some(seed) => c.integer_within(seed, "sensor_noise.seed", &crate::noise::SEED)? as u64,
            None => 0,
        };
        Ok(Some(SensorNoise {
            position: q,
            velocity: qd,
            seed,
        }))
    }

    /// The file's `safety` (or its old spelling `hold_correction = true | false`), if given.
    fn safety_mode(&self, c: &Checker<'_>) -> Result<Option<SafetyMode>, FileError> {
        match (&self.raw.safety, &self.raw.hold_correction) {
            (Some(_), Some(old)) => Err(c.invalid(
                &old.span(),
                "hold_correction",
                "give either `safety` or the older `hold_correction`, not both".to_string(),
            )),
            (Some(name), None) => SafetyMode::parse(name.get_ref())
                .map(Some)
                .map_err(|message| c.invalid(&name.span(), "safety", message)),
            (None, Some(old)) => Ok(Some(if *old.get_ref() {
                SafetyMode::HoldCorrection
            } else {
                SafetyMode::Paper
            })),
            (None, None) => Ok(None),
        }
    }

    /// Checks that `duration` holds at least one tick of `period` and at most
    /// [`MAX_TICKS`]; the error names the option or the field that gave the duration.
    fn check_ticks(
        &self,
        c: &Checker<'_>,
        duration: &Sourced<f64>,
        period: &Sourced<f64>,
    ) -> Result<(), ScenarioError> {
        let (duration_s, period_s) = (duration.value, period.value);
        let from = |source: Source| match source {
            Source::CommandLine => " (--control-period)".to_string(),
            Source::BuiltIn => " (the default)".to_string(),
            _ => String::new(),
        };
        let problem = if duration_s < period_s {
            format!(
                "{duration_s} s is shorter than the control period ({period_s} s{}): not one \
                 tick would be simulated",
                from(period.source)
            )
        } else if duration_s / period_s > MAX_TICKS {
            format!(
                "{duration_s} s at a period of {period_s} s{} is {:.1e} ticks, more than \
                 {MAX_TICKS:.0e}",
                from(period.source),
                duration_s / period_s
            )
        } else {
            return Ok(());
        };
        if duration.source == Source::CommandLine {
            return Err(ScenarioError::Option(format!("--duration: {problem}")));
        }
        let span = self
            .raw
            .duration
            .as_ref()
            .or(self.raw.control_period.as_ref())
            .map_or(0..0, Spanned::span);
        Err(c.invalid(&span, "duration", problem).into())
    }

    /// What a run lacks when neither the command line, the scenario nor the robot file
    /// gives a set point, and every way to give one.
    fn no_set_point(&self, robot: &Robot) -> String {
        let nq = 3 * robot.modules.len();
        let names: Vec<String> = (1..=robot.modules.len())
            .flat_map(|k| [format!("Δx{k}"), format!("Δy{k}"), format!("δL{k}")])
            .collect();
        let shown = if names.len() > 6 {
            format!("{}, …, {}", names[..3].join(","), names[nq - 1])
        } else {
            names.join(",")
        };
        format!(
            "no set point for the robot {} ({}): its file has no `set_point` and the scenario \
             {} no [reference]. Give one of: `--set-point {shown}` ({nq} numbers [m], 3 per \
             module; `set_point=` in Python), a line `set_point = [...]` with {nq} numbers in \
             the robot file (robots/README.md), or a scenario file with a [reference] table \
             (`--scenario FILE`, scenarios/README.md)",
            robot.name,
            crate::settings::file_name(&robot.source),
            self.path.display(),
        )
    }

    /// The file's `[reference]` table, checked against `robot`.
    fn reference(
        &self,
        c: &Checker<'_>,
        reference: &Spanned<RawReference>,
        robot: &Robot,
        control_period: f64,
    ) -> Result<ReferenceSpec, FileError> {
        let span = reference.span();
        match (
            &reference.get_ref().set_point,
            &reference.get_ref().waypoints,
        ) {
            (Some(point), None) => Ok(ReferenceSpec::SetPoint(state(
                c,
                Some(point),
                "reference.set_point",
                robot,
                Coordinates,
            )?)),
            (None, Some(points)) => {
                if points.get_ref().is_empty() {
                    return Err(c.invalid(
                        &points.span(),
                        "reference.waypoints",
                        "needs at least one waypoint { t = …, q = […] }".into(),
                    ));
                }
                let mut out: Vec<(f64, Vec<f64>)> = Vec::new();
                for (k, point) in points.get_ref().iter().enumerate() {
                    let field = format!("reference.waypoints[{}]", k + 1);
                    let waypoint = point.get_ref();
                    let t =
                        c.within(&waypoint.t, &format!("{field}.t"), &limits::WAYPOINT_TIME_S)?;
                    if let Some((previous, _)) = out.last() {
                        let (now, before) = (short(t), short(*previous));
                        let problem = if t <= *previous {
                            Some(format!("times must increase: {now} s follows {before} s"))
                        } else if t - previous < control_period * (1.0 - SPACING_TOLERANCE) {
                            Some(format!(
                                "{now} s is {:.2e} s after waypoint {k} ({before} s); \
                                 consecutive waypoints must be at least one control period \
                                 apart ({control_period} s)",
                                t - previous
                            ))
                        } else {
                            None
                        };
                        if let Some(message) = problem {
                            return Err(c.invalid(
                                &waypoint.t.span(),
                                &format!("{field}.t"),
                                message,
                            ));
                        }
                    }
                    let q = state(
                        c,
                        Some(&waypoint.q),
                        &format!("{field}.q"),
                        robot,
                        Coordinates,
                    )?;
                    out.push((t, q));
                }
                Ok(ReferenceSpec::Waypoints(out))
            }
            (Some(_), Some(_)) => Err(c.invalid(
                &span,
                "reference",
                "give either `set_point` or `waypoints`, not both".into(),
            )),
            (None, None) => Err(c.invalid(
                &span,
                "reference",
                "needs `set_point = [...]` or `waypoints = [{ t = …, q = [...] }, …]`".into(),
            )),
        }
    }
}

/// The first way in which `plant`'s structure differs from `controller`'s (the robot the
/// controller uses), in words; `None` if they have one structure.
pub fn structure_difference(controller: &Robot, plant: &Robot) -> Option<String> {
    let (ours, theirs) = (controller.structure(), plant.structure());
    if ours == theirs {
        return None;
    }
    let (n, m) = (ours.corners.len(), theirs.corners.len());
    if n != m {
        return Some(format!("it has {m} modules, the controller's robot {n}"));
    }
    let per_module = |what: &str, a: &[usize], b: &[usize]| {
        a.iter()
            .zip(b)
            .enumerate()
            .find(|(_, (x, y))| x != y)
            .map(|(k, (x, y))| format!("module {}: {y} {what}, the controller's robot {x}", k + 1))
    };
    if let Some(text) = per_module("plate corners", &ours.corners, &theirs.corners) {
        return Some(text);
    }
    if let Some(text) = per_module("tendons", &ours.tendons, &theirs.tendons) {
        return Some(text);
    }
    if ours.routing != theirs.routing {
        let name = |routing| format!("{routing:?}").to_lowercase();
        return Some(format!(
            "routing `{}`, the controller's robot `{}`",
            name(theirs.routing),
            name(ours.routing)
        ));
    }
    let (a, b) = (ours.obstacles.len(), theirs.obstacles.len());
    if a != b {
        return Some(format!("{b} obstacles, the controller's robot {a}"));
    }
    let k = ours
        .obstacles
        .iter()
        .zip(&theirs.obstacles)
        .position(|(a, b)| a != b)
        .unwrap_or_default();
    Some(format!(
        "obstacle {}: another kind or other watched points than the controller's robot's",
        k + 1
    ))
}

/// Relative slack on the spacing of waypoints, so that times written in decimals one
/// period apart (0.3 after 0.2 at 0.1 s) are not refused for their rounding.
const SPACING_TOLERANCE: f64 = 1e-9;

/// Which part of the state a vector holds.
#[derive(Clone, Copy)]
enum Part {
    Coordinates,
    Velocities,
}
use Part::{Coordinates, Velocities};

/// A state vector of `robot` (zeros when not given): one finite entry per coordinate, in
/// the model's domain (`softcbf_description::domain`).
fn state(
    c: &Checker<'_>,
    v: Option<&RawVector>,
    field: &str,
    robot: &Robot,
    part: Part,
) -> Result<Vec<f64>, FileError> {
    let nq = 3 * robot.modules.len();
    let Some(v) = v else {
        return Ok(vec![0.0; nq]);
    };
    sized(c, v, field, nq, "coordinates (3 per module: Δx, Δy, δL)")?;
    let values = c.finite_list(v.get_ref(), field)?;
    let problem = match part {
        Coordinates => domain::coordinates_problem(robot, &values),
        Velocities => domain::velocities_problem(robot, &values),
    };
    c.state(problem, v, field)?;
    Ok(values)
}

/// A given state vector of `robot` (`coordinates`: a `q`, else a `q̇`), checked like the
/// scenario's initial state.
pub fn state_vector(
    c: &Checker<'_>,
    v: &RawVector,
    field: &str,
    robot: &Robot,
    coordinates: bool,
) -> Result<Vec<f64>, FileError> {
    let part = if coordinates { Coordinates } else { Velocities };
    state(c, Some(v), field, robot, part)
}

/// Checks that the array `v` has `n` entries (`what` says what they are).
fn sized<T>(
    c: &Checker<'_>,
    v: &Spanned<Vec<T>>,
    field: &str,
    n: usize,
    what: &str,
) -> Result<(), FileError> {
    let len = v.get_ref().len();
    if len == n {
        return Ok(());
    }
    Err(c.invalid(
        &v.span(),
        field,
        format!("has {len} entries, the robot has {n} {what}"),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paper robot (6 coordinates: `d` = 0.04 m, `L0` = 0.1 m per module).
    fn model() -> Model {
        Model::new(Robot::paper_sim()).expect("the paper model is generated")
    }

    const REFERENCE: &str = "[reference]\nset_point = [0, 0, 0, 0, 0, 0]\n";

    fn resolve(text: &str) -> Result<Scenario, FileError> {
        ScenarioFile::parse(text, Path::new("scenarios/x.toml"))?.resolve(&model())
    }

    /// Asserts that `text` is refused with `fragment` in the message (which starts with
    /// the file, the line and the field).
    #[track_caller]
    fn refused(text: &str, fragment: &str) {
        match resolve(text) {
            Ok(_) => panic!("accepted:\n{text}"),
            Err(error) => {
                let message = error.to_string();
                assert!(message.contains(fragment), "`{message}` lacks `{fragment}`");
            }
        }
    }

    #[test]
    fn the_default_scenario_is_the_paper_scenario_with_the_certified_rows() {
        let default = ScenarioFile::default_scenario().resolve(&model()).unwrap();
        let paper = ScenarioFile::paper_sim().resolve(&model()).unwrap();
        assert_eq!(default.controller.safety, SafetyMode::Certified);
        assert_eq!(paper.controller.safety, SafetyMode::Paper);
        assert_eq!(
            (default.duration, default.control_period, &default.reference),
            (paper.duration, paper.control_period, &paper.reference)
        );
        assert!(default.compare && paper.compare);
    }

    #[test]
    fn the_paper_scenario_builds_the_paper_controller_with_its_period_and_rows() {
        // One way to build controller settings: a scenario's are the paper's (the built-in
        // gains, K_P = 5·I and K_D = 1·I) with the scenario's hold, rows and filter.
        let model = model();
        let scenario = ScenarioFile::paper_sim().resolve(&model).unwrap();
        let nq = model.nq();
        let identity = |k: f64| {
            (0..nq * nq)
                .map(|i| if i % (nq + 1) == 0 { k } else { 0.0 })
                .collect::<Vec<_>>()
        };
        let expected = ControllerSettings {
            kp: identity(5.0),
            kd: identity(1.0),
            hold: 1e-3,
            safety: SafetyMode::Paper,
            ..ControllerSettings::paper(&model)
        };
        assert_eq!(scenario.controller, expected);
    }

    #[test]
    fn sensor_noise_of_a_scenario_is_the_one_sensor_noise() {
        let scenario = resolve("[sensor_noise]\nq = 1e-4\nqd = 2e-3\nseed = 5\n").unwrap();
        let noise = SensorNoise {
            position: 1e-4,
            velocity: 2e-3,
            seed: 5,
        };
        assert_eq!(scenario.sensor_noise, Some(noise));
        // The emulator's readings take the same type (`softcbf::hardware::emulator`'s tests).
    }

    #[test]
    fn the_paper_scenario_resolves_to_its_numbers() {
        let scenario = ScenarioFile::paper_sim().resolve(&model()).unwrap();
        assert_eq!((scenario.duration, scenario.control_period), (10.0, 1e-3));
        assert_eq!(
            scenario.reference,
            ReferenceSpec::SetPoint(vec![0.08, 0.0, -0.05, 0.0, -0.06, -0.07])
        );
        assert_eq!(scenario.controller.kp[0], 5.0);
        assert_eq!(scenario.controller.kd[7], 1.0);
        assert_eq!(scenario.controller.barrier_gains, [10.0, 10.0]);
    }

    #[test]
    fn numbers_lie_in_their_physical_ranges() {
        refused(
            &format!("duration = 1e300\n{REFERENCE}"),
            "x.toml:1: field `duration`: must be > 0 and ≤ 1000000 s, got 1e300",
        );
        refused(
            &format!("control_period = 2\n{REFERENCE}"),
            "x.toml:1: field `control_period`: must be ≥ 1e-6 and ≤ 1 s, got 2",
        );
        refused(
            &format!("{REFERENCE}[gains]\np1 = 1e308\n"),
            "x.toml:4: field `gains.p1`: must be > 0 and ≤ 10000 1/s, got 1e308",
        );
        refused(
            &format!("{REFERENCE}[gains]\np2 = -1\n"),
            "field `gains.p2`: must be > 0",
        );
        refused(
            &format!("{REFERENCE}[gains]\nkp = 2e6\n"),
            "x.toml:4: field `gains.kp`: must be ≥ 0 and ≤ 1000000 N/m, got 2000000",
        );
        refused(
            &format!("{REFERENCE}[gains]\nkd = [1, 1, 1, 1, -1, 1]\n"),
            "field `gains.kd`: entry 5 must be ≥ 0 and ≤ 1000000 N·s/m, got -1",
        );
        refused(
            &format!("{REFERENCE}[integrator]\nrtol = 0\n"),
            "x.toml:4: field `integrator.rtol`: must be ≥ 1e-12 and ≤ 1, got 0",
        );
        refused(
            &format!("{REFERENCE}[integrator]\natol = 10\n"),
            "field `integrator.atol`: must be ≥ 1e-15 and ≤ 1, got 10",
        );
        refused(
            &format!("{REFERENCE}[integrator]\nh_initial = 1e-300\n"),
            "field `integrator.h_initial`: must be ≥ 1e-12 and ≤ 1 s, got 1e-300",
        );
        refused(
            &format!("{REFERENCE}[integrator]\nmax_steps = 0\n"),
            "field `integrator.max_steps`: must be an integer in 1..=10000000, got 0",
        );
        // The bounds themselves are accepted.
        let scenario = resolve(&format!(
            "duration = 1\ncontrol_period = 1\n{REFERENCE}[gains]\nkp = 1e6\nkd = 0\np1 = 1e4\n\
             [integrator]\nrtol = 1e-12\natol = 1\nh_initial = 1\nmax_steps = 10000000\n"
        ))
        .unwrap();
        assert_eq!(scenario.controller.kp[0], 1e6);
        assert_eq!(scenario.controller.barrier_gains[0], 1e4);
        assert_eq!(scenario.tolerances.max_steps, 10_000_000);
    }

    /// Set points, waypoints and the initial state lie in the state domain: bends of at most
    /// 1.5π·0.04 m = 0.1885 m, elongations of at most 1 m, speeds of at most 100 m/s.
    #[test]
    fn states_lie_in_the_state_domain() {
        refused(
            "[reference]\nset_point = [1e308, 0, 0, 0, 0, 0]\n",
            "x.toml:2: field `reference.set_point`: module 1 bends by",
        );
        refused(
            "[reference]\nset_point = [0, 0, 0,\n 0, 0, -1.01]\n",
            "x.toml:3: field `reference.set_point`: entry 6 (δL of module 2)",
        );
        refused(
            &format!("{REFERENCE}[initial]\nq = [0, 0, 0, 0.14, 0.14, 0]\n"),
            "x.toml:4: field `initial.q`: module 2 bends",
        );
        refused(
            &format!("{REFERENCE}[initial]\nqd = [0, 0, 0, 0, 0, 100.5]\n"),
            "field `initial.qd`: entry 6 is 1.005e2 m/s; speeds must be ≤ 100 m/s",
        );
        refused(
            "[reference]\nwaypoints = [{ t = 0, q = [0, 0, 0, 0, 0, 0] },\n { t = 1, q = [0, 0, 11, 0, 0, 0] }]\n",
            "x.toml:3: field `reference.waypoints[2].q`: entry 3 (δL of module 1)",
        );
        let scenario = resolve(&format!(
            "{REFERENCE}[initial]\nq = [0.108, 0.144, 1, 0, 0, -0.0999]\nqd = [100, -100, 0, 0, 0, 0]\n"
        ))
        .unwrap();
        assert_eq!(scenario.initial_q, [0.108, 0.144, 1.0, 0.0, 0.0, -0.0999]);
        refused(
            &format!("{REFERENCE}[initial]\nq = [0, 0, 0, 0, 0, -0.1]\n"),
            "x.toml:4: field `initial.q`: entry 6 (δL of module 2) is -0.1 m: the backbone length \
             L0 + δL = 0 m is not positive",
        );
    }

    #[test]
    fn full_matrix_gains_are_positive_semidefinite() {
        let rows = |diagonal: [f64; 6], extra: (usize, usize, f64)| {
            let mut text = String::from("kp = [\n");
            for (i, own) in diagonal.iter().enumerate() {
                let row: Vec<String> = (0..6)
                    .map(|j| {
                        let v = if i == j {
                            *own
                        } else if (i, j) == (extra.0, extra.1) {
                            extra.2
                        } else {
                            0.0
                        };
                        v.to_string()
                    })
                    .collect();
                text += &format!("  [{}],\n", row.join(", "));
            }
            format!("{REFERENCE}[gains]\n{text}]\n")
        };
        // A −1 on the diagonal (the list form forbids it too).
        refused(
            &rows([5.0, 5.0, -1.0, 5.0, 5.0, 5.0], (0, 1, 0.0)),
            "x.toml:7: field `gains.kp`: row 3 entry 3 must be ≥ 0 and ≤ 1000000 N/m, got -1",
        );
        // Non-negative diagonal, but [[1, 3], [3, 1]] has the eigenvalue 1 − 3 = −2.
        refused(
            &rows([1.0, 1.0, 1.0, 1.0, 1.0, 1.0], (0, 1, 6.0)),
            "field `gains.kp`: the symmetric part (K + Kᵀ)/2 has the eigenvalue -2",
        );
        // [[1, 2], [0, 1]]: symmetric part [[1, 1], [1, 1]], eigenvalues 0 and 2: accepted.
        let scenario = resolve(&rows([1.0; 6], (0, 1, 2.0))).unwrap();
        assert_eq!(scenario.controller.kp[1], 2.0);
        assert_eq!(scenario.controller.kp[6], 0.0);
        refused(
            &rows([1.0; 6], (0, 1, 1e7)),
            "row 1 entry 2 must be ≥ -1000000 and ≤ 1000000 N/m, got 1e7",
        );
        refused(
            &format!("{REFERENCE}[gains]\nkp = [[1, 0], [0, 1]]\n"),
            "field `gains.kp`: has 2 rows, expected 6",
        );
    }

    #[test]
    fn a_gain_of_the_wrong_form_names_the_forms_and_the_field() {
        refused(
            &format!("{REFERENCE}[gains]\nkp = \"five\"\n"),
            "x.toml:4:6: field `gains.kp`: invalid type: string \"five\", expected a number, \
             a list (the diagonal) or a list of rows",
        );
        refused(
            &format!("{REFERENCE}[gains]\nkd = [1, [1, 2]]\n"),
            "field `gains.kd`: mixes numbers and rows",
        );
        refused(
            &format!("{REFERENCE}[gains]\nkd = [[1, \"a\"]]\n"),
            "x.toml:4:11: field `gains.kd`, row 1 entry 2: invalid type: string \"a\", \
             expected a number",
        );
    }

    #[test]
    fn the_record_period_is_in_range_and_at_most_the_control_period() {
        refused(
            &format!("record_period = 0\n{REFERENCE}"),
            "x.toml:1: field `record_period`: must be ≥ 1e-6 and ≤ 1 s, got 0",
        );
        refused(
            &format!("control_period = 0.01\nrecord_period = 0.02\n{REFERENCE}"),
            "x.toml:2: field `record_period`: 0.02 s is longer than the control period \
             (0.01 s): rows are recorded at every tick already",
        );
        // 1e4 s at 1 kHz, 999 rows between ticks: 1e10 rows.
        refused(
            &format!("duration = 1e4\nrecord_period = 1e-6\n{REFERENCE}"),
            "x.toml:2: field `record_period`: 1e-6 s over 10000 s of simulated time \
             records 1.0e10 rows, more than 1e8",
        );
        assert_eq!(resolve(REFERENCE).unwrap().record_period, None);
        let scenario = resolve(&format!("record_period = 5e-4\n{REFERENCE}")).unwrap();
        assert_eq!(scenario.record_period, Some(5e-4));
        assert_eq!(scenario.sources.record_period, Source::Scenario);
        // The command line wins, and is named in its own errors.
        let file = ScenarioFile::parse(
            &format!("record_period = 5e-4\n{REFERENCE}"),
            Path::new("scenarios/x.toml"),
        )
        .unwrap();
        let overrides = Overrides {
            record_period: Some(2e-4),
            ..Overrides::default()
        };
        let scenario = file.resolve_with(&model(), &overrides).unwrap();
        assert_eq!(scenario.record_period, Some(2e-4));
        assert_eq!(scenario.sources.record_period, Source::CommandLine);
        let overrides = Overrides {
            record_period: Some(2e-3),
            ..Overrides::default()
        };
        let error = file.resolve_with(&model(), &overrides).unwrap_err();
        assert_eq!(
            error.to_string(),
            "--record-period: 0.002 s is longer than the control period (0.001 s): rows are \
             recorded at every tick already; give at most the control period"
        );
    }

    #[test]
    fn the_run_holds_at_least_one_tick_and_waypoints_a_period_apart() {
        refused(
            &format!("control_period = 1.0\nduration = 0.05\n{REFERENCE}"),
            "x.toml:2: field `duration`: 0.05 s is shorter than the control period (1 s)",
        );
        let waypoints = |t2: &str| {
            format!(
                "control_period = 0.1\n[reference]\nwaypoints = [\n  {{ t = 0.2, q = [0, 0, 0, 0, 0, 0] }},\n  {{ t = {t2}, q = [0.01, 0, 0, 0, 0, 0] }},\n]\n"
            )
        };
        refused(
            &waypoints("0.2000000001"),
            "x.toml:5: field `reference.waypoints[2].t`: 0.2000000001 s is 1.00e-10 s after \
             waypoint 1 (0.2 s); consecutive waypoints must be at least one control period \
             apart (0.1 s)",
        );
        refused(
            &waypoints("0.1"),
            "times must increase: 0.1 s follows 0.2 s",
        );
        // 0.3 − 0.2 rounds to 0.09999999999999998: one period, written in decimals.
        assert!(resolve(&waypoints("0.3")).is_ok());
        // Waypoints at 0 and 1e-300 s gave a NaN tick.
        refused(
            "[reference]\nwaypoints = [{ t = 0, q = [0, 0, 0, 0, 0, 0] },\n  \
             { t = 1e-300, q = [0.01, 0, 0, 0, 0, 0] }]\n",
            "x.toml:3: field `reference.waypoints[2].t`: 1e-300 s is 1.00e-300 s after \
             waypoint 1 (0 s); consecutive waypoints must be at least one control period \
             apart (0.001 s)",
        );
    }
}
