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

/// One module's box: each of its uncertain numbers may be off by its fraction (0.2: ±20 %).
/// [`crate::robot::Robot::module_box`] gives it: the module's own `uncertainty = { … }`
/// where written, the robot's `[uncertainty]` elsewhere.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ModuleBox {
    /// `[κθ, κL]`.
    pub stiffness: [f64; 2],
    /// `[βθ, βL]`.
    pub damping: [f64; 2],
    /// The plate's mass and with it its inertia.
    pub mass: f64,
}

impl ModuleBox {
    /// Every number of the module at the robot-wide fractions of `u`.
    pub fn of(u: &Uncertainty) -> ModuleBox {
        ModuleBox {
            stiffness: [u.stiffness; 2],
            damping: [u.damping; 2],
            mass: u.mass,
        }
    }

    /// Whether a module's factors lie inside this box (a round-off of
    /// [`RELATIVE_TOLERANCE`] allowed).
    pub fn admits(&self, factors: &ModuleFactors) -> bool {
        let within = |factor: f64, fraction: f64| {
            factor.is_finite() && (factor - 1.0).abs() <= fraction + RELATIVE_TOLERANCE
        };
        (0..2).all(|k| {
            within(factors.stiffness[k], self.stiffness[k])
                && within(factors.damping[k], self.damping[k])
        }) && within(factors.mass, self.mass)
    }

    /// The bending (`0`, `1`) or axial (`2`) coordinate's stiffness and damping fractions.
    pub fn coordinate(&self, c: usize) -> (f64, f64) {
        let k = usize::from(c % 3 == 2);
        (self.stiffness[k], self.damping[k])
    }
}

/// A module's `uncertainty = { … }` as written in its `[[module]]` table (or in
/// `[defaults]`): the fractions it gives, `None` where the robot's `[uncertainty]` holds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ModuleUncertainty {
    pub bending_stiffness: Option<f64>,
    pub axial_stiffness: Option<f64>,
    pub bending_damping: Option<f64>,
    pub axial_damping: Option<f64>,
    pub mass: Option<f64>,
}

impl ModuleUncertainty {
    /// Whether the module gives none of its own.
    pub fn is_empty(&self) -> bool {
        *self == ModuleUncertainty::default()
    }

    /// The module's box: its own fractions, the robot-wide ones of `u` elsewhere.
    pub fn over(&self, u: &Uncertainty) -> ModuleBox {
        ModuleBox {
            stiffness: [
                self.bending_stiffness.unwrap_or(u.stiffness),
                self.axial_stiffness.unwrap_or(u.stiffness),
            ],
            damping: [
                self.bending_damping.unwrap_or(u.damping),
                self.axial_damping.unwrap_or(u.damping),
            ],
            mass: self.mass.unwrap_or(u.mass),
        }
    }

    /// Every number given: `bx` written out in full.
    pub fn from_box(bx: &ModuleBox) -> ModuleUncertainty {
        ModuleUncertainty {
            bending_stiffness: Some(bx.stiffness[0]),
            axial_stiffness: Some(bx.stiffness[1]),
            bending_damping: Some(bx.damping[0]),
            axial_damping: Some(bx.damping[1]),
            mass: Some(bx.mass),
        }
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
        let fraction = |v: &Option<Spanned<f64>>, name: &str| {
            self.fraction(v, &format!("uncertainty.{name}"))
                .map(|x| x.unwrap_or(0.0))
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

impl Checker<'_> {
    /// One fraction of a box (`field` names it in an error), if written: within
    /// [`limits::UNCERTAINTY_FRACTION`], checked on its line.
    fn fraction(&self, v: &Option<Spanned<f64>>, field: &str) -> Result<Option<f64>, FileError> {
        v.as_ref()
            .map(|v| {
                limits::UNCERTAINTY_FRACTION
                    .check(*v.get_ref())
                    .map_err(|m| {
                        self.invalid(&v.span(), field, format!("{m} (a fraction: 0.2 is ±20 %)"))
                    })
            })
            .transpose()
    }
}

/// A module's `uncertainty = { … }` as serde reads it.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ModuleUncertaintyTable {
    bending_stiffness: Option<Spanned<f64>>,
    axial_stiffness: Option<Spanned<f64>>,
    bending_damping: Option<Spanned<f64>>,
    axial_damping: Option<Spanned<f64>>,
    mass: Option<Spanned<f64>>,
}

impl Checker<'_> {
    /// A module's own fractions (`field`: `module[2].uncertainty`), each checked on its line.
    pub(crate) fn module_uncertainty(
        &self,
        table: &Spanned<ModuleUncertaintyTable>,
        field: &str,
    ) -> Result<ModuleUncertainty, FileError> {
        let t = table.get_ref();
        let fraction =
            |v: &Option<Spanned<f64>>, name: &str| self.fraction(v, &format!("{field}.{name}"));
        Ok(ModuleUncertainty {
            bending_stiffness: fraction(&t.bending_stiffness, "bending_stiffness")?,
            axial_stiffness: fraction(&t.axial_stiffness, "axial_stiffness")?,
            bending_damping: fraction(&t.bending_damping, "bending_damping")?,
            axial_damping: fraction(&t.axial_damping, "axial_damping")?,
            mass: fraction(&t.mass, "mass")?,
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
