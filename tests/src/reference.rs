//! A plain, hand-written evaluation of docs/model.md §2–4 (no generated code): segment transforms,
//! corner heights, world poses, mass matrix, `C q̇` and gravity, with exact derivatives by jets.
//!
//! Derivatives come from forward-mode [`Jet`]s, which carry a value, its gradient over the
//! `N` coordinates, its first and second derivatives along one direction (the velocity
//! `q̇`), and the derivative of the gradient along that direction. `f_s`, `f_c` come from
//! `sin`/`cos` of `θ = √u` for `u ≥` [`SERIES_BELOW`] and from their power series below.
//!
//! The barriers beyond the plate corners (limits, obstacles on plate and backbone points)
//! come both as jets ([`all_barriers`]) and as plain values from closed forms in the bend
//! angle and direction ([`all_barrier_values_closed_form`]); [`arc_point_integrated`]
//! integrates the backbone's tangent.

use std::f64::consts::PI;
use std::ops::{Add, Div, Mul, Neg, Sub};
use std::path::PathBuf;

use rand::RngExt;
use softcbf_description::barriers::{Limits, Shape, WatchedPoint};
use softcbf_description::robot::{Module, Robot, Routing};

use crate::TestRng;

/// Below this `u = θ²`, `f_s`, `f_c` come from their power series (30 terms, exact to the
/// last bit there); above it from `sin θ`, `cos θ`, where the quotients lose < 4 ulp.
pub const SERIES_BELOW: f64 = 1.0;

/// Terms of the power series used below [`SERIES_BELOW`].
const SERIES_TERMS: usize = 30;

/// A truncated multivariate Taylor expansion of a function of `q(t) = q + t q̇`:
/// value, gradient `∂/∂q_k`, first and second derivatives along `q̇`, and `∂/∂q_k` of the
/// first derivative along `q̇` (i.e. `(∇²f q̇)_k`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Jet<const N: usize> {
    /// `f(q)`.
    pub v: f64,
    /// `∇f · q̇`.
    pub d: f64,
    /// `q̇ᵀ ∇²f q̇`.
    pub dd: f64,
    /// `∇f`.
    pub g: [f64; N],
    /// `∇²f q̇`.
    pub gd: [f64; N],
}

impl<const N: usize> Jet<N> {
    /// A constant.
    pub const fn constant(v: f64) -> Self {
        Jet {
            v,
            d: 0.0,
            dd: 0.0,
            g: [0.0; N],
            gd: [0.0; N],
        }
    }

    /// The coordinates `q_k` themselves, moving with velocity `qd`.
    pub fn seed(q: &[f64; N], qd: &[f64; N]) -> [Self; N] {
        std::array::from_fn(|k| {
            let mut x = Jet::constant(q[k]);
            x.d = qd[k];
            x.g[k] = 1.0;
            x
        })
    }

    /// `f(self)` from `f`, `f'`, `f''` at `self.v` (chain rule).
    pub fn lift(self, f0: f64, f1: f64, f2: f64) -> Self {
        Jet {
            v: f0,
            d: f1 * self.d,
            dd: f2 * self.d * self.d + f1 * self.dd,
            g: std::array::from_fn(|k| f1 * self.g[k]),
            gd: std::array::from_fn(|k| f2 * self.d * self.g[k] + f1 * self.gd[k]),
        }
    }

    /// `1 / self`.
    pub fn recip(self) -> Self {
        let r = 1.0 / self.v;
        self.lift(r, -r * r, 2.0 * r * r * r)
    }

    /// `√self` (needs `self.v > 0` for finite derivatives).
    pub fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.lift(s, 0.5 / s, -0.25 / (s * self.v))
    }

    /// `sin self`.
    pub fn sin(self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.lift(s, c, -s)
    }

    /// `cos self`.
    pub fn cos(self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.lift(c, -s, -c)
    }
}

impl<const N: usize> Add for Jet<N> {
    type Output = Self;
    fn add(self, b: Self) -> Self {
        Jet {
            v: self.v + b.v,
            d: self.d + b.d,
            dd: self.dd + b.dd,
            g: std::array::from_fn(|k| self.g[k] + b.g[k]),
            gd: std::array::from_fn(|k| self.gd[k] + b.gd[k]),
        }
    }
}

impl<const N: usize> Neg for Jet<N> {
    type Output = Self;
    fn neg(self) -> Self {
        self * -1.0
    }
}

impl<const N: usize> Sub for Jet<N> {
    type Output = Self;
    fn sub(self, b: Self) -> Self {
        self + (-b)
    }
}

impl<const N: usize> Mul for Jet<N> {
    type Output = Self;
    fn mul(self, b: Self) -> Self {
        let a = self;
        Jet {
            v: a.v * b.v,
            d: a.d * b.v + a.v * b.d,
            dd: a.dd * b.v + 2.0 * a.d * b.d + a.v * b.dd,
            g: std::array::from_fn(|k| a.g[k] * b.v + a.v * b.g[k]),
            gd: std::array::from_fn(|k| {
                a.gd[k] * b.v + a.g[k] * b.d + a.d * b.g[k] + a.v * b.gd[k]
            }),
        }
    }
}

impl<const N: usize> Div for Jet<N> {
    type Output = Self;
    #[allow(clippy::suspicious_arithmetic_impl)]
    fn div(self, b: Self) -> Self {
        self * b.recip()
    }
}

impl<const N: usize> Mul<f64> for Jet<N> {
    type Output = Self;
    fn mul(self, c: f64) -> Self {
        Jet {
            v: self.v * c,
            d: self.d * c,
            dd: self.dd * c,
            g: self.g.map(|x| x * c),
            gd: self.gd.map(|x| x * c),
        }
    }
}

