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
//! settle_time`], over the last [`ExperimentSettings::quiet_window`] every coordinate's
//! spread and drift are within [`ExperimentSettings::rest_threshold`] (`Experiment::quiet`);
//! the next [`ExperimentSettings::rest_window`] of rows is marked `rest`. A set that does
//! not come to rest within [`ExperimentSettings::step_time`] is counted and left.
//!
//! **Levels.** Nothing is known of a robot before it is identified: the experiment takes
//! it to be within [`ExperimentSettings::uncertainty`] (±50 %) of its file in stiffness,
//! damping and actuator gains. Every tension's deviation from `f_min` is scaled by a level:
//! the first is what keeps every module of any robot in that box within half of its room
//! ([`module_room`]; [`MIN_START_SCALE`] where the box leaves none). The level grows by
//! [`ExperimentSettings::growth`] only while each barrier, extrapolated from the largest
//! drop per newton it showed at the levels run (against the reference state: the base set
//! at rest, or the dynamic experiment's first reading) to the design's largest deviation,
//! stays above [`ExperimentSettings::growth_distance`]; beyond the level measured the drop
//! is taken to grow faster than linearly, as the level to [`DROP_GROWTH_POWER`]
//! (`beyond_measured`). The static experiment measures its levels on rounds of the three
//! single-tendon sets (the sets that bend and compress a module most), then runs the other
//! sets at the level chosen; the dynamic one reconsiders its level every
//! [`ExperimentSettings::check_window`].
//!
//! **Guard.** Each tick the run loop gives [`Experiment::observe`] the barriers at the
//! state read and where the robot is heading by the next command; when one is below
//! [`ExperimentSettings::stop_distance`] the experiment stops ([`ExperimentStop`]), its
//! tensions fall to `f_min`, and the run ends in its safe stop.
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
/// The experiment's own uncertainty on stiffness, damping and actuator gains (a fraction):
/// up to 90 % (a robot at least a tenth as stiff as its file).
pub const EXPERIMENT_UNCERTAINTY: Limit = Limit::closed(0.0, 0.9, "");
/// Barrier distances of the experiment's guard \[m, or rad for a bend limit\]: up to 10 cm.
pub const GUARD_DISTANCE: Limit = Limit::closed(0.0, 0.1, "m");

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
/// The window over which rest is judged \[s\].
pub const DEFAULT_QUIET_WINDOW: f64 = 0.5;
/// How long a set is kept once at rest, its rows marked `rest` \[s\].
pub const DEFAULT_REST_WINDOW: f64 = 1.0;
/// Rest threshold \[m\]: about four position quanta of a tendon wound on a 45 mm pulley by a
/// 4096-count encoder (0.07 mm each). Rest is judged on the readings' spread (at most a
/// quarter of it, over √2) and drift (half of it), so that a reading noisy by one count
/// (a spread of about 0.06 mm in a coordinate) still counts as at rest.
pub const DEFAULT_REST_THRESHOLD: f64 = 3e-4;
/// Operating points of a dynamic experiment.
pub const DEFAULT_OPERATING_POINTS: usize = 3;
/// Raised-cosine fade between operating points \[s\].
pub const DEFAULT_FADE: f64 = 1.0;
/// Band of the multisines \[Hz\]; the upper end is also at most a sixth of the loop rate.
pub const DEFAULT_BAND: [f64; 2] = [0.2, 5.0];
/// Spacing `f0` of the multisines' frequency grid \[Hz\] (period `1/f0`).
pub const DEFAULT_RESOLUTION: f64 = 0.1;
/// The experiment's own uncertainty on stiffness, damping and actuator gains when not
/// given: before identification nothing is known to better than half.
pub const DEFAULT_UNCERTAINTY: f64 = 0.5;
/// The guard stops the experiment when a barrier at the state read falls below this \[m, or
/// rad\]: a few ticks of the fastest motion an experiment makes (about 0.1 m/s at 33 Hz).
pub const DEFAULT_STOP_DISTANCE: f64 = 1e-3;
/// Amplitudes grow only while the lowest barrier predicted for the next level stays above
/// this \[m, or rad\].
pub const DEFAULT_GROWTH_DISTANCE: f64 = 3e-3;
/// The factor by which the amplitudes grow from one level to the next.
pub const DEFAULT_GROWTH: f64 = 2.0;
/// The smallest first level, as a fraction of the full amplitude: where the experiment's
/// uncertainty leaves no room at all, it starts here and lets the measurements decide.
pub const MIN_START_SCALE: f64 = 0.125;
/// Dynamic: how often the level is reconsidered \[s\] (a few periods of the slowest lines
/// but the lowest, and several of the robot's slowest mode).
pub const DEFAULT_CHECK_WINDOW: f64 = 2.0;

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
/// The patterns the level's rounds run (the base and the three single tendons), before
/// the others.
const PROBED: usize = 4;
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
    /// Static: the window over which rest is judged \[s\].
    pub quiet_window: f64,
    /// Static: how long a set is kept once at rest, its rows marked `rest` \[s\].
    pub rest_window: f64,
    /// Static: the band within which a coordinate counts as at rest \[m\]: over the quiet
    /// window its standard deviation at most this over `2√2` (a sinusoid spanning it), its
    /// mean drifting by at most half of it.
    pub rest_threshold: f64,
    /// Dynamic: number of operating points.
    pub operating_points: usize,
    /// Dynamic: the raised-cosine fade into each operating point \[s\].
    pub fade: f64,
    /// Dynamic: the multisines' band \[Hz\] (the upper end at most a sixth of the loop rate).
    pub band: [f64; 2],
    /// Dynamic: the frequency grid's spacing `f0` \[Hz\].
    pub resolution: f64,
    /// The experiment's own uncertainty on stiffness, damping and actuator gains (a
    /// fraction): the first level is chosen safe for any robot within it.
    pub uncertainty: f64,
    /// The guard: the experiment stops when a barrier at the state read falls below this
    /// \[m, or rad for a bend limit\].
    pub stop_distance: f64,
    /// Amplitudes grow only while the lowest barrier predicted for the next level stays
    /// above this \[m, or rad\].
    pub growth_distance: f64,
    /// The factor from one level to the next (above 1).
    pub growth: f64,
    /// Dynamic: how often the level is reconsidered \[s\].
    pub check_window: f64,
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
            uncertainty: DEFAULT_UNCERTAINTY,
            stop_distance: DEFAULT_STOP_DISTANCE,
            growth_distance: DEFAULT_GROWTH_DISTANCE,
            growth: DEFAULT_GROWTH,
            check_window: DEFAULT_CHECK_WINDOW,
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
        check(
            "--experiment-uncertainty",
            self.uncertainty,
            &EXPERIMENT_UNCERTAINTY,
        )?;
        check("--stop-distance", self.stop_distance, &GUARD_DISTANCE)?;
        check("--growth-distance", self.growth_distance, &GUARD_DISTANCE)?;
        if self.growth_distance < self.stop_distance {
            return Err(format!(
                "--growth-distance: {} must be at least the stop distance {} (--stop-distance): \
                 amplitudes that grow up to the stop would end every experiment there",
                self.growth_distance, self.stop_distance
            ));
        }
        if !(self.growth.is_finite() && self.growth > 1.0 && self.growth <= 10.0) {
            return Err(format!(
                "growth: must be above 1 and at most 10, got {}",
                self.growth
            ));
        }
        for (name, value) in [
            ("settle time", self.settle_time),
            ("quiet window", self.quiet_window),
            ("rest window", self.rest_window),
            ("fade", self.fade),
            ("resolution", self.resolution),
            ("check window", self.check_window),
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
/// lowered by the fraction `softer_by` (or the declared uncertainty, if larger) and every
/// tension pulling harder than commanded by the fraction `stronger_by` (actuator gains
/// off): the room is the least any such robot has, and the tensions are commanded ones.
pub fn module_room(
    robot: &Robot,
    tension_limits: &[[f64; 2]],
    softer_by: f64,
    stronger_by: f64,
) -> Vec<ModuleRoom> {
    let down = -robot.gravity[2];
    let softer = 1.0 - softer_by.max(robot.uncertainty.stiffness);
    let stronger = 1.0 + stronger_by.max(0.0);
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
                -(load + 3.0 * f_min * stronger) / kappa_l
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
                (0.5 * kappa_l * room / stronger).min(3.0 * (f_max - f_min).max(0.0))
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
                / (module.tendon_radius * stronger))
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
    /// The first level, as a fraction of the full amplitude: safe for any robot within the
    /// experiment's uncertainty where that leaves room ([`MIN_START_SCALE`] where not).
    pub start_scale: f64,
    /// The levels measured (static: each round of single tendons; dynamic: each check
    /// window): the level, the lowest barrier reached, and the lowest predicted for the
    /// level chosen next.
    pub levels: Vec<Level>,
    /// Why the guard stopped the experiment (`None`: it did not).
    pub stopped: Option<ExperimentStop>,
}

