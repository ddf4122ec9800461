//! The robot's motion over one zero-order hold, predicted for the sampled-data safety rows
//! (docs/model.md §5): the dynamics linearized at the tick, solved exactly by one matrix exponential.
//!
//! At a tick with state `(q₀, q̇₀)`, `M` and `h` are frozen at the tick, `G` is linearized
//! there (`G_q = ∂G/∂q`) and `K`, `D` are kept, so the excursion `e(t) = q(t) − q₀` under
//! a held command `τ` obeys the linear system
//!
//! ```text
//! M ë + D ė + K̃ e = τ − g₀     K̃ = K + G_q     g₀ = h + G + K q₀     e(0) = 0, ė(0) = q̇₀
//! ```
//!
//! With `x = (e, ė)` and a step `δ`, `x(t + δ) = F x(t) + Γ (τ − g₀)` where
//! `[[F, Γ], [0, I]] = exp(δ [[A, B], [0, 0]])`, `A = [[0, I], [−M⁻¹K̃, −M⁻¹D]]`,
//! `B = [0; M⁻¹]`: exact for the linear system however stiff it is. The samples are
//! `m` even ones, `t = k Δ/m`, and before the first of them `L` early ones,
//! `t = 2^{i−L} Δ/m` (`i = 0 … L−1`), where the velocity settles after a new command; the
//! propagators of the doubling steps are squares of the first. [`HoldPrediction`] keeps,
//! for every sample `t_j`, the free part `a_j` and the forced part `Γ_j` of
//! `e(t_j) = a_j + Γ_j (τ − g₀)`.

use crate::linalg::MatrixExponential;

/// The excursion over one hold at its early and even samples, affine in the held command.
/// Preallocated for one `nq` and `m`; [`HoldPrediction::predict`] allocates nothing.
pub struct HoldPrediction {
    nq: usize,
    /// Even samples `m` and early samples `L`.
    even: usize,
    early: usize,
    exponential: MatrixExponential,
    /// `δ₀ [[A, B], [0, 0]]` with `δ₀ = 2^{−L} Δ/m`; row-major `3nq × 3nq`.
    generator: Vec<f64>,
    /// The propagators of steps `2^i δ₀`, `i = 0 … L`, each row-major `3nq × 3nq`.
    propagators: Vec<f64>,
    scratch: Vec<f64>,
    /// The state `x_j` of the free motion (`2nq`) and the forced part (`2nq × nq`,
    /// row-major), with scratch of the same sizes.
    free_state: Vec<f64>,
    forced_state: Vec<f64>,
    free_next: Vec<f64>,
    forced_next: Vec<f64>,
    /// `a_j` (`m × nq`) and `Γ_j` (`m × nq × nq`, each row-major).
    free: Vec<f64>,
    forced: Vec<f64>,
    /// `ȧ_j` and `Γ̇_j`, the same layouts.
    free_velocity: Vec<f64>,
    forced_velocity: Vec<f64>,
    hold: f64,
}

impl HoldPrediction {
    /// Storage for `nq` coordinates, `even ≥ 1` even samples and `early` early samples
    /// per hold.
    pub fn new(nq: usize, even: usize, early: usize) -> HoldPrediction {
        let even = even.max(1);
        let samples = even + early;
        let size = 3 * nq;
        HoldPrediction {
            nq,
            even,
            early,
            exponential: MatrixExponential::new(size),
            generator: vec![0.0; size * size],
            propagators: vec![0.0; (early + 1) * size * size],
            scratch: vec![0.0; size * size],
            free_state: vec![0.0; 2 * nq],
            forced_state: vec![0.0; 2 * nq * nq],
            free_next: vec![0.0; 2 * nq],
            forced_next: vec![0.0; 2 * nq * nq],
            free: vec![0.0; samples * nq],
            forced: vec![0.0; samples * nq * nq],
            free_velocity: vec![0.0; samples * nq],
            forced_velocity: vec![0.0; samples * nq * nq],
            hold: 0.0,
        }
    }

    /// Number of samples per hold, early and even.
    pub fn samples(&self) -> usize {
        self.early + self.even
    }

