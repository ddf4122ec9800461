//! The sampled-data guarantee (docs/model.md §5) in closed loop at the hardware's rate: the
//! plant is integrated between ticks and its barriers are read every millisecond, not only
//! at the ticks, for the paper's set points, random set points and plants off the model.

use softcbf::control::{Controller, ControllerSettings, Reference, SafetyMode, TickStatus, tick};
use softcbf::integrator::Tolerances;
use softcbf::model::Model;
use softcbf::plant::Plant;
use softcbf_description::Robot;

/// What one closed-loop run measured.
#[derive(Debug, Clone, Copy)]
struct Outcome {
    /// Lowest barrier over every 1 ms record \[m\].
    lowest: f64,
    /// Lowest barrier at the ticks only \[m\].
    lowest_at_ticks: f64,
    /// `‖q(T) − q̄‖` \[m\].
    set_point_error: f64,
    relaxed: usize,
    failed: usize,
}

/// Runs `controller_model`'s controller on `plant_model`'s physics for `duration` s at
/// `period`, reading the plant's barriers every `record` s.
fn closed_loop(
    controller_model: &Model,
    plant_model: &Model,
    settings: ControllerSettings,
    set_point: &[f64],
    period: f64,
    duration: f64,
    record: f64,
) -> Outcome {
    let nq = controller_model.nq();
    let mut controller = Controller::new(controller_model, settings).unwrap();
    let mut tolerances = Tolerances::default();
    tolerances.h_max = record;
    let mut plant = Plant::new(plant_model, tolerances).unwrap();
    let zero = vec![0.0; nq];
    plant.reset(&zero, &zero, 0.0);
    let mut barriers = vec![0.0; plant_model.nb()];
    let pieces = (period / record).round().max(1.0) as usize;
    let ticks = (duration / period).round() as usize;
    let mut outcome = Outcome {
        lowest: f64::INFINITY,
        lowest_at_ticks: f64::INFINITY,
        set_point_error: f64::NAN,
        relaxed: 0,
        failed: 0,
    };
    for _ in 0..ticks {
        let reference = Reference {
            q: set_point,
            qd: &zero,
            qdd: &zero,
        };
        let status = tick(
            controller_model,
            &mut controller,
            plant.q(),
            plant.qd(),
            reference,
        );
        if std::env::var("DEBUG").is_ok() {
            let tau_max = controller.tau().iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            let low = controller
                .barriers()
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min);
            println!(
                "t {:.4} {status:?} |tau| {tau_max:.3} b {low:.3e} q {:?}",
                plant.time(),
                plant.q()
            );
        }
        match status {
            TickStatus::Relaxed => outcome.relaxed += 1,
            s if s.is_fallback() => outcome.failed += 1,
            _ => {}
        }
        plant_model
            .generated
            .barriers(&plant_model.params, plant.q(), &mut barriers);
        let at_tick = barriers.iter().copied().fold(f64::INFINITY, f64::min);
        outcome.lowest_at_ticks = outcome.lowest_at_ticks.min(at_tick);
        plant.tau_mut().copy_from_slice(controller.tau());
        for _ in 0..pieces {
            plant.advance(period / pieces as f64).unwrap();
            plant_model
                .generated
                .barriers(&plant_model.params, plant.q(), &mut barriers);
            let low = barriers.iter().copied().fold(f64::INFINITY, f64::min);
            outcome.lowest = outcome.lowest.min(low);
        }
    }
    outcome.lowest = outcome.lowest.min(outcome.lowest_at_ticks);
    outcome.set_point_error = plant
        .q()
        .iter()
        .zip(set_point)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        .sqrt();
    outcome
}

fn settings(model: &Model, safety: SafetyMode, period: f64) -> ControllerSettings {
    let mut settings = ControllerSettings::paper(model);
    settings.safety = safety;
    settings.hold = period;
    settings
}

