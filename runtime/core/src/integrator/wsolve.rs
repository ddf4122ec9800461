//! The `W = I − γ h J̃` of the Rosenbrock-W integrator for mechanical systems: the `2n×2n`
//! solve reduced to one `n×n` SPD system ([`MechanicalW`]).

use crate::linalg::{cholesky_in_place, cholesky_solve, dot, lu_in_place, lu_solve};

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
/// [`WSolve`](super::WSolve) by filling [`MechanicalW::mass_matrix_mut`] (and `K̃`, `D̃` once, or whenever they
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
            self.b[i] = dot(&self.m[row.clone()], r2) - gh * dot(&self.k[row], r1);
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
