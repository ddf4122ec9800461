//! The generated kinematics (segment transforms, plate poses, barriers, their Jacobians and
//! `J̇q̇`, joint terms) against the hand-written jets, double-double series and quadrature.

use rand::RngExt;
use softcbf_codegen::analytic::SWITCH_POINTS;
use softcbf_description::layout::pack_params;
use softcbf_description::robot::{Module, Robot};
use softcbf_generated::{hex_4, paper_sim};
use softcbf_tests::TestRng;
use softcbf_tests::highprec::{DD, fs_fc_reference};
use softcbf_tests::reference::{
    self, Jet, Mat3, Vec3, chain, corner_height, mat_value, motion_subspace, sample_module,
    sample_theta, segment_value,
};

const NQ: usize = paper_sim::NQ;
const NB: usize = paper_sim::NB;

/// Central-difference step [m] (coordinates are ~0.01–0.1 m).
const STEP: f64 = 1e-6;

/// The paper's robot with two different modules (the second one scaled, so a mix-up of
/// module parameters shows), and its parameter vector.
fn paper() -> (Robot, [f64; paper_sim::NP]) {
    let robot = reference::two_different_modules();
    let p = pack_params(&robot)
        .try_into()
        .expect("paper_sim parameter count");
    (robot, p)
}

/// A random state of every module of `robot` and a random velocity.
fn sample_state<const N: usize>(rng: &mut TestRng, robot: &Robot) -> ([f64; N], [f64; N]) {
    let mut q = [0.0; N];
    for (i, module) in robot.modules.iter().enumerate() {
        let theta = sample_theta(rng, &SWITCH_POINTS);
        q[3 * i..3 * i + 3].copy_from_slice(&sample_module(rng, module, theta));
    }
    let qd = std::array::from_fn(|_| rng.random_range(-0.2..0.2));
    (q, qd)
}

/// The docs/model.md §8 acceptance test: `|got − exact| ≤ 1e-12·s + 1e-9·|exact|`. Returns the
/// error in units of the bound.
fn bound_ratio(got: f64, exact: f64, s: f64) -> f64 {
    (got - exact).abs() / (1e-12 * s + 1e-9 * exact.abs())
}

fn max_abs<'a>(x: impl IntoIterator<Item = &'a f64>) -> f64 {
    x.into_iter().fold(0.0, |m, v| m.max(v.abs()))
}

fn generated_terms(
    p: &[f64; paper_sim::NP],
    q: &[f64; NQ],
    qd: &[f64; NQ],
) -> ([f64; NB], [[f64; NQ]; NB], [f64; NB]) {
    let (mut b, mut jac, mut jdot) = ([0.0; NB], [[0.0; NQ]; NB], [0.0; NB]);
    paper_sim::barrier_terms(p, q, qd, &mut b, &mut jac, &mut jdot);
    (b, jac, jdot)
}

fn generated_barriers(p: &[f64; paper_sim::NP], q: &[f64; NQ]) -> [f64; NB] {
    let mut b = [0.0; NB];
    paper_sim::barriers(p, q, &mut b);
    b
}

fn shifted<const N: usize>(q: &[f64; N], dir: &[f64; N], h: f64) -> [f64; N] {
    std::array::from_fn(|k| q[k] + h * dir[k])
}

