//! The runtime rigid-plate dynamics (`M`, `h = C q̇`, `G`, `K`, `D`, forward dynamics)
//! against the hand-written jets, finite differences and the identities of docs/model.md §4.

use rand::RngExt;
use softcbf::dynamics::{
    BarrierTerms, DynamicsError, DynamicsWorkspace, bias_and_gravity, elastic_energy,
    forward_dynamics, gravity_energy, kinetic_energy, mass_matrix, model_terms, nonlinear_effects,
    update_joints,
};
use softcbf::model::Model;
use softcbf_codegen::analytic::SWITCH_POINTS;
use softcbf_description::robot::{Module, Robot};
use softcbf_tests::TestRng;
use softcbf_tests::reference::{
    self, dynamics, paper_module, paper_robot, sample_module, sample_theta, stiffness_and_damping,
};

/// Runtime `M` (row-major), `h`, `G` at `(q, q̇)`.
struct Terms {
    mass: Vec<f64>,
    bias: Vec<f64>,
    gravity: Vec<f64>,
}

fn runtime_terms(model: &Model, ws: &mut DynamicsWorkspace, q: &[f64], qd: &[f64]) -> Terms {
    update_joints(model, ws, q, qd).unwrap();
    mass_matrix(model, ws).unwrap();
    bias_and_gravity(model, ws, qd).unwrap();
    Terms {
        mass: ws.mass_matrix.clone(),
        bias: ws.bias.clone(),
        gravity: ws.gravity.clone(),
    }
}

fn model_of(robot: Robot) -> Model {
    match Model::new(robot) {
        Ok(model) => model,
        Err(error) => panic!("{error}"),
    }
}

/// Modules that differ from each other (mass, inertia, lengths, stiffness), so that an
/// index mix-up between modules shows; `com_offset` for all of them.
fn modules(n: usize, com_offset: f64) -> Vec<Module> {
    (0..n)
        .map(|i| {
            let mut m = paper_module(com_offset);
            let f = 1.0 + 0.15 * i as f64;
            m.rest_length *= f;
            m.tendon_radius /= f;
            m.mass *= f * f;
            m.inertia = [m.inertia[0] * f, m.inertia[1] * f, m.inertia[2] * f * 1.3];
            m.bending_stiffness *= f;
            m.axial_stiffness /= f;
            m.bending_damping *= 1.0 + 0.5 * i as f64;
            m.axial_damping /= f;
            m.com_offset = com_offset * f;
            m
        })
        .collect()
}

/// A random state (bends from 0 to 3 rad, including 0 exactly, tiny and around the series
/// switch points) and velocity.
fn sample_state<const N: usize>(rng: &mut TestRng, robot: &Robot) -> ([f64; N], [f64; N]) {
    let mut q = [0.0; N];
    for (i, module) in robot.modules.iter().enumerate() {
        let theta = sample_theta(rng, &SWITCH_POINTS).min(3.0);
        q[3 * i..3 * i + 3].copy_from_slice(&sample_module(rng, module, theta));
    }
    (q, std::array::from_fn(|_| rng.random_range(-0.5..0.5)))
}

fn max_abs<'a>(x: impl IntoIterator<Item = &'a f64>) -> f64 {
    x.into_iter().fold(0.0, |m, v| m.max(v.abs()))
}

/// The docs/model.md §8 test `|got − exact| ≤ 1e-12·s + 1e-9·|exact|`, as a ratio to the bound.
fn bound_ratio(got: f64, exact: f64, s: f64) -> f64 {
    (got - exact).abs() / (1e-12 * s + 1e-9 * exact.abs())
}

/// Cholesky pivots of a row-major symmetric matrix (all positive iff positive definite).
fn cholesky_pivots(a: &[f64], n: usize) -> Vec<f64> {
    let mut l = vec![0.0; n * n];
    let mut pivots = Vec::new();
    for j in 0..n {
        let diagonal = a[j * n + j] - (0..j).map(|k| l[j * n + k] * l[j * n + k]).sum::<f64>();
        pivots.push(diagonal);
        let root = diagonal.max(0.0).sqrt();
        l[j * n + j] = root;
        for i in j + 1..n {
            let sum = a[i * n + j] - (0..j).map(|k| l[i * n + k] * l[j * n + k]).sum::<f64>();
            l[i * n + j] = sum / root;
        }
    }
    pivots
}

