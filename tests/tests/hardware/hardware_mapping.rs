//! Tests of the servo ↔ `q` and `τ` ↔ tension ↔ current mapping (docs/model.md §6) against hand
//! computations on the example hardware robot, and round trips.

use std::f64::consts::PI;

use rand::RngExt;
use softcbf::hardware::mapping::{Clamps, TendonMap};
use softcbf_description::robot::Robot;

fn example() -> (Robot, TendonMap) {
    let robot = softcbf_tests::robots::hardware_example();
    let map = TendonMap::new(&robot).unwrap();
    (robot, map)
}

fn close(a: f64, b: f64, tol: f64) {
    assert!((a - b).abs() <= tol, "{a} vs {b} (tol {tol})");
}

/// The paper's tendons ψ = 90°, 210°, 330°: A Aᵀ = diag(3/2, 3/2, 3), so
/// `f_k = (2/3)(cos ψ_k τx + sin ψ_k τy) − τz/3`.
fn tensions_by_hand(tau: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|k| {
        let psi = (90.0 + 120.0 * k as f64).to_radians();
        2.0 / 3.0 * (psi.cos() * tau[0] + psi.sin() * tau[1]) - tau[2] / 3.0
    })
}

#[test]
fn tensions_match_the_closed_form_and_round_trip() {
    let (_, map) = example();
    let mut rng = softcbf_tests::rng(7);
    let mut tensions = [0.0; 6];
    let mut back = [0.0; 6];
    for _ in 0..200 {
        // τ from tensions inside the limits [0.2, 40], so nothing is clamped.
        let f: [f64; 6] = std::array::from_fn(|_| 0.2 + 39.8 * rng.random::<f64>());
        let mut tau = [0.0; 6];
        map.tau_from_tensions(&f, &mut tau);
        for i in 0..2 {
            let by_hand = tensions_by_hand([tau[3 * i], tau[3 * i + 1], tau[3 * i + 2]]);
            for k in 0..3 {
                close(by_hand[k], f[3 * i + k], 1e-12);
            }
        }
        let clamps = map.tensions_from_tau(&tau, &mut tensions);
        assert_eq!(clamps, Clamps::default());
        for k in 0..6 {
            close(tensions[k], f[k], 1e-12);
        }
        map.tau_from_tensions(&tensions, &mut back);
        for k in 0..6 {
            close(back[k], tau[k], 1e-11);
        }
    }
}

#[test]
fn tensions_outside_the_limits_are_clamped_and_counted() {
    let (_, map) = example();
    let mut tensions = [0.0; 6];
    // Module 1: τ = (1, 0, 0): f = (0, −1/√3, 1/√3) → two below f_min = 0.2.
    // Module 2: τ = (0, 0, −150): f = (50, 50, 50) → three above f_max = 40.
    let clamps = map.tensions_from_tau(&[1.0, 0.0, 0.0, 0.0, 0.0, -150.0], &mut tensions);
    assert_eq!(clamps, Clamps { low: 2, high: 3 });
    close(tensions[0], 0.2, 0.0);
    close(tensions[1], 0.2, 0.0);
    close(tensions[2], 1.0 / 3f64.sqrt(), 1e-15);
    assert_eq!(&tensions[3..], &[40.0; 3]);
    // A non-finite command pulls with f_min everywhere.
    let clamps = map.tensions_from_tau(&[f64::NAN, 0.0, 0.0, 0.0, 0.0, -3.0], &mut tensions);
    assert_eq!(clamps.low, 3);
    assert_eq!(&tensions[..3], &[0.2; 3]);
    close(tensions[3], 1.0, 1e-15);
}

#[test]
fn servo_angles_of_a_hand_computed_bend() {
    let (_, map) = example();
    // Module 1 bent Δx = 0.01 m: ℓ_k = L0 − 0.01 cos ψ_k, L0 = ℓ_k0 = 0.06, ρ = 0.045,
    // signs (1, −1, 1), zero angles π: θ_k = π + (ℓ_k0 − ℓ_k)/(ρ s_k) = π + (0.01/ρ) cos ψ_k / s_k.
    let q = [0.01, 0.0, 0.0, 0.0, 0.0, -0.02];
    let mut angles = [0.0; 6];
    map.angles_from_q(&q, &mut angles);
    close(angles[0], PI, 1e-15);
    let bend = 0.01 / 0.045 * 3f64.sqrt() / 2.0;
    close(angles[1], PI + bend, 1e-14);
    close(angles[2], PI + bend, 1e-14);
    // Module 2 compressed δL = −0.02: every tendon 0.02 shorter, wound by 0.02/ρ rad in its
    // winding direction (signs 1, 1, −1).
    close(angles[3], PI + 0.02 / 0.045, 1e-14);
    close(angles[4], PI + 0.02 / 0.045, 1e-14);
    close(angles[5], PI - 0.02 / 0.045, 1e-14);
    let mut back = [0.0; 6];
    map.q_from_angles(&angles, &mut back);
    for k in 0..6 {
        close(back[k], q[k], 1e-15);
    }
}