/// Every barrier, Jacobian element and `J̇q̇` at 1500 random states: against central
/// differences (~1e-7, ~1e-5 of the output's scale) and against the jets to the §8 bound.
#[test]
fn barrier_terms_against_finite_differences_and_jets() {
    let (robot, p) = paper();
    let mut rng = softcbf_tests::rng(0x5eed_0001);
    let mut worst = (0.0, String::new());
    for trial in 0..1500 {
        let (q, qd) = sample_state::<NQ>(&mut rng, &robot);
        let (b, jac, jdot) = generated_terms(&p, &q, &qd);
        let exact = reference::barriers(&robot, &q, &qd);
        let s_b = max_abs(exact.iter().map(|x| &x.v));
        let s_j = exact
            .iter()
            .flat_map(|x| x.g)
            .fold(0.0_f64, |m, v| m.max(v.abs()));
        let s_jd = max_abs(exact.iter().map(|x| &x.dd));
        let plain = generated_barriers(&p, &q);
        let mut fd_jac = [[0.0; NQ]; NB];
        for k in 0..NQ {
            let mut e = [0.0; NQ];
            e[k] = 1.0;
            let plus = generated_barriers(&p, &shifted(&q, &e, STEP));
            let minus = generated_barriers(&p, &shifted(&q, &e, -STEP));
            for r in 0..NB {
                fd_jac[r][k] = (plus[r] - minus[r]) / (2.0 * STEP);
            }
        }
        let (_, jac_plus, _) = generated_terms(&p, &shifted(&q, &qd, STEP), &qd);
        let (_, jac_minus, _) = generated_terms(&p, &shifted(&q, &qd, -STEP), &qd);
        let qd_max = max_abs(&qd);
        // The plate corners, which come first in the table (the limits after them are
        // checked by barrier_kinds.rs).
        for r in 0..exact.len() {
            let ctx = || format!("trial {trial}, barrier {r}, q = {q:?}, qd = {qd:?}");
            assert!(
                b[r] == plain[r],
                "{}: barrier_terms and barriers differ",
                ctx()
            );
            let ratio = bound_ratio(b[r], exact[r].v, s_b);
            assert!(
                ratio <= 1.0,
                "{}: b = {:e}, reference {:e}",
                ctx(),
                b[r],
                exact[r].v
            );
            for k in 0..NQ {
                let ratio = bound_ratio(jac[r][k], exact[r].g[k], s_j);
                if ratio > worst.0 {
                    worst = (ratio, format!("J[{r}][{k}] at {}", ctx()));
                }
                assert!(
                    ratio <= 1.0,
                    "{}: J[{r}][{k}] = {:e}, reference {:e}",
                    ctx(),
                    jac[r][k],
                    exact[r].g[k]
                );
                assert!(
                    (fd_jac[r][k] - jac[r][k]).abs() <= 1e-7 * s_j,
                    "{}: J[{r}][{k}] = {:e}, central difference {:e}",
                    ctx(),
                    jac[r][k],
                    fd_jac[r][k]
                );
            }
            let ratio = bound_ratio(jdot[r], exact[r].dd, s_jd);
            if ratio > worst.0 {
                worst = (ratio, format!("J̇q̇[{r}] at {}", ctx()));
            }
            assert!(
                ratio <= 1.0,
                "{}: J̇q̇ = {:e}, reference {:e}",
                ctx(),
                jdot[r],
                exact[r].dd
            );
            // d/dt (J q̇) along q̇ by central differences of the generated J.
            let along = |j: &[[f64; NQ]; NB]| (0..NQ).map(|k| j[r][k] * qd[k]).sum::<f64>();
            let fd = (along(&jac_plus) - along(&jac_minus)) / (2.0 * STEP);
            // Rounding floor of the difference quotient: ~eps·|J|·|q̇|/STEP.
            let tol = 1e-5 * s_jd + 1e-9 * s_j * qd_max;
            assert!(
                (fd - jdot[r]).abs() <= tol,
                "{}: J̇q̇ = {:e}, central difference {fd:e}",
                ctx(),
                jdot[r]
            );
        }
    }
    eprintln!(
        "barrier_terms: worst error {:.2e} × the §8 bound ({})",
        worst.0, worst.1
    );
}

/// `R`, `t` from double-double `f_s`, `f_c` (for small θ, where the reference's own
/// sin/cos path is not used).
fn segment_double_double(module: &Module, q: [f64; 3]) -> (Mat3<f64>, Vec3<f64>) {
    let d = DD::from(module.tendon_radius);
    let (a, b) = (DD::from(q[0]) / d, DD::from(q[1]) / d);
    let u = a * a + b * b;
    let (fs, fc) = fs_fc_reference(u.to_f64(), 0);
    let (fs, fc) = (fs[0], fc[0]);
    let one = DD::ONE;
    let length = DD::from(module.rest_length) + DD::from(q[2]);
    let r = [
        [one - a * a * fc, -(a * b * fc), a * fs],
        [-(a * b * fc), one - b * b * fc, b * fs],
        [-(a * fs), -(b * fs), one - u * fc],
    ];
    let t = [length * a * fc, length * b * fc, length * fs];
    (r.map(|row| row.map(DD::to_f64)), t.map(DD::to_f64))
}

fn generated_transforms(p: &[f64; paper_sim::NP], q: &[f64; NQ]) -> [[[f64; 4]; 4]; 2] {
    let mut t = [[[0.0; 4]; 4]; 2];
    paper_sim::segment_transforms(p, q, &mut t);
    t
}