fn check_symmetric_positive_definite<const N: usize>(robot: Robot, seed: u64, trials: usize) {
    let model = model_of(robot.clone());
    let mut ws = DynamicsWorkspace::new(&model);
    let mut rng = softcbf_tests::rng(seed);
    for trial in 0..trials {
        let (q, qd) = if trial == 0 {
            ([0.0; N], [0.0; N])
        } else {
            sample_state::<N>(&mut rng, &robot)
        };
        let terms = runtime_terms(&model, &mut ws, &q, &qd);
        let m = &terms.mass;
        let scale = max_abs(m);
        for i in 0..N {
            for j in 0..N {
                assert!(
                    (m[i * N + j] - m[j * N + i]).abs() <= 1e-15 * scale,
                    "q = {q:?}: M not symmetric at ({i}, {j})"
                );
            }
        }
        let pivots = cholesky_pivots(m, N);
        // Positive definite with margin: the smallest pivot is far above rounding.
        let smallest = pivots.iter().fold(f64::INFINITY, |a, &b| a.min(b));
        assert!(
            smallest > 1e-10 * scale,
            "q = {q:?}: Cholesky pivots {pivots:?}"
        );
    }
}

/// `M = Mᵀ ≻ 0` for 1, 2 and 4 modules, at `q = 0` and random states up to 3 rad.
#[test]
fn mass_matrix_symmetric_positive_definite() {
    check_symmetric_positive_definite::<3>(paper_robot(modules(1, 0.0)), 11, 500);
    check_symmetric_positive_definite::<6>(paper_robot(modules(2, 0.01)), 12, 500);
    check_symmetric_positive_definite::<12>(paper_robot(modules(4, 0.0)), 13, 300);
}

/// Runtime `M`, `h`, `G`, `T`, `U_g` against the jets at random states, to the §8 bound.
fn check_against_reference<const N: usize>(robot: Robot, seed: u64, trials: usize) -> f64 {
    let model = model_of(robot.clone());
    let mut ws = DynamicsWorkspace::new(&model);
    let mut rng = softcbf_tests::rng(seed);
    let mut worst = 0.0_f64;
    for trial in 0..trials {
        let (q, qd) = sample_state::<N>(&mut rng, &robot);
        let terms = runtime_terms(&model, &mut ws, &q, &qd);
        let exact = dynamics(&robot, &q, &qd);
        let ctx = || format!("trial {trial}, q = {q:?}, qd = {qd:?}");
        let s_m = max_abs(exact.mass_matrix.iter().flatten());
        for i in 0..N {
            for j in 0..N {
                let (got, want) = (terms.mass[i * N + j], exact.mass_matrix[i][j]);
                let ratio = bound_ratio(got, want, s_m);
                worst = worst.max(ratio);
                assert!(
                    ratio <= 1.0,
                    "{}: M[{i}][{j}] = {got:e}, reference {want:e}",
                    ctx()
                );
            }
        }
        let (s_h, s_g) = (max_abs(&exact.bias), max_abs(&exact.gravity));
        for i in 0..N {
            let ratio = bound_ratio(terms.bias[i], exact.bias[i], s_h);
            worst = worst.max(ratio);
            assert!(
                ratio <= 1.0,
                "{}: h[{i}] = {:e}, reference {:e}",
                ctx(),
                terms.bias[i],
                exact.bias[i]
            );
            let ratio = bound_ratio(terms.gravity[i], exact.gravity[i], s_g);
            worst = worst.max(ratio);
            assert!(
                ratio <= 1.0,
                "{}: G[{i}] = {:e}, reference {:e}",
                ctx(),
                terms.gravity[i],
                exact.gravity[i]
            );
        }
        // Energies: T from the runtime's body twists, U_g from its own chain.
        let t = kinetic_energy(&model, &ws).unwrap();
        assert!(
            bound_ratio(t, exact.kinetic_energy, exact.kinetic_energy) <= 1.0,
            "{}: T",
            ctx()
        );
        let quadratic: f64 = (0..N)
            .map(|i| {
                (0..N)
                    .map(|j| qd[i] * exact.mass_matrix[i][j] * qd[j])
                    .sum::<f64>()
            })
            .sum();
        assert!((0.5 * quadratic - exact.kinetic_energy).abs() <= 1e-13 * exact.kinetic_energy);
        let u = gravity_energy(&model, &ws).unwrap();
        assert!(
            (u - exact.gravity_energy).abs() <= 1e-13 * exact.gravity_energy.abs().max(1e-3),
            "{}: U_g = {u:e}, reference {:e}",
            ctx(),
            exact.gravity_energy
        );
    }
    worst
}

