//! Integration tests of the safety QP: KKT certificates on random instances, agreement
//! with clarabel, infeasible and non-finite input, and zero allocation per solve.

#![allow(clippy::needless_range_loop)] // index-heavy numeric checks read clearer with indices

use rand::RngExt;
use softcbf::qp::{QpSettings, QpSetupError, QpSolver, QpStatus, SafetyQp};

use softcbf_tests::TestRng;
use softcbf_tests::alloc::allocations;

/// One random safety-QP instance.
#[derive(Clone, Debug)]
struct Instance {
    n: usize,
    m: usize,
    a: Vec<f64>,
    b: Vec<f64>,
    tau_nom: Vec<f64>,
}

/// Feasible by construction: every row holds at a point `tau_f`. The kind selects
/// scaled rows, duplicates, near-parallel rows, rows through `tau_nom`, all
/// inactive and many-active (all rows through one point) cases.
fn feasible_instance(rng: &mut TestRng, kind: usize) -> Instance {
    let (n, m) = if rng.random::<f64>() < 0.8 {
        (6, 12)
    } else {
        (rng.random_range(1..=24usize), rng.random_range(0..=96usize))
    };
    let scale_tau = 10f64.powf(rng.random_range(-2.0..3.0));
    let tau_nom: Vec<f64> = (0..n)
        .map(|_| scale_tau * rng.random_range(-1.0..1.0))
        .collect();
    let tau_f: Vec<f64> = (0..n)
        .map(|_| scale_tau * rng.random_range(-1.0..1.0))
        .collect();
    let mut a = vec![0.0; m * n];
    let mut b = vec![0.0; m];
    for i in 0..m {
        let row_scale = 10f64.powf(rng.random_range(-4.0..4.0));
        let row = &mut a[i * n..(i + 1) * n];
        for v in row.iter_mut() {
            *v = row_scale * rng.random_range(-1.0..1.0);
        }
        let variant = rng.random_range(0..10usize);
        if i > 0 && kind % 3 == 1 && variant < 4 {
            // Duplicate (positively scaled) or near-parallel copy of an earlier row.
            let src = rng.random_range(0..i);
            let factor = 10f64.powf(rng.random_range(-3.0..3.0));
            let tilt = if variant < 2 { 0.0 } else { 1e-7 };
            for j in 0..n {
                let v = a[src * n + j] * factor;
                a[i * n + j] = v * (1.0 + tilt * rng.random_range(-1.0..1.0));
            }
        }
        let row = &a[i * n..(i + 1) * n];
        let at_f: f64 = row.iter().zip(&tau_f).map(|(x, y)| x * y).sum();
        let at_nom: f64 = row.iter().zip(&tau_nom).map(|(x, y)| x * y).sum();
        let norm = row.iter().map(|v| v * v).sum::<f64>().sqrt();
        b[i] = match kind % 5 {
            // Many active: all rows through tau_f, tau_nom elsewhere.
            0 => at_f,
            // Some rows through tau_nom exactly (if tau_nom satisfies them at equality
            // they stay feasible: the others are set from tau_f with margin).
            2 if variant < 3 => at_nom.min(at_f),
            // All inactive: tau_nom strictly inside.
            3 => at_nom.min(at_f) - norm * scale_tau * rng.random_range(0.0..0.5),
            _ => at_f - norm * scale_tau * rng.random_range(0.0..0.3) * (variant % 2) as f64,
        };
    }
    Instance {
        n,
        m,
        a,
        b,
        tau_nom,
    }
}

fn inf_norm(v: &[f64]) -> f64 {
    v.iter().fold(0.0_f64, |acc, x| acc.max(x.abs()))
}