/// `R`, `t` and `c_ij` of both modules: against sin/cos of θ for `u ≥ 1`, against the
/// double-double series for `u < 1` (both to the §8 bound), at 3000 random states.
#[test]
fn transforms_and_corner_heights_against_reference() {
    let (robot, p) = paper();
    let mut rng = softcbf_tests::rng(0x5eed_0002);
    let mut worst = 0.0_f64;
    for trial in 0..3000 {
        let (q, _) = sample_state::<NQ>(&mut rng, &robot);
        let transforms = generated_transforms(&p, &q);
        let b = generated_barriers(&p, &q);
        for (i, module) in robot.modules.iter().enumerate() {
            let qi = [q[3 * i], q[3 * i + 1], q[3 * i + 2]];
            let u = (qi[0] * qi[0] + qi[1] * qi[1]) / (module.tendon_radius * module.tendon_radius);
            let (r, t) = if u < reference::SERIES_BELOW {
                segment_double_double(module, qi)
            } else {
                segment_value(module, qi)
            };
            let s_t = max_abs(&t);
            for row in 0..3 {
                for col in 0..3 {
                    let ratio = bound_ratio(transforms[i][row][col], r[row][col], 1.0);
                    worst = worst.max(ratio);
                    assert!(
                        ratio <= 1.0,
                        "trial {trial}, module {i}, q_i = {qi:?}: R[{row}][{col}] = {:e}, exact {:e}",
                        transforms[i][row][col],
                        r[row][col]
                    );
                }
                let ratio = bound_ratio(transforms[i][row][3], t[row], s_t);
                worst = worst.max(ratio);
                assert!(
                    ratio <= 1.0,
                    "trial {trial}, module {i}, q_i = {qi:?}: t[{row}] = {:e}, exact {:e}",
                    transforms[i][row][3],
                    t[row]
                );
            }
            assert_eq!(transforms[i][3], [0.0, 0.0, 0.0, 1.0]);
            // Corner heights: f_s from double-double times the lever in f64.
            let (fs, _) = fs_fc_reference(u, 0);
            let heights: Vec<f64> = (0..module.corner_angles.len())
                .map(|j| {
                    let phi = module.corner_angles[j];
                    let lever = (DD::from(qi[0]) * DD::from(phi.cos())
                        + DD::from(qi[1]) * DD::from(phi.sin()))
                        * DD::from(module.corner_radius)
                        / DD::from(module.tendon_radius);
                    (fs[0] * (DD::from(module.rest_length) + DD::from(qi[2]) - lever)).to_f64()
                })
                .collect();
            let s_c = max_abs(&heights);
            for (j, c) in heights.iter().enumerate() {
                let got = b[6 * i + j] + module.margins[j];
                let ratio = bound_ratio(got, *c, s_c);
                worst = worst.max(ratio);
                assert!(
                    ratio <= 1.0,
                    "trial {trial}, module {i}, corner {j}, q_i = {qi:?}: c = {got:e}, exact {c:e}"
                );
            }
        }
    }
    eprintln!("segment_transforms, barriers: worst error {worst:.2e} × the §8 bound");
}

