//! Integration tests of the time integrators: problems with known exact solutions, measured
//! convergence orders, order conditions of the tableaus, error paths and zero allocation.

// Small dense matrices in index form are clearer than iterator chains here.
#![allow(clippy::needless_range_loop)]

use std::f64::consts::PI;

use softcbf::integrator::{
    IntegratorError, MechanicalW, OdeSystem, ROS34PW2, Rosenbrock, Stats, Tolerances, WSolve,
};
use softcbf_tests::integrators::{DenseW, DormandPrince, Jacobian, dormand_prince_tableau};

use softcbf_tests::alloc::allocations;

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn tol(rtol: f64, atol: f64) -> Tolerances {
    Tolerances {
        rtol,
        atol,
        ..Tolerances::default()
    }
}

// ---------------------------------------------------------------------------------------
// Test problems
// ---------------------------------------------------------------------------------------

/// Limit cycle `x' = −y + x(1 − r²)`, `y' = x + y(1 − r²)`: `θ = θ₀ + t`,
/// `r(t) = 1/√(1 + (1/r₀² − 1) e^{−2t})`. Nonlinear, non-stiff, analytic Jacobian.
struct LimitCycle;

impl LimitCycle {
    fn exact(t: f64, r0: f64) -> [f64; 2] {
        let r = 1.0 / (1.0 + (1.0 / (r0 * r0) - 1.0) * (-2.0 * t).exp()).sqrt();
        [r * t.cos(), r * t.sin()]
    }
}

impl OdeSystem for LimitCycle {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, _t: f64, x: &[f64], dx: &mut [f64]) -> bool {
        let s = 1.0 - x[0] * x[0] - x[1] * x[1];
        dx[0] = -x[1] + x[0] * s;
        dx[1] = x[0] + x[1] * s;
        true
    }
}

impl Jacobian for LimitCycle {
    fn jacobian(&mut self, _t: f64, x: &[f64], j: &mut [f64]) -> bool {
        let s = 1.0 - x[0] * x[0] - x[1] * x[1];
        j[0] = s - 2.0 * x[0] * x[0];
        j[1] = -1.0 - 2.0 * x[0] * x[1];
        j[2] = 1.0 - 2.0 * x[0] * x[1];
        j[3] = s - 2.0 * x[1] * x[1];
        true
    }
}

/// Manufactured non-autonomous problem `x' = g(x) + φ'(t) − g(φ(t))` with exact solution
/// `φ(t) = (cos t, sin 2t)`, `g(x) = (−x₂ − x₁³, x₁ x₂ − sin x₂)`.
struct Manufactured;

impl Manufactured {
    fn phi(t: f64) -> [f64; 2] {
        [t.cos(), (2.0 * t).sin()]
    }
    fn g(x: &[f64]) -> [f64; 2] {
        [-x[1] - x[0].powi(3), x[0] * x[1] - x[1].sin()]
    }
}

impl OdeSystem for Manufactured {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, t: f64, x: &[f64], dx: &mut [f64]) -> bool {
        let p = Self::phi(t);
        let dp = [-t.sin(), 2.0 * (2.0 * t).cos()];
        let gx = Self::g(x);
        let gp = Self::g(&p);
        dx[0] = gx[0] + dp[0] - gp[0];
        dx[1] = gx[1] + dp[1] - gp[1];
        true
    }
}

/// A 2-dimensional system with a fixed `J̃` (unrelated to `∂f/∂x`) and `∂f/∂t ≈ 0`: the
/// W-method must keep its order with it.
struct FixedW<S> {
    sys: S,
    jt: [f64; 4],
    winv: [f64; 4],
}

impl<S: OdeSystem> OdeSystem for FixedW<S> {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, t: f64, x: &[f64], dx: &mut [f64]) -> bool {
        self.sys.rhs(t, x, dx)
    }
}

impl<S: OdeSystem> WSolve for FixedW<S> {
    fn prepare_w(&mut self, _t: f64, _x: &[f64], gh: f64) -> bool {
        let (a, b, c, d) = (
            1.0 - gh * self.jt[0],
            -gh * self.jt[1],
            -gh * self.jt[2],
            1.0 - gh * self.jt[3],
        );
        let det = a * d - b * c;
        self.winv = [d / det, -b / det, -c / det, a / det];
        det != 0.0
    }
    fn solve_w(&mut self, r: &mut [f64]) -> bool {
        let (r0, r1) = (r[0], r[1]);
        r[0] = self.winv[0] * r0 + self.winv[1] * r1;
        r[1] = self.winv[2] * r0 + self.winv[3] * r1;
        true
    }
}

/// `x' = A x` with `A = V diag(−1, −10⁴) V⁻¹`, exact solution by the same decomposition.
struct StiffLinear {
    a: [f64; 4],
}

const V: [f64; 4] = [1.0, 1.0, 0.5, -1.0];
const LAMBDA: [f64; 2] = [-1.0, -1e4];

impl StiffLinear {
    fn new() -> Self {
        let det = V[0] * V[3] - V[1] * V[2];
        let vi = [V[3] / det, -V[1] / det, -V[2] / det, V[0] / det];
        let mut a = [0.0; 4];
        for i in 0..2 {
            for j in 0..2 {
                a[i * 2 + j] = (0..2)
                    .map(|k| V[i * 2 + k] * LAMBDA[k] * vi[k * 2 + j])
                    .sum();
            }
        }
        Self { a }
    }
    fn exact(t: f64, x0: [f64; 2]) -> [f64; 2] {
        let det = V[0] * V[3] - V[1] * V[2];
        let c = [
            (V[3] * x0[0] - V[1] * x0[1]) / det,
            (-V[2] * x0[0] + V[0] * x0[1]) / det,
        ];
        let e = [c[0] * (LAMBDA[0] * t).exp(), c[1] * (LAMBDA[1] * t).exp()];
        [V[0] * e[0] + V[1] * e[1], V[2] * e[0] + V[3] * e[1]]
    }
}

impl OdeSystem for StiffLinear {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, _t: f64, x: &[f64], dx: &mut [f64]) -> bool {
        dx[0] = self.a[0] * x[0] + self.a[1] * x[1];
        dx[1] = self.a[2] * x[0] + self.a[3] * x[1];
        true
    }
}

/// Prothero–Robinson `y' = λ (y − φ(t)) + φ'(t)`, `φ = 1 + sin t`, `y = φ` exactly.
struct ProtheroRobinson {
    lambda: f64,
}

impl OdeSystem for ProtheroRobinson {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&mut self, t: f64, x: &[f64], dx: &mut [f64]) -> bool {
        dx[0] = self.lambda * (x[0] - 1.0 - t.sin()) + t.cos();
        true
    }
}

/// Kepler orbit (μ = 1, a = 1, eccentricity `e`), exact solution by Kepler's equation.
struct Kepler;

impl Kepler {
    fn initial(e: f64) -> [f64; 4] {
        [1.0 - e, 0.0, 0.0, ((1.0 + e) / (1.0 - e)).sqrt()]
    }
    fn exact(t: f64, e: f64) -> [f64; 4] {
        let mut ea = t;
        for _ in 0..50 {
            ea -= (ea - e * ea.sin() - t) / (1.0 - e * ea.cos());
        }
        let b = (1.0 - e * e).sqrt();
        let edot = 1.0 / (1.0 - e * ea.cos());
        [
            ea.cos() - e,
            b * ea.sin(),
            -ea.sin() * edot,
            b * ea.cos() * edot,
        ]
    }
    fn energy(x: &[f64]) -> f64 {
        0.5 * (x[2] * x[2] + x[3] * x[3]) - 1.0 / (x[0] * x[0] + x[1] * x[1]).sqrt()
    }
}

