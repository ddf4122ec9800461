//! Adaptive Rosenbrock-W integrator (ROS34PW2: 4 stages, order 3(2), L-stable, W-method).
//! Uses the transformed stage form so each stage needs one rhs evaluation and one `W` solve.

use super::{IntegratorError, Stats, Tolerances, WSolve, check_call, error_norm};

/// Coefficients of a 4-stage Rosenbrock(-W) method in the form of Hairer & Wanner (IV.7.4):
/// `(I − γ h J̃) k_i = h f(t + α_i h, x + Σ_{j<i} α_ij k_j) + h J̃ Σ_{j<i} γ_ij k_j
/// + γ_i h² ∂f/∂t`, `x₁ = x + Σ b_i k_i`, embedded `x̂₁ = x + Σ b̂_i k_i`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RosenbrockTableau {
    /// Diagonal `γ = γ_ii`.
    pub gamma: f64,
    /// `α_ij`, strictly lower triangular.
    pub alpha: [[f64; 4]; 4],
    /// `γ_ij` for `j < i` (strictly lower triangular; the diagonal is `gamma`).
    pub gamma_lower: [[f64; 4]; 4],
    /// Weights of the order-3 solution.
    pub b: [f64; 4],
    /// Weights of the embedded order-2 solution.
    pub b_hat: [f64; 4],
    /// Order of the solution with weights `b`.
    pub order: u32,
}

/// ROS34PW2 of J. Rang and L. Angermann, "New Rosenbrock W-methods of order 3 for partial
/// differential algebraic equations of index 1", BIT 45 (2005) 761–787: order 3 for any
/// `J̃` (W-method), L-stable, stiffly accurate (`b_i = α_4i + γ_4i`), embedded order 2.
/// The order conditions are checked in the tests, not taken on trust. Digits as published.
#[allow(clippy::excessive_precision)]
pub const ROS34PW2: RosenbrockTableau = RosenbrockTableau {
    gamma: 4.358_665_215_084_590e-1,
    alpha: [
        [0.0; 4],
        [8.717_330_430_169_180_1e-1, 0.0, 0.0, 0.0],
        [
            8.445_706_001_536_942_3e-1,
            -1.129_906_423_648_418_5e-1,
            0.0,
            0.0,
        ],
        [0.0, 0.0, 1.0, 0.0],
    ],
    gamma_lower: [
        [0.0; 4],
        [-8.717_330_430_169_180_1e-1, 0.0, 0.0, 0.0],
        [
            -9.033_805_701_304_408_2e-1,
            5.418_067_238_809_532_6e-2,
            0.0,
            0.0,
        ],
        [
            2.421_238_070_609_534_6e-1,
            -1.223_250_583_904_514_7,
            5.452_602_553_351_021_4e-1,
            0.0,
        ],
    ],
    b: [
        2.421_238_070_609_534_6e-1,
        -1.223_250_583_904_514_7,
        1.545_260_255_335_102,
        4.358_665_215_084_590e-1,
    ],
    b_hat: [
        3.781_090_314_581_936_9e-1,
        -9.604_229_221_242_317_8e-2,
        0.5,
        2.179_332_607_542_295e-1,
    ],
    order: 3,
};

/// The tableau in transformed variables `u_i = Σ_{j≤i} γ_ij k_j` (Hairer & Wanner IV.7.25):
/// `(I − γhJ̃) u_i = γh [f(t + α_i h, x + Σ a_ij u_j) + Σ (c_ij/h) u_j + γ_i h ∂f/∂t]`.
#[derive(Clone, Copy, Debug)]
struct Transformed {
    gamma: f64,
    a: [[f64; 4]; 4],
    c: [[f64; 4]; 4],
    m: [f64; 4],
    e: [f64; 4],
    alpha_sum: [f64; 4],
    gamma_sum: [f64; 4],
}