impl<const N: usize> Add<f64> for Jet<N> {
    type Output = Self;
    fn add(self, c: f64) -> Self {
        Jet {
            v: self.v + c,
            ..self
        }
    }
}

impl<const N: usize> Sub<Jet<N>> for f64 {
    type Output = Jet<N>;
    fn sub(self, b: Jet<N>) -> Jet<N> {
        -b + self
    }
}

/// `[p(u), p'(u), p''(u)]` of the power series `p(u) = Σ_n (−u)^n / (2n + first)!`.
fn series(u: f64, first: usize) -> [f64; 3] {
    let mut a = [0.0; SERIES_TERMS + 2];
    a[0] = 1.0 / (1..=first).map(|k| k as f64).product::<f64>();
    for n in 0..SERIES_TERMS + 1 {
        let m = (2 * n + first) as f64;
        a[n + 1] = -a[n] / ((m + 1.0) * (m + 2.0));
    }
    let mut out = [0.0; 3];
    for (order, o) in out.iter_mut().enumerate() {
        // Σ_n (n+1)⋯(n+order) a_{n+order} u^n by Horner.
        let mut sum = 0.0;
        for n in (0..SERIES_TERMS).rev() {
            let falling: f64 = (1..=order).map(|j| (n + j) as f64).product();
            sum = sum * u + falling * a[n + order];
        }
        *o = sum;
    }
    out
}

/// `(f_s(u), f_c(u))` of docs/model.md §2 as jets.
pub fn fs_fc<const N: usize>(u: Jet<N>) -> (Jet<N>, Jet<N>) {
    if u.v < SERIES_BELOW {
        let [s0, s1, s2] = series(u.v, 1);
        let [c0, c1, c2] = series(u.v, 2);
        (u.lift(s0, s1, s2), u.lift(c0, c1, c2))
    } else {
        let theta = u.sqrt();
        let fs = theta.sin() / theta;
        let half = theta * 0.5;
        let sinc_half = half.sin() / half;
        (fs, sinc_half * sinc_half * 0.5)
    }
}

/// `(f_s(u), f_c(u))` in plain f64.
pub fn fs_fc_value(u: f64) -> (f64, f64) {
    let (s, c) = fs_fc(Jet::<0>::constant(u));
    (s.v, c.v)
}

/// A 3-vector.
pub type Vec3<T> = [T; 3];
/// A 3×3 matrix, rows.
pub type Mat3<T> = [[T; 3]; 3];

/// `(R, t)` of one segment at `(Δx, Δy, δL)` (docs/model.md §2).
pub fn segment<const N: usize>(
    module: &Module,
    dx: Jet<N>,
    dy: Jet<N>,
    dl: Jet<N>,
) -> (Mat3<Jet<N>>, Vec3<Jet<N>>) {
    let inv_d = 1.0 / module.tendon_radius;
    let (a, b) = (dx * inv_d, dy * inv_d);
    let u = a * a + b * b;
    let (fs, fc) = fs_fc(u);
    let length = dl + module.rest_length;
    let abfc = a * b * fc;
    let rotation = [
        [1.0 - a * a * fc, -abfc, a * fs],
        [-abfc, 1.0 - b * b * fc, b * fs],
        [-(a * fs), -(b * fs), 1.0 - u * fc],
    ];
    let translation = [length * a * fc, length * b * fc, length * fs];
    (rotation, translation)
}

/// `(R, t)` of one segment in plain f64.
pub fn segment_value(module: &Module, q: [f64; 3]) -> (Mat3<f64>, Vec3<f64>) {
    let [dx, dy, dl] = q.map(Jet::<0>::constant);
    let (r, t) = segment(module, dx, dy, dl);
    (r.map(|row| row.map(|x| x.v)), t.map(|x| x.v))
}

/// Corner height `c_ij` of corner `j` (docs/model.md §3).
pub fn corner_height<const N: usize>(
    module: &Module,
    corner: usize,
    dx: Jet<N>,
    dy: Jet<N>,
    dl: Jet<N>,
) -> Jet<N> {
    let inv_d = 1.0 / module.tendon_radius;
    let (a, b) = (dx * inv_d, dy * inv_d);
    let (fs, _) = fs_fc(a * a + b * b);
    let phi = module.corner_angles[corner];
    let lever = (dx * phi.cos() + dy * phi.sin()) * (module.corner_radius * inv_d);
    fs * (dl + module.rest_length - lever)
}

/// Every barrier `b_ij = c_ij − ε_ij` of the robot, module-major, corner-minor.
pub fn barriers<const N: usize>(robot: &Robot, q: &[f64; N], qd: &[f64; N]) -> Vec<Jet<N>> {
    check_size::<N>(robot);
    let x = Jet::seed(q, qd);
    let mut out = Vec::new();
    for (i, module) in robot.modules.iter().enumerate() {
        for (j, margin) in module.margins.iter().enumerate() {
            let c = corner_height(module, j, x[3 * i], x[3 * i + 1], x[3 * i + 2]);
            out.push(c + (-margin));
        }
    }
    out
}

/// Segment and world kinematics of the whole chain as jets.
#[derive(Clone, Debug)]
pub struct Chain<const N: usize> {
    /// `R_i` of each segment.
    pub rotation: Vec<Mat3<Jet<N>>>,
    /// `t_i` of each segment.
    pub translation: Vec<Vec3<Jet<N>>>,
    /// World rotation of each plate (rotation part of `W_i`).
    pub world_rotation: Vec<Mat3<Jet<N>>>,
    /// World position of each plate's tip-frame origin.
    pub world_position: Vec<Vec3<Jet<N>>>,
    /// World position of each plate's centre of mass.
    pub com: Vec<Vec3<Jet<N>>>,
}

