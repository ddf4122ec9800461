//! `softcbf identify`: stiffness, damping and actuator gains from the robot's own logs
//! (paper §V; docs/model.md §4), by least squares on the equation of motion.
//!
//! The equation `M q̈ + h + G + K q + D q̇ = A diag(u) g` (`u = max(s·I, 0)`, the goal
//! currents that pull) is linear in the unknowns of each module: `κθ, κL, βθ, βL` and the
//! three actuator gains `g_k`. Masses and geometry are the robot file's.
//!
//! - [`logs`]: `trajectory.csv`, `summary.json` and `hardware.json` read and checked.
//! - [`filter`]: one smooth kernel applied to both sides of the equation ("filtered
//!   differentiation" without differentiating data: the derivatives move onto the kernel).
//! - `rows`, `regression`, `estimate`: the stacked weighted least-squares problem, reduced
//!   by faer's QR block by block; excitation (zero columns, tiny singular values), held
//!   and tied parameters, delete-one-block jackknife standard errors, and the refits with
//!   moved landing times, a wider filter and more noise (`noise`) that give their
//!   systematic parts.
//! - `holdout`, [`figure`]: the last 20 % of each dynamic log predicted by the plant with
//!   the identified numbers and with the file's.
//! - [`output`]: the identified robot file, the input with only those numbers changed and
//!   an `[uncertainty]` table from the standard errors ([`bounds`]).
//! - [`synthetic`]: logs of a simulated robot, for tests and benchmarks.
//!
//! Why this filter: a log's readings are quantized and noisy, so `q̇`, `q̈` are never formed
//! pointwise. Filtering every term of the equation with the same kernel keeps it exact for
//! the linear terms (`K F[q]`, `D F[q̇]`, `A diag(F[u]) g`), needs no derivative of data
//! (`F[q̈] = ∫ k″ q`), and handles non-uniform sample times and commands that land between
//! readings exactly. Only the known nonlinear terms are approximated, at the filtered
//! state: `M(q̄) F[q̈] + F[1] (h(q̄, v̄) + G(q̄))` (filtering `G(q)` reading by reading
//! changed no estimate by more than 1e-4 of itself, at twice the cost). The half-width `T`
//! is `max(0.08 s, 5 periods)`: windows of at least ten readings (four per half-width gave
//! 4 % errors, quadrature of `k″` over too few points), yet short against the motion, so
//! that `M`, `h` vary little across a window. Measured on exact synthetic logs of the
//! example robot (a static and a multisine experiment; `accuracy_against_rate_and_half_width`
//! in tests/tests/hardware/identify.rs): at 100 and 200 Hz every number within 0.3 % for T from
//! 0.06 to 0.2 s, at 50 Hz within 0.9 %; at 33 Hz all within 0.9 % but module 2's bending
//! damping, off by 2–8 % depending on where the readings fall between command landings:
//! the tension steps excite that light module's damped modes (time constants near 15 ms)
//! faster than readings 30 ms apart resolve. Run the dynamic experiment at 100 Hz where the
//! bus allows; a slower log gets a note in the report.

// The lower crates' modules at the root, so that the paths the files had in `softcbf`
// (`crate::model`, `crate::hardware::log`, …) keep resolving. This crate's own `output` and
// `noise` modules take those two names: the outputs crate's console and the core's noise
// are named by their crates.
use softcbf_core::{dynamics, exit, hardware_description, integrator, model, plant, record};
use softcbf_figures::plot;
use softcbf_hardware as hardware;
use softcbf_outputs::mcap_log;

pub mod bounds;
pub mod figure;
pub mod filter;
pub mod holdout;
pub mod logs;
pub mod output;
pub mod synthetic;

mod estimate;
mod noise;
mod regression;
mod rows;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use clap::Args;
use softcbf_description::robot::{Robot, RobotError};
use softcbf_outputs::output::Console;

use crate::hardware::log_description::{DescriptionError, LogDescription};
use crate::hardware_description::{self as description, Hardware};
use crate::model::{Model, ModelError};

pub use estimate::{Fit, KindStats, Status};
pub use holdout::Prediction;
pub use logs::{ExperimentKind, Log, read_logs};