impl Transformed {
    #[allow(clippy::needless_range_loop)] // 4×4 tableau algebra in index form
    fn new(tab: &RosenbrockTableau) -> Self {
        // Γ (lower triangular, diagonal γ) and its inverse by forward substitution.
        let mut g = tab.gamma_lower;
        for (i, row) in g.iter_mut().enumerate() {
            row[i] = tab.gamma;
        }
        let mut ginv = [[0.0; 4]; 4];
        for col in 0..4 {
            for i in 0..4 {
                let mut s = if i == col { 1.0 } else { 0.0 };
                for k in 0..i {
                    s -= g[i][k] * ginv[k][col];
                }
                ginv[i][col] = s / g[i][i];
            }
        }
        let mut a = [[0.0; 4]; 4];
        let mut c = [[0.0; 4]; 4];
        let mut m = [0.0; 4];
        let mut e = [0.0; 4];
        for i in 0..4 {
            for j in 0..4 {
                a[i][j] = (0..4).map(|k| tab.alpha[i][k] * ginv[k][j]).sum();
                c[i][j] = if i == j {
                    1.0 / g[i][i] - ginv[i][j]
                } else {
                    -ginv[i][j]
                };
            }
            m[i] = (0..4).map(|k| tab.b[k] * ginv[k][i]).sum();
            e[i] = m[i] - (0..4).map(|k| tab.b_hat[k] * ginv[k][i]).sum::<f64>();
        }
        let alpha_sum = [0, 1, 2, 3].map(|i| tab.alpha[i].iter().sum());
        let gamma_sum = [0, 1, 2, 3].map(|i| g[i].iter().sum());
        Self {
            gamma: tab.gamma,
            a,
            c,
            m,
            e,
            alpha_sum,
            gamma_sum,
        }
    }
}

/// Outcome of one step attempt.
enum Attempt {
    /// Step done; scaled error norm (≤ 1 is acceptable).
    Done(f64),
    /// A stage evaluation or solve failed / was non-finite.
    StageFailed,
    /// `W` could not be prepared.
    WFailed,
}

/// Adaptive ROS34PW2 integrator with preallocated stage storage; see the module docs.
#[derive(Clone, Debug)]
pub struct Rosenbrock {
    dim: usize,
    tol: Tolerances,
    tab: Transformed,
    /// Step size to try next (kept across calls: warm start).
    h: f64,
    /// Step size proposed for the first step of the next call, from the error of this
    /// call's first step (a new zero-order-hold input restarts the same fast transient).
    h_first: f64,
    u: [Vec<f64>; 4],
    f0: Vec<f64>,
    fs: Vec<f64>,
    xs: Vec<f64>,
    x_new: Vec<f64>,
    err: Vec<f64>,
    dfdt: Vec<f64>,
    filter_error: bool,
}

impl Rosenbrock {
    /// Integrator for systems of dimension `dim` with the given tolerances (validated).
    pub fn new(dim: usize, tol: Tolerances) -> Result<Self, IntegratorError> {
        tol.validate()?;
        let v = || vec![0.0; dim];
        Ok(Self {
            dim,
            tol,
            tab: Transformed::new(&ROS34PW2),
            h: tol.h_initial,
            h_first: f64::INFINITY,
            u: [v(), v(), v(), v()],
            f0: v(),
            fs: v(),
            xs: v(),
            x_new: v(),
            err: v(),
            dfdt: v(),
            filter_error: false,
        })
    }

    /// Whether the error estimate is filtered through `W⁻¹` before the tolerance test
    /// (default `false`: the plain estimate). The filter (Shampine; Hairer & Wanner IV.8) scales the estimate's
    /// components along stiff directions (`hλ ≪ −1`) by `1/(1 − γhλ)`: those local errors are
    /// damped by every later step and do not accumulate. ROS34PW2's embedded solution is not
    /// L-stable (`R̂(−∞) ≈ −0.48`), so it over-reports the error of steps across a fresh fast
    /// transient. Measured on the plant surrogate (module docs): 20 % fewer evaluations,
    /// 10× larger trajectory error, so it is off by default.
    pub fn set_error_filter(&mut self, on: bool) {
        self.filter_error = on;
    }

    /// The tolerances in use.
    pub fn tolerances(&self) -> &Tolerances {
        &self.tol
    }

    /// Replaces the tolerances (validated) and restarts from `h_initial`.
    pub fn set_tolerances(&mut self, tol: Tolerances) -> Result<(), IntegratorError> {
        tol.validate()?;
        self.tol = tol;
        self.reset();
        Ok(())
    }