    /// Time of sample `j` (0-based, increasing) of the last prediction \[s\]: the early
    /// samples `2^{j−L} Δ/m`, then the even ones `(j − L + 1) Δ/m`.
    pub fn time(&self, j: usize) -> f64 {
        let even_step = self.hold / self.even as f64;
        if j < self.early {
            even_step * 0.5_f64.powi((self.early - j) as i32)
        } else {
            (j + 1 - self.early) as f64 * even_step
        }
    }

    /// Predicts the excursion over a hold of `hold` seconds for the mass-matrix inverse
    /// `inverse_mass` and the stiffness `K̃` (both row-major `nq × nq`), the damping `D`
    /// (its diagonal, `nq` entries, or the whole matrix, row-major `nq × nq`), and the
    /// velocity `velocity` at the tick. Returns `false` (the
    /// prediction is then unusable) for wrong sizes, a hold that is not finite and > 0, or
    /// a non-finite result.
    pub fn predict(
        &mut self,
        inverse_mass: &[f64],
        stiffness: &[f64],
        damping: &[f64],
        velocity: &[f64],
        hold: f64,
    ) -> bool {
        let nq = self.nq;
        let sizes = inverse_mass.len() == nq * nq
            && stiffness.len() == nq * nq
            && (damping.len() == nq || damping.len() == nq * nq)
            && velocity.len() == nq;
        let full = damping.len() == nq * nq;
        if !(sizes && hold.is_finite() && hold > 0.0) {
            return false;
        }
        self.hold = hold;
        let step = hold / self.even as f64 * 0.5_f64.powi(self.early as i32);
        let size = 3 * nq;
        let z = &mut self.generator;
        z.fill(0.0);
        for i in 0..nq {
            z[i * size + nq + i] = step;
            let row = (nq + i) * size;
            let inverse_row = &inverse_mass[i * nq..(i + 1) * nq];
            for j in 0..nq {
                let w = step * inverse_row[j];
                let k: f64 = (0..nq)
                    .map(|c| inverse_row[c] * stiffness[c * nq + j])
                    .sum();
                z[row + j] = -step * k;
                z[row + nq + j] = if full {
                    -step
                        * (0..nq)
                            .map(|c| inverse_row[c] * damping[c * nq + j])
                            .sum::<f64>()
                } else {
                    -w * damping[j]
                };
                z[row + 2 * nq + j] = w;
            }
        }
        let square = size * size;
        if !self
            .exponential
            .compute(&self.generator, &mut self.propagators[..square])
        {
            return false;
        }
        for i in 0..self.early {
            // exp(2δ Z) = exp(δ Z)².
            self.scratch
                .copy_from_slice(&self.propagators[i * square..(i + 1) * square]);
            crate::linalg::multiply(
                &self.scratch,
                &self.scratch,
                &mut self.propagators[(i + 1) * square..(i + 2) * square],
                size,
            );
        }
        let two = 2 * nq;
        self.free_state[..nq].fill(0.0);
        self.free_state[nq..].copy_from_slice(velocity);
        self.forced_state.fill(0.0);
        for j in 0..self.samples() {
            // Steps δ₀, δ₀, 2δ₀, …, 2^{L−1}δ₀ reach the early samples and the first even
            // one; then steps of Δ/m.
            let power = if j == 0 { 0 } else { (j - 1).min(self.early) };
            let p = &self.propagators[power * square..(power + 1) * square];
            // x ← F x (free); X ← F X + Γ (forced).
            for r in 0..two {
                let row = &p[r * size..r * size + two];
                self.free_next[r] = crate::linalg::dot(row, &self.free_state);
                for c in 0..nq {
                    let mut s = p[r * size + two + c];
                    for (k, f) in row.iter().enumerate() {
                        s += f * self.forced_state[k * nq + c];
                    }
                    self.forced_next[r * nq + c] = s;
                }
            }
            std::mem::swap(&mut self.free_state, &mut self.free_next);
            std::mem::swap(&mut self.forced_state, &mut self.forced_next);
            self.free[j * nq..(j + 1) * nq].copy_from_slice(&self.free_state[..nq]);
            self.forced[j * nq * nq..(j + 1) * nq * nq]
                .copy_from_slice(&self.forced_state[..nq * nq]);
            self.free_velocity[j * nq..(j + 1) * nq].copy_from_slice(&self.free_state[nq..]);
            self.forced_velocity[j * nq * nq..(j + 1) * nq * nq]
                .copy_from_slice(&self.forced_state[nq * nq..]);
        }
        self.free.iter().chain(&self.forced).all(|v| v.is_finite())
    }