fn row_norm(row: &[f64]) -> f64 {
    row.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// Largest relative KKT residual of (tau, lambda) for the instance, computed here
/// in the caller's units (rows are normalised only to measure distances).
fn kkt_residual(inst: &Instance, tau: &[f64], lambda: &[f64]) -> f64 {
    let n = inst.n;
    let mut scale = 1.0 + inf_norm(&inst.tau_nom).max(inf_norm(tau));
    let mut lscale = 0.0_f64;
    for i in 0..inst.m {
        let norm = row_norm(&inst.a[i * n..(i + 1) * n]);
        scale = scale.max(inst.b[i].abs() / norm);
        lscale = lscale.max(lambda[i] * norm);
    }
    let lscale = scale.max(lscale);
    let mut worst = 0.0_f64;
    let mut stationarity: Vec<f64> = tau.iter().zip(&inst.tau_nom).map(|(t, u)| t - u).collect();
    for i in 0..inst.m {
        let row = &inst.a[i * n..(i + 1) * n];
        let norm = row_norm(row);
        let slack = (row.iter().zip(tau).map(|(x, y)| x * y).sum::<f64>() - inst.b[i]) / norm;
        let mult = lambda[i] * norm;
        worst = worst.max(-slack / scale); // primal feasibility
        worst = worst.max(-mult / lscale); // dual feasibility
        worst = worst.max(mult.max(0.0) * slack.max(0.0) / (scale * lscale)); // complementarity
        for (s, a) in stationarity.iter_mut().zip(row) {
            *s -= lambda[i] * a;
        }
    }
    worst.max(inf_norm(&stationarity) / lscale)
}

#[test]
fn kkt_holds_on_random_feasible_instances() {
    let mut rng = softcbf_tests::rng(7);
    let count = 100_000;
    let mut solvers: Vec<Option<SafetyQp>> = (0..25 * 97).map(|_| None).collect();
    let mut worst = 0.0_f64;
    let mut fallbacks = 0;
    let mut active_hist = [0usize; 25];
    for k in 0..count {
        let inst = feasible_instance(&mut rng, k);
        let qp = solvers[inst.n * 97 + inst.m]
            .get_or_insert_with(|| SafetyQp::new(inst.n, inst.m, QpSettings::default()).unwrap());
        let mut tau = vec![0.0; inst.n];
        let report = qp.solve(&inst.tau_nom, &inst.a, &inst.b, &mut tau).clone();
        assert_eq!(report.status, QpStatus::Solved, "instance {k}: {inst:?}");
        if report.solver == QpSolver::Clarabel {
            fallbacks += 1;
            continue;
        }
        active_hist[report.active.min(24)] += 1;
        let res = kkt_residual(&inst, &tau, qp.multipliers());
        assert!(res < 1e-9, "instance {k}: KKT residual {res:e}: {inst:?}");
        worst = worst.max(res);
    }
    println!("worst KKT residual {worst:e}, clarabel fallbacks {fallbacks}/{count}");
    println!("active-row histogram {active_hist:?}");
    assert!(fallbacks * 1000 < count, "too many fallbacks: {fallbacks}");
    assert!(active_hist[0] > 1000 && active_hist[3..].iter().sum::<usize>() > 1000);
}

#[test]
fn fast_path_agrees_with_clarabel() {
    let mut rng = softcbf_tests::rng(11);
    let count = 10_200;
    let reference = QpSettings {
        use_fast_path: false,
        ..QpSettings::default()
    };
    let mut worst = 0.0_f64;
    let (mut agreements, mut disagreements, mut clarabel_failed) = (0, 0, 0);
    for k in 0..count {
        let inst = feasible_instance(&mut rng, k);
        let mut fast = SafetyQp::new(inst.n, inst.m, QpSettings::default()).unwrap();
        let mut clarabel = SafetyQp::new(inst.n, inst.m, reference).unwrap();
        let mut tau_fast = vec![0.0; inst.n];
        let mut tau_ref = vec![0.0; inst.n];
        let rf = fast
            .solve(&inst.tau_nom, &inst.a, &inst.b, &mut tau_fast)
            .clone();
        let rc = clarabel
            .solve(&inst.tau_nom, &inst.a, &inst.b, &mut tau_ref)
            .clone();
        assert_eq!(rf.status, QpStatus::Solved);
        if rc.status != QpStatus::Solved {
            clarabel_failed += 1;
            continue;
        }
        assert_eq!(rc.solver, QpSolver::Clarabel);
        let diff = tau_fast
            .iter()
            .zip(&tau_ref)
            .fold(0.0_f64, |acc, (x, y)| acc.max((x - y).abs()));
        let mut scale = 1.0 + inf_norm(&inst.tau_nom);
        for i in 0..inst.m {
            scale = scale.max(inst.b[i].abs() / row_norm(&inst.a[i * inst.n..(i + 1) * inst.n]));
        }
        let rel = diff / scale;
        if rel > 1e-6 {
            // Clarabel is accurate to about √clarabel_tol when a row is active with a
            // zero multiplier (rows through τ_nom, many rows through one point). The
            // fast τ then must be feasible and no worse in objective.
            let objective = |t: &[f64]| -> f64 {
                t.iter()
                    .zip(&inst.tau_nom)
                    .map(|(x, y)| 0.5 * (x - y) * (x - y))
                    .sum()
            };
            let violation = (0..inst.m)
                .map(|i| {
                    let row = &inst.a[i * inst.n..(i + 1) * inst.n];
                    let at: f64 = row.iter().zip(&tau_fast).map(|(x, y)| x * y).sum();
                    (inst.b[i] - at) / row_norm(row)
                })
                .fold(0.0_f64, f64::max);
            assert!(violation <= 1e-9 * scale, "instance {k}");
            assert!(objective(&tau_fast) <= objective(&tau_ref) + 1e-9 * scale * scale);
            disagreements += 1;
            continue;
        }
        agreements += 1;
        worst = worst.max(rel);
    }
    println!(
        "fast/clarabel: {agreements} agree (worst {worst:e}), {disagreements} differ with the \
         fast τ feasible and no worse, clarabel failed {clarabel_failed}"
    );
    assert!(agreements >= 10_000);
}

/// Newton step `H⁻¹ ∇f` of the relaxed objective
/// `f(τ) = ½‖τ − τ_nom‖² + ½ρ Σ max(0, b̂ᵢ − âᵢ·τ)²` (unit rows): zero at the optimum.
fn relaxed_newton_step(inst: &Instance, tau: &[f64], rho: f64) -> Vec<f64> {
    let n = inst.n;
    let mut g: Vec<f64> = tau.iter().zip(&inst.tau_nom).map(|(t, u)| t - u).collect();
    let mut h = vec![0.0; n * n];
    for j in 0..n {
        h[j * n + j] = 1.0;
    }
    for i in 0..inst.m {
        let row = &inst.a[i * n..(i + 1) * n];
        let norm = row_norm(row);
        let viol = (inst.b[i] - row.iter().zip(tau).map(|(x, y)| x * y).sum::<f64>()) / norm;
        if viol > 0.0 {
            for j in 0..n {
                g[j] -= rho * viol * row[j] / norm;
                for l in 0..n {
                    h[j * n + l] += rho * row[j] * row[l] / (norm * norm);
                }
            }
        }
    }
    // Gaussian elimination with partial pivoting.
    for col in 0..n {
        let piv = (col..n)
            .max_by(|&x, &y| h[x * n + col].abs().total_cmp(&h[y * n + col].abs()))
            .unwrap();
        for l in 0..n {
            h.swap(col * n + l, piv * n + l);
        }
        g.swap(col, piv);
        for r in col + 1..n {
            let f = h[r * n + col] / h[col * n + col];
            for l in col..n {
                h[r * n + l] -= f * h[col * n + l];
            }
            g[r] -= f * g[col];
        }
    }
    for r in (0..n).rev() {
        let mut acc = g[r];
        for l in r + 1..n {
            acc -= h[r * n + l] * g[l];
        }
        g[r] = acc / h[r * n + r];
    }
    g
}

#[test]
fn contradictory_rows_are_relaxed() {
    let rho = QpSettings::default().slack_penalty;
    for use_fast_path in [true, false] {
        let settings = QpSettings {
            use_fast_path,
            ..QpSettings::default()
        };
        let mut qp = SafetyQp::new(3, 3, settings).unwrap();
        // τ₀ ≥ 1, −τ₀ ≥ 0 (impossible together), τ₁ ≥ −5 (inactive).
        let a = [1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let b = [1.0, 0.0, -5.0];
        let tau_nom = [0.3, 2.0, -1.0];
        let mut tau = [0.0; 3];
        let report = qp.solve(&tau_nom, &a, &b, &mut tau).clone();
        assert_eq!(report.status, QpStatus::Relaxed);
        assert_eq!(report.relaxed_rows, vec![0, 1]);
        // Closed form: (τ₀ − 0.3) − ρ(1 − τ₀) + ρ τ₀ = 0.
        let expected = (0.3 + rho) / (1.0 + 2.0 * rho);
        assert!((tau[0] - expected).abs() < 1e-9, "{tau:?} vs {expected}");
        assert_eq!(&tau[1..], &tau_nom[1..]);
        assert!((report.max_violation - (1.0 - expected)).abs() < 1e-9);
    }
}

/// `solve_strict` answers the hard problem only: contradictory rows fail (NaN τ, nothing
/// relaxed), a feasible problem gets the same τ as `solve`.
#[test]
fn strict_solve_does_not_relax() {
    for use_fast_path in [true, false] {
        let settings = QpSettings {
            use_fast_path,
            ..QpSettings::default()
        };
        let mut qp = SafetyQp::new(3, 3, settings).unwrap();
        let a = [1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let tau_nom = [0.3, 2.0, -1.0];
        let mut tau = [0.0; 3];
        let report = qp
            .solve_strict(&tau_nom, &a, &[1.0, 0.0, -5.0], &mut tau)
            .clone();
        assert_eq!(report.status, QpStatus::Failed);
        assert!(report.relaxed_rows.is_empty());
        assert!(tau.iter().all(|x| x.is_nan()), "{tau:?}");
        // τ₀ ≥ 1, −τ₀ ≥ −4, τ₁ ≥ −5: τ = (1, 2, −1), the closed form.
        let b = [1.0, -4.0, -5.0];
        let report = qp.solve_strict(&tau_nom, &a, &b, &mut tau).clone();
        assert_eq!(report.status, QpStatus::Solved);
        let expected = [1.0, 2.0, -1.0];
        assert!(
            tau.iter().zip(expected).all(|(x, e)| (x - e).abs() < 1e-8),
            "{tau:?}"
        );
        let mut relaxing = [0.0; 3];
        qp.solve(&tau_nom, &a, &b, &mut relaxing);
        assert_eq!(tau, relaxing);
    }
}

#[test]
fn random_infeasible_instances_are_relaxed_optimally() {
    let mut rng = softcbf_tests::rng(3);
    let rho = QpSettings::default().slack_penalty;
    let mut worst = 0.0_f64;
    let mut failed = 0;
    for k in 0..2000 {
        let mut inst = feasible_instance(&mut rng, 4);
        if inst.m < 2 {
            continue;
        }
        // Make row 1 contradict row 0: −a₀·τ ≥ −b₀ + gap.
        let n = inst.n;
        let gap = row_norm(&inst.a[..n]) * rng.random_range(1e-3..1.0);
        let factor = 10f64.powf(rng.random_range(-2.0..2.0));
        for j in 0..n {
            inst.a[n + j] = -factor * inst.a[j];
        }
        inst.b[1] = factor * (-inst.b[0] + gap);
        for use_fast_path in [true, false] {
            let settings = QpSettings {
                use_fast_path,
                ..QpSettings::default()
            };
            let mut qp = SafetyQp::new(inst.n, inst.m, settings).unwrap();
            let mut tau = vec![0.0; n];
            let report = qp.solve(&inst.tau_nom, &inst.a, &inst.b, &mut tau).clone();
            if report.status == QpStatus::Failed {
                // Allowed (rarely) on these near-degenerate sets: τ is NaN, never wrong.
                assert!(tau.iter().all(|v| v.is_nan()));
                failed += 1;
                continue;
            }
            assert_eq!(
                report.status,
                QpStatus::Relaxed,
                "instance {k} fast {use_fast_path} {report:?} {tau:?} {inst:?}"
            );
            // The relaxed rows are exactly those violated by more than the tolerance.
            let violated: Vec<usize> = (0..inst.m)
                .filter(|&i| {
                    let row = &inst.a[i * n..(i + 1) * n];
                    let at: f64 = row.iter().zip(&tau).map(|(x, y)| x * y).sum();
                    (inst.b[i] - at) / row_norm(row) > QpSettings::default().relaxed_row_tol
                })
                .collect();
            assert!(!violated.is_empty());
            assert_eq!(report.relaxed_rows, violated);
            if use_fast_path {
                assert_eq!(report.solver, QpSolver::Fast);
            }
            let g = relaxed_newton_step(&inst, &tau, rho);
            let scale = 1.0 + inf_norm(&inst.tau_nom).max(inf_norm(&tau)) + gap;
            worst = worst.max(inf_norm(&g) / scale);
            // The check's own solve with H (condition up to 1 + ρ) is good to ~ρ·ε.
            assert!(
                inf_norm(&g) < 1e-7 * scale,
                "instance {k} fast {use_fast_path}: Newton step {g:?}"
            );
        }
    }
    println!("worst relative Newton step of relaxed solutions {worst:e}; failed {failed}/4000");
    assert!(failed <= 4, "{failed} failures");
}

#[test]
fn zero_row_with_positive_rhs_is_relaxed() {
    let mut qp = SafetyQp::new(2, 2, QpSettings::default()).unwrap();
    let mut tau = [0.0; 2];
    let report = qp.solve(&[1.0, 2.0], &[0.0, 0.0, 1.0, 0.0], &[0.5, 3.0], &mut tau);
    assert_eq!(report.status, QpStatus::Relaxed);
    assert_eq!(report.relaxed_rows, vec![0]);
    assert!((tau[0] - 3.0).abs() < 1e-6 && tau[1] == 2.0, "{tau:?}");
    // Zero row with b ≤ 0 always holds.
    let report = qp.solve(&[1.0, 2.0], &[0.0, 0.0, 1.0, 0.0], &[-0.5, 3.0], &mut tau);
    assert_eq!(report.status, QpStatus::Solved);
    assert_eq!(tau, [3.0, 2.0]);
}

#[test]
fn non_finite_input_fails_with_nan() {
    let good_a = [1.0, 0.0, 0.0, 1.0];
    let good_b = [0.0, 0.0];
    let good_tau = [-1.0, 1.0];
    for use_fast_path in [true, false] {
        let settings = QpSettings {
            use_fast_path,
            ..QpSettings::default()
        };
        let mut qp = SafetyQp::new(2, 2, settings).unwrap();
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            for slot in 0..8 {
                let (mut a, mut b, mut t) = (good_a, good_b, good_tau);
                match slot {
                    0..4 => a[slot] = bad,
                    4..6 => b[slot - 4] = bad,
                    _ => t[slot - 6] = bad,
                }
                let mut tau = [0.0; 2];
                let report = qp.solve(&t, &a, &b, &mut tau);
                assert_eq!(report.status, QpStatus::Failed);
                assert!(report.max_violation.is_nan());
                assert!(tau.iter().all(|v| v.is_nan()));
            }
        }
        // Wrong lengths fail too.
        let mut tau = [0.0; 2];
        assert_eq!(
            qp.solve(&good_tau, &good_a[..3], &good_b, &mut tau).status,
            QpStatus::Failed
        );
        assert!(tau.iter().all(|v| v.is_nan()));
        // And the solver recovers on good input.
        let report = qp.solve(&good_tau, &good_a, &good_b, &mut tau);
        assert_eq!(report.status, QpStatus::Solved);
        assert!((tau[0]).abs() < 1e-7 && (tau[1] - 1.0).abs() < 1e-7);
    }
}

#[test]
fn feasible_tau_nom_is_returned_exactly() {
    let mut rng = softcbf_tests::rng(5);
    for k in 0..2000 {
        let inst = feasible_instance(&mut rng, 3);
        for use_fast_path in [true, false] {
            let settings = QpSettings {
                use_fast_path,
                ..QpSettings::default()
            };
            let mut qp = SafetyQp::new(inst.n, inst.m, settings).unwrap();
            let mut tau = vec![0.0; inst.n];
            let report = qp.solve(&inst.tau_nom, &inst.a, &inst.b, &mut tau);
            assert_eq!(
                report.status,
                QpStatus::Solved,
                "{k} {use_fast_path} {inst:?}"
            );
            if use_fast_path {
                assert_eq!(tau, inst.tau_nom, "instance {k}");
                assert_eq!(report.active, 0);
            } else {
                let diff = tau.iter().zip(&inst.tau_nom).map(|(x, y)| (x - y).abs());
                // Interior point: accurate to about √clarabel_tol when a row is
                // nearly active at τ_nom.
                let d = diff.fold(0.0, f64::max);
                assert!(d < 1e-5 * (1.0 + inf_norm(&inst.tau_nom)), "{d:e}");
            }
        }
    }
}

#[test]
fn settings_are_validated() {
    assert!(QpSettings::default().validate().is_ok());
    let bad = QpSettings {
        slack_penalty: 0.5,
        ..QpSettings::default()
    };
    assert!(matches!(
        SafetyQp::new(6, 12, bad),
        Err(QpSetupError::Setting {
            field: "slack_penalty",
            ..
        })
    ));
    let bad = QpSettings {
        kkt_tol: f64::NAN,
        ..QpSettings::default()
    };
    assert!(bad.validate().is_err());
    assert!(matches!(
        SafetyQp::new(0, 3, QpSettings::default()),
        Err(QpSetupError::NoInputs)
    ));
}

#[test]
fn fast_path_does_not_allocate() {
    let mut rng = softcbf_tests::rng(9);
    let mut instances: Vec<Instance> = Vec::new();
    while instances.len() < 200 {
        let inst = feasible_instance(&mut rng, instances.len());
        if inst.n == 6 && inst.m == 12 {
            instances.push(inst);
        }
    }
    // Some infeasible ones so that the relaxed fast path runs too.
    for inst in instances.iter_mut().step_by(10) {
        for j in 0..6 {
            inst.a[6 + j] = -inst.a[j];
        }
        inst.b[1] = -inst.b[0] + 1.0;
    }
    let mut qp = SafetyQp::new(6, 12, QpSettings::default()).unwrap();
    let mut tau = vec![0.0; 6];
    qp.solve(
        &instances[0].tau_nom,
        &instances[0].a,
        &instances[0].b,
        &mut tau,
    );
    let before = allocations();
    let mut relaxed = 0;
    for _ in 0..5 {
        for inst in &instances {
            let report = qp.solve(&inst.tau_nom, &inst.a, &inst.b, &mut tau);
            assert_eq!(report.solver, QpSolver::Fast);
            relaxed += usize::from(report.status == QpStatus::Relaxed);
        }
    }
    let fast_allocs = allocations() - before;
    assert_eq!(fast_allocs, 0);
    assert!(relaxed >= 100);

    let reference = QpSettings {
        use_fast_path: false,
        ..QpSettings::default()
    };
    let mut clarabel = SafetyQp::new(6, 12, reference).unwrap();
    clarabel.solve(
        &instances[1].tau_nom,
        &instances[1].a,
        &instances[1].b,
        &mut tau,
    );
    let before = allocations();
    for inst in &instances[1..101] {
        clarabel.solve(&inst.tau_nom, &inst.a, &inst.b, &mut tau);
    }
    println!(
        "clarabel path: {} allocations per solve",
        (allocations() - before) as f64 / 100.0
    );
}

/// One solver reused along a path of slowly changing problems (as from tick to tick, when
/// it starts from the previous active set) gives what a fresh solver gives for each, to
/// rounding, including where the active set changes; so does one reused across unrelated
/// problems (a wrong guess).
#[test]
fn warm_started_solves_agree_with_fresh_ones() {
    let mut rng = softcbf_tests::rng(23);
    let mut warm = SafetyQp::new(6, 12, QpSettings::default()).unwrap();
    let (mut changes, mut compared, mut active_solves) = (0, 0, 0);
    let mut last_active = usize::MAX;
    for path in 0..60 {
        let base = loop {
            let inst = feasible_instance(&mut rng, path);
            if inst.n == 6 && inst.m == 12 {
                break inst;
            }
        };
        let scale = 1.0 + inf_norm(&base.tau_nom);
        let drift_tau: Vec<f64> = (0..6)
            .map(|_| scale * rng.random_range(-0.02..0.02))
            .collect();
        let drift_b: Vec<f64> = (0..12)
            .map(|_| scale * rng.random_range(-0.01..0.01))
            .collect();
        for step in 0..100 {
            let t = step as f64;
            let mut inst = base.clone();
            for (v, d) in inst.tau_nom.iter_mut().zip(&drift_tau) {
                *v += t * d;
            }
            for (i, d) in drift_b.iter().enumerate() {
                let norm = row_norm(&inst.a[i * 6..(i + 1) * 6]);
                inst.b[i] += t * d * norm;
            }
            let mut fresh = SafetyQp::new(6, 12, QpSettings::default()).unwrap();
            let (mut tau_warm, mut tau_fresh) = (vec![0.0; 6], vec![0.0; 6]);
            let rw = warm
                .solve(&inst.tau_nom, &inst.a, &inst.b, &mut tau_warm)
                .clone();
            let rf = fresh
                .solve(&inst.tau_nom, &inst.a, &inst.b, &mut tau_fresh)
                .clone();
            assert_eq!(rw.status, rf.status, "path {path} step {step}");
            if rw.status != QpStatus::Solved {
                continue;
            }
            compared += 1;
            let diff = tau_warm
                .iter()
                .zip(&tau_fresh)
                .fold(0.0_f64, |acc, (a, b)| acc.max((a - b).abs()));
            let tol = 1e-9 * (1.0 + inf_norm(&tau_fresh));
            assert!(
                diff <= tol,
                "path {path} step {step}: τ differs by {diff:e}"
            );
            let res = kkt_residual(&inst, &tau_warm, warm.multipliers());
            assert!(res < 1e-9, "path {path} step {step}: KKT residual {res:e}");
            if rw.active > 0 {
                active_solves += 1;
            }
            if rw.active != last_active {
                changes += 1;
                last_active = rw.active;
            }
        }
    }
    println!("{compared} compared, {active_solves} with active rows, {changes} active-set changes");
    assert!(compared > 3000 && active_solves > 1000 && changes > 100);
}