/// At `Δx = Δy = 0` (with and without `δL`), and for subnormal bends, `R = I`,
/// `t = (0, 0, L0 + δL)`, `c = L0 + δL` exactly; `J` and `J̇q̇` are their exact limits
/// `∂c/∂(Δx, Δy, δL) = (−(r/d) cos φ, −(r/d) sin φ, 1)`, `J̇q̇ = −L (Δẋ² + Δẏ²)/(3 d²)`.
#[test]
fn exact_limits_when_straight() {
    let (robot, p) = paper();
    let qd = [0.13, -0.07, 0.2, -0.11, 0.05, -0.3];
    for dl in [0.0, 0.03, -0.02, 1e-300, 5e-324] {
        for bend in [0.0, -0.0, 1e-310, 5e-324, -5e-324] {
            let q = [bend, 0.0, dl, -0.0, bend, dl];
            let transforms = generated_transforms(&p, &q);
            let (b, jac, jdot) = generated_terms(&p, &q, &qd);
            for (i, module) in robot.modules.iter().enumerate() {
                let (m, d, r) = (module, module.tendon_radius, module.corner_radius);
                let length = m.rest_length + dl;
                let tf = &transforms[i];
                let ctx = format!("q = {q:?}, module {i}");
                let bent = bend / d;
                // f_s, f_c are their limits here: the only non-trivial entries are
                // linear in Δx/d (exact up to the subnormal rounding of Δx/d itself).
                let expected = [
                    [
                        1.0,
                        0.0,
                        if i == 0 { bent } else { 0.0 },
                        0.5 * length * if i == 0 { bent } else { 0.0 },
                    ],
                    [
                        0.0,
                        1.0,
                        if i == 1 { bent } else { 0.0 },
                        0.5 * length * if i == 1 { bent } else { 0.0 },
                    ],
                    [
                        if i == 0 { -bent } else { 0.0 },
                        if i == 1 { -bent } else { 0.0 },
                        1.0,
                        length,
                    ],
                ];
                for row in 0..3 {
                    for col in 0..4 {
                        let (got, want) = (tf[row][col], expected[row][col]);
                        assert!(got.is_finite(), "{ctx}: T[{row}][{col}] = {got}");
                        // Subnormal results carry few bits: allow 2 subnormal ulps there.
                        assert!(
                            got == want || (got - want).abs() <= 1e-15 * want.abs() + 1e-323,
                            "{ctx}: T[{row}][{col}] = {got:e}, expected {want:e}"
                        );
                    }
                }
                if bend == 0.0 {
                    assert_eq!(
                        [tf[0][3], tf[1][3], tf[2][3]],
                        [0.0, 0.0, length],
                        "{ctx}: t not exact"
                    );
                }
                let qdi = [qd[3 * i], qd[3 * i + 1], qd[3 * i + 2]];
                let jdot_exact = -length * (qdi[0] * qdi[0] + qdi[1] * qdi[1]) / (3.0 * d * d);
                for j in 0..6 {
                    let row = 6 * i + j;
                    let phi = m.corner_angles[j];
                    let lever = r / d
                        * (if i == 0 {
                            bend * phi.cos()
                        } else {
                            bend * phi.sin()
                        });
                    let c = length - lever;
                    assert!(
                        (b[row] + m.margins[j] - c).abs() <= 4e-16 * c,
                        "{ctx}: corner {j}: c = {:e}, expected {c:e}",
                        b[row] + m.margins[j]
                    );
                    if bend == 0.0 {
                        assert_eq!(
                            b[row],
                            length - m.margins[j],
                            "{ctx}: corner {j}: b not exact"
                        );
                    }
                    let mut j_exact = [0.0; NQ];
                    j_exact[3 * i] = -r / d * phi.cos();
                    j_exact[3 * i + 1] = -r / d * phi.sin();
                    j_exact[3 * i + 2] = 1.0;
                    for k in 0..NQ {
                        assert!(jac[row][k].is_finite());
                        assert!(
                            (jac[row][k] - j_exact[k]).abs() <= 1e-15 * (1.0 + j_exact[k].abs()),
                            "{ctx}: J[{row}][{k}] = {:e}, expected {:e}",
                            jac[row][k],
                            j_exact[k]
                        );
                    }
                    assert!(
                        (jdot[row] - jdot_exact).abs() <= 1e-14 * jdot_exact.abs(),
                        "{ctx}: J̇q̇[{row}] = {:e}, expected {jdot_exact:e}",
                        jdot[row]
                    );
                }
            }
            // Everything else generated is finite there too.
            let mut poses = [[[0.0; 4]; 4]; 2];
            paper_sim::plate_poses(&p, &q, &mut poses);
            let (mut rot, mut tr, mut s, mut c) = (
                [[[0.0; 3]; 3]; 2],
                [[0.0; 3]; 2],
                [[[0.0; 3]; 6]; 2],
                [[0.0; 6]; 2],
            );
            paper_sim::joint_terms(&p, &q, &qd, &mut rot, &mut tr, &mut s, &mut c);
            let all = poses
                .iter()
                .flatten()
                .flatten()
                .chain(rot.iter().flatten().flatten());
            let all = all
                .chain(tr.iter().flatten())
                .chain(s.iter().flatten().flatten());
            assert!(
                all.chain(c.iter().flatten()).all(|x| x.is_finite()),
                "q = {q:?}"
            );
        }
    }
}

