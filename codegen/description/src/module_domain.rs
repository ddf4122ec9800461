//! The state domain of a chain of modules, the part of [`crate::domain`] that needs no
//! [`crate::robot::Robot`]: the limits of the coordinates and velocities, the problem of a
//! state outside them, and the check of a state written in a file. The robot file's own
//! checks (its `set_point`) use it while the robot is being built; [`crate::domain`] gives
//! the same for a whole robot.

use std::fmt;

use toml::Spanned;

use crate::module::Module;
use crate::toml_file::{Checker, FileError};

pub use crate::limits::{MAX_BEND_RAD, MAX_ELONGATION_RATIO, MAX_SPEED};

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
                crate::limits::rounded(rest_length + value),
                crate::limits::short(-rest_length)
            ),
            StateProblem::Speed { index, value } => write!(
                f,
                "entry {index} is {value:e} m/s; speeds must be ≤ {MAX_SPEED} m/s in magnitude"
            ),
        }
    }
}

/// [`crate::domain::coordinates_problem`] for a robot given by its modules (base first), for checks made
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

impl Checker<'_> {
    /// Turns a problem of a state vector ([`crate::domain::coordinates_problem`],
    /// [`crate::domain::velocities_problem`])
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