impl OdeSystem for Kepler {
    fn dim(&self) -> usize {
        4
    }
    fn rhs(&mut self, _t: f64, x: &[f64], dx: &mut [f64]) -> bool {
        let r2 = x[0] * x[0] + x[1] * x[1];
        let r3 = r2 * r2.sqrt();
        dx[0] = x[2];
        dx[1] = x[3];
        dx[2] = -x[0] / r3;
        dx[3] = -x[1] / r3;
        true
    }
}

/// Damped chain of 4 masses (constant diagonal `M`), springs to ground and between
/// neighbours, Rayleigh damping `D = a M + b K`, constant force `F`. Exact solution by modal
/// decomposition of `M^{-1/2} K M^{-1/2}` (Jacobi eigenvalue iteration).
struct Chain {
    m: [f64; 4],
    k: [[f64; 4]; 4],
    d: [[f64; 4]; 4],
    f: [f64; 4],
    w: MechanicalW,
    /// Scale applied to the off-diagonal part of `K̃`, `D̃` given to `W` (1 = exact `J`).
    w_offdiag: f64,
}

impl Chain {
    fn new(w_offdiag: f64) -> Self {
        let m = [0.3, 0.2, 0.1, 0.05];
        let ks = 6250.0;
        let mut k = [[0.0; 4]; 4];
        for i in 0..4 {
            k[i][i] = if i < 3 { 2.0 * ks } else { ks };
            if i > 0 {
                k[i][i - 1] = -ks;
                k[i - 1][i] = -ks;
            }
        }
        let (ra, rb) = (2.0, 0.25);
        let mut d = [[0.0; 4]; 4];
        for i in 0..4 {
            for j in 0..4 {
                d[i][j] = rb * k[i][j] + if i == j { ra * m[i] } else { 0.0 };
            }
        }
        let mut w = MechanicalW::new(4);
        for i in 0..4 {
            w.mass_matrix_mut()[i * 4 + i] = m[i];
            for j in 0..4 {
                let s = if i == j { 1.0 } else { w_offdiag };
                w.stiffness_mut()[i * 4 + j] = s * k[i][j];
                w.damping_mut()[i * 4 + j] = s * d[i][j];
            }
        }
        Self {
            m,
            k,
            d,
            f: [10.0, -20.0, 5.0, 30.0],
            w,
            w_offdiag,
        }
    }

    /// Exact state at `t` from `x0` (Rayleigh damping keeps the modes uncoupled).
    fn exact(&self, t: f64, x0: &[f64]) -> [f64; 8] {
        let n = 4;
        let s: Vec<f64> = self.m.iter().map(|m| 1.0 / m.sqrt()).collect();
        // Symmetric A = M^{-1/2} K M^{-1/2}; Jacobi rotations give A = Φ Λ Φᵀ.
        let mut a = [[0.0; 4]; 4];
        for i in 0..n {
            for j in 0..n {
                a[i][j] = s[i] * self.k[i][j] * s[j];
            }
        }
        let mut phi = [[0.0; 4]; 4];
        for (i, row) in phi.iter_mut().enumerate() {
            row[i] = 1.0;
        }
        for _sweep in 0..50 {
            for p in 0..n {
                for q in p + 1..n {
                    if a[p][q].abs() < 1e-300 {
                        continue;
                    }
                    let theta = 0.5 * (2.0 * a[p][q]).atan2(a[q][q] - a[p][p]);
                    let (sn, cs) = theta.sin_cos();
                    for r in 0..n {
                        let (arp, arq) = (a[r][p], a[r][q]);
                        a[r][p] = cs * arp - sn * arq;
                        a[r][q] = sn * arp + cs * arq;
                    }
                    for r in 0..n {
                        let (apr, aqr) = (a[p][r], a[q][r]);
                        a[p][r] = cs * apr - sn * aqr;
                        a[q][r] = sn * apr + cs * aqr;
                    }
                    for row in phi.iter_mut() {
                        let (rp, rq) = (row[p], row[q]);
                        row[p] = cs * rp - sn * rq;
                        row[q] = sn * rp + cs * rq;
                    }
                }
            }
        }
        let (ra, rb) = (2.0, 0.25);
        let mut out = [0.0; 8];
        for mode in 0..n {
            let w2 = a[mode][mode];
            let c = ra + rb * w2;
            // Modal coordinate η = φᵀ M^{1/2} q, forcing g = φᵀ M^{-1/2} F.
            let proj = |v: &[f64], scale: &dyn Fn(usize) -> f64| {
                (0..n).map(|i| phi[i][mode] * scale(i) * v[i]).sum::<f64>()
            };
            let eta0 = proj(&x0[..4], &|i| self.m[i].sqrt());
            let v0 = proj(&x0[4..], &|i| self.m[i].sqrt());
            let g = proj(&self.f, &|i| s[i]);
            let e0 = eta0 - g / w2;
            let disc = c * c - 4.0 * w2;
            let (e, v) = if disc > 0.0 {
                let sq = disc.sqrt();
                let (s1, s2) = (0.5 * (-c + sq), 0.5 * (-c - sq));
                let ca = (v0 - s2 * e0) / (s1 - s2);
                let cb = e0 - ca;
                let (x1, x2) = ((s1 * t).exp(), (s2 * t).exp());
                (ca * x1 + cb * x2, ca * s1 * x1 + cb * s2 * x2)
            } else {
                let (sg, wd) = (0.5 * c, 0.5 * (-disc).sqrt());
                let (b1, b2) = (e0, (v0 + sg * e0) / wd);
                let (sn, cs) = (wd * t).sin_cos();
                let ex = (-sg * t).exp();
                let e = ex * (b1 * cs + b2 * sn);
                let de = ex * ((-sg * b1 + wd * b2) * cs + (-sg * b2 - wd * b1) * sn);
                (e, de)
            };
            let eta = e + g / w2;
            for i in 0..n {
                out[i] += s[i] * phi[i][mode] * eta;
                out[4 + i] += s[i] * phi[i][mode] * v;
            }
        }
        out
    }
}

impl OdeSystem for Chain {
    fn dim(&self) -> usize {
        8
    }
    fn rhs(&mut self, _t: f64, x: &[f64], dx: &mut [f64]) -> bool {
        for i in 0..4 {
            let mut force = self.f[i];
            for j in 0..4 {
                force -= self.k[i][j] * x[j] + self.d[i][j] * x[4 + j];
            }
            dx[i] = x[4 + i];
            dx[4 + i] = force / self.m[i];
        }
        true
    }
}

impl WSolve for Chain {
    fn prepare_w(&mut self, _t: f64, _x: &[f64], gamma_h: f64) -> bool {
        let _ = self.w_offdiag;
        self.w.factor(gamma_h)
    }
    fn solve_w(&mut self, r: &mut [f64]) -> bool {
        self.w.solve(r)
    }
}

// ---------------------------------------------------------------------------------------
// Surrogate of the paper's plant (n = 6): used for accuracy, allocation and the measurement.
// ---------------------------------------------------------------------------------------

