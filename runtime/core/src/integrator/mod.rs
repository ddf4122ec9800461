//! The adaptive time integrators of the simulated plant between control ticks (zero-order
//! hold): the exponential integrator [`Exponential`] (what [`crate::plant::Plant`] runs) and
//! the Rosenbrock-W method ROS34PW2 with the mechanical `W` of the stiff plant
//! ([`Rosenbrock`], which the controller's own predictions run).
//!
//! # Problem
//!
//! The plant `M(q) q̈ = τ − h(q,q̇) − G(q) − K q − D q̇` is integrated as the first-order
//! system `x' = f(t, x)`, `x = (q, q̇) ∈ R^{2n}` ([`OdeSystem`]), with `τ` constant over each
//! 1 ms tick. It is stiff: `K/d² ≈ 6250 N/m`, `D/d² ≈ 3100 N·s/m` on generalized masses of
//! 0.05–2.7 kg give eigenvalues from ≈ −2 s⁻¹ down to ≈ −4·10⁴ s⁻¹, far beyond the explicit
//! stability limit of a 1 ms step, and every tick's new `τ` restarts transients, of which
//! those at ≈ −1.2·10³ s⁻¹ (bending) and ≈ −85 s⁻¹ (elongation) last about a tick.
//!
//! # Methods
//!
//! [`Exponential`]: an exponential Runge–Kutta method for `x' = A x + N(x)` with the linear
//! part `A` of the stiff dynamics, from the system ([`LinearPart`]): for the plant
//! `A = [[0, I], [−M⁻¹K, −M⁻¹D]]` with `M` frozen where `A` was built, so every linear
//! mode, the transients after a new `τ` included, is propagated exactly by `φ`-functions
//! of `hA`, and only `N = f − A x` (Coriolis, gravity, the change of `M`) is sampled.
//! ETD3RK (Cox & Matthews 2002; stages at `0, h/2, h`, 3 evaluations, classical order 3)
//! with the embedded order-2 solution of the same stages (exponential midpoint,
//! `b = (φ₁ − 2φ₂, 2φ₂, 0)`): the error estimate is their difference,
//! `h (4φ₃ − φ₂)(hA) (N(b) − 2N(a) + N(x))`, held to the tolerances of [`Tolerances`] by
//! the usual step-size control (order 3 on the estimate's exponent). It reports no error
//! for the linear transients, which it integrates exactly; it does for whatever of them
//! leaks into `N`. The `φ` matrices cost a few dozen `2n×2n` products, so they are kept:
//! `A` is rebuilt only when its `M` has drifted (`‖M_A⁻¹(M(x) − M_A)‖ · h‖A‖₁ > 10`, or
//! `> 0.1` after a rejected step, which is then retried with the new `A`), and steps are
//! the call's span divided by a power of two, so that every tick reuses the same `φ`
//! family (one computation gives the span and its first five halvings).
//!
//! [`Rosenbrock`]: ROS34PW2 (Rang & Angermann 2005), a 4-stage Rosenbrock-W method: order 3
//! with *any* matrix `J̃` in `W = I − γ h J̃` (a W-method), L-stable and stiffly accurate,
//! embedded order-2 solution for error control. Each step costs 4 rhs evaluations, one
//! preparation of `W` and 4 solves. [`MechanicalW`] provides `W` for mechanical systems from
//! `M`, `K̃`, `D̃` frozen at the step start: `J̃ = [[0, I], [−M⁻¹K̃, −M⁻¹D̃]]`, whose solve
//! reduces to one SPD `n×n` system. The integrator keeps its step size between calls, so
//! consecutive ticks start warm, and allocates nothing after construction.
//!
//! The reference integrators of the comparison below — explicit Dormand–Prince 5(4) and a
//! dense `W` from a finite-difference or analytic Jacobian — live in the tests crate
//! (`softcbf_tests::integrators`), built on [`OdeSystem`], [`WSolve`], [`Tolerances`],
//! [`error_norm`] and [`check_call`]: nothing in the runtime runs them.
//!
//! # Why ROS34PW2 among the Runge–Kutta-type methods (measured on a surrogate)
//!
//! Surrogate of the paper robot (`n = 6`, `M(q) = L(q)L(q)ᵀ + 0.02 I` with diagonal
//! 0.08–0.33 kg varying smoothly with `q`, `K = diag(6250, 6250, 10, …)`,
//! `D = diag(3125, 3125, 5, …)`, quadratic velocity and sinusoidal gravity-like terms, `τ` from
//! the paper's PD+ law recomputed every 1 ms tick from rest toward the paper's set point),
//! 10 s = 10 000 ticks, release build (the test `measure_surrogate_ticks`). "rhs / tick"
//! counts every evaluation, those of the finite-difference Jacobian included; "error" is the
//! largest state deviation over the 10 s from a Dormand–Prince run at rtol 1e-12. The
//! machine was shared (load ≈ 8 on 2 cores), so the µs are inflated 2–4×; the counts are not.
//!
//! | method | rtol / atol | rhs / tick | W / tick | µs / tick | error |
//! |---|---|---|---|---|---|
//! | ROS34PW2, mechanical `J̃` (frozen `M`, `K`, `D`) | 1e-6 / 1e-9 | 6.5 | 1.63 | 9.3 | 5.6e-9 |
//! | same, error estimate filtered by `W⁻¹` | 1e-6 / 1e-9 | 5.2 | 1.31 | 8.1 | 6.5e-8 |
//! | ROS34PW2, finite-difference Jacobian | 1e-6 / 1e-9 | 22.3 | 1.31 | 26.2 | 6.5e-8 |
//! | DormandPrince 5(4) | 1e-6 / 1e-9 | 90.7 | 0 | 87.7 | 7.4e-9 |
//! | ROS34PW2, mechanical `J̃` | 1e-8 / 1e-11 | 20.8 | 5.21 | 34.3 | 1.1e-10 |
//! | same, error estimate filtered by `W⁻¹` | 1e-8 / 1e-11 | 18.1 | 4.53 | 31.0 | 1.4e-10 |
//! | ROS34PW2, finite-difference Jacobian | 1e-8 / 1e-11 | 76.9 | 4.53 | 105.0 | 7.4e-11 |
//! | DormandPrince 5(4) | 1e-8 / 1e-11 | 97.1 | 0 | 72.6 | 8.8e-11 |
//!
//! The W-method with the frozen mechanical `J̃` needs 14× fewer evaluations than the explicit
//! pair at 1e-6 and 5× fewer at 1e-8: the explicit pair is held by stability (|λ| up to
//! ≈ 4·10⁴ s⁻¹), so a looser tolerance buys it nothing. The finite-difference Jacobian buys
//! nothing either: ROS34PW2 keeps order 3 with the approximate `J̃` (what `J̃` omits — Coriolis,
//! gravity and `∂M/∂q` terms — is not stiff), while it costs `2n` evaluations per step. Every
//! new zero-order-hold `τ` restarts a ≈0.1 ms transient, so a tick takes 1–4 steps; each call
//! therefore starts from the first step size its previous call found acceptable, which removed
//! all but a handful of rejections (38 → 16 evaluations per tick before that change).
//!
//! # Why the exponential method for the plant (measured)
//!
//! The paper scenario itself (paper robot, `n = 6`; 10 s at 1 kHz with the safety filter,
//! 10 001 ticks; `cargo bench -p softcbf --bench control -- paper_scenario_10s` prints the
//! split), release build, idle 2-core machine, best of 3–5 runs. "error" is the largest
//! `|Δq|` over all ticks from the run at rtol 1e-10 / atol 1e-13 with ROS34PW2 (the same
//! run with [`Exponential`] agrees with it to 6e-11 m). The Rosenbrock time per tick
//! includes 0.7 µs per evaluation of the dynamics; "A / tick" counts rebuilt linear parts
//! (each with one `φ` family).
//!
//! | plant integrator | rtol / atol | steps / tick | rhs / tick | W or A / tick | µs / tick | error |
//! |---|---|---|---|---|---|---|
//! | ROS34PW2, mechanical `J̃` | 1e-6 / 1e-9 | 3.3 | 13.2 | 3.3 | 10.0 | 1.4e-7 m |
//! | same, error estimate filtered by `W⁻¹` | 1e-6 / 1e-9 | 2.65 | 10.6 | 2.65 | 8.5 | 1.7e-7 m |
//! | ROS34PW2, fixed 1 step per tick (no control) | — | 1 | 4 | 1 | 3.4 | 1.2e-2 m |
//! | ROS34PW2, fixed 2 steps per tick | — | 2 | 8 | 2 | 6.5 | 1.6e-3 m |
//! | ETD2RK (exponential Euler estimate), `A` at every step | 1e-6 / 1e-9 | 7.9 | 15.8 | 0.26 | 80 | 6e-9 m |
//! | ETD3RK, `A` rebuilt at drift·h‖A‖ > 1 | 1e-6 / 1e-9 | 1.08 | 3.30 | 0.13 | 6.0 | 4.3e-8 m |
//! | **ETD3RK, `A` rebuilt at drift·h‖A‖ > 10** | 1e-6 / 1e-9 | 1.09 | 3.42 | 0.05 | 4.0 | 1.4e-7 m |
//! | ETD3RK, `A` rebuilt only after rejections | 1e-6 / 1e-9 | 1.13 | 3.52 | 0.05 | 4.2 | 1.9e-7 m |
//! | ETD3RK | 1e-10 / 1e-13 | 17.4 | 53.4 | 0.05 | 46 | 6e-11 m |
//!
//! ROS34PW2 spends its steps on the transients of each new `τ`: at a whole tick per step
//! its error is 1e-2 m (the ≈ −1.2·10³ s⁻¹ bending mode is not stiff enough for its
//! L-stability to damp it and not slow enough for order 3 to resolve it), and its estimate,
//! filtered or not, rightly refuses such steps. The exponential method integrates those
//! modes exactly and takes one step per tick on 92 % of the ticks; the rest is the first
//! 0.1 s (elongation speeds of 2 m/s, `M` changing by 1–2 % per tick, and a velocity
//! transient that `N` sees through the Coriolis terms) and the barrier's activation around
//! 0.5–0.9 s. The φ-function ETD2RK pair was tried first: its estimate is of order 1, so
//! it cut the ticks into 8 steps. Rebuilding `A` more eagerly (drift threshold 1) made
//! the error smaller but did not save steps and cost 2.8× the rebuilds; a 10× lower
//! threshold is still well inside 1e-6 m over 10 s.
//!
//! # Cost per tick (measured)
//!
//! Same scenario, release build, the least of 8 runs of `softcbf simulate` (the machine
//! shared with another 1.2-core job, so the µs are somewhat inflated); "A" the rebuilds of
//! the linear part, "max |Δq|" from the rtol 1e-10 run.
//!
//! | plant side | control µs / tick | integration µs / tick | rhs / tick | steps / tick | A / tick | max \|Δq\| |
//! |---|---|---|---|---|---|---|
//! | ETD3RK as above | 2.93 | 3.92 | 3.42 | 1.09 | 0.05 | 1.41e-7 m |
//! | + the tick's first rhs from the controller's evaluation, products by `X` skipping its zeros, vectorized `φ` updates, `A x` in four partial sums | 2.74 | 3.35 | 3.42 (1.0 of them a solve only) | 1.09 | 0.05 | 1.41e-7 m |
//! | + kernels with the size a compile-time constant (`φ` products, `A x`, Cholesky, the drift; the controller's rows and QP loops), `φ` doublings on lower half rows, the QP started from the previous active set | 1.66 | 2.55 | 3.42 (1.0 of them a solve only) | 1.09 | 0.05 | 1.41e-7 m |
//!
//! The last row is the one-run split of `cargo bench -p softcbf --bench control --
//! paper_scenario_10s` on the machine shared at load 2–3, where the code of the row before
//! it gave 2.75 and 3.29 µs; callgrind counts 934M → 544M instructions for the whole run
//! (control 416M → 205M, integration 502M → 323M).
//!
//! A `φ` family costs ≈ 20 µs (≈ 40 products of `2n × 2n` matrices: 14 by `X` in the
//! Taylor series, whose upper half rows `[0, I]` hold one entry each and are skipped over,
//! and 4 per doubling; since, 2.5 per doubling: of the products by `e^X` for `φ₁`, `φ₂`
//! and `e^X` only the lower half rows, the upper ones following from
//! `φ_k = I/k! + X φ_{k+1}`), ≈ 1 µs per tick at one rebuild in 20 ticks. 417 of the 499
//! rebuilds of the run follow a rejected step (en 1.0–2.2 at a whole-tick step around the
//! barrier's activation, 0.5–0.9 s); rebuilding less after rejections trades them for more
//! steps at about the same cost (threshold after a rejection 0.1 / 3 / 10: 499 / 353 / 178
//! rebuilds for 3.42 / 3.77 / 4.54 rhs per tick, max |Δq| 1.4e-7 / 1.3e-7 / 7.5e-8 m), and
//! a larger drift threshold costs far more steps (30: 11.4 rhs per tick), so both stay.

