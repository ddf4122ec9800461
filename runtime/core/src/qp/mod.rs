//! Safety-filter QP of the paper (eq. 16, docs/model.md §5): `min ½‖τ − τ_nom‖² s.t. A τ ≥ b`,
//! solved every tick by a dual active-set fast path with clarabel as reference and fallback.
//!
//! The fast path first tries the active set of the previous solve (when that one was its
//! own, on the hard problem): from tick to tick the active rows rarely change, and a right
//! guess needs only their factorization and one pass over the rows, a near guess goes on
//! from there (measured on the paper scenario: the dual solve 15.5k → 4.2k instructions per
//! tick). The optimum is unique, so the guess changes only the rounding of the result.
//!
//! Every row is scaled to unit norm first, so tolerances, slacks and
//! `max_violation` are distances in τ units. When no τ satisfies all rows the
//! slack-relaxed problem `min ½‖τ − τ_nom‖² + ½ ρ ‖s‖²  s.t.  Â τ + s ≥ b̂` (Â, b̂
//! the unit-norm rows) is solved instead and the status is [`QpStatus::Relaxed`].
//! At the optimum `s = max(0, b̂ − Â τ)`, so `s ≥ 0` need not be imposed.

mod clarabel_backend;
mod dual;
mod polish;
mod settings;

pub use settings::{QpSettings, QpSetupError};

use crate::linalg::{dot, with_const_size};
use clarabel_backend::{ClarabelOutcome, ClarabelQp};
use dual::{DualActiveSet, DualOutcome, DualTolerances};
use polish::RelaxedPolish;

/// Outcome of a solve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QpStatus {
    /// All rows hold and the KKT conditions were verified.
    Solved,
    /// The rows have no common point: the slack-relaxed problem was solved (and
    /// its KKT conditions verified); `relaxed_rows` lists the rows violated.
    Relaxed,
    /// Bad input or no verified solution: `tau` is all NaN.
    Failed,
}

/// Which solver produced the reported τ (or failed last).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QpSolver {
    /// The dual active-set (Goldfarb–Idnani) fast path.
    Fast,
    /// Clarabel interior point.
    Clarabel,
}

/// What one solve did. Owned by [`SafetyQp`] and overwritten by every solve.
#[derive(Clone, Debug)]
pub struct QpReport {
    /// Outcome.
    pub status: QpStatus,
    /// Solver whose result is reported.
    pub solver: QpSolver,
    /// Add/drop steps (fast path) or interior-point iterations (clarabel) of that solver.
    pub iterations: usize,
    /// Rows with a positive multiplier.
    pub active: usize,
    /// Rows violated by more than `QpSettings::relaxed_row_tol` (status `Relaxed`),
    /// ascending. Preallocated with capacity `m`; cleared by every solve.
    pub relaxed_rows: Vec<usize>,
    /// Largest violation `max(0, bᵢ − aᵢ·τ) / ‖aᵢ‖` over the rows (τ units; for a
    /// zero row `aᵢ = 0` it is `max(0, bᵢ)`); NaN when `Failed`.
    pub max_violation: f64,
}

/// The safety QP for `n` inputs and `m` rows, with every workspace preallocated:
/// [`SafetyQp::solve`] allocates nothing on the fast path.
pub struct SafetyQp {
    n: usize,
    m: usize,
    settings: QpSettings,
    /// Unit-norm rows, row-major `m × n`, and their right-hand sides.
    rows: Vec<f64>,
    rhs: Vec<f64>,
    row_norm: Vec<f64>,
    /// Rows that no τ can satisfy (`aᵢ = 0`, `bᵢ > 0`, or `bᵢ/‖aᵢ‖` overflowing).
    impossible: Vec<bool>,
    /// Rows with slack columns, row-major `m × (n + m)`, and the point `(τ_nom, 0)`.
    aug_rows: Vec<f64>,
    aug_x0: Vec<f64>,
    residual: Vec<f64>,
    fast: DualActiveSet,
    clarabel_hard: ClarabelQp,
    clarabel_relaxed: ClarabelQp,
    polish: RelaxedPolish,
    /// Multipliers of the last solve in the units of the caller's rows.
    lambda: Vec<f64>,
    /// The active rows of the last solve if the fast path solved the hard problem (empty
    /// otherwise): the next solve's first guess of its active set.
    warm: Vec<usize>,
    report: QpReport,
}

