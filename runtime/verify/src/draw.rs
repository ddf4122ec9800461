//! What one run of a batch is given, drawn from its seed: the group (safety mode and
//! control period, by index), the set point, the initial state, the plant's factors and
//! the seed of its sensor noise.

use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use softcbf_description::uncertainty::{self, ModuleFactors};

use crate::control::SafetyMode;
use crate::model::Model;
use crate::noise::SensorNoise;
use crate::reference::ReferenceSpec;
use crate::scenario::Scenario;
use crate::spec::{Bounds, INITIAL_STATE_TRIES, VerifySpec};

/// One run's draws.
#[derive(Clone, Debug, PartialEq)]
pub struct Draw {
    /// The seed its draws came from ([`run_seed`]).
    pub seed: u64,
    /// Its group (index into [`VerifySpec::groups`]), safety mode and control period.
    pub group: usize,
    pub safety: SafetyMode,
    pub control_period: f64,
    /// Set point \[m\].
    pub set_point: Vec<f64>,
    /// Initial `q` \[m\] and `q̇` \[m/s\].
    pub initial_q: Vec<f64>,
    pub initial_qd: Vec<f64>,
    /// The plant's factors per module (all 1 without parameter errors).
    pub factors: Vec<ModuleFactors>,
    /// Seed of the sensor noise.
    pub noise_seed: u64,
}

impl Draw {
    /// The scenario of this run of `spec`: its group's, with the drawn set point, initial state,
    /// plant numbers and sensor noise.
    pub fn scenario(&self, spec: &VerifySpec, model: &Model) -> Result<Scenario, String> {
        let group = spec
            .groups
            .get(self.group)
            .ok_or_else(|| format!("no group {}", self.group))?;
        let mut scenario = group.scenario.clone();
        if spec.set_point.is_some() {
            scenario.reference = ReferenceSpec::SetPoint(self.set_point.clone());
        }
        scenario.initial_q.clone_from(&self.initial_q);
        scenario.initial_qd.clone_from(&self.initial_qd);
        if spec.parameter_errors {
            let plant =
                uncertainty::scaled(&model.robot, &self.factors).map_err(|e| e.to_string())?;
            scenario.plant = Some(plant);
        }
        if spec.sensor_noise.iter().any(|&s| s > 0.0) {
            scenario.sensor_noise = Some(SensorNoise {
                position: spec.sensor_noise[0],
                velocity: spec.sensor_noise[1],
                seed: self.noise_seed,
            });
        }
        scenario.compare = false;
        Ok(scenario)
    }
}

/// SplitMix64's output function: a bijection of `u64` that mixes every bit into every bit.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The seed of run `run` of a batch seeded `seed`: neighbouring runs and neighbouring
/// batch seeds give unrelated streams.
pub fn run_seed(seed: u64, run: usize) -> u64 {
    mix(mix(seed) ^ (run as u64))
}

/// A uniform draw in `[lo, hi]`.
fn uniform(draws: &mut Xoshiro256PlusPlus, lo: f64, hi: f64) -> f64 {
    let u: f64 = draws.random();
    lo + (hi - lo) * u
}

fn in_box(draws: &mut Xoshiro256PlusPlus, bounds: &Bounds) -> Vec<f64> {
    bounds
        .min
        .iter()
        .zip(&bounds.max)
        .map(|(&lo, &hi)| uniform(draws, lo, hi))
        .collect()
}

