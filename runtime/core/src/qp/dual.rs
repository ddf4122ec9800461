//! Goldfarb–Idnani dual active-set solver specialised to the projection
//! `min ½‖x − x0‖²  s.t.  Nᵢ·x ≥ bᵢ` (identity Hessian, dense rows, no allocation).

use crate::linalg::{dot, with_const_size};

/// How the dual active-set iteration ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum DualOutcome {
    /// No row is violated beyond the tolerance: `x` and `lambda` hold the optimum.
    Optimal,
    /// A violated row cannot be added: the rows have no common point.
    Infeasible,
    /// The iteration budget ran out (cycling on degenerate data, or a huge problem).
    MaxIterations,
}

/// What a guessed active set gave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Guess {
    /// It is the optimum's.
    Optimal,
    /// Its multipliers are `≥ 0` but some other row is violated: the dual method goes on
    /// from there.
    DualFeasible,
    /// Not usable: start from no active row.
    Unusable,
}

/// Tolerances of one dual active-set run.
#[derive(Clone, Copy, Debug)]
pub(crate) struct DualTolerances {
    /// A row counts as violated when `Nᵢ·x − bᵢ < −feas · (1 + |bᵢ| + ‖x‖∞)`.
    pub feas: f64,
    /// A row is linearly dependent on the active rows when its distance to their
    /// span is below `dependence` (rows have unit norm).
    pub dependence: f64,
    /// Maximum number of add/drop steps.
    pub max_iterations: usize,
}

/// Preallocated workspace of the dual active-set method for up to `nv_max`
/// variables and `m_max` rows. `N = Q [R; 0]` is kept for the active rows.
#[derive(Debug)]
pub(crate) struct DualActiveSet {
    nv_max: usize,
    /// Orthogonal `nv × nv`, column-major with leading dimension `nv_max`.
    q: Vec<f64>,
    /// Upper-triangular factor of the active rows, column-major, leading dim `nv_max`.
    r: Vec<f64>,
    /// Indices of the active rows, in factor order.
    active: Vec<usize>,
    /// Multipliers of the active rows, plus one slot for the row being added.
    u: Vec<f64>,
    is_active: Vec<bool>,
    d: Vec<f64>,
    z: Vec<f64>,
    step: Vec<f64>,
    /// Primal solution (length `nv` after a solve).
    pub x: Vec<f64>,
    /// Multipliers of all rows (length `m` after a solve; zero for inactive rows).
    pub lambda: Vec<f64>,
    /// Add and drop steps taken by the last solve.
    pub iterations: usize,
}

impl DualActiveSet {
    pub(crate) fn new(nv_max: usize, m_max: usize) -> Self {
        Self {
            nv_max,
            q: vec![0.0; nv_max * nv_max],
            r: vec![0.0; nv_max * nv_max],
            active: Vec::with_capacity(nv_max + 1),
            u: Vec::with_capacity(nv_max + 1),
            is_active: vec![false; m_max],
            d: vec![0.0; nv_max],
            z: vec![0.0; nv_max],
            step: vec![0.0; nv_max + 1],
            x: Vec::with_capacity(nv_max),
            lambda: Vec::with_capacity(m_max),
            iterations: 0,
        }
    }

    /// Number of active rows at the end of the last solve.
    pub(crate) fn active_count(&self) -> usize {
        self.active.len()
    }

    /// Active rows at the end of the last solve, in factor order.
    pub(crate) fn active_rows(&self) -> &[usize] {
        &self.active
    }

    /// Starts a solve: `x = x0`, no active row, `Q = I`.
    fn start(&mut self, nv: usize, m: usize, x0: &[f64]) {
        let ld = self.nv_max;
        self.x.clear();
        self.x.extend_from_slice(&x0[..nv]);
        self.lambda.clear();
        self.lambda.resize(m, 0.0);
        self.active.clear();
        self.u.clear();
        self.is_active[..m].fill(false);
        self.iterations = 0;
        for j in 0..nv {
            let col = &mut self.q[j * ld..j * ld + nv];
            col.fill(0.0);
            col[j] = 1.0;
        }
    }

