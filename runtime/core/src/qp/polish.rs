//! Exact polish of an approximate relaxed-QP solution: semismooth Newton on
//! `½‖τ − τ_nom‖² + ½ρ Σ max(0, b̂ᵢ − âᵢ·τ)²`, each step a Householder least squares.

use super::scaled_norm;
use crate::linalg::dot;

/// Newton steps before the polish gives up.
const MAX_NEWTON: usize = 50;

/// `½‖τ − τ_nom‖² + ½ρ Σ max(0, b̂ᵢ − âᵢ·τ)²`.
fn objective(rows: &[f64], b: &[f64], tau_nom: &[f64], tau: &[f64], rho: f64) -> f64 {
    let n = tau.len();
    let mut f: f64 = tau
        .iter()
        .zip(tau_nom)
        .map(|(t, u)| 0.5 * (t - u) * (t - u))
        .sum();
    for (i, bi) in b.iter().enumerate() {
        let v = (bi - dot(&rows[i * n..(i + 1) * n], tau)).max(0.0);
        f += 0.5 * rho * v * v;
    }
    f
}

/// Workspace for `n` inputs and `m` unit-norm rows.
#[derive(Debug)]
pub(crate) struct RelaxedPolish {
    n: usize,
    m: usize,
    /// Least-squares matrix `[I; √ρ Â_V]`, column-major, leading dimension `n + m`.
    mat: Vec<f64>,
    rhs: Vec<f64>,
    v: Vec<f64>,
    pressing: Vec<bool>,
    current: Vec<f64>,
    candidate: Vec<f64>,
    /// Polished `(τ, σ)` with `σ = c z`, `c = 1/√ρ`.
    pub x: Vec<f64>,
    /// Polished multipliers `zᵢ = ρ max(0, b̂ᵢ − âᵢ·τ)`.
    pub z: Vec<f64>,
}

impl RelaxedPolish {
    pub(crate) fn new(n: usize, m: usize) -> Self {
        let ld = n + m;
        Self {
            n,
            m,
            mat: vec![0.0; ld * n],
            rhs: vec![0.0; ld],
            v: vec![0.0; ld],
            pressing: vec![false; m],
            current: vec![0.0; n],
            candidate: vec![0.0; n],
            x: vec![0.0; ld],
            z: vec![0.0; m],
        }
    }

    /// Starts from `tau0` and multipliers `z0` (from a solver) and takes Newton
    /// steps, backtracking when the objective does not decrease, until a full step
    /// leaves the set of pressing rows unchanged. Returns whether it settled.
    pub(crate) fn run(
        &mut self,
        rows: &[f64],
        b: &[f64],
        tau_nom: &[f64],
        (tau0, z0): (&[f64], &[f64]),
        rho: f64,
    ) -> bool {
        let (n, m) = (self.n, self.m);
        if tau0.len() < n || z0.len() < m {
            return false;
        }
        for i in 0..m {
            let violation = b[i] - dot(&rows[i * n..(i + 1) * n], &tau0[..n]);
            self.pressing[i] = violation + z0[i] / rho > 0.0;
        }
        self.current[..n].copy_from_slice(&tau0[..n]);
        let mut f_current = objective(rows, b, tau_nom, &self.current[..n], rho);
        for _ in 0..MAX_NEWTON {
            if !self.newton_step(rows, b, tau_nom, rho) {
                return false;
            }
            // x[..n] holds the full step; backtrack along it if f does not decrease.
            let mut t = 1.0;
            let mut f_new = objective(rows, b, tau_nom, &self.x[..n], rho);
            let allowed = f_current + 1e-12 * f_current.abs();
            while f_new > allowed && t > 1e-12 {
                t *= 0.5;
                for j in 0..n {
                    self.candidate[j] = self.current[j] + t * (self.x[j] - self.current[j]);
                }
                f_new = objective(rows, b, tau_nom, &self.candidate[..n], rho);
            }
            if t < 1.0 {
                self.x[..n].copy_from_slice(&self.candidate[..n]);
            }
            let mut changed = false;
            for i in 0..m {
                let violation = b[i] - dot(&rows[i * n..(i + 1) * n], &self.x[..n]);
                let now = violation > 0.0;
                changed |= now != self.pressing[i];
                self.pressing[i] = now;
                self.z[i] = rho * violation.max(0.0);
                self.x[n + i] = self.z[i] / rho.sqrt();
            }
            if !changed && t == 1.0 {
                return true;
            }
            self.current[..n].copy_from_slice(&self.x[..n]);
            f_current = f_new.min(f_current);
        }
        false
    }

    /// Minimises `½‖τ − τ_nom‖² + ½ρ Σ_{pressing} (âᵢ·τ − b̂ᵢ)²` into `x[..n]`.
    fn newton_step(&mut self, rows: &[f64], b: &[f64], tau_nom: &[f64], rho: f64) -> bool {
        let (n, m) = (self.n, self.m);
        let ld = n + m;
        let sr = rho.sqrt();
        let mut k = n;
        self.rhs[..n].copy_from_slice(tau_nom);
        for j in 0..n {
            let col = &mut self.mat[j * ld..j * ld + n];
            col.fill(0.0);
            col[j] = 1.0;
        }
        for i in (0..m).filter(|&i| self.pressing[i]) {
            for j in 0..n {
                self.mat[j * ld + k] = sr * rows[i * n + j];
            }
            self.rhs[k] = sr * b[i];
            k += 1;
        }
        for j in 0..n {
            let col = &self.mat[j * ld + j..j * ld + k];
            let norm = scaled_norm(col);
            if norm == 0.0 {
                return false;
            }
            let alpha = if col[0] > 0.0 { -norm } else { norm };
            let v = &mut self.v[j..k];
            v.copy_from_slice(col);
            v[0] -= alpha;
            let vv = dot(v, v);
            for l in j + 1..n {
                let target = &mut self.mat[l * ld + j..l * ld + k];
                let f = 2.0 * dot(v, target) / vv;
                for (t, vi) in target.iter_mut().zip(v.iter()) {
                    *t -= f * vi;
                }
            }
            let f = 2.0 * dot(v, &self.rhs[j..k]) / vv;
            for (t, vi) in self.rhs[j..k].iter_mut().zip(v.iter()) {
                *t -= f * vi;
            }
            self.mat[j * ld + j] = alpha;
        }
        for j in (0..n).rev() {
            let mut acc = self.rhs[j];
            for l in j + 1..n {
                acc -= self.mat[l * ld + j] * self.x[l];
            }
            self.x[j] = acc / self.mat[j * ld + j];
        }
        self.x[..n].iter().all(|v| v.is_finite())
    }
}