const NQ: usize = 6;
const K_DIAG: [f64; NQ] = [6250.0, 6250.0, 10.0, 6250.0, 6250.0, 10.0];
const D_DIAG: [f64; NQ] = [3125.0, 3125.0, 5.0, 3125.0, 3125.0, 5.0];
const Q_SET: [f64; NQ] = [0.08, 0.0, -0.05, 0.0, -0.06, -0.07];

/// `M(q) q̈ = τ − h − G − K q − D q̇` with `M = L(q) L(q)ᵀ + 0.02 I` smooth in `q`,
/// quadratic velocity terms `h` and a sinusoidal `G`; `τ` is set per tick.
#[derive(Clone)]
struct Surrogate {
    tau: [f64; NQ],
    w: MechanicalW,
    m: [f64; NQ * NQ],
}

impl Surrogate {
    fn new() -> Self {
        let mut w = MechanicalW::new(NQ);
        for i in 0..NQ {
            w.stiffness_mut()[i * NQ + i] = K_DIAG[i];
            w.damping_mut()[i * NQ + i] = D_DIAG[i];
        }
        Self {
            tau: [0.0; NQ],
            w,
            m: [0.0; NQ * NQ],
        }
    }

    fn mass_matrix(q: &[f64], m: &mut [f64]) {
        const L_DIAG: [f64; NQ] = [0.55, 0.5, 0.45, 0.35, 0.3, 0.25];
        let mut l = [0.0; NQ * NQ];
        let mut sn = [0.0; NQ];
        let mut cs = [0.0; NQ];
        for i in 0..NQ {
            (sn[i], cs[i]) = (20.0 * q[i]).sin_cos();
        }
        for i in 0..NQ {
            for j in 0..=i {
                let base = if i == j { L_DIAG[i] } else { 0.08 };
                l[i * NQ + j] = base * (1.0 + 0.25 * sn[i]) * (1.0 + 0.1 * cs[j]);
            }
        }
        for i in 0..NQ {
            for j in 0..=i {
                let s: f64 = (0..=j).map(|k| l[i * NQ + k] * l[j * NQ + k]).sum();
                let s = s + if i == j { 0.02 } else { 0.0 };
                m[i * NQ + j] = s;
                m[j * NQ + i] = s;
            }
        }
    }

    fn gravity(q: &[f64], g: &mut [f64; NQ]) {
        for i in 0..NQ {
            g[i] = 1.5 * (10.0 * q[i] + 0.3 * i as f64).sin();
            // (6 more trig calls: the generated model's cost is of this order.)
        }
    }

    /// PD+ law of the paper's form (the per-tick controller of the measurement).
    fn control(&mut self, x: &[f64]) {
        let mut g = [0.0; NQ];
        Self::gravity(&x[..NQ], &mut g);
        for i in 0..NQ {
            self.tau[i] = g[i] + K_DIAG[i] * Q_SET[i] + 5.0 * (Q_SET[i] - x[i]) - 1.0 * x[NQ + i];
        }
    }
}

impl OdeSystem for Surrogate {
    fn dim(&self) -> usize {
        2 * NQ
    }
    fn rhs(&mut self, _t: f64, x: &[f64], dx: &mut [f64]) -> bool {
        let (q, qd) = x.split_at(NQ);
        Self::mass_matrix(q, &mut self.m);
        let mut g = [0.0; NQ];
        Self::gravity(q, &mut g);
        let sq: f64 = qd.iter().sum();
        let mut rhs = [0.0; NQ];
        for i in 0..NQ {
            let h = 0.05 * qd[i] * sq;
            rhs[i] = self.tau[i] - h - g[i] - K_DIAG[i] * q[i] - D_DIAG[i] * qd[i];
        }
        // Cholesky solve M q̈ = rhs.
        let m = &mut self.m;
        for j in 0..NQ {
            let mut d = m[j * NQ + j];
            for k in 0..j {
                d -= m[j * NQ + k] * m[j * NQ + k];
            }
            if d.is_nan() || d <= 0.0 {
                return false;
            }
            let ljj = d.sqrt();
            m[j * NQ + j] = ljj;
            for i in j + 1..NQ {
                let mut s = m[i * NQ + j];
                for k in 0..j {
                    s -= m[i * NQ + k] * m[j * NQ + k];
                }
                m[i * NQ + j] = s / ljj;
            }
        }
        for i in 0..NQ {
            let mut s = rhs[i];
            for k in 0..i {
                s -= m[i * NQ + k] * rhs[k];
            }
            rhs[i] = s / m[i * NQ + i];
        }
        for i in (0..NQ).rev() {
            let mut s = rhs[i];
            for k in i + 1..NQ {
                s -= m[k * NQ + i] * rhs[k];
            }
            rhs[i] = s / m[i * NQ + i];
        }
        dx[..NQ].copy_from_slice(qd);
        dx[NQ..].copy_from_slice(&rhs);
        dx.iter().all(|v| v.is_finite())
    }
}

impl WSolve for Surrogate {
    fn prepare_w(&mut self, _t: f64, x: &[f64], gamma_h: f64) -> bool {
        Self::mass_matrix(&x[..NQ], self.w.mass_matrix_mut());
        self.w.factor(gamma_h)
    }
    fn solve_w(&mut self, r: &mut [f64]) -> bool {
        self.w.solve(r)
    }
}

/// Runs the closed loop (PD+ every 1 ms tick, zero-order hold) for `ticks` ticks with the
/// given per-tick integration; returns the trajectory at the ticks and summed stats.
fn closed_loop<F>(ticks: usize, mut tick: F) -> (Vec<[f64; 2 * NQ]>, Stats)
where
    F: FnMut(f64, f64, &mut [f64]) -> Stats,
{
    let mut x = [0.0; 2 * NQ];
    let mut traj = Vec::with_capacity(ticks + 1);
    traj.push(x);
    let mut total = Stats::default();
    for k in 0..ticks {
        let t = k as f64 * 1e-3;
        let s = tick(t, t + 1e-3, &mut x);
        total.accumulate(&s);
        traj.push(x);
    }
    (traj, total)
}

fn surrogate_reference(ticks: usize) -> Vec<[f64; 2 * NQ]> {
    let mut sys = Surrogate::new();
    let mut dp = DormandPrince::new(2 * NQ, tol(1e-12, 1e-15)).unwrap();
    closed_loop(ticks, |t0, t1, x| {
        sys.control(x);
        dp.integrate(&mut sys, t0, t1, x).unwrap()
    })
    .0
}

// ---------------------------------------------------------------------------------------
// Order conditions and stability of the tableaus
// ---------------------------------------------------------------------------------------

