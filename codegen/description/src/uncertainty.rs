//! How far a robot file says its numbers may be off (`[uncertainty]`, docs/model.md §5):
//! the table read and checked, plant robots scaled inside that box, and the test of one.
//!
//! The declared box is relative: a plant's stiffness, damping, mass and inertia of each
//! module lie within `(1 ± fraction)` times the nominal file's, every other number the
//! plant's motion depends on is the nominal one, and an unmodelled generalized force of at
//! most `force` acts on each coordinate. The controller's robust margin covers the box; a
//! file without the table declares nothing and its model is taken as exact.

use crate::limits::{self, Limit};
use crate::module::Module;
use crate::robot::Robot;
pub use crate::uncertainty_box::{
    ModuleBox, ModuleFactors, ModuleUncertainty, RELATIVE_TOLERANCE, Uncertainty,
};

// ---------------------------------------------------------------------------------------
// Plant robots inside the box.

/// Why [`scaled`] could not build a plant robot.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PlantError {
    /// Not one set of factors per module.
    #[error(
        "{factors} sets of module factors for a robot of {modules} modules; give one per module"
    )]
    Count { modules: usize, factors: usize },
    /// A factor that is not a finite positive number.
    #[error("module {module}: the factor of {number} must be a finite number > 0, got {value}")]
    Factor {
        /// 1-based.
        module: usize,
        number: &'static str,
        value: f64,
    },
    /// A scaled number outside the range a robot file may give it.
    #[error("module {module}: the scaled {number} {message}")]
    Range {
        /// 1-based.
        module: usize,
        number: &'static str,
        message: String,
    },
}

/// Which declared fraction bounds an uncertain number.
#[derive(Clone, Copy)]
enum Bound {
    Stiffness,
    Damping,
    Mass,
}

/// The uncertain numbers of a module, in the order of [`values`]: name (the robot file's
/// key), the fraction that bounds it and its range.
const UNCERTAIN: [(&str, Bound, &Limit); 8] = [
    (
        "bending_stiffness",
        Bound::Stiffness,
        &limits::BENDING_STIFFNESS,
    ),
    (
        "axial_stiffness",
        Bound::Stiffness,
        &limits::AXIAL_STIFFNESS,
    ),
    ("bending_damping", Bound::Damping, &limits::BENDING_DAMPING),
    ("axial_damping", Bound::Damping, &limits::AXIAL_DAMPING),
    ("mass", Bound::Mass, &limits::MASS_KG),
    ("inertia Ixx", Bound::Mass, &limits::INERTIA_KG_M2),
    ("inertia Iyy", Bound::Mass, &limits::INERTIA_KG_M2),
    ("inertia Izz", Bound::Mass, &limits::INERTIA_KG_M2),
];

/// A module's uncertain numbers, in the order of [`UNCERTAIN`].
fn values(m: &Module) -> [f64; 8] {
    let [ixx, iyy, izz] = m.inertia;
    [
        m.bending_stiffness,
        m.axial_stiffness,
        m.bending_damping,
        m.axial_damping,
        m.mass,
        ixx,
        iyy,
        izz,
    ]
}

/// Writes a module's uncertain numbers, in the order of [`UNCERTAIN`].
fn set_values(m: &mut Module, v: [f64; 8]) {
    let [ks, kl, bs, bl, mass, ixx, iyy, izz] = v;
    m.bending_stiffness = ks;
    m.axial_stiffness = kl;
    m.bending_damping = bs;
    m.axial_damping = bl;
    m.mass = mass;
    m.inertia = [ixx, iyy, izz];
}

/// Each factor, in the order of [`UNCERTAIN`] (the inertia takes the mass's).
fn factor_list(f: &ModuleFactors) -> [f64; 8] {
    let [ks, kl] = f.stiffness;
    let [bs, bl] = f.damping;
    [ks, kl, bs, bl, f.mass, f.mass, f.mass, f.mass]
}

