//! Criterion benchmark of the safety QP (n = 6, m = 12): fast path versus clarabel on
//! a realistic mix of instances (0–6 active rows), plus a repeat of the fast path as a noise estimate.

use criterion::{Criterion, criterion_group, criterion_main};
use softcbf::qp::{QpSettings, SafetyQp};
use std::hint::black_box;

const N: usize = 6;
const M: usize = 12;

/// Deterministic pseudo-random numbers in [-1, 1) (xorshift), no extra dependency.
struct Xorshift(u64);

impl Xorshift {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// Rows with scales over four decades; τ_nom pushed against a random number of rows.
fn instances(count: usize) -> Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let mut rng = Xorshift(0x9e37_79b9_7f4a_7c15);
    (0..count)
        .map(|k| {
            let tau_nom: Vec<f64> = (0..N).map(|_| 5.0 * rng.next()).collect();
            let mut a = vec![0.0; M * N];
            let mut b = vec![0.0; M];
            let pushing = k % 7; // rows that cut τ_nom off
            for i in 0..M {
                let scale = 10f64.powf(2.0 * rng.next());
                for j in 0..N {
                    a[i * N + j] = scale * rng.next();
                }
                let at: f64 = (0..N).map(|j| a[i * N + j] * tau_nom[j]).sum();
                let norm = (0..N).map(|j| a[i * N + j].powi(2)).sum::<f64>().sqrt();
                let margin = norm * (0.5 + rng.next().abs());
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