/// `M` (and `h`, `G`) against `Σ m Jvᵀ Jv + Jωᵀ R I Rᵀ Jω` from the jets: one module
/// (hex_1) and two (paper_sim), COM offset zero and non-zero; also four modules.
#[test]
fn dynamics_against_hand_written_reference() {
    let names = [1, 2, 4].map(|n| model_of(paper_robot(modules(n, 0.0))).generated.name());
    assert_eq!(names, ["hex_1", "paper_sim", "hex_4"]);
    let mut worst = 0.0_f64;
    for offset in [0.0, 0.02, -0.013] {
        worst = worst.max(check_against_reference::<3>(
            paper_robot(modules(1, offset)),
            21,
            400,
        ));
        worst = worst.max(check_against_reference::<6>(
            paper_robot(modules(2, offset)),
            22,
            400,
        ));
    }
    worst = worst.max(check_against_reference::<12>(
        paper_robot(modules(4, 0.01)),
        23,
        100,
    ));
    eprintln!("M, h, G: worst error {worst:.2e} × the §8 bound");
}

/// `∂M/∂q_k` by central differences of the runtime `M`, for every `k`.
fn mass_derivatives(
    model: &Model,
    ws: &mut DynamicsWorkspace,
    q: &[f64],
    step: f64,
) -> Vec<Vec<f64>> {
    let zero = vec![0.0; q.len()];
    (0..q.len())
        .map(|k| {
            let mut plus = q.to_vec();
            let mut minus = q.to_vec();
            plus[k] += step;
            minus[k] -= step;
            let mp = runtime_terms(model, ws, &plus, &zero).mass;
            let mm = runtime_terms(model, ws, &minus, &zero).mass;
            mp.iter()
                .zip(&mm)
                .map(|(a, b)| (a - b) / (2.0 * step))
                .collect()
        })
        .collect()
}

fn check_bias<const N: usize>(robot: Robot, seed: u64, trials: usize) {
    let model = model_of(robot.clone());
    let mut ws = DynamicsWorkspace::new(&model);
    let mut rng = softcbf_tests::rng(seed);
    // Step ~1e-5 of the tendon radius: truncation (~step²/d²) and rounding (~eps·d/step)
    // both near 1e-9 of |∂M|.
    let step = 1e-5 * robot.modules[0].tendon_radius;
    for trial in 0..trials {
        let (q, qd) = sample_state::<N>(&mut rng, &robot);
        let h = runtime_terms(&model, &mut ws, &q, &qd).bias;
        let dm = mass_derivatives(&model, &mut ws, &q, step);
        let s_dm = max_abs(dm.iter().flatten());
        let qd_sum: f64 = qd.iter().map(|x| x.abs()).sum();
        let tol = 1e-7 * s_dm * qd_sum * qd_sum;
        // Christoffel: h_i = Σ_jk (∂M_ij/∂q_k − ½ ∂M_jk/∂q_i) q̇_j q̇_k.
        for i in 0..N {
            let mut christoffel = 0.0;
            for j in 0..N {
                for k in 0..N {
                    christoffel += (dm[k][i * N + j] - 0.5 * dm[i][j * N + k]) * qd[j] * qd[k];
                }
            }
            assert!(
                (h[i] - christoffel).abs() <= tol,
                "trial {trial}, q = {q:?}, qd = {qd:?}: h[{i}] = {:e}, Christoffel {christoffel:e}",
                h[i]
            );
        }
        // q̇ᵀ h = ½ q̇ᵀ Ṁ q̇, Ṁ by central differences along q̇.
        let zero = [0.0; N];
        let along = |s: f64| -> [f64; N] { std::array::from_fn(|k| q[k] + s * qd[k]) };
        let mp = runtime_terms(&model, &mut ws, &along(step), &zero).mass;
        let mm = runtime_terms(&model, &mut ws, &along(-step), &zero).mass;
        let mut power = 0.0;
        for i in 0..N {
            for j in 0..N {
                power += 0.5 * qd[i] * (mp[i * N + j] - mm[i * N + j]) / (2.0 * step) * qd[j];
            }
        }
        let qdh: f64 = (0..N).map(|i| qd[i] * h[i]).sum();
        assert!(
            (qdh - power).abs() <= tol * qd_sum,
            "trial {trial}, q = {q:?}, qd = {qd:?}: q̇ᵀh = {qdh:e}, ½q̇ᵀṀq̇ = {power:e}"
        );
    }
}