/// The draws of run `run` of `spec`'s batch on `model`. The draws come in a fixed order
/// (set point, initial `q` and `q̇` until the start is one the guarantee covers
/// ([`crate::start`]), factors, noise seed), each
/// from the run's own generator, so a run does not depend on any other.
pub fn draw(model: &Model, spec: &VerifySpec, run: usize) -> Result<Draw, String> {
    let seed = run_seed(spec.seed, run);
    let mut draws = Xoshiro256PlusPlus::seed_from_u64(seed);
    let group_index = run % spec.groups.len().max(1);
    let group = spec
        .groups
        .get(group_index)
        .ok_or("the batch has no group of safety mode and control period")?;
    let scenario = &group.scenario;
    let set_point = match &spec.set_point {
        Some(bounds) => in_box(&mut draws, bounds),
        None => scenario.reference.final_target().to_vec(),
    };
    // Initial q and q̇ drawn together until the start is one the guarantee covers
    // (`StartSet`); a start that is not drawn is checked once.
    let mut initial_q = scenario.initial_q.clone();
    let mut initial_qd = scenario.initial_qd.clone();
    let drawn = spec.initial_q.is_some() || spec.initial_qd.is_some();
    let tries = if drawn { INITIAL_STATE_TRIES } else { 1 };
    let mut problem = None;
    for _ in 0..tries {
        if let Some(bounds) = &spec.initial_q {
            initial_q = in_box(&mut draws, bounds);
        }
        if let Some(bounds) = &spec.initial_qd {
            initial_qd = in_box(&mut draws, bounds);
        }
        problem = spec.start.problem(model, &initial_q, &initial_qd);
        if problem.is_none() {
            break;
        }
    }
    if let Some(problem) = problem {
        return Err(if drawn {
            format!(
                "no initial state the guarantee covers in {INITIAL_STATE_TRIES} draws from \
                 the boxes `initial_q_min`..`initial_q_max`, `initial_qd_min`..\
                 `initial_qd_max` (the last: {problem}): move the boxes into the safe set, \
                 slow the starts down"
            )
        } else {
            format!("the scenario's initial state is not one the guarantee covers: {problem}")
        });
    }
    let factors = if spec.parameter_errors {
        // Each module inside its own box (the robot-wide one unless it gives its own).
        (0..model.robot.modules.len())
            .map(|i| {
                let b = model.robot.module_box(i);
                ModuleFactors {
                    stiffness: [
                        uniform(&mut draws, 1.0 - b.stiffness[0], 1.0 + b.stiffness[0]),
                        uniform(&mut draws, 1.0 - b.stiffness[1], 1.0 + b.stiffness[1]),
                    ],
                    damping: [
                        uniform(&mut draws, 1.0 - b.damping[0], 1.0 + b.damping[0]),
                        uniform(&mut draws, 1.0 - b.damping[1], 1.0 + b.damping[1]),
                    ],
                    mass: uniform(&mut draws, 1.0 - b.mass, 1.0 + b.mass),
                }
            })
            .collect()
    } else {
        VerifySpec::nominal_factors(model)
    };
    let noise_seed: u64 = draws.random();
    Ok(Draw {
        seed,
        group: group_index,
        safety: group.safety,
        control_period: group.control_period,
        set_point,
        initial_q,
        initial_qd,
        factors,
        noise_seed,
    })
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use softcbf_description::Robot;

    use super::*;
    use crate::scenario::ScenarioFile;
    use crate::spec::VerifyOverrides;

    /// With `parameter_errors`, each module's factors are drawn in its own box: module 1
    /// narrowed to ±1 % in its file stays there, module 2 spreads over the table's ±20 %.
    #[test]
    fn plants_are_drawn_in_each_modules_own_box() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let file = ScenarioFile::load(&root.join("scenarios/falsify/uncertain-33hz.toml"))
            .expect("the falsifier's scenario");
        let path = root.join("robots/paper-sim-uncertain.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        let first = text.find("[[module]]\n").unwrap() + "[[module]]\n".len();
        let edited = format!(
            "{}uncertainty = {{ bending_stiffness = 0.01, axial_stiffness = 0.01, \
             bending_damping = 0.01, axial_damping = 0.01, mass = 0.01 }}\n{}",
            &text[..first],
            &text[first..]
        );
        let model = Model::new(Robot::parse(&edited, &path).unwrap()).unwrap();
        let spec = VerifySpec::from_file(&file, &model, &VerifyOverrides::default(), &edited)
            .expect("the spec");
        assert!(spec.parameter_errors);
        let mut spread = [0.0f64; 2];
        for run in 0..100 {
            let drawn = draw(&model, &spec, run).expect("a draw");
            assert!(model.robot.admits(&drawn.factors), "run {run}");
            for (module, f) in drawn.factors.iter().enumerate() {
                let numbers = [f.stiffness[0], f.stiffness[1], f.damping[0], f.damping[1]];
                for x in numbers.into_iter().chain([f.mass]) {
                    spread[module] = spread[module].max((x - 1.0).abs());
                }
            }
        }
        assert!(spread[0] <= 0.01 + 1e-12, "module 1: {}", spread[0]);
        assert!(spread[1] > 0.19, "module 2: {}", spread[1]);
    }
}
