//! Criterion benchmarks of the generated model: the paper robot's 12 barriers with Jacobian
//! rows and `J̇q̇`, `M`, `h`, `G` together for 1, 2, 4 and 8 modules (issues 2 and 3), and
//! `model_terms`, everything a control tick needs from the model in one call (issue 10),
//! for the paper robot and 1, 2, 4 and 8 modules: its time against the sum of
//! `mass_bias_gravity/2_modules` and `barrier_terms_paper_sim/arrays` of the same run.
//!
//! Each iteration evaluates one state of a fixed set of 64 bent, moving states (θ up to
//! 2 rad, every bend direction), cycled so that no single input is cached. Run with
//! `cargo bench -p softcbf --bench model -- --warm-up-time 1 --measurement-time 3`.

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use softcbf::dynamics::{
    BarrierTerms, DynamicsWorkspace, bias_and_gravity, forward_dynamics, mass_matrix, model_terms,
    update_joints,
};
use softcbf::model::Model;
use softcbf_description::robot::Robot;
use softcbf_generated::paper_sim;

/// Number of states cycled through.
const STATES: usize = 64;

/// `STATES` pairs `(q, q̇)` for `model`: bend θ in [0, 2] rad in a random direction,
/// `δL` in [−0.03, 0.03] m, `q̇` in [−0.2, 0.2].
fn states(model: &Model) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut rng: Xoshiro256PlusPlus = SeedableRng::seed_from_u64(0x2545_f491_4f6c_dd1d);
    (0..STATES)
        .map(|_| {
            let mut q = Vec::with_capacity(model.nq());
            for module in &model.robot.modules {
                let theta = 2.0 * rng.random::<f64>();
                let alpha = std::f64::consts::TAU * rng.random::<f64>();
                let r = theta * module.tendon_radius;
                q.extend([
                    r * alpha.cos(),
                    r * alpha.sin(),
                    0.06 * rng.random::<f64>() - 0.03,
                ]);
            }
            let qd = (0..model.nq())
                .map(|_| 0.4 * rng.random::<f64>() - 0.2)
                .collect();
            (q, qd)
        })
        .collect()
}

/// The model of `n` modules with the default (paper) module values; `expected` is the
/// generated structure it must use.
fn model_with(n: usize, expected: &str) -> Model {
    let text = format!("name = \"bench-{n}\"\nmodules = {n}\n");
    let robot = Robot::parse(&text, Path::new("<bench>")).unwrap_or_else(|e| panic!("{e}"));
    let model = Model::new(robot).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(model.generated.name(), expected, "{n} modules");
    model
}