/// `h = C q̇` against the Christoffel formula with `∂M` by central differences, and the
/// power identity `q̇ᵀ h = ½ q̇ᵀ Ṁ q̇`.
#[test]
fn bias_matches_christoffel_symbols() {
    check_bias::<3>(paper_robot(modules(1, 0.02)), 31, 200);
    check_bias::<6>(paper_robot(modules(2, 0.0)), 32, 200);
    check_bias::<6>(paper_robot(modules(2, -0.015)), 33, 200);
}

fn check_gravity<const N: usize>(robot: Robot, seed: u64, trials: usize) {
    let model = model_of(robot.clone());
    let mut ws = DynamicsWorkspace::new(&model);
    let mut rng = softcbf_tests::rng(seed);
    let step = 1e-5 * robot.modules[0].tendon_radius;
    let zero = [0.0; N];
    for trial in 0..trials {
        let (q, _) = sample_state::<N>(&mut rng, &robot);
        let g = runtime_terms(&model, &mut ws, &q, &zero).gravity;
        let scale = max_abs(&g).max(robot.modules.iter().map(|m| m.mass * 9.81).sum());
        for k in 0..N {
            let mut plus = q;
            let mut minus = q;
            plus[k] += step;
            minus[k] -= step;
            update_joints(&model, &mut ws, &plus, &zero).unwrap();
            let up = gravity_energy(&model, &ws).unwrap();
            update_joints(&model, &mut ws, &minus, &zero).unwrap();
            let um = gravity_energy(&model, &ws).unwrap();
            let fd_runtime = (up - um) / (2.0 * step);
            let fd_reference = (dynamics(&robot, &plus, &zero).gravity_energy
                - dynamics(&robot, &minus, &zero).gravity_energy)
                / (2.0 * step);
            for (what, fd) in [("runtime U_g", fd_runtime), ("reference U_g", fd_reference)] {
                assert!(
                    (g[k] - fd).abs() <= 1e-7 * scale,
                    "trial {trial}, q = {q:?}: G[{k}] = {:e}, ∂({what})/∂q = {fd:e}",
                    g[k]
                );
            }
        }
    }
}

/// `G = ∇U_g` by central differences of the runtime's and the reference's `U_g`.
#[test]
fn gravity_is_gradient_of_potential() {
    check_gravity::<3>(paper_robot(modules(1, 0.02)), 41, 300);
    check_gravity::<6>(paper_robot(modules(2, 0.0)), 42, 300);
    let mut tilted = paper_robot(modules(2, 0.01));
    tilted.gravity = [1.5, -2.0, -9.0];
    check_gravity::<6>(tilted, 43, 300);
}