mod exponential;
mod rosenbrock;
mod wsolve;

pub use exponential::{Exponential, LinearPart};
pub use rosenbrock::{ROS34PW2, Rosenbrock, RosenbrockTableau};
pub use wsolve::MechanicalW;

/// A first-order system `x' = f(t, x)`.
pub trait OdeSystem {
    /// Dimension of the state `x`.
    fn dim(&self) -> usize;

    /// Writes `f(t, x)` into `dx` (both of length [`OdeSystem::dim`]). Returns `false` if the
    /// evaluation failed or produced a non-finite value; the integrator then reduces the step
    /// or reports [`IntegratorError::NonFinite`].
    fn rhs(&mut self, t: f64, x: &[f64], dx: &mut [f64]) -> bool;
}

/// What a Rosenbrock-W method needs besides `f`: the matrix `W = I − γ h J̃` with `J̃` any
/// approximation of `∂f/∂x` (the method keeps its order for any `J̃`; a better `J̃` gives
/// better stability and larger steps on stiff problems).
pub trait WSolve: OdeSystem {
    /// Builds and factors `W = I − gamma_h · J̃(t, x)`. Called at the start of every step
    /// attempt (again with a smaller `gamma_h` after a rejection at the same `(t, x)`, where
    /// `J̃` may be reused). Returns `false` if `W` is singular or its construction failed.
    fn prepare_w(&mut self, t: f64, x: &[f64], gamma_h: f64) -> bool;

