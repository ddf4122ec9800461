//! Identification experiments of `softcbf run --experiment`: the feed-forward tensions of
//! each tick (static tension sets held to rest, multisine excitation), under the filter.
//!
//! An [`Experiment`] knows nothing of the bus: each tick it is given the time and the state
//! read, writes the tensions it wants (one per servo, servo `3i + k` pulling tendon `k` of
//! module `i`) and returns a [`Mark`] for the log (`step`, `rest`). The run loop turns the
//! tensions into `τ = A f` and passes them through the safety filter; a simulation can
//! drive it the same way. [`Experiment::command`] allocates nothing.
//!
//! **Static.** A sequence of constant tension sets, per module a base tension `b` plus an
//! increment `a` on single tendons, shared by pairs and by all three, at two levels,
//! the first set repeated at the end ([`STATIC_PATTERNS`]); each set adds `a` or `a/2`
//! in all, so that a module with little room to compress still bends. The module's equilibrium
//! `K_i q_i + G_i(q) = A_i f_i` then sees its three tensions vary independently and their
//! sum vary against the weight, which fixes the scale of the stiffness and of each servo's
//! actuator gain. A set is held until the robot is at rest: after [`ExperimentSettings::
//! settle_time`], every coordinate has stayed within a band of
//! [`ExperimentSettings::rest_threshold`] for [`ExperimentSettings::quiet_window`]; the
//! next [`ExperimentSettings::rest_window`] of rows is marked `rest`. A set that does not
//! come to rest within [`ExperimentSettings::step_time`] is counted and left.
//!
//! **Dynamic.** Around a few operating points (base tensions, each for an equal share of
//! the duration, joined by raised-cosine fades), every servo adds a multisine: the grid
//! `k·f0` over the band is dealt out line by line, servo `j` taking every `n`-th line, so
//! the servos' excitations share no frequency (uncorrelated over a period `1/f0`); each
//! servo's lines have Schroeder phases and one amplitude, scaled so that the servo's
//! deviation never exceeds `a`, and `base ± a` stays inside `[f_min, f_max]`.
//!
//! **Defaults** ([`module_room`]): from the robot file's numbers (the weight each module
//! carries, its axial and bending stiffness, its limits and corners), the tensions that
//! keep a straight module within half of the room its barriers leave at `f_min`, for a
//! robot [`STIFFNESS_ALLOWANCE`] softer than the file says (the safety filter is the
//! backstop: when it changes a command, the tensions sent are logged).

use std::f64::consts::PI;

use softcbf_description::limits::Limit;
use softcbf_description::robot::Robot;

/// Amplitude `a` of an experiment \[N\]: above zero, up to a tendon tension's range.
pub const AMPLITUDE_N: Limit = Limit::above(0.0, 1e5, "N");
/// Base tension `b` of an experiment \[N\] (within a tendon tension's range).
pub const BASE_TENSION_N: Limit = Limit::closed(0.0, 1e5, "N");
/// Longest wait for a static step to come to rest \[s\]: up to an hour.
pub const STEP_TIME_S: Limit = Limit::above(0.0, 3600.0, "s");
/// Band within which a coordinate counts as at rest \[m\]: up to 10 cm.
pub const REST_THRESHOLD_M: Limit = Limit::above(0.0, 0.1, "m");

/// Length of a dynamic experiment when not given \[s\].
pub const DEFAULT_DYNAMIC_DURATION: f64 = 60.0;
/// Longest wait for a static step to come to rest \[s\]: many times the settling time of
/// the example robot's slowest mode (module 1 axial, `1/(ζω) ≈ 0.2 s`).
pub const DEFAULT_STEP_TIME: f64 = 6.0;
/// Least time a static set is held before rest is looked for \[s\].
pub const DEFAULT_SETTLE_TIME: f64 = 1.0;
/// The raised-cosine ramp from one static set to the next \[s\]: a few periods of the
/// example robot's fastest modes, so that a set change rings less.
pub const DEFAULT_RAMP: f64 = 0.3;
/// How long every coordinate must stay within the rest threshold \[s\].
pub const DEFAULT_QUIET_WINDOW: f64 = 0.5;
/// How long a set is kept once at rest, its rows marked `rest` \[s\].
pub const DEFAULT_REST_WINDOW: f64 = 1.0;
/// Rest threshold \[m\]: about four position quanta of a tendon wound on a 45 mm pulley by a
/// 4096-count encoder (0.07 mm each), so that a reading noisy by one count still counts as
/// at rest.
pub const DEFAULT_REST_THRESHOLD: f64 = 3e-4;
/// Operating points of a dynamic experiment.
pub const DEFAULT_OPERATING_POINTS: usize = 3;
/// Raised-cosine fade between operating points \[s\].
pub const DEFAULT_FADE: f64 = 1.0;
/// Band of the multisines \[Hz\]; the upper end is also at most a sixth of the loop rate.
pub const DEFAULT_BAND: [f64; 2] = [0.2, 5.0];
/// Spacing `f0` of the multisines' frequency grid \[Hz\] (period `1/f0`).
pub const DEFAULT_RESOLUTION: f64 = 0.1;

/// The loop rate over the multisines' highest frequency, at least.
const SAMPLES_PER_PERIOD: f64 = 6.0;

/// Static tension sets per module: the increment over the base on each tendon, as a
/// multiple of the amplitude `a`. Every set adds `a` or `a/2` in all to the module's
/// tensions, on one tendon, two or all three (so each tendon's tension varies on its own,
/// and the bend with it, while the compression stays what one tendon's increment gives),
/// between the base set and the base set again (drift, hysteresis).
pub const STATIC_PATTERNS: [[f64; 3]; 16] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.5, 0.5, 0.0],
    [0.0, 0.5, 0.5],
    [0.5, 0.0, 0.5],
    [THIRD, THIRD, THIRD],
    [0.5, 0.0, 0.0],
    [0.0, 0.5, 0.0],
    [0.0, 0.0, 0.5],
    [0.25, 0.25, 0.0],
    [0.0, 0.25, 0.25],
    [0.25, 0.0, 0.25],
    [SIXTH, SIXTH, SIXTH],
    [0.0, 0.0, 0.0],
];

const THIRD: f64 = 1.0 / 3.0;
const SIXTH: f64 = 1.0 / 6.0;

/// How much softer than its file the robot the defaults are chosen for is (or the
/// declared `[uncertainty] stiffness`, if larger): a robot that sags more than its file
/// says starts nearer its compression limit and goes further with each newton.
pub const STIFFNESS_ALLOWANCE: f64 = 0.3;

/// Which experiment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExperimentKind {
    /// Constant tension sets held to rest (stiffness, actuator gain).
    Static,
    /// Multisines around operating points (damping, actuator gain).
    Dynamic,
}

impl ExperimentKind {
    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ExperimentKind::Static => "static",
            ExperimentKind::Dynamic => "dynamic",
        }
    }

    /// The experiment named `text`.
    pub fn parse(text: &str) -> Result<ExperimentKind, String> {
        match text.trim() {
            "static" => Ok(ExperimentKind::Static),
            "dynamic" => Ok(ExperimentKind::Dynamic),
            other => Err(format!(
                "`{other}` is not an experiment; use `static` or `dynamic`"
            )),
        }
    }
}