/// `K_i = diag(κθ/d², κθ/d², κL)`, `D_i = diag(βθ/d², βθ/d², βL)`; `U_e = Σ ½(κθ u + κL δL²)`
/// and `K q = ∇U_e` (central differences).
#[test]
fn stiffness_and_damping_diagonals() {
    let robot = paper_robot(modules(2, 0.0));
    let model = model_of(robot.clone());
    let (k_all, d_all) = stiffness_and_damping(&robot);
    for i in 0..robot.modules.len() {
        let k = &k_all[3 * i..3 * i + 3];
        let d = &d_all[3 * i..3 * i + 3];
        for c in 0..3 {
            let (ks, ds) = (model.stiffness[3 * i + c], model.damping[3 * i + c]);
            assert!(
                (ks - k[c]).abs() <= 1e-15 * k[c],
                "K[{i}][{c}] = {ks}, expected {}",
                k[c]
            );
            assert!(
                (ds - d[c]).abs() <= 1e-15 * d[c],
                "D[{i}][{c}] = {ds}, expected {}",
                d[c]
            );
        }
    }
    // The paper's numbers (docs/model.md §7): κθ/d² = 6250 N/m, βθ/d² = 3125 N·s/m.
    let paper = model_of(paper_robot(vec![paper_module(0.0), paper_module(0.0)]));
    assert!((paper.stiffness[0] - 6250.0).abs() < 1e-9 && (paper.damping[1] - 3125.0).abs() < 1e-9);
    let mut rng = softcbf_tests::rng(51);
    for _ in 0..200 {
        let (q, _) = sample_state::<6>(&mut rng, &robot);
        let energy: f64 = robot
            .modules
            .iter()
            .enumerate()
            .map(|(i, m)| {
                let u = (q[3 * i].powi(2) + q[3 * i + 1].powi(2)) / m.tendon_radius.powi(2);
                0.5 * (m.bending_stiffness * u + m.axial_stiffness * q[3 * i + 2].powi(2))
            })
            .sum();
        let got = elastic_energy(&model, &q).unwrap();
        assert!(
            (got - energy).abs() <= 1e-14 * energy.max(1e-300),
            "U_e = {got}, expected {energy}"
        );
        for k in 0..6 {
            let step = 1e-6;
            let mut plus = q;
            let mut minus = q;
            plus[k] += step;
            minus[k] -= step;
            let fd = (elastic_energy(&model, &plus).unwrap()
                - elastic_energy(&model, &minus).unwrap())
                / (2.0 * step);
            let kq = model.stiffness[k] * q[k];
            assert!(
                (fd - kq).abs() <= 1e-8 * model.stiffness[k],
                "(K q)[{k}] = {kq}, ∇U_e = {fd}"
            );
        }
    }
}

/// The even part `½(f(q0 + εe) + f(q0 − εe))` of an analytic `f` around the straight
/// configuration `q0` is `f(q0) + ε² A + O(ε⁴)`; `A` is estimated at `ε_a = 1e-3·d`.
/// The odd part, whose first-order change can be ~1e-6 relative at θ = 1e-6, cancels
/// exactly, and `ε² A` is kept, so what is left is O(ε⁴) plus rounding: the values at
/// θ = 1e-12 and 1e-6 must then agree with the value at θ = 0 to ~1e-12.
fn check_continuity<const N: usize>(robot: Robot, seed: u64, trials: usize) {
    let model = model_of(robot.clone());
    let mut ws = DynamicsWorkspace::new(&model);
    let mut rng = softcbf_tests::rng(seed);
    for trial in 0..trials {
        let mut q0 = [0.0; N];
        let mut direction = [0.0; N];
        for (i, m) in robot.modules.iter().enumerate() {
            q0[3 * i + 2] = if trial == 0 {
                0.0
            } else {
                rng.random_range(-0.05..0.05)
            };
            let alpha: f64 = if trial == 0 {
                0.0
            } else {
                rng.random_range(-3.2..3.2)
            };
            direction[3 * i] = m.tendon_radius * alpha.cos();
            direction[3 * i + 1] = m.tendon_radius * alpha.sin();
        }
        let qd: [f64; N] = std::array::from_fn(|_| rng.random_range(-0.5..0.5));
        let even = |ws: &mut DynamicsWorkspace, theta: f64| -> Vec<f64> {
            let plus: [f64; N] = std::array::from_fn(|k| q0[k] + theta * direction[k]);
            let minus: [f64; N] = std::array::from_fn(|k| q0[k] - theta * direction[k]);
            let a = runtime_terms(&model, ws, &plus, &qd);
            let b = runtime_terms(&model, ws, &minus, &qd);
            let flat = |t: Terms| [t.mass, t.bias, t.gravity].concat();
            flat(a)
                .iter()
                .zip(flat(b))
                .map(|(x, y)| 0.5 * (x + y))
                .collect()
        };
        let at_zero = even(&mut ws, 0.0);
        let theta_a = 1e-3;
        let curvature: Vec<f64> = even(&mut ws, theta_a)
            .iter()
            .zip(&at_zero)
            .map(|(x, x0)| (x - x0) / (theta_a * theta_a))
            .collect();
        let groups = [
            ("M", 0..N * N),
            ("h", N * N..N * N + N),
            ("G", N * N + N..N * N + 2 * N),
        ];
        for theta in [1e-12, 1e-6] {
            let value = even(&mut ws, theta);
            for (name, range) in groups.clone() {
                let scale = max_abs(&at_zero[range.clone()]);
                for k in range {
                    let predicted = at_zero[k] + theta * theta * curvature[k];
                    assert!(
                        (value[k] - predicted).abs() <= 1e-12 * scale,
                        "q0 = {q0:?}, θ = {theta:e} along {direction:?}: {name} element {k}: \
                         even part {:e}, limit {:e} (+ θ² term {:e})",
                        value[k],
                        at_zero[k],
                        theta * theta * curvature[k]
                    );
                }
            }
            // One-sided: the value at +θ itself is within first order of the limit.
            let plus: [f64; N] = std::array::from_fn(|k| q0[k] + theta * direction[k]);
            let t = runtime_terms(&model, &mut ws, &plus, &qd);
            let one_sided = [t.mass, t.bias, t.gravity].concat();
            for (name, range) in groups.clone() {
                let scale = max_abs(&at_zero[range.clone()]);
                for k in range {
                    assert!(
                        (one_sided[k] - at_zero[k]).abs() <= 10.0 * theta * scale + 1e-14 * scale,
                        "q0 = {q0:?}, θ = {theta:e}: {name} element {k} jumps: {:e} vs {:e}",
                        one_sided[k],
                        at_zero[k]
                    );
                }
            }
        }
    }
}

