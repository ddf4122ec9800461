//! What the interpreted model costs against compiled code: `model_terms` (everything a
//! control tick needs from the model) for 1, 2 (paper), 4 and 8 modules, and the paper's
//! closed loop for 1 s (ticks, QP, plant), each on both.
//!
//! Each `model_terms` iteration evaluates one of 64 bent, moving states (θ up to 2 rad),
//! cycled. Run with
//! `cargo bench -p softcbf-tests --bench interpreter -- --warm-up-time 1 --measurement-time 3`.

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use rand::RngExt;
use softcbf::model::Model;
use softcbf::scenario::{Overrides, ScenarioFile};
use softcbf::sim::simulate;
use softcbf_description::robot::Robot;
use softcbf_interpreter::interpreted;

/// Number of states cycled through.
const STATES: usize = 64;

/// The compiled and the interpreted model of `n` paper modules.
fn models(n: usize) -> (Model, Model) {
    let text = format!("name = \"bench-{n}\"\nmodules = {n}\n");
    let robot = Robot::parse(&text, Path::new("<bench>")).unwrap_or_else(|e| panic!("{e}"));
    let compiled = Model::new(robot.clone()).unwrap_or_else(|e| panic!("{e}"));
    let generated = interpreted(&robot.structure());
    let model = Model::with_generated(robot, generated).unwrap_or_else(|e| panic!("{e}"));
    (compiled, model)
}

fn states(model: &Model) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut rng = softcbf_tests::rng(0x2545_f491_4f6c_dd1d);
    (0..STATES)
        .map(|_| {
            let mut q = Vec::new();
            for module in &model.robot.modules {
                let theta = rng.random_range(0.0..2.0);
                let alpha: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                let r = theta * module.tendon_radius;
                q.extend([
                    r * alpha.cos(),
                    r * alpha.sin(),
                    rng.random_range(-0.03..0.03),
                ]);
            }
            let qd = (0..model.nq())
                .map(|_| rng.random_range(-0.2..0.2))
                .collect();
            (q, qd)
        })
        .collect()
}

fn bench_model_terms(c: &mut Criterion) {
    let mut group = c.benchmark_group("model_terms");
    for n in [1, 2, 4, 8] {
        let (compiled, interpreted) = models(n);
        let set = states(&compiled);
        for (label, model) in [("compiled", &compiled), ("interpreted", &interpreted)] {
            let (m, nq, nb) = (model.n_modules(), model.nq(), model.nb());
            let mut rotation = vec![[[0.0; 3]; 3]; m];
            let mut translation = vec![[0.0; 3]; m];
            let mut subspace = vec![[[0.0; 3]; 6]; m];
            let mut bias = vec![[0.0; 6]; m];
            let (mut b, mut jacobian, mut jdot) =
                (vec![0.0; nb], vec![0.0; nb * nq], vec![0.0; nb]);
            group.bench_function(format!("{n}_modules/{label}"), |bench| {
                let mut k = 0;
                bench.iter(|| {
                    let (q, qd) = &set[k % STATES];
                    k += 1;
                    black_box(model.generated).model_terms(
                        black_box(&model.params),
                        black_box(q),
                        black_box(qd),
                        &mut rotation,
                        &mut translation,
                        &mut subspace,
                        &mut bias,
                        &mut b,
                        &mut jacobian,
                        &mut jdot,
                    );
                    black_box((
                        &rotation,
                        &translation,
                        &subspace,
                        &bias,
                        &b,
                        &jacobian,
                        &jdot,
                    ));
                })
            });
        }
    }
    group.finish();
}

fn bench_closed_loop(c: &mut Criterion) {
    let mut group = c.benchmark_group("paper_closed_loop_1s");
    group.sample_size(10);
    let (compiled, interpreted) = models(2);
    // The robot file of `models` gives no set point: the paper's, as on the command line.
    let overrides = Overrides {
        set_point: Some(vec![0.08, 0.0, -0.05, 0.0, -0.06, -0.07]),
        ..Overrides::default()
    };
    let mut scenario = ScenarioFile::paper_sim()
        .resolve_with(&compiled, &overrides)
        .expect("paper scenario");
    scenario.duration = 1.0;
    for (label, model) in [("compiled", &compiled), ("interpreted", &interpreted)] {
        group.bench_function(label, |bench| {
            bench.iter(|| simulate(model, &scenario, true, &mut |_| {}).expect("runs"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench_model_terms, bench_closed_loop);
criterion_main!(benches);
