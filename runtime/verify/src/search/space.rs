//! The variables `softcbf verify --search` moves, from the scenario's `[verify]` table:
//! every entry of the set point, the initial `q` and `q̇` whose box has width, and, with
//! `parameter_errors = true`, each module's stiffness, damping and mass factors inside the
//! robot file's `[uncertainty]` box. A point of the unit box `[0, 1]^d` maps onto them
//! linearly; everything else of a candidate (its group, its noise seed) is given.

use softcbf_description::uncertainty::ModuleFactors;

use crate::draw::Draw;
use crate::model::Model;
use crate::record::coordinate_names;
use crate::spec::VerifySpec;

/// What a variable sets.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Slot {
    SetPoint(usize),
    InitialQ(usize),
    InitialQd(usize),
    /// Module, and which factor: bending and axial stiffness, bending and axial damping,
    /// mass (0..5).
    Factor(usize, usize),
}

/// One variable: its name, its range and what it sets.
#[derive(Clone, Debug, PartialEq)]
pub struct Variable {
    /// `set_point dx1 [m]`, `module 2 mass factor`, …
    pub name: String,
    /// Its range.
    pub lo: f64,
    pub hi: f64,
    slot: Slot,
}

/// The names of a module's five factors, in the order of `runs.csv`.
pub const FACTOR_NAMES: [&str; 5] = [
    "bend stiffness",
    "axial stiffness",
    "bend damping",
    "axial damping",
    "mass",
];

/// The search's variables.
#[derive(Clone, Debug, PartialEq)]
pub struct Space {
    /// In order: set point, initial `q`, initial `q̇`, factors (module by module).
    pub variables: Vec<Variable>,
}

impl Space {
    /// The variables of `spec`'s table for `model` (a box of zero width along an entry
    /// fixes it and adds no variable).
    pub fn new(model: &Model, spec: &VerifySpec) -> Space {
        let names = coordinate_names(model.nq());
        let mut variables = Vec::new();
        let mut boxed = |bounds: &Option<crate::spec::Bounds>,
                         what: &str,
                         unit: &str,
                         slot: fn(usize) -> Slot| {
            if let Some(b) = bounds {
                for (k, (&lo, &hi)) in b.min.iter().zip(&b.max).enumerate() {
                    if hi > lo {
                        variables.push(Variable {
                            name: format!("{what} {}{unit}", names[k]),
                            lo,
                            hi,
                            slot: slot(k),
                        });
                    }
                }
            }
        };
        boxed(&spec.set_point, "set_point", " [m]", Slot::SetPoint);
        boxed(&spec.initial_q, "initial", " [m]", Slot::InitialQ);
        boxed(&spec.initial_qd, "initial", "/dt [m/s]", Slot::InitialQd);
        if spec.parameter_errors {
            for module in 0..model.robot.modules.len() {
                let b = model.robot.module_box(module);
                let fractions = [
                    b.stiffness[0],
                    b.stiffness[1],
                    b.damping[0],
                    b.damping[1],
                    b.mass,
                ];
                for (which, (&fraction, name)) in fractions.iter().zip(FACTOR_NAMES).enumerate() {
                    if fraction > 0.0 {
                        variables.push(Variable {
                            name: format!("module {} {name} factor", module + 1),
                            lo: 1.0 - fraction,
                            hi: 1.0 + fraction,
                            slot: Slot::Factor(module, which),
                        });
                    }
                }
            }
        }
        Space { variables }
    }

    /// Number of variables.
    pub fn dimension(&self) -> usize {
        self.variables.len()
    }

    /// The draw of group `group` of `spec` at the point `x` of the unit box (one
    /// coordinate per variable, each clamped into `[0, 1]`), with noise seed `noise_seed`
    /// and `seed` recorded as the stream it came from. Entries without a variable keep the
    /// scenario's value (factors: 1).
    pub fn decode(
        &self,
        model: &Model,
        spec: &VerifySpec,
        group: usize,
        x: &[f64],
        noise_seed: u64,
        seed: u64,
    ) -> Draw {
        let g = &spec.groups[group];
        let scenario = &g.scenario;
        let mut draw = Draw {
            seed,
            group,
            safety: g.safety,
            control_period: g.control_period,
            set_point: scenario.reference.final_target().to_vec(),
            initial_q: scenario.initial_q.clone(),
            initial_qd: scenario.initial_qd.clone(),
            factors: VerifySpec::nominal_factors(model),
            noise_seed,
        };
        // A box of zero width: its one value.
        let fixed = |bounds: &Option<crate::spec::Bounds>, values: &mut Vec<f64>| {
            if let Some(b) = bounds {
                values.clone_from(&b.min);
            }
        };
        fixed(&spec.set_point, &mut draw.set_point);
        fixed(&spec.initial_q, &mut draw.initial_q);
        fixed(&spec.initial_qd, &mut draw.initial_qd);
        for (v, &u) in self.variables.iter().zip(x) {
            let value = (v.lo + (v.hi - v.lo) * u.clamp(0.0, 1.0)).clamp(v.lo, v.hi);
            match v.slot {
                Slot::SetPoint(k) => draw.set_point[k] = value,
                Slot::InitialQ(k) => draw.initial_q[k] = value,
                Slot::InitialQd(k) => draw.initial_qd[k] = value,
                Slot::Factor(module, which) => {
                    let f: &mut ModuleFactors = &mut draw.factors[module];
                    match which {
                        0 => f.stiffness[0] = value,
                        1 => f.stiffness[1] = value,
                        2 => f.damping[0] = value,
                        3 => f.damping[1] = value,
                        _ => f.mass = value,
                    }
                }
            }
        }
        draw
    }
}