#[test]
fn configurations_and_velocities_round_trip() {
    let (_, map) = example();
    let mut rng = softcbf_tests::rng(11);
    let (mut angles, mut rates, mut q2, mut qd2) = ([0.0; 6], [0.0; 6], [0.0; 6], [0.0; 6]);
    for _ in 0..200 {
        let q: [f64; 6] = std::array::from_fn(|_| 0.1 * (rng.random::<f64>() - 0.5));
        let qd: [f64; 6] = std::array::from_fn(|_| rng.random::<f64>() - 0.5);
        map.angles_from_q(&q, &mut angles);
        map.rates_from_qd(&qd, &mut rates);
        map.q_from_angles(&angles, &mut q2);
        map.qd_from_rates(&rates, &mut qd2);
        for k in 0..6 {
            close(q2[k], q[k], 1e-15);
            close(qd2[k], qd[k], 1e-14);
        }
        // The rates are the derivative of the angles: central difference along q̇.
        let h = 1e-6;
        let (mut plus, mut minus) = ([0.0; 6], [0.0; 6]);
        let qp: [f64; 6] = std::array::from_fn(|k| q[k] + h * qd[k]);
        let qm: [f64; 6] = std::array::from_fn(|k| q[k] - h * qd[k]);
        map.angles_from_q(&qp, &mut plus);
        map.angles_from_q(&qm, &mut minus);
        for k in 0..6 {
            close((plus[k] - minus[k]) / (2.0 * h), rates[k], 1e-7);
        }
    }
}

#[test]
fn currents_and_registers_by_hand() {
    let (_, map) = example();
    // 1 N at 0.04 N/mA is 25 mA = 9.294 units of 2.69 mA → 9, with the servo's sign.
    assert_eq!(map.current_from_tension(0, 1.0), 9);
    assert_eq!(map.current_from_tension(1, 1.0), -9);
    assert_eq!(map.current_from_tension(5, 40.0), -372); // 40/0.04/2.69 = 371.75
    close(map.tension_from_current(0, 5), 5.0 * 2.69 * 0.04, 1e-15);
    close(map.tension_from_current(1, -5), 5.0 * 2.69 * 0.04, 1e-15);
    close(map.tension_from_current(0, -5), -0.538, 1e-12);
    // Saturation at the register's range.
    assert_eq!(map.current_from_tension(0, 1e9), i16::MAX);
    // Present Position 2048 is 180°; one velocity unit is 0.229 rev/min.
    close(map.angle_from_position(2048), PI, 1e-15);
    assert_eq!(map.position_from_angle(PI), 2048);
    assert_eq!(map.position_from_angle(-PI / 2.0), -1024);
    close(map.rate_from_velocity(1), 0.229 * 2.0 * PI / 60.0, 1e-15);
    assert_eq!(map.velocity_from_rate(0.229 * 2.0 * PI / 60.0 * 7.4), 7);
}

/// Per-tendon gains (`robots/calibration-true.toml`: module 1 `[0.030, 0.052, 0.050]`,
/// module 2 `[0.048, 0.030, 0.056]` N/mA, signs `(1, −1, 1)` and `(1, 1, −1)`): each servo's
/// current follows its own gain, `I = s f / (g · 2.69 mA)`.
#[test]
fn per_tendon_gains_give_per_tendon_currents() {
    let robot = Robot::load(&softcbf_tests::robots::path("calibration-true.toml")).unwrap();
    let map = TendonMap::new(&robot).unwrap();
    // 10 N: 10/(0.030·2.69) = 123.9 → 124; 10/(0.052·2.69) = 71.49 → −71 (unwinding
    // sign); 10/(0.050·2.69) = 74.35 → 74; 10/(0.048·2.69) = 77.45 → 77; the 0.030 servo of
    // module 2 → 124; 10/(0.056·2.69) = 66.38 → −66. One gain for all would give 93 each.
    let currents: Vec<i16> = (0..6).map(|s| map.current_from_tension(s, 10.0)).collect();
    assert_eq!(currents, [124, -71, 74, 77, 124, -66]);
    // Back: 100 units pull s·g·269 mA: 8.07, −13.988, 13.45, 12.912, 8.07, −15.064 N.
    let by_hand = [8.07, -13.988, 13.45, 12.912, 8.07, -15.064];
    for (s, f) in by_hand.iter().enumerate() {
        close(map.tension_from_current(s, 100), *f, 1e-12);
    }
}

#[test]
fn a_robot_without_hardware_is_refused() {
    let error = TendonMap::new(&Robot::paper_sim()).unwrap_err();
    assert!(error.to_string().contains("no [hardware] table"), "{error}");
}

/// The tension-limit rows given to the safety filter hold exactly when the tensions of the
/// hand-written closed form lie in `[f_min, f_max]`.
#[test]
fn tension_limit_rows_are_the_tension_limits() {
    let (_, map) = example();
    let (rows, rhs) = map.tension_limit_rows();
    let nq = 6;
    assert_eq!((rows.len(), rhs.len()), (2 * nq * nq, 2 * nq));
    let mut rng = softcbf_tests::rng(8);
    for _ in 0..500 {
        let tau: Vec<f64> = (0..nq).map(|_| rng.random_range(-20.0..20.0)).collect();
        for (i, hw) in map.hardware().modules.iter().enumerate() {
            let [f_min, f_max] = hw.tension_limits;
            let f = tensions_by_hand([tau[3 * i], tau[3 * i + 1], tau[3 * i + 2]]);
            for (k, f_k) in f.iter().enumerate() {
                let row = 2 * (3 * i + k);
                let value = |r: usize| -> f64 {
                    let a = &rows[r * nq..(r + 1) * nq];
                    a.iter().zip(&tau).map(|(x, t)| x * t).sum::<f64>() - rhs[r]
                };
                close(value(row), f_k - f_min, 1e-12);
                close(value(row + 1), f_max - f_k, 1e-12);
            }
        }
    }
}