    /// Solves the projection for `nv` variables and `m` rows. `rows` is row-major
    /// `m × nv` with unit-norm (or zero) rows, `b` the right-hand sides, `x0` the
    /// point projected. Sizes must not exceed those given to `new`.
    ///
    /// `guess` (for example the previous tick's [`DualActiveSet::active_rows`]) is tried
    /// first as the active set: its rows are factored and `x` put where they all hold.
    /// If their multipliers are all `≥ 0`, that is a starting point of the dual method
    /// (the optimum with these rows as constraints), from which the iteration below goes
    /// on as usual: with no other row violated it ends at once, else it adds rows (and
    /// drops some) as from its usual start. Otherwise (a row repeated or out of range,
    /// linearly dependent rows, a negative multiplier) it starts from no active row. The
    /// problem is strictly convex, its optimum unique: the guess changes only the
    /// rounding of the result and how many steps lead there.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn solve(
        &mut self,
        nv: usize,
        m: usize,
        rows: &[f64],
        b: &[f64],
        x0: &[f64],
        tol: DualTolerances,
        guess: &[usize],
    ) -> DualOutcome {
        let mut warm = Guess::Unusable;
        if !guess.is_empty() && guess.len() <= nv {
            self.start(nv, m, x0);
            warm = self.try_active_set(nv, m, rows, b, x0, tol, guess);
        }
        match warm {
            Guess::Optimal => return DualOutcome::Optimal,
            Guess::DualFeasible => {}
            Guess::Unusable => self.start(nv, m, x0),
        }
        let ld = self.nv_max;

        loop {
            // Step 1: the most violated row (in distance units: rows are unit-norm).
            let p = self.most_violated(nv, m, rows, b, tol);
            if p == usize::MAX {
                self.polish(nv, b, x0);
                for (k, &i) in self.active.iter().enumerate() {
                    self.lambda[i] = self.u[k];
                }
                return DualOutcome::Optimal;
            }
            let row_p = &rows[p * nv..(p + 1) * nv];
            let mut u_p = 0.0;

            // Step 2: move along the dual/primal direction until p is added.
            loop {
                self.iterations += 1;
                if self.iterations > tol.max_iterations {
                    return DualOutcome::MaxIterations;
                }
                let nq = self.active.len();
                for j in 0..nv {
                    self.d[j] = dot(&self.q[j * ld..j * ld + nv], row_p);
                }
                // Dual direction: R r = d[..nq].
                for j in (0..nq).rev() {
                    let mut acc = self.d[j];
                    for l in j + 1..nq {
                        acc -= self.r[l * ld + j] * self.step[l];
                    }
                    self.step[j] = acc / self.r[j * ld + j];
                }
                let rmax = self.step[..nq]
                    .iter()
                    .fold(0.0_f64, |acc, v| acc.max(v.abs()));
                let mut t1 = f64::INFINITY;
                let mut k_drop = usize::MAX;
                for j in 0..nq {
                    let rj = self.step[j];
                    if rj > 1e-14 * (1.0 + rmax) {
                        let ratio = self.u[j] / rj;
                        if ratio < t1 {
                            t1 = ratio;
                            k_drop = j;
                        }
                    }
                }
                // Primal direction: the part of row p orthogonal to the active rows.
                let d2_sq = dot(&self.d[nq..nv], &self.d[nq..nv]);
                let t2 = if d2_sq.sqrt() <= tol.dependence {
                    f64::INFINITY
                } else {
                    let s_p = dot(row_p, &self.x) - b[p];
                    (-s_p / d2_sq).max(0.0)
                };
                let t = t1.min(t2);
                if !t.is_finite() {
                    return DualOutcome::Infeasible;
                }
                if t2.is_finite() {
                    self.z[..nv].fill(0.0);
                    for j in nq..nv {
                        let dj = self.d[j];
                        let col = &self.q[j * ld..j * ld + nv];
                        for (zk, qk) in self.z[..nv].iter_mut().zip(col) {
                            *zk += dj * qk;
                        }
                    }
                    for (xk, zk) in self.x.iter_mut().zip(&self.z[..nv]) {
                        *xk += t * zk;
                    }
                }
                for j in 0..nq {
                    self.u[j] -= t * self.step[j];
                }
                u_p += t;
                if t2 <= t1 {
                    self.add_row(nv, p, u_p);
                    break;
                }
                self.drop_row(nv, k_drop);
            }
        }
    }

    /// The inactive row most violated at `x` (`usize::MAX` if none is violated beyond the
    /// tolerance).
    fn most_violated(
        &self,
        nv: usize,
        m: usize,
        rows: &[f64],
        b: &[f64],
        tol: DualTolerances,
    ) -> usize {
        with_const_size!(nv, [3, 6, 9, 12], |nv| {
            self.most_violated_sized(m, rows, b, tol, nv)
        })
    }

    /// [`DualActiveSet::most_violated`] with `nv` a compile-time constant for the usual
    /// sizes.
    #[inline(always)]
    fn most_violated_sized(
        &self,
        m: usize,
        rows: &[f64],
        b: &[f64],
        tol: DualTolerances,
        nv: usize,
    ) -> usize {
        let x = &self.x[..nv];
        let xnorm = x.iter().fold(0.0_f64, |acc, v| acc.max(v.abs()));
        let mut p = usize::MAX;
        let mut worst = 0.0;
        for i in 0..m {
            if self.is_active[i] {
                continue;
            }
            let s = dot(&rows[i * nv..(i + 1) * nv], x) - b[i];
            let lim = tol.feas * (1.0 + b[i].abs() + xnorm);
            if s < -lim && s < worst {
                worst = s;
                p = i;
            }
        }
        p
    }

    /// Tries `guess` as the active set (see [`DualActiveSet::solve`]): on
    /// [`Guess::Optimal`] `x` and `lambda` hold the optimum, on [`Guess::DualFeasible`] the
    /// iteration can go on from the factorization, `x` and `u`.
    #[allow(clippy::too_many_arguments)]
    fn try_active_set(
        &mut self,
        nv: usize,
        m: usize,
        rows: &[f64],
        b: &[f64],
        x0: &[f64],
        tol: DualTolerances,
        guess: &[usize],
    ) -> Guess {
        let ld = self.nv_max;
        for &p in guess {
            if p >= m || self.is_active[p] {
                return Guess::Unusable;
            }
            let row_p = &rows[p * nv..(p + 1) * nv];
            for j in 0..nv {
                self.d[j] = dot(&self.q[j * ld..j * ld + nv], row_p);
            }
            let nq = self.active.len();
            if dot(&self.d[nq..nv], &self.d[nq..nv]).sqrt() <= tol.dependence {
                return Guess::Unusable;
            }
            self.iterations += 1;
            self.add_row(nv, p, 0.0);
        }
        // x where the guessed rows hold, and their multipliers.
        self.polish(nv, b, x0);
        if !self.u.iter().all(|&u| u >= 0.0) || !self.x.iter().all(|v| v.is_finite()) {
            return Guess::Unusable;
        }
        if self.most_violated(nv, m, rows, b, tol) != usize::MAX {
            return Guess::DualFeasible;
        }
        for (k, &i) in self.active.iter().enumerate() {
            self.lambda[i] = self.u[k];
        }
        Guess::Optimal
    }

    /// Appends row `p` (whose `d = Qᵀ N_p` is in `self.d`) to the factorization.
    fn add_row(&mut self, nv: usize, p: usize, u_p: f64) {
        let ld = self.nv_max;
        let nq = self.active.len();
        for j in (nq + 1..nv).rev() {
            let (a, bb) = (self.d[j - 1], self.d[j]);
            if bb == 0.0 {
                continue;
            }
            let h = givens_norm(a, bb);
            let (c, s) = (a / h, bb / h);
            self.d[j - 1] = h;
            self.d[j] = 0.0;
            rotate_columns(&mut self.q, ld, nv, j - 1, c, s);
        }
        self.r[nq * ld..nq * ld + nq + 1].copy_from_slice(&self.d[..nq + 1]);
        self.active.push(p);
        self.u.push(u_p);
        self.is_active[p] = true;
    }

    /// Removes the active row at factor position `k` and restores the triangle.
    fn drop_row(&mut self, nv: usize, k: usize) {
        let ld = self.nv_max;
        let nq = self.active.len();
        self.is_active[self.active[k]] = false;
        self.active.remove(k);
        self.u.remove(k);
        for col in k..nq - 1 {
            self.r
                .copy_within((col + 1) * ld..(col + 1) * ld + col + 2, col * ld);
        }
        for j in k..nq - 1 {
            let (a, bb) = (self.r[j * ld + j], self.r[j * ld + j + 1]);
            let h = givens_norm(a, bb);
            if h == 0.0 {
                continue;
            }
            let (c, s) = (a / h, bb / h);
            for col in j..nq - 1 {
                let (rj, rj1) = (self.r[col * ld + j], self.r[col * ld + j + 1]);
                self.r[col * ld + j] = c * rj + s * rj1;
                self.r[col * ld + j + 1] = -s * rj + c * rj1;
            }
            self.r[j * ld + j + 1] = 0.0;
            rotate_columns(&mut self.q, ld, nv, j, c, s);
        }
    }

    /// Recomputes `x` and `u` from the factorization so that the active rows hold
    /// to rounding: `Rᵀ v = b_A`, `x = x0 + Q₁ (v − Q₁ᵀ x0)`, `R u = v − Q₁ᵀ x0`.
    fn polish(&mut self, nv: usize, b: &[f64], x0: &[f64]) {
        let ld = self.nv_max;
        let nq = self.active.len();
        if nq == 0 {
            return;
        }
        // Forward substitution Rᵀ v = b_A into d, then w = v − Q₁ᵀ x0.
        for j in 0..nq {
            let mut acc = b[self.active[j]];
            for l in 0..j {
                acc -= self.r[j * ld + l] * self.d[l];
            }
            self.d[j] = acc / self.r[j * ld + j];
        }
        for j in 0..nq {
            self.d[j] -= dot(&self.q[j * ld..j * ld + nv], &x0[..nv]);
        }
        self.x.copy_from_slice(&x0[..nv]);
        for j in 0..nq {
            let w = self.d[j];
            for (xk, qk) in self.x.iter_mut().zip(&self.q[j * ld..j * ld + nv]) {
                *xk += w * qk;
            }
        }
        for j in (0..nq).rev() {
            let mut acc = self.d[j];
            for l in j + 1..nq {
                acc -= self.r[l * ld + j] * self.u[l];
            }
            self.u[j] = acc / self.r[j * ld + j];
        }
    }
}

/// `√(a² + b²)` for a Givens rotation: the plain formula (the entries here are those of
/// unit-norm rows and an orthogonal `Q`, far from overflow), [`f64::hypot`] (several
/// times dearer) only when the squares underflow.
#[inline]
fn givens_norm(a: f64, b: f64) -> f64 {
    let h = (a * a + b * b).sqrt();
    if h.is_normal() && h > 1e-150 {
        h
    } else {
        a.hypot(b)
    }
}

/// `(q_j, q_{j+1}) ← (c q_j + s q_{j+1}, −s q_j + c q_{j+1})` on the first `nv` rows.
fn rotate_columns(q: &mut [f64], ld: usize, nv: usize, j: usize, c: f64, s: f64) {
    let (left, right) = q.split_at_mut((j + 1) * ld);
    let a = &mut left[j * ld..j * ld + nv];
    let bcol = &mut right[..nv];
    for (x, y) in a.iter_mut().zip(bcol.iter_mut()) {
        let (xv, yv) = (*x, *y);
        *x = c * xv + s * yv;
        *y = -s * xv + c * yv;
    }
}
