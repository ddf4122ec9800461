//! Providers of `W = I − γ h J̃` for the Rosenbrock-W integrator: the mechanical `n×n` SPD
//! reduction ([`MechanicalW`]) and a general dense finite-difference/LU version ([`DenseW`]).

use super::{OdeSystem, WSolve};
use crate::linalg::{cholesky_in_place, cholesky_solve, lu_in_place, lu_solve};

/// `W` for a mechanical system `x = (q, q̇)`, `q ∈ Rⁿ`, with the approximate Jacobian
/// `J̃ = [[0, I], [−M⁻¹K̃, −M⁻¹D̃]]` built from a mass matrix `M` and stiffness and damping
/// approximations `K̃`, `D̃` (all `n×n`, row-major, filled by the user).
///
/// `W y = r` with `W = I − γh J̃` reads `y₁ − γh y₂ = r₁`, `γh K̃ y₁ + (M + γh D̃) y₂ = M r₂`
/// (second block row multiplied by `M`); substituting `y₁ = r₁ + γh y₂`:
///
/// `(M + γh D̃ + γ²h² K̃) y₂ = M r₂ − γh K̃ r₁`,  `y₁ = r₁ + γh y₂`.
///
/// The `n×n` matrix is SPD when `M` is and `K̃`, `D̃` are symmetric positive semidefinite; it is
/// factored by Cholesky, falling back to LU with pivoting otherwise. A user system implements
/// [`WSolve`] by filling [`MechanicalW::mass_matrix_mut`] (and `K̃`, `D̃` once, or whenever they
/// change) in `prepare_w`, then calling [`MechanicalW::factor`]; `solve_w` calls
/// [`MechanicalW::solve`]. Nothing allocates after [`MechanicalW::new`].
#[derive(Clone, Debug)]
pub struct MechanicalW {
    n: usize,
    m: Vec<f64>,
    k: Vec<f64>,
    d: Vec<f64>,
    s: Vec<f64>,
    piv: Vec<usize>,
    b: Vec<f64>,
    tmp: Vec<f64>,
    gamma_h: f64,
    spd: bool,
    ready: bool,
}

impl MechanicalW {
    /// Workspace for `n` generalized coordinates (state dimension `2n`); `M = I`, `K̃ = D̃ = 0`.
    pub fn new(n: usize) -> Self {
        let mut m = vec![0.0; n * n];
        for i in 0..n {
            m[i * n + i] = 1.0;
        }
        Self {
            n,
            m,
            k: vec![0.0; n * n],
            d: vec![0.0; n * n],
            s: vec![0.0; n * n],
            piv: vec![0; n],
            b: vec![0.0; n],
            tmp: vec![0.0; n],
            gamma_h: 0.0,
            spd: true,
            ready: false,
        }
    }

    /// Number of generalized coordinates `n`.
    pub fn dofs(&self) -> usize {
        self.n
    }

    /// Mass matrix `M`, in kg, row-major `n×n`, to be filled at the step's start state.
    pub fn mass_matrix_mut(&mut self) -> &mut [f64] {
        &mut self.m
    }

    /// Stiffness approximation `K̃ ≈ ∂(forces)/∂q` with sign such that `q̈ ≈ −M⁻¹K̃ q`, in N/m.
    pub fn stiffness_mut(&mut self) -> &mut [f64] {
        &mut self.k
    }

    /// Damping approximation `D̃` with `q̈ ≈ −M⁻¹D̃ q̇`, in N·s/m.
    pub fn damping_mut(&mut self) -> &mut [f64] {
        &mut self.d
    }

    /// Forms `S = M + γh D̃ + γ²h² K̃` and factors it. Returns `false` if `S` is singular or
    /// non-finite.
    pub fn factor(&mut self, gamma_h: f64) -> bool {
        let g2 = gamma_h * gamma_h;
        for i in 0..self.n * self.n {
            self.s[i] = self.m[i] + gamma_h * self.d[i] + g2 * self.k[i];
        }
        self.gamma_h = gamma_h;
        self.spd = cholesky_in_place(&mut self.s, self.n);
        if !self.spd {
            for i in 0..self.n * self.n {
                self.s[i] = self.m[i] + gamma_h * self.d[i] + g2 * self.k[i];
            }
            self.ready = lu_in_place(&mut self.s, self.n, &mut self.piv);
        } else {
            self.ready = true;
        }
        self.ready
    }

    /// Overwrites `r = (r₁, r₂)` (length `2n`) with `W⁻¹ r`. Returns `false` if
    /// [`MechanicalW::factor`] has not succeeded or `r` has the wrong length.
    pub fn solve(&mut self, r: &mut [f64]) -> bool {
        let n = self.n;
        if !self.ready || r.len() != 2 * n {
            return false;
        }
        let gh = self.gamma_h;
        let (r1, r2) = r.split_at_mut(n);
        for i in 0..n {
            let row = i * n..(i + 1) * n;
            let mr2: f64 = self.m[row.clone()]
                .iter()
                .zip(r2.iter())
                .map(|(a, b)| a * b)
                .sum();
            let kr1: f64 = self.k[row].iter().zip(r1.iter()).map(|(a, b)| a * b).sum();
            self.b[i] = mr2 - gh * kr1;
        }
        if self.spd {
            cholesky_solve(&self.s, n, &mut self.b);
        } else {
            lu_solve(&self.s, n, &self.piv, &mut self.b, &mut self.tmp);
        }
        r2.copy_from_slice(&self.b);
        for (r1i, bi) in r1.iter_mut().zip(&self.b) {
            *r1i += gh * bi;
        }
        true
    }
}

/// Wraps any [`OdeSystem`] into a [`WSolve`] with the full Jacobian: analytic if the system
/// provides one ([`OdeSystem::has_jacobian`]), else forward finite differences (`dim` extra
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
    jac_evals: usize,
}

impl<S: OdeSystem> DenseW<S> {
    /// Wraps `system` (treated as non-autonomous; set [`DenseW::autonomous`] if it is).
    pub fn new(system: S) -> Self {
        let n = system.dim();
        Self {
            system,
            autonomous: false,
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
            jac_evals: 0,
        }
    }

    /// Right-hand-side evaluations spent on Jacobians and `∂f/∂t` since construction.
    pub fn jacobian_rhs_evals(&self) -> usize {
        self.jac_rhs_evals
    }

    /// Jacobian evaluations (analytic or finite-difference) since construction.
    pub fn jacobian_evals(&self) -> usize {
        self.jac_evals
    }

    /// The last Jacobian (row-major `dim×dim`).
    pub fn jacobian(&self) -> &[f64] {
        &self.jac
    }

    #[allow(clippy::needless_range_loop)] // column j of the Jacobian: index form is clearer
    fn evaluate_jacobian(&mut self, t: f64, x: &[f64]) -> bool {
        let n = self.n;
        self.jac_evals += 1;
        let need_base = !self.system.has_jacobian() || !self.autonomous;
        if need_base {
            self.jac_rhs_evals += 1;
            if !self.system.rhs(t, x, &mut self.f_base) {
                return false;
            }
        }
        if self.system.has_jacobian() {
            if !self.system.jacobian(t, x, &mut self.jac) {
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

    fn has_jacobian(&self) -> bool {
        self.system.has_jacobian()
    }

    fn jacobian(&mut self, t: f64, x: &[f64], jac: &mut [f64]) -> bool {
        self.system.jacobian(t, x, jac)
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