/// Conditions derived by expanding the method on `x' = f(x)` with an arbitrary `J̃`: with
/// `Γ̂` the full lower-triangular `γ_ij` (diagonal `γ`), `α` and `1` the ones vector, the
/// local error is O(h⁴) for every `J̃` iff `b·1 = 1`, `bα1 = ½`, `bΓ̂1 = 0`, `b(α1)² = ⅓`,
/// `bαα1 = ⅙`, `bαΓ̂1 = bΓ̂α1 = bΓ̂Γ̂1 = 0`; with `J̃ = J` only the sums with `α + Γ̂` must hold.
#[test]
fn ros34pw2_satisfies_w_order_conditions() {
    let t = ROS34PW2;
    let mut g = t.gamma_lower;
    for (i, row) in g.iter_mut().enumerate() {
        row[i] = t.gamma;
    }
    let mv = |m: &[[f64; 4]; 4], v: &[f64; 4]| -> [f64; 4] {
        let mut o = [0.0; 4];
        for i in 0..4 {
            o[i] = (0..4).map(|j| m[i][j] * v[j]).sum();
        }
        o
    };
    let dot = |a: &[f64; 4], b: &[f64; 4]| -> f64 { (0..4).map(|i| a[i] * b[i]).sum() };
    let one = [1.0; 4];
    let a1 = mv(&t.alpha, &one);
    let g1 = mv(&g, &one);
    let a1sq = a1.map(|v| v * v);
    let checks = [
        ("b·1 = 1", dot(&t.b, &one), 1.0),
        ("bα1 = 1/2", dot(&t.b, &a1), 0.5),
        ("bΓ1 = 0", dot(&t.b, &g1), 0.0),
        ("b(α1)² = 1/3", dot(&t.b, &a1sq), 1.0 / 3.0),
        ("bαα1 = 1/6", dot(&t.b, &mv(&t.alpha, &a1)), 1.0 / 6.0),
        ("bαΓ1 = 0", dot(&t.b, &mv(&t.alpha, &g1)), 0.0),
        ("bΓα1 = 0", dot(&t.b, &mv(&g, &a1)), 0.0),
        ("bΓΓ1 = 0", dot(&t.b, &mv(&g, &g1)), 0.0),
        ("b̂·1 = 1", dot(&t.b_hat, &one), 1.0),
        ("b̂α1 = 1/2", dot(&t.b_hat, &a1), 0.5),
        ("b̂Γ1 = 0", dot(&t.b_hat, &g1), 0.0),
    ];
    for (name, got, want) in checks {
        assert!((got - want).abs() < 1e-14, "{name}: {got} vs {want}");
    }
    // The embedded solution must differ at third order (else the estimate is useless).
    assert!(
        (dot(&t.b_hat, &a1sq) - 1.0 / 3.0).abs() > 1e-3
            || (dot(&t.b_hat, &mv(&t.alpha, &a1)) - 1.0 / 6.0).abs() > 1e-3
    );
    // Stiffly accurate: b is the last row of α + Γ̂.
    for j in 0..4 {
        assert!((t.b[j] - (t.alpha[3][j] + g[3][j])).abs() < 1e-14);
    }
}

/// Stability function `R(z) = 1 + z b (I − z B)⁻¹ 1`, `B = α + Γ̂`, evaluated in complex
/// arithmetic: `|R| ≤ 1` on the imaginary axis and the left half plane samples (A-stability),
/// `R(−∞) = 0` (L-stability).
#[test]
fn ros34pw2_is_l_stable() {
    let t = ROS34PW2;
    let mut bm = t.alpha;
    for i in 0..4 {
        for j in 0..4 {
            bm[i][j] += if i == j { t.gamma } else { t.gamma_lower[i][j] };
        }
    }
    // Forward substitution with complex numbers as (re, im) pairs; I − zB is lower triangular.
    let r = |zr: f64, zi: f64| -> (f64, f64) {
        let mut y = [(0.0, 0.0); 4];
        for i in 0..4 {
            let (mut sr, mut si) = (1.0, 0.0);
            for (j, yj) in y.iter().enumerate().take(i) {
                // s += z B_ij y_j
                let (pr, pi) = (zr * bm[i][j], zi * bm[i][j]);
                sr += pr * yj.0 - pi * yj.1;
                si += pr * yj.1 + pi * yj.0;
            }
            let (dr, di) = (1.0 - zr * bm[i][i], -zi * bm[i][i]);
            let den = dr * dr + di * di;
            y[i] = ((sr * dr + si * di) / den, (si * dr - sr * di) / den);
        }
        let (mut rr, mut ri) = (1.0, 0.0);
        for i in 0..4 {
            let (pr, pi) = (zr * t.b[i], zi * t.b[i]);
            rr += pr * y[i].0 - pi * y[i].1;
            ri += pr * y[i].1 + pi * y[i].0;
        }
        (rr, ri)
    };
    let abs = |(a, b): (f64, f64)| (a * a + b * b).sqrt();
    for k in 0..4000 {
        let y = 10f64.powf(-3.0 + 9.0 * k as f64 / 4000.0);
        assert!(
            abs(r(0.0, y)) <= 1.0 + 1e-12,
            "|R(i{y})| = {}",
            abs(r(0.0, y))
        );
    }
    for k in 0..200 {
        for l in 0..60 {
            let rad = 10f64.powf(-2.0 + 8.0 * k as f64 / 200.0);
            let ang = PI / 2.0 + PI * (l as f64 + 0.5) / 60.0;
            let z = (rad * ang.cos(), rad * ang.sin());
            assert!(abs(r(z.0, z.1)) <= 1.0 + 1e-12);
        }
    }
    assert!(abs(r(-1e12, 0.0)) < 1e-9, "R(-inf) = {:?}", r(-1e12, 0.0));
    assert!((r(-1e-3, 0.0).0 - (-1e-3f64).exp()).abs() < 1e-11);
}

#[test]
fn dormand_prince_satisfies_order_conditions() {
    let (c, a, b, e) = dormand_prince_tableau();
    let bh: Vec<f64> = (0..7).map(|i| b[i] - e[i]).collect();
    let ac = |v: &[f64; 7]| -> [f64; 7] {
        let mut o = [0.0; 7];
        for i in 0..7 {
            o[i] = (0..i.min(6)).map(|j| a[i][j] * v[j]).sum();
        }
        o
    };
    let dot = |w: &[f64], v: &[f64; 7]| -> f64 { (0..7).map(|i| w[i] * v[i]).sum() };
    for i in 1..7 {
        let row: f64 = a[i].iter().sum();
        assert!((row - c[i]).abs() < 1e-14);
    }
    let pw = |k: i32| c.map(|ci| ci.powi(k));
    let c1 = ac(&pw(1));
    let c2 = ac(&pw(2));
    let c3 = ac(&pw(3));
    let ac1 = ac(&c1);
    let mut cac = [0.0; 7];
    let mut c2ac = [0.0; 7];
    let mut cac2 = [0.0; 7];
    let mut cacac = [0.0; 7];
    let mut ac1sq = [0.0; 7];
    let mut caac = [0.0; 7];
    for i in 0..7 {
        cac[i] = c[i] * c1[i];
        c2ac[i] = c[i] * c[i] * c1[i];
        cac2[i] = c[i] * c2[i];
        cacac[i] = c[i] * ac1[i];
        ac1sq[i] = c1[i] * c1[i];
        caac[i] = c[i] * ac1[i];
    }
    let order5 = [
        (dot(&b, &[1.0; 7]), 1.0),
        (dot(&b, &pw(1)), 1.0 / 2.0),
        (dot(&b, &pw(2)), 1.0 / 3.0),
        (dot(&b, &c1), 1.0 / 6.0),
        (dot(&b, &pw(3)), 1.0 / 4.0),
        (dot(&b, &cac), 1.0 / 8.0),
        (dot(&b, &c2), 1.0 / 12.0),
        (dot(&b, &ac1), 1.0 / 24.0),
        (dot(&b, &pw(4)), 1.0 / 5.0),
        (dot(&b, &c2ac), 1.0 / 10.0),
        (dot(&b, &cac2), 1.0 / 15.0),
        (dot(&b, &cacac), 1.0 / 30.0),
        (dot(&b, &ac1sq), 1.0 / 20.0),
        (dot(&b, &c3), 1.0 / 20.0),
        (dot(&b, &ac(&cac)), 1.0 / 40.0),
        (dot(&b, &ac(&c2)), 1.0 / 60.0),
        (dot(&b, &ac(&ac1)), 1.0 / 120.0),
    ];
    for (k, (got, want)) in order5.iter().enumerate() {
        assert!((got - want).abs() < 1e-14, "condition {k}: {got} vs {want}");
    }
    let _ = caac;
    let order4 = [
        (dot(&bh, &[1.0; 7]), 1.0),
        (dot(&bh, &pw(1)), 0.5),
        (dot(&bh, &pw(2)), 1.0 / 3.0),
        (dot(&bh, &c1), 1.0 / 6.0),
        (dot(&bh, &pw(3)), 0.25),
        (dot(&bh, &cac), 0.125),
        (dot(&bh, &c2), 1.0 / 12.0),
        (dot(&bh, &ac1), 1.0 / 24.0),
    ];
    for (k, (got, want)) in order4.iter().enumerate() {
        assert!(
            (got - want).abs() < 1e-14,
            "embedded condition {k}: {got} vs {want}"
        );
    }
    assert!(
        (dot(&bh, &pw(4)) - 0.2).abs() > 1e-4,
        "embedded pair must differ at order 5"
    );
}

