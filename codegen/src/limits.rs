//! The valid range of every number a user gives softcbf, in a description file or on the
//! command line: one definition per setting, so that both are checked by the same rule.
//!
//! A [`Limit`] says what a value must be (finite, between bounds, perhaps an integer) and
//! builds the message when it is not; the file checker (`toml_file`) adds the file, line
//! and field, the command line adds the option's name. The ranges are physical: a bound
//! says where a value stops describing a robot (a reply that takes more than a second, a
//! module longer than 10 m), not where the arithmetic happens to break, and every value
//! inside them leaves the model's arithmetic finite (`tests/tests/descriptions.rs`).
//!
//! The state domain ([`state_problem`]) bounds `q` and `q̇` the same way: a bend of at
//! most three quarters of a turn, an elongation within ten rest lengths, speeds within
//! 100 m/s.

use std::f64::consts::PI;
use std::fmt;

use crate::robot::{Module, Robot};

/// What a number must be: finite, within `[min, max]` (or `(min, max]`), perhaps an
/// integer. `unit` is for messages.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limit {
    /// Lower bound.
    pub min: f64,
    /// Whether `min` itself is allowed (`false`: the value must exceed it).
    pub min_inclusive: bool,
    /// Upper bound (always allowed).
    pub max: f64,
    /// Whether the value must be a whole number.
    pub integer: bool,
    /// Unit shown in messages (`""` for none).
    pub unit: &'static str,
}

impl Limit {
    /// `min ≤ value ≤ max`.
    pub const fn closed(min: f64, max: f64, unit: &'static str) -> Limit {
        Limit {
            min,
            min_inclusive: true,
            max,
            integer: false,
            unit,
        }
    }

    /// `min < value ≤ max`.
    pub const fn above(min: f64, max: f64, unit: &'static str) -> Limit {
        Limit {
            min,
            min_inclusive: false,
            max,
            integer: false,
            unit,
        }
    }

    /// The same range mirrored to negative values, `-max ≤ value ≤ max` (for entries whose
    /// sign is free, such as the off-diagonal entries of a gain matrix).
    pub const fn either_sign(self) -> Limit {
        Limit {
            min: -self.max,
            min_inclusive: true,
            ..self
        }
    }

    /// A whole number in `min..=max`.
    pub const fn integer(min: i64, max: i64) -> Limit {
        Limit {
            min: min as f64,
            min_inclusive: true,
            max: max as f64,
            integer: true,
            unit: "",
        }
    }

    /// Whether `value` is allowed.
    pub fn contains(&self, value: f64) -> bool {
        let low = if self.min_inclusive {
            value >= self.min
        } else {
            value > self.min
        };
        value.is_finite() && low && value <= self.max && (!self.integer || value.fract() == 0.0)
    }

    /// The allowed range in words: `> 0 and ≤ 1000 ms`, `an integer in 1..=1000`.
    pub fn describe(&self) -> String {
        if self.integer {
            return format!("an integer in {}..={}", self.min, self.max);
        }
        let unit = match self.unit {
            "" => String::new(),
            "°" => "°".to_string(),
            unit => format!(" {unit}"),
        };
        let low = if self.min_inclusive { "≥" } else { ">" };
        format!("{low} {} and ≤ {}{unit}", short(self.min), short(self.max))
    }

    /// `Ok(value)` if allowed, else the message (without the field's name):
    /// `must be > 0 and ≤ 1000 ms, got 1e300`.
    pub fn check(&self, value: f64) -> Result<f64, String> {
        if self.contains(value) {
            return Ok(value);
        }
        if value.is_nan() || (!self.integer && value.is_infinite()) {
            return Err(format!(
                "must be a finite number {}, got {value}",
                self.describe()
            ));
        }
        Err(format!("must be {}, got {}", self.describe(), short(value)))
    }

    /// [`Limit::check`] for an integer setting, returned as `i64`.
    pub fn check_integer(&self, value: i64) -> Result<i64, String> {
        if self.contains(value as f64) {
            Ok(value)
        } else {
            Err(format!("must be {}, got {value}", self.describe()))
        }
    }
}

