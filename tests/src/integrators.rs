//! The reference integrators the tests compare the runtime's Rosenbrock-W against: explicit
//! Dormand–Prince 5(4) and a dense finite-difference/LU `W` for any [`OdeSystem`].

use softcbf::integrator::{
    IntegratorError, OdeSystem, Stats, Tolerances, WSolve, check_call, error_norm,
    shrink_after_rejection,
};
use softcbf::linalg::{lu_in_place, lu_solve};

// ---------------------------------------------------------------------------------------
// Dormand–Prince 5(4): explicit, FSAL, PI step control; the non-stiff reference for energy
// checks and cross-checks of the stiff method.

// Dormand & Prince (1980), the RK5(4)7M pair; C[i] nodes, A[i][j] coupling, B 5th-order
// weights (= A[6], FSAL), E = B − B̂ (B̂ the 4th-order weights).
const C: [f64; 7] = [0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0];
const A: [[f64; 6]; 7] = [
    [0.0; 6],
    [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
    [
        19372.0 / 6561.0,
        -25360.0 / 2187.0,
        64448.0 / 6561.0,
        -212.0 / 729.0,
        0.0,
        0.0,
    ],
    [
        9017.0 / 3168.0,
        -355.0 / 33.0,
        46732.0 / 5247.0,
        49.0 / 176.0,
        -5103.0 / 18656.0,
        0.0,
    ],
    [
        35.0 / 384.0,
        0.0,
        500.0 / 1113.0,
        125.0 / 192.0,
        -2187.0 / 6784.0,
        11.0 / 84.0,
    ],
];
const E: [f64; 7] = [
    71.0 / 57600.0,
    0.0,
    -71.0 / 16695.0,
    71.0 / 1920.0,
    -17253.0 / 339200.0,
    22.0 / 525.0,
    -1.0 / 40.0,
];

/// Nodes, coupling coefficients and error weights of the pair, for the tests' check of the
/// order conditions: `(c, a, b, e)` with `b` the order-5 weights and `e = b − b̂`.
pub fn dormand_prince_tableau() -> ([f64; 7], [[f64; 6]; 7], [f64; 7], [f64; 7]) {
    let mut b = [0.0; 7];
    b[..6].copy_from_slice(&A[6]);
    (C, A, b, E)
}

/// PI controller constants (Hairer, Nørsett & Wanner II.4): `β`, safety factor, bounds.
const BETA: f64 = 0.04;
const SAFETY: f64 = 0.9;
const FAC_MIN: f64 = 0.2;
const FAC_MAX: f64 = 10.0;

/// Adaptive Dormand–Prince 5(4) with preallocated stages; keeps its step between calls.
#[derive(Clone, Debug)]
pub struct DormandPrince {
    dim: usize,
    tol: Tolerances,
    h: f64,
    err_old: f64,
    k: [Vec<f64>; 7],
    xs: Vec<f64>,
    x_new: Vec<f64>,
    err: Vec<f64>,
}

impl DormandPrince {
    /// Integrator for systems of dimension `dim` with the given tolerances (validated).
    pub fn new(dim: usize, tol: Tolerances) -> Result<Self, IntegratorError> {
        tol.validate()?;
        let v = || vec![0.0; dim];
        Ok(Self {
            dim,
            tol,
            h: tol.h_initial,
            err_old: 1e-4,
            k: [v(), v(), v(), v(), v(), v(), v()],
            xs: v(),
            x_new: v(),
            err: v(),
        })
    }

    /// Forgets the warm-start step size.
    pub fn reset(&mut self) {
        self.h = self.tol.h_initial;
        self.err_old = 1e-4;
    }

    /// Integrates `x` from `t0` to `t1 ≥ t0` with error control; `x` holds `x(t0)` on entry
    /// and `x(t1)` on success (on error: the last accepted state, at the reported `t`).
    pub fn integrate<S: OdeSystem + ?Sized>(
        &mut self,
        sys: &mut S,
        t0: f64,
        t1: f64,
        x: &mut [f64],
    ) -> Result<Stats, IntegratorError> {
        check_call(self.dim, sys.dim(), x, t0, t1)?;
        if t1 < t0 {
            return Err(IntegratorError::InvalidTolerances { field: "t1 < t0" });
        }
        let tol = self.tol;
        let mut stats = Stats::default();
        if t1 == t0 {
            return Ok(stats);
        }
        stats.rhs_evals += 1;
        if !sys.rhs(t0, x, &mut self.k[0]) || self.k[0].iter().any(|v| !v.is_finite()) {
            return Err(IntegratorError::NonFinite { t: t0 });
        }
        let mut t = t0;
        let mut attempts = 0usize;
        let mut last_rejected = false;
        while t < t1 {
            if attempts >= tol.max_steps {
                return Err(IntegratorError::TooManySteps { t });
            }
            attempts += 1;
            let h_wanted = self.h.clamp(tol.h_min, tol.h_max);
            let remaining = t1 - t;
            let (h, truncated) = if h_wanted * 1.01 >= remaining {
                (remaining, true)
            } else {
                (h_wanted, false)
            };
            let ok = self.attempt(sys, t, h, x, &mut stats);
            let en = if ok {
                error_norm(&tol, x, &self.x_new, &self.err)
            } else {
                f64::NAN
            };
            if en.is_finite() && en <= 1.0 {
                stats.steps += 1;
                t = if truncated { t1 } else { t + h };
                x.copy_from_slice(&self.x_new);
                self.k.swap(0, 6);
                let en = en.max(1e-10);
                let mut fac = SAFETY * en.powf(-(0.2 - 0.75 * BETA)) * self.err_old.powf(BETA);
                fac = fac.clamp(FAC_MIN, FAC_MAX);
                if last_rejected {
                    fac = fac.min(1.0);
                }
                self.err_old = en.max(1e-4);
                let h_next = h * fac;
                self.h = if truncated {
                    h_next.max(h_wanted)
                } else {
                    h_next
                }
                .min(tol.h_max);
                last_rejected = false;
            } else {
                stats.rejected += 1;
                last_rejected = true;
                self.h = shrink_after_rejection(h, en, 5.0, FAC_MIN, &tol, t)?;
            }
        }
        Ok(stats)
    }

    /// Integrates from `t0` to `t1` in `steps` equal steps without error control (for
    /// convergence-order measurements). Does not change the warm-start step size.
    pub fn integrate_fixed<S: OdeSystem + ?Sized>(
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
        stats.rhs_evals += 1;
        if !sys.rhs(t0, x, &mut self.k[0]) {
            return Err(IntegratorError::NonFinite { t: t0 });
        }
        for s in 0..steps {
            let t = t0 + s as f64 * h;
            if !self.attempt(sys, t, h, x, &mut stats) || self.x_new.iter().any(|v| !v.is_finite())
            {
                return Err(IntegratorError::NonFinite { t });
            }
            x.copy_from_slice(&self.x_new);
            self.k.swap(0, 6);
            stats.steps += 1;
        }
        Ok(stats)
    }

    /// One step from `(t, x)` with `k[0] = f(t, x)`; writes `x_new`, `err` and `k[6] =
    /// f(t + h, x_new)`. Returns `false` if an evaluation failed or was non-finite.
    fn attempt<S: OdeSystem + ?Sized>(
        &mut self,
        sys: &mut S,
        t: f64,
        h: f64,
        x: &[f64],
        stats: &mut Stats,
    ) -> bool {
        for i in 1..7 {
            let (done, rest) = self.k.split_at_mut(i);
            let target = if i < 6 { &mut self.xs } else { &mut self.x_new };
            for (m, xm) in target.iter_mut().enumerate() {
                let mut s = 0.0;
                for (j, kj) in done.iter().enumerate() {
                    s += A[i][j] * kj[m];
                }
                *xm = x[m] + h * s;
            }
            let arg = if i < 6 { &self.xs } else { &self.x_new };
            stats.rhs_evals += 1;
            if !sys.rhs(t + C[i] * h, arg, &mut rest[0]) || rest[0].iter().any(|v| !v.is_finite()) {
                return false;
            }
        }
        for m in 0..self.dim {
            let mut e = 0.0;
            for (j, kj) in self.k.iter().enumerate() {
                e += E[j] * kj[m];
            }
            self.err[m] = h * e;
        }
        true
    }
}

// ---------------------------------------------------------------------------------------
// A dense W for any system.

/// An analytic Jacobian, for [`DenseW::with_jacobian`].
pub trait Jacobian: OdeSystem {
    /// Writes `∂f/∂x` (row-major `dim×dim`) into `jac`; returns `false` on failure.
    fn jacobian(&mut self, t: f64, x: &[f64], jac: &mut [f64]) -> bool;
}

/// The analytic Jacobian of a wrapped system, if it has one.
type JacobianFn<S> = fn(&mut S, f64, &[f64], &mut [f64]) -> bool;

/// Wraps any [`OdeSystem`] into a [`WSolve`] with the full Jacobian: analytic if the system
/// provides one ([`DenseW::with_jacobian`]), else forward finite differences (`dim` extra
/// rhs evaluations, step `√(ε·max(10⁻⁵, |x_j|))`); `W` is factored by LU with pivoting.
/// The Jacobian is reused when `prepare_w` is called again at the same `(t, x)` (after a
/// rejected step). Unless [`DenseW::autonomous`] is set, `∂f/∂t` is also approximated by a
/// forward difference (one more evaluation).
#[derive(Clone, Debug)]
pub struct DenseW<S> {
    /// The wrapped system.
    pub system: S,
    /// `true`: `f` does not depend on `t`, so `∂f/∂t = 0` is used without evaluation.
    pub autonomous: bool,
    analytic: Option<JacobianFn<S>>,
    n: usize,
    jac: Vec<f64>,
    lu: Vec<f64>,
    piv: Vec<usize>,
    tmp: Vec<f64>,
    f_base: Vec<f64>,
    f_pert: Vec<f64>,
    x_pert: Vec<f64>,
    x_jac: Vec<f64>,
    t_jac: f64,
    dfdt: Vec<f64>,
    jac_valid: bool,
    ready: bool,
    jac_rhs_evals: usize,
}

impl<S: OdeSystem> DenseW<S> {
    /// Wraps `system` (treated as non-autonomous; set [`DenseW::autonomous`] if it is).
    pub fn new(system: S) -> Self {
        let n = system.dim();
        Self {
            system,
            autonomous: false,
            analytic: None,
            n,
            jac: vec![0.0; n * n],
            lu: vec![0.0; n * n],
            piv: vec![0; n],
            tmp: vec![0.0; n],
            f_base: vec![0.0; n],
            f_pert: vec![0.0; n],
            x_pert: vec![0.0; n],
            x_jac: vec![0.0; n],
            t_jac: f64::NAN,
            dfdt: vec![0.0; n],
            jac_valid: false,
            ready: false,
            jac_rhs_evals: 0,
        }
    }

    /// Wraps `system` with its analytic Jacobian (no finite differences).
    pub fn with_jacobian(system: S) -> Self
    where
        S: Jacobian,
    {
        let mut w = Self::new(system);
        w.analytic = Some(S::jacobian);
        w
    }

    /// Right-hand-side evaluations spent on Jacobians and `∂f/∂t` since construction.
    pub fn jacobian_rhs_evals(&self) -> usize {
        self.jac_rhs_evals
    }

    #[allow(clippy::needless_range_loop)] // column j of the Jacobian: index form is clearer
    fn evaluate_jacobian(&mut self, t: f64, x: &[f64]) -> bool {
        let n = self.n;
        let need_base = self.analytic.is_none() || !self.autonomous;
        if need_base {
            self.jac_rhs_evals += 1;
            if !self.system.rhs(t, x, &mut self.f_base) {
                return false;
            }
        }
        if let Some(jacobian) = self.analytic {
            if !jacobian(&mut self.system, t, x, &mut self.jac) {
                return false;
            }
        } else {
            self.x_pert.copy_from_slice(x);
            for j in 0..n {
                let xj = x[j];
                let delta = (f64::EPSILON * xj.abs().max(1e-5)).sqrt();
                self.x_pert[j] = xj + delta;
                let dx = self.x_pert[j] - xj;
                self.jac_rhs_evals += 1;
                if !self.system.rhs(t, &self.x_pert, &mut self.f_pert) {
                    return false;
                }
                for i in 0..n {
                    self.jac[i * n + j] = (self.f_pert[i] - self.f_base[i]) / dx;
                }
                self.x_pert[j] = xj;
            }
        }
        if self.autonomous {
            self.dfdt.fill(0.0);
        } else {
            let dt = (f64::EPSILON * t.abs().max(1e-5)).sqrt();
            let tp = t + dt;
            self.jac_rhs_evals += 1;
            if !self.system.rhs(tp, x, &mut self.f_pert) {
                return false;
            }
            for i in 0..n {
                self.dfdt[i] = (self.f_pert[i] - self.f_base[i]) / (tp - t);
            }
        }
        self.jac.iter().all(|v| v.is_finite()) && self.dfdt.iter().all(|v| v.is_finite())
    }
}

impl<S: OdeSystem> OdeSystem for DenseW<S> {
    fn dim(&self) -> usize {
        self.n
    }

    fn rhs(&mut self, t: f64, x: &[f64], dx: &mut [f64]) -> bool {
        self.system.rhs(t, x, dx)
    }
}

impl<S: OdeSystem> WSolve for DenseW<S> {
    fn prepare_w(&mut self, t: f64, x: &[f64], gamma_h: f64) -> bool {
        self.ready = false;
        if x.len() != self.n {
            return false;
        }
        let same_point = self.jac_valid && t == self.t_jac && x == self.x_jac.as_slice();
        if !same_point {
            self.jac_valid = false;
            if !self.evaluate_jacobian(t, x) {
                return false;
            }
            self.jac_valid = true;
            self.t_jac = t;
            self.x_jac.copy_from_slice(x);
        }
        let n = self.n;
        for i in 0..n * n {
            self.lu[i] = -gamma_h * self.jac[i];
        }
        for i in 0..n {
            self.lu[i * n + i] += 1.0;
        }
        self.ready = lu_in_place(&mut self.lu, n, &mut self.piv);
        self.ready
    }

    fn solve_w(&mut self, r: &mut [f64]) -> bool {
        if !self.ready || r.len() != self.n {
            return false;
        }
        lu_solve(&self.lu, self.n, &self.piv, r, &mut self.tmp);
        true
    }

    fn time_derivative(&mut self, dfdt: &mut [f64]) -> bool {
        if !self.jac_valid || dfdt.len() != self.n {
            return false;
        }
        dfdt.copy_from_slice(&self.dfdt);
        true
    }
}