/// What an experiment does; `None` where the robot's numbers choose ([`module_room`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ExperimentSettings {
    /// Static or dynamic.
    pub kind: ExperimentKind,
    /// Base tension `b` per module \[N\] (one entry: every module): the static sets' base,
    /// the dynamic experiment's lowest operating point.
    pub base_tension: Option<Vec<f64>>,
    /// Amplitude `a` per module \[N\] (one entry: every module): the static increment, the
    /// largest deviation of a dynamic servo's multisine.
    pub amplitude: Option<Vec<f64>>,
    /// Dynamic: the length \[s\] (default [`DEFAULT_DYNAMIC_DURATION`]); static: a cap (the
    /// steps not run by then are left).
    pub duration: Option<f64>,
    /// Static: longest wait for a set to come to rest \[s\].
    pub step_time: f64,
    /// Static: least time a set is held before rest is looked for \[s\] (counted from the
    /// start of its ramp).
    pub settle_time: f64,
    /// Static: the raised-cosine ramp from one set's tensions to the next's (the first
    /// from `f_min`) \[s\].
    pub ramp: f64,
    /// Static: how long every coordinate must stay within `rest_threshold` \[s\].
    pub quiet_window: f64,
    /// Static: how long a set is kept once at rest, its rows marked `rest` \[s\].
    pub rest_window: f64,
    /// Static: the band (max − min) within which a coordinate counts as at rest \[m\].
    pub rest_threshold: f64,
    /// Dynamic: number of operating points.
    pub operating_points: usize,
    /// Dynamic: the raised-cosine fade into each operating point \[s\].
    pub fade: f64,
    /// Dynamic: the multisines' band \[Hz\] (the upper end at most a sixth of the loop rate).
    pub band: [f64; 2],
    /// Dynamic: the frequency grid's spacing `f0` \[Hz\].
    pub resolution: f64,
}

impl ExperimentSettings {
    /// The defaults of `kind`.
    pub fn new(kind: ExperimentKind) -> ExperimentSettings {
        ExperimentSettings {
            kind,
            base_tension: None,
            amplitude: None,
            duration: None,
            step_time: DEFAULT_STEP_TIME,
            settle_time: DEFAULT_SETTLE_TIME,
            ramp: DEFAULT_RAMP,
            quiet_window: DEFAULT_QUIET_WINDOW,
            rest_window: DEFAULT_REST_WINDOW,
            rest_threshold: DEFAULT_REST_THRESHOLD,
            operating_points: DEFAULT_OPERATING_POINTS,
            fade: DEFAULT_FADE,
            band: DEFAULT_BAND,
            resolution: DEFAULT_RESOLUTION,
        }
    }

    /// The dynamic experiment's length, or the static one's cap \[s\].
    pub fn length(&self) -> Option<f64> {
        match self.kind {
            ExperimentKind::Dynamic => Some(self.duration.unwrap_or(DEFAULT_DYNAMIC_DURATION)),
            ExperimentKind::Static => self.duration,
        }
    }

    /// Checks every number against its range and the others, without the robot; messages
    /// name the command-line option.
    pub fn validate(&self) -> Result<(), String> {
        let check = |name: &str, value: f64, limit: &Limit| {
            limit
                .check(value)
                .map(|_| ())
                .map_err(|m| format!("{name}: {m}"))
        };
        for (name, values, limit) in [
            ("--base-tension", &self.base_tension, &BASE_TENSION_N),
            ("--amplitude", &self.amplitude, &AMPLITUDE_N),
        ] {
            if let Some(values) = values {
                if values.is_empty() {
                    return Err(format!("{name}: needs a value"));
                }
                for &v in values {
                    check(name, v, limit)?;
                }
            }
        }
        if let Some(d) = self.duration {
            check("--duration", d, &softcbf_description::limits::DURATION_S)?;
        }
        check("--step-time", self.step_time, &STEP_TIME_S)?;
        check("--rest-threshold", self.rest_threshold, &REST_THRESHOLD_M)?;
        for (name, value) in [
            ("settle time", self.settle_time),
            ("quiet window", self.quiet_window),
            ("rest window", self.rest_window),
            ("fade", self.fade),
            ("resolution", self.resolution),
        ] {
            check(name, value, &STEP_TIME_S)?;
        }
        if !(0.0..=self.settle_time).contains(&self.ramp) {
            return Err(format!(
                "ramp: must be ≥ 0 and at most the settle time {} s, got {}",
                self.settle_time, self.ramp
            ));
        }
        if self.step_time <= self.settle_time.max(self.quiet_window) {
            return Err(format!(
                "--step-time: {} s leaves no time to come to rest: a set is held at least {} s \
                 before rest is looked for",
                self.step_time,
                self.settle_time.max(self.quiet_window)
            ));
        }
        if !(1..=100).contains(&self.operating_points) {
            return Err(format!(
                "operating points: must be 1 to 100, got {}",
                self.operating_points
            ));
        }
        let [lo, hi] = self.band;
        if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo < hi) {
            return Err(format!("band: must be 0 < low < high, got [{lo}, {hi}] Hz"));
        }
        if self.kind == ExperimentKind::Dynamic {
            let length = self.length().unwrap_or(DEFAULT_DYNAMIC_DURATION);
            let share = length / self.operating_points as f64;
            if share <= self.fade {
                return Err(format!(
                    "--duration: {length} s gives each of the {} operating points {share:.3} s, \
                     not more than its fade of {} s",
                    self.operating_points, self.fade
                ));
            }
        }
        Ok(())
    }
}

/// What one tick of an experiment is, for its log row.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Mark {
    /// The step: a static set, or a dynamic operating point (from 0).
    pub step: usize,
    /// Whether the row's reading is part of a static set's rest state.
    pub rest: bool,
}

/// What the robot file's numbers leave a module for an experiment: its straight
/// equilibrium under its load with `f_min` on every tendon, and the tensions that keep it
/// within half of the room its barriers leave from there, all for a module
/// [`STIFFNESS_ALLOWANCE`] softer than the file's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModuleRoom {
    /// Weight the module carries along its axis when straight \[N\]: its own plate and
    /// every one above (gravity's component along the base's −z).
    pub load: f64,
    /// The stiffness factor the room is reckoned with (`1 − allowance`).
    pub softer: f64,
    /// `δL` of the straight module with `f_min` on every tendon \[m\].
    pub elongation_at_f_min: f64,
    /// The lowest `δL` its barriers allow \[m\]: the elongation limit plus its margin, or
    /// the plates' corners at their margin, whichever is higher.
    pub lowest_elongation: f64,
    /// Total tension above `3 f_min` that takes it half of the way there \[N\] (at most
    /// `3 (f_max − f_min)`).
    pub extra_tension: f64,
    /// A bending force (a tension on one tendon over the others) that bends it half of
    /// the way to its bend limit or to its corners touching \[N\].
    pub bend_tension: f64,
}