/// `x` in the shortest readable form: `1000`, `0.25`, `1e300`, `1e-9`.
pub fn short(x: f64) -> String {
    let magnitude = x.abs();
    if x == 0.0 || !x.is_finite() || (1e-4..1e7).contains(&magnitude) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

// ---------------------------------------------------------------------------------------
// The robot file: modules, gravity, barrier gains.

/// Number of modules of a robot (`modules = N`): a guard against typos, not a limit of the
/// model.
pub const MODULES: Limit = Limit::integer(1, crate::robot::MAX_MODULES as i64);
/// A length or radius of a module \[m\] (`rest_length`, `tendon_radius`, `corner_radius`,
/// a tendon's `zero_length`): from a tenth of a millimetre (below, foam and plates are no
/// longer rigid bodies on a backbone) to 10 m (no soft module is longer).
pub const LENGTH_M: Limit = Limit::closed(1e-4, 10.0, "m");
/// Mass lumped in a plate \[kg\]: a milligram to ten tonnes.
pub const MASS_KG: Limit = Limit::closed(1e-6, 1e4, "kg");
/// A principal moment of inertia of a plate \[kg·m²\]: from a milligram disc of 0.1 mm
/// radius (`m r²/8 ≈ 1e-15`) to ten tonnes at ten metres (`m r² = 1e6`).
pub const INERTIA_KG_M2: Limit = Limit::closed(1e-16, 1e6, "kg·m²");
/// Offset of a plate's centre of mass along its normal \[m\]: within a module's length.
pub const COM_OFFSET_M: Limit = Limit::closed(-10.0, 10.0, "m");
/// A corner or tendon angle \[deg\]: one turn either way covers every direction.
pub const ANGLE_DEG: Limit = Limit::closed(-360.0, 360.0, "°");
/// Bending stiffness `κθ` \[N·m/rad\]: soft modules have 0.01–10; 1e4 is a steel rod.
pub const BENDING_STIFFNESS: Limit = Limit::closed(0.0, 1e4, "N·m/rad");
/// Axial stiffness `κL` \[N/m\]: soft modules have 10–1e4; 1e7 is a steel spring.
pub const AXIAL_STIFFNESS: Limit = Limit::closed(0.0, 1e7, "N/m");
/// Bending damping `βθ` \[N·m·s/rad\]: as the bending stiffness, at most 1e4.
pub const BENDING_DAMPING: Limit = Limit::closed(0.0, 1e4, "N·m·s/rad");
/// Axial damping `βL` \[N·s/m\]: an industrial shock absorber has 1e5.
pub const AXIAL_DAMPING: Limit = Limit::closed(0.0, 1e6, "N·s/m");
/// Barrier margin of a corner \[m\]: a safety distance of more than a metre between
/// plates describes no contact.
pub const MARGIN_M: Limit = Limit::closed(0.0, 1.0, "m");
/// A component of gravity \[m/s²\]: ten times the Earth's covers every planet and a
/// centrifuge.
pub const GRAVITY_M_S2: Limit = Limit::closed(-100.0, 100.0, "m/s²");
/// HOCBF class-K gains `p1`, `p2` \[1/s\] (robot `[barrier]`, scenario `[gains]`): above
/// 1e4 1/s a barrier would be corrected within 0.1 ms, faster than any actuator.
pub const BARRIER_GAIN_PER_S: Limit = Limit::above(0.0, 1e4, "1/s");

// ---------------------------------------------------------------------------------------
// The robot file's `[hardware]` table (with RETRIES, MAX_CONSECUTIVE_ERRORS,
// REPLY_TIMEOUT_MS, SERVO_ID and the baud rates below).

/// Time constant of the velocity filter \[ms\]: longer than a second filters out the motion.
pub const VELOCITY_FILTER_MS: Limit = Limit::above(0.0, 1000.0, "ms");
/// Model number a servo answers to a ping (a 16-bit register).
pub const MODEL_NUMBER: Limit = Limit::integer(0, 65_535);
/// Current unit of the Goal/Present Current registers \[mA\] (X-series: 1 or 2.69).
pub const CURRENT_UNIT_MA: Limit = Limit::closed(1e-3, 100.0, "mA");
/// Position unit of Present Position \[deg\] (X-series: 360°/4096).
pub const POSITION_UNIT_DEG: Limit = Limit::closed(1e-4, 360.0, "°");
/// Velocity unit of Present Velocity \[rev/min\] (X-series: 0.229).
pub const VELOCITY_UNIT_RPM: Limit = Limit::closed(1e-4, 100.0, "rev/min");
/// Servo angle in the calibration pose \[deg\]: a hundred turns either way.
pub const ZERO_ANGLE_DEG: Limit = Limit::closed(-36_000.0, 36_000.0, "°");
/// Radius of the pulley a tendon winds on \[m\]: 0.1 mm to 1 m.
pub const PULLEY_RADIUS_M: Limit = Limit::closed(1e-4, 1.0, "m");
/// Tension per unit of motor current \[N/mA\] (XM430 on a 45 mm pulley: 0.04).
pub const ACTUATOR_GAIN_N_PER_MA: Limit = Limit::closed(1e-6, 100.0, "N/mA");
/// A tendon tension limit \[N\]: up to 100 kN, ten tonnes on one cable.
pub const TENSION_N: Limit = Limit::closed(0.0, 1e5, "N");

// ---------------------------------------------------------------------------------------
// The scenario file (with DURATION_S below).

/// Control period of a simulation \[s\]: 1 µs (1 MHz) to 1 s (the slowest loop,
/// [`RATE_HZ`]).
pub const CONTROL_PERIOD_S: Limit = Limit::closed(1e-6, 1.0, "s");
/// Time of a waypoint \[s\]: within the longest run ([`DURATION_S`]).
pub const WAYPOINT_TIME_S: Limit = Limit::closed(0.0, 1e6, "s");
/// A diagonal entry (or the scalar) of `K_P` \[N/m\]: 1e6 N/m moves a 10 t plate at 1.6 Hz
/// and a milligram one far beyond any servo; off-diagonal entries lie within `±max`.
pub const KP_N_PER_M: Limit = Limit::closed(0.0, 1e6, "N/m");
/// A diagonal entry (or the scalar) of `K_D` \[N·s/m\]; off-diagonal entries within `±max`.
pub const KD_N_S_PER_M: Limit = Limit::closed(0.0, 1e6, "N·s/m");
/// Relative tolerance of the plant integration: above 1 nothing is controlled; below
/// 1e-12 it asks for more than double precision can give.
pub const RTOL: Limit = Limit::closed(1e-12, 1.0, "");
/// Absolute tolerance of the plant integration \[m, m/s\]: a femtometre to a metre.
pub const ATOL: Limit = Limit::closed(1e-15, 1.0, "");
/// First step of the plant integration \[s\]: from the integrator's smallest step
/// (1e-12 s) to the longest control period.
pub const H_INITIAL_S: Limit = Limit::closed(1e-12, 1.0, "s");
/// Step attempts of the plant integration within one tick.
pub const MAX_STEPS: Limit = Limit::integer(1, 10_000_000);

// ---------------------------------------------------------------------------------------
// The hardware loop (`softcbf run`).

/// Loop rate \[Hz\]: below 1 Hz a soft robot moves a barrier's width between ticks; above
/// 10 kHz no servo bus answers (6 servos at 4.5 Mbit/s: ≈ 2 kHz).
pub const RATE_HZ: Limit = Limit::closed(1.0, 10_000.0, "Hz");
/// Duration of a run or a simulation \[s\] (up to about 11 days).
pub const DURATION_S: Limit = Limit::above(0.0, 1e6, "s");
/// Lowest barrier a run may reach and still count as safe \[m\].
pub const BARRIER_THRESHOLD_M: Limit = Limit::closed(-1.0, 1.0, "m");
/// Default of [`BARRIER_THRESHOLD_M`]: one millimetre of penetration of the margin.
pub const DEFAULT_BARRIER_THRESHOLD: f64 = -1e-3;
/// Ticks in a row without a good reading before the safe stop.
pub const MAX_CONSECUTIVE_ERRORS: Limit = Limit::integer(1, 1000);
/// Sync-read retries within one tick.
pub const RETRIES: Limit = Limit::integer(0, 1000);
/// Wait for one status packet \[ms\]: a reply that takes longer than a second is lost.
pub const REPLY_TIMEOUT_MS: Limit = Limit::above(0.0, 1000.0, "ms");
/// Servo ID on the bus (252 is the largest a single servo may have).
pub const SERVO_ID: Limit = Limit::integer(0, 252);
/// Baud rates the X-series servos support (Baud Rate register values 0..=7).
pub const SUPPORTED_BAUDS: [u32; 8] = [
    9_600, 57_600, 115_200, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000,
];

/// Checks a baud rate against [`SUPPORTED_BAUDS`].
pub fn check_baud(baud: i64) -> Result<u32, String> {
    u32::try_from(baud)
        .ok()
        .filter(|b| SUPPORTED_BAUDS.contains(b))
        .ok_or_else(|| {
            format!("{baud} bit/s is not an X-series baud rate; use one of {SUPPORTED_BAUDS:?}")
        })
}

/// Bus Watchdog time \[ms\]: `0` (off) or 20 to 2540 ms, the register's 1..=127 units of
/// 20 ms.
pub const BUS_WATCHDOG_MS: Limit = Limit::closed(0.0, 2540.0, "ms");
/// Unit of the Bus Watchdog register \[ms\].
pub const BUS_WATCHDOG_UNIT_MS: f64 = 20.0;

// ---------------------------------------------------------------------------------------
// The emulator (`softcbf emulate`).

/// Injected extra delay of a status packet \[ms\] (up to ten minutes).
pub const DELAY_MS: Limit = Limit::closed(0.0, 600_000.0, "ms");
/// A probability.
pub const FRACTION: Limit = Limit::closed(0.0, 1.0, "");
/// Return Delay Time \[µs\]: the register holds 0..=254 units of 2 µs.
pub const RETURN_DELAY_US: Limit = Limit::closed(0.0, 508.0, "µs");
/// Seconds after the start when a servo falls silent (up to about 11 days).
pub const SILENT_AFTER_S: Limit = Limit::closed(0.0, 1e6, "s");

// ---------------------------------------------------------------------------------------
// The state domain.

/// Largest bend `θ = √(Δx² + Δy²)/d` of a segment \[rad\]: three quarters of a turn
/// (270°). At a full turn the plate comes back onto its base whatever the bend's direction
/// and the segment's length, so `M(q)` is singular there (its smallest Cholesky pivot
/// falls as `(2π − θ)²`: 4e-3 of the largest at 1.5π, 2e-6 at 1.99π for the paper robot);
/// no module bends that far without its plates meeting.
pub const MAX_BEND_RAD: f64 = 1.5 * PI;
/// Largest `|δL|` as a multiple of the segment's rest length `L0`.
pub const MAX_ELONGATION_RATIO: f64 = 10.0;
/// Largest `|q̇|` entry \[m/s\]: far beyond any soft robot, small enough that every product
/// of the dynamics stays finite.
pub const MAX_SPEED: f64 = 100.0;

/// Why a state lies outside the model's domain. `module` and `index` count from 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StateProblem {
    /// A vector has the wrong length.
    Length {
        /// Entries given.
        got: usize,
        /// Entries expected.
        expected: usize,
    },
    /// An entry is NaN or infinite.
    NonFinite {
        /// The entry (from 1).
        index: usize,
        /// Its value.
        value: f64,
    },
    /// A segment bends more than [`MAX_BEND_RAD`].
    Bend {
        /// The module (from 1).
        module: usize,
        /// Its bend `θ` \[rad\].
        theta: f64,
        /// The largest `√(Δx² + Δy²)` allowed, `MAX_BEND_RAD · d` \[m\].
        max: f64,
    },
    /// `|δL|` exceeds [`MAX_ELONGATION_RATIO`] rest lengths.
    Elongation {
        /// The module (from 1).
        module: usize,
        /// `δL` \[m\].
        value: f64,
        /// The largest `|δL|` allowed \[m\].
        max: f64,
    },
    /// A velocity entry exceeds [`MAX_SPEED`].
    Speed {
        /// The entry (from 1).
        index: usize,
        /// Its value \[m/s\].
        value: f64,
    },
}