fn bench_barriers(c: &mut Criterion) {
    let model = Model::new(Robot::paper_sim()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(model.generated.name(), "paper_sim");
    let set = states(&model);
    let p: [f64; paper_sim::NP] = model.params.as_slice().try_into().expect("paper_sim NP");
    let arrays: Vec<([f64; paper_sim::NQ], [f64; paper_sim::NQ])> = set
        .iter()
        .map(|(q, qd)| {
            let q = q.as_slice().try_into().expect("paper_sim NQ");
            (q, qd.as_slice().try_into().expect("paper_sim NQ"))
        })
        .collect();

    let mut group = c.benchmark_group("barrier_terms_paper_sim");
    let mut b = [0.0; paper_sim::NB];
    let mut jacobian = [[0.0; paper_sim::NQ]; paper_sim::NB];
    let mut jdot_qd = [0.0; paper_sim::NB];
    group.bench_function("arrays", |bench| {
        let mut k = 0;
        bench.iter(|| {
            let (q, qd) = &arrays[k % STATES];
            k += 1;
            paper_sim::barrier_terms(
                black_box(&p),
                black_box(q),
                black_box(qd),
                &mut b,
                &mut jacobian,
                &mut jdot_qd,
            );
            black_box((&b, &jacobian, &jdot_qd));
        })
    });
    let (nb, nq) = (model.nb(), model.nq());
    let (mut b, mut jacobian, mut jdot_qd) = (vec![0.0; nb], vec![0.0; nb * nq], vec![0.0; nb]);
    group.bench_function("trait", |bench| {
        let mut k = 0;
        bench.iter(|| {
            let (q, qd) = &set[k % STATES];
            k += 1;
            black_box(model.generated).barrier_terms(
                black_box(&model.params),
                black_box(q),
                black_box(qd),
                &mut b,
                &mut jacobian,
                &mut jdot_qd,
            );
            black_box((&b, &jacobian, &jdot_qd));
        })
    });
    group.finish();
}

fn bench_dynamics(c: &mut Criterion) {
    let mut group = c.benchmark_group("mass_bias_gravity");
    for (n, name) in [(1, "hex_1"), (2, "paper_sim"), (4, "hex_4"), (8, "hex_8")] {
        let model = model_with(n, name);
        let set = states(&model);
        let mut ws = DynamicsWorkspace::new(&model);
        group.bench_function(format!("{n}_modules"), |bench| {
            let mut k = 0;
            bench.iter(|| {
                let (q, qd) = &set[k % STATES];
                k += 1;
                update_joints(&model, &mut ws, black_box(q), black_box(qd)).unwrap();
                mass_matrix(&model, &mut ws).unwrap();
                bias_and_gravity(&model, &mut ws, black_box(qd)).unwrap();
                black_box((&ws.mass_matrix, &ws.bias, &ws.gravity));
            })
        });
    }
    group.finish();

    // Where the paper robot's time goes: each stage alone (the later stages reuse the
    // joint terms of the last update_joints).
    let model = model_with(2, "paper_sim");
    let set = states(&model);
    let mut ws = DynamicsWorkspace::new(&model);
    let mut group = c.benchmark_group("dynamics_stages_paper_sim");
    group.bench_function("update_joints", |bench| {
        let mut k = 0;
        bench.iter(|| {
            let (q, qd) = &set[k % STATES];
            k += 1;
            update_joints(&model, &mut ws, black_box(q), black_box(qd)).unwrap();
            black_box(ws.transforms());
        })
    });
    update_joints(&model, &mut ws, &set[0].0, &set[0].1).unwrap();
    group.bench_function("mass_matrix", |bench| {
        bench.iter(|| {
            mass_matrix(black_box(&model), &mut ws).unwrap();
            black_box(&ws.mass_matrix);
        })
    });
    group.bench_function("bias_and_gravity", |bench| {
        bench.iter(|| {
            bias_and_gravity(black_box(&model), &mut ws, black_box(&set[0].1)).unwrap();
            black_box((&ws.bias, &ws.gravity));
        })
    });
    group.finish();

    // For reference: the whole forward dynamics (adds the Cholesky solve) of the paper robot.
    let model = model_with(2, "paper_sim");
    let set = states(&model);
    let mut ws = DynamicsWorkspace::new(&model);
    let tau = vec![0.1; model.nq()];
    let mut qdd = vec![0.0; model.nq()];
    c.bench_function("forward_dynamics/paper_sim", |bench| {
        let mut k = 0;
        bench.iter(|| {
            let (q, qd) = &set[k % STATES];
            k += 1;
            let status =
                forward_dynamics(&model, &mut ws, black_box(q), black_box(qd), &tau, &mut qdd);
            black_box((status.is_ok(), &qdd));
        })
    });
}

fn bench_model_terms(c: &mut Criterion) {
    let mut group = c.benchmark_group("model_terms");
    // The paper robot (2 modules, from its robot file), then 1, 4 and 8 modules.
    let paper = Model::new(Robot::paper_sim()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(paper.generated.name(), "paper_sim");
    let models = [
        ("paper_sim", paper),
        ("hex_1", model_with(1, "hex_1")),
        ("hex_4", model_with(4, "hex_4")),
        ("hex_8", model_with(8, "hex_8")),
    ];
    for (name, model) in &models {
        let set = states(model);
        let mut ws = DynamicsWorkspace::new(model);
        let mut barriers = BarrierTerms::new(model);
        group.bench_function(*name, |bench| {
            let mut k = 0;
            bench.iter(|| {
                let (q, qd) = &set[k % STATES];
                k += 1;
                let status =
                    model_terms(model, &mut ws, &mut barriers, black_box(q), black_box(qd));
                black_box((
                    status.is_ok(),
                    &ws.mass_matrix,
                    &ws.bias,
                    &ws.gravity,
                    &barriers,
                ));
            })
        });
    }
    group.finish();

    // The generated part alone (joint and barrier terms at one state).
    let (_, model) = &models[0];
    let set = states(model);
    let (n, nq, nb) = (model.n_modules(), model.nq(), model.nb());
    let mut rotation = vec![[[0.0; 3]; 3]; n];
    let mut translation = vec![[0.0; 3]; n];
    let mut subspace = vec![[[0.0; 3]; 6]; n];
    let mut bias = vec![[0.0; 6]; n];
    let (mut b, mut jacobian, mut jdot_qd) = (vec![0.0; nb], vec![0.0; nb * nq], vec![0.0; nb]);
    let mut group = c.benchmark_group("generated_paper_sim");
    group.bench_function("model_terms", |bench| {
        let mut k = 0;
        bench.iter(|| {
            let (q, qd) = &set[k % STATES];
            k += 1;
            black_box(model.generated).model_terms(
                &model.params,
                black_box(q),
                black_box(qd),
                &mut rotation,
                &mut translation,
                &mut subspace,
                &mut bias,
                &mut b,
                &mut jacobian,
                &mut jdot_qd,
            );
            black_box((&rotation, &b));
        })
    });
    group.bench_function("joint_terms", |bench| {
        let mut k = 0;
        bench.iter(|| {
            let (q, qd) = &set[k % STATES];
            k += 1;
            black_box(model.generated).joint_terms(
                &model.params,
                black_box(q),
                black_box(qd),
                &mut rotation,
                &mut translation,
                &mut subspace,
                &mut bias,
            );
            black_box(&rotation);
        })
    });
    group.finish();
}

criterion_group!(benches, bench_barriers, bench_dynamics, bench_model_terms);
criterion_main!(benches);