impl SafetyQp {
    /// Builds the solver and all workspaces for `n ≥ 1` inputs and `m` rows.
    pub fn new(n: usize, m: usize, settings: QpSettings) -> Result<Self, QpSetupError> {
        settings.validate()?;
        if n == 0 {
            return Err(QpSetupError::NoInputs);
        }
        let c = settings.slack_penalty.sqrt().recip();
        let nv = n + m;
        let clarabel_hard = ClarabelQp::new(n, m, false, c, &settings);
        let clarabel_relaxed = ClarabelQp::new(n, m, true, c, &settings);
        if !clarabel_hard.is_built() || !clarabel_relaxed.is_built() {
            return Err(QpSetupError::Clarabel);
        }
        let mut aug_rows = vec![0.0; m * nv];
        for i in 0..m {
            aug_rows[i * nv + n + i] = c;
        }
        Ok(Self {
            n,
            m,
            settings,
            rows: vec![0.0; m * n],
            rhs: vec![0.0; m],
            row_norm: vec![0.0; m],
            impossible: vec![false; m],
            aug_rows,
            aug_x0: vec![0.0; nv],
            residual: vec![0.0; nv],
            fast: DualActiveSet::new(nv, m),
            clarabel_hard,
            clarabel_relaxed,
            polish: RelaxedPolish::new(n, m),
            lambda: vec![0.0; m],
            warm: Vec::with_capacity(n),
            report: QpReport {
                status: QpStatus::Failed,
                solver: QpSolver::Fast,
                iterations: 0,
                active: 0,
                relaxed_rows: Vec::with_capacity(m),
                max_violation: f64::NAN,
            },
        })
    }

    /// Number of inputs `n`.
    pub fn inputs(&self) -> usize {
        self.n
    }

    /// Number of rows `m`.
    pub fn rows(&self) -> usize {
        self.m
    }

    /// Settings in use.
    pub fn settings(&self) -> &QpSettings {
        &self.settings
    }

    /// Report of the last solve.
    pub fn report(&self) -> &QpReport {
        &self.report
    }

    /// Multipliers `λ ≥ 0` of the last solve, one per row in the caller's units:
    /// `τ − τ_nom = Aᵀ λ` when `Solved`. Zero for zero rows; NaN when `Failed`.
    pub fn multipliers(&self) -> &[f64] {
        &self.lambda
    }

    /// Filters `tau_nom` (length `n`) through the rows `a τ ≥ b` (`a` row-major
    /// `m × n`, `b` length `m`) and writes the result into `tau` (length `n`).
    /// Wrong lengths or non-finite input give `Failed` with `tau` all NaN; never panics.
    pub fn solve(&mut self, tau_nom: &[f64], a: &[f64], b: &[f64], tau: &mut [f64]) -> &QpReport {
        self.solve_with(tau_nom, a, b, tau, true)
    }

    /// [`SafetyQp::solve`] without the relaxed problem: where the rows have no common point
    /// (or the hard problem has no verified solution) the result is `Failed`, `tau` all NaN.
    /// For a caller that has another command to fall back on (the relaxed problem, with
    /// `n + m` variables, costs far more than the hard one).
    pub fn solve_strict(
        &mut self,
        tau_nom: &[f64],
        a: &[f64],
        b: &[f64],
        tau: &mut [f64],
    ) -> &QpReport {
        self.solve_with(tau_nom, a, b, tau, false)
    }

