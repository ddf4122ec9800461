//! The emitted small-θ functions `pcc_fs_fc_6` against the double-double reference: exact
//! limits at 0, tiny and subnormal u, a dense grid, both sides of every switch, derivatives.

use rand::RngExt;
use softcbf_codegen::analytic::SWITCH_POINTS;
use softcbf_tests::analytic::pcc_fs_fc_6;
use softcbf_tests::highprec::{DD, fs_fc_reference, limits_at_zero};

const ORDER: usize = 6;

/// Error of `x` against `exact` in units of the acceptance bound
/// `1e-14·|exact| + 1e-15·s`, `s = |f^(k)(0)|` (the largest magnitude of that order).
fn bound_ratio(x: f64, exact: DD, s: f64) -> f64 {
    let err = (DD::from_f64(x) - exact).abs().to_f64();
    err / (1e-14 * exact.abs().to_f64() + 1e-15 * s)
}

/// `(|f_s^(k)(0)|, |f_c^(k)(0)|)`.
fn scales(k: usize) -> (f64, f64) {
    let (s, c) = limits_at_zero(k);
    (s.abs().to_f64(), c.abs().to_f64())
}

/// Worst bound ratio over all orders and both functions at `u`, with the order and name.
fn worst_at(u: f64) -> (f64, usize, &'static str) {
    let (fs, fc) = pcc_fs_fc_6(u);
    let (rs, rc) = fs_fc_reference(u, ORDER);
    let mut worst = (0.0, 0, "f_s");
    for k in 0..=ORDER {
        let (ss, sc) = scales(k);
        let es = bound_ratio(fs[k], rs[k], ss);
        let ec = bound_ratio(fc[k], rc[k], sc);
        if es > worst.0 || es.is_nan() {
            worst = (es, k, "f_s");
        }
        if ec > worst.0 || ec.is_nan() {
            worst = (ec, k, "f_c");
        }
    }
    worst
}

fn assert_accurate(points: &[f64]) {
    for &u in points {
        let (ratio, k, name) = worst_at(u);
        assert!(
            ratio <= 1.0,
            "u = {u:e}: {name}^({k}) error is {ratio:.3} × the bound"
        );
    }
}

#[test]
fn exact_limits_at_zero() {
    let (fs, fc) = pcc_fs_fc_6(0.0);
    for k in 0..=ORDER {
        let (s0, c0) = limits_at_zero(k);
        // The correctly rounded exact limits (−1)^k k!/(2k+1)! and (−1)^k k!/(2k+2)!.
        assert_eq!(fs[k], s0.to_f64(), "f_s^({k})(0)");
        assert_eq!(fc[k], c0.to_f64(), "f_c^({k})(0)");
    }
    assert_eq!((fs[0], fc[0], fs[1]), (1.0, 0.5, -1.0 / 6.0));
    // −0.0 is the same point.
    assert_eq!(pcc_fs_fc_6(-0.0), pcc_fs_fc_6(0.0));
}

#[test]
fn tiny_and_subnormal_u() {
    assert_accurate(&[
        5e-324,
        1e-320,
        1e-310,
        2.2250738585072014e-308,
        1e-300,
        1e-200,
    ]);
    assert_accurate(&[1e-100, 1e-30, 1e-16, 1e-12, 1e-8, 1e-6, 1e-4]);
    // So close to 0 the values are the limits themselves.
    let (fs, fc) = pcc_fs_fc_6(5e-324);
    for k in 0..=ORDER {
        let (s0, c0) = limits_at_zero(k);
        assert_eq!((fs[k], fc[k]), (s0.to_f64(), c0.to_f64()));
    }
}

#[test]
fn dense_log_grid() {
    let n = 3000;
    let points: Vec<f64> = (0..=n)
        .map(|i| 10f64.powf(-12.0 + 14.0 * i as f64 / n as f64))
        .collect();
    assert_accurate(&points);
}

#[test]
fn dense_linear_grid() {
    let points: Vec<f64> = (1..=2000).map(|i| i as f64 * 0.05).collect();
    assert_accurate(&points);
}

#[test]
fn both_sides_of_every_switch() {
    for &uk in &SWITCH_POINTS {
        let mut points = vec![uk, uk * (1.0 - 1e-9), uk * (1.0 + 1e-9)];
        points.extend([uk * (1.0 - 1e-6), uk * (1.0 + 1e-6), uk * 0.99, uk * 1.01]);
        let (mut below, mut above) = (uk, uk);
        for _ in 0..3 {
            below = below.next_down();
            above = above.next_up();
            points.extend([below, above]);
        }
        assert_accurate(&points);
        // No visible jump: values one ulp apart agree to the bound on both sides.
        let (ls, lc) = pcc_fs_fc_6(uk.next_down());
        let (rs, rc) = pcc_fs_fc_6(uk);
        for k in 0..=ORDER {
            let (ss, sc) = scales(k);
            assert!(
                (ls[k] - rs[k]).abs() <= 2e-15 * ss,
                "U = {uk}: f_s^({k}) jumps"
            );
            assert!(
                (lc[k] - rc[k]).abs() <= 2e-15 * sc,
                "U = {uk}: f_c^({k}) jumps"
            );
        }
    }
}