    /// Step size the next call will try first, in s.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// Forgets the warm-start step size (next call starts from `h_initial`).
    pub fn reset(&mut self) {
        self.h = self.tol.h_initial;
        self.h_first = f64::INFINITY;
    }

    /// Integrates `x` from `t0` to `t1 ≥ t0` with error control; `x` holds `x(t0)` on entry
    /// and `x(t1)` on success (on error: the last accepted state, at the reported `t`).
    pub fn integrate<S: WSolve + ?Sized>(
        &mut self,
        sys: &mut S,
        t0: f64,
        t1: f64,
        x: &mut [f64],
    ) -> Result<Stats, IntegratorError> {
        self.integrate_observed(sys, t0, t1, x, |_, _| {})
    }

    /// [`Rosenbrock::integrate`], calling `observe(t, x)` at every accepted step that ends
    /// before `t1` (not at `t0`, not at `t1`). The observer only reads: the steps taken and
    /// the result are those of `integrate`, bit for bit.
    pub fn integrate_observed<S: WSolve + ?Sized, O: FnMut(f64, &[f64])>(
        &mut self,
        sys: &mut S,
        t0: f64,
        t1: f64,
        x: &mut [f64],
        mut observe: O,
    ) -> Result<Stats, IntegratorError> {
        check_call(self.dim, sys.dim(), x, t0, t1)?;
        if t1 < t0 {
            return Err(IntegratorError::InvalidTolerances { field: "t1 < t0" });
        }
        let mut stats = Stats::default();
        let tol = self.tol;
        let mut t = t0;
        let mut need_f0 = true;
        let mut attempts = 0usize;
        let mut last_rejected = false;
        let mut first = true;
        self.h = self.h.min(self.h_first);
        while t < t1 {
            if attempts >= tol.max_steps {
                return Err(IntegratorError::TooManySteps { t });
            }
            attempts += 1;
            let h_wanted = self.h.clamp(tol.h_min, tol.h_max);
            let remaining = t1 - t;
            // Take the rest in one step if it is within 1 % of the wanted step, in two equal
            // steps if within two (no tiny last step).
            let (h, truncated) = if h_wanted * 1.01 >= remaining {
                (remaining, true)
            } else if h_wanted * 2.0 >= remaining {
                (0.5 * remaining, false)
            } else {
                (h_wanted, false)
            };
            if need_f0 {
                stats.rhs_evals += 1;
                if !sys.rhs(t, x, &mut self.f0) || self.f0.iter().any(|v| !v.is_finite()) {
                    return Err(IntegratorError::NonFinite { t });
                }
                need_f0 = false;
            }
            stats.w_factorizations += 1;
            let outcome = self.attempt(sys, t, h, x, &mut stats);
            match outcome {
                Attempt::Done(en) if en <= 1.0 => {
                    stats.steps += 1;
                    t = if truncated { t1 } else { t + h };
                    x.copy_from_slice(&self.x_new);
                    if t < t1 {
                        observe(t, x);
                    }
                    need_f0 = true;
                    let mut fac = 0.9 * en.max(1e-10).powf(-1.0 / 3.0);
                    fac = fac.clamp(0.2, 6.0);
                    if last_rejected {
                        fac = fac.min(1.0);
                    }
                    let h_next = h * fac;
                    if first {
                        // Without the post-rejection cap: the next call starts fresh.
                        self.h_first = h * (0.9 * en.max(1e-10).powf(-1.0 / 3.0)).clamp(0.2, 6.0);
                        first = false;
                    }
                    // A step shortened to land on t1 says little about the step size wanted.
                    self.h = if truncated {
                        h_next.max(h_wanted)
                    } else {
                        h_next
                    };
                    self.h = self.h.min(tol.h_max);
                    last_rejected = false;
                }
                Attempt::Done(en) => {
                    stats.rejected += 1;
                    let fac = if en.is_finite() {
                        (0.9 * en.powf(-1.0 / 3.0)).clamp(0.1, 0.9)
                    } else {
                        0.25
                    };
                    self.h = h * fac;
                    last_rejected = true;
                    if self.h < tol.h_min {
                        return Err(IntegratorError::StepTooSmall { t, h: self.h });
                    }
                }
                failed @ (Attempt::StageFailed | Attempt::WFailed) => {
                    stats.rejected += 1;
                    self.h = h * 0.25;
                    last_rejected = true;
                    if self.h < tol.h_min {
                        return Err(match failed {
                            Attempt::WFailed => IntegratorError::WFailed { t },
                            _ => IntegratorError::NonFinite { t },
                        });
                    }
                }
            }
        }
        Ok(stats)
    }