/// `RᵀR = I` to 1e-14 and `det R = +1` at random states (θ up to 3 rad and, near the
/// switch points, up to √48).
#[test]
fn rotation_is_orthonormal() {
    let (robot, p) = paper();
    let mut rng = softcbf_tests::rng(0x5eed_0003);
    for _ in 0..3000 {
        let (q, _) = sample_state::<NQ>(&mut rng, &robot);
        for tf in generated_transforms(&p, &q) {
            for a in 0..3 {
                for b in 0..3 {
                    let dot: f64 = (0..3).map(|k| tf[k][a] * tf[k][b]).sum();
                    let want = if a == b { 1.0 } else { 0.0 };
                    assert!(
                        (dot - want).abs() <= 1e-14,
                        "q = {q:?}: (RᵀR)[{a}][{b}] = {dot}"
                    );
                }
            }
            let det = tf[0][0] * (tf[1][1] * tf[2][2] - tf[1][2] * tf[2][1])
                - tf[0][1] * (tf[1][0] * tf[2][2] - tf[1][2] * tf[2][0])
                + tf[0][2] * (tf[1][0] * tf[2][1] - tf[1][1] * tf[2][0]);
            assert!((det - 1.0).abs() <= 1e-14, "q = {q:?}: det R = {det}");
        }
    }
}

/// `t = ∫₀ᴸ R(s) e_z ds` with the PCC backbone bent by `θ s / L` about the axis
/// perpendicular to `(Δx, Δy)`: composite Simpson with 4000 intervals (error < 1e-14·L).
#[test]
fn translation_is_integral_of_backbone_tangent() {
    let (robot, p) = paper();
    let mut rng = softcbf_tests::rng(0x5eed_0004);
    for _ in 0..300 {
        let (q, _) = sample_state::<NQ>(&mut rng, &robot);
        let transforms = generated_transforms(&p, &q);
        for (i, module) in robot.modules.iter().enumerate() {
            let (dx, dy, dl) = (q[3 * i], q[3 * i + 1], q[3 * i + 2]);
            let length = module.rest_length + dl;
            let theta = dx.hypot(dy) / module.tendon_radius;
            let alpha = dy.atan2(dx);
            let tangent = |s: f64| {
                let bend = theta * s / length;
                [
                    alpha.cos() * bend.sin(),
                    alpha.sin() * bend.sin(),
                    bend.cos(),
                ]
            };
            let integral = reference::simpson(tangent, length, 4000);
            for c in 0..3 {
                assert!(
                    (transforms[i][c][3] - integral[c]).abs() <= 1e-13 * length,
                    "q = {q:?}, module {i}: t[{c}] = {:e}, integral {:e}",
                    transforms[i][c][3],
                    integral[c]
                );
            }
        }
    }
}

/// `c_ij` (generated barrier + margin) is the z coordinate of the corner `t + R p_j` in
/// the segment base frame (from the generated transform).
#[test]
fn corner_height_is_height_of_corner_point() {
    let (robot, p) = paper();
    let mut rng = softcbf_tests::rng(0x5eed_0005);
    for _ in 0..3000 {
        let (q, _) = sample_state::<NQ>(&mut rng, &robot);
        let transforms = generated_transforms(&p, &q);
        let b = generated_barriers(&p, &q);
        for (i, module) in robot.modules.iter().enumerate() {
            let tf = &transforms[i];
            for (j, phi) in module.corner_angles.iter().enumerate() {
                let corner = [
                    module.corner_radius * phi.cos(),
                    module.corner_radius * phi.sin(),
                ];
                let z = tf[2][3] + tf[2][0] * corner[0] + tf[2][1] * corner[1];
                let c = b[6 * i + j] + module.margins[j];
                let scale = module.rest_length + module.corner_radius;
                assert!(
                    (c - z).abs() <= 1e-15 * scale,
                    "q = {q:?}, module {i}, corner {j}: c = {c:e}, corner z = {z:e}"
                );
                // And the reference's own corner height agrees with its transform.
                let [x, y, l] = [q[3 * i], q[3 * i + 1], q[3 * i + 2]].map(Jet::<0>::constant);
                let c_ref = corner_height(module, j, x, y, l).v;
                assert!((c_ref - z).abs() <= 1e-15 * scale);
            }
        }
    }
}

fn multiply(a: &[[f64; 4]; 4], b: &[[f64; 4]; 4]) -> [[f64; 4]; 4] {
    std::array::from_fn(|r| std::array::from_fn(|c| (0..4).map(|k| a[r][k] * b[k][c]).sum()))
}