#[test]
fn random_points() {
    let mut rng = softcbf_tests::rng(0x5eed_5cbf);
    let mut points = Vec::new();
    for _ in 0..1000 {
        points.push(100.0 * rng.random::<f64>());
        points.push(10f64.powf(-20.0 + 22.0 * rng.random::<f64>()));
    }
    assert_accurate(&points);
}

/// Per order: the worst error (in units of the bound) below and above its switch point,
/// printed as the table in the module docs (`cargo test -- --nocapture error_table`).
#[test]
fn error_table() {
    let mut points: Vec<f64> = (0..=4000)
        .map(|i| 10f64.powf(-12.0 + 14.0 * i as f64 / 4000.0))
        .collect();
    points.extend((1..=4000).map(|i| i as f64 * 0.025));
    let mut below = [0.0_f64; ORDER + 1];
    let mut above = [0.0_f64; ORDER + 1];
    // Largest |error|/s and largest relative error where |x| ≥ s/100.
    let (mut abs_s, mut rel) = ([0.0_f64; ORDER + 1], [0.0_f64; ORDER + 1]);
    for &u in &points {
        let (fs, fc) = pcc_fs_fc_6(u);
        let (rs, rc) = fs_fc_reference(u, ORDER);
        for k in 0..=ORDER {
            let (ss, sc) = scales(k);
            let e = bound_ratio(fs[k], rs[k], ss).max(bound_ratio(fc[k], rc[k], sc));
            let side = if u < SWITCH_POINTS[k] {
                &mut below
            } else {
                &mut above
            };
            side[k] = side[k].max(e);
            for (x, r, sk) in [(fs[k], rs[k], ss), (fc[k], rc[k], sc)] {
                let err = (DD::from_f64(x) - r).abs().to_f64();
                abs_s[k] = abs_s[k].max(err / sk);
                if r.abs().to_f64() >= 0.01 * sk {
                    rel[k] = rel[k].max(err / r.abs().to_f64());
                }
            }
        }
    }
    println!(
        "| order | U_k | below U_k | above U_k | max abs err / s | max rel err (abs x ≥ s/100) |"
    );
    for k in 0..=ORDER {
        println!(
            "| {k} | {} | {:.3} | {:.3} | {:.1e} | {:.1e} |",
            SWITCH_POINTS[k], below[k], above[k], abs_s[k], rel[k]
        );
        assert!(below[k] <= 1.0 && above[k] <= 1.0, "order {k}");
    }
}

/// Each derivative against central differences of the order below (coarse check).
#[test]
fn derivatives_match_central_differences() {
    let mut points = vec![0.03, 0.5, 2.0, 9.0, 20.0, 40.0, 70.0];
    points.extend(SWITCH_POINTS.iter().filter(|&&u| u > 1e-3));
    for &u in &points {
        let h = 1e-4 * u.max(0.1);
        let (up, um) = (u + h, u - h);
        let (fs, fc) = pcc_fs_fc_6(u);
        let (ps, pc) = pcc_fs_fc_6(up);
        let (ms, mc) = pcc_fs_fc_6(um);
        for k in 0..ORDER {
            let (ss, sc) = scales(k + 1);
            let ds = (ps[k] - ms[k]) / (up - um);
            let dc = (pc[k] - mc[k]) / (up - um);
            assert!(
                (ds - fs[k + 1]).abs() <= 1e-6 * ss,
                "u = {u}: f_s^({}) {} vs difference {ds}",
                k + 1,
                fs[k + 1]
            );
            assert!(
                (dc - fc[k + 1]).abs() <= 1e-6 * sc,
                "u = {u}: f_c^({}) {} vs difference {dc}",
                k + 1,
                fc[k + 1]
            );
        }
    }
}

#[test]
fn nan_and_infinity() {
    let (fs, fc) = pcc_fs_fc_6(f64::NAN);
    assert!(fs.iter().chain(fc.iter()).all(|x| x.is_nan()));
    // Any value, but no panic.
    let _ = pcc_fs_fc_6(f64::INFINITY);
    let (fs, fc) = pcc_fs_fc_6(f64::MAX);
    assert!(fs.iter().chain(fc.iter()).all(|x| x.is_finite()));
}