/// `M`, `h`, `G` at θ = 0, 1e-12, 1e-6 agree with their limits (see [`check_continuity`]).
#[test]
fn continuity_through_straight_configuration() {
    check_continuity::<3>(paper_robot(modules(1, 0.01)), 61, 40);
    check_continuity::<6>(paper_robot(modules(2, 0.0)), 62, 40);
}

/// Non-finite inputs give `Err(NonFinite)` (no panic) and a NaN-filled `q̈`.
#[test]
fn forward_dynamics_rejects_non_finite_input() {
    let model = model_of(paper_robot(modules(2, 0.0)));
    let mut ws = DynamicsWorkspace::new(&model);
    let good = [0.01, -0.02, 0.005, 0.0, 0.03, -0.01];
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        for which in 0..3 {
            for k in [0, 2, 5] {
                let (mut q, mut qd, mut tau) = (good, good, good);
                [&mut q, &mut qd, &mut tau][which][k] = bad;
                let mut qdd = [0.0; 6];
                let result = forward_dynamics(&model, &mut ws, &q, &qd, &tau, &mut qdd);
                assert_eq!(
                    result,
                    Err(DynamicsError::NonFinite),
                    "input {which}[{k}] = {bad}"
                );
                assert!(qdd.iter().all(|x| x.is_nan()));
            }
        }
    }
    // And the workspace still works afterwards.
    let mut qdd = [0.0; 6];
    assert!(forward_dynamics(&model, &mut ws, &good, &good, &good, &mut qdd).is_ok());
}

fn check_forward_dynamics<const N: usize>(robot: Robot, seed: u64, trials: usize) {
    let model = model_of(robot.clone());
    let mut ws = DynamicsWorkspace::new(&model);
    let mut rng = softcbf_tests::rng(seed);
    // K and D written from docs/model.md §4, not read from the model.
    let (k_diag, d_diag) = stiffness_and_damping(&robot);
    for trial in 0..trials {
        let (q, qd) = sample_state::<N>(&mut rng, &robot);
        let tau: [f64; N] = std::array::from_fn(|_| rng.random_range(-5.0..5.0));
        let mut qdd = [0.0; N];
        let result = forward_dynamics(&model, &mut ws, &q, &qd, &tau, &mut qdd);
        assert!(result.is_ok(), "trial {trial}, q = {q:?}: {result:?}");
        let exact = dynamics(&robot, &q, &qd);
        // Against the workspace's own M and h + G (the solve), then against the jets (all).
        let runtime_m = ws.mass_matrix.clone();
        let sources = [
            ("runtime", runtime_m, ws.nonlinear.clone(), vec![0.0; N]),
            (
                "reference",
                exact.mass_matrix.iter().flatten().copied().collect(),
                exact.bias.to_vec(),
                exact.gravity.to_vec(),
            ),
        ];
        for (what, m, h, g) in sources {
            let mut scale = 0.0_f64;
            for i in 0..N {
                let m_qdd: f64 = (0..N).map(|j| m[i * N + j] * qdd[j]).sum();
                let parts = [
                    tau[i],
                    h[i],
                    g[i],
                    k_diag[i] * q[i],
                    d_diag[i] * qd[i],
                    m_qdd,
                ];
                scale = scale.max(max_abs(&parts));
            }
            for i in 0..N {
                let m_qdd: f64 = (0..N).map(|j| m[i * N + j] * qdd[j]).sum();
                let rhs = tau[i] - h[i] - g[i] - k_diag[i] * q[i] - d_diag[i] * qd[i];
                assert!(
                    (m_qdd - rhs).abs() <= 1e-12 * scale,
                    "trial {trial}, q = {q:?}, qd = {qd:?}: ({what} M q̈)[{i}] = {m_qdd:e}, \
                     τ − h − G − Kq − Dq̇ = {rhs:e}"
                );
            }
        }
    }
}