fn check_size<const N: usize>(robot: &Robot) {
    assert_eq!(
        3 * robot.modules.len(),
        N,
        "reference: state size {N} does not fit {} modules",
        robot.modules.len()
    );
}

fn jet_mat_mul<const N: usize>(a: &Mat3<Jet<N>>, b: &Mat3<Jet<N>>) -> Mat3<Jet<N>> {
    std::array::from_fn(|r| {
        std::array::from_fn(|c| a[r][0] * b[0][c] + a[r][1] * b[1][c] + a[r][2] * b[2][c])
    })
}

fn jet_mat_vec<const N: usize>(a: &Mat3<Jet<N>>, x: &Vec3<Jet<N>>) -> Vec3<Jet<N>> {
    std::array::from_fn(|r| a[r][0] * x[0] + a[r][1] * x[1] + a[r][2] * x[2])
}

/// The chain's kinematics at `(q, q̇)`.
pub fn chain<const N: usize>(robot: &Robot, q: &[f64; N], qd: &[f64; N]) -> Chain<N> {
    check_size::<N>(robot);
    let x = Jet::seed(q, qd);
    let zero = Jet::constant(0.0);
    let one = Jet::constant(1.0);
    let mut world_r = [[one, zero, zero], [zero, one, zero], [zero, zero, one]];
    let mut world_p = [zero; 3];
    let mut out = Chain {
        rotation: Vec::new(),
        translation: Vec::new(),
        world_rotation: Vec::new(),
        world_position: Vec::new(),
        com: Vec::new(),
    };
    for (i, module) in robot.modules.iter().enumerate() {
        let (r, t) = segment(module, x[3 * i], x[3 * i + 1], x[3 * i + 2]);
        let moved = jet_mat_vec(&world_r, &t);
        world_p = std::array::from_fn(|k| world_p[k] + moved[k]);
        world_r = jet_mat_mul(&world_r, &r);
        let com = std::array::from_fn(|k| world_p[k] + world_r[k][2] * module.com_offset);
        out.rotation.push(r);
        out.translation.push(t);
        out.world_rotation.push(world_r);
        out.world_position.push(world_p);
        out.com.push(com);
    }
    out
}

/// Values of a jet matrix.
pub fn mat_value<const N: usize>(m: &Mat3<Jet<N>>) -> Mat3<f64> {
    m.map(|row| row.map(|x| x.v))
}

fn mat_part<const N: usize>(m: &Mat3<Jet<N>>, part: impl Fn(&Jet<N>) -> f64) -> Mat3<f64> {
    m.map(|row| row.map(|x| part(&x)))
}

fn vec_part<const N: usize>(v: &Vec3<Jet<N>>, part: impl Fn(&Jet<N>) -> f64) -> Vec3<f64> {
    v.map(|x| part(&x))
}