    fn solve_with(
        &mut self,
        tau_nom: &[f64],
        a: &[f64],
        b: &[f64],
        tau: &mut [f64],
        relax: bool,
    ) -> &QpReport {
        let (n, m) = (self.n, self.m);
        self.report.relaxed_rows.clear();
        self.report.iterations = 0;
        self.report.active = 0;
        self.report.solver = if self.settings.use_fast_path {
            QpSolver::Fast
        } else {
            QpSolver::Clarabel
        };
        let sizes_ok = tau_nom.len() == n && a.len() == m * n && b.len() == m && tau.len() == n;
        let finite = sizes_ok && tau_nom.iter().chain(a).chain(b).all(|v| v.is_finite());
        if !finite {
            return self.fail(tau);
        }
        let any_impossible = self.scale_rows(a, b);
        let hard = if any_impossible {
            Attempt::Infeasible
        } else {
            self.solve_hard(tau_nom)
        };
        match hard {
            Attempt::Done => self.finish(QpStatus::Solved, a, b, tau),
            Attempt::Infeasible | Attempt::Failed if !relax => self.fail(tau),
            // Infeasible, or no verified solution: the relaxed problem is always
            // feasible. Its result is used only if it does violate some row (then the
            // rows have no common point, up to `relaxed_row_tol`); otherwise the hard
            // problem was feasible but unsolved, and that is a failure.
            Attempt::Infeasible | Attempt::Failed => match self.solve_relaxed(tau_nom) {
                Attempt::Done if self.relaxed_violates() => {
                    self.finish(QpStatus::Relaxed, a, b, tau)
                }
                _ => self.fail(tau),
            },
        }
    }

    /// Scales every row to unit norm; returns whether some row is impossible.
    fn scale_rows(&mut self, a: &[f64], b: &[f64]) -> bool {
        with_const_size!(self.n, [3, 6, 9, 12], |n| self.scale_rows_sized(a, b, n))
    }

    /// [`SafetyQp::scale_rows`] with `n` a compile-time constant for the usual sizes.
    #[inline(always)]
    fn scale_rows_sized(&mut self, a: &[f64], b: &[f64], n: usize) -> bool {
        let mut any = false;
        for i in 0..self.m {
            let row = &a[i * n..(i + 1) * n];
            let norm = scaled_norm(row);
            let rhs = b[i] / norm;
            let out = &mut self.rows[i * n..(i + 1) * n];
            if norm.is_normal() && norm.is_finite() && rhs.is_finite() {
                for (o, v) in out.iter_mut().zip(row) {
                    *o = v / norm;
                }
                self.rhs[i] = rhs;
                self.row_norm[i] = norm;
                self.impossible[i] = false;
            } else {
                // Neutral row 0·τ ≥ −1; remembered as impossible when b demands more.
                out.fill(0.0);
                self.rhs[i] = -1.0;
                self.row_norm[i] = 0.0;
                self.impossible[i] = b[i] > 0.0;
                any |= self.impossible[i];
            }
        }
        any
    }

    fn solve_hard(&mut self, tau_nom: &[f64]) -> Attempt {
        let (n, m) = (self.n, self.m);
        if self.settings.use_fast_path {
            let tol = self.tolerances();
            let outcome = self
                .fast
                .solve(n, m, &self.rows, &self.rhs, tau_nom, tol, &self.warm);
            self.warm.clear();
            self.report.solver = QpSolver::Fast;
            self.report.iterations = self.fast.iterations;
            match outcome {
                DualOutcome::Optimal => {
                    if self.accept(n, false, tau_nom, FromSolver::Fast) {
                        self.report.active = self.fast.active_count();
                        self.warm.extend_from_slice(self.fast.active_rows());
                        return Attempt::Done;
                    }
                }
                DualOutcome::Infeasible => return Attempt::Infeasible,
                DualOutcome::MaxIterations => {}
            }
        }
        self.warm.clear();
        self.report.solver = QpSolver::Clarabel;
        let outcome = self.clarabel_hard.solve(&self.rows, &self.rhs, tau_nom);
        self.report.iterations = self.clarabel_hard.iterations;
        match outcome {
            ClarabelOutcome::Solved if self.accept(n, false, tau_nom, FromSolver::Hard) => {
                Attempt::Done
            }
            ClarabelOutcome::Infeasible => Attempt::Infeasible,
            _ => Attempt::Failed,
        }
    }

