//! The state domain of a model: the coordinates and velocities it describes (a bend of at
//! most three quarters of a turn, a positive backbone length `L0 + δL` up to eleven rest
//! lengths, speeds within 100 m/s), and the problem of a state outside it, located in a
//! file when one gave it.
//!
//! The domain is also a constraint of the controller: every module always has its three
//! limit barriers (docs/model.md §3), and where its robot file writes no limit, the
//! domain's defaults (`crate::limits::DEFAULT_MIN_LENGTH_FRACTION` and its neighbours,
//! [`crate::barriers::Limits::domain`]) keep the state well inside the domain, so that the
//! safety filter cannot keep one barrier by driving another coordinate out of the model.

use std::f64::consts::PI;
use std::fmt;

use toml::Spanned;

use crate::module::Module;
use crate::robot::Robot;
use crate::toml_file::{Checker, FileError};

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
    /// The backbone length `L0 + δL` is zero or negative: no segment is that short.
    NonPositiveLength {
        /// The module (from 1).
        module: usize,
        /// `δL` \[m\].
        value: f64,
        /// `L0` \[m\].
        rest_length: f64,
    },
    /// `δL` exceeds [`MAX_ELONGATION_RATIO`] rest lengths.
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
            StateProblem::Elongation { module, .. }
            | StateProblem::NonPositiveLength { module, .. } => Some(3 * module),
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
                "entry {} (δL of module {module}) is {value:e} m; δL must be ≤ {max} m, \
                 {MAX_ELONGATION_RATIO} rest lengths",
                3 * module
            ),
            StateProblem::NonPositiveLength {
                module,
                value,
                rest_length,
            } => write!(
                f,
                "entry {} (δL of module {module}) is {value} m: the backbone length L0 + δL = \
                 {} m is not positive (L0 = {rest_length} m); δL must be > {} m",
                3 * module,
                rounded(rest_length + value),
                crate::limits::short(-rest_length)
            ),
            StateProblem::Speed { index, value } => write!(
                f,
                "entry {index} is {value:e} m/s; speeds must be ≤ {MAX_SPEED} m/s in magnitude"
            ),
        }
    }
}

/// `x` to nine significant digits, in the shortest form (`-0.05`, not
/// `-0.04999999999999999`): for lengths computed from written ones.
pub(crate) fn rounded(x: f64) -> String {
    let nine: f64 = format!("{x:.8e}").parse().unwrap_or(x);
    crate::limits::short(nine)
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
        if module.rest_length + q[2] <= 0.0 {
            return Some(StateProblem::NonPositiveLength {
                module: i + 1,
                value: q[2],
                rest_length: module.rest_length,
            });
        }
        let max = MAX_ELONGATION_RATIO * module.rest_length;
        if q[2] > max {
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

impl Checker<'_> {
    /// Turns a problem of a state vector ([`coordinates_problem`], [`velocities_problem`])
    /// written at `v` into an error on the entry it concerns.
    pub fn state(
        &self,
        problem: Option<StateProblem>,
        v: &Spanned<Vec<Spanned<f64>>>,
        field: &str,
    ) -> Result<(), FileError> {
        let Some(problem) = problem else {
            return Ok(());
        };
        let span = problem
            .entry()
            .and_then(|k| v.get_ref().get(k.wrapping_sub(1)))
            .map_or_else(|| v.span(), Spanned::span);
        Err(self.invalid(&span, field, problem.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        q[2] = 1.01;
        let problem = coordinates_problem(&robot, &q).unwrap();
        assert!(matches!(
            problem,
            StateProblem::Elongation { module: 1, .. }
        ));
        assert!(problem.to_string().contains("entry 3"), "{problem}");
        // A backbone of zero or negative length: L0 = 0.1 m.
        q[2] = -0.0999;
        assert_eq!(coordinates_problem(&robot, &q), None);
        for dl in [-0.1, -0.2, -1.01] {
            q[2] = dl;
            let problem = coordinates_problem(&robot, &q).unwrap();
            assert!(
                matches!(problem, StateProblem::NonPositiveLength { module: 1, .. }),
                "{problem:?}"
            );
            assert!(problem.to_string().contains("not positive"), "{problem}");
        }
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
