//! Criterion benchmark of the safety QP (n = 6, m = 12): fast path versus clarabel on
//! a realistic mix of instances (0–6 active rows), plus a repeat of the fast path as a noise estimate.

use criterion::{Criterion, criterion_group, criterion_main};
use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use softcbf::linalg::dot;
use softcbf::qp::{QpSettings, SafetyQp};
use std::hint::black_box;

const N: usize = 6;
const M: usize = 12;

/// Rows with scales over four decades; τ_nom pushed against a random number of rows.
fn instances(count: usize) -> Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(0x9e37_79b9_7f4a_7c15);
    let mut next = move || rng.random_range(-1.0..1.0);
    (0..count)
        .map(|k| {
            let tau_nom: Vec<f64> = (0..N).map(|_| 5.0 * next()).collect();
            let mut a = vec![0.0; M * N];
            let mut b = vec![0.0; M];
            let pushing = k % 7; // rows that cut τ_nom off
            for i in 0..M {
                let scale = 10f64.powf(2.0 * next());
                for j in 0..N {
                    a[i * N + j] = scale * next();
                }
                let row = &a[i * N..(i + 1) * N];
                let at = dot(row, &tau_nom);
                let norm = dot(row, row).sqrt();
                let margin = norm * (0.5 + next().abs());
                b[i] = if i < pushing {
                    at + margin
                } else {
                    at - margin
                };
            }
            (tau_nom, a, b)
        })
        .collect()
}

fn bench_qp(c: &mut Criterion) {
    let set = instances(64);
    let mut fast = SafetyQp::new(N, M, QpSettings::default()).expect("valid settings");
    let reference = QpSettings {
        use_fast_path: false,
        ..QpSettings::default()
    };
    let mut clarabel = SafetyQp::new(N, M, reference).expect("valid settings");
    let mut tau = [0.0; N];
    for name in ["fast_path", "fast_path_repeat"] {
        c.bench_function(&format!("qp_6x12/{name}"), |bench| {
            let mut k = 0;
            bench.iter(|| {
                let (t, a, b) = &set[k % set.len()];
                k += 1;
                black_box(
                    fast.solve(black_box(t), black_box(a), black_box(b), &mut tau)
                        .status,
                )
            })
        });
    }
    c.bench_function("qp_6x12/clarabel", |bench| {
        let mut k = 0;
        bench.iter(|| {
            let (t, a, b) = &set[k % set.len()];
            k += 1;
            black_box(
                clarabel
                    .solve(black_box(t), black_box(a), black_box(b), &mut tau)
                    .status,
            )
        })
    });
}

criterion_group!(benches, bench_qp);
criterion_main!(benches);
