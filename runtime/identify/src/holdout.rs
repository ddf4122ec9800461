//! The held-out check: the last part of a dynamic log, kept out of the fit, simulated by
//! the plant from the measured state at its start under the logged currents (held from
//! each command's landing), with the identified numbers and with the file's.

use crate::hardware_description::Hardware;
use crate::integrator::Tolerances;
use crate::model::Model;

use super::filter::{Kernel, trapezoid_weight};
use super::logs::Log;
use super::rows::holdout_start;

/// The simulations' tolerances: a micrometre is far below what a figure shows or a
/// prediction error of interest (the plant's default, `atol` 1e-9, takes about 6 steps
/// per millisecond; these about one).
const TOLERANCES: Tolerances = Tolerances {
    rtol: 1e-5,
    atol: 1e-6,
    h_initial: 1e-4,
    h_min: 1e-12,
    h_max: f64::INFINITY,
    max_steps: 100_000,
};

/// A robot to simulate: its model and the actuator gain of each servo \[N/mA\].
#[derive(Clone, Copy)]
pub struct Plant<'a> {
    /// Dynamics (stiffness, damping, masses).
    pub model: &'a Model,
    /// Gains, one per servo.
    pub gains: &'a [f64],
}

/// Measured and predicted `q` over a held-out part.
#[derive(Clone, Debug, PartialEq)]
pub struct Prediction {
    /// The log's name.
    pub log: String,
    /// Number of coordinates.
    pub nq: usize,
    /// Reading times \[s\].
    pub t: Vec<f64>,
    /// Measured `q`, `nq` per time \[m\].
    pub measured: Vec<f64>,
    /// Predicted `q` of each plant (identified, file), `nq` per time \[m\]; NaN after a
    /// failed step.
    pub predicted: Vec<Vec<f64>>,
    /// RMS of `q − q_measured` over times and coordinates, per plant \[m\].
    pub rms: Vec<f64>,
}

/// Simulates each of `plants` over the held-out part of `log` (at most `horizon` seconds
/// of it); `None` when that part holds no full filter window (the initial velocity is
/// the filtered one).
pub fn predict(
    plants: &[Plant<'_>],
    hardware: &Hardware,
    log: &Log,
    kernel: &Kernel,
    holdout: f64,
    horizon: f64,
) -> Result<Option<Prediction>, String> {
    let start = holdout_start(log, holdout);
    let t_half = kernel.half_width();
    let n = log.readings();
    let nq = log.nq;
    let Some(j0) = (0..n).find(|&j| log.time[j] >= start + t_half) else {
        return Ok(None);
    };
    let t0 = log.time[j0];
    if t0 + t_half > log.time[n - 1] || log.landing.first().is_none_or(|&l| l > t0) {
        return Ok(None);
    }
    // The filtered velocity at t0.
    let (mut f1, mut v0) = (0.0, vec![0.0; nq]);
    for j in 0..n {
        let [k0, k1, _] = kernel.values(t0 - log.time[j]);
        if k0 == 0.0 {
            continue;
        }
        let w = trapezoid_weight(&log.time, j);
        f1 += w * k0;
        for (v, q) in v0.iter_mut().zip(log.q_of(j)) {
            *v += w * k1 * q;
        }
    }
    v0.iter_mut().for_each(|v| *v /= f1);
    let end = log.time[n - 1].min(t0 + horizon);
    let last = (j0..n)
        .take_while(|&j| log.time[j] <= end)
        .last()
        .unwrap_or(j0);
    let t: Vec<f64> = log.time[j0..=last].to_vec();
    let measured: Vec<f64> = log.q[j0 * nq..(last + 1) * nq].to_vec();
    let directions: Vec<f64> = hardware.modules.iter().flat_map(|m| m.directions).collect();
    let mut predicted = Vec::with_capacity(plants.len());
    let mut rms = Vec::with_capacity(plants.len());
    // The plants' simulations are independent: one thread each.
    let simulated = super::parallel_map(plants.len(), |k| {
        simulate(&plants[k], &directions, log, j0, last, &v0)
    });
    for q in simulated {
        let q = q?;
        let (mut sum, mut count) = (0.0, 0usize);
        for (a, b) in q.iter().zip(&measured) {
            if a.is_finite() {
                sum += (a - b).powi(2);
                count += 1;
            }
        }
        rms.push(if count > 0 {
            (sum / count as f64).sqrt()
        } else {
            f64::NAN
        });
        predicted.push(q);
    }
    Ok(Some(Prediction {
        log: log.name(),
        nq,
        t,
        measured,
        predicted,
        rms,
    }))
}

/// `q` of `plant` at readings `j0..=last` of `log`, from `q(j0)` and `v0`.
fn simulate(
    plant: &Plant<'_>,
    directions: &[f64],
    log: &Log,
    j0: usize,
    last: usize,
    v0: &[f64],
) -> Result<Vec<f64>, String> {
    let model = plant.model;
    let nq = model.nq();
    let mut sim = crate::plant::Plant::new(model, TOLERANCES).map_err(|e| e.to_string())?;
    sim.reset(log.q_of(j0), v0, log.time[j0]);
    let geometry: Vec<[[f64; 3]; 3]> = model
        .robot
        .modules
        .iter()
        .map(|m| {
            std::array::from_fn(|c| {
                std::array::from_fn(|k| match c {
                    0 => m.tendon_angles[k].cos(),
                    1 => m.tendon_angles[k].sin(),
                    _ => -1.0,
                })
            })
        })
        .collect();
    let apply = |sim: &mut crate::plant::Plant<'_>, m: usize| {
        let currents = log.current_of(m);
        let tau = sim.tau_mut();
        for (i, a) in geometry.iter().enumerate() {
            for c in 0..3 {
                tau[3 * i + c] = (0..3)
                    .map(|k| {
                        let s = 3 * i + k;
                        a[c][k] * plant.gains[s] * (directions[s] * currents[s]).max(0.0)
                    })
                    .sum();
            }
        }
    };
    let mut m = (0..log.landing.len())
        .take_while(|&m| log.landing[m] <= log.time[j0])
        .last()
        .unwrap_or(0);
    apply(&mut sim, m);
    let mut out = Vec::with_capacity((last - j0 + 1) * nq);
    out.extend_from_slice(log.q_of(j0));
    let mut failed = false;
    for j in j0 + 1..=last {
        if !failed {
            while m + 1 < log.landing.len() && log.landing[m + 1] <= log.time[j] {
                m += 1;
                if sim.advance(log.landing[m] - sim.time()).is_err() {
                    failed = true;
                    break;
                }
                apply(&mut sim, m);
            }
        }
        if !failed && sim.advance(log.time[j] - sim.time()).is_err() {
            failed = true;
        }
        if failed {
            out.extend(std::iter::repeat_n(f64::NAN, nq));
        } else {
            out.extend_from_slice(sim.q());
        }
    }
    Ok(out)
}