    /// Steps a state `x = (e, ė)` (`2 nq` entries) of the linear model over cell `j` (from
    /// sample `j − 1`, or the tick for `j = 0`, to sample `j`) under a force `force` held
    /// over the cell (`nq` entries, added to `τ − g₀`): `x ← F x + W force` with the cell's
    /// propagator of the last [`HoldPrediction::predict`]. `out` receives the new state.
    pub fn step(&self, j: usize, x: &[f64], force: &[f64], out: &mut [f64]) {
        let nq = self.nq;
        let (two, size) = (2 * nq, 3 * nq);
        let square = size * size;
        let power = if j == 0 { 0 } else { (j - 1).min(self.early) };
        let p = &self.propagators[power * square..(power + 1) * square];
        for r in 0..two {
            let row = &p[r * size..(r + 1) * size];
            out[r] = crate::linalg::dot(&row[..two], &x[..two])
                + crate::linalg::dot(&row[two..], &force[..nq]);
        }
    }

    /// `ė(Δ)` with `τ = g₀`: the velocity at the end of the hold \[m/s\].
    pub fn end_velocity_free(&self) -> &[f64] {
        &self.free_state[self.nq..]
    }

    /// `∂ė(Δ)/∂τ`, row-major `nq × nq` \[m/(N·s)\].
    pub fn end_velocity_forced(&self) -> &[f64] {
        &self.forced_state[self.nq * self.nq..]
    }

    /// `a_j`: the excursion at sample `j` (0-based) with `τ = g₀` \[m\].
    pub fn free(&self, j: usize) -> &[f64] {
        &self.free[j * self.nq..(j + 1) * self.nq]
    }

    /// `Γ_j = ∂e(t_j)/∂τ`, row-major `nq × nq` \[m/N\].
    pub fn forced(&self, j: usize) -> &[f64] {
        let size = self.nq * self.nq;
        &self.forced[j * size..(j + 1) * size]
    }

    /// `ȧ_j`: the velocity at sample `j` with `τ = g₀` \[m/s\].
    pub fn free_velocity(&self, j: usize) -> &[f64] {
        &self.free_velocity[j * self.nq..(j + 1) * self.nq]
    }

    /// `Γ̇_j = ∂ė(t_j)/∂τ`, row-major `nq × nq` \[m/(N·s)\]: also the impulse response
    /// `H(t_j)`, the motion at `t_j` after a unit impulse of force at `0`.
    pub fn forced_velocity(&self, j: usize) -> &[f64] {
        let size = self.nq * self.nq;
        &self.forced_velocity[j * size..(j + 1) * size]
    }

    /// `e(t_j) = a_j + Γ_j u` for the held `u = τ − g₀` (length `nq`), into `out`.
    pub fn excursion(&self, j: usize, u: &[f64], out: &mut [f64]) {
        let nq = self.nq;
        let (free, forced) = (self.free(j), self.forced(j));
        for (i, o) in out.iter_mut().enumerate().take(nq) {
            *o = free[i] + crate::linalg::dot(&forced[i * nq..(i + 1) * nq], u);
        }
    }
}

/// The class-K comparison curve of a barrier over the hold: the solution of
/// `ψ̈ + (p1 + p2) ψ̇ + p1 p2 ψ = 0` with `ψ(0) = b`, `ψ̇(0) = ḃ`, at time `t ≥ 0`:
/// `ψ = e^{−p1 t} b + (ḃ + p1 b) φ(t)`, `φ = (e^{−p1 t} − e^{−p2 t}) / (p2 − p1)`
/// (`t e^{−p t}` when `p1 = p2`). A barrier that keeps the paper's HOCBF condition along the
/// hold stays above `ψ` (docs/model.md §5).
pub fn comparison(b: f64, b_dot: f64, p1: f64, p2: f64, t: f64) -> f64 {
    let decay = (-p1 * t).exp();
    let gap = p2 - p1;
    // φ = e^{−p1 t} (1 − e^{−gap t}) / gap, written with expm1 so that gap → 0 gives t e^{−p1 t}.
    let phi = if gap.abs() * t < 1e-12 {
        t * decay
    } else {
        -decay * (-gap * t).exp_m1() / gap
    };
    decay * b + (b_dot + p1 * b) * phi
}
