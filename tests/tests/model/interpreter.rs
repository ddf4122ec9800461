//! The interpreted model (`softcbf_interpreter::interpreted`) against the compiled one: every
//! trait function of every compiled model at random states and near the small-θ switch
//! points, bit for bit; its analytic functions against the emitted series; a closed loop.

use std::collections::HashMap;

use rand::RngExt;
use softcbf::model::{Model, ModelError};
use softcbf::robot_file::load_robot;
use softcbf::scenario::ScenarioFile;
use softcbf::sim::simulate;
use softcbf_codegen::analytic::{MAX_ORDER, SWITCH_POINTS};
use softcbf_codegen::registry;
use softcbf_description::robot::{Robot, Structure};
use softcbf_generated::{GeneratedModel, MODELS};
use softcbf_interpreter::interpreted;
use softcbf_tests::alloc::allocations;
use softcbf_tests::{TestRng, analytic::pcc_fs_fc_6};

/// The structure of every compiled model: the shipped robot files, the registered ones and
/// the benchmark structures, by key.
fn structures() -> HashMap<String, Structure> {
    let robots = softcbf_tests::robots::path("");
    let mut files = registry::shipped(&robots);
    if let Ok(entries) = registry::read(&robots.join(registry::REGISTRY_FILE)) {
        files.extend(entries.into_iter().map(|e| e.path));
    }
    let mut all: HashMap<String, Structure> = files
        .iter()
        .filter_map(|path| Robot::load(path).ok())
        .map(|robot| (robot.structure().key(), robot.structure()))
        .collect();
    for (_, structure) in registry::benchmarks() {
        all.insert(structure.key(), structure);
    }
    all
}

/// A parameter vector of plausible size for each named parameter.
fn params(model: &dyn GeneratedModel, rng: &mut TestRng) -> Vec<f64> {
    model
        .param_names()
        .iter()
        .map(|name| {
            let (low, high) = match name {
                n if n.starts_with("rest_length") => (0.05, 0.12),
                n if n.starts_with("tendon_radius") => (0.01, 0.03),
                n if n.starts_with("corner_radius") => (0.03, 0.06),
                n if n.starts_with("corner_cos") || n.starts_with("corner_sin") => (-1.0, 1.0),
                n if n.starts_with("max_bend") => (0.5, 1.5),
                n if n.contains("_arc_") => (0.1, 1.0),
                n if n.contains("normal") || n.contains("center") || n.contains("point") => {
                    (-0.3, 0.3)
                }
                _ => (0.001, 0.05),
            };
            rng.random_range(low..high)
        })
        .collect()
}

/// The bend angles θ (u = θ²) a state is drawn at: tiny bends, both sides of every switch
/// point `U_k` (also 1 ulp-scale and 1e-6 relative away), and plain random bends.
fn bend_angles(rng: &mut TestRng) -> Vec<f64> {
    let mut angles = vec![0.0, 1e-300, 1e-12, 1e-8, 1e-6, 1e-4, 1e-3, 1e-2];
    for &u in &SWITCH_POINTS {
        for relative in [-1e-6, -1e-15, 0.0, 1e-15, 1e-6] {
            angles.push((u * (1.0 + relative)).sqrt());
        }
    }
    for _ in 0..200 {
        angles.push(10f64.powf(rng.random_range(-9.0..0.5)));
    }
    angles
}

/// A state with every module bent by `theta` (jittered per module) in a random direction.
fn state(
    model: &dyn GeneratedModel,
    p: &[f64],
    theta: f64,
    rng: &mut TestRng,
) -> (Vec<f64>, Vec<f64>) {
    let mut q = Vec::new();
    for i in 0..model.n_modules() {
        let radius = p[model
            .param_names()
            .iter()
            .position(|n| *n == format!("tendon_radius_{i}"))
            .expect("every module has a tendon radius")];
        let angle = if i == 0 {
            theta
        } else {
            theta * rng.random_range(0.5..1.5)
        };
        let direction: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        q.extend([
            angle * radius * direction.cos(),
            angle * radius * direction.sin(),
            rng.random_range(-0.01..0.01),
        ]);
    }
    let qd = (0..q.len()).map(|_| rng.random_range(-0.5..0.5)).collect();
    (q, qd)
}