/// [`ModuleRoom`] of each module of `robot`, whose tendons are held in `tension_limits`
/// (`[f_min, f_max]` per module), from the linear statics of a straight module:
/// `κL δL = −(load + Σ f)`, `θ = d·F/κθ` for a bending force `F`, with both stiffnesses
/// lowered by [`STIFFNESS_ALLOWANCE`] (or the declared uncertainty, if larger).
pub fn module_room(robot: &Robot, tension_limits: &[[f64; 2]]) -> Vec<ModuleRoom> {
    let down = -robot.gravity[2];
    let softer = 1.0 - STIFFNESS_ALLOWANCE.max(robot.uncertainty.stiffness);
    let n = robot.modules.len();
    (0..n)
        .map(|i| {
            let module = &robot.modules[i];
            let limits = robot.limits.get(i);
            let [f_min, f_max] = tension_limits.get(i).copied().unwrap_or([0.0, 0.0]);
            let carried: f64 = robot.modules[i..].iter().map(|m| m.mass).sum();
            let load = down * carried;
            let kappa_l = softer * module.axial_stiffness;
            let elongation_at_f_min = if kappa_l > 0.0 {
                -(load + 3.0 * f_min) / kappa_l
            } else {
                f64::NEG_INFINITY
            };
            let corner_margin = module.margins.iter().copied().fold(0.0, f64::max);
            let mut lowest = -module.rest_length + corner_margin;
            if let Some(l) = limits {
                lowest = lowest.max(l.elongation[0] + l.elongation_margin);
            }
            let room = elongation_at_f_min - lowest;
            let extra_tension = if room.is_finite() && room > 0.0 {
                (0.5 * kappa_l * room).min(3.0 * (f_max - f_min).max(0.0))
            } else {
                0.0
            };
            // Bend room: the bend limit, or a corner at radius r dropping r·sin θ onto the
            // plate below from the height L0 + δL.
            let height = module.rest_length + elongation_at_f_min.max(lowest) - corner_margin;
            let mut bend = if module.corner_radius > height {
                (height.max(0.0) / module.corner_radius).asin()
            } else {
                PI / 2.0
            };
            if let Some(l) = limits {
                bend = bend.min(l.max_bend - l.bend_margin);
            }
            let bend_tension = (0.5 * bend.max(0.0) * softer * module.bending_stiffness
                / module.tendon_radius)
                .max(0.0);
            ModuleRoom {
                load,
                softer,
                elongation_at_f_min,
                lowest_elongation: lowest,
                extra_tension,
                bend_tension,
            }
        })
        .collect()
}

/// One line of a multisine: `amplitude · cos(omega t + phase)`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Line {
    omega: f64,
    phase: f64,
    amplitude: f64,
}

/// The counts and the design of an experiment, for the summary.
#[derive(Clone, Debug, PartialEq)]
pub struct ExperimentReport {
    /// The settings, as given (the defaults filled in where the robot does not choose).
    pub settings: ExperimentSettings,
    /// Base tension per module \[N\] (dynamic: the lowest operating point).
    pub base_tension: Vec<f64>,
    /// Amplitude per module \[N\].
    pub amplitude: Vec<f64>,
    /// Dynamic: the base tension of each operating point per module \[N\], `[module][point]`.
    pub operating_points: Vec<Vec<f64>>,
    /// Dynamic: the multisines' band used \[Hz\] (lowest and highest line).
    pub band: [f64; 2],
    /// Dynamic: frequency lines per servo.
    pub lines_per_servo: Vec<usize>,
    /// Steps planned (static sets or operating points).
    pub steps: usize,
    /// Steps begun.
    pub steps_run: usize,
    /// Static steps that came to rest.
    pub steps_at_rest: usize,
    /// Static steps that did not come to rest within the step time.
    pub steps_without_rest: usize,
    /// Rows marked `rest`.
    pub rest_rows: u64,
    /// Whether every step ran to its end.
    pub complete: bool,
}

/// An experiment's tensions, tick by tick; see the module's documentation.
#[derive(Clone, Debug)]
pub struct Experiment {
    settings: ExperimentSettings,
    n_servos: usize,
    f_min: Vec<f64>,
    base: Vec<f64>,
    amplitude: Vec<f64>,
    /// Static: `STATIC_PATTERNS.len() × n_servos` tensions.
    sets: Vec<f64>,
    /// Dynamic: every line, servo by servo; servo `j`'s are `lines[first[j]..first[j + 1]]`.
    lines: Vec<Line>,
    first: Vec<usize>,
    band: [f64; 2],
    length: Option<f64>,
    // Progress.
    t0: Option<f64>,
    step: usize,
    step_start: f64,
    stretch_start: Option<f64>,
    low: Vec<f64>,
    high: Vec<f64>,
    rest_start: Option<f64>,
    steps_at_rest: usize,
    steps_without_rest: usize,
    rest_rows: u64,
    finished: bool,
}

/// A per-module list given as one value or one per module.
fn per_module(name: &str, values: &[f64], n: usize) -> Result<Vec<f64>, String> {
    match values.len() {
        1 => Ok(vec![values[0]; n]),
        len if len == n => Ok(values.to_vec()),
        len => Err(format!(
            "{name}: give one value or one per module ({n}), got {len}"
        )),
    }
}

/// The largest `|Σ lines|` over one period `1/f0` \[in the lines' unit\], bounded from
/// above: sampled finely, plus the most the sum can rise between samples (half the
/// largest second derivative times the squared half step).
fn peak(lines: &[Line], f0: f64) -> f64 {
    let omega_max = lines.iter().fold(0.0_f64, |m, l| m.max(l.omega));
    let curvature: f64 = lines
        .iter()
        .map(|l| l.amplitude.abs() * l.omega * l.omega)
        .sum();
    if omega_max == 0.0 {
        return lines.iter().map(|l| l.amplitude.abs()).sum();
    }
    let samples = (64.0 * omega_max / (2.0 * PI * f0)).ceil().max(64.0) as usize;
    let dt = 1.0 / (f0 * samples as f64);
    let mut sampled = 0.0_f64;
    for s in 0..samples {
        let t = s as f64 * dt;
        let v: f64 = lines
            .iter()
            .map(|l| l.amplitude * (l.omega * t + l.phase).cos())
            .sum();
        sampled = sampled.max(v.abs());
    }
    sampled + 0.5 * curvature * (0.5 * dt) * (0.5 * dt)
}

/// `(1 − cos(π s))/2` for `s` in `[0, 1]`: from 0 to 1 with zero slope at both ends.
fn raised_cosine(s: f64) -> f64 {
    0.5 * (1.0 - (PI * s.clamp(0.0, 1.0)).cos())
}