    /// Overwrites `r` with `W⁻¹ r` for the last prepared `W`. Returns `false` on failure.
    fn solve_w(&mut self, r: &mut [f64]) -> bool;

    /// Writes an approximation of `∂f/∂t` at the last `(t, x)` given to
    /// [`WSolve::prepare_w`]. The default writes zero, which is exact for autonomous systems
    /// (the plant within a tick) and keeps the W-method's order otherwise.
    fn time_derivative(&mut self, dfdt: &mut [f64]) -> bool {
        dfdt.fill(0.0);
        true
    }
}

/// Error control settings of an integrator. Tolerances are per component: a step
/// is accepted when the RMS over `i` of `err_i / (atol + rtol · max(|x_i|, |x_new_i|))` ≤ 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerances {
    /// Relative tolerance (dimensionless). Default `1e-6`.
    pub rtol: f64,
    /// Absolute tolerance (units of the state). Default `1e-9`.
    pub atol: f64,
    /// First step size tried by a new integrator, in s; later calls start from the last
    /// step size. Default `1e-4`.
    pub h_initial: f64,
    /// Smallest step allowed before giving up with [`IntegratorError::StepTooSmall`], in s.
    /// Default `1e-12`.
    pub h_min: f64,
    /// Largest step allowed, in s. Default `f64::INFINITY`.
    pub h_max: f64,
    /// Largest number of step attempts (accepted or rejected) in one `integrate` call.
    /// Default `100_000`.
    pub max_steps: usize,
}