    fn solve_relaxed(&mut self, tau_nom: &[f64]) -> Attempt {
        let (n, m) = (self.n, self.m);
        let nv = n + m;
        for i in 0..m {
            self.aug_rows[i * nv..i * nv + n].copy_from_slice(&self.rows[i * n..(i + 1) * n]);
        }
        self.aug_x0[..n].copy_from_slice(tau_nom);
        self.aug_x0[n..].fill(0.0);
        // Both solvers' results are polished: the relaxed multipliers are ρ·slack,
        // large, and a solver's accuracy relative to them leaves τ imprecise. The
        // polish is exact once the set of violated rows is right.
        if self.settings.use_fast_path {
            let outcome = self.fast.solve(
                nv,
                m,
                &self.aug_rows,
                &self.rhs,
                &self.aug_x0,
                self.tolerances(),
                &[],
            );
            self.report.solver = QpSolver::Fast;
            self.report.iterations = self.fast.iterations;
            let start = (self.fast.x.as_slice(), self.fast.lambda.as_slice());
            let rho = self.settings.slack_penalty;
            if outcome == DualOutcome::Optimal
                && self.polish.run(&self.rows, &self.rhs, tau_nom, start, rho)
                && self.accept(nv, true, tau_nom, FromSolver::Polished)
            {
                self.report.active = self.fast.active_count();
                return Attempt::Done;
            }
        }
        self.report.solver = QpSolver::Clarabel;
        let outcome = self.clarabel_relaxed.solve(&self.rows, &self.rhs, tau_nom);
        self.report.iterations = self.clarabel_relaxed.iterations;
        if outcome != ClarabelOutcome::Solved {
            return Attempt::Failed;
        }
        // Interior-point accuracy is relative to the multipliers ρ·slack of the
        // relaxed rows: polish to the exact piecewise-quadratic optimum (as above).
        let start = (self.clarabel_relaxed.x(), self.clarabel_relaxed.z());
        let rho = self.settings.slack_penalty;
        if start.0.len() == nv
            && start.1.len() == m
            && self.polish.run(&self.rows, &self.rhs, tau_nom, start, rho)
            && self.accept(nv, true, tau_nom, FromSolver::Polished)
        {
            Attempt::Done
        } else {
            Attempt::Failed
        }
    }

    /// Whether the accepted relaxed τ (in `aug_x0[..n]`) violates some row by more
    /// than `relaxed_row_tol`, or some row is impossible.
    fn relaxed_violates(&self) -> bool {
        let n = self.n;
        let tau = &self.aug_x0[..n];
        (0..self.m).any(|i| {
            self.impossible[i]
                || self.rhs[i] - dot(&self.rows[i * n..(i + 1) * n], tau)
                    > self.settings.relaxed_row_tol
        })
    }

    fn tolerances(&self) -> DualTolerances {
        DualTolerances {
            feas: self.settings.feasibility_tol,
            dependence: self.settings.dependence_tol,
            max_iterations: self.settings.max_iterations,
        }
    }

    /// Checks the KKT conditions of the (hard or relaxed) scaled problem for the
    /// candidate of `from`; on success copies its multipliers into `self.lambda`
    /// (scaled units, converted in `finish`) and its τ into `aug_x0[..n]`.
    fn accept(&mut self, nv: usize, relaxed: bool, tau_nom: &[f64], from: FromSolver) -> bool {
        with_const_size!(nv, [3, 6, 9, 12], |nv| {
            self.accept_sized(nv, relaxed, tau_nom, from)
        })
    }