/// One level of an experiment's amplitudes and what it did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Level {
    /// The level: a fraction of the full amplitude (and base above `f_min`).
    pub scale: f64,
    /// The lowest barrier at a state read during it \[m, or rad\].
    pub lowest: f64,
    /// The next level chosen.
    pub next: f64,
    /// The lowest barrier predicted for the rest of the experiment at the next level,
    /// extrapolated from the drops measured so far \[m, or rad\] (`+∞`: nothing moved).
    pub predicted: f64,
}

/// Why an experiment's guard stopped it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ExperimentStop {
    /// A barrier at the state read fell below the stop distance (or was not a number).
    Barrier {
        /// Its index in the model's barrier table.
        barrier: usize,
        /// Its value at the state read \[m, or rad\].
        value: f64,
        /// The lower of that and its value where the robot was heading \[m, or rad\].
        ahead: f64,
        /// The stop distance \[m, or rad\].
        distance: f64,
    },
    /// The drops measured leave no level above zero whose predicted lowest barrier stays
    /// above the growth distance.
    NoRoom {
        /// The barrier that decided it.
        barrier: usize,
        /// Its value in the reference state \[m, or rad\].
        reference: f64,
        /// The growth distance \[m, or rad\].
        distance: f64,
    },
}

impl ExperimentStop {
    /// The index of the barrier that stopped the experiment.
    pub fn barrier(&self) -> usize {
        match *self {
            ExperimentStop::Barrier { barrier, .. } | ExperimentStop::NoRoom { barrier, .. } => {
                barrier
            }
        }
    }

    /// What happened, in a sentence, `label` and `unit` naming the barrier.
    pub fn describe(&self, label: &str, unit: &str) -> String {
        match *self {
            ExperimentStop::Barrier {
                value,
                ahead,
                distance,
                ..
            } => format!(
                "{label} at {value:.3e} {unit}, heading for {ahead:.3e} {unit} by the next \
                 command, below the stop distance {distance:e} {unit} (--stop-distance): the \
                 robot is farther from its file than its levels allow, or the filter pulled it \
                 there (see the relaxed ticks)"
            ),
            ExperimentStop::NoRoom {
                reference,
                distance,
                ..
            } => format!(
                "{label} sits at {reference:.3e} {unit} with the cables at their base, and moves \
                 with the excitation: no level keeps it above the growth distance {distance:e} \
                 {unit} (--growth-distance)"
            ),
        }
    }
}

/// How fast a barrier's drop may grow with the level beyond the levels measured: as the
/// level to this power (`beyond_measured`). The example robot against
/// `calibration-true.toml` shows 1.2 to 1.3 from a level to twice it (module 1's
/// elongation: the tendons' moment arms and the weight's lever grow with the bend, and a
/// step's overshoot adds to the rest state); a linear extrapolation then missed by up to
/// 1.5 mm and a loaded run's guard stopped the experiment.
pub const DROP_GROWTH_POWER: f64 = 1.5;

/// The next level from `linear`, the level at which a barrier's drop, extrapolated linearly
/// from the largest drop per newton measured, reaches the growth distance, and `measured`,
/// the level of the window just measured (both fractions of the full amplitude). Within the
/// level measured the linear extrapolation stands; beyond it the drop is allowed to grow
/// as the level to [`DROP_GROWTH_POWER`] (`drop(s) = sensitivity · s · (s / measured)^(p −
/// 1)`), which gives `measured · (linear / measured)^(1/p)`.
fn beyond_measured(linear: f64, measured: f64) -> f64 {
    if linear <= measured || measured <= 0.0 {
        linear
    } else {
        measured * (linear / measured).powf(1.0 / DROP_GROWTH_POWER)
    }
}