/// A plant robot: `robot` with each module's `κθ`, `κL`, `βθ`, `βL`, mass and principal
/// inertia multiplied by its [`ModuleFactors`] (`factors[i]` is module `i + 1`'s; the
/// inertia takes the mass's factor), every other field as it is. The factors need not lie
/// in the declared box (see [`contains`]), but must be finite and positive, and the scaled
/// numbers within the ranges a robot file may give them. Scaling keeps a rigid body's
/// inertia valid and leaves the structure (and so the generated model) unchanged.
pub fn scaled(robot: &Robot, factors: &[ModuleFactors]) -> Result<Robot, PlantError> {
    if factors.len() != robot.modules.len() {
        return Err(PlantError::Count {
            modules: robot.modules.len(),
            factors: factors.len(),
        });
    }
    let mut plant = robot.clone();
    for (i, (module, f)) in plant.modules.iter_mut().zip(factors).enumerate() {
        let mut v = values(module);
        for ((x, factor), (number, _, limit)) in v.iter_mut().zip(factor_list(f)).zip(UNCERTAIN) {
            if !(factor.is_finite() && factor > 0.0) {
                return Err(PlantError::Factor {
                    module: i + 1,
                    number,
                    value: factor,
                });
            }
            *x = limit
                .check(*x * factor)
                .map_err(|message| PlantError::Range {
                    module: i + 1,
                    number,
                    message,
                })?;
        }
        set_values(module, v);
    }
    Ok(plant)
}

/// Whether `plant` lies inside the box `nominal.uncertainty` declares around `nominal`
/// ([`outside`] says where it does not).
pub fn contains(nominal: &Robot, plant: &Robot) -> bool {
    outside(nominal, plant).is_none()
}

