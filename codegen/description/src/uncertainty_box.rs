//! The box a robot file's `[uncertainty]` declares (docs/model.md §5): the table read and
//! checked, and the test of one module's factors against it. The part of
//! [`crate::uncertainty`] that the robot file itself needs; plant robots built inside the
//! box are [`crate::uncertainty`]'s.

use serde::Deserialize;
use toml::Spanned;

use crate::limits;
use crate::toml_file::{Checker, FileError};

/// The declared uncertainty of a robot's numbers: relative bounds on stiffness, damping and
/// mass, and a bound on unmodelled generalized force. All zero (the default): the nominal
/// model is taken as exact.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Uncertainty {
    /// `κθ`, `κL` of every module may be off by this fraction (0.2: ±20 %).
    pub stiffness: f64,
    /// `βθ`, `βL` of every module may be off by this fraction.
    pub damping: f64,
    /// Every plate's mass (and with it its inertia) may be off by this fraction.
    pub mass: f64,
    /// Unmodelled generalized force on each coordinate is at most this \[N\].
    pub force: f64,
}

impl Uncertainty {
    /// Whether anything is declared.
    pub fn is_declared(&self) -> bool {
        *self != Uncertainty::default()
    }

    /// Whether the factors of one module lie inside the declared box: every stiffness and
    /// damping factor within `1 ± stiffness` and `1 ± damping`, the mass factor within
    /// `1 ± mass` (a round-off of [`RELATIVE_TOLERANCE`] allowed).
    pub fn admits(&self, factors: &ModuleFactors) -> bool {
        let within = |factor: f64, fraction: f64| {
            factor.is_finite() && (factor - 1.0).abs() <= fraction + RELATIVE_TOLERANCE
        };
        factors.stiffness.iter().all(|&f| within(f, self.stiffness))
            && factors.damping.iter().all(|&f| within(f, self.damping))
            && within(factors.mass, self.mass)
    }
}

/// Relative round-off allowed when a number is compared with the edge of the box: a factor
/// drawn on the edge and multiplied in floating point stays inside.
pub const RELATIVE_TOLERANCE: f64 = 1e-12;

// ---------------------------------------------------------------------------------------
// The table.

/// `[uncertainty]` as serde reads it: each value with its byte span.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct UncertaintyTable {
    stiffness: Option<Spanned<f64>>,
    damping: Option<Spanned<f64>>,
    mass: Option<Spanned<f64>>,
    force: Option<Spanned<f64>>,
}

impl Checker<'_> {
    /// The declared uncertainty of a robot file (none without the table, and zero for a
    /// field not written), each value checked on its line.
    pub(crate) fn uncertainty(
        &self,
        table: Option<&UncertaintyTable>,
    ) -> Result<Uncertainty, FileError> {
        let Some(table) = table else {
            return Ok(Uncertainty::default());
        };
        let fraction = |v: &Option<Spanned<f64>>, name: &str| match v {
            Some(v) => limits::UNCERTAINTY_FRACTION
                .check(*v.get_ref())
                .map_err(|m| {
                    self.invalid(
                        &v.span(),
                        &format!("uncertainty.{name}"),
                        format!("{m} (a fraction: 0.2 is ±20 %)"),
                    )
                }),
            None => Ok(0.0),
        };
        Ok(Uncertainty {
            stiffness: fraction(&table.stiffness, "stiffness")?,
            damping: fraction(&table.damping, "damping")?,
            mass: fraction(&table.mass, "mass")?,
            force: match &table.force {
                Some(v) => self.within(v, "uncertainty.force", &limits::UNMODELLED_FORCE_N)?,
                None => 0.0,
            },
        })
    }
}

/// The factors by which a plant's module differs from the nominal one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModuleFactors {
    /// Factors of the bending and axial stiffness `[κθ, κL]`.
    pub stiffness: [f64; 2],
    /// Factors of the bending and axial damping `[βθ, βL]`.
    pub damping: [f64; 2],
    /// Factor of the plate's mass and of each of its principal moments of inertia.
    pub mass: f64,
}

impl ModuleFactors {
    /// Every number as in the nominal module.
    pub const NOMINAL: ModuleFactors = ModuleFactors {
        stiffness: [1.0; 2],
        damping: [1.0; 2],
        mass: 1.0,
    };
}