// ---------------------------------------------------------------------------------------
// Measured convergence orders (fixed steps, error against the exact solution)
// ---------------------------------------------------------------------------------------

/// Observed orders `log2(e(N)/e(2N))` for `N = n0, 2n0, 4n0, 8n0`.
fn observed_orders(n0: usize, mut err_at: impl FnMut(usize) -> f64) -> Vec<f64> {
    let errs: Vec<f64> = (0..4).map(|k| err_at(n0 << k)).collect();
    errs.windows(2).map(|w| (w[0] / w[1]).log2()).collect()
}

fn assert_order(name: &str, orders: &[f64], nominal: f64) {
    println!("{name}: observed orders {orders:.2?}");
    let last = orders[orders.len() - 1];
    assert!(
        (last - nominal).abs() <= 0.3,
        "{name}: observed orders {orders:?}, nominal {nominal}"
    );
}

const T_END: f64 = 2.0;

#[test]
fn rosenbrock_order_3_with_exact_and_approximate_jacobian() {
    let x0 = LimitCycle::exact(0.0, 0.5);
    let exact = LimitCycle::exact(T_END, 0.5);
    let run = |sys: &mut dyn FnMut(&mut Rosenbrock, &mut [f64], usize), n: usize| {
        let mut r = Rosenbrock::new(2, Tolerances::default()).unwrap();
        let mut x = x0;
        sys(&mut r, &mut x, n);
        max_abs_diff(&x, &exact)
    };
    // Exact (analytic) Jacobian.
    let mut exact_w = |r: &mut Rosenbrock, x: &mut [f64], n: usize| {
        let mut s = DenseW::with_jacobian(LimitCycle);
        s.autonomous = true;
        r.integrate_fixed(&mut s, 0.0, T_END, x, n).unwrap();
    };
    let o = observed_orders(10, |n| run(&mut exact_w, n));
    assert_order("ROS34PW2, analytic J", &o, 3.0);
    // Finite-difference Jacobian.
    let mut fd_w = |r: &mut Rosenbrock, x: &mut [f64], n: usize| {
        struct NoJac;
        impl OdeSystem for NoJac {
            fn dim(&self) -> usize {
                2
            }
            fn rhs(&mut self, t: f64, x: &[f64], dx: &mut [f64]) -> bool {
                LimitCycle.rhs(t, x, dx)
            }
        }
        let mut s = DenseW::new(NoJac);
        r.integrate_fixed(&mut s, 0.0, T_END, x, n).unwrap();
    };
    let o = observed_orders(10, |n| run(&mut fd_w, n));
    assert_order("ROS34PW2, FD J", &o, 3.0);
    // A fixed J̃ unrelated to the true Jacobian, and J̃ = 0 (the method is then explicit).
    for jt in [[-0.3, 0.7, 0.2, -1.1], [0.0; 4], [2.0, -1.0, 3.0, 0.5]] {
        let mut w = |r: &mut Rosenbrock, x: &mut [f64], n: usize| {
            let mut s = FixedW {
                sys: LimitCycle,
                jt,
                winv: [0.0; 4],
            };
            r.integrate_fixed(&mut s, 0.0, T_END, x, n).unwrap();
        };
        let o = observed_orders(10, |n| run(&mut w, n));
        assert_order(&format!("ROS34PW2, J̃ = {jt:?}"), &o, 3.0);
    }
}

#[test]
fn rosenbrock_order_3_on_non_autonomous_problem() {
    let x0 = Manufactured::phi(0.0);
    let exact = Manufactured::phi(T_END);
    // FD Jacobian and FD ∂f/∂t.
    let o = observed_orders(10, |n| {
        let mut r = Rosenbrock::new(2, Tolerances::default()).unwrap();
        let mut s = DenseW::new(Manufactured);
        let mut x = x0;
        r.integrate_fixed(&mut s, 0.0, T_END, &mut x, n).unwrap();
        max_abs_diff(&x, &exact)
    });
    assert_order("ROS34PW2 non-autonomous, FD J and f_t", &o, 3.0);
    // Approximate J̃ and ∂f/∂t taken as 0.
    let o = observed_orders(10, |n| {
        let mut r = Rosenbrock::new(2, Tolerances::default()).unwrap();
        let mut s = FixedW {
            sys: Manufactured,
            jt: [-1.0, 0.5, 0.0, -2.0],
            winv: [0.0; 4],
        };
        let mut x = x0;
        r.integrate_fixed(&mut s, 0.0, T_END, &mut x, n).unwrap();
        max_abs_diff(&x, &exact)
    });
    assert_order("ROS34PW2 non-autonomous, J̃ fixed, f_t = 0", &o, 3.0);
}

#[test]
fn dormand_prince_order_5() {
    // (On the limit cycle the leading error term nearly vanishes: order ≈ 6 is observed.)
    let e = 0.5;
    let exact = Kepler::exact(PI, e);
    let o = observed_orders(20, |n| {
        let mut d = DormandPrince::new(4, Tolerances::default()).unwrap();
        let mut x = Kepler::initial(e);
        d.integrate_fixed(&mut Kepler, 0.0, PI, &mut x, n).unwrap();
        max_abs_diff(&x, &exact)
    });
    assert_order("DOPRI5 Kepler", &o, 5.0);
    let x0 = Manufactured::phi(0.0);
    let exact = Manufactured::phi(T_END);
    let o = observed_orders(40, |n| {
        let mut d = DormandPrince::new(2, Tolerances::default()).unwrap();
        let mut x = x0;
        d.integrate_fixed(&mut Manufactured, 0.0, T_END, &mut x, n)
            .unwrap();
        max_abs_diff(&x, &exact)
    });
    assert_order("DOPRI5 manufactured", &o, 5.0);
}