/// `W_i = T_1 ⋯ T_i`: generated plate poses against the product of generated segment
/// transforms (4 modules) and against the jets' world poses (2 and 4 modules).
#[test]
fn plate_poses_are_products_of_segment_transforms() {
    let robot4 = reference::paper_robot(
        (0..4)
            .map(|i| {
                let mut m = reference::paper_module(0.0);
                m.rest_length += 0.01 * i as f64;
                m.tendon_radius -= 0.002 * i as f64;
                m
            })
            .collect(),
    );
    let p4: [f64; hex_4::NP] = pack_params(&robot4)
        .try_into()
        .expect("hex_4 parameter count");
    let (robot2, p2) = paper();
    let mut rng = softcbf_tests::rng(0x5eed_0006);
    for _ in 0..1000 {
        let (q, qd) = sample_state::<{ hex_4::NQ }>(&mut rng, &robot4);
        let mut transforms = [[[0.0; 4]; 4]; 4];
        let mut poses = [[[0.0; 4]; 4]; 4];
        hex_4::segment_transforms(&p4, &q, &mut transforms);
        hex_4::plate_poses(&p4, &q, &mut poses);
        let exact = chain(&robot4, &q, &qd);
        let mut product = transforms[0];
        for i in 0..4 {
            if i > 0 {
                product = multiply(&product, &transforms[i]);
            }
            let world_r = mat_value(&exact.world_rotation[i]);
            let world_p = exact.world_position[i].map(|x| x.v);
            let s_p = max_abs(&world_p);
            for r in 0..4 {
                for c in 0..4 {
                    assert!(
                        (poses[i][r][c] - product[r][c]).abs() <= 1e-15,
                        "q = {q:?}: W_{i}[{r}][{c}] = {:e}, product {:e}",
                        poses[i][r][c],
                        product[r][c]
                    );
                }
            }
            for r in 0..3 {
                for c in 0..3 {
                    assert!(bound_ratio(poses[i][r][c], world_r[r][c], 1.0) <= 1.0);
                }
                assert!(
                    bound_ratio(poses[i][r][3], world_p[r], s_p) <= 1.0,
                    "q = {q:?}: W_{i} position[{r}] = {:e}, reference {:e}",
                    poses[i][r][3],
                    world_p[r]
                );
            }
        }
        let (q2, _) = sample_state::<NQ>(&mut rng, &robot2);
        let mut poses2 = [[[0.0; 4]; 4]; 2];
        paper_sim::plate_poses(&p2, &q2, &mut poses2);
        let exact2 = chain(&robot2, &q2, &[0.0; NQ]);
        for (pose, position) in poses2.iter().zip(&exact2.world_position) {
            let world_p = position.map(|x| x.v);
            for r in 0..3 {
                assert!(bound_ratio(pose[r][3], world_p[r], max_abs(&world_p)) <= 1.0);
            }
        }
    }
}

/// One coordinate subnormal, the others normal (bends of 1 rad and 1e-4 rad): generated
/// transforms, barriers, `J` and `J̇q̇` finite and equal to the jets' values (§8 bound).
#[test]
fn subnormal_coordinates_next_to_normal_ones() {
    let (robot, p) = paper();
    let qd = [0.13, -0.07, 0.2, -0.11, 0.05, -0.3];
    for tiny in [1e-310, -5e-324, 5e-324, 2.2e-308] {
        for normal in [0.04, -4e-6] {
            for q in [
                [normal, tiny, 0.01, tiny, normal, tiny],
                [tiny, normal, tiny, normal, tiny, -0.01],
            ] {
                let transforms = generated_transforms(&p, &q);
                let (b, jac, jdot) = generated_terms(&p, &q, &qd);
                let exact = reference::barriers(&robot, &q, &qd);
                let s_j = exact
                    .iter()
                    .flat_map(|x| x.g)
                    .fold(0.0_f64, |m, v| m.max(v.abs()));
                let s_jd = max_abs(exact.iter().map(|x| &x.dd));
                // The plate corners, which come first in the table (the limits after them are
                // checked by barrier_kinds.rs).
                for r in 0..exact.len() {
                    assert!(
                        bound_ratio(b[r], exact[r].v, 0.1) <= 1.0,
                        "q = {q:?}: b[{r}]"
                    );
                    for (k, (got, want)) in jac[r].iter().zip(&exact[r].g).enumerate() {
                        assert!(
                            bound_ratio(*got, *want, s_j) <= 1.0,
                            "q = {q:?}: J[{r}][{k}] = {got:e}, reference {want:e}"
                        );
                    }
                    assert!(
                        bound_ratio(jdot[r], exact[r].dd, s_jd) <= 1.0,
                        "q = {q:?}: J̇q̇[{r}] = {:e}, reference {:e}",
                        jdot[r],
                        exact[r].dd
                    );
                }
                for (i, module) in robot.modules.iter().enumerate() {
                    let (r, t) = segment_value(module, [q[3 * i], q[3 * i + 1], q[3 * i + 2]]);
                    for row in 0..3 {
                        for col in 0..3 {
                            assert!(bound_ratio(transforms[i][row][col], r[row][col], 1.0) <= 1.0);
                        }
                        assert!(
                            bound_ratio(transforms[i][row][3], t[row], max_abs(&t)) <= 1.0,
                            "q = {q:?}: t_{i}[{row}] = {:e}, reference {:e}",
                            transforms[i][row][3],
                            t[row]
                        );
                    }
                }
            }
        }
    }
}