    /// Integrates from `t0` to `t1` in `steps` equal steps without error control (for
    /// convergence-order measurements). Does not change the warm-start step size.
    pub fn integrate_fixed<S: WSolve + ?Sized>(
        &mut self,
        sys: &mut S,
        t0: f64,
        t1: f64,
        x: &mut [f64],
        steps: usize,
    ) -> Result<Stats, IntegratorError> {
        check_call(self.dim, sys.dim(), x, t0, t1)?;
        if steps == 0 {
            return Err(IntegratorError::InvalidTolerances { field: "steps" });
        }
        let mut stats = Stats::default();
        let h = (t1 - t0) / steps as f64;
        for k in 0..steps {
            let t = t0 + k as f64 * h;
            stats.rhs_evals += 1;
            if !sys.rhs(t, x, &mut self.f0) || self.f0.iter().any(|v| !v.is_finite()) {
                return Err(IntegratorError::NonFinite { t });
            }
            stats.w_factorizations += 1;
            match self.attempt(sys, t, h, x, &mut stats) {
                Attempt::Done(_) => {}
                Attempt::StageFailed => return Err(IntegratorError::NonFinite { t }),
                Attempt::WFailed => return Err(IntegratorError::WFailed { t }),
            }
            if self.x_new.iter().any(|v| !v.is_finite()) {
                return Err(IntegratorError::NonFinite { t });
            }
            x.copy_from_slice(&self.x_new);
            stats.steps += 1;
        }
        Ok(stats)
    }

    /// One step of size `h` from `(t, x)` with `f0 = f(t, x)` already computed; writes
    /// `x_new` and returns the scaled error norm.
    #[allow(clippy::needless_range_loop)] // stage k of every u_j: index form is clearer
    fn attempt<S: WSolve + ?Sized>(
        &mut self,
        sys: &mut S,
        t: f64,
        h: f64,
        x: &[f64],
        stats: &mut Stats,
    ) -> Attempt {
        let tab = self.tab;
        let gh = tab.gamma * h;
        if !sys.prepare_w(t, x, gh) {
            return Attempt::WFailed;
        }
        if !sys.time_derivative(&mut self.dfdt) {
            return Attempt::StageFailed;
        }
        for i in 0..4 {
            if i > 0 {
                self.xs.copy_from_slice(x);
                for j in 0..i {
                    let a = tab.a[i][j];
                    if a != 0.0 {
                        for (xs, u) in self.xs.iter_mut().zip(&self.u[j]) {
                            *xs += a * u;
                        }
                    }
                }
                stats.rhs_evals += 1;
                if !sys.rhs(t + tab.alpha_sum[i] * h, &self.xs, &mut self.fs) {
                    return Attempt::StageFailed;
                }
            }
            let (done, rest) = self.u.split_at_mut(i);
            let ui = &mut rest[0];
            let f = if i == 0 { &self.f0 } else { &self.fs };
            let gt = tab.gamma_sum[i] * h;
            for k in 0..self.dim {
                let mut r = f[k] + gt * self.dfdt[k];
                for (j, uj) in done.iter().enumerate() {
                    r += tab.c[i][j] / h * uj[k];
                }
                ui[k] = gh * r;
            }
            if !sys.solve_w(ui) || ui.iter().any(|v| !v.is_finite()) {
                return Attempt::StageFailed;
            }
        }
        for k in 0..self.dim {
            let mut xn = x[k];
            let mut e = 0.0;
            for j in 0..4 {
                xn += tab.m[j] * self.u[j][k];
                e += tab.e[j] * self.u[j][k];
            }
            self.x_new[k] = xn;
            self.err[k] = e;
        }
        if self.filter_error && !sys.solve_w(&mut self.err) {
            return Attempt::StageFailed;
        }
        Attempt::Done(error_norm(&self.tol, x, &self.x_new, &self.err))
    }
}