/// Unknowns per module: `κθ, κL, βθ, βL, g₁, g₂, g₃`.
pub const PER_MODULE: usize = 7;

/// One identified number of a module.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Parameter {
    /// `κθ` \[N·m/rad\] (`bending_stiffness`).
    BendingStiffness,
    /// `κL` \[N/m\] (`axial_stiffness`).
    AxialStiffness,
    /// `βθ` \[N·m·s/rad\] (`bending_damping`).
    BendingDamping,
    /// `βL` \[N·s/m\] (`axial_damping`).
    AxialDamping,
    /// The actuator gain of the servo of tendon `k` (0, 1, 2) \[N/mA\].
    ActuatorGain(usize),
}

impl Parameter {
    /// The module and parameter of unknown `j` (`PER_MODULE` per module, in the order of
    /// the variants).
    pub fn of_index(j: usize) -> (usize, Parameter) {
        let parameter = match j % PER_MODULE {
            0 => Parameter::BendingStiffness,
            1 => Parameter::AxialStiffness,
            2 => Parameter::BendingDamping,
            3 => Parameter::AxialDamping,
            k => Parameter::ActuatorGain(k - 4),
        };
        (j / PER_MODULE, parameter)
    }

    /// The index of this parameter of `module`.
    pub fn index(self, module: usize) -> usize {
        PER_MODULE * module
            + match self {
                Parameter::BendingStiffness => 0,
                Parameter::AxialStiffness => 1,
                Parameter::BendingDamping => 2,
                Parameter::AxialDamping => 3,
                Parameter::ActuatorGain(k) => 4 + k.min(2),
            }
    }

    /// Its symbol (`κθ`, `κL`, `βθ`, `βL`, `g1`…).
    pub fn symbol(self) -> String {
        match self {
            Parameter::BendingStiffness => "κθ".into(),
            Parameter::AxialStiffness => "κL".into(),
            Parameter::BendingDamping => "βθ".into(),
            Parameter::AxialDamping => "βL".into(),
            Parameter::ActuatorGain(k) => format!("g{}", k + 1),
        }
    }

    /// Its unit.
    pub fn unit(self) -> &'static str {
        match self {
            Parameter::BendingStiffness => "N·m/rad",
            Parameter::AxialStiffness => "N/m",
            Parameter::BendingDamping => "N·m·s/rad",
            Parameter::AxialDamping => "N·s/m",
            Parameter::ActuatorGain(_) => "N/mA",
        }
    }

    /// Its key in the robot file.
    pub fn key(self) -> &'static str {
        match self {
            Parameter::BendingStiffness => "bending_stiffness",
            Parameter::AxialStiffness => "axial_stiffness",
            Parameter::BendingDamping => "bending_damping",
            Parameter::AxialDamping => "axial_damping",
            Parameter::ActuatorGain(_) => "actuator_gain",
        }
    }

    /// `κθ of module 1`, `g2 of module 2` for unknown `j`.
    pub fn describe(j: usize) -> String {
        let (module, parameter) = Parameter::of_index(j);
        format!("{} of module {}", parameter.symbol(), module + 1)
    }
}