impl StateProblem {
    /// The entry (from 1) the problem concerns, `None` for a wrong length; for a bend, the
    /// module's `Δx`.
    pub fn entry(&self) -> Option<usize> {
        match *self {
            StateProblem::Length { .. } => None,
            StateProblem::NonFinite { index, .. } | StateProblem::Speed { index, .. } => {
                Some(index)
            }
            StateProblem::Bend { module, .. } => Some((3 * module).saturating_sub(2)),
            StateProblem::Elongation { module, .. } => Some(3 * module),
        }
    }
}

impl fmt::Display for StateProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            StateProblem::Length { got, expected } => write!(
                f,
                "{got} values given, the robot has {expected} coordinates (3 per module: Δx, Δy, δL)"
            ),
            StateProblem::NonFinite { index, value } => {
                write!(f, "entry {index} is {value}; values must be finite")
            }
            StateProblem::Bend { module, theta, max } => write!(
                f,
                "module {module} bends by θ = {theta:.4e} rad, more than three quarters of a \
                 turn (1.5π rad): √(Δx² + Δy²) of entries {}, {} must be ≤ {max:.4} m",
                3 * module - 2,
                3 * module - 1
            ),
            StateProblem::Elongation { module, value, max } => write!(
                f,
                "entry {} (δL of module {module}) is {value:e} m; |δL| must be ≤ {max} m, \
                 {MAX_ELONGATION_RATIO} rest lengths",
                3 * module
            ),
            StateProblem::Speed { index, value } => write!(
                f,
                "entry {index} is {value:e} m/s; speeds must be ≤ {MAX_SPEED} m/s in magnitude"
            ),
        }
    }
}

