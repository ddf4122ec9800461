//! The valid range of every number a user gives softcbf, in a description file or on the
//! command line: one definition per setting, so that both are checked by the same rule.
//!
//! A [`Limit`] says what a value must be (finite, between bounds, perhaps an integer) and
//! builds the message when it is not; the file checker (`toml_file`) adds the file, line
//! and field, the command line adds the option's name. The ranges are physical: a bound
//! says where a value stops describing a robot (a reply that takes more than a second, a
//! bend of more than two turns), not where the arithmetic happens to break, and every
//! value inside them leaves the model's arithmetic finite (tested).
//!
//! The state domain ([`state_problem`]) bounds `q` and `q̇` the same way: a bend of at
//! most two full turns, an elongation within ten rest lengths, speeds within 100 m/s.

use std::f64::consts::PI;
use std::fmt;

use crate::robot::Robot;

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
        let unit = if self.unit.is_empty() {
            String::new()
        } else {
            format!(" {}", self.unit)
        };
        let low = if self.min_inclusive { "≥" } else { ">" };
        format!("{low} {} and ≤ {}{unit}", self.min, self.max)
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
        self.check(value as f64).map(|_| value)
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

/// Largest bend `θ = √(Δx² + Δy²)/d` of a segment \[rad\]: two full turns.
pub const MAX_BEND_RAD: f64 = 4.0 * PI;
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
                "module {module} bends by θ = {theta:.4e} rad, more than two full turns \
                 (4π rad): √(Δx² + Δy²) of entries {}, {} must be ≤ {max:.4} m",
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
    let expected = 3 * robot.modules.len();
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
    for (i, (module, q)) in robot.modules.iter().zip(q.chunks_exact(3)).enumerate() {
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