/// Why identification gave no result (and wrote nothing).
#[derive(Debug, thiserror::Error)]
pub enum IdentifyError {
    /// No log directory was named.
    #[error(
        "no logs given: name one or more run directories (each with trajectory.csv and \
         summary.json, as `softcbf run --experiment static|dynamic --out DIR` writes them)"
    )]
    NoLogs,
    /// A log directory without `trajectory.csv`.
    #[error(
        "{}: no trajectory.csv in this directory (give the directories `softcbf run --out` wrote)",
        dir.display()
    )]
    MissingTrajectory {
        /// The directory.
        dir: PathBuf,
    },
    /// A file could not be read or written.
    #[error("{}: {message}", file.display())]
    Io {
        /// The file.
        file: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A column identification needs is missing.
    #[error("{}:1: no column `{column}`{why}", file.display())]
    MissingColumn {
        /// The file.
        file: PathBuf,
        /// The column's name.
        column: String,
        /// Why it might be missing.
        why: &'static str,
    },
    /// A value that cannot be used.
    #[error("{}:{line}: column `{column}`: {what}", file.display())]
    Value {
        /// The file.
        file: PathBuf,
        /// 1-based line.
        line: usize,
        /// The column.
        column: String,
        /// What is wrong.
        what: String,
    },
    /// Too little data for the unknowns.
    #[error("{}: too short: {have}; needs {need}", file.display())]
    TooShort {
        /// The file (or `the logs`).
        file: PathBuf,
        /// What it has.
        have: String,
        /// What it needs.
        need: String,
    },
    /// Most commands at a limit.
    #[error("{}: saturated: {message}", file.display())]
    Saturated {
        /// The file.
        file: PathBuf,
        /// The counts and what to do.
        message: String,
    },
    /// A log of another robot.
    #[error("{}: from a different robot: {what}", file.display())]
    DifferentRobot {
        /// The file.
        file: PathBuf,
        /// What differs.
        what: String,
    },
    /// A log's `hardware.json` missing or unreadable.
    #[error(transparent)]
    Description(#[from] DescriptionError),
    /// The robot file is not valid.
    #[error(transparent)]
    Robot(#[from] RobotError),
    /// The robot has no generated model.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The robot file has no `[hardware]` table, or another problem of the robot.
    #[error("{}: {message}", file.display())]
    RobotFile {
        /// The robot file.
        file: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The regression failed.
    #[error("identification failed: {0}")]
    Fit(String),
}

/// How identification is done. [`Options::default`] is what `softcbf identify` uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Half-width `T` of the filter kernel \[s\] (`None`: [`filter::default_half_width`]
    /// of the logs' median reading period).
    pub half_width: Option<f64>,
    /// Least time between output instants, as a share of `T` (0: every reading). The
    /// default 0.25 (an instant every 20 ms at 100 Hz): the filtered rows of neighbouring
    /// readings say nearly the same; measured, the standard errors grow by 15 % and the
    /// time of the fit falls by 40 % against every reading.
    pub spacing: f64,
    /// Share of each dynamic log, at its end, kept out of the fit and predicted.
    pub holdout: f64,
    /// Blocks of time of the jackknife.
    pub blocks: usize,
    /// Longest stretch of a held-out part simulated \[s\].
    pub horizon: f64,
    /// Simulate the held-out parts.
    pub predict: bool,
    /// Standard uncertainty of the time between a reading's sampling and a command's
    /// landing \[s\] ([`TIMING_UNCERTAINTY`] by default); with `systematic`, the fit is
    /// repeated with every landing moved by `±` this.
    pub timing_uncertainty: f64,
    /// Add the systematic parts (timing and filter) to the standard errors.
    pub systematic: bool,
}

/// The default standard uncertainty of the time between sampling and landing \[s\]. A
/// USB full-speed adapter moves bytes in 1 ms frames: a write reaches the bus somewhere in
/// the frame after the call, and a reply reaches the host somewhere in its frame. Two
/// independent errors, each uniform over 1 ms, have a standard deviation of
/// `√(2/12)` ms = 0.41 ms; rounded up.
pub const TIMING_UNCERTAINTY: f64 = 0.5e-3;

impl Default for Options {
    fn default() -> Self {
        Options {
            half_width: None,
            spacing: 0.25,
            holdout: 0.2,
            blocks: 20,
            horizon: 10.0,
            predict: true,
            timing_uncertainty: TIMING_UNCERTAINTY,
            systematic: true,
        }
    }
}

/// The filter part of the standard errors compares the fit with one whose kernel is this
/// many times wider.
pub const FILTER_CHECK: f64 = 1.5;

/// Readings further apart than this \[s\] get the note on damping in the report.
pub const SLOW_PERIOD: f64 = 1.0 / 60.0;

/// Per-log facts for the report.
#[derive(Clone, Debug, PartialEq)]
pub struct LogFacts {
    /// The directory's name.
    pub name: String,
    /// Readings (fresh rows).
    pub readings: usize,
    /// Whether its last part was held out.
    pub dynamic: bool,
}

/// The result of identification.
#[derive(Clone, Debug)]
pub struct Identification {
    /// The file's value of every parameter ([`Parameter::of_index`] order).
    pub file: Vec<f64>,
    /// The fit: values, standard errors, statuses.
    pub fit: Fit,
    /// The logs used.
    pub logs: Vec<LogFacts>,
    /// Output instants (dynamic) and rest states (static) used.
    pub instants: usize,
    /// Rest states used.
    pub rest_states: usize,
    /// Static and dynamic rows.
    pub rows: [usize; 2],
    /// The filter's half-width \[s\].
    pub half_width: f64,
    /// The median interval between readings over all logs \[s\].
    pub period: f64,
    /// The timing uncertainty of the systematic part \[s\] (`None`: no systematic part).
    pub timing_uncertainty: Option<f64>,
    /// Share of each dynamic log held out.
    pub holdout: f64,
    /// The held-out predictions, one per dynamic log.
    pub predictions: Vec<Prediction>,
    /// Remarks (a prediction that failed, …).
    pub notes: Vec<String>,
}

impl Identification {
    /// Number of modules.
    pub fn modules(&self) -> usize {
        self.file.len() / PER_MODULE
    }

    /// The value of `parameter` of `module`: identified, or the file's where kept.
    pub fn value(&self, module: usize, parameter: Parameter) -> f64 {
        self.fit.theta[parameter.index(module)]
    }

    /// Whether `parameter` of `module` was identified.
    pub fn identified(&self, module: usize, parameter: Parameter) -> bool {
        self.fit.status[parameter.index(module)] == Status::Identified
    }

    /// The actuator gain of every servo \[N/mA\] (identified or the file's).
    pub fn gains(&self) -> Vec<f64> {
        (0..self.modules())
            .flat_map(|i| (0..3).map(move |k| (i, k)))
            .map(|(i, k)| self.value(i, Parameter::ActuatorGain(k)))
            .collect()
    }

    /// `robot` with the identified stiffness and damping (gains live in the hardware
    /// table: [`Identification::gains`]).
    pub fn identified_robot(&self, robot: &Robot) -> Robot {
        let mut robot = robot.clone();
        for (i, module) in robot.modules.iter_mut().enumerate() {
            module.bending_stiffness = self.value(i, Parameter::BendingStiffness);
            module.axial_stiffness = self.value(i, Parameter::AxialStiffness);
            module.bending_damping = self.value(i, Parameter::BendingDamping);
            module.axial_damping = self.value(i, Parameter::AxialDamping);
        }
        robot
    }

    /// The report `softcbf identify` prints, one line each.
    pub fn report(&self) -> Vec<String> {
        output::report(self)
    }
}

/// The file's values of every parameter, in [`Parameter::of_index`] order.
pub fn file_values(robot: &Robot, hardware: &Hardware) -> Vec<f64> {
    robot
        .modules
        .iter()
        .zip(&hardware.modules)
        .flat_map(|(m, hw)| {
            [
                m.bending_stiffness,
                m.axial_stiffness,
                m.bending_damping,
                m.axial_damping,
                hw.actuator_gain[0],
                hw.actuator_gain[1],
                hw.actuator_gain[2],
            ]
        })
        .collect()
}

/// The robot's hardware description, required for identification.
pub fn hardware_of(robot: &Robot) -> Result<Hardware, IdentifyError> {
    description::load(robot)?.ok_or_else(|| IdentifyError::RobotFile {
        file: robot.source.clone(),
        message: "no [hardware] table: identification needs the servos' directions, \
                      current unit and actuator gains"
            .into(),
    })
}

/// Reads the run directories `dirs` as logs of `robot` (its name, coordinates, servos and
/// the hardware description each log was taken with must match): [`read_logs`] with what
/// `robot` says a log must have.
pub fn read_logs_for(robot: &Robot, dirs: &[PathBuf]) -> Result<Vec<Log>, IdentifyError> {
    let hardware = hardware_of(robot)?;
    let expected = logs::Expected {
        name: &robot.name,
        file: &robot.source,
        nq: 3 * robot.modules.len(),
        hardware: &hardware,
        description: LogDescription::of(robot, &hardware),
    };
    read_logs(dirs, &expected)
}

/// The median interval between readings over all logs \[s\].
fn median_period(logs: &[Log]) -> Option<f64> {
    let mut intervals: Vec<f64> = logs
        .iter()
        .flat_map(|log| log.time.windows(2).map(|w| w[1] - w[0]))
        .collect();
    if intervals.is_empty() {
        return None;
    }
    let middle = intervals.len() / 2;
    let (_, median, _) = intervals.select_nth_unstable_by(middle, f64::total_cmp);
    Some(*median)
}

/// Identifies `robot`'s stiffness, damping and actuator gains from `logs` (read by
/// [`read_logs`] against the same robot).
pub fn identify(
    robot: &Robot,
    logs: &[Log],
    options: &Options,
) -> Result<Identification, IdentifyError> {
    if logs.is_empty() {
        return Err(IdentifyError::NoLogs);
    }
    let hardware = hardware_of(robot)?;
    let model = Model::new(robot.clone())?;
    let period = median_period(logs).unwrap_or(0.01);
    let half_width = match options.half_width {
        Some(t) => t,
        None => filter::default_half_width(period),
    };
    if !(half_width > 0.0 && half_width.is_finite()) {
        return Err(IdentifyError::Fit(format!(
            "the filter half-width must be positive, got {half_width} s"
        )));
    }
    let kernel = filter::Kernel::new(half_width);
    let settings = rows::RowSettings {
        kernel,
        spacing: options.spacing.max(0.0) * half_width,
        holdout: options.holdout.clamp(0.0, 0.9),
        blocks: options.blocks.max(1),
    };
    // The rows, and with the systematic parts the same rows with every landing moved by
    // ∓σ (one pass: only the currents' filtering differs).
    let sigma = options.timing_uncertainty.max(0.0);
    let shifts: &[f64] = if options.systematic && sigma > 0.0 {
        &[0.0, -sigma, sigma]
    } else {
        &[0.0]
    };
    let mut variants = rows::build_shifted(&model, &hardware, logs, &settings, shifts)?;
    let shifted = variants.split_off(1);
    let Some(built) = variants.pop() else {
        return Err(IdentifyError::Fit("no rows were built".into()));
    };
    let file = file_values(robot, &hardware);
    let mut fit = estimate::fit(&built, &file).map_err(IdentifyError::Fit)?;
    let mut notes = Vec::new();
    if options.systematic {
        // The same fit on rows made a little differently: the spread is an error the
        // jackknife cannot see, as every block shares it.
        let timing = match shifted.as_slice() {
            [minus, plus] => estimate::refit(minus, &fit).zip(estimate::refit(plus, &fit)),
            _ => None,
        };
        let wide = filter::Kernel::new(FILTER_CHECK * half_width);
        let filter = rows::build(
            &model,
            &hardware,
            logs,
            &rows::RowSettings {
                kernel: wide,
                spacing: options.spacing.max(0.0) * wide.half_width(),
                ..settings
            },
        )
        .ok()
        .and_then(|rows| estimate::refit(&rows, &fit));
        // The noise measured at rest, added once more: the change approximates the bias
        // the noise already in the readings causes (it grows with the noise's variance).
        let noise = noise::at_rest(logs)
            .filter(|sigma| sigma.iter().any(|&s| s > 0.0))
            .and_then(|sigma| {
                // One log per thread: each draws from its own seed.
                let noisy: Vec<Log> = parallel_map(logs.len(), |l| {
                    noise::with_added(&logs[l], &sigma, noise::SEED + l as u64)
                });
                rows::build(&model, &hardware, &noisy, &settings).ok()
            })
            .and_then(|rows| estimate::refit(&rows, &fit));
        if sigma > 0.0 && timing.is_none() {
            notes.push(
                "note: the fit with the landing times moved could not be solved; the standard \
                 errors lack the timing part"
                    .to_string(),
            );
        }
        if filter.is_none() {
            notes.push(format!(
                "note: the fit with a {:.3} s filter could not be solved (logs too short?); the \
                 standard errors lack the filter part",
                wide.half_width()
            ));
        }
        if noise.is_none() {
            notes.push(
                "note: the standard errors lack the noise part (no rest state in the logs shows \
                 noise to measure, or the fit with more noise failed)"
                    .to_string(),
            );
        }
        estimate::add_systematic(
            &mut fit,
            &estimate::Refits {
                timing,
                filter,
                noise,
            },
        );
    }
    if fit.status.iter().all(|s| *s != Status::Identified) {
        let reasons: Vec<String> = fit
            .status
            .iter()
            .enumerate()
            .filter_map(|(j, s)| match s {
                Status::Kept(reason) => Some(format!("{}: {reason}", Parameter::describe(j))),
                Status::Identified => None,
            })
            .take(3)
            .collect();
        return Err(IdentifyError::Fit(format!(
            "these logs identify none of the numbers ({}, …)",
            reasons.join("; ")
        )));
    }
    let mut identification = Identification {
        file,
        fit,
        logs: logs
            .iter()
            .map(|log| LogFacts {
                name: log.name(),
                readings: log.readings(),
                dynamic: rows::is_dynamic(log),
            })
            .collect(),
        instants: built.instants,
        rest_states: built.rest_states,
        rows: built.rows,
        half_width,
        period,
        timing_uncertainty: options
            .systematic
            .then_some(options.timing_uncertainty.max(0.0)),
        holdout: settings.holdout,
        predictions: Vec::new(),
        notes,
    };
    if period > SLOW_PERIOD {
        identification.notes.push(format!(
            "note: readings every {:.1} ms: below 60 Hz the damping of light modules with fast \
             modes may be off by several percent (module 2 of the example robot: 2–8 % at 33 Hz \
             on exact synthetic logs, 15–18 % through the emulator); widen [uncertainty] on \
             damping accordingly (docs/hardware.md, Identifying stiffness, damping and actuator gains)",
            1e3 * period
        ));
    }
    if options.predict {
        let identified = Model::new(identification.identified_robot(robot))?;
        let gains = identification.gains();
        let file_gains: Vec<f64> = hardware
            .modules
            .iter()
            .flat_map(|m| m.actuator_gain)
            .collect();
        for log in logs.iter().filter(|log| rows::is_dynamic(log)) {
            let plants = [
                holdout::Plant {
                    model: &identified,
                    gains: &gains,
                },
                holdout::Plant {
                    model: &model,
                    gains: &file_gains,
                },
            ];
            match holdout::predict(
                &plants,
                &hardware,
                log,
                &kernel,
                settings.holdout,
                options.horizon,
            ) {
                Ok(Some(prediction)) => identification.predictions.push(prediction),
                Ok(None) => identification.notes.push(format!(
                    "{}: the held-out part is too short to predict",
                    log.name()
                )),
                Err(message) => identification.notes.push(format!(
                    "{}: the held-out prediction failed: {message}",
                    log.name()
                )),
            }
        }
    }
    Ok(identification)
}

/// Options of `softcbf identify`.
#[derive(Args, Debug)]
pub struct IdentifyArgs {
    /// The robot file whose numbers are identified (with a `[hardware]` table).
    #[arg(long)]
    pub robot: PathBuf,
    /// Run directories of `softcbf run` (`--experiment static`, `dynamic`, or any run),
    /// each with trajectory.csv and summary.json, or their MCAP logs (`run.mcap` of
    /// `softcbf run --mcap`, which holds all three).
    #[arg(value_name = "LOG_DIR")]
    pub logs: Vec<PathBuf>,
    /// The robot file to write: the input with the identified numbers (and a comment on
    /// each) replaced.
    #[arg(long)]
    pub out: PathBuf,
    /// Directory of the figure `identify.png`/`.svg` (default: beside --out).
    #[arg(long, value_name = "DIR")]
    pub figures: Option<PathBuf>,
    /// Half-width of the filter kernel (s) (default: 0.08 s or five reading periods,
    /// whichever is longer).
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub half_width: Option<f64>,
    /// Standard uncertainty of the time from a reading's sampling to a command's landing
    /// (ms), 0 to 20; part of every standard error (default 0.5: a USB full-speed
    /// adapter's 1 ms frames; 0 leaves the timing part out).
    #[arg(long, value_name = "MS", allow_negative_numbers = true)]
    pub timing_uncertainty_ms: Option<f64>,
}

/// `softcbf identify`: reads, fits, writes the robot file and the figure, prints the report.
pub fn run(args: IdentifyArgs, console: &mut Console) -> Result<u8, String> {
    if let Some(t) = args.half_width
        && !(t > 0.0 && t <= 10.0)
    {
        return Err(format!("--half-width: must be > 0 and ≤ 10 s, got {t}"));
    }
    if let Some(ms) = args.timing_uncertainty_ms
        && !(0.0..=20.0).contains(&ms)
    {
        return Err(format!(
            "--timing-uncertainty-ms: must be ≥ 0 and ≤ 20 ms, got {ms}"
        ));
    }
    if args.logs.is_empty() {
        return Err(IdentifyError::NoLogs.to_string());
    }
    output::check_out_path(&args.robot, &args.out).map_err(|e| e.to_string())?;
    let text = std::fs::read_to_string(&args.robot)
        .map_err(|e| format!("{}: {e}", args.robot.display()))?;
    let robot = Robot::parse(&text, &args.robot).map_err(|e| e.to_string())?;
    let logs = read_logs_for(&robot, &args.logs).map_err(|e| e.to_string())?;
    let options = Options {
        half_width: args.half_width,
        timing_uncertainty: args
            .timing_uncertainty_ms
            .map_or(TIMING_UNCERTAINTY, |ms| 1e-3 * ms),
        ..Options::default()
    };
    let identification = identify(&robot, &logs, &options).map_err(|e| e.to_string())?;
    let figures_dir = match &args.figures {
        Some(dir) => dir.clone(),
        None => args
            .out
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .map_or_else(|| PathBuf::from("."), Path::to_path_buf),
    };
    output::write_robot(&text, &robot, &identification, &args.out).map_err(|e| e.to_string())?;
    let mut written = vec![args.out.display().to_string()];
    if let Some(prediction) = identification.predictions.first() {
        let files = figure::draw(&figures_dir, "identify", prediction, &robot)
            .map_err(|e| e.to_string())?;
        written.extend(files.iter().map(|p| p.display().to_string()));
    }
    for line in identification.report() {
        console.say(&line);
    }
    let bounds = output::identified_bounds(&robot, &identification);
    console.say(&format!(
        "[uncertainty] written: stiffness {}, damping {} ({} standard errors of the least \
         certain identified number of each kind); mass {}, force {} N (not measured: the \
         input's); each line's comment in {} says where it came from",
        bounds.stiffness.value,
        bounds.damping.value,
        bounds::K_SIGMA,
        bounds.mass.value,
        bounds.force.value,
        args.out.display()
    ));
    // Each module's own box, the numbers it identified (the table's elsewhere).
    let show = |x: Option<f64>| x.map_or("table".to_string(), |x| x.to_string());
    for (i, own) in bounds.modules.iter().enumerate() {
        console.say(&format!(
            "module {} uncertainty written: κθ {}, κL {}, βθ {}, βL {} (its own {} standard \
             errors)",
            i + 1,
            show(own.bending_stiffness),
            show(own.axial_stiffness),
            show(own.bending_damping),
            show(own.axial_damping),
            bounds::K_SIGMA
        ));
    }
    console.say(&format!("wrote {}", written.join(", ")));
    if let Some(error) = console.error() {
        eprintln!("error: {error}");
        return Ok(crate::exit::ERROR);
    }
    Ok(crate::exit::OK)
}

/// `f(0), …, f(n − 1)` computed on up to the machine's parallelism of threads, in order.
pub fn parallel_map<T: Send>(n: usize, f: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let threads = std::thread::available_parallelism()
        .map_or(1, |t| t.get())
        .min(n);
    if threads <= 1 {
        return (0..n).map(f).collect();
    }
    let next = AtomicUsize::new(0);
    let mut parts: Vec<(usize, T)> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    let mut done = Vec::new();
                    loop {
                        let k = next.fetch_add(1, Ordering::Relaxed);
                        if k >= n {
                            break done;
                        }
                        done.push((k, f(k)));
                    }
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|handle| match handle.join() {
                Ok(done) => done,
                Err(panic) => std::panic::resume_unwind(panic),
            })
            .collect()
    });
    parts.sort_by_key(|(k, _)| *k);
    parts.into_iter().map(|(_, value)| value).collect()
}