/// `a · b`.
pub fn dot(a: &Vec3<f64>, b: &Vec3<f64>) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a b`.
pub fn mat_mul(a: &Mat3<f64>, b: &Mat3<f64>) -> Mat3<f64> {
    std::array::from_fn(|r| std::array::from_fn(|c| (0..3).map(|k| a[r][k] * b[k][c]).sum()))
}

/// `aᵀ`.
pub fn transpose(a: &Mat3<f64>) -> Mat3<f64> {
    std::array::from_fn(|r| std::array::from_fn(|c| a[c][r]))
}

/// `a x`.
pub fn mat_vec(a: &Mat3<f64>, x: &Vec3<f64>) -> Vec3<f64> {
    std::array::from_fn(|r| dot(&a[r], x))
}

fn mat_add(a: &Mat3<f64>, b: &Mat3<f64>) -> Mat3<f64> {
    std::array::from_fn(|r| std::array::from_fn(|c| a[r][c] + b[r][c]))
}

/// The axial vector of the skew-symmetric part of `a` (`vee(½(a − aᵀ))`).
pub fn vee(a: &Mat3<f64>) -> Vec3<f64> {
    [
        0.5 * (a[2][1] - a[1][2]),
        0.5 * (a[0][2] - a[2][0]),
        0.5 * (a[1][0] - a[0][1]),
    ]
}

/// Motion subspace `S_i` (rows ω then v, tip coordinates) and `c_J = Ṡ_i q̇_i` of segment
/// `module_index`, from its jets: column `k` is `(vee(Rᵀ ∂_k R), Rᵀ ∂_k t)`.
pub fn motion_subspace<const N: usize>(
    chain: &Chain<N>,
    module_index: usize,
    qd: &[f64; N],
) -> ([[f64; 3]; 6], [f64; 6]) {
    let (r, t) = (
        &chain.rotation[module_index],
        &chain.translation[module_index],
    );
    let rv = mat_value(r);
    let rt = transpose(&rv);
    let rdt = transpose(&mat_part(r, |x| x.d));
    let mut s = [[0.0; 3]; 6];
    let mut bias = [0.0; 6];
    for l in 0..3 {
        let k = 3 * module_index + l;
        let dr = mat_part(r, |x| x.g[k]);
        let dr_dot = mat_part(r, |x| x.gd[k]);
        let dt = vec_part(t, |x| x.g[k]);
        let dt_dot = vec_part(t, |x| x.gd[k]);
        let w = vee(&mat_mul(&rt, &dr));
        let v = mat_vec(&rt, &dt);
        // d/dt of the column along q̇ (q̈ = 0).
        let w_dot = vee(&mat_add(&mat_mul(&rdt, &dr), &mat_mul(&rt, &dr_dot)));
        let v_dot: Vec3<f64> =
            std::array::from_fn(|c| mat_vec(&rdt, &dt)[c] + mat_vec(&rt, &dt_dot)[c]);
        let column = [w[0], w[1], w[2], v[0], v[1], v[2]];
        let column_dot = [w_dot[0], w_dot[1], w_dot[2], v_dot[0], v_dot[1], v_dot[2]];
        for ((row, b), (x, x_dot)) in s
            .iter_mut()
            .zip(&mut bias)
            .zip(column.iter().zip(column_dot))
        {
            row[l] = *x;
            *b += x_dot * qd[k];
        }
    }
    (s, bias)
}

/// Dynamics terms of docs/model.md §4 from the jets.
#[derive(Clone, Debug)]
pub struct Dynamics<const N: usize> {
    /// `M = Σ m Jvᵀ Jv + Jωᵀ R I Rᵀ Jω` (world frame).
    pub mass_matrix: [[f64; N]; N],
    /// `h = C q̇ = d/dt(∂T/∂q̇) − ∂T/∂q` at `q̈ = 0`.
    pub bias: [f64; N],
    /// `G = ∂U_g/∂q`.
    pub gravity: [f64; N],
    /// `T = ½ q̇ᵀ M q̇`.
    pub kinetic_energy: f64,
    /// `U_g = −Σ m gᵀ p`.
    pub gravity_energy: f64,
}

/// `M`, `h`, `G`, `T`, `U_g` at `(q, q̇)` from the COM and rotation jets of each plate.
pub fn dynamics<const N: usize>(robot: &Robot, q: &[f64; N], qd: &[f64; N]) -> Dynamics<N> {
    let chain = chain(robot, q, qd);
    let g = robot.gravity;
    let mut out = Dynamics {
        mass_matrix: [[0.0; N]; N],
        bias: [0.0; N],
        gravity: [0.0; N],
        kinetic_energy: 0.0,
        gravity_energy: 0.0,
    };
    for (i, module) in robot.modules.iter().enumerate() {
        let m = module.mass;
        let (p, rw) = (&chain.com[i], &chain.world_rotation[i]);
        let inertia_tip = [
            [module.inertia[0], 0.0, 0.0],
            [0.0, module.inertia[1], 0.0],
            [0.0, 0.0, module.inertia[2]],
        ];
        let r = mat_value(rw);
        let r_dot = mat_part(rw, |x| x.d);
        let r_ddot = mat_part(rw, |x| x.dd);
        let (rt, r_dot_t) = (transpose(&r), transpose(&r_dot));
        // World inertia Ī = R I Rᵀ and its time derivative.
        let world_inertia = mat_mul(&mat_mul(&r, &inertia_tip), &rt);
        let world_inertia_dot = mat_add(
            &mat_mul(&mat_mul(&r_dot, &inertia_tip), &rt),
            &mat_mul(&mat_mul(&r, &inertia_tip), &r_dot_t),
        );
        let p_value = vec_part(p, |x| x.v);
        let p_dot = vec_part(p, |x| x.d);
        let p_ddot = vec_part(p, |x| x.dd);
        // ω = vee(Ṙ Rᵀ), ω̇ = vee(R̈ Rᵀ + Ṙ Ṙᵀ).
        let omega = vee(&mat_mul(&r_dot, &rt));
        let omega_dot = vee(&mat_add(&mat_mul(&r_ddot, &rt), &mat_mul(&r_dot, &r_dot_t)));
        let jv: [Vec3<f64>; N] = std::array::from_fn(|k| vec_part(p, |x| x.g[k]));
        let dr: [Mat3<f64>; N] = std::array::from_fn(|k| mat_part(rw, |x| x.g[k]));
        let dr_dot: [Mat3<f64>; N] = std::array::from_fn(|k| mat_part(rw, |x| x.gd[k]));
        let jw: [Vec3<f64>; N] = std::array::from_fn(|k| vee(&mat_mul(&dr[k], &rt)));
        let iw_omega = mat_vec(&world_inertia, &omega);
        for k in 0..N {
            let iw_jk = mat_vec(&world_inertia, &jw[k]);
            for l in 0..N {
                out.mass_matrix[k][l] += m * dot(&jv[k], &jv[l]) + dot(&jw[l], &iw_jk);
            }
            // Translation: m p̈·Jv_k (the ṗ·J̇v_k of d/dt ∂T/∂q̇ cancels ṗ·∂_k ṗ of ∂T/∂q).
            let translational = m * dot(&p_ddot, &jv[k]);
            // Rotation: d/dt(ωᵀ Ī Jω_k) − ∂_k(½ ωᵀ Ī ω).
            let jw_dot = vee(&mat_add(
                &mat_mul(&dr_dot[k], &rt),
                &mat_mul(&dr[k], &r_dot_t),
            ));
            let d_omega = vee(&mat_add(
                &mat_mul(&dr_dot[k], &rt),
                &mat_mul(&r_dot, &transpose(&dr[k])),
            ));
            let d_inertia = mat_add(
                &mat_mul(&mat_mul(&dr[k], &inertia_tip), &rt),
                &mat_mul(&mat_mul(&r, &inertia_tip), &transpose(&dr[k])),
            );
            let rotational = dot(&omega_dot, &iw_jk)
                + dot(&omega, &mat_vec(&world_inertia_dot, &jw[k]))
                + dot(&iw_omega, &jw_dot)
                - dot(&iw_omega, &d_omega)
                - 0.5 * dot(&omega, &mat_vec(&d_inertia, &omega));
            out.bias[k] += translational + rotational;
            out.gravity[k] -= m * dot(&g, &jv[k]);
        }
        out.kinetic_energy += 0.5 * (m * dot(&p_dot, &p_dot) + dot(&omega, &iw_omega));
        out.gravity_energy -= m * dot(&g, &p_value);
    }
    out
}

/// One module of the paper's simulation (docs/model.md §1) with the given COM offset.
pub fn paper_module(com_offset: f64) -> Module {
    let (m, r) = (0.15, 0.05);
    let corners: Vec<f64> = (0..6).map(|j| j as f64 * PI / 3.0).collect();
    Module {
        rest_length: 0.1,
        tendon_radius: 0.04,
        corner_radius: r,
        margins: vec![0.005; corners.len()],
        corner_angles: corners,
        tendon_angles: (0..3)
            .map(|k| PI / 2.0 + k as f64 * 2.0 * PI / 3.0)
            .collect(),
        mass: m,
        inertia: [
            5.0 / 24.0 * m * r * r,
            5.0 / 24.0 * m * r * r,
            5.0 / 12.0 * m * r * r,
        ],
        com_offset,
        bending_stiffness: 10.0,
        axial_stiffness: 10.0,
        bending_damping: 5.0,
        axial_damping: 5.0,
        uncertainty: Default::default(),
    }
}

/// A robot of `modules` paper modules (local routing, gravity `−9.81 e_z`).
pub fn paper_robot(modules: Vec<Module>) -> Robot {
    Robot {
        name: "reference".into(),
        source: PathBuf::from("<reference>"),
        gravity: [0.0, 0.0, -9.81],
        barrier: [Some(10.0), Some(10.0)],
        gains: Default::default(),
        routing: Routing::Local,
        limits: modules
            .iter()
            .map(|m| Limits::domain(m.rest_length))
            .collect(),
        obstacles: Vec::new(),
        uncertainty: Default::default(),
        modules,
        set_point: None,
        hardware: None,
    }
}

/// The paper's robot with a second, different module (longer, other radii, corners turned
/// by 0.3 rad, a margin per corner), so that a mix-up of module parameters shows.
pub fn two_different_modules() -> Robot {
    let mut second = paper_module(0.0);
    second.rest_length = 0.12;
    second.tendon_radius = 0.035;
    second.corner_radius = 0.055;
    second.corner_angles = (0..6)
        .map(|j| 0.3 + j as f64 * std::f64::consts::PI / 3.0)
        .collect();
    second.margins = vec![0.004, 0.005, 0.006, 0.007, 0.008, 0.009];
    paper_robot(vec![paper_module(0.0), second])
}

/// A bend angle θ from the mixture the tests need: exactly 0, in `[0, 1e-8]`, log-uniform
/// tiny, right around one of `switch_points` (given in `u = θ²`, both sides, down to one
/// ulp), or uniform in `[0, 3]` rad.
pub fn sample_theta(rng: &mut TestRng, switch_points: &[f64]) -> f64 {
    match rng.random_range(0..10) {
        0 => 0.0,
        1 => 1e-8 * rng.random::<f64>(),
        2 => 10f64.powf(rng.random_range(-300.0..-4.0)),
        3..=5 if !switch_points.is_empty() => {
            let uk = switch_points[rng.random_range(0..switch_points.len())];
            let u = match rng.random_range(0..4) {
                0 => uk,
                1 => uk.next_down(),
                2 => uk.next_up(),
                _ => {
                    let sign = if rng.random() { -1.0 } else { 1.0 };
                    uk * (1.0 + sign * 10f64.powf(rng.random_range(-15.0..-1.0)))
                }
            };
            u.sqrt()
        }
        _ => rng.random_range(0.0..3.0),
    }
}

/// A module state `(Δx, Δy, δL)` with bend `theta`: a random bend direction (sometimes
/// along an axis), and `δL` in `[−0.06, 0.06]` m (sometimes exactly 0).
pub fn sample_module(rng: &mut TestRng, module: &Module, theta: f64) -> [f64; 3] {
    let r = theta * module.tendon_radius;
    let (dx, dy) = match rng.random_range(0..8) {
        0 => (r, 0.0),
        1 => (0.0, -r),
        _ => {
            let alpha = rng.random_range(-PI..PI);
            (r * alpha.cos(), r * alpha.sin())
        }
    };
    let dl = if rng.random_range(0..6) == 0 {
        0.0
    } else {
        rng.random_range(-0.06..0.06)
    };
    [dx, dy, dl]
}

/// The diagonals of `K` and `D` written from docs/model.md §4, module by module:
/// `K_i = diag(κθ/d², κθ/d², κL)`, `D_i = diag(βθ/d², βθ/d², βL)`.
pub fn stiffness_and_damping(robot: &Robot) -> (Vec<f64>, Vec<f64>) {
    let (mut stiffness, mut damping) = (Vec::new(), Vec::new());
    for m in &robot.modules {
        let d2 = m.tendon_radius * m.tendon_radius;
        stiffness.extend([
            m.bending_stiffness / d2,
            m.bending_stiffness / d2,
            m.axial_stiffness,
        ]);
        damping.extend([
            m.bending_damping / d2,
            m.bending_damping / d2,
            m.axial_damping,
        ]);
    }
    (stiffness, damping)
}

// ---------------------------------------------------------------------------------------
// The barrier kinds beyond the plate corners (limits and obstacles), and the backbone.

/// The point at arc fraction `s` of a segment's backbone, in the segment's base frame, as
/// jets: the PCC arc up to `s` has bend coordinates `(s a, s b)` and length `s L`, so its
/// end is `s L (s a f_c, s b f_c, f_s)` at `u = s² (a² + b²)` (`s = 1`: the translation of
/// [`segment`]).
pub fn arc_point<const N: usize>(
    module: &Module,
    s: f64,
    dx: Jet<N>,
    dy: Jet<N>,
    dl: Jet<N>,
) -> Vec3<Jet<N>> {
    let scale = s / module.tendon_radius;
    let (a, b) = (dx * scale, dy * scale);
    let (fs, fc) = fs_fc(a * a + b * b);
    let length = (dl + module.rest_length) * s;
    [length * a * fc, length * b * fc, length * fs]
}

/// `sin x / x`, 1 at `x = 0`.
fn sinc(x: f64) -> f64 {
    if x == 0.0 { 1.0 } else { x.sin() / x }
}

/// Bend angle `θ = |(Δx, Δy)| / d` and bend direction `φ = atan2(Δy, Δx)` of a module state.
pub fn bend_angle_direction(module: &Module, q: [f64; 3]) -> (f64, f64) {
    (q[0].hypot(q[1]) / module.tendon_radius, q[1].atan2(q[0]))
}

/// The backbone point at arc fraction `s` in the segment's base frame, in closed form from
/// the bend angle `θ` and direction `φ`: an arc of length `s L` and bend `s θ` ends at
/// `(s L / (s θ)) ((1 − cos sθ) cos φ, (1 − cos sθ) sin φ, sin sθ)`, written with
/// `1 − cos x = 2 sin²(x/2)` and `sin x / x` so that nothing divides by a small `θ`.
pub fn arc_point_closed_form(module: &Module, q: [f64; 3], s: f64) -> Vec3<f64> {
    let (theta, phi) = bend_angle_direction(module, q);
    let length = s * (module.rest_length + q[2]);
    let bend = s * theta;
    let half = 0.5 * bend;
    // (1 − cos x)/x = 2 sin²(x/2)/x = sin(x/2) · sinc(x/2).
    let lateral = length * half.sin() * sinc(half);
    [
        lateral * phi.cos(),
        lateral * phi.sin(),
        length * sinc(bend),
    ]
}

/// A segment's `(R, t)` in closed form from `θ`, `φ`: `R = R_z(φ) R_y(θ) R_z(−φ)` (a
/// rotation by `θ` about the axis `(−sin φ, cos φ, 0)`), `t` the arc's end
/// ([`arc_point_closed_form`] at `s = 1`).
pub fn segment_closed_form(module: &Module, q: [f64; 3]) -> (Mat3<f64>, Vec3<f64>) {
    let (theta, phi) = bend_angle_direction(module, q);
    let (sp, cp) = phi.sin_cos();
    let (st, ct) = theta.sin_cos();
    let rz = |s: f64, c: f64| [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]];
    let ry = [[ct, 0.0, st], [0.0, 1.0, 0.0], [-st, 0.0, ct]];
    let rotation = mat_mul(&mat_mul(&rz(sp, cp), &ry), &rz(-sp, cp));
    (rotation, arc_point_closed_form(module, q, 1.0))
}

/// The backbone point at arc fraction `s` by integrating the tangent, independent of the
/// closed form: `dp/dσ = R(σ) e_z` for `σ ∈ [0, s L]`, with `R(σ)` the rotation by `κ σ`
/// (`κ = θ / L`) about the bend axis `k ∝ (−Δy, Δx, 0)` by Rodrigues' formula, summed by
/// composite Simpson over `steps` (even) intervals. Its error is below
/// `s L (s θ / steps)⁴ / 180`.
pub fn arc_point_integrated(module: &Module, q: [f64; 3], s: f64, steps: usize) -> Vec3<f64> {
    let steps = steps.max(2).next_multiple_of(2);
    let length = module.rest_length + q[2];
    let lateral = q[0].hypot(q[1]);
    let curvature = lateral / module.tendon_radius / length;
    let axis = if lateral > 0.0 {
        [-q[1] / lateral, q[0] / lateral, 0.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    // R(σ) e_z = e_z + sin α (k × e_z) + (1 − cos α) k × (k × e_z), α = κ σ.
    let cross = |x: &Vec3<f64>, y: &Vec3<f64>| -> Vec3<f64> {
        [
            x[1] * y[2] - x[2] * y[1],
            x[2] * y[0] - x[0] * y[2],
            x[0] * y[1] - x[1] * y[0],
        ]
    };
    let k_ez = cross(&axis, &[0.0, 0.0, 1.0]);
    let k_k_ez = cross(&axis, &k_ez);
    let tangent = |sigma: f64| -> Vec3<f64> {
        let (sa, ca) = (curvature * sigma).sin_cos();
        std::array::from_fn(|c| {
            let ez = if c == 2 { 1.0 } else { 0.0 };
            ez + sa * k_ez[c] + (1.0 - ca) * k_k_ez[c]
        })
    };
    simpson(tangent, s * length, steps)
}

/// `∫₀ᵘ f(σ) dσ` of a vector function by composite Simpson over `steps` (made even, at least
/// 2) intervals, with compensated (Kahan) sums so that rounding stays near one ulp over the
/// many terms.
pub fn simpson(f: impl Fn(f64) -> Vec3<f64>, upper: f64, steps: usize) -> Vec3<f64> {
    let steps = steps.max(2).next_multiple_of(2);
    let h = upper / steps as f64;
    let (mut sum, mut carry) = ([0.0; 3], [0.0; 3]);
    for n in 0..=steps {
        let weight = if n == 0 || n == steps {
            1.0
        } else if n % 2 == 1 {
            4.0
        } else {
            2.0
        };
        let t = f(n as f64 * h);
        for c in 0..3 {
            let y = weight * t[c] - carry[c];
            let next = sum[c] + y;
            carry[c] = (next - sum[c]) - y;
            sum[c] = next;
        }
    }
    sum.map(|x| x * h / 3.0)
}

/// `R x + t`.
fn transform<T>(rotation: &Mat3<T>, translation: &Vec3<T>, x: &Vec3<T>) -> Vec3<T>
where
    T: Copy + Add<Output = T> + Mul<Output = T>,
{
    std::array::from_fn(|r| {
        rotation[r][0] * x[0] + rotation[r][1] * x[1] + rotation[r][2] * x[2] + translation[r]
    })
}

/// A watched point of an obstacle as the robot gives it, in the frame it is fixed in: a
/// plate point's coordinates in its plate's tip frame, or an arc fraction.
enum Local {
    Plate(Vec3<f64>),
    Arc(f64),
}

fn local_point(module: &Module, point: &WatchedPoint) -> Local {
    match *point {
        WatchedPoint::Corner(j) => {
            let (s, c) = module.corner_angles[j].sin_cos();
            Local::Plate([module.corner_radius * c, module.corner_radius * s, 0.0])
        }
        WatchedPoint::Centre => Local::Plate([0.0; 3]),
        WatchedPoint::Listed(p) => Local::Plate(p),
        WatchedPoint::Arc(s) => Local::Arc(s),
    }
}

/// Every barrier of `robot` as jets (docs/model.md §3), in this order: the plate corners
/// (module by module, corner by corner), each module's limits (elongation min and max,
/// bend: every module has them), each obstacle's watched points in the robot's order. Limits:
/// `b = δL − (δL_min + ε)`, `b = (δL_max − ε) − δL`, `b = (θ_b² − θ²)/(2 θ_b)` with
/// `θ_b = θ_max − ε`; obstacles: `b = n·x − o − ε` and `b = |x − c| − ρ − ε` with `x` the
/// watched point in the world.
pub fn all_barriers<const N: usize>(robot: &Robot, q: &[f64; N], qd: &[f64; N]) -> Vec<Jet<N>> {
    let mut out = barriers(robot, q, qd);
    let x = Jet::seed(q, qd);
    for (i, (module, limits)) in robot.modules.iter().zip(&robot.limits).enumerate() {
        let dl = x[3 * i + 2];
        let [min, max] = limits.elongation;
        out.push(dl + (-(min + limits.elongation_margin)));
        out.push((max - limits.elongation_margin) - dl);
        let bound = limits.max_bend - limits.bend_margin;
        let inv_d = 1.0 / module.tendon_radius;
        let (a, b) = (x[3 * i] * inv_d, x[3 * i + 1] * inv_d);
        out.push((bound * bound - (a * a + b * b)) * (0.5 / bound));
    }
    let kinematics = chain(robot, q, qd);
    for obstacle in &robot.obstacles {
        for watched in &obstacle.watch {
            let i = watched.module;
            let module = &robot.modules[i];
            let point = match local_point(module, &watched.point) {
                Local::Plate(p) => transform(
                    &kinematics.world_rotation[i],
                    &kinematics.world_position[i],
                    &p.map(Jet::constant),
                ),
                Local::Arc(s) => {
                    let local = arc_point(module, s, x[3 * i], x[3 * i + 1], x[3 * i + 2]);
                    match i.checked_sub(1) {
                        None => local,
                        Some(below) => transform(
                            &kinematics.world_rotation[below],
                            &kinematics.world_position[below],
                            &local,
                        ),
                    }
                }
            };
            out.push(obstacle_barrier(&obstacle.shape, obstacle.margin, point));
        }
    }
    out
}

/// An obstacle's barrier at world point `x` (jets or plain numbers).
fn obstacle_barrier<const N: usize>(shape: &Shape, margin: f64, x: Vec3<Jet<N>>) -> Jet<N> {
    match *shape {
        Shape::HalfSpace { normal, offset } => {
            x[0] * normal[0] + x[1] * normal[1] + x[2] * normal[2] + (-(offset + margin))
        }
        Shape::Sphere { center, radius } => {
            let d: Vec3<Jet<N>> = std::array::from_fn(|c| x[c] + (-center[c]));
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() + (-(radius + margin))
        }
    }
}

/// The world pose `(R, t)` of every plate as products of the closed-form segment
/// transforms ([`segment_closed_form`]).
pub fn plate_poses_closed_form(robot: &Robot, q: &[f64]) -> Vec<(Mat3<f64>, Vec3<f64>)> {
    let mut poses: Vec<(Mat3<f64>, Vec3<f64>)> = Vec::with_capacity(robot.modules.len());
    for (i, module) in robot.modules.iter().enumerate() {
        let (r, t) = segment_closed_form(module, [q[3 * i], q[3 * i + 1], q[3 * i + 2]]);
        poses.push(match poses.last() {
            None => (r, t),
            Some((parent_r, parent_t)) => {
                (mat_mul(parent_r, &r), transform(parent_r, parent_t, &t))
            }
        });
    }
    poses
}

/// The world position of watched point `point` of module `module` from the closed forms:
/// a plate point through its plate's pose, an arc point through the pose of the plate below
/// (the world frame for the first module).
pub fn watched_point_closed_form(
    robot: &Robot,
    q: &[f64],
    module: usize,
    point: &WatchedPoint,
) -> Vec3<f64> {
    let poses = plate_poses_closed_form(robot, q);
    let m = &robot.modules[module];
    match local_point(m, point) {
        Local::Plate(p) => transform(&poses[module].0, &poses[module].1, &p),
        Local::Arc(s) => {
            let local =
                arc_point_closed_form(m, [q[3 * module], q[3 * module + 1], q[3 * module + 2]], s);
            match module.checked_sub(1) {
                None => local,
                Some(below) => transform(&poses[below].0, &poses[below].1, &local),
            }
        }
    }
}

/// Every barrier's value in plain f64 from the closed forms in `θ`, `φ` (no `f_s`, `f_c`):
/// corner heights as the third coordinate of `t + R p_ij` in the segment's base frame,
/// `θ = |(Δx, Δy)| / d` for the bend limit, watched points through
/// [`watched_point_closed_form`]. Same order as [`all_barriers`].
pub fn all_barrier_values_closed_form(robot: &Robot, q: &[f64]) -> Vec<f64> {
    let mut out = Vec::new();
    for (i, module) in robot.modules.iter().enumerate() {
        let (r, t) = segment_closed_form(module, [q[3 * i], q[3 * i + 1], q[3 * i + 2]]);
        for (j, margin) in module.margins.iter().enumerate() {
            let corner = match local_point(module, &WatchedPoint::Corner(j)) {
                Local::Plate(p) => p,
                Local::Arc(_) => unreachable!("a corner is a plate point"),
            };
            out.push(transform(&r, &t, &corner)[2] - margin);
        }
    }
    for (i, (module, limits)) in robot.modules.iter().zip(&robot.limits).enumerate() {
        let dl = q[3 * i + 2];
        let [min, max] = limits.elongation;
        out.push(dl - (min + limits.elongation_margin));
        out.push((max - limits.elongation_margin) - dl);
        let bound = limits.max_bend - limits.bend_margin;
        let (theta, _) = bend_angle_direction(module, [q[3 * i], q[3 * i + 1], q[3 * i + 2]]);
        out.push((bound * bound - theta * theta) / (2.0 * bound));
    }
    for obstacle in &robot.obstacles {
        for watched in &obstacle.watch {
            let x = watched_point_closed_form(robot, q, watched.module, &watched.point);
            let value =
                obstacle_barrier::<0>(&obstacle.shape, obstacle.margin, x.map(Jet::constant));
            out.push(value.v);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::highprec::fs_fc_reference;

    /// The reference's `f_s`, `f_c` and two u-derivatives against double-double, on both
    /// sides of its own series switch and across `[0, 50]`.
    #[test]
    fn fs_fc_matches_double_double() {
        let mut points = vec![0.0, 1e-300, 1e-12, 1e-3, 0.5, 0.999_999, 1.0, 1.000_001];
        points.extend((1..=50).map(|k| k as f64 - 0.3));
        for u in points {
            let mut x = Jet::<1>::constant(u);
            x.g[0] = 1.0;
            x.d = 1.0;
            let (fs, fc) = fs_fc(x);
            let (rs, rc) = fs_fc_reference(u, 2);
            for (jet, exact) in [(fs, &rs), (fc, &rc)] {
                for (got, k) in [(jet.v, 0), (jet.g[0], 1), (jet.dd, 2)] {
                    let want = exact[k].to_f64();
                    let scale = exact[0].to_f64().abs().max(want.abs()).max(1e-3);
                    assert!(
                        (got - want).abs() <= 1e-14 * scale,
                        "u = {u}: order {k}: {got:e} vs {want:e}"
                    );
                }
            }
        }
    }

    /// Jet arithmetic against a function with known derivatives: f = x² y / (1 + x).
    #[test]
    fn jet_rules() {
        let [x, y] = Jet::<2>::seed(&[0.7, -1.3], &[0.4, 2.0]);
        let f = x * x * y / (x + 1.0);
        let (xv, yv) = (0.7, -1.3);
        let fx = |x: f64, y: f64| (x * x + 2.0 * x) * y / ((1.0 + x) * (1.0 + x));
        let fy = |x: f64, _y: f64| x * x / (1.0 + x);
        let h = 1e-6;
        let along = |t: f64| {
            let (a, b) = (xv + 0.4 * t, yv + 2.0 * t);
            a * a * b / (1.0 + a)
        };
        assert!((f.g[0] - fx(xv, yv)).abs() < 1e-14);
        assert!((f.g[1] - fy(xv, yv)).abs() < 1e-14);
        assert!((f.d - (0.4 * fx(xv, yv) + 2.0 * fy(xv, yv))).abs() < 1e-14);
        let second = (along(1e-4) - 2.0 * along(0.0) + along(-1e-4)) / 1e-8;
        assert!((f.dd - second).abs() < 1e-6, "{} vs {second}", f.dd);
        let gd0 = (fx(xv + 0.4 * h, yv + 2.0 * h) - fx(xv - 0.4 * h, yv - 2.0 * h)) / (2.0 * h);
        assert!((f.gd[0] - gd0).abs() < 1e-8);
    }

    /// The closed forms in `θ`, `φ` against the jets' `f_s`, `f_c` form at random states,
    /// including `θ = 0` and subnormal bends: rotation, translation and the arc at `s = 1`.
    #[test]
    fn closed_form_segment_matches_jets() {
        let module = paper_module(0.0);
        let mut rng = crate::rng(0x5eed_0c10);
        for _ in 0..2000 {
            let theta = sample_theta(&mut rng, &[SERIES_BELOW]);
            let q = sample_module(&mut rng, &module, theta);
            let (r, t) = segment_value(&module, q);
            let (rc, tc) = segment_closed_form(&module, q);
            for (x, y) in r.iter().flatten().zip(rc.iter().flatten()) {
                assert!((x - y).abs() <= 1e-15, "q = {q:?}: R {x:e} vs {y:e}");
            }
            for (x, y) in t.iter().zip(&tc) {
                assert!((x - y).abs() <= 1e-16, "q = {q:?}: t {x:e} vs {y:e}");
            }
            assert_eq!(arc_point_closed_form(&module, q, 1.0), tc);
        }
    }
}