/// The mechanical W reduction on a stiff chain (constant M, exact `K̃`, `D̃`): order 3 at
/// steps far beyond the explicit stability limit.
#[test]
fn rosenbrock_mechanical_w_order_on_stiff_chain() {
    let chain = Chain::new(1.0);
    let x0 = [0.01, -0.02, 0.0, 0.03, 0.0, 0.5, -0.5, 0.0];
    let t_end = 0.5;
    let exact = chain.exact(t_end, &x0);
    let o = observed_orders(40, |n| {
        let mut c = Chain::new(1.0);
        let mut r = Rosenbrock::new(8, Tolerances::default()).unwrap();
        let mut x = x0;
        r.integrate_fixed(&mut c, 0.0, t_end, &mut x, n).unwrap();
        max_abs_diff(&x, &exact)
    });
    // Steps of 12.5 ms down to 1.6 ms, |hλ| up to ≈ 10³: the fast modes are damped by
    // L-stability and the classical order shows. (A J̃ that is wrong in the stiff part has
    // the W order only once h‖J − J̃‖ ≪ 1: see the adaptive chain test.)
    assert_order("ROS34PW2 chain, exact K̃ and D̃", &o, 3.0);
}

// ---------------------------------------------------------------------------------------
// Adaptive runs against exact solutions
// ---------------------------------------------------------------------------------------

#[test]
fn stiff_linear_system_adaptive() {
    let x0 = [1.0, 1.0];
    let t_end = 10.0;
    for (rtol, atol) in [(1e-4, 1e-7), (1e-6, 1e-9), (1e-8, 1e-11)] {
        let mut r = Rosenbrock::new(2, tol(rtol, atol)).unwrap();
        let mut s = DenseW::new(StiffLinear::new());
        s.autonomous = true;
        let mut x = x0;
        let mut max_err: f64 = 0.0;
        let mut stats = Stats::default();
        for k in 0..100 {
            let (t0, t1) = (k as f64 * 0.1, (k + 1) as f64 * 0.1);
            stats.accumulate(&r.integrate(&mut s, t0, t1, &mut x).unwrap());
            let ex = StiffLinear::exact(t1, x0);
            max_err =
                max_err.max(max_abs_diff(&x, &ex) / (atol + rtol * ex[0].abs().max(ex[1].abs())));
        }
        assert!(max_err < 10.0, "rtol {rtol}: error {max_err} tolerances");
        assert!(stats.steps < 2000, "rtol {rtol}: {} steps", stats.steps);
        assert!((t_end - 10.0f64).abs() < 1e-12);
    }
    // The explicit pair needs ≈ |λ| h ≤ 3.3 for stability: many more evaluations.
    let mut r = Rosenbrock::new(2, tol(1e-6, 1e-9)).unwrap();
    let mut s = DenseW::new(StiffLinear::new());
    s.autonomous = true;
    let mut x = x0;
    let sr = r.integrate(&mut s, 0.0, t_end, &mut x).unwrap();
    let mut d = DormandPrince::new(2, tol(1e-6, 1e-9)).unwrap();
    let mut y = x0;
    let sd = d
        .integrate(&mut StiffLinear::new(), 0.0, t_end, &mut y)
        .unwrap();
    let ex = StiffLinear::exact(t_end, x0);
    assert!(max_abs_diff(&y, &ex) < 1e-5);
    assert!(max_abs_diff(&x, &ex) < 1e-5);
    assert!(
        sd.rhs_evals > 20 * (sr.rhs_evals + s.jacobian_rhs_evals()),
        "{sd:?} vs {sr:?}"
    );
}

#[test]
fn prothero_robinson_adaptive() {
    for lambda in [-1e6, -1e2] {
        for (rtol, atol) in [(1e-5, 1e-8), (1e-8, 1e-11)] {
            let mut r = Rosenbrock::new(1, tol(rtol, atol)).unwrap();
            let mut s = DenseW::new(ProtheroRobinson { lambda });
            let mut x = [1.0];
            let mut max_err: f64 = 0.0;
            let mut steps = 0;
            for k in 0..50 {
                let (t0, t1) = (k as f64 * 0.1, (k + 1) as f64 * 0.1);
                steps += r.integrate(&mut s, t0, t1, &mut x).unwrap().steps;
                max_err = max_err.max((x[0] - 1.0 - t1.sin()).abs());
            }
            assert!(
                max_err < 10.0 * (rtol * 2.0 + atol),
                "λ {lambda} rtol {rtol}: error {max_err}"
            );
            assert!(steps < 5000, "λ {lambda} rtol {rtol}: {steps} steps");
        }
    }
}

#[test]
fn stiff_chain_adaptive_with_mechanical_w() {
    let x0 = [0.01, -0.02, 0.0, 0.03, 0.0, 0.5, -0.5, 0.0];
    for offdiag in [1.0, 0.9, 0.0] {
        let mut c = Chain::new(offdiag);
        let mut r = Rosenbrock::new(8, tol(1e-7, 1e-10)).unwrap();
        let mut x = x0;
        let mut stats = Stats::default();
        let mut max_err: f64 = 0.0;
        for k in 0..1000 {
            let (t0, t1) = (k as f64 * 1e-3, (k + 1) as f64 * 1e-3);
            stats.accumulate(&r.integrate(&mut c, t0, t1, &mut x).unwrap());
            if k % 50 == 49 {
                let ex = c.exact(t1, &x0);
                max_err = max_err.max(max_abs_diff(&x, &ex));
            }
        }
        // States are O(1e-2) m and O(1) m/s; tolerance 1e-7 relative.
        println!("off-diagonal {offdiag}: error {max_err:.2e}, {stats:?}");
        assert!(max_err < 2e-6, "off-diagonal {offdiag}: error {max_err}");
        // A J̃ without the stiff coupling (0) stays accurate but loses the large steps.
        let budget = if offdiag > 0.5 { 12 * 1000 } else { 60 * 1000 };
        assert!(
            stats.rhs_evals < budget,
            "off-diagonal {offdiag}: {stats:?}"
        );
    }
}

#[test]
fn kepler_orbit_and_energy() {
    let e = 0.6;
    let period = 2.0 * PI;
    // Dormand–Prince at rtol 1e-12: position and energy over two orbits.
    let mut d = DormandPrince::new(4, tol(1e-12, 1e-14)).unwrap();
    let mut x = Kepler::initial(e);
    let e0 = Kepler::energy(&x);
    let mut drift: f64 = 0.0;
    for k in 0..20 {
        let (t0, t1) = (k as f64 * period / 10.0, (k + 1) as f64 * period / 10.0);
        d.integrate(&mut Kepler, t0, t1, &mut x).unwrap();
        drift = drift.max((Kepler::energy(&x) - e0).abs());
        let ex = Kepler::exact(t1, e);
        assert!(
            max_abs_diff(&x, &ex) < 1e-8,
            "DOPRI5 error {} at t = {t1}",
            max_abs_diff(&x, &ex)
        );
    }
    assert!(drift < 1e-10, "energy drift {drift}");
    // Rosenbrock (non-stiff use) at rtol 1e-8 over one orbit.
    let mut r = Rosenbrock::new(4, tol(1e-8, 1e-11)).unwrap();
    let mut s = DenseW::new(Kepler);
    s.autonomous = true;
    let mut x = Kepler::initial(e);
    r.integrate(&mut s, 0.0, period, &mut x).unwrap();
    let err = max_abs_diff(&x, &Kepler::exact(period, e));
    assert!(err < 1e-5, "ROS34PW2 Kepler error {err}");
}