type JointTerms = (
    [[[f64; 3]; 3]; 2],
    [[f64; 3]; 2],
    [[[f64; 3]; 6]; 2],
    [[f64; 6]; 2],
);

fn generated_joint_terms(p: &[f64; paper_sim::NP], q: &[f64; NQ], qd: &[f64; NQ]) -> JointTerms {
    let mut out: JointTerms = Default::default();
    paper_sim::joint_terms(p, q, qd, &mut out.0, &mut out.1, &mut out.2, &mut out.3);
    out
}

/// Joint terms: `R`, `t` equal the segment transforms; `S_i` (body twist per unit `q̇_i`)
/// and `c_J = Ṡ_i q̇_i` against the jets (§8 bound) and `c_J` against central differences
/// of the generated `S_i` along `q̇`.
#[test]
fn joint_terms_against_jets_and_finite_differences() {
    let (robot, p) = paper();
    let mut rng = softcbf_tests::rng(0x5eed_0007);
    for _ in 0..1500 {
        let (q, qd) = sample_state::<NQ>(&mut rng, &robot);
        let (rot, tr, s, c) = generated_joint_terms(&p, &q, &qd);
        let transforms = generated_transforms(&p, &q);
        let (_, _, s_plus, _) = generated_joint_terms(&p, &shifted(&q, &qd, STEP), &qd);
        let (_, _, s_minus, _) = generated_joint_terms(&p, &shifted(&q, &qd, -STEP), &qd);
        let exact = chain(&robot, &q, &qd);
        for i in 0..2 {
            for r in 0..3 {
                for col in 0..3 {
                    assert!((rot[i][r][col] - transforms[i][r][col]).abs() <= 1e-16);
                }
                assert!((tr[i][r] - transforms[i][r][3]).abs() <= 1e-17);
            }
            let (s_exact, c_exact) = motion_subspace(&exact, i, &qd);
            let scale_s = max_abs(s_exact.iter().flatten());
            let scale_c = max_abs(&c_exact);
            for r in 0..6 {
                for k in 0..3 {
                    assert!(
                        bound_ratio(s[i][r][k], s_exact[r][k], scale_s) <= 1.0,
                        "q = {q:?}: S_{i}[{r}][{k}] = {:e}, reference {:e}",
                        s[i][r][k],
                        s_exact[r][k]
                    );
                }
                assert!(
                    bound_ratio(c[i][r], c_exact[r], scale_c) <= 1.0,
                    "q = {q:?}, qd = {qd:?}: c_J,{i}[{r}] = {:e}, reference {:e}",
                    c[i][r],
                    c_exact[r]
                );
                let along = |s: &[[[f64; 3]; 6]; 2]| {
                    (0..3).map(|k| s[i][r][k] * qd[3 * i + k]).sum::<f64>()
                };
                let fd = (along(&s_plus) - along(&s_minus)) / (2.0 * STEP);
                let tol = 1e-5 * scale_c + 1e-9 * scale_s * max_abs(&qd);
                assert!(
                    (fd - c[i][r]).abs() <= tol,
                    "q = {q:?}, qd = {qd:?}: c_J,{i}[{r}] = {:e}, central difference {fd:e}",
                    c[i][r]
                );
            }
        }
    }
}