/// The first problem of coordinates `q` of `robot` (length, finiteness, bend, elongation),
/// or `None` when `q` lies in the model's domain. Allocates nothing.
pub fn coordinates_problem(robot: &Robot, q: &[f64]) -> Option<StateProblem> {
    modules_coordinates_problem(&robot.modules, q)
}

/// [`coordinates_problem`] for a robot given by its modules (base first), for checks made
/// while the robot itself is still being built.
pub fn modules_coordinates_problem(modules: &[Module], q: &[f64]) -> Option<StateProblem> {
    let expected = 3 * modules.len();
    if q.len() != expected {
        return Some(StateProblem::Length {
            got: q.len(),
            expected,
        });
    }
    if let Some(index) = q.iter().position(|v| !v.is_finite()) {
        return Some(StateProblem::NonFinite {
            index: index + 1,
            value: q[index],
        });
    }
    for (i, (module, q)) in modules.iter().zip(q.chunks_exact(3)).enumerate() {
        let max = MAX_BEND_RAD * module.tendon_radius;
        let bend = q[0].hypot(q[1]);
        if bend > max {
            return Some(StateProblem::Bend {
                module: i + 1,
                theta: bend / module.tendon_radius,
                max,
            });
        }
        let max = MAX_ELONGATION_RATIO * module.rest_length;
        if q[2].abs() > max {
            return Some(StateProblem::Elongation {
                module: i + 1,
                value: q[2],
                max,
            });
        }
    }
    None
}