    /// [`SafetyQp::accept`] with `nv` a compile-time constant for the usual sizes.
    #[inline(always)]
    fn accept_sized(
        &mut self,
        nv: usize,
        relaxed: bool,
        tau_nom: &[f64],
        from: FromSolver,
    ) -> bool {
        let (n, m) = (self.n, self.m);
        let (x, z): (&[f64], &[f64]) = match from {
            FromSolver::Fast => (&self.fast.x, &self.fast.lambda),
            FromSolver::Hard => (self.clarabel_hard.x(), self.clarabel_hard.z()),
            FromSolver::Polished => (&self.polish.x, &self.polish.z),
        };
        if x.len() != nv || z.len() != m {
            return false;
        }
        let rows: &[f64] = if relaxed { &self.aug_rows } else { &self.rows };
        let tol = self.settings.kkt_tol;
        let inf = |v: &[f64]| v.iter().fold(0.0_f64, |acc, w| acc.max(w.abs()));
        // Tolerances scale with the data, plus rounding of products with a large x.
        let scale = 1.0 + inf(tau_nom).max(inf(&self.rhs));
        let rounding = 64.0 * f64::EPSILON * inf(x);
        let lscale = scale.max(inf(z));
        // Stationarity: x − x0 − rowsᵀ z = 0 (x0 = (τ_nom, 0)).
        let res = &mut self.residual[..nv];
        for (r, (xv, t)) in res[..n].iter_mut().zip(x.iter().zip(tau_nom)) {
            *r = xv - t;
        }
        res[n..].copy_from_slice(&x[n..]);
        let mut ok = true;
        for i in 0..m {
            let row = &rows[i * nv..(i + 1) * nv];
            let zi = z[i];
            for (r, a) in res.iter_mut().zip(row) {
                *r -= zi * a;
            }
            let s = dot(row, x) - self.rhs[i];
            ok &= zi.is_finite() && s.is_finite();
            ok &= s >= -tol * scale - rounding && zi >= -tol * lscale;
            ok &= zi.max(0.0) * s.max(0.0) <= tol * scale * scale.max(zi);
        }
        ok &= inf(res) <= tol * lscale + (rounding + 64.0 * f64::EPSILON * lscale) * nv as f64;
        if ok {
            for (l, zi) in self.lambda.iter_mut().zip(z) {
                *l = zi.max(0.0);
            }
            let tau = &x[..n];
            self.aug_x0[..n].copy_from_slice(tau);
            if !matches!(from, FromSolver::Fast) {
                self.report.active = z.iter().filter(|&&zi| zi > tol * lscale).count();
            }
        }
        ok
    }

    /// Writes τ (left in `aug_x0[..n]` by `accept`), multipliers and the report.
    fn finish(&mut self, status: QpStatus, a: &[f64], b: &[f64], tau: &mut [f64]) -> &QpReport {
        with_const_size!(self.n, [3, 6, 9, 12], |n| {
            self.finish_sized(status, a, b, tau, n)
        });
        &self.report
    }

    /// [`SafetyQp::finish`] with `n` a compile-time constant for the usual sizes.
    #[inline(always)]
    fn finish_sized(&mut self, status: QpStatus, a: &[f64], b: &[f64], tau: &mut [f64], n: usize) {
        tau.copy_from_slice(&self.aug_x0[..n]);
        let mut worst = 0.0_f64;
        for i in 0..self.m {
            let norm = self.row_norm[i];
            let violation = if norm > 0.0 {
                self.lambda[i] /= norm;
                ((b[i] - dot(&a[i * n..(i + 1) * n], tau)) / norm).max(0.0)
            } else {
                self.lambda[i] = 0.0;
                b[i].max(0.0)
            };
            worst = worst.max(violation);
            if status == QpStatus::Relaxed
                && (self.impossible[i] || violation > self.settings.relaxed_row_tol)
            {
                self.report.relaxed_rows.push(i);
            }
        }
        self.report.status = status;
        self.report.max_violation = worst;
    }

    fn fail(&mut self, tau: &mut [f64]) -> &QpReport {
        tau.fill(f64::NAN);
        self.lambda.fill(f64::NAN);
        self.report.status = QpStatus::Failed;
        self.report.active = 0;
        self.report.max_violation = f64::NAN;
        &self.report
    }
}

#[derive(Clone, Copy)]
enum Attempt {
    Done,
    Infeasible,
    Failed,
}

#[derive(Clone, Copy)]
enum FromSolver {
    Fast,
    Hard,
    Polished,
}

/// Euclidean norm of `v` computed on `v / max|vᵢ|`, so entries far from 1 neither overflow
/// nor underflow when squared; 0 for a zero vector.
fn scaled_norm(v: &[f64]) -> f64 {
    let amax = v.iter().fold(0.0_f64, |acc, x| acc.max(x.abs()));
    if amax > 0.0 {
        amax * v
            .iter()
            .map(|x| (x / amax) * (x / amax))
            .sum::<f64>()
            .sqrt()
    } else {
        0.0
    }
}
