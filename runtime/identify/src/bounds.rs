//! The `[uncertainty]` table of the identified robot file: how far its numbers may be off,
//! from identification's own standard errors, each bound with the reason it has.
//!
//! A bound is a fraction of the written number (the robust filter's box is
//! `(1 ± fraction)` times the file's, docs/model.md §5). For the numbers identify measures
//! (stiffness, damping) it is [`K_SIGMA`] standard errors — each standard error already
//! holds its systematic parts (timing, filter, noise; docs/model.md §10) — of the least
//! certain such number over all modules, plus the rounding of the written value, plus
//! [`SLOW_DAMPING`] on damping when the readings are slower than [`super::SLOW_PERIOD`]:
//! there the damping of a light module misses by more than its standard error says
//! (docs/hardware.md). Where a number of a kind was not identified (not excited), its
//! uncertainty is not known from these logs and the input's bound for that kind is kept,
//! saying so. Masses and the unmodelled force are not measured by identify: the input's
//! bounds are kept, saying so. The table has no field for the actuator gains; their bound
//! is said in a comment.

use softcbf_description::limits::UNCERTAINTY_FRACTION;
use softcbf_description::uncertainty::{ModuleUncertainty, Uncertainty};

use super::{Identification, Parameter, SLOW_PERIOD, Status};

/// Standard errors in a bound: a number identified well lies within three of them of the
/// truth (the walk-through's fourteen numbers lie within 1.3 of theirs, docs/hardware.md).
pub const K_SIGMA: f64 = 3.0;

/// The systematic part added to the damping bound when the readings are slower than
/// [`SLOW_PERIOD`]: at 33 Hz through the emulator's factory preset, module 2's bending
/// damping of the example robot came out 15–18 % high, three to four standard errors off
/// (docs/hardware.md, Identifying stiffness, damping and actuator gains).
pub const SLOW_DAMPING: f64 = 0.2;

/// One bound of the table and where it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Bound {
    /// The fraction written.
    pub value: f64,
    /// Why: the comment written above it.
    pub source: String,
}

/// The table identify writes.
#[derive(Clone, Debug, PartialEq)]
pub struct Bounds {
    /// `stiffness`.
    pub stiffness: Bound,
    /// `damping`.
    pub damping: Bound,
    /// `mass`.
    pub mass: Bound,
    /// `force` \[N\].
    pub force: Bound,
    /// The actuator gains' bound (not a field of the table): its comment.
    pub gains: String,
    /// Each module's own bounds (its `uncertainty = { … }`): the stiffness and damping it
    /// identified, each from its own standard error as the table's from the least certain;
    /// `None` where not identified (the table's bound holds there).
    pub modules: Vec<ModuleUncertainty>,
}

impl Bounds {
    /// The values as the robot file's [`Uncertainty`].
    pub fn uncertainty(&self) -> Uncertainty {
        Uncertainty {
            stiffness: self.stiffness.value,
            damping: self.damping.value,
            mass: self.mass.value,
            force: self.force.value,
        }
    }
}

/// `x` rounded up to two significant digits (a bound is never written smaller than
/// computed).
fn round_up(x: f64) -> f64 {
    if !(x > 0.0 && x.is_finite()) {
        return x;
    }
    let scale = 10f64.powf(x.log10().floor() - 1.0);
    let rounded = (x / scale).ceil() * scale;
    // The decimal text of the product may fall a hair below `x`.
    let text: f64 = format!("{rounded:.2e}").parse().unwrap_or(rounded);
    if text >= x {
        text
    } else {
        rounded * (1.0 + 1e-12)
    }
}

/// The relative bound of parameter `j`: `K_SIGMA` standard errors and the rounding of the
/// written value `written`, over the written value.
fn relative(id: &Identification, j: usize, written: f64) -> f64 {
    (K_SIGMA * id.fit.se[j] + (written - id.fit.theta[j]).abs()) / written.abs()
}

/// A percentage for a comment.
fn percent(x: f64) -> String {
    format!("{:.2} %", 100.0 * x)
}