impl Experiment {
    /// The experiment `settings` on `robot` (three tendons per module), whose tendons are
    /// held in `tension_limits` (`[f_min, f_max]` per module), at the loop rate `rate`
    /// \[Hz\]. Refuses settings out of range, tensions outside the limits and a robot whose
    /// numbers leave a module no room (messages name the option to give).
    pub fn new(
        settings: &ExperimentSettings,
        robot: &Robot,
        tension_limits: &[[f64; 2]],
        rate: f64,
    ) -> Result<Experiment, String> {
        settings.validate()?;
        let modules = robot.modules.len();
        if tension_limits.len() != modules {
            return Err(format!(
                "{} tension limits for {modules} modules",
                tension_limits.len()
            ));
        }
        if let Some(i) = robot
            .modules
            .iter()
            .position(|m| m.tendon_angles.len() != 3)
        {
            return Err(format!(
                "module {}: experiments drive three tendons per module",
                i + 1
            ));
        }
        if !(rate.is_finite() && rate > 0.0) {
            return Err(format!("--rate: {rate} Hz"));
        }
        let n = 3 * modules;
        let f_min: Vec<f64> = tension_limits.iter().map(|l| l[0]).collect();
        let f_max: Vec<f64> = tension_limits.iter().map(|l| l[1]).collect();
        let room = module_room(robot, tension_limits);

        // Dynamic: the lines first (the default amplitude depends on how the three servos
        // of a module add up).
        let (mut lines, mut first, mut band) = (Vec::new(), vec![0], [0.0; 2]);
        let mut common = vec![3.0; modules];
        let points = settings.operating_points as f64;
        if settings.kind == ExperimentKind::Dynamic {
            let f0 = settings.resolution;
            let high = settings.band[1].min(rate / SAMPLES_PER_PERIOD);
            let k_lo = (settings.band[0] / f0 - 1e-9).ceil().max(1.0);
            let k_hi = (high / f0 + 1e-9).floor();
            let count = if k_hi >= k_lo {
                (k_hi - k_lo) as usize + 1
            } else {
                0
            };
            if count < n {
                return Err(format!(
                    "--rate: at {rate} Hz the band {} to {high:.3} Hz has {count} lines of \
                     {f0} Hz, fewer than the {n} servos (one each at least): run faster",
                    settings.band[0]
                ));
            }
            band = [k_lo * f0, k_hi * f0];
            for j in 0..n {
                let own: Vec<f64> = (j..count)
                    .step_by(n)
                    .map(|m| (k_lo + m as f64) * f0)
                    .collect();
                let count_j = own.len() as f64;
                let start = lines.len();
                for (i, f) in own.iter().enumerate() {
                    let index = (i + 1) as f64;
                    lines.push(Line {
                        omega: 2.0 * PI * f,
                        phase: -PI * index * (index - 1.0) / count_j,
                        amplitude: 1.0,
                    });
                }
                // Unit peak per servo.
                let p = peak(&lines[start..], f0);
                for line in &mut lines[start..] {
                    line.amplitude /= p;
                }
                first.push(lines.len());
            }
            for (i, c) in common.iter_mut().enumerate() {
                *c = peak(&lines[first[3 * i]..first[3 * i + 3]], f0);
            }
        }

        // Amplitudes and bases: given, else from the room.
        let given_amplitude = match &settings.amplitude {
            Some(v) => Some(per_module("--amplitude", v, modules)?),
            None => None,
        };
        let given_base = match &settings.base_tension {
            Some(v) => Some(per_module("--base-tension", v, modules)?),
            None => None,
        };
        let bend_factor = |i: usize| {
            let psi = &robot.modules[i].tendon_angles;
            STATIC_PATTERNS
                .iter()
                .map(|p| {
                    let x: f64 = (0..3).map(|k| p[k] * psi[k].cos()).sum();
                    let y: f64 = (0..3).map(|k| p[k] * psi[k].sin()).sum();
                    x.hypot(y)
                })
                .fold(0.0, f64::max)
        };
        let mut amplitude = vec![0.0; modules];
        let mut base = vec![0.0; modules];
        for i in 0..modules {
            let r = &room[i];
            let span = f_max[i] - f_min[i];
            let a = match (&given_amplitude, settings.kind) {
                (Some(a), _) => a[i],
                (None, ExperimentKind::Static) => r
                    .extra_tension
                    .min(r.bend_tension / bend_factor(i))
                    .min(span),
                (None, ExperimentKind::Dynamic) => {
                    let levels = 3.0 + 1.5 * (points - 1.0) + common[i];
                    (r.extra_tension / levels)
                        .min(r.bend_tension / 3.0)
                        .min(span / (2.0 + 0.5 * (points - 1.0)))
                }
            };
            if a.is_nan() || a <= 0.0 {
                return Err(format!(
                    "module {}: the robot file's numbers leave it no room at f_min = {} N \
                     (straight, it sits at δL = {:.4} m under {:.3} N; its barriers allow \
                     δL ≥ {:.4} m): give --amplitude and --base-tension",
                    i + 1,
                    f_min[i],
                    r.elongation_at_f_min,
                    r.load,
                    r.lowest_elongation
                ));
            }
            amplitude[i] = a;
            base[i] = match (&given_base, settings.kind) {
                (Some(b), _) => b[i],
                (None, ExperimentKind::Static) => f_min[i],
                (None, ExperimentKind::Dynamic) => f_min[i] + a,
            };
            let b = base[i];
            let (lowest, highest, what) = match settings.kind {
                ExperimentKind::Static => (b, b + a, "base and base + amplitude"),
                ExperimentKind::Dynamic => (
                    b - a,
                    b + 0.5 * a * (points - 1.0) + a,
                    "every operating point ± amplitude",
                ),
            };
            let tolerance = 1e-9 * f_max[i].abs().max(1.0);
            if lowest < f_min[i] - tolerance || highest > f_max[i] + tolerance {
                let option = if given_base.is_some() {
                    "--base-tension"
                } else {
                    "--amplitude"
                };
                return Err(format!(
                    "{option}: module {}'s tensions would span {lowest:.4} to {highest:.4} N \
                     ({what}), outside its tension limits [{}, {}] N",
                    i + 1,
                    f_min[i],
                    f_max[i]
                ));
            }
        }
        if settings.kind == ExperimentKind::Dynamic {
            for (i, a) in amplitude.iter().enumerate() {
                for line in &mut lines[first[3 * i]..first[3 * i + 3]] {
                    line.amplitude *= a;
                }
            }
        }

        let mut sets = Vec::new();
        if settings.kind == ExperimentKind::Static {
            sets.reserve(STATIC_PATTERNS.len() * n);
            for pattern in &STATIC_PATTERNS {
                for i in 0..modules {
                    for p in pattern {
                        sets.push(base[i] + p * amplitude[i]);
                    }
                }
            }
        }
        Ok(Experiment {
            settings: settings.clone(),
            n_servos: n,
            f_min,
            base,
            amplitude,
            sets,
            lines,
            first,
            band,
            length: settings.length(),
            t0: None,
            step: 0,
            step_start: 0.0,
            stretch_start: None,
            low: vec![0.0; n],
            high: vec![0.0; n],
            rest_start: None,
            steps_at_rest: 0,
            steps_without_rest: 0,
            rest_rows: 0,
            finished: false,
        })
    }

    /// Which experiment.
    pub fn kind(&self) -> ExperimentKind {
        self.settings.kind
    }

    /// Number of servos (tensions per tick).
    pub fn n_servos(&self) -> usize {
        self.n_servos
    }

    /// Steps planned: static sets, or operating points.
    pub fn steps(&self) -> usize {
        match self.settings.kind {
            ExperimentKind::Static => STATIC_PATTERNS.len(),
            ExperimentKind::Dynamic => self.settings.operating_points,
        }
    }

    /// The current step (from 0).
    pub fn step(&self) -> usize {
        self.step
    }

    /// Static steps that came to rest so far.
    pub fn steps_at_rest(&self) -> usize {
        self.steps_at_rest
    }

    /// Static steps that did not come to rest within the step time so far.
    pub fn steps_without_rest(&self) -> usize {
        self.steps_without_rest
    }

    /// Steps not run to their end: static sets neither at rest nor timed out; none of a
    /// dynamic experiment once finished (its length is its end).
    pub fn steps_left(&self) -> usize {
        match self.settings.kind {
            ExperimentKind::Static => {
                STATIC_PATTERNS.len() - (self.steps_at_rest + self.steps_without_rest)
            }
            ExperimentKind::Dynamic => {
                if self.finished {
                    0
                } else {
                    self.settings.operating_points - self.step
                }
            }
        }
    }

    /// Rows marked `rest` so far.
    pub fn rest_rows(&self) -> u64 {
        self.rest_rows
    }

    /// Whether the experiment is over (every step run, or its length or cap reached).
    pub fn finished(&self) -> bool {
        self.finished
    }

    /// Base tension per module \[N\].
    pub fn base_tension(&self) -> &[f64] {
        &self.base
    }

    /// Amplitude per module \[N\].
    pub fn amplitude(&self) -> &[f64] {
        &self.amplitude
    }

    /// Static: the tensions of set `k` (one per servo).
    pub fn set(&self, k: usize) -> Option<&[f64]> {
        self.sets.get(k * self.n_servos..(k + 1) * self.n_servos)
    }

