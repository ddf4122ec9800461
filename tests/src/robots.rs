//! The shipped robot files the integration tests load, found from the tests crate's folder,
//! and plant robots drawn inside a robot's declared uncertainty.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use rand::RngExt;
use softcbf::model::Model;
use softcbf_description::robot::Robot;
use softcbf_description::uncertainty::{self, ModuleFactors};

use crate::TestRng;

/// Path of `robots/<name>` in the checkout.
pub fn path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(name)
}

/// `robots/hardware-example.toml`: the paper's hardware layout, six servos with IDs 1–6.
pub fn hardware_example() -> Robot {
    Robot::load(&path("hardware-example.toml")).expect("the shipped example robot is valid")
}

/// The model of [`hardware_example`], built once per test binary.
pub fn hardware_example_model() -> &'static Model {
    static MODEL: OnceLock<Model> = OnceLock::new();
    MODEL.get_or_init(|| Model::new(hardware_example()).expect("the example robot has a model"))
}

/// Factors for every module of `robot`, each drawn uniformly and independently inside the
/// box its `[uncertainty]` declares (each module's own box, `Robot::module_box`): `κθ`, `κL`
/// factors in `1 ± stiffness`, `βθ`, `βL` in
/// `1 ± damping`, the mass (and inertia) factor in `1 ± mass`. With nothing declared every
/// factor is 1 (and no number is drawn).
pub fn draw_factors(robot: &Robot, rng: &mut TestRng) -> Vec<ModuleFactors> {
    let mut factor = |fraction: f64| {
        if fraction > 0.0 {
            rng.random_range(1.0 - fraction..=1.0 + fraction)
        } else {
            1.0
        }
    };
    // Each module inside its own box (the robot-wide one unless it gives its own).
    (0..robot.modules.len())
        .map(|i| {
            let b = robot.module_box(i);
            ModuleFactors {
                stiffness: [factor(b.stiffness[0]), factor(b.stiffness[1])],
                damping: [factor(b.damping[0]), factor(b.damping[1])],
                mass: factor(b.mass),
            }
        })
        .collect()
}

/// A plant robot drawn inside `robot`'s declared uncertainty: `robot` scaled
/// ([`uncertainty::scaled`]) by [`draw_factors`] from `softcbf_tests::rng(seed)`, so the
/// same seed gives the same plant. Its other numbers, structure and declared uncertainty are
/// `robot`'s; `uncertainty::contains(robot, &plant)` holds. Panics if a scaled number
/// leaves the range a robot file may give it (a nominal number near the end of its range).
pub fn draw_within(robot: &Robot, seed: u64) -> Robot {
    let factors = draw_factors(robot, &mut crate::rng(seed));
    uncertainty::scaled(robot, &factors)
        .unwrap_or_else(|e| panic!("{}: a plant drawn inside its box: {e}", robot.name))
}

/// `robots/paper-sim-uncertain.toml`: the paper's robot with ±20 % on stiffness, damping
/// and mass and 0.05 N of unmodelled force declared.
pub fn paper_sim_uncertain() -> Robot {
    Robot::load(&path("paper-sim-uncertain.toml")).expect("the shipped robot file is valid")
}