impl Default for Tolerances {
    fn default() -> Self {
        Self {
            rtol: 1e-6,
            atol: 1e-9,
            h_initial: 1e-4,
            h_min: 1e-12,
            h_max: f64::INFINITY,
            max_steps: 100_000,
        }
    }
}

impl Tolerances {
    /// Checks that every field is usable: tolerances finite and non-negative with
    /// `rtol + atol > 0`, `0 < h_min ≤ h_initial ≤ h_max`, `max_steps ≥ 1`.
    pub fn validate(&self) -> Result<(), IntegratorError> {
        let bad = |field: &'static str| Err(IntegratorError::InvalidTolerances { field });
        if !(self.rtol >= 0.0 && self.rtol.is_finite()) {
            return bad("rtol");
        }
        if !(self.atol >= 0.0 && self.atol.is_finite()) || self.rtol + self.atol <= 0.0 {
            return bad("atol");
        }
        if !(self.h_min > 0.0 && self.h_min.is_finite()) {
            return bad("h_min");
        }
        if !(self.h_initial >= self.h_min && self.h_initial.is_finite()) {
            return bad("h_initial");
        }
        if self.h_max.is_nan() || self.h_max < self.h_initial {
            return bad("h_max");
        }
        if self.max_steps == 0 {
            return bad("max_steps");
        }
        Ok(())
    }
}

