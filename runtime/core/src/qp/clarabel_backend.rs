//! Clarabel reference/fallback for the safety QP: built once with a dense pattern,
//! updated in place (`update_q/A/b`) every solve; hard and slack-relaxed variants.

use super::QpSettings;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};

/// Outcome of one clarabel solve, mapped to what the safety QP needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ClarabelOutcome {
    /// Solved or almost solved: `x`/`z` hold a candidate to be checked.
    Solved,
    /// Primal infeasibility certificate (full or reduced accuracy).
    Infeasible,
    /// Iteration limit, numerical error, lack of progress or setup failure.
    Failed,
}

/// One clarabel instance for `min ½‖x − x0‖² s.t. rows·x ≥ b` with `x = (τ, σ)`:
/// `nv = n` (hard) or `nv = n + m` (each row `i` gets slack column `c σᵢ`).
pub(crate) struct ClarabelQp {
    solver: Option<DefaultSolver<f64>>,
    n: usize,
    m: usize,
    q: Vec<f64>,
    a_values: Vec<f64>,
    b_values: Vec<f64>,
    x_out: Vec<f64>,
    z_out: Vec<f64>,
    /// Last iteration count.
    pub iterations: usize,
}

impl ClarabelQp {
    /// Builds the solver for `n` inputs and `m` rows; `slack_coeff` is the slack
    /// column coefficient `c` when `relaxed`.
    pub(crate) fn new(
        n: usize,
        m: usize,
        relaxed: bool,
        slack_coeff: f64,
        settings: &QpSettings,
    ) -> Self {
        let nv = if relaxed { n + m } else { n };
        let p = CscMatrix::<f64>::identity(nv);
        let mut colptr = Vec::with_capacity(nv + 1);
        let mut rowval = Vec::new();
        let mut nzval = Vec::new();
        colptr.push(0);
        for _ in 0..n {
            for i in 0..m {
                rowval.push(i);
                nzval.push(-1.0);
            }
            colptr.push(rowval.len());
        }
        if relaxed {
            for i in 0..m {
                rowval.push(i);
                nzval.push(-slack_coeff);
                colptr.push(rowval.len());
            }
        }
        let a_values = nzval.clone();
        let a = CscMatrix::new(m, nv, colptr, rowval, nzval);
        let q = vec![0.0; nv];
        let b_values = vec![0.0; m];
        let (x_out, z_out) = (vec![0.0; nv], vec![0.0; m]);
        let settings: Option<DefaultSettings<f64>> = DefaultSettingsBuilder::default()
            .verbose(false)
            .equilibrate_enable(false)
            .presolve_enable(false)
            .input_sparse_dropzeros(false)
            .max_iter(settings.clarabel_max_iter)
            .tol_gap_abs(settings.clarabel_tol)
            .tol_gap_rel(settings.clarabel_tol)
            .tol_feas(settings.clarabel_tol)
            .build()
            .ok();
        let cones = [SupportedConeT::NonnegativeConeT(m)];
        let solver =
            settings.and_then(|s| DefaultSolver::new(&p, &q, &a, &b_values, &cones, s).ok());
        Self {
            solver,
            n,
            m,
            q,
            a_values,
            b_values,
            x_out,
            z_out,
            iterations: 0,
        }
    }

    /// Solves with unit-norm `rows` (row-major `m × n`), right-hand sides `b` and
    /// target `tau_nom`. The slack column coefficient is fixed at construction.
    ///
    /// With equilibration off (the data change every tick), the problem is scaled
    /// here instead: rows are unit-norm already and `τ = scale · y` with `scale`
    /// the largest of 1, ‖τ_nom‖∞ and max |bᵢ|, so clarabel sees O(1) data.
    pub(crate) fn solve(&mut self, rows: &[f64], b: &[f64], tau_nom: &[f64]) -> ClarabelOutcome {
        let (n, m) = (self.n, self.m);
        let Some(solver) = self.solver.as_mut() else {
            return ClarabelOutcome::Failed;
        };
        let inf = |v: &[f64]| v.iter().fold(1.0_f64, |acc, w| acc.max(w.abs()));
        let scale = inf(tau_nom).max(inf(b));
        for (qk, t) in self.q.iter_mut().zip(tau_nom) {
            *qk = -t / scale;
        }
        // Clarabel form: −rows·y + s = −b/scale, s ≥ 0; A values are column-major.
        for j in 0..n {
            for i in 0..m {
                self.a_values[j * m + i] = -rows[i * n + j];
            }
        }
        for (bc, bi) in self.b_values.iter_mut().zip(b) {
            *bc = -bi / scale;
        }
        let updated = solver.update_q(&self.q).is_ok()
            && solver.update_A(&self.a_values).is_ok()
            && solver.update_b(&self.b_values).is_ok();
        if !updated {
            return ClarabelOutcome::Failed;
        }
        solver.solve();
        self.iterations = solver.solution.iterations as usize;
        for (o, v) in self.x_out.iter_mut().zip(&solver.solution.x) {
            *o = v * scale;
        }
        for (o, v) in self.z_out.iter_mut().zip(&solver.solution.z) {
            *o = v * scale;
        }
        match solver.solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => ClarabelOutcome::Solved,
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
                ClarabelOutcome::Infeasible
            }
            _ => ClarabelOutcome::Failed,
        }
    }

    /// Primal solution `x` (τ, then the scaled slacks when relaxed) of the last solve.
    pub(crate) fn x(&self) -> &[f64] {
        &self.x_out
    }

    /// Multipliers of the rows of the last solve.
    pub(crate) fn z(&self) -> &[f64] {
        &self.z_out
    }

    /// Whether clarabel accepted the problem at construction.
    pub(crate) fn is_built(&self) -> bool {
        self.solver.is_some()
    }
}