#[test]
fn surrogate_plant_matches_reference() {
    let ticks = 300;
    let reference = surrogate_reference(ticks);
    for (rtol, atol) in [(1e-6, 1e-9), (1e-8, 1e-11)] {
        let mut sys = Surrogate::new();
        let mut r = Rosenbrock::new(2 * NQ, tol(rtol, atol)).unwrap();
        let (traj, stats) = closed_loop(ticks, |t0, t1, x| {
            sys.control(x);
            r.integrate(&mut sys, t0, t1, x).unwrap()
        });
        let mut worst: f64 = 0.0;
        for (a, b) in traj.iter().zip(&reference) {
            for i in 0..2 * NQ {
                worst = worst.max((a[i] - b[i]).abs() / (atol + rtol * b[i].abs().max(1e-2)));
            }
        }
        println!("rtol {rtol}: trajectory error {worst:.2} tolerances, {stats:?}");
        assert!(
            worst < 100.0,
            "rtol {rtol}: trajectory error {worst} tolerances"
        );
        // Includes the start-up transient from rest (τ jumps to ≈ K q̄ at t = 0).
        assert!(
            stats.rhs_evals < if rtol > 1e-7 { 30 } else { 150 } * ticks,
            "rtol {rtol}: {stats:?}"
        );
    }
}

// ---------------------------------------------------------------------------------------
// Error paths
// ---------------------------------------------------------------------------------------

struct NanAfter {
    t_bad: f64,
}

impl OdeSystem for NanAfter {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, t: f64, x: &[f64], dx: &mut [f64]) -> bool {
        dx[0] = if t >= self.t_bad { f64::NAN } else { -x[0] };
        dx[1] = -x[1];
        true
    }
}

struct Riccati;

impl OdeSystem for Riccati {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&mut self, _t: f64, x: &[f64], dx: &mut [f64]) -> bool {
        dx[0] = x[0] * x[0];
        dx[0].is_finite()
    }
}

struct SingularW;

impl OdeSystem for SingularW {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&mut self, _t: f64, x: &[f64], dx: &mut [f64]) -> bool {
        dx[0] = -x[0];
        true
    }
}

impl WSolve for SingularW {
    fn prepare_w(&mut self, _t: f64, _x: &[f64], _gh: f64) -> bool {
        false
    }
    fn solve_w(&mut self, _r: &mut [f64]) -> bool {
        false
    }
}

#[test]
fn error_paths_are_errors_not_panics() {
    // NaN from the start: NonFinite at t0.
    let mut r = Rosenbrock::new(2, Tolerances::default()).unwrap();
    let mut s = DenseW::new(NanAfter { t_bad: 0.0 });
    let mut x = [1.0, 1.0];
    assert_eq!(
        r.integrate(&mut s, 0.0, 1.0, &mut x),
        Err(IntegratorError::NonFinite { t: 0.0 })
    );
    let mut d = DormandPrince::new(2, Tolerances::default()).unwrap();
    assert_eq!(
        d.integrate(&mut NanAfter { t_bad: 0.0 }, 0.0, 1.0, &mut x),
        Err(IntegratorError::NonFinite { t: 0.0 })
    );
    // NaN from t = 0.5 on: the integrators shrink the step, then report NonFinite before 0.5
    // with the last good state.
    let mut s = DenseW::new(NanAfter { t_bad: 0.5 });
    s.autonomous = true;
    let mut x = [1.0, 1.0];
    match r.integrate(&mut s, 0.0, 1.0, &mut x) {
        Err(IntegratorError::NonFinite { t }) => {
            assert!(t <= 0.5 && t > 0.49, "t = {t}");
            assert!((x[1] - (-t).exp()).abs() < 1e-5);
        }
        other => panic!("{other:?}"),
    }
    let mut x = [1.0, 1.0];
    match d.integrate(&mut NanAfter { t_bad: 0.5 }, 0.0, 1.0, &mut x) {
        Err(IntegratorError::NonFinite { t }) => assert!(t <= 0.5 && t > 0.49, "t = {t}"),
        other => panic!("{other:?}"),
    }
    // Non-finite initial state.
    let mut x = [f64::NAN, 1.0];
    assert!(matches!(
        d.integrate(&mut NanAfter { t_bad: 9.0 }, 0.0, 1.0, &mut x),
        Err(IntegratorError::NonFinite { .. })
    ));
    // Blow-up of y' = y² at t = 1: an error before t = 1, never a panic or a wrong success.
    for max_steps in [100_000, 50] {
        let tl = Tolerances {
            max_steps,
            ..Tolerances::default()
        };
        let mut r = Rosenbrock::new(1, tl).unwrap();
        let mut s = DenseW::new(Riccati);
        s.autonomous = true;
        let mut x = [1.0];
        let res = r.integrate(&mut s, 0.0, 2.0, &mut x);
        match res {
            Err(IntegratorError::StepTooSmall { t, .. })
            | Err(IntegratorError::NonFinite { t })
            | Err(IntegratorError::TooManySteps { t }) => assert!(t < 1.01, "{res:?}"),
            other => panic!("{other:?}"),
        }
        if max_steps == 50 {
            assert!(
                matches!(res, Err(IntegratorError::TooManySteps { .. })),
                "{res:?}"
            );
        }
        let mut d = DormandPrince::new(1, tl).unwrap();
        let mut x = [1.0];
        let res = d.integrate(&mut Riccati, 0.0, 2.0, &mut x);
        assert!(res.is_err(), "{res:?}");
    }
    // W that cannot be factored.
    let mut r = Rosenbrock::new(1, Tolerances::default()).unwrap();
    let mut x = [1.0];
    assert!(
        matches!(r.integrate(&mut SingularW, 0.0, 1.0, &mut x), Err(IntegratorError::WFailed { t }) if t == 0.0)
    );
    // Sizes and settings.
    let mut x3 = [1.0, 2.0, 3.0];
    assert_eq!(
        r.integrate(&mut SingularW, 0.0, 1.0, &mut x3),
        Err(IntegratorError::DimensionMismatch {
            expected: 1,
            got: 3
        })
    );
    assert!(r.integrate(&mut SingularW, 1.0, 0.0, &mut x).is_err());
    for bad in [
        Tolerances {
            rtol: -1.0,
            ..Tolerances::default()
        },
        Tolerances {
            rtol: 0.0,
            atol: 0.0,
            ..Tolerances::default()
        },
        Tolerances {
            atol: f64::NAN,
            ..Tolerances::default()
        },
        Tolerances {
            h_min: 0.0,
            ..Tolerances::default()
        },
        Tolerances {
            h_initial: 1e-20,
            ..Tolerances::default()
        },
        Tolerances {
            h_max: 1e-9,
            ..Tolerances::default()
        },
        Tolerances {
            max_steps: 0,
            ..Tolerances::default()
        },
    ] {
        assert!(bad.validate().is_err(), "{bad:?}");
        assert!(Rosenbrock::new(2, bad).is_err());
        assert!(DormandPrince::new(2, bad).is_err());
    }
    assert!(Tolerances::default().validate().is_ok());
    // An empty interval is a no-op.
    let mut x = [1.0];
    assert_eq!(
        r.integrate(&mut SingularW, 1.0, 1.0, &mut x)
            .map(|s| s.steps),
        Ok(0)
    );
}