    /// How long it takes \[s\]: the dynamic length; static, the least (every set at rest
    /// as soon as allowed) and the most (none at rest) before any cap.
    pub fn expected_length(&self) -> [f64; 2] {
        let s = &self.settings;
        match s.kind {
            ExperimentKind::Dynamic => {
                let d = self.length.unwrap_or(DEFAULT_DYNAMIC_DURATION);
                [d, d]
            }
            ExperimentKind::Static => {
                let steps = STATIC_PATTERNS.len() as f64;
                let least = steps * (s.settle_time.max(s.quiet_window) + s.rest_window);
                let most = steps * (s.step_time + s.rest_window);
                match self.length {
                    Some(cap) => [least.min(cap), most.min(cap)],
                    None => [least, most],
                }
            }
        }
    }

    /// The tensions of the tick at time `t` \[s\] (any origin: the experiment starts at the
    /// first call) with the state read `q`, written into `tensions` (one per servo), and
    /// the tick's [`Mark`]. Static rest is judged on `q`; a non-finite `q` breaks it. Once
    /// [`Experiment::finished`], the last tensions are repeated. Allocates nothing.
    pub fn command(&mut self, t: f64, q: &[f64], tensions: &mut [f64]) -> Mark {
        let t0 = match self.t0 {
            Some(t0) => t0,
            None => {
                self.t0 = Some(t);
                self.step_start = t;
                t
            }
        };
        let time = t - t0;
        if self.length.is_some_and(|d| time >= d) {
            self.finished = true;
        }
        match self.settings.kind {
            ExperimentKind::Static => self.command_static(t, q, tensions),
            ExperimentKind::Dynamic => self.command_dynamic(time, tensions),
        }
    }

    fn command_static(&mut self, t: f64, q: &[f64], tensions: &mut [f64]) -> Mark {
        let steps = STATIC_PATTERNS.len();
        let mut rest = false;
        if !self.finished {
            let s = &self.settings;
            let (rest_window, quiet_window) = (s.rest_window, s.quiet_window);
            let (settle_time, step_time) = (s.settle_time, s.step_time);
            let mut advance = false;
            if let Some(start) = self.rest_start {
                if t - start >= rest_window {
                    self.steps_at_rest += 1;
                    advance = true;
                } else {
                    rest = true;
                }
            } else {
                self.observe(t, q);
                let held = t - self.step_start;
                let quiet = self
                    .stretch_start
                    .is_some_and(|from| t - from >= quiet_window);
                if held >= settle_time && quiet {
                    self.rest_start = Some(t);
                    rest = true;
                } else if held >= step_time {
                    self.steps_without_rest += 1;
                    advance = true;
                }
            }
            if advance {
                if self.step + 1 >= steps {
                    self.finished = true;
                } else {
                    self.step += 1;
                    self.step_start = t;
                    self.stretch_start = None;
                    self.rest_start = None;
                }
            }
        }
        if rest {
            self.rest_rows += 1;
        }
        let n = self.n_servos;
        let k = self.step.min(steps - 1);
        let to = &self.sets[k * n..(k + 1) * n];
        let ramp = self.settings.ramp;
        let into = t - self.step_start;
        if into < ramp {
            let w = raised_cosine(into / ramp);
            for (j, tension) in tensions[..n].iter_mut().enumerate() {
                let from = match k {
                    0 => self.f_min[j / 3],
                    _ => self.sets[(k - 1) * n + j],
                };
                *tension = from + (to[j] - from) * w;
            }
        } else {
            tensions[..n].copy_from_slice(to);
        }
        Mark {
            step: self.step,
            rest,
        }
    }

    /// Adds a reading to the stretch during which every coordinate has stayed within the
    /// rest threshold; a reading that widens some coordinate's band beyond it starts a new
    /// stretch there. The stretch, when longer than the quiet window, contains the last
    /// window: every coordinate's max − min over that window is below the threshold too.
    fn observe(&mut self, t: f64, q: &[f64]) {
        let threshold = self.settings.rest_threshold;
        let n = q.len().min(self.low.len());
        if q[..n].iter().any(|v| !v.is_finite()) {
            self.stretch_start = None;
            return;
        }
        if self.stretch_start.is_some() {
            let mut wide = false;
            for (i, &v) in q[..n].iter().enumerate() {
                let (low, high) = (self.low[i].min(v), self.high[i].max(v));
                wide |= high - low > threshold;
                self.low[i] = low;
                self.high[i] = high;
            }
            if !wide {
                return;
            }
        }
        self.stretch_start = Some(t);
        self.low[..n].copy_from_slice(&q[..n]);
        self.high[..n].copy_from_slice(&q[..n]);
    }

    fn command_dynamic(&mut self, time: f64, tensions: &mut [f64]) -> Mark {
        let s = &self.settings;
        let length = self.length.unwrap_or(DEFAULT_DYNAMIC_DURATION);
        let points = s.operating_points;
        let share = length / points as f64;
        let time = time.clamp(0.0, length);
        let point = ((time / share) as usize).min(points - 1);
        let into = time - point as f64 * share;
        let fade = raised_cosine(into / s.fade);
        // The multisines fade in with the first operating point, from f_min.
        let envelope = if point == 0 { fade } else { 1.0 };
        for (j, tension) in tensions[..self.n_servos].iter_mut().enumerate() {
            let i = j / 3;
            let (a, b) = (self.amplitude[i], self.base[i]);
            let level = |p: usize| b + 0.5 * a * p as f64;
            let from = if point == 0 {
                self.f_min[i]
            } else {
                level(point - 1)
            };
            let base = from + (level(point) - from) * fade;
            let wave: f64 = self.lines[self.first[j]..self.first[j + 1]]
                .iter()
                .map(|l| l.amplitude * (l.omega * time + l.phase).cos())
                .sum();
            *tension = base + envelope * wave;
        }
        self.step = point;
        Mark {
            step: point,
            rest: false,
        }
    }