/// The factor by which the linear extrapolation's drop at `level` is raised when `level`
/// lies beyond `measured` ([`beyond_measured`]).
fn drop_allowance(level: f64, measured: f64) -> f64 {
    if level <= measured || measured <= 0.0 {
        1.0
    } else {
        (level / measured).powf(DROP_GROWTH_POWER - 1.0)
    }
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
    /// Static: the readings of the step so far (the last ones a ring can hold), for rest:
    /// their times, and `n_servos` coordinates each.
    ring_t: Vec<f64>,
    ring_q: Vec<f64>,
    ring_len: usize,
    ring_head: usize,
    rest_start: Option<f64>,
    steps_at_rest: usize,
    steps_without_rest: usize,
    rest_rows: u64,
    finished: bool,
    // Levels and the guard.
    /// The level in force, and (dynamic) the one before it and when it changed.
    scale: f64,
    scale_from: f64,
    scale_changed: f64,
    start_scale: f64,
    /// The largest deviation of a tension from `f_min` over the design at full level \[N\].
    full_deviation: f64,
    /// Static: the single-tendon rounds that measure the levels are over, from this step.
    main_from: Option<usize>,
    /// Static: the tensions of the set held and of the one before (the ramp's start).
    held: Vec<f64>,
    previous: Vec<f64>,
    /// Barriers of the reference state (static: the base set at its end; dynamic: the first
    /// reading), the last read, the lowest of the window, and the drop per newton of
    /// deviation measured so far \[m/N\].
    reference: Vec<f64>,
    last_barriers: Vec<f64>,
    window_low: Vec<f64>,
    sensitivity: Vec<f64>,
    /// The largest deviation commanded in the window \[N\], and when it began (dynamic).
    window_deviation: f64,
    window_start: f64,
    levels: Vec<Level>,
    stop: Option<ExperimentStop>,
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
        // The full level: room for a robot STIFFNESS_ALLOWANCE softer than its file; the
        // first: room for any robot within the experiment's uncertainty.
        let room = module_room(robot, tension_limits, STIFFNESS_ALLOWANCE, 0.0);
        let worst = module_room(
            robot,
            tension_limits,
            settings.uncertainty,
            settings.uncertainty,
        );

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
        // The first level: what keeps every module of any robot within the uncertainty in
        // half of its room, as a fraction of the full level (the static increment and the
        // dynamic amplitude and operating points alike).
        let mut start_scale: f64 = 1.0;
        for i in 0..modules {
            let (full, safe) = match settings.kind {
                ExperimentKind::Static => (
                    amplitude[i].max(amplitude[i] * bend_factor(i)),
                    worst[i]
                        .extra_tension
                        .min(worst[i].bend_tension / bend_factor(i)),
                ),
                ExperimentKind::Dynamic => {
                    let levels = 3.0 + 1.5 * (points - 1.0) + common[i];
                    (
                        amplitude[i],
                        (worst[i].extra_tension / levels).min(worst[i].bend_tension / 3.0),
                    )
                }
            };
            if full > 0.0 {
                start_scale = start_scale.min(safe / full);
            }
        }
        let start_scale = if start_scale.is_finite() {
            start_scale.clamp(MIN_START_SCALE, 1.0)
        } else {
            MIN_START_SCALE
        };
        let full_deviation = (0..modules)
            .map(|i| {
                let above = base[i] - f_min[i];
                match settings.kind {
                    ExperimentKind::Static => above + amplitude[i],
                    ExperimentKind::Dynamic => {
                        above + 0.5 * amplitude[i] * (points - 1.0) + amplitude[i]
                    }
                }
            })
            .fold(0.0, f64::max);
        let probe_rounds = (1.0 / start_scale).log(settings.growth).ceil().max(0.0) as usize + 1;
        let window_count = match settings.kind {
            ExperimentKind::Static => probe_rounds,
            ExperimentKind::Dynamic => {
                (settings.length().unwrap_or(DEFAULT_DYNAMIC_DURATION) / settings.check_window)
                    .ceil() as usize
                    + 1
            }
        };
        // Room for the quiet window's readings at up to twice the loop rate.
        let ring = match settings.kind {
            ExperimentKind::Static => (2.0 * settings.quiet_window * rate).ceil() as usize + 8,
            ExperimentKind::Dynamic => 0,
        };
        // Static: the base set first, ramped from f_min.
        let previous: Vec<f64> = f_min.iter().flat_map(|&f| [f; 3]).collect();
        let held: Vec<f64> = (0..n)
            .map(|j| f_min[j / 3] + start_scale * (base[j / 3] - f_min[j / 3]))
            .collect();
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
            ring_t: vec![0.0; ring],
            ring_q: vec![0.0; ring * n],
            ring_len: 0,
            ring_head: 0,
            rest_start: None,
            steps_at_rest: 0,
            steps_without_rest: 0,
            rest_rows: 0,
            finished: false,
            scale: start_scale,
            scale_from: start_scale,
            scale_changed: 0.0,
            start_scale,
            full_deviation,
            main_from: None,
            previous,
            held,
            reference: Vec::new(),
            last_barriers: Vec::new(),
            window_low: Vec::new(),
            sensitivity: Vec::new(),
            window_deviation: 0.0,
            window_start: 0.0,
            levels: Vec::with_capacity(window_count.min(10_000)),
            stop: None,
        })
    }

    /// Makes room to watch `barriers` barriers ([`Experiment::observe`]); before the loop.
    pub fn watch(&mut self, barriers: usize) {
        self.reference = vec![f64::NAN; barriers];
        self.last_barriers = vec![f64::NAN; barriers];
        self.window_low = vec![f64::INFINITY; barriers];
        self.sensitivity = vec![0.0; barriers];
    }

    /// The barriers `b` at the state read of a tick, before its [`Experiment::command`], and
    /// `ahead` where the robot will be when the next command lands (the state read carried
    /// on at its velocity): the guard stops the experiment when one of either is below the
    /// stop distance or not a number (then [`Experiment::finished`], and its tensions fall
    /// to `f_min` until the run's safe stop), and the lowest of each at the state read is
    /// kept for the level's measurement. Allocates nothing.
    pub fn observe(&mut self, b: &[f64], ahead: &[f64]) {
        let n = b.len().min(self.window_low.len());
        for (j, &value) in b[..n].iter().enumerate() {
            let heading = ahead.get(j).copied().unwrap_or(value);
            let guarded = value.min(heading);
            let below = value.is_nan() || heading.is_nan() || guarded < self.settings.stop_distance;
            if self.stop.is_none() && !self.finished && below {
                self.stop = Some(ExperimentStop::Barrier {
                    barrier: j,
                    value,
                    ahead: guarded,
                    distance: self.settings.stop_distance,
                });
                self.finished = true;
            }
            self.window_low[j] = self.window_low[j].min(value);
            self.last_barriers[j] = value;
        }
    }

    /// Why the guard stopped the experiment, if it did.
    pub fn stopped(&self) -> Option<ExperimentStop> {
        self.stop
    }

    /// The level in force (a fraction of the full amplitude).
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// The end of a level's window: the drops measured so far give each barrier's drop per
    /// newton of deviation (the most seen), and the next level is the largest, at most
    /// `growth` times this one and at most the full level, at which every barrier,
    /// extrapolated to the design's largest deviation (linearly within the level measured,
    /// faster beyond: [`beyond_measured`]), stays above the growth distance. Records the
    /// [`Level`]; stops the experiment when no level above zero qualifies. Allocates nothing
    /// (the levels' room is reserved).
    fn end_window(&mut self) {
        let s = &self.settings;
        let mut lowest = f64::INFINITY;
        let mut safe = f64::INFINITY;
        let mut no_room = None;
        for j in 0..self.window_low.len() {
            let low = self.window_low[j];
            lowest = lowest.min(low);
            let reference = self.reference[j];
            if self.window_deviation > 0.0 && reference.is_finite() && low.is_finite() {
                let drop = (reference - low).max(0.0);
                self.sensitivity[j] = self.sensitivity[j].max(drop / self.window_deviation);
            }
            let sensitivity = self.sensitivity[j];
            if sensitivity > 0.0 && reference.is_finite() {
                let linear = (reference - s.growth_distance) / (sensitivity * self.full_deviation);
                let level = beyond_measured(linear, self.scale);
                if level <= 0.0 && no_room.is_none() {
                    no_room = Some(ExperimentStop::NoRoom {
                        barrier: j,
                        reference,
                        distance: s.growth_distance,
                    });
                }
                safe = safe.min(level);
            }
            self.window_low[j] = f64::INFINITY;
        }
        let next = safe.min(s.growth * self.scale).clamp(0.0, 1.0);
        let predicted = (0..self.sensitivity.len())
            .filter(|&j| self.sensitivity[j] > 0.0 && self.reference[j].is_finite())
            .map(|j| {
                self.reference[j]
                    - self.sensitivity[j]
                        * next
                        * drop_allowance(next, self.scale)
                        * self.full_deviation
            })
            .fold(f64::INFINITY, f64::min);
        if self.levels.len() < self.levels.capacity() {
            self.levels.push(Level {
                scale: self.scale,
                lowest,
                next,
                predicted,
            });
        }
        self.window_deviation = 0.0;
        if let Some(stop) = no_room {
            self.stop.get_or_insert(stop);
            self.finished = true;
        }
        self.scale_from = self.scale;
        self.scale = next;
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
            // The base, the rounds of single tendons that measure the levels (those run and
            // those the level in force still needs to reach the full one), the other sets.
            ExperimentKind::Static => match self.main_from {
                Some(from) => from + STATIC_PATTERNS.len() - PROBED,
                None => {
                    let to_go = if self.scale < 1.0 {
                        (1.0 / self.scale).log(self.settings.growth).ceil() as usize
                    } else {
                        0
                    };
                    1 + 3 * (self.levels.len() + 1 + to_go) + STATIC_PATTERNS.len() - PROBED
                }
            },
            ExperimentKind::Dynamic => self.settings.operating_points,
        }
    }

    /// Static: the pattern of [`STATIC_PATTERNS`] step `step` holds.
    fn pattern(&self, step: usize) -> usize {
        match self.main_from {
            _ if step == 0 => 0,
            Some(from) if step >= from => (PROBED + step - from).min(STATIC_PATTERNS.len() - 1),
            _ => 1 + (step - 1) % 3,
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
    /// dynamic experiment once finished (its length is its end) unless its guard stopped
    /// it.
    pub fn steps_left(&self) -> usize {
        match self.settings.kind {
            ExperimentKind::Static => self
                .steps()
                .saturating_sub(self.steps_at_rest + self.steps_without_rest),
            ExperimentKind::Dynamic => {
                if self.finished && self.stop.is_none() {
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
                let d = self.length.unwrap_or(DEFAULT_DYNAMIC_DURATION) + self.lead();
                [d, d]
            }
            ExperimentKind::Static => {
                let steps = self.steps() as f64;
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
        if self.length.is_some_and(|d| time >= d + self.lead()) {
            self.finished = true;
        }
        match self.settings.kind {
            ExperimentKind::Static => self.command_static(t, q, tensions),
            ExperimentKind::Dynamic => self.command_dynamic(time, tensions),
        }
    }

    fn command_static(&mut self, t: f64, q: &[f64], tensions: &mut [f64]) -> Mark {
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
                self.observe_rest(t, q);
                let held = t - self.step_start;
                let quiet = self.quiet(t, quiet_window);
                if held >= settle_time && quiet {
                    self.rest_start = Some(t);
                    rest = true;
                } else if held >= step_time {
                    self.steps_without_rest += 1;
                    advance = true;
                }
            }
            if advance {
                self.end_step(t);
            }
        }
        if rest {
            self.rest_rows += 1;
        }
        let n = self.n_servos;
        let ramp = self.settings.ramp;
        let into = t - self.step_start;
        if self.stop.is_some() {
            // Stopped by the guard: the cables back to f_min until the safe stop.
            for (j, tension) in tensions[..n].iter_mut().enumerate() {
                *tension = self.f_min[j / 3];
            }
        } else if into < ramp {
            let w = raised_cosine(into / ramp);
            for (j, tension) in tensions[..n].iter_mut().enumerate() {
                *tension = self.previous[j] + (self.held[j] - self.previous[j]) * w;
            }
        } else {
            tensions[..n].copy_from_slice(&self.held[..n]);
        }
        self.note_deviation(&tensions[..n]);
        Mark {
            step: self.step,
            rest,
        }
    }

    /// The largest deviation from `f_min` of the tensions commanded in this window.
    fn note_deviation(&mut self, tensions: &[f64]) {
        for (j, &f) in tensions.iter().enumerate() {
            self.window_deviation = self.window_deviation.max(f - self.f_min[j / 3]);
        }
    }

    /// Static: the step held is over at `t`; the next one, or the end. The base set's end
    /// is the reference state; each round of single tendons ends a level's window, and
    /// the rounds go on while the level grows by at least the square root of the growth
    /// factor (else the other sets follow at the level chosen).
    fn end_step(&mut self, t: f64) {
        let step = self.step;
        if step == 0 {
            self.reference.copy_from_slice(&self.last_barriers);
            self.window_low.fill(f64::INFINITY);
            self.window_deviation = 0.0;
        } else if self.main_from.is_none() && (step - 1) % 3 == 2 {
            let before = self.scale;
            self.end_window();
            if self.scale < self.settings.growth.sqrt() * before {
                self.main_from = Some(step + 1);
            }
        }
        if self.finished
            || (self.main_from.is_some() && self.pattern(step) == STATIC_PATTERNS.len() - 1)
        {
            self.finished = true;
            return;
        }
        self.step += 1;
        self.step_start = t;
        self.ring_len = 0;
        self.rest_start = None;
        let pattern = STATIC_PATTERNS[self.pattern(self.step)];
        let modules = self.base.len();
        self.previous.copy_from_slice(&self.held);
        for i in 0..modules {
            for (k, p) in pattern.iter().enumerate() {
                let f_min = self.f_min[i];
                self.held[3 * i + k] =
                    f_min + self.scale * (self.base[i] - f_min + p * self.amplitude[i]);
            }
        }
    }

    /// Adds a reading of the step to the ring; a reading that is not a number empties it
    /// (rest is looked for afresh).
    fn observe_rest(&mut self, t: f64, q: &[f64]) {
        let n = self.n_servos;
        let capacity = self.ring_t.len();
        if capacity == 0 || q.len() < n {
            return;
        }
        if q[..n].iter().any(|v| !v.is_finite()) {
            self.ring_len = 0;
            return;
        }
        let slot = (self.ring_head + self.ring_len) % capacity;
        self.ring_t[slot] = t;
        self.ring_q[slot * n..(slot + 1) * n].copy_from_slice(&q[..n]);
        if self.ring_len < capacity {
            self.ring_len += 1;
        } else {
            self.ring_head = (self.ring_head + 1) % capacity;
        }
    }

    /// Whether the robot is at rest at `t`: the readings cover the last `window` seconds,
    /// and over them every coordinate's standard deviation is at most `threshold/(2√2)`
    /// (a sinusoid of that spread spans `threshold`, peak to peak) and the mean of their
    /// second half differs from the first half's by at most `threshold/2` (drift). Unlike
    /// the span of the readings, which grows with every reading a window holds (at 100 Hz
    /// readings noisy by one encoder count span more than 0.3 mm in a bend coordinate in
    /// one window of 0.5 s in seven, by 1.5 counts in nineteen of twenty), the
    /// spread and the means settle on the motion (`readings_noisy_by_encoder_counts_still_
    /// come_to_rest`). Allocates nothing.
    fn quiet(&self, t: f64, window: f64) -> bool {
        let n = self.n_servos;
        let capacity = self.ring_t.len();
        if self.ring_len < 2 {
            return false;
        }
        let from = t - window;
        let at = |k: usize| (self.ring_head + k) % capacity;
        // The window is covered: a reading at or before its start.
        if self.ring_t[at(0)] > from + 1e-9 {
            return false;
        }
        let middle = t - 0.5 * window;
        let threshold = self.settings.rest_threshold;
        for c in 0..n {
            let (mut count, mut sum, mut squares) = (0.0, 0.0, 0.0);
            let (mut early, mut early_n, mut late, mut late_n) = (0.0, 0.0, 0.0, 0.0);
            // Deviations from the latest reading, for round-off.
            let origin = self.ring_q[at(self.ring_len - 1) * n + c];
            for k in 0..self.ring_len {
                let slot = at(k);
                let time = self.ring_t[slot];
                if time < from - 1e-9 {
                    continue;
                }
                let v = self.ring_q[slot * n + c] - origin;
                count += 1.0;
                sum += v;
                squares += v * v;
                if time < middle {
                    early += v;
                    early_n += 1.0;
                } else {
                    late += v;
                    late_n += 1.0;
                }
            }
            if count < 2.0 || early_n < 1.0 || late_n < 1.0 {
                return false;
            }
            let mean = sum / count;
            let variance = (squares / count - mean * mean).max(0.0);
            if variance.sqrt() > threshold / (2.0 * std::f64::consts::SQRT_2)
                || (late / late_n - early / early_n).abs() > 0.5 * threshold
            {
                return false;
            }
        }
        true
    }

    /// Dynamic: the hold at `f_min` before the excitation \[s\] (the settle time), at whose
    /// end the reference state is read; static: none (the base set is its reference).
    fn lead(&self) -> f64 {
        match self.settings.kind {
            ExperimentKind::Static => 0.0,
            ExperimentKind::Dynamic => self.settings.settle_time,
        }
    }

    fn command_dynamic(&mut self, time: f64, tensions: &mut [f64]) -> Mark {
        let n = self.n_servos;
        let lead = self.lead();
        if time < lead {
            // The cables at f_min until the robot has settled there: the reference state
            // the levels' drops are measured from.
            for (j, tension) in tensions[..n].iter_mut().enumerate() {
                *tension = self.f_min[j / 3];
            }
            return Mark {
                step: 0,
                rest: false,
            };
        }
        if self.window_start < lead {
            self.reference.copy_from_slice(&self.last_barriers);
            self.window_low.fill(f64::INFINITY);
            self.window_deviation = 0.0;
            self.window_start = lead;
            self.scale_changed = 0.0;
        }
        let time = time - lead;
        if !self.finished && time + lead - self.window_start >= self.settings.check_window {
            self.end_window();
            self.window_start = time + lead;
            self.scale_changed = time;
        }
        if self.stop.is_some() {
            // Stopped by the guard: the cables back to f_min until the safe stop.
            for (j, tension) in tensions[..n].iter_mut().enumerate() {
                *tension = self.f_min[j / 3];
            }
            return Mark {
                step: self.step,
                rest: false,
            };
        }
        // The level, moved to the new one over the ramp.
        let scale = self.scale_from
            + (self.scale - self.scale_from)
                * raised_cosine((time - self.scale_changed) / self.settings.ramp.max(1e-9));
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
            let f_min = self.f_min[i];
            *tension = f_min + scale * (base + envelope * wave - f_min);
        }
        self.note_deviation(&tensions[..n]);
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
        let complete = self.finished && self.steps_left() == 0 && self.stop.is_none();
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
            start_scale: self.start_scale,
            levels: self.levels.clone(),
            stopped: self.stop,
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
            "/../../robots/hardware-example.toml"
        );
        let robot = Robot::load(std::path::Path::new(path)).unwrap();
        let hardware = crate::hardware_description::load(&robot).unwrap().unwrap();
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
        // The base, four rounds of single tendons (levels 1/8 to 1: nothing watched, so
        // nothing holds the levels back) and the twelve other sets.
        assert_eq!(e.steps(), 25);
        let room = module_room(&robot, &limits, STIFFNESS_ALLOWANCE, 0.0);
        for (i, module) in robot.modules.iter().enumerate() {
            let [f_min, f_max] = limits[i];
            let (b, a) = (e.base_tension()[i], e.amplitude()[i]);
            let sets: Vec<[f64; 3]> = (0..STATIC_PATTERNS.len())
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
        assert_eq!(e.steps_at_rest(), 25);
        assert_eq!(e.steps_without_rest(), 0);
        let dt = 1.0 / RATE;
        for step in 0..25 {
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
            // Over the quiet window before the onset, each coordinate's spread was within a
            // sinusoid's spanning the threshold, and over the rest rows it moves less than
            // the threshold (brute force over the samples).
            for c in 0..6 {
                let window: Vec<f64> = rows
                    .iter()
                    .filter(|s| s.0 >= onset - settings.quiet_window - 1e-9 && s.0 <= onset)
                    .map(|s| s.2[c])
                    .collect();
                let mean = window.iter().sum::<f64>() / window.len() as f64;
                let spread = (window.iter().map(|v| (v - mean).powi(2)).sum::<f64>()
                    / window.len() as f64)
                    .sqrt();
                assert!(
                    spread <= settings.rest_threshold / 8f64.sqrt(),
                    "step {step}: spread {spread}"
                );
                let values = rest.iter().map(|s| s.2[c]);
                let span =
                    values.clone().fold(f64::MIN, f64::max) - values.fold(f64::MAX, f64::min);
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

    /// Readings noisy by 1.5 encoder counts (Gaussian, before rounding to counts of
    /// 0.069 mm of tendon), at 100 Hz, of a robot that is at rest: every set comes to rest
    /// within a second of the settle time. Judged on the span of the readings, as before,
    /// nineteen windows of 0.5 s in twenty spanned more than 0.3 mm in a bend coordinate
    /// (one in seven with one count), and sets were left without rest.
    #[test]
    fn readings_noisy_by_encoder_counts_still_come_to_rest() {
        let (robot, limits) = example();
        let settings = ExperimentSettings::new(ExperimentKind::Static);
        let rate = 100.0;
        let mut e = Experiment::new(&settings, &robot, &limits, rate).unwrap();
        let count = 0.045 * 2.0 * PI / 4096.0;
        // Tendon lengths of module i (the coordinates' own combination of them, as the
        // mapping forms them: bend from differences, δL from the mean).
        let mut state = 12345_u64;
        let mut gaussian = || {
            // Box–Muller on a 64-bit linear congruential generator.
            let mut uniform = || {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (u, v) = (uniform(), uniform());
            (-2.0 * u.ln()).sqrt() * (2.0 * PI * v).cos()
        };
        let mut tensions = [0.0; 6];
        let mut k = 0;
        let mut onsets = Vec::new();
        let mut step_start = 0.0;
        let mut last_step = 0;
        while !e.finished() {
            let t = k as f64 / rate;
            let mut q = [0.0; 6];
            for i in 0..2 {
                let psi = &robot.modules[i].tendon_angles;
                let lengths: Vec<f64> =
                    (0..3).map(|_| (0.3 + gaussian()).round() * count).collect();
                q[3 * i] = (0..3).map(|j| -2.0 / 3.0 * psi[j].cos() * lengths[j]).sum();
                q[3 * i + 1] = (0..3).map(|j| -2.0 / 3.0 * psi[j].sin() * lengths[j]).sum();
                q[3 * i + 2] = -lengths.iter().sum::<f64>() / 3.0;
            }
            let mark = e.command(t, &q, &mut tensions);
            if mark.step != last_step {
                (last_step, step_start) = (mark.step, t);
            }
            if mark.rest && onsets.len() == mark.step {
                onsets.push(t - step_start);
            }
            k += 1;
            assert!(k < 1_000_000);
        }
        assert_eq!(e.steps_without_rest(), 0);
        assert_eq!(e.steps_at_rest(), e.steps());
        for (step, onset) in onsets.iter().enumerate() {
            assert!(
                *onset <= settings.settle_time + 1.0,
                "step {step}: at rest after {onset} s"
            );
        }
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
        assert_eq!((e.steps_at_rest(), e.steps_without_rest()), (0, 25));
        assert_eq!(e.rest_rows(), 0);
        let start = |step: usize| samples.iter().find(|s| s.1 == step).unwrap().0;
        for step in 0..24 {
            // The next step starts at the first sample 2 s after this one's start.
            let held = start(step + 1) - start(step);
            assert!(
                (2.0 - 1e-9..2.0 + 1.0 / RATE).contains(&held),
                "step {step}: {held} s"
            );
        }
        let report = e.report();
        assert!(report.complete);
        assert_eq!(report.steps_run, 25);
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
        assert_eq!(e.steps_left(), 23);
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
                // Its length after the hold at f_min (the settle time, 1 s).
                assert!((t - 107.0).abs() < 0.011, "finished at {t}");
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
        let lead = settings.settle_time;
        for k in 0..((DEFAULT_DYNAMIC_DURATION + lead) / dt) as usize {
            let t = k as f64 * dt;
            let mark = e.command(t, &[0.0; 6], &mut tensions);
            let into = t - lead - mark.step as f64 * share;
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
        // Through the first operating point: the levels grow to the full one (nothing is
        // watched) and its ramp ends.
        for k in 0..2000 {
            e.command(k as f64 * 0.01, &[0.0; 6], &mut tensions);
        }
        assert_eq!(e.scale(), 1.0);
        let mut deviation = vec![[0.0; 6]; samples];
        for (s, d) in deviation.iter_mut().enumerate() {
            // After the hold at f_min (1 s), 1 s into the second point.
            let t = 22.0 + s as f64 * dt;
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
            for k in 0..STATIC_PATTERNS.len() {
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

    /// The first level on the full nonlinear model: against a robot 20 % softer than its
    /// file with every actuator 20 % stronger (the corner of an experiment uncertainty of
    /// 0.2), every static set at the first level keeps each module within half of the
    /// compression room it has at `f_min` (where the old defaults, made for a robot 30 %
    /// softer with its file's gains, took module 1 of such a robot further).
    #[test]
    fn the_first_level_keeps_half_of_the_room_of_any_robot_in_the_uncertainty() {
        let (robot, limits) = example();
        let mut settings = ExperimentSettings::new(ExperimentKind::Static);
        settings.uncertainty = 0.2;
        let e = experiment(&settings);
        let start = e.report().start_scale;
        assert!(start > MIN_START_SCALE && start < 1.0, "{start}");
        let soft = scaled(
            &robot,
            &[ModuleFactors {
                stiffness: [0.8; 2],
                ..ModuleFactors::NOMINAL
            }; 2],
        )
        .unwrap();
        let model = Model::new(soft).unwrap();
        let mut plant = Plant::new(&model, Tolerances::default()).unwrap();
        let stronger = 1.2;
        let f_min: Vec<f64> = (0..6).map(|j| stronger * limits[j / 3][0]).collect();
        let q = equilibrium(&model, &mut plant, &f_min);
        let (room, _) = elongation_barriers(&model, &q);
        for pattern in &STATIC_PATTERNS {
            let f: Vec<f64> = (0..6)
                .map(|j| {
                    let (i, f_min) = (j / 3, limits[j / 3][0]);
                    let commanded = f_min
                        + start * (e.base_tension()[i] - f_min + pattern[j % 3] * e.amplitude()[i]);
                    stronger * commanded
                })
                .collect();
            let q = equilibrium(&model, &mut plant, &f);
            let (left, _) = elongation_barriers(&model, &q);
            for i in 0..2 {
                assert!(
                    left[i] >= 0.5 * room[i] - 1e-6,
                    "{pattern:?}: module {} keeps {} of {} m",
                    i + 1,
                    left[i],
                    room[i]
                );
            }
        }
    }

    /// A static experiment on a robot whose one barrier `h0 − σ·d` falls with the largest
    /// deviation `d` of a commanded tension from `f_min` (at once, and at rest at once):
    /// the barriers it observed each tick, and the experiment.
    fn linear_static(h0: f64, sigma: f64, settings: &ExperimentSettings) -> (Vec<f64>, Experiment) {
        let (_, limits) = example();
        let mut e = experiment(settings);
        e.watch(1);
        let mut tensions = [limits[0][0]; 6];
        let mut seen = Vec::new();
        let mut k = 0;
        while !e.finished() {
            let deviation = (0..6)
                .map(|j| tensions[j] - limits[j / 3][0])
                .fold(0.0, f64::max);
            let h = [h0 - sigma * deviation];
            seen.push(h[0]);
            e.observe(&h, &h);
            e.command(k as f64 / RATE, &[0.0; 6], &mut tensions);
            k += 1;
            assert!(k < 100_000, "not finished");
        }
        (seen, e)
    }

    #[test]
    fn levels_grow_while_the_predicted_barrier_keeps_its_distance_and_no_further() {
        let settings = ExperimentSettings::new(ExperimentKind::Static);
        let full = experiment(&settings).amplitude()[1];
        // At the full level the barrier would fall by 6 mm from 5 mm: the growth distance
        // (3 mm) allows a third of it, linearly. Beyond the level measured the drop is
        // allowed to grow as the level to the power p = DROP_GROWTH_POWER: from 1/8, the next
        // level is 1/8 · (8/3)^(1/p); from there the next grows by less than √2 and ends the
        // rounds.
        let (h0, sigma) = (5e-3, 6e-3 / full);
        let (seen, e) = linear_static(h0, sigma, &settings);
        let report = e.report();
        assert!(report.complete, "{report:?}");
        assert_eq!(report.start_scale, MIN_START_SCALE);
        let scales: Vec<f64> = report.levels.iter().map(|l| l.scale).collect();
        let beyond = |m: f64| m * (1.0 / (3.0 * m)).powf(1.0 / DROP_GROWTH_POWER);
        let second = beyond(0.125);
        assert_eq!(scales.len(), 2, "{scales:?}");
        assert_eq!(scales[0], 0.125);
        assert!((scales[1] - second).abs() < 1e-12, "{scales:?}");
        let last = report.levels.last().unwrap();
        let third = beyond(second);
        assert!(third < 2f64.sqrt() * second);
        assert!((last.next - third).abs() < 1e-12, "{last:?}");
        // Predicted with the allowance: exactly the growth distance.
        assert!((last.predicted - 3e-3).abs() < 1e-12, "{last:?}");
        // This robot's drop is linear: the lowest it went to is no lower than 5 mm less 6 mm
        // times the level the other sets ran at, and is reached on the second round (its
        // single tendons deviate most).
        let lowest = seen.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(lowest >= 5e-3 - 6e-3 * third - 1e-9, "{lowest}");
        assert!((lowest - (5e-3 - 6e-3 * second)).abs() < 1e-9, "{lowest}");
        // The base, two rounds, the twelve other sets.
        assert_eq!(report.steps, 1 + 6 + 12);
        assert_eq!(report.steps_at_rest, report.steps);

        // With room to spare the levels reach the full one.
        let (seen, e) = linear_static(h0, 1e-3 / full, &settings);
        let scales: Vec<f64> = e.report().levels.iter().map(|l| l.scale).collect();
        assert_eq!(scales.len(), 4, "{scales:?}");
        for (scale, expected) in scales.iter().zip([0.125, 0.25, 0.5, 1.0]) {
            assert!((scale - expected).abs() < 1e-12, "{scales:?}");
        }
        let lowest = seen.iter().copied().fold(f64::INFINITY, f64::min);
        assert!((lowest - 4e-3).abs() < 1e-9, "{lowest}");
    }

    /// A dynamic experiment on a robot whose one barrier sits at 10 mm with the cables
    /// slack (the first reading), 2 mm lower with them at `f_min`, and falls linearly with
    /// the largest deviation from `f_min` beyond, by 1 mm (8 mm) at the design's largest:
    /// the levels are measured from the hold at `f_min`, so they reach the full one when
    /// the fall leaves room (from the first reading, the 2 mm of `f_min` counted as a drop
    /// of the first level and held the levels back), and stay where the extrapolation keeps
    /// 3 mm when it does not.
    #[test]
    fn dynamic_levels_are_measured_from_the_hold_at_f_min() {
        let (_, limits) = example();
        let settings = ExperimentSettings::new(ExperimentKind::Dynamic);
        // The design's largest deviation: the top operating point (a above the lowest,
        // itself a above f_min) plus a.
        let a = experiment(&settings)
            .amplitude()
            .iter()
            .copied()
            .fold(0.0, f64::max);
        for (drop, full) in [(1e-3, true), (8e-3, false)] {
            let sigma = drop / (3.0 * a);
            let mut e = experiment(&settings);
            e.watch(1);
            let mut tensions = [0.0; 6];
            let mut lowest = f64::INFINITY;
            let mut k = 0;
            while !e.finished() {
                let h = if k == 0 {
                    10e-3
                } else {
                    let deviation = (0..6)
                        .map(|j| tensions[j] - limits[j / 3][0])
                        .fold(0.0, f64::max);
                    8e-3 - sigma * deviation
                };
                lowest = lowest.min(h);
                e.observe(&[h], &[h]);
                e.command(k as f64 / RATE, &[0.0; 6], &mut tensions);
                k += 1;
            }
            let report = e.report();
            assert!(report.complete, "{report:?}");
            let top = report.levels.iter().map(|l| l.scale).fold(0.0, f64::max);
            if full {
                assert_eq!(top, 1.0, "{:?}", report.levels);
            } else {
                assert!(top < 1.0, "{:?}", report.levels);
                assert!(lowest >= 3e-3 - 1e-9, "{lowest}");
            }
        }
    }

    #[test]
    fn the_guard_stops_below_the_stop_distance_and_lowers_the_tensions_to_f_min() {
        let (_, limits) = example();
        for kind in [ExperimentKind::Static, ExperimentKind::Dynamic] {
            // Where the robot is heading decides as well as where it is; a NaN stops too.
            for (now, ahead) in [(0.5e-3, 5e-3), (5e-3, 0.5e-3), (f64::NAN, 5e-3)] {
                let mut e = experiment(&ExperimentSettings::new(kind));
                e.watch(2);
                let mut tensions = [0.0; 6];
                for k in 0..100 {
                    e.observe(&[5e-3, 5e-3], &[5e-3, 5e-3]);
                    e.command(k as f64 / RATE, &[0.0; 6], &mut tensions);
                }
                assert!(!e.finished());
                e.observe(&[5e-3, now], &[5e-3, ahead]);
                e.command(100.0 / RATE, &[0.0; 6], &mut tensions);
                assert!(e.finished());
                match e.stopped() {
                    Some(ExperimentStop::Barrier { barrier: 1, .. }) => {}
                    other => panic!("{other:?}"),
                }
                for (j, f) in tensions.iter().enumerate() {
                    assert_eq!(*f, limits[j / 3][0], "{kind:?}");
                }
                assert!(!e.report().complete);
            }
        }
        // Above the distance it goes on.
        let mut e = experiment(&ExperimentSettings::new(ExperimentKind::Static));
        e.watch(1);
        e.observe(&[1.5e-3], &[1.1e-3]);
        assert!(!e.finished() && e.stopped().is_none());
    }

    #[test]
    fn a_barrier_that_moves_from_within_the_growth_distance_leaves_no_room() {
        let settings = ExperimentSettings::new(ExperimentKind::Static);
        let full = experiment(&settings).amplitude()[1];
        let (seen, e) = linear_static(2.5e-3, 1e-3 / full, &settings);
        match e.stopped() {
            Some(ExperimentStop::NoRoom { barrier: 0, .. }) => {}
            other => panic!("{other:?}"),
        }
        // After the first round, at the first level.
        assert_eq!(e.report().levels.len(), 1);
        let lowest = seen.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(lowest > 2e-3, "{lowest}");
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
        s.step_time = DEFAULT_STEP_TIME;
        s.uncertainty = 0.95;
        assert!(refused(&s).starts_with("--experiment-uncertainty: must be"));
        s.uncertainty = DEFAULT_UNCERTAINTY;
        s.stop_distance = -1e-3;
        assert!(refused(&s).starts_with("--stop-distance: must be"));
        s.stop_distance = 4e-3;
        assert!(refused(&s).starts_with("--growth-distance: 0.003 must be at least"));
        s.stop_distance = DEFAULT_STOP_DISTANCE;
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