/// The bound of one kind (`parameters` of every module): the largest relative bound of
/// the identified ones; the input's `kept` where one of them was not identified.
fn kind_bound(
    id: &Identification,
    parameters: [Parameter; 2],
    written: &dyn Fn(usize) -> f64,
    kept: f64,
    what: &str,
) -> (f64, String, Vec<String>) {
    let mut largest = (0.0, String::new());
    let mut not_identified = Vec::new();
    for i in 0..id.modules() {
        for parameter in parameters {
            let j = parameter.index(i);
            let label = format!("module {} {}", i + 1, parameter.symbol());
            match id.fit.status[j] {
                Status::Identified => {
                    let r = relative(id, j, written(j));
                    if r >= largest.0 {
                        largest = (r, label);
                    }
                }
                Status::Kept(_) => not_identified.push(label),
            }
        }
    }
    let mut source = if largest.1.is_empty() {
        format!("no {what} was identified")
    } else {
        format!(
            "{K_SIGMA} standard errors of the least certain identified {what}, {} ({})",
            largest.1,
            percent(largest.0)
        )
    };
    let mut value = largest.0;
    if !not_identified.is_empty() {
        source += &format!(
            "; {} not identified (the logs do not excite it): the input file's {} kept",
            not_identified.join(", "),
            percent(kept)
        );
        value = value.max(kept);
    }
    (value, source, not_identified)
}

/// Capped at the table's largest fraction, saying so.
fn capped(value: f64, source: String) -> Bound {
    let most = UNCERTAINTY_FRACTION.max;
    if value > most {
        Bound {
            value: most,
            source: format!(
                "{source}; capped at {most}, the largest the table takes: this number is barely \
                 known"
            ),
        }
    } else {
        Bound {
            value: round_up(value),
            source: source + ", rounded up",
        }
    }
}

/// The table for `id`, whose written values are `written(j)`, from a robot file that
/// declared `input` (all zero: none).
pub fn bounds(id: &Identification, written: &dyn Fn(usize) -> f64, input: &Uncertainty) -> Bounds {
    let (value, source, _) = kind_bound(
        id,
        [Parameter::BendingStiffness, Parameter::AxialStiffness],
        written,
        input.stiffness,
        "stiffness",
    );
    let stiffness = capped(value, source);
    let (mut value, mut source, _) = kind_bound(
        id,
        [Parameter::BendingDamping, Parameter::AxialDamping],
        written,
        input.damping,
        "damping",
    );
    if id.period > SLOW_PERIOD {
        value += SLOW_DAMPING;
        source += &format!(
            ", plus {} for readings every {:.1} ms (slower than {:.0} Hz the damping of a \
             light module misses by more than its standard error: docs/hardware.md)",
            percent(SLOW_DAMPING),
            1e3 * id.period,
            1.0 / SLOW_PERIOD
        );
    }
    let damping = capped(value, source);
    let declared = |x: f64| {
        if x > 0.0 {
            format!("the input file's {x} kept")
        } else {
            "none declared, as in the input file".to_string()
        }
    };
    let mass = Bound {
        value: input.mass,
        source: format!(
            "not measured by identify (masses and inertias are the file's): {}",
            declared(input.mass)
        ),
    };
    let force = Bound {
        value: input.force,
        source: format!("not measured by identify: {}", declared(input.force)),
    };
    let mut gain = (0.0, String::new());
    for i in 0..id.modules() {
        for k in 0..3 {
            let j = Parameter::ActuatorGain(k).index(i);
            if id.fit.status[j] == Status::Identified {
                let r = relative(id, j, written(j));
                if r >= gain.0 {
                    gain = (r, format!("module {} g{}", i + 1, k + 1));
                }
            }
        }
    }
    let gains = if gain.1.is_empty() {
        "actuator gains: none identified".to_string()
    } else {
        format!(
            "actuator gains: within {} ({K_SIGMA} standard errors, {}); the table has no field \
             for them, so a tension off by that fraction is not covered by it",
            percent(gain.0),
            gain.1
        )
    };
    let modules = (0..id.modules())
        .map(|i| {
            let own = |parameter: Parameter, extra: f64| {
                let j = parameter.index(i);
                (id.fit.status[j] == Status::Identified)
                    .then(|| capped(relative(id, j, written(j)) + extra, String::new()).value)
            };
            let slow = if id.period > SLOW_PERIOD {
                SLOW_DAMPING
            } else {
                0.0
            };
            ModuleUncertainty {
                bending_stiffness: own(Parameter::BendingStiffness, 0.0),
                axial_stiffness: own(Parameter::AxialStiffness, 0.0),
                bending_damping: own(Parameter::BendingDamping, slow),
                axial_damping: own(Parameter::AxialDamping, slow),
                mass: None,
            }
        })
        .collect();
    Bounds {
        stiffness,
        damping,
        mass,
        force,
        gains,
        modules,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_are_rounded_up_never_down() {
        for x in [0.012_34, 0.1, 0.099_999, 3.0e-4, 0.5555] {
            let r = round_up(x);
            assert!(r >= x && r <= x * 1.1, "{x} → {r}");
        }
        assert_eq!(round_up(0.012_34), 0.013);
        assert_eq!(round_up(0.1), 0.1);
    }
}