/// Work done by one `integrate` call.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Accepted steps.
    pub steps: usize,
    /// Rejected step attempts (error too large or a non-finite evaluation).
    pub rejected: usize,
    /// Right-hand-side evaluations made by the integrator itself (those a [`WSolve`] makes
    /// to build `W`, such as a finite-difference Jacobian's, are its own to count).
    pub rhs_evals: usize,
    /// Calls of [`WSolve::prepare_w`] (0 for explicit methods); for [`Exponential`], linear
    /// parts built ([`LinearPart::linear_part`], each followed by one family of `φ` matrices).
    pub w_factorizations: usize,
}

impl Stats {
    /// Adds another call's counts to these.
    pub fn accumulate(&mut self, other: &Stats) {
        self.steps += other.steps;
        self.rejected += other.rejected;
        self.rhs_evals += other.rhs_evals;
        self.w_factorizations += other.w_factorizations;
    }
}

/// Why an `integrate` call stopped before `t1`. The state then holds the last accepted
/// value, at the `t` reported.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum IntegratorError {
    /// The right-hand side failed or was non-finite at the current state, or kept failing
    /// down to the minimum step.
    #[error("non-finite or failed right-hand side at t = {t}")]
    NonFinite { t: f64 },
    /// The error control asked for a step below `h_min`.
    #[error("step size {h} below h_min at t = {t}")]
    StepTooSmall { t: f64, h: f64 },
    /// `max_steps` step attempts did not reach `t1`.
    #[error("max_steps reached at t = {t}")]
    TooManySteps { t: f64 },
    /// `W = I − γ h J̃` could not be built or factored down to the minimum step.
    #[error("W matrix could not be factored at t = {t}")]
    WFailed { t: f64 },
    /// The system's dimension or the state's length differs from the integrator's.
    #[error("dimension mismatch: integrator has {expected}, got {got}")]
    DimensionMismatch { expected: usize, got: usize },
    /// A [`Tolerances`] field is out of range, or `t0`/`t1` not finite.
    #[error("invalid integrator setting `{field}`")]
    InvalidTolerances { field: &'static str },
}

/// Scaled RMS norm of a step's error estimate `err`, the tolerances relative to
/// `max(|x|, |x_new|)`: the step is accepted when it is at most 1 (see [`Tolerances`]).
pub fn error_norm(tol: &Tolerances, x: &[f64], x_new: &[f64], err: &[f64]) -> f64 {
    let mut s = 0.0;
    for ((e, a), b) in err.iter().zip(x).zip(x_new) {
        let sc = tol.atol + tol.rtol * a.abs().max(b.abs());
        let r = e / sc;
        s += r * r;
    }
    (s / err.len().max(1) as f64).sqrt()
}

/// The step size after a rejected step of size `h` at time `t` whose scaled error was `en`
/// ([`error_norm`]), for an error estimate that shrinks like `h^order`: `h` times
/// `0.9 en^{−1/order}` kept within `[least, 0.9]`, or a quarter of `h` when `en` is not
/// finite. Below `tol.h_min` it is an error: [`IntegratorError::StepTooSmall`], or
/// [`IntegratorError::NonFinite`] when `en` is not finite.
pub fn shrink_after_rejection(
    h: f64,
    en: f64,
    order: f64,
    least: f64,
    tol: &Tolerances,
    t: f64,
) -> Result<f64, IntegratorError> {
    let factor = if en.is_finite() {
        (0.9 * en.powf(-1.0 / order)).clamp(least, 0.9)
    } else {
        0.25
    };
    let shrunk = h * factor;
    if shrunk < tol.h_min {
        return Err(if en.is_finite() {
            IntegratorError::StepTooSmall { t, h: shrunk }
        } else {
            IntegratorError::NonFinite { t }
        });
    }
    Ok(shrunk)
}

/// Checks an `integrate` call: the integrator's dimension `dim` against the system's and
/// the state's, `t0` and `t1` finite, the state finite.
pub fn check_call(
    dim: usize,
    sys_dim: usize,
    x: &[f64],
    t0: f64,
    t1: f64,
) -> Result<(), IntegratorError> {
    if sys_dim != dim {
        return Err(IntegratorError::DimensionMismatch {
            expected: dim,
            got: sys_dim,
        });
    }
    if x.len() != dim {
        return Err(IntegratorError::DimensionMismatch {
            expected: dim,
            got: x.len(),
        });
    }
    if !(t0.is_finite() && t1.is_finite()) {
        return Err(IntegratorError::InvalidTolerances { field: "t0/t1" });
    }
    if x.iter().any(|v| !v.is_finite()) {
        return Err(IntegratorError::NonFinite { t: t0 });
    }
    Ok(())
}