const PAPER_SIM: [f64; 6] = [0.08, 0.0, -0.05, 0.0, -0.06, -0.07];
const PERIOD: f64 = 1.0 / 33.0;

#[test]
#[ignore = "exploration: prints the lowest barriers of each safety mode"]
fn explore_modes() {
    let model = Model::new(Robot::paper_sim()).unwrap();
    for set_point in [PAPER_SIM, [0.0, 0.0, -0.09, 0.0, -0.065, 0.0]] {
        for safety in [
            SafetyMode::Paper,
            SafetyMode::HoldCorrection,
            SafetyMode::Sampled,
        ] {
            let start = std::time::Instant::now();
            let outcome = closed_loop(
                &model,
                &model,
                settings(&model, safety, PERIOD),
                &set_point,
                PERIOD,
                10.0,
                1e-3,
            );
            println!(
                "{set_point:?} {safety}: {outcome:?} ({:.2} s)",
                start.elapsed().as_secs_f64()
            );
        }
    }
}

/// A set point drawn over the reachable range: bends up to 0.08 m of tendon travel each
/// way, elongations from −0.06 to +0.04 m.
fn random_set_point(rng: &mut softcbf_tests::TestRng, modules: usize) -> Vec<f64> {
    use rand::RngExt;
    (0..modules)
        .flat_map(|_| {
            [
                rng.random_range(-0.08..0.08),
                rng.random_range(-0.08..0.08),
                rng.random_range(-0.06..0.04),
            ]
        })
        .collect()
}

#[test]
#[ignore = "exploration: random set points"]
fn explore_random() {
    use rand::RngExt;
    let model = match std::env::var("ROBOT") {
        Ok(path) => Model::new(Robot::load(std::path::Path::new(&path)).unwrap()).unwrap(),
        Err(_) => Model::new(Robot::paper_sim()).unwrap(),
    };
    let mut rng = softcbf_tests::rng(13);
    let mut worst = [(f64::INFINITY, vec![]), (f64::INFINITY, vec![])];
    if let Ok(point) = std::env::var("POINT") {
        let set_point: Vec<f64> = point.split(',').map(|v| v.parse().unwrap()).collect();
        let mut s = settings(&model, SafetyMode::Sampled, PERIOD);
        if let Ok(n) = std::env::var("PASSES") {
            s.sampled.passes = n.parse().unwrap();
        }
        let outcome = closed_loop(&model, &model, s, &set_point, PERIOD, 5.0, 1e-3);
        println!("{outcome:?}");
        return;
    }
    let runs: usize = std::env::var("RUNS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(40);
    for _ in 0..runs {
        let set_point = random_set_point(&mut rng, 2);
        for (i, safety) in [SafetyMode::HoldCorrection, SafetyMode::Sampled]
            .into_iter()
            .enumerate()
        {
            let mut s = settings(&model, safety, PERIOD);
            if let Ok(n) = std::env::var("EARLY") {
                s.sampled.early = n.parse().unwrap();
            }
            if let Ok(n) = std::env::var("SAMPLES") {
                s.sampled.samples = n.parse().unwrap();
            }
            if let Ok(n) = std::env::var("PASSES") {
                s.sampled.passes = n.parse().unwrap();
            }
            let plant = match std::env::var("DRAW") {
                Ok(_) => Model::new(softcbf_tests::robots::draw_within(
                    &model.robot,
                    rng.random(),
                ))
                .unwrap(),
                Err(_) => Model::new(model.robot.clone()).unwrap(),
            };
            let outcome = closed_loop(&model, &plant, s, &set_point, PERIOD, 5.0, 1e-3);
            if outcome.lowest < worst[i].0 {
                worst[i] = (outcome.lowest, set_point.clone());
            }
            if outcome.lowest < -1e-6 || outcome.relaxed > 0 || outcome.failed > 0 {
                println!("{safety} {set_point:?}: {outcome:?}");
            }
        }
    }
    println!("worst: {worst:?}");
}