/// `M q̈ = τ − h − G − K q − D q̇` to 1e-12 relative, with `K`, `D` from docs/model.md §4.
#[test]
fn forward_dynamics_satisfies_equation_of_motion() {
    check_forward_dynamics::<3>(paper_robot(modules(1, 0.01)), 71, 300);
    check_forward_dynamics::<6>(paper_robot(modules(2, 0.0)), 72, 300);
    check_forward_dynamics::<12>(paper_robot(modules(4, 0.02)), 73, 100);
    // The paper's own robot (identical modules).
    let paper = paper_robot(vec![
        reference::paper_module(0.0),
        reference::paper_module(0.0),
    ]);
    check_forward_dynamics::<6>(paper, 74, 300);
}

/// The single RNEA pass with the base accelerating against gravity gives `h + G` as the
/// two separate passes do (the sum is linear in the base acceleration).
#[test]
fn nonlinear_effects_are_bias_plus_gravity() {
    let robot = paper_robot(modules(2, 0.01));
    let model = model_of(robot.clone());
    let mut ws = DynamicsWorkspace::new(&model);
    let mut rng = softcbf_tests::rng(77);
    for _ in 0..200 {
        let (q, qd) = sample_state::<6>(&mut rng, &robot);
        update_joints(&model, &mut ws, &q, &qd).unwrap();
        bias_and_gravity(&model, &mut ws, &qd).unwrap();
        let sum: Vec<f64> = ws
            .bias
            .iter()
            .zip(&ws.gravity)
            .map(|(h, g)| h + g)
            .collect();
        ws.nonlinear.fill(f64::NAN);
        nonlinear_effects(&model, &mut ws, &qd).expect("sizes of the model");
        let scale = 1.0 + max_abs(&sum);
        for (a, b) in ws.nonlinear.iter().zip(&sum) {
            assert!((a - b).abs() <= 1e-13 * scale, "{a} vs {b}");
        }
    }
}

