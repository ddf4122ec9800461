//! The readings' noise and what it does to the estimates: its variance measured at the
//! static rest states, and the logs with as much noise again, whose fit shows the bias
//! the noise causes (noise in the filtered readings of the regressor, errors in the
//! variables).

use rand::SeedableRng;
use rand::rngs::Xoshiro256PlusPlus;
use softcbf_core::noise::standard_normal;

use super::logs::Log;

/// The seed of the added noise: the same logs always give the same report.
pub const SEED: u64 = 0x5eed_0f4e;

/// The standard deviation of each coordinate's readings at rest, pooled over every rest
/// state of `logs` (a run of rest readings within one step); `None` without a rest state
/// of two readings.
pub fn at_rest(logs: &[Log]) -> Option<Vec<f64>> {
    let nq = logs.first()?.nq;
    let (mut squares, mut freedom) = (vec![0.0; nq], 0usize);
    let mut mean = vec![0.0; nq];
    for log in logs {
        let n = log.readings();
        let mut start = 0;
        while start < n {
            let mut end = start + 1;
            while end < n && log.rest[start] == log.rest[end] && log.step[end] == log.step[start] {
                end += 1;
            }
            if log.rest[start] && end - start >= 2 {
                mean.fill(0.0);
                for j in start..end {
                    for (m, v) in mean.iter_mut().zip(log.q_of(j)) {
                        *m += v;
                    }
                }
                let count = (end - start) as f64;
                mean.iter_mut().for_each(|m| *m /= count);
                for j in start..end {
                    for ((s, m), v) in squares.iter_mut().zip(&mean).zip(log.q_of(j)) {
                        *s += (v - m) * (v - m);
                    }
                }
                freedom += end - start - 1;
            }
            start = end;
        }
    }
    (freedom > 0).then(|| {
        squares
            .iter()
            .map(|s| (s / freedom as f64).sqrt())
            .collect()
    })
}

/// `log` with Gaussian noise of standard deviation `sigma` (per coordinate) added to
/// every reading, drawn from `seed`.
pub fn with_added(log: &Log, sigma: &[f64], seed: u64) -> Log {
    let mut draws = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut noisy = log.clone();
    for reading in noisy.q.chunks_exact_mut(log.nq) {
        for (v, s) in reading.iter_mut().zip(sigma) {
            *v += s * standard_normal(&mut draws);
        }
    }
    noisy
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_noise_at_rest_is_found_and_added_noise_doubles_its_variance() {
        let nq = 2;
        let n = 4000;
        let mut log = Log {
            dir: Default::default(),
            file: Default::default(),
            kind: None,
            rows: n,
            nq,
            servos: 0,
            time: (0..n).map(|j| 0.01 * j as f64).collect(),
            line: (2..n + 2).collect(),
            q: vec![0.0; n * nq],
            step: vec![0.0; n],
            rest: vec![false; n],
            landing: Vec::new(),
            current: Vec::new(),
            end: 0.01 * n as f64,
        };
        let sigma = [1e-4, 3e-4];
        // Two rest states at different places, and moving readings between them.
        for j in 0..n {
            log.rest[j] = !(1500..2500).contains(&j);
            log.step[j] = if j < 2000 { 0.0 } else { 1.0 };
            let base = if j < 2000 {
                [0.01, -0.02]
            } else {
                [0.03, 0.05]
            };
            let moving = if log.rest[j] { 0.0 } else { 1e-3 * j as f64 };
            for (v, b) in log.q[j * nq..(j + 1) * nq].iter_mut().zip(base) {
                *v = b + moving;
            }
        }
        let exact = at_rest(std::slice::from_ref(&log)).unwrap();
        assert!(exact.iter().all(|&s| s < 1e-12), "{exact:?}");
        let noisy = with_added(&log, &sigma, 1);
        let measured = at_rest(std::slice::from_ref(&noisy)).unwrap();
        for (m, s) in measured.iter().zip(&sigma) {
            assert!((m / s - 1.0).abs() < 0.05, "{m} against {s}");
        }
        let twice = with_added(&noisy, &measured, 2);
        let doubled = at_rest(std::slice::from_ref(&twice)).unwrap();
        for (d, s) in doubled.iter().zip(&sigma) {
            assert!(
                (d / (s * 2f64.sqrt()) - 1.0).abs() < 0.07,
                "{d} against √2·{s}"
            );
        }
        assert!(at_rest(&[]).is_none());
    }
}