/// Every output of every trait function at one state, in a fixed order.
fn outputs(
    model: &dyn GeneratedModel,
    p: &[f64],
    q: &[f64],
    qd: &[f64],
) -> Vec<(&'static str, f64)> {
    let (n, nq, nb) = (model.n_modules(), model.nq(), model.nb());
    let mut out = Vec::new();
    let mut transforms = vec![[[0.0; 4]; 4]; n];
    model.segment_transforms(p, q, &mut transforms);
    out.extend(
        transforms
            .iter()
            .flatten()
            .flatten()
            .map(|&v| ("segment_transforms", v)),
    );
    model.plate_poses(p, q, &mut transforms);
    out.extend(
        transforms
            .iter()
            .flatten()
            .flatten()
            .map(|&v| ("plate_poses", v)),
    );
    let mut b = vec![0.0; nb];
    model.barriers(p, q, &mut b);
    out.extend(b.iter().map(|&v| ("barriers", v)));
    let (mut jacobian, mut jdot) = (vec![0.0; nb * nq], vec![0.0; nb]);
    model.barrier_terms(p, q, qd, &mut b, &mut jacobian, &mut jdot);
    for values in [&b, &jacobian, &jdot] {
        out.extend(values.iter().map(|&v| ("barrier_terms", v)));
    }
    let mut rotation = vec![[[0.0; 3]; 3]; n];
    let mut translation = vec![[0.0; 3]; n];
    let mut subspace = vec![[[0.0; 3]; 6]; n];
    let mut bias = vec![[0.0; 6]; n];
    model.joint_terms(
        p,
        q,
        qd,
        &mut rotation,
        &mut translation,
        &mut subspace,
        &mut bias,
    );
    let joint = |out: &mut Vec<(&'static str, f64)>,
                 name,
                 r: &[[[f64; 3]; 3]],
                 t: &[[f64; 3]],
                 s: &[[[f64; 3]; 6]],
                 c: &[[f64; 6]]| {
        out.extend(r.iter().flatten().flatten().map(|&v| (name, v)));
        out.extend(t.iter().flatten().map(|&v| (name, v)));
        out.extend(s.iter().flatten().flatten().map(|&v| (name, v)));
        out.extend(c.iter().flatten().map(|&v| (name, v)));
    };
    joint(
        &mut out,
        "joint_terms",
        &rotation,
        &translation,
        &subspace,
        &bias,
    );
    model.model_terms(
        p,
        q,
        qd,
        &mut rotation,
        &mut translation,
        &mut subspace,
        &mut bias,
        &mut b,
        &mut jacobian,
        &mut jdot,
    );
    joint(
        &mut out,
        "model_terms",
        &rotation,
        &translation,
        &subspace,
        &bias,
    );
    for values in [&b, &jacobian, &jdot] {
        out.extend(values.iter().map(|&v| ("model_terms", v)));
    }
    out
}

/// Every compiled model and its interpreted twin agree bit for bit on every output of every
/// function, at random states, tiny bends and both sides of each series switch point; the
/// tables and names agree too.
#[test]
fn interpreted_models_agree_with_the_compiled_ones() {
    let structures = structures();
    let mut rng = softcbf_tests::rng(0x1a7e_4b01);
    let mut checked = 0usize;
    let mut largest = 0.0f64;
    for &compiled in MODELS {
        let structure = structures
            .get(compiled.structure_key())
            .unwrap_or_else(|| panic!("{}: structure not found", compiled.name()));
        let model = interpreted(structure);
        assert_eq!(model.structure_key(), compiled.structure_key());
        assert_eq!(model.corners(), compiled.corners());
        assert_eq!(model.tendons(), compiled.tendons());
        assert_eq!(model.routing(), compiled.routing());
        assert_eq!(model.param_names(), compiled.param_names());
        assert_eq!(model.barrier_table(), compiled.barrier_table());
        for theta in bend_angles(&mut rng) {
            let p = params(compiled, &mut rng);
            let (q, qd) = state(compiled, &p, theta, &mut rng);
            let want = outputs(compiled, &p, &q, &qd);
            let got = outputs(model, &p, &q, &qd);
            assert_eq!(want.len(), got.len());
            for (k, (&(name, w), &(_, g))) in want.iter().zip(&got).enumerate() {
                let difference = (w - g).abs() / w.abs().max(g.abs()).max(f64::MIN_POSITIVE);
                if !difference.is_nan() {
                    largest = largest.max(difference);
                }
                assert!(
                    w.to_bits() == g.to_bits() || (w.is_nan() && g.is_nan()),
                    "{}: {name} output {k} at θ = {theta:e}, q = {q:?}: compiled {w:e}, \
                     interpreted {g:e}",
                    compiled.name()
                );
                checked += 1;
            }
        }
    }
    println!(
        "{} models, {checked} outputs compared: largest relative difference {largest:e}",
        MODELS.len()
    );
}

/// The run-time `f_s`, `f_c` (`softcbf_codegen::analytic::evaluate`) are the emitted
/// `pcc_fs_fc_6`'s bits, for every order it is asked for, on a log grid and both sides of
/// every switch point.
#[test]
fn run_time_analytic_functions_are_the_emitted_ones() {
    let mut points = vec![0.0, -1e-3, 1e-300, f64::NAN, f64::INFINITY];
    points.extend((0..=4000).map(|i| 10f64.powf(-14.0 + 17.0 * f64::from(i) / 4000.0)));
    for &u in &SWITCH_POINTS {
        for step in -3i64..=3 {
            points.push(f64::from_bits((u.to_bits() as i64 + step) as u64));
        }
    }
    for u in points {
        let (fs, fc) = pcc_fs_fc_6(u);
        for order in 0..=MAX_ORDER {
            let (s, c) = softcbf_codegen::analytic::evaluate(order, u);
            for k in 0..=order {
                for (want, got, name) in [(fs[k], s[k], "f_s"), (fc[k], c[k], "f_c")] {
                    assert!(
                        want.to_bits() == got.to_bits() || (want.is_nan() && got.is_nan()),
                        "{name}^({k}) at u = {u:e} (order {order}): emitted {want:e}, run time {got:e}"
                    );
                }
            }
        }
    }
}

/// A second call of an interpreted function allocates nothing (the value buffer is the
/// thread's, grown on first use), and a model is built once per structure.
#[test]
fn interpreted_calls_allocate_nothing_and_models_are_cached() {
    let structure = registry::every_barrier();
    let model = interpreted(&structure);
    assert!(std::ptr::addr_eq(model, interpreted(&structure)));
    let mut rng = softcbf_tests::rng(7);
    let p = params(model, &mut rng);
    let (q, qd) = state(model, &p, 0.3, &mut rng);
    let (n, nq, nb) = (model.n_modules(), model.nq(), model.nb());
    let mut rotation = vec![[[0.0; 3]; 3]; n];
    let mut translation = vec![[0.0; 3]; n];
    let mut subspace = vec![[[0.0; 3]; 6]; n];
    let mut bias = vec![[0.0; 6]; n];
    let (mut b, mut jacobian, mut jdot) = (vec![0.0; nb], vec![0.0; nb * nq], vec![0.0; nb]);
    let mut call = || {
        model.model_terms(
            &p,
            &q,
            &qd,
            &mut rotation,
            &mut translation,
            &mut subspace,
            &mut bias,
            &mut b,
            &mut jacobian,
            &mut jdot,
        )
    };
    call();
    let before = allocations();
    call();
    call();
    assert_eq!(allocations(), before, "model_terms allocated");
}

/// A generated model of another structure is refused by `Model::with_generated`.
#[test]
fn a_model_of_another_structure_is_refused() {
    let robot = load_robot(None).expect("embedded robot");
    let other = interpreted(&registry::every_barrier());
    match Model::with_generated(robot, other) {
        Err(ModelError::StructureMismatch { generated, .. }) => {
            assert_eq!(generated, "interpreted")
        }
        Err(e) => panic!("another error: {e}"),
        Ok(_) => panic!("a model of another structure was accepted"),
    }
}

/// The paper's closed loop for 1 s on the interpreted model follows the compiled one:
/// every recorded coordinate, velocity and command agrees.
#[test]
fn paper_closed_loop_on_the_interpreted_model() {
    let robot = load_robot(None).expect("embedded robot");
    let compiled = Model::new(robot.clone()).expect("paper model");
    let model = Model::with_generated(robot.clone(), interpreted(&robot.structure()))
        .expect("same structure");
    assert_eq!(model.generated.name(), "interpreted");
    let mut scenario = ScenarioFile::paper_sim()
        .resolve(&compiled)
        .expect("paper scenario");
    scenario.duration = 1.0;
    let want = simulate(&compiled, &scenario, true, &mut |_| {}).expect("compiled run");
    let got = simulate(&model, &scenario, true, &mut |_| {}).expect("interpreted run");
    assert_eq!(want.record.len(), got.record.len());
    assert!(want.summary.counts.active > 0, "the filter acted");
    let (mut state, mut command) = (0.0f64, 0.0f64);
    for (w, g) in want.record.rows().zip(got.record.rows()) {
        assert_eq!(w.t, g.t);
        for (a, b) in w.q.iter().chain(w.qd).zip(g.q.iter().chain(g.qd)) {
            state = state.max((a - b).abs());
        }
        for (a, b) in w.tau.iter().zip(g.tau) {
            command = command.max((a - b).abs());
        }
    }
    println!(
        "{} rows over 1 s: largest difference in q, q̇ {state:e}, in τ {command:e}",
        want.record.len()
    );
    assert!(
        state <= 1e-9 && command <= 1e-9,
        "state {state:e}, command {command:e}"
    );
}