/// The first problem of velocities `qd` of `robot` (length, finiteness, speed), or `None`.
/// Allocates nothing.
pub fn velocities_problem(robot: &Robot, qd: &[f64]) -> Option<StateProblem> {
    let expected = 3 * robot.modules.len();
    if qd.len() != expected {
        return Some(StateProblem::Length {
            got: qd.len(),
            expected,
        });
    }
    qd.iter().enumerate().find_map(|(k, &value)| {
        if !value.is_finite() {
            Some(StateProblem::NonFinite {
                index: k + 1,
                value,
            })
        } else if value.abs() > MAX_SPEED {
            Some(StateProblem::Speed {
                index: k + 1,
                value,
            })
        } else {
            None
        }
    })
}

/// The first problem of the state `(q, q̇)`, or `None` when it lies in the model's domain.
pub fn state_problem(robot: &Robot, q: &[f64], qd: &[f64]) -> Option<StateProblem> {
    coordinates_problem(robot, q).or_else(|| velocities_problem(robot, qd))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_accept_their_range_and_name_it_otherwise() {
        assert_eq!(REPLY_TIMEOUT_MS.check(10.0), Ok(10.0));
        assert_eq!(REPLY_TIMEOUT_MS.check(1000.0), Ok(1000.0));
        let message = REPLY_TIMEOUT_MS.check(1e300).unwrap_err();
        assert_eq!(message, "must be > 0 and ≤ 1000 ms, got 1e300");
        assert!(REPLY_TIMEOUT_MS.check(0.0).unwrap_err().contains("> 0"));
        assert!(
            REPLY_TIMEOUT_MS
                .check(f64::NAN)
                .unwrap_err()
                .contains("finite")
        );
        assert!(
            DELAY_MS
                .check(f64::INFINITY)
                .unwrap_err()
                .contains("finite")
        );
        assert_eq!(MAX_CONSECUTIVE_ERRORS.check_integer(1000), Ok(1000));
        assert_eq!(
            MAX_CONSECUTIVE_ERRORS.check_integer(100_000).unwrap_err(),
            "must be an integer in 1..=1000, got 100000"
        );
        assert!(MAX_CONSECUTIVE_ERRORS.check(2.5).is_err());
        assert!(RATE_HZ.check(1e-9).is_err());
        assert!(RATE_HZ.check(-33.0).is_err());
        assert_eq!(check_baud(1_000_000), Ok(1_000_000));
        for bad in [0, 12345, -1, i64::MAX] {
            assert!(
                check_baud(bad)
                    .unwrap_err()
                    .contains("not an X-series baud rate")
            );
        }
    }

    /// Every range is a proper interval with finite ends (integer ranges with whole ends),
    /// and its description is what the READMEs print.
    #[test]
    fn every_range_is_a_proper_interval_described_in_short_numbers() {
        let all = [
            RATE_HZ,
            DURATION_S,
            BARRIER_THRESHOLD_M,
            MAX_CONSECUTIVE_ERRORS,
            RETRIES,
            REPLY_TIMEOUT_MS,
            SERVO_ID,
            BUS_WATCHDOG_MS,
            DELAY_MS,
            FRACTION,
            RETURN_DELAY_US,
            SILENT_AFTER_S,
            MODULES,
            LENGTH_M,
            MASS_KG,
            INERTIA_KG_M2,
            COM_OFFSET_M,
            ANGLE_DEG,
            BENDING_STIFFNESS,
            AXIAL_STIFFNESS,
            BENDING_DAMPING,
            AXIAL_DAMPING,
            MARGIN_M,
            GRAVITY_M_S2,
            BARRIER_GAIN_PER_S,
            VELOCITY_FILTER_MS,
            MODEL_NUMBER,
            CURRENT_UNIT_MA,
            POSITION_UNIT_DEG,
            VELOCITY_UNIT_RPM,
            ZERO_ANGLE_DEG,
            PULLEY_RADIUS_M,
            ACTUATOR_GAIN_N_PER_MA,
            TENSION_N,
            CONTROL_PERIOD_S,
            WAYPOINT_TIME_S,
            KP_N_PER_M,
            KD_N_S_PER_M,
            RTOL,
            ATOL,
            H_INITIAL_S,
            MAX_STEPS,
        ];
        for limit in all {
            assert!(limit.min.is_finite() && limit.max.is_finite() && limit.min < limit.max);
            assert!(limit.contains(limit.max), "{limit:?}");
            assert_eq!(limit.contains(limit.min), limit.min_inclusive, "{limit:?}");
            if limit.integer {
                assert_eq!((limit.min.fract(), limit.max.fract()), (0.0, 0.0));
            }
        }
        assert_eq!(INERTIA_KG_M2.describe(), "≥ 1e-16 and ≤ 1000000 kg·m²");
        assert_eq!(ANGLE_DEG.describe(), "≥ -360 and ≤ 360°");
        assert_eq!(AXIAL_STIFFNESS.describe(), "≥ 0 and ≤ 1e7 N/m");
        assert_eq!(RTOL.describe(), "≥ 1e-12 and ≤ 1");
        assert_eq!(
            KP_N_PER_M.either_sign().check(-1.5e6).unwrap_err(),
            "must be ≥ -1000000 and ≤ 1000000 N/m, got -1500000"
        );
        assert_eq!(KP_N_PER_M.either_sign().check(-1e6), Ok(-1e6));
        assert_eq!(
            MODULES.check_integer(i64::MIN).unwrap_err(),
            "must be an integer in 1..=1000, got -9223372036854775808"
        );
    }

    #[test]
    fn state_problems_point_at_their_entry() {
        let robot = Robot::paper_sim();
        let bend = MAX_BEND_RAD * 0.04;
        let q = [0.0, 0.0, 0.0, 0.0, 1.01 * bend, 0.0];
        let problem = coordinates_problem(&robot, &q).unwrap();
        // The bend of module 2 is reported at its Δx, entry 4.
        assert_eq!(problem.entry(), Some(4));
        assert_eq!(
            modules_coordinates_problem(&robot.modules, &q),
            Some(problem)
        );
        let q = [0.0, 0.0, 1.5, 0.0, 0.0, 0.0];
        assert_eq!(coordinates_problem(&robot, &q).unwrap().entry(), Some(3));
        let qd = [0.0, 0.0, 0.0, 0.0, f64::NAN, 0.0];
        assert_eq!(velocities_problem(&robot, &qd).unwrap().entry(), Some(5));
        assert_eq!(coordinates_problem(&robot, &[0.0]).unwrap().entry(), None);
    }

    #[test]
    fn the_state_domain_bounds_bend_elongation_and_speed() {
        let robot = Robot::paper_sim();
        let d = robot.modules[0].tendon_radius;
        let mut q = vec![0.0; 6];
        assert_eq!(coordinates_problem(&robot, &q), None);
        q[3] = 0.999 * MAX_BEND_RAD * d;
        assert_eq!(coordinates_problem(&robot, &q), None);
        q[3] = 1.001 * MAX_BEND_RAD * d;
        assert!(matches!(
            coordinates_problem(&robot, &q),
            Some(StateProblem::Bend { module: 2, .. })
        ));
        q[3] = 0.0;
        q[2] = -1.01;
        let problem = coordinates_problem(&robot, &q).unwrap();
        assert!(matches!(
            problem,
            StateProblem::Elongation { module: 1, .. }
        ));
        assert!(problem.to_string().contains("entry 3"), "{problem}");
        q[2] = 1e308;
        assert!(coordinates_problem(&robot, &q).is_some());
        q[2] = f64::NAN;
        assert!(matches!(
            coordinates_problem(&robot, &q),
            Some(StateProblem::NonFinite { index: 3, .. })
        ));
        let mut qd = vec![0.0; 6];
        qd[5] = -100.0;
        assert_eq!(velocities_problem(&robot, &qd), None);
        qd[5] = -100.5;
        assert!(matches!(
            velocities_problem(&robot, &qd),
            Some(StateProblem::Speed { index: 6, .. })
        ));
        assert!(matches!(
            state_problem(&robot, &[0.0; 3], &qd),
            Some(StateProblem::Length {
                got: 3,
                expected: 6
            })
        ));
    }
}