/// `model_terms` (one generated evaluation) gives the `M`, `h`, `G` of the separate stages
/// and the generated barrier terms, exactly: the same kernels on the same joint terms.
#[test]
fn model_terms_are_the_stages_and_the_barrier_terms() {
    for (robot, seed) in [
        (paper_robot(modules(1, 0.01)), 81),
        (paper_robot(modules(2, 0.0)), 82),
        (paper_robot(modules(4, 0.02)), 83),
    ] {
        let model = model_of(robot.clone());
        let (nq, nb) = (model.nq(), model.nb());
        let mut fused = DynamicsWorkspace::new(&model);
        let mut staged = DynamicsWorkspace::new(&model);
        let mut barriers = BarrierTerms::new(&model);
        let (mut b, mut jacobian, mut jdot_qd) = (vec![0.0; nb], vec![0.0; nb * nq], vec![0.0; nb]);
        let mut rng = softcbf_tests::rng(seed);
        for _ in 0..50 {
            let (q, qd): (Vec<f64>, Vec<f64>) = match nq {
                3 => {
                    let (q, qd) = sample_state::<3>(&mut rng, &robot);
                    (q.to_vec(), qd.to_vec())
                }
                6 => {
                    let (q, qd) = sample_state::<6>(&mut rng, &robot);
                    (q.to_vec(), qd.to_vec())
                }
                _ => {
                    let (q, qd) = sample_state::<12>(&mut rng, &robot);
                    (q.to_vec(), qd.to_vec())
                }
            };
            model_terms(&model, &mut fused, &mut barriers, &q, &qd).expect("sizes of the model");
            let expected = runtime_terms(&model, &mut staged, &q, &qd);
            assert_eq!(fused.mass_matrix, expected.mass);
            assert_eq!(fused.bias, expected.bias);
            assert_eq!(fused.gravity, expected.gravity);
            assert_eq!(fused.nonlinear, staged.nonlinear);
            assert_eq!(
                kinetic_energy(&model, &fused).unwrap(),
                kinetic_energy(&model, &staged).unwrap()
            );
            assert_eq!(
                gravity_energy(&model, &fused).unwrap(),
                gravity_energy(&model, &staged).unwrap()
            );
            model.generated.barrier_terms(
                &model.params,
                &q,
                &qd,
                &mut b,
                &mut jacobian,
                &mut jdot_qd,
            );
            assert_eq!(barriers.values(), b.as_slice());
            assert_eq!(barriers.jacobian(), jacobian.as_slice());
            assert_eq!(barriers.jdot_qd(), jdot_qd.as_slice());
        }
    }
}

/// A wrong length is a size error naming the argument, never `NonFinite` or a panic, and
/// leaves the workspace usable.
#[test]
fn wrong_lengths_are_size_errors() {
    let model = model_of(paper_robot(modules(2, 0.0)));
    let other = model_of(paper_robot(modules(1, 0.0)));
    let mut ws = DynamicsWorkspace::new(&model);
    let mut barriers = BarrierTerms::new(&model);
    let good = [0.01, -0.02, 0.005, 0.0, 0.03, -0.01];
    let short = [0.0; 5];
    let size = |what: &'static str, expected: usize, got: usize| {
        Err(DynamicsError::Size {
            what,
            expected,
            got,
        })
    };
    assert_eq!(
        model_terms(&model, &mut ws, &mut barriers, &short, &good),
        size("q", 6, 5)
    );
    assert_eq!(
        model_terms(&model, &mut ws, &mut barriers, &good, &[0.0; 7]),
        size("q̇", 6, 7)
    );
    let mut qdd = [0.0; 6];
    assert_eq!(
        forward_dynamics(&model, &mut ws, &good, &good, &short, &mut qdd),
        size("τ", 6, 5)
    );
    assert_eq!(
        forward_dynamics(&model, &mut ws, &good, &good, &good, &mut [0.0; 3]),
        size("q̈", 6, 3)
    );
    assert_eq!(
        forward_dynamics(&model, &mut ws, &short, &good, &good, &mut qdd),
        size("q", 6, 5)
    );
    assert_eq!(nonlinear_effects(&model, &mut ws, &short), size("q̇", 6, 5));
    // A workspace or barrier storage built for another model.
    let mut other_ws = DynamicsWorkspace::new(&other);
    let mut other_barriers = BarrierTerms::new(&other);
    assert_eq!(
        model_terms(&model, &mut other_ws, &mut barriers, &good, &good),
        size("workspace modules", 2, 1)
    );
    assert!(matches!(
        model_terms(&model, &mut ws, &mut other_barriers, &good, &good),
        Err(DynamicsError::Size { .. })
    ));
    // The separate stages and the energies check the same way.
    assert_eq!(
        update_joints(&model, &mut ws, &short, &good),
        size("q", 6, 5)
    );
    assert_eq!(
        mass_matrix(&model, &mut other_ws),
        size("workspace modules", 2, 1)
    );
    assert_eq!(bias_and_gravity(&model, &mut ws, &short), size("q̇", 6, 5));
    assert!(matches!(
        kinetic_energy(&model, &other_ws),
        Err(DynamicsError::Size { .. })
    ));
    assert!(matches!(
        elastic_energy(&model, &short),
        Err(DynamicsError::Size { .. })
    ));
    // And the right lengths work afterwards.
    assert!(model_terms(&model, &mut ws, &mut barriers, &good, &good).is_ok());
    assert!(forward_dynamics(&model, &mut ws, &good, &good, &good, &mut qdd).is_ok());
}