/// The first number of `plant` outside the box declared around `nominal`, in words; `None`
/// when the plant lies inside. Inside means: the same module count, routing and gravity;
/// per module the same rest length, tendon radius, tendon angles and centre-of-mass
/// offset (bit for bit); and `κθ`, `κL` within `1 ± stiffness`, `βθ`, `βL` within
/// `1 ± damping`, the mass and each principal moment of inertia within `1 ± mass` times
/// the nominal number, with the fractions of the module's own box
/// ([`Robot::module_box`]) (each on its own: mass and inertia scaled by factors in the box keep
/// the mass matrix between `(1 − mass)` and `(1 + mass)` times the nominal one). Numbers
/// only the controller reads (corner geometry, margins, limits, obstacles, gains) are not
/// compared, and the unmodelled force is no number of the plant.
pub fn outside(nominal: &Robot, plant: &Robot) -> Option<String> {
    if plant.modules.len() != nominal.modules.len() {
        return Some(format!(
            "the plant has {} modules, the nominal robot {}",
            plant.modules.len(),
            nominal.modules.len()
        ));
    }
    if plant.routing != nominal.routing {
        return Some(format!(
            "the plant's routing is {:?}, the nominal robot's {:?}",
            plant.routing, nominal.routing
        ));
    }
    if plant.gravity != nominal.gravity {
        return Some(format!(
            "the plant's gravity is {:?} m/s², the nominal robot's {:?} m/s²",
            plant.gravity, nominal.gravity
        ));
    }
    for (i, (n, p)) in nominal.modules.iter().zip(&plant.modules).enumerate() {
        let module = i + 1;
        let exact = [
            ("rest_length", n.rest_length == p.rest_length),
            ("tendon_radius", n.tendon_radius == p.tendon_radius),
            ("tendon_angles", n.tendon_angles == p.tendon_angles),
            ("com_offset", n.com_offset == p.com_offset),
        ];
        if let Some((name, _)) = exact.iter().find(|(_, same)| !same) {
            return Some(format!(
                "module {module}: {name} differs from the nominal robot's, and the declared \
                 uncertainty does not cover it"
            ));
        }
        // This module's own box (the robot-wide one unless it gives its own).
        let bx = nominal.module_box(i);
        for ((x, x0), (number, bound, limit)) in values(p).into_iter().zip(values(n)).zip(UNCERTAIN)
        {
            let fraction = match (bound, number) {
                (Bound::Stiffness, "bending_stiffness") => bx.stiffness[0],
                (Bound::Stiffness, _) => bx.stiffness[1],
                (Bound::Damping, "bending_damping") => bx.damping[0],
                (Bound::Damping, _) => bx.damping[1],
                (Bound::Mass, _) => bx.mass,
            };
            // A NaN is outside too: the comparison is false.
            let inside = (x - x0).abs() <= (fraction + RELATIVE_TOLERANCE) * x0.abs();
            if !inside {
                return Some(format!(
                    "module {module}: {number} = {}{unit} is outside {}{unit} ± {} %",
                    limits::short(x),
                    limits::short(x0),
                    limits::short(100.0 * fraction),
                    unit = if limit.unit.is_empty() {
                        String::new()
                    } else {
                        format!(" {}", limit.unit)
                    },
                ));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::toml_file::FileError;
    use crate::toml_file::testing::assert_invalid;

    const PAPER_SIM_UNCERTAIN_TOML: &str = include_str!("../../../robots/paper-sim-uncertain.toml");

    fn parse(text: &str) -> Result<Robot, FileError> {
        Robot::parse(text, Path::new("robots/x.toml"))
    }

    /// The paper's robot with a declared box of ±20 % and 0.05 N.
    fn uncertain_paper() -> Robot {
        let mut robot = Robot::paper_sim();
        robot.uncertainty = Uncertainty {
            stiffness: 0.2,
            damping: 0.2,
            mass: 0.2,
            force: 0.05,
        };
        robot
    }

    #[test]
    fn the_table_is_read_with_zero_for_what_it_omits() {
        let robot = parse(
            "modules = 2\n[uncertainty]\nstiffness = 0.2\ndamping = 0.3\nmass = 0.1\nforce = 0.05\n",
        )
        .unwrap();
        assert_eq!(
            robot.uncertainty,
            Uncertainty {
                stiffness: 0.2,
                damping: 0.3,
                mass: 0.1,
                force: 0.05
            }
        );
        assert!(robot.uncertainty.is_declared());
        let partial = parse("modules = 1\n[uncertainty]\nmass = 0.9\n").unwrap();
        assert_eq!(
            partial.uncertainty,
            Uncertainty {
                mass: 0.9,
                ..Uncertainty::default()
            }
        );
        // Integers are numbers; the ends of the ranges are allowed.
        let ends = parse("modules = 1\n[uncertainty]\nstiffness = 0\nforce = 10000\n").unwrap();
        assert_eq!(
            (ends.uncertainty.stiffness, ends.uncertainty.force),
            (0.0, 1e4)
        );
        // No table, or an empty one: nothing declared.
        assert!(!parse("modules = 1\n").unwrap().uncertainty.is_declared());
        assert!(
            !parse("modules = 1\n[uncertainty]\n")
                .unwrap()
                .uncertainty
                .is_declared()
        );
        assert!(!Robot::paper_sim().uncertainty.is_declared());
    }

    /// A module's own `uncertainty = { … }`: its numbers over the table's, the other
    /// modules the table's, and the robot-wide fractions the widest any module keeps.
    #[test]
    fn a_module_gives_its_own_box_over_the_table() {
        let robot = parse(
            "[uncertainty]\nstiffness = 0.2\ndamping = 0.3\nmass = 0.1\nforce = 0.05\n\
             [[module]]\nuncertainty = { bending_stiffness = 0.02, axial_damping = 0.5 }\n\
             [[module]]\n[module.uncertainty]\nbending_stiffness = 0.01\naxial_stiffness = 0.01\n\
             bending_damping = 0.01\naxial_damping = 0.01\nmass = 0.0\n[[module]]\n",
        )
        .unwrap();
        let boxes: Vec<ModuleBox> = (0..3).map(|i| robot.module_box(i)).collect();
        assert_eq!(
            boxes[0],
            ModuleBox {
                stiffness: [0.02, 0.2],
                damping: [0.3, 0.5],
                mass: 0.1
            }
        );
        assert_eq!(
            boxes[1],
            ModuleBox {
                stiffness: [0.01, 0.01],
                damping: [0.01, 0.01],
                mass: 0.0
            }
        );
        assert_eq!(
            boxes[2],
            ModuleBox {
                stiffness: [0.2, 0.2],
                damping: [0.3, 0.3],
                mass: 0.1
            }
        );
        // The widest any module keeps: damping 0.5 from module 1's axial number.
        assert_eq!(
            robot.uncertainty,
            Uncertainty {
                stiffness: 0.2,
                damping: 0.5,
                mass: 0.1,
                force: 0.05
            }
        );
        // A fraction of the table no module keeps counts for nothing.
        let narrowed = parse(
            "[uncertainty]\nstiffness = 0.2\n[[module]]\n\
             uncertainty = { bending_stiffness = 0.0, axial_stiffness = 0.0 }\n",
        )
        .unwrap();
        assert!(!narrowed.uncertainty.is_declared());
        // `[defaults]` gives it to every module that gives none.
        let defaults = parse("modules = 2\n[defaults]\nuncertainty = { mass = 0.3 }\n").unwrap();
        assert_eq!(defaults.module_box(1).mass, 0.3);
        assert_eq!(defaults.uncertainty.mass, 0.3);
        // Factors are judged against each module's own box.
        let inside = ModuleFactors {
            stiffness: [1.02, 0.81],
            damping: [0.7, 1.5],
            mass: 0.9,
        };
        assert!(boxes[0].admits(&inside));
        assert!(!boxes[1].admits(&inside));
        let too_stiff = ModuleFactors {
            stiffness: [1.03, 1.0],
            ..ModuleFactors::NOMINAL
        };
        assert!(!boxes[0].admits(&too_stiff));
        assert!(robot.admits(&[inside, ModuleFactors::NOMINAL, ModuleFactors::NOMINAL]));
        assert!(!robot.admits(&[inside, inside, ModuleFactors::NOMINAL]));
        assert!(!robot.admits(&[inside]));
        // The plant test names the module and the number outside its own box.
        let plant = scaled(
            &robot,
            &[too_stiff, ModuleFactors::NOMINAL, ModuleFactors::NOMINAL],
        )
        .unwrap();
        let reason = outside(&robot, &plant).expect("outside module 1's box");
        assert!(
            reason.starts_with("module 1: bending_stiffness"),
            "{reason}"
        );
        let plant = scaled(
            &robot,
            &[ModuleFactors::NOMINAL, ModuleFactors::NOMINAL, too_stiff],
        )
        .unwrap();
        assert_eq!(outside(&robot, &plant), None);
    }

    #[test]
    fn a_modules_bad_fraction_names_its_line_and_field() {
        assert_invalid(
            parse("[[module]]\n[[module]]\nuncertainty = { bending_damping = 1.5 }\n"),
            3,
            "module[2].uncertainty.bending_damping",
            "≤ 0.9, got 1.5 (a fraction: 0.2 is ±20 %)",
        );
        assert_invalid(
            parse("[defaults]\nuncertainty = { mass = -0.1 }\n[[module]]\n"),
            2,
            "defaults.uncertainty.mass",
            "got -0.1",
        );
    }

    #[test]
    fn bad_values_name_file_line_and_field() {
        assert_invalid(
            parse("modules = 1\n[uncertainty]\nstiffness = 20\n"),
            3,
            "uncertainty.stiffness",
            "must be ≥ 0 and ≤ 0.9, got 20 (a fraction: 0.2 is ±20 %)",
        );
        assert_invalid(
            parse("modules = 1\n[uncertainty]\nstiffness = 0.2\n\ndamping = -0.1\n"),
            5,
            "uncertainty.damping",
            "got -0.1",
        );
        assert_invalid(
            parse("[uncertainty]\nmass = 1\n[[module]]\n"),
            2,
            "uncertainty.mass",
            "≤ 0.9, got 1",
        );
        assert_invalid(
            parse("[uncertainty]\nmass = nan\n[[module]]\n"),
            2,
            "uncertainty.mass",
            "finite",
        );
        assert_invalid(
            parse("modules = 1\n[uncertainty]\nforce = -0.05\n"),
            3,
            "uncertainty.force",
            "must be ≥ 0 and ≤ 10000 N, got -0.05",
        );
        assert_invalid(
            parse("modules = 1\n[uncertainty]\nforce = 1e5\n"),
            3,
            "uncertainty.force",
            "≤ 10000 N, got 100000",
        );
        let error = parse("modules = 1\n[uncertainty]\nforce = inf\n")
            .unwrap_err()
            .to_string();
        assert_eq!(
            error,
            "robots/x.toml:3: field `uncertainty.force`: must be a finite number ≥ 0 and ≤ \
             10000 N, got inf"
        );
    }

    /// Asserts a syntax error at `line` whose message contains `fragment`.
    #[track_caller]
    fn assert_syntax(text: &str, line: usize, fragment: &str) {
        match parse(text) {
            Err(FileError::Syntax {
                line: l, message, ..
            }) => {
                assert_eq!(l, line, "message: {message}");
                assert!(message.contains(fragment), "`{message}` lacks `{fragment}`");
            }
            other => panic!("expected a Syntax error, got {other:?}"),
        }
    }

    #[test]
    fn unknown_fields_and_wrong_types_are_refused() {
        assert_syntax(
            "modules = 1\n[uncertainty]\nstifness = 0.2\n",
            3,
            "field `uncertainty.stifness`: unknown field `stifness`, expected one of \
             `stiffness`, `damping`, `mass`, `force`",
        );
        assert_syntax(
            "modules = 1\n[uncertainty]\nstiffness = \"20 %\"\n",
            3,
            "field `uncertainty.stiffness`: invalid type: string \"20 %\", expected a number",
        );
        // A module's own box names each number (the robot-wide kinds are the table's).
        assert_syntax(
            "[[module]]\n[module.uncertainty]\nmass = 0.1\nstiffness = 0.2\n",
            4,
            "field `module[1].uncertainty.stiffness`: unknown field `stiffness`, expected one \
             of `bending_stiffness`, `axial_stiffness`, `bending_damping`, `axial_damping`, \
             `mass`",
        );
        assert_syntax(
            "[defaults]\nuncertainty = { force = 0.2 }\n[[module]]\n",
            2,
            "unknown field `force`",
        );
    }

    /// The declared uncertainty is numbers, not structure: the same generated model serves
    /// the robot with and without it.
    #[test]
    fn the_structure_key_does_not_change_with_uncertainty() {
        let plain = Robot::paper_sim();
        let uncertain = Robot::parse(
            PAPER_SIM_UNCERTAIN_TOML,
            Path::new("robots/paper-sim-uncertain.toml"),
        )
        .unwrap();
        assert!(uncertain.uncertainty.is_declared());
        assert_eq!(plain.structure().key(), uncertain.structure().key());
        assert_eq!(
            crate::layout::pack_params(&plain),
            crate::layout::pack_params(&uncertain)
        );
        // The shipped file is paper-sim.toml with the table: every other field equal.
        let same_but_declared = Robot {
            name: plain.name.clone(),
            source: plain.source.clone(),
            uncertainty: Uncertainty::default(),
            ..uncertain.clone()
        };
        assert_eq!(same_but_declared, plain);
        assert_eq!(
            uncertain.uncertainty,
            Uncertainty {
                stiffness: 0.2,
                damping: 0.2,
                mass: 0.2,
                force: 0.05
            }
        );
        // A written table with other numbers gives the same key too.
        let other = parse("modules = 2\n[uncertainty]\nstiffness = 0.9\nforce = 3\n").unwrap();
        assert_eq!(
            other.structure().key(),
            parse("modules = 2\n").unwrap().structure().key()
        );
    }

    #[test]
    fn scaling_multiplies_each_uncertain_number_and_nothing_else() {
        let nominal = uncertain_paper();
        let factors = [
            ModuleFactors {
                stiffness: [1.1, 0.9],
                damping: [1.2, 0.8],
                mass: 1.15,
            },
            ModuleFactors {
                stiffness: [0.85, 1.05],
                damping: [1.0, 1.19],
                mass: 0.82,
            },
        ];
        let plant = scaled(&nominal, &factors).unwrap();
        // The paper's numbers (docs/model.md §1), times the factors by hand.
        let (mass, mr2) = (0.15, 0.15 * 0.05 * 0.05);
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-15 * b.abs();
        for (m, f) in plant.modules.iter().zip(&factors) {
            assert!(close(m.bending_stiffness, 10.0 * f.stiffness[0]));
            assert!(close(m.axial_stiffness, 10.0 * f.stiffness[1]));
            assert!(close(m.bending_damping, 5.0 * f.damping[0]));
            assert!(close(m.axial_damping, 5.0 * f.damping[1]));
            assert!(close(m.mass, mass * f.mass));
            // The inertia scales with the mass: a thin hexagon of the scaled mass.
            let expected = [5.0 / 24.0, 5.0 / 24.0, 5.0 / 12.0].map(|c| c * mr2 * f.mass);
            for (i, e) in m.inertia.iter().zip(expected) {
                assert!(close(*i, e), "{i} != {e}");
            }
        }
        assert_eq!(plant.modules[0].axial_stiffness, 9.0);
        // Everything else untouched: put the six numbers back and the robots are equal.
        let mut restored = plant.clone();
        for (m, n) in restored.modules.iter_mut().zip(&nominal.modules) {
            set_values(m, values(n));
        }
        assert_eq!(restored, nominal);
        assert_eq!(plant.structure().key(), nominal.structure().key());
        // Nominal factors give the robot back bit for bit.
        assert_eq!(
            scaled(&nominal, &[ModuleFactors::NOMINAL; 2]).unwrap(),
            nominal
        );
    }

    #[test]
    fn scaling_refuses_bad_factors_and_ranges() {
        let robot = Robot::paper_sim();
        assert_eq!(
            scaled(&robot, &[ModuleFactors::NOMINAL]),
            Err(PlantError::Count {
                modules: 2,
                factors: 1
            })
        );
        let zero_mass = ModuleFactors {
            mass: 0.0,
            ..ModuleFactors::NOMINAL
        };
        assert_eq!(
            scaled(&robot, &[ModuleFactors::NOMINAL, zero_mass]),
            Err(PlantError::Factor {
                module: 2,
                number: "mass",
                value: 0.0
            })
        );
        let nan = ModuleFactors {
            damping: [1.0, f64::NAN],
            ..ModuleFactors::NOMINAL
        };
        let error = scaled(&robot, &[nan, nan]).unwrap_err().to_string();
        assert_eq!(
            error,
            "module 1: the factor of axial_damping must be a finite number > 0, got NaN"
        );
        // κθ = 10 N·m/rad times 2000 leaves the range a robot file may give it.
        let stiff = ModuleFactors {
            stiffness: [2000.0, 1.0],
            ..ModuleFactors::NOMINAL
        };
        let error = scaled(&robot, &[ModuleFactors::NOMINAL, stiff])
            .unwrap_err()
            .to_string();
        assert_eq!(
            error,
            "module 2: the scaled bending_stiffness must be ≥ 0 and ≤ 10000 N·m/rad, got 20000"
        );
    }

    #[test]
    fn the_box_contains_plants_scaled_inside_it_and_no_others() {
        let nominal = uncertain_paper();
        // On every edge of the box, and inside.
        for factor in [0.8, 1.2, 1.0, 0.95] {
            let f = ModuleFactors {
                stiffness: [factor; 2],
                damping: [factor; 2],
                mass: factor,
            };
            assert!(nominal.uncertainty.admits(&f));
            let plant = scaled(&nominal, &[f, ModuleFactors::NOMINAL]).unwrap();
            assert!(
                contains(&nominal, &plant),
                "{:?}",
                outside(&nominal, &plant)
            );
        }
        // One number just past the edge, each in turn.
        for k in 0..5 {
            let mut f = ModuleFactors::NOMINAL;
            let slot = match k {
                0 => &mut f.stiffness[0],
                1 => &mut f.stiffness[1],
                2 => &mut f.damping[0],
                3 => &mut f.damping[1],
                _ => &mut f.mass,
            };
            *slot = if k % 2 == 0 { 1.2001 } else { 0.7999 };
            assert!(!nominal.uncertainty.admits(&f));
            let plant = scaled(&nominal, &[ModuleFactors::NOMINAL, f]).unwrap();
            let reason = outside(&nominal, &plant).expect("outside the box");
            assert!(reason.starts_with("module 2: "), "{reason}");
        }
        let heavier = scaled(
            &nominal,
            &[
                ModuleFactors {
                    mass: 1.3,
                    ..ModuleFactors::NOMINAL
                },
                ModuleFactors::NOMINAL,
            ],
        )
        .unwrap();
        assert_eq!(
            outside(&nominal, &heavier).unwrap(),
            "module 1: mass = 0.195 kg is outside 0.15 kg ± 20 %"
        );
        // Without a declaration only the nominal robot is inside.
        let exact = Robot::paper_sim();
        assert!(contains(&exact, &exact));
        let slightly = ModuleFactors {
            damping: [1.001, 1.0],
            ..ModuleFactors::NOMINAL
        };
        assert!(!contains(
            &exact,
            &scaled(&exact, &[slightly, ModuleFactors::NOMINAL]).unwrap()
        ));
        // An inertia changed on its own, within the mass's fraction, is inside; beyond, not.
        let mut plant = nominal.clone();
        plant.modules[1].inertia[2] *= 1.19;
        assert!(contains(&nominal, &plant));
        plant.modules[1].inertia[2] *= 1.02;
        assert_eq!(
            outside(&nominal, &plant).map(|r| r.starts_with("module 2: inertia Izz")),
            Some(true)
        );
        // Numbers outside the declaration must be the nominal ones.
        let mut longer = nominal.clone();
        longer.modules[0].rest_length = 0.11;
        assert!(
            outside(&nominal, &longer)
                .unwrap()
                .contains("module 1: rest_length")
        );
        let mut moon = nominal.clone();
        moon.gravity = [0.0, 0.0, -1.62];
        assert!(!contains(&nominal, &moon));
        let mut one = nominal.clone();
        one.modules.pop();
        assert!(!contains(&nominal, &one));
        // The controller's own numbers are not the plant's: a margin may differ.
        let mut margins = nominal.clone();
        margins.modules[0].margins = vec![0.01; 6];
        assert!(contains(&nominal, &margins));
    }

    /// Hostile values in every field return an error (or a robot), never a panic; the table
    /// written as a value or an array of tables is a syntax error.
    #[test]
    fn hostile_tables_are_errors_not_panics() {
        for value in [
            "", "-1", "nan", "-inf", "1e400", "\"x\"", "[]", "{}", "true", "20000",
        ] {
            for field in ["stiffness", "damping", "mass", "force", "other"] {
                let text = format!("modules = 1\n[uncertainty]\n{field} = {value}\n");
                assert!(parse(&text).is_err(), "{text}");
            }
        }
        assert_syntax("modules = 1\nuncertainty = 0.2\n", 2, "uncertainty");
        assert_syntax(
            "modules = 1\n[[uncertainty]]\nmass = 0.2\n",
            2,
            "uncertainty",
        );
    }
}