    /// The design and the counts so far.
    pub fn report(&self) -> ExperimentReport {
        let modules = self.base.len();
        let operating_points = match self.settings.kind {
            ExperimentKind::Dynamic => (0..modules)
                .map(|i| {
                    (0..self.settings.operating_points)
                        .map(|p| self.base[i] + 0.5 * self.amplitude[i] * p as f64)
                        .collect()
                })
                .collect(),
            ExperimentKind::Static => Vec::new(),
        };
        let started = self.t0.is_some();
        let complete = self.finished && self.steps_left() == 0;
        ExperimentReport {
            settings: ExperimentSettings {
                duration: self.length,
                ..self.settings.clone()
            },
            base_tension: self.base.clone(),
            amplitude: self.amplitude.clone(),
            operating_points,
            band: self.band,
            lines_per_servo: self.first.windows(2).map(|w| w[1] - w[0]).collect(),
            steps: self.steps(),
            steps_run: if started { self.step + 1 } else { 0 },
            steps_at_rest: self.steps_at_rest,
            steps_without_rest: self.steps_without_rest,
            rest_rows: self.rest_rows,
            complete,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::Tolerances;
    use crate::model::Model;
    use crate::plant::Plant;
    use nalgebra::{DMatrix, DVector};
    use softcbf_description::barriers::BarrierKind;
    use softcbf_description::uncertainty::{ModuleFactors, scaled};

    const RATE: f64 = 33.0;

    fn example() -> (Robot, Vec<[f64; 2]>) {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../robots/hardware-example.toml"
        );
        let robot = Robot::load(std::path::Path::new(path)).unwrap();
        let hardware = crate::hardware::description::load(&robot).unwrap().unwrap();
        let limits = hardware.modules.iter().map(|m| m.tension_limits).collect();
        (robot, limits)
    }

    fn experiment(settings: &ExperimentSettings) -> Experiment {
        let (robot, limits) = example();
        Experiment::new(settings, &robot, &limits, RATE).unwrap()
    }

    /// `τ_i = A_i f_i` with `A_i`'s columns `(cos ψ_k, sin ψ_k, −1)` (docs/model.md §6).
    fn generalized_force(robot: &Robot, f: &[f64], tau: &mut [f64]) {
        for (i, module) in robot.modules.iter().enumerate() {
            let psi = &module.tendon_angles;
            let f = &f[3 * i..3 * i + 3];
            tau[3 * i] = (0..3).map(|k| psi[k].cos() * f[k]).sum();
            tau[3 * i + 1] = (0..3).map(|k| psi[k].sin() * f[k]).sum();
            tau[3 * i + 2] = -f.iter().sum::<f64>();
        }
    }

    /// One module's static identification in its simplest form: equilibria of the linear
    /// statics `K q = A diag(I) g − (0, 0, W)` of a true module `truth = (κθ/d², κL, g1,
    /// g2, g3)` at the currents `I = f / g_file` of `sets`, and the regressor of the
    /// unknowns with its right-hand side (`κθ/d² Δx − Σ cos ψ_k I_k g_k = 0`, the same in
    /// `y`, `κL δL + Σ I_k g_k = −W`).
    fn static_regressor(
        psi: &[f64],
        sets: &[[f64; 3]],
        truth: [f64; 5],
        load: f64,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let gain_file = 0.04;
        let mut a = DMatrix::zeros(3 * sets.len(), 5);
        let mut rhs = DVector::zeros(3 * sets.len());
        for (s, f) in sets.iter().enumerate() {
            let current: Vec<f64> = f.iter().map(|f| f / gain_file).collect();
            let pulled: Vec<f64> = (0..3).map(|k| truth[2 + k] * current[k]).collect();
            let dx = (0..3).map(|k| psi[k].cos() * pulled[k]).sum::<f64>() / truth[0];
            let dy = (0..3).map(|k| psi[k].sin() * pulled[k]).sum::<f64>() / truth[0];
            let dl = -(load + pulled.iter().sum::<f64>()) / truth[1];
            a[(3 * s, 0)] = dx;
            a[(3 * s + 1, 0)] = dy;
            a[(3 * s + 2, 1)] = dl;
            for k in 0..3 {
                a[(3 * s, 2 + k)] = -psi[k].cos() * current[k];
                a[(3 * s + 1, 2 + k)] = -psi[k].sin() * current[k];
                a[(3 * s + 2, 2 + k)] = current[k];
            }
            rhs[3 * s + 2] = -load;
        }
        (a, rhs)
    }

    /// The condition number of `a` with unit columns.
    fn condition(a: &DMatrix<f64>) -> f64 {
        let mut scaled = a.clone();
        for mut column in scaled.column_iter_mut() {
            let norm = column.norm();
            column /= norm;
        }
        let s = scaled.svd(false, false).singular_values;
        s.max() / s.min()
    }

    #[test]
    fn static_sets_move_every_tendon_on_its_own_and_the_total_against_the_weight() {
        let (robot, limits) = example();
        let e = experiment(&ExperimentSettings::new(ExperimentKind::Static));
        assert_eq!(e.steps(), 16);
        let room = module_room(&robot, &limits);
        for (i, module) in robot.modules.iter().enumerate() {
            let [f_min, f_max] = limits[i];
            let (b, a) = (e.base_tension()[i], e.amplitude()[i]);
            let sets: Vec<[f64; 3]> = (0..e.steps())
                .map(|k| {
                    let s = &e.set(k).unwrap()[3 * i..3 * i + 3];
                    [s[0], s[1], s[2]]
                })
                .collect();
            // First and last: the base, on every tendon.
            assert_eq!(sets[0], sets[15]);
            assert_eq!(sets[0], [b; 3]);
            for f in sets.iter().flatten() {
                assert!((f_min..=f_max).contains(f), "module {i}: {f} N");
            }
            // Every set adds at most `a` in all, within the room chosen for the module.
            for f in &sets {
                let extra: f64 = f.iter().map(|f| f - b).sum();
                assert!((0.0..=a * (1.0 + 1e-12)).contains(&extra), "{extra} > {a}");
            }
            assert!(a <= room[i].extra_tension * (1.0 + 1e-12));
            // Each tendon takes at least three tensions.
            for k in 0..3 {
                let mut levels: Vec<f64> = sets.iter().map(|f| f[k]).collect();
                levels.sort_by(f64::total_cmp);
                levels.dedup_by(|x, y| (*x - *y).abs() < 1e-12);
                assert!(levels.len() >= 3, "tendon {k}: {levels:?}");
            }
            // The equilibria determine both stiffnesses and the three gains: a true module
            // 5 to 20 % off is recovered from them, and the regressor is well conditioned.
            let d = module.tendon_radius;
            let truth = [
                1.2 * module.bending_stiffness / (d * d),
                0.8 * module.axial_stiffness,
                0.04 * 1.1,
                0.04 * 0.9,
                0.04 * 1.05,
            ];
            let psi = &module.tendon_angles;
            let (regressor, rhs) = static_regressor(psi, &sets, truth, room[i].load);
            let kappa = condition(&regressor);
            assert!(kappa < 100.0, "module {i}: condition {kappa}");
            let estimate = regressor.svd(true, true).solve(&rhs, 1e-15).unwrap();
            for c in 0..5 {
                assert!(
                    (estimate[c] / truth[c] - 1.0).abs() < 1e-9,
                    "module {i} unknown {c}: {} vs {}",
                    estimate[c],
                    truth[c]
                );
            }
            // Sets pulling all three tendons alike cannot tell the gains apart: the same
            // check fails without the single tendons and pairs.
            let symmetric = [sets[0], sets[7], sets[14], sets[15]];
            let (regressor, _) = static_regressor(psi, &symmetric, truth, room[i].load);
            assert!(condition(&regressor) > 1e8);
        }
    }

    /// A static experiment driven at [`RATE`] by readings `q(step, time into the step,
    /// sample)` until it finishes or `limit` seconds pass; every sample's `(t, step, q,
    /// mark)`.
    fn drive(
        e: &mut Experiment,
        q: impl Fn(usize, f64, usize) -> [f64; 6],
        limit: f64,
    ) -> Vec<(f64, usize, [f64; 6], Mark)> {
        let mut tensions = [0.0; 6];
        let mut samples = Vec::new();
        let (mut step, mut start) = (0, 0.0);
        let mut k = 0;
        while !e.finished() {
            let t = k as f64 / RATE;
            assert!(t < limit, "not finished after {limit} s");
            let reading = q(step, t - start, k);
            let mark = e.command(t, &reading, &mut tensions);
            if mark.step != step {
                (step, start) = (mark.step, t);
            }
            samples.push((t, step, reading, mark));
            k += 1;
        }
        samples
    }

    #[test]
    fn rest_is_found_once_the_motion_has_died_down_within_the_threshold() {
        let settings = ExperimentSettings::new(ExperimentKind::Static);
        let mut e = experiment(&settings);
        let (amplitude, omega) = (5e-3, 25.0);
        // Step k rings down with time constant 0.1 + 0.05 k s about its own equilibrium.
        let tau = |step: usize| 0.1 + 0.05 * step as f64;
        let q = |step: usize, into: f64, _| {
            std::array::from_fn(|c| {
                let equilibrium = 1e-3 * (step as f64 + c as f64);
                let phase = c as f64;
                equilibrium + amplitude * (-into / tau(step)).exp() * (omega * into + phase).cos()
            })
        };
        let samples = drive(&mut e, q, 200.0);
        assert_eq!(e.steps_at_rest(), 16);
        assert_eq!(e.steps_without_rest(), 0);
        let dt = 1.0 / RATE;
        for step in 0..16 {
            let rows: Vec<_> = samples.iter().filter(|s| s.1 == step).collect();
            let start = rows[0].0;
            let rest: Vec<_> = rows.iter().filter(|s| s.3.rest).collect();
            // The rest window's rows: 1 s of them.
            assert!(
                (33..=34).contains(&rest.len()),
                "step {step}: {}",
                rest.len()
            );
            let onset = rest[0].0;
            assert!(onset - start >= settings.settle_time - 1e-9);
            // Over the quiet window before the onset, each coordinate moved less than the
            // threshold (brute force over the samples).
            for c in 0..6 {
                let window: Vec<f64> = rows
                    .iter()
                    .filter(|s| s.0 >= onset - settings.quiet_window - 1e-9 && s.0 <= onset)
                    .map(|s| s.2[c])
                    .collect();
                let span = window.iter().copied().fold(f64::MIN, f64::max)
                    - window.iter().copied().fold(f64::MAX, f64::min);
                assert!(span < settings.rest_threshold, "step {step}: span {span}");
            }
            // Not late: from t_q on, the ringing stays within half the threshold of the
            // equilibrium; the last stretch began by max(settle, t_q + quiet).
            let t_q = tau(step) * (2.0 * amplitude / settings.rest_threshold).ln();
            let latest = settings.settle_time.max(t_q + settings.quiet_window)
                + settings.quiet_window
                + 2.0 * dt;
            assert!(
                onset - start <= latest,
                "step {step}: rest after {} s, expected by {latest} s",
                onset - start
            );
        }
        assert!(e.report().complete);
        assert_eq!(e.report().rest_rows, e.rest_rows());
    }

    #[test]
    fn a_step_that_never_comes_to_rest_is_left_after_the_step_time() {
        let mut settings = ExperimentSettings::new(ExperimentKind::Static);
        settings.step_time = 2.0;
        let mut e = experiment(&settings);
        // Jitter of twice the threshold, every other sample.
        let threshold = settings.rest_threshold;
        let q = |_, _, k: usize| {
            [if k.is_multiple_of(2) {
                threshold
            } else {
                -threshold
            }; 6]
        };
        let samples = drive(&mut e, q, 100.0);
        assert!(samples.iter().all(|s| !s.3.rest));
        assert_eq!((e.steps_at_rest(), e.steps_without_rest()), (0, 16));
        assert_eq!(e.rest_rows(), 0);
        let start = |step: usize| samples.iter().find(|s| s.1 == step).unwrap().0;
        for step in 0..15 {
            // The next step starts at the first sample 2 s after this one's start.
            let held = start(step + 1) - start(step);
            assert!(
                (2.0 - 1e-9..2.0 + 1.0 / RATE).contains(&held),
                "step {step}: {held} s"
            );
        }
        let report = e.report();
        assert!(report.complete);
        assert_eq!(report.steps_run, 16);
    }

    #[test]
    fn an_experiment_finishes_at_its_length_or_its_cap() {
        let mut settings = ExperimentSettings::new(ExperimentKind::Static);
        settings.duration = Some(5.0);
        let mut e = experiment(&settings);
        let samples = drive(&mut e, |_, _, _| [0.0; 6], 10.0);
        let last = samples.last().unwrap().0;
        assert!((5.0..5.0 + 1.0 / RATE).contains(&last), "{last}");
        // Steps of 2 s (settle 1 s, rest 1 s): two done, the third cut.
        assert_eq!(e.steps_at_rest(), 2);
        assert_eq!(e.steps_left(), 14);
        assert!(!e.report().complete);

        let mut settings = ExperimentSettings::new(ExperimentKind::Dynamic);
        settings.duration = Some(6.0);
        let mut e = experiment(&settings);
        let mut tensions = [0.0; 6];
        let mut steps = Vec::new();
        for k in 0..1000 {
            // Starting at t = 100 s: the experiment's own clock starts at its first call.
            let t = 100.0 + k as f64 * 0.01;
            let mark = e.command(t, &[0.0; 6], &mut tensions);
            assert!(!mark.rest);
            if e.finished() {
                assert!((t - 106.0).abs() < 0.011, "finished at {t}");
                break;
            }
            steps.push(mark.step);
        }
        assert!(e.finished());
        assert_eq!(steps[0], 0);
        assert_eq!(*steps.last().unwrap(), 2);
        assert!(steps.windows(2).all(|w| w[1] == w[0] || w[1] == w[0] + 1));
        let report = e.report();
        assert!(report.complete);
        assert_eq!((report.steps, report.steps_run, e.steps_left()), (3, 3, 0));
    }

    #[test]
    fn dynamic_tensions_stay_in_their_limits_and_reach_the_amplitude() {
        let (_, limits) = example();
        let settings = ExperimentSettings::new(ExperimentKind::Dynamic);
        let mut e = experiment(&settings);
        let report = e.report();
        let mut tensions = [0.0; 6];
        let mut largest = [0.0_f64; 6];
        let dt = 1e-3;
        let share = DEFAULT_DYNAMIC_DURATION / 3.0;
        for k in 0..(DEFAULT_DYNAMIC_DURATION / dt) as usize {
            let t = k as f64 * dt;
            let mark = e.command(t, &[0.0; 6], &mut tensions);
            let into = t - mark.step as f64 * share;
            for (j, &f) in tensions.iter().enumerate() {
                let [f_min, f_max] = limits[j / 3];
                assert!((f_min..=f_max).contains(&f), "servo {j} at {t} s: {f} N");
                if into > settings.fade {
                    // Past the fade: the operating point's base, plus at most `a`.
                    let base = report.operating_points[j / 3][mark.step];
                    let a = report.amplitude[j / 3];
                    assert!((f - base).abs() <= a, "servo {j} at {t} s: {f} N");
                    largest[j] = largest[j].max((f - base).abs() / a);
                }
            }
        }
        for (j, &reached) in largest.iter().enumerate() {
            assert!(
                reached > 0.95,
                "servo {j} reached {reached} of its amplitude"
            );
        }
        for (i, points) in report.operating_points.iter().enumerate() {
            let a = report.amplitude[i];
            assert!(points[0] - a >= limits[i][0] - 1e-12);
            assert!(points.windows(2).all(|w| w[1] > w[0]), "{points:?}");
        }
    }

    #[test]
    fn each_servo_has_its_own_lines_of_the_grid() {
        let settings = ExperimentSettings::new(ExperimentKind::Dynamic);
        let mut e = experiment(&settings);
        let report = e.report();
        let f0 = settings.resolution;
        // One period 1/f0 of the second operating point, past its fade.
        let samples = 1000;
        let dt = 1.0 / (f0 * samples as f64);
        let mut tensions = [0.0; 6];
        e.command(0.0, &[0.0; 6], &mut tensions);
        let mut deviation = vec![[0.0; 6]; samples];
        for (s, d) in deviation.iter_mut().enumerate() {
            let t = 21.0 + s as f64 * dt;
            let mark = e.command(t, &[0.0; 6], &mut tensions);
            assert_eq!(mark.step, 1);
            for j in 0..6 {
                d[j] = tensions[j] - report.operating_points[j / 3][1];
            }
        }
        // The grid k·f0 from 0.2 to 5 Hz (at 33 Hz, 33/6 > 5), dealt out in turn.
        let (k_lo, k_hi) = (2, 50);
        for j in 0..6 {
            let a = report.amplitude[j / 3];
            for k in 1..=80 {
                let (mut re, mut im) = (0.0, 0.0);
                for (s, d) in deviation.iter().enumerate() {
                    let angle = 2.0 * PI * k as f64 * f0 * s as f64 * dt;
                    re += d[j] * angle.cos();
                    im += d[j] * angle.sin();
                }
                let magnitude = 2.0 * re.hypot(im) / samples as f64;
                let own = (k_lo..=k_hi).contains(&k) && (k - k_lo) % 6 == j;
                if own {
                    assert!(magnitude > 0.05 * a, "servo {j} line {k}: {magnitude}");
                } else {
                    assert!(magnitude < 1e-9 * a, "servo {j} line {k}: {magnitude}");
                }
            }
            // No two servos share a frequency: uncorrelated over the period.
            for other in 0..j {
                let product: f64 = deviation.iter().map(|d| d[j] * d[other]).sum();
                let scale: f64 = deviation.iter().map(|d| d[j] * d[j]).sum::<f64>().sqrt()
                    * deviation
                        .iter()
                        .map(|d| d[other] * d[other])
                        .sum::<f64>()
                        .sqrt();
                assert!(product.abs() < 1e-9 * scale, "servos {j} and {other}");
            }
        }
        assert_eq!(report.band, [0.2, 5.0]);
        assert_eq!(report.lines_per_servo, vec![9, 8, 8, 8, 8, 8]);
    }

    /// The lowest elongation barrier of each module at `q`.
    fn elongation_barriers(model: &Model, q: &[f64]) -> (Vec<f64>, f64) {
        let mut b = vec![0.0; model.nb()];
        model.generated.barriers(&model.params, q, &mut b);
        let table = model.generated.barrier_table();
        let mut per_module = vec![f64::INFINITY; model.n_modules()];
        for (info, &value) in table.iter().zip(&b) {
            if info.kind == BarrierKind::ElongationMin {
                per_module[info.module] = per_module[info.module].min(value);
            }
        }
        (per_module, b.iter().copied().fold(f64::INFINITY, f64::min))
    }

    /// Equilibrium of `model` under constant tensions `f`, reached from the straight pose
    /// by its own damping.
    fn equilibrium(model: &Model, plant: &mut Plant<'_>, f: &[f64]) -> Vec<f64> {
        plant.reset(&[0.0; 6], &[0.0; 6], 0.0);
        generalized_force(&model.robot, f, plant.tau_mut());
        plant.advance(15.0).unwrap();
        assert!(
            plant.qd().iter().all(|v| v.abs() < 1e-6),
            "{:?}",
            plant.qd()
        );
        plant.q().to_vec()
    }

    /// The defaults, checked on the full nonlinear model: the file's own robot and one
    /// 30 % softer keep every static set's equilibrium within half of
    /// the compression room they have at `f_min`, and the dynamic experiment's whole
    /// course (the file's robot under the tensions held for each tick) above every
    /// barrier and within half of that room too.
    #[test]
    fn the_defaults_keep_half_of_the_room_on_the_model() {
        let (robot, limits) = example();
        // 30 % softer in both stiffnesses.
        let softer = 0.7;
        let soft = scaled(
            &robot,
            &[ModuleFactors {
                stiffness: [softer; 2],
                ..ModuleFactors::NOMINAL
            }; 2],
        )
        .unwrap();
        let static_experiment = experiment(&ExperimentSettings::new(ExperimentKind::Static));
        for plant_robot in [robot.clone(), soft] {
            let model = Model::new(plant_robot).unwrap();
            let mut plant = Plant::new(&model, Tolerances::default()).unwrap();
            let f_min: Vec<f64> = (0..6).map(|j| limits[j / 3][0]).collect();
            let q = equilibrium(&model, &mut plant, &f_min);
            let (room, _) = elongation_barriers(&model, &q);
            assert!(room.iter().all(|&r| r > 0.0), "{room:?}");
            for k in 0..static_experiment.steps() {
                let q = equilibrium(&model, &mut plant, static_experiment.set(k).unwrap());
                let (left, lowest) = elongation_barriers(&model, &q);
                assert!(lowest > 0.0, "set {k}: {lowest}");
                for i in 0..2 {
                    // The set of the largest extra tension takes the softer robot's straight
                    // module exactly half way, by construction of the defaults (linear
                    // statics, which its axial equilibrium obeys): equal up to rounding, so
                    // 1e-12 m of slack, far below the integration's accuracy and anything
                    // physical, keeps the check from testing the last bit.
                    assert!(
                        left[i] >= 0.5 * room[i] - 1e-12,
                        "{}: set {k} leaves module {} {} of {} m",
                        model.robot.name,
                        i + 1,
                        left[i],
                        room[i]
                    );
                }
            }
        }

        let model = Model::new(robot.clone()).unwrap();
        let mut plant = Plant::new(&model, Tolerances::default()).unwrap();
        let f_min: Vec<f64> = (0..6).map(|j| limits[j / 3][0]).collect();
        let q = equilibrium(&model, &mut plant, &f_min);
        let (room, _) = elongation_barriers(&model, &q);
        let mut e = experiment(&ExperimentSettings::new(ExperimentKind::Dynamic));
        let mut tensions = [0.0; 6];
        let dt = 1.0 / RATE;
        let mut lowest = [f64::INFINITY; 2];
        let mut overall = f64::INFINITY;
        let mut k = 0;
        while !e.finished() {
            e.command(k as f64 * dt, plant.q(), &mut tensions);
            generalized_force(&robot, &tensions, plant.tau_mut());
            plant.advance(dt).unwrap();
            let (left, least) = elongation_barriers(&model, plant.q());
            overall = overall.min(least);
            for i in 0..2 {
                lowest[i] = lowest[i].min(left[i]);
            }
            k += 1;
        }
        assert!(overall > 0.0);
        for i in 0..2 {
            assert!(
                lowest[i] >= 0.5 * room[i],
                "module {}: {lowest:?} of {room:?}",
                i + 1
            );
        }
    }

    #[test]
    fn settings_out_of_range_or_beyond_the_tension_limits_are_refused() {
        let (robot, limits) = example();
        let refused = |settings: &ExperimentSettings| {
            Experiment::new(settings, &robot, &limits, RATE)
                .err()
                .unwrap()
        };
        let mut s = ExperimentSettings::new(ExperimentKind::Static);
        s.amplitude = Some(vec![50.0]);
        let message = refused(&s);
        assert!(message.starts_with("--amplitude: module 1"), "{message}");
        s.amplitude = Some(vec![0.5, 0.5, 0.5]);
        assert!(refused(&s).contains("one value or one per module (2), got 3"));
        s.amplitude = Some(vec![-1.0]);
        assert!(refused(&s).starts_with("--amplitude: must be > 0"));
        s.amplitude = None;
        s.base_tension = Some(vec![0.1]);
        assert!(refused(&s).starts_with("--base-tension: module 1"));
        s.base_tension = None;
        s.step_time = 0.8;
        assert!(refused(&s).starts_with("--step-time: 0.8 s leaves no time"));
        s.step_time = f64::NAN;
        assert!(refused(&s).starts_with("--step-time: must be a finite number"));
        let mut d = ExperimentSettings::new(ExperimentKind::Dynamic);
        d.duration = Some(2.0);
        assert!(refused(&d).starts_with("--duration: 2 s gives each"));
        d.duration = None;
        let slow = Experiment::new(&d, &robot, &limits, 3.0).err().unwrap();
        assert!(slow.starts_with("--rate: at 3 Hz"), "{slow}");
        // Given amplitudes and bases, one per module, within the limits: taken as given.
        d.amplitude = Some(vec![0.3, 1.0]);
        d.base_tension = Some(vec![0.5, 1.2]);
        let e = Experiment::new(&d, &robot, &limits, RATE).unwrap();
        assert_eq!(
            (e.amplitude(), e.base_tension()),
            (&[0.3, 1.0][..], &[0.5, 1.2][..])
        );
    }
}