#[test]
fn mechanical_w_solves_the_block_system() {
    // Build W = I − γh J̃ explicitly (2n×2n) for random-ish M, K̃, D̃ and compare W·(W⁻¹ r) = r.
    let n = 3;
    let mut w = MechanicalW::new(n);
    let m = [0.4, 0.05, 0.02, 0.05, 0.3, -0.03, 0.02, -0.03, 0.2];
    let k = [6000.0, 100.0, 0.0, 100.0, 5000.0, -50.0, 0.0, -50.0, 10.0];
    let d = [3000.0, 0.0, 10.0, 0.0, 2000.0, 0.0, 10.0, 0.0, 5.0];
    w.mass_matrix_mut().copy_from_slice(&m);
    w.stiffness_mut().copy_from_slice(&k);
    w.damping_mut().copy_from_slice(&d);
    // M⁻¹ by solving with unit vectors through a 3×3 adjugate, independent of the code.
    let det = m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6])
        + m[2] * (m[3] * m[7] - m[4] * m[6]);
    let minv = [
        (m[4] * m[8] - m[5] * m[7]) / det,
        (m[2] * m[7] - m[1] * m[8]) / det,
        (m[1] * m[5] - m[2] * m[4]) / det,
        (m[5] * m[6] - m[3] * m[8]) / det,
        (m[0] * m[8] - m[2] * m[6]) / det,
        (m[2] * m[3] - m[0] * m[5]) / det,
        (m[3] * m[7] - m[4] * m[6]) / det,
        (m[1] * m[6] - m[0] * m[7]) / det,
        (m[0] * m[4] - m[1] * m[3]) / det,
    ];
    for gh in [1e-6, 1e-4, 1e-2, 1.0] {
        assert!(w.factor(gh));
        let r = [1.0, -2.0, 0.5, 3.0, 0.1, -0.7];
        let mut y = r;
        assert!(w.solve(&mut y));
        // W y = (y₁ − γh y₂, y₂ + γh M⁻¹(K̃ y₁ + D̃ y₂)).
        let mut wy = [0.0; 6];
        for i in 0..n {
            wy[i] = y[i] - gh * y[n + i];
            let mut s = 0.0;
            for j in 0..n {
                let f: f64 = (0..n)
                    .map(|l| k[j * n + l] * y[l] + d[j * n + l] * y[n + l])
                    .sum();
                s += minv[i * n + j] * f;
            }
            wy[n + i] = y[n + i] + gh * s;
        }
        let scale = r.iter().map(|v: &f64| v.abs()).fold(0.0, f64::max);
        assert!(
            max_abs_diff(&wy, &r) < 1e-9 * scale * (1.0 + gh * 1e4),
            "γh = {gh}: {wy:?}"
        );
    }
    let mut short = [0.0; 4];
    assert!(!w.solve(&mut short));
}

// ---------------------------------------------------------------------------------------
// Allocation
// ---------------------------------------------------------------------------------------

#[test]
fn no_allocation_per_integrate_call() {
    let mut sys = Surrogate::new();
    let mut r = Rosenbrock::new(2 * NQ, Tolerances::default()).unwrap();
    let mut dense = DenseW::new(Surrogate::new());
    dense.autonomous = true;
    let mut rd = Rosenbrock::new(2 * NQ, Tolerances::default()).unwrap();
    let mut dp = DormandPrince::new(2 * NQ, Tolerances::default()).unwrap();
    let mut x = [0.0; 2 * NQ];
    let mut y = x;
    let mut z = x;
    sys.control(&x);
    r.integrate(&mut sys, 0.0, 1e-3, &mut x).unwrap();
    rd.integrate(&mut dense, 0.0, 1e-3, &mut y).unwrap();
    dp.integrate(&mut sys, 0.0, 1e-3, &mut z).unwrap();
    let before = allocations();
    for k in 1..200 {
        let (t0, t1) = (k as f64 * 1e-3, (k + 1) as f64 * 1e-3);
        sys.control(&x);
        r.integrate(&mut sys, t0, t1, &mut x).unwrap();
        dense.system.control(&y);
        rd.integrate(&mut dense, t0, t1, &mut y).unwrap();
        sys.control(&z);
        dp.integrate(&mut sys, t0, t1, &mut z).unwrap();
        let _ = r.integrate_fixed(&mut sys, t0, t1, &mut x.clone(), 2);
    }
    assert_eq!(allocations() - before, 0);
}

// ---------------------------------------------------------------------------------------
// Measurement (run with `cargo test --release --test controller integrator:: -- --ignored --nocapture`)
// ---------------------------------------------------------------------------------------

#[test]
#[ignore = "measurement: prints the table of the module docs"]
fn measure_surrogate_ticks() {
    let ticks = 10_000;
    let t_ref = std::time::Instant::now();
    let reference = surrogate_reference(ticks);
    println!(
        "reference DOPRI5 rtol 1e-12: {:.1} s",
        t_ref.elapsed().as_secs_f64()
    );
    let last = reference[ticks];
    println!(
        "| method | rtol / atol | rhs / tick | W factor. / tick | µs / tick | max error over 10 s |"
    );
    println!("|---|---|---|---|---|---|");
    for (rtol, atol) in [(1e-6, 1e-9), (1e-8, 1e-11)] {
        for method in [
            "ROS34PW2, mechanical J̃ (frozen M, K, D)",
            "same, error estimate filtered by W⁻¹",
            "ROS34PW2, FD Jacobian",
            "DOPRI5",
        ] {
            let mut sys = Surrogate::new();
            let mut dense = DenseW::new(Surrogate::new());
            dense.autonomous = true;
            let mut r = Rosenbrock::new(2 * NQ, tol(rtol, atol)).unwrap();
            let mut dp = DormandPrince::new(2 * NQ, tol(rtol, atol)).unwrap();
            r.set_error_filter(method.contains("filtered"));
            let mut best = f64::INFINITY;
            let mut result = None;
            for _rep in 0..3 {
                let start = std::time::Instant::now();
                let fd_before = dense.jacobian_rhs_evals();
                let (traj, stats) = closed_loop(ticks, |t0, t1, x| match method {
                    m if m.starts_with("DOPRI5") => {
                        sys.control(x);
                        dp.integrate(&mut sys, t0, t1, x).unwrap()
                    }
                    m if m.contains("FD") => {
                        dense.system.control(x);
                        r.integrate(&mut dense, t0, t1, x).unwrap()
                    }
                    _ => {
                        sys.control(x);
                        r.integrate(&mut sys, t0, t1, x).unwrap()
                    }
                });
                let el = start.elapsed().as_secs_f64();
                best = best.min(el);
                let fd = dense.jacobian_rhs_evals() - fd_before;
                let err = traj
                    .iter()
                    .zip(&reference)
                    .map(|(a, b)| max_abs_diff(a, b))
                    .fold(0.0, f64::max);
                result = Some((stats, fd, err, max_abs_diff(&traj[ticks], &last)));
                r.reset();
                dp.reset();
            }
            let (stats, fd, err, _end) = result.unwrap();
            println!(
                "| {method} | {rtol:e} / {atol:e} | {:.1} | {:.2} | {:.2} | {:.1e} |",
                (stats.rhs_evals + fd) as f64 / ticks as f64,
                stats.w_factorizations as f64 / ticks as f64,
                best / ticks as f64 * 1e6,
                err
            );
        }
    }
}
