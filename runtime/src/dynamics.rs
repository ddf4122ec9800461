//! Rigid-plate dynamics `M q̈ + C q̇ + G + K q + D q̇ = τ` (MODEL.md §4) by recursive
//! algorithms over the generated joint terms: CRBA for `M`, RNEA for `C q̇` and `G`.
//!
//! Why recursive rather than fully symbolic: each segment's transform, motion subspace `S_i`
//! and `c_J,i = Ṡ_i q̇_i` are generated symbolically (their cost is linear in the number of
//! modules and they hold all the small-θ care); composing bodies numerically keeps `M`
//! O(N²) and `h`, `G` O(N), whereas closed forms of `M` over the products `T_1⋯T_i` grow
//! with every module the chain gets. Bodies are composed with compact transforms and
//! inertias ([`crate::spatial`]).

use crate::linalg::{cholesky_in_place, cholesky_solve};
use crate::model::Model;
use crate::spatial::{Inertia, Mat3, Transform, Vec6, cross_force, cross_motion};

/// Why forward dynamics gave no acceleration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DynamicsError {
    /// An input (state or torque) was NaN or infinite.
    #[error("non-finite input to the dynamics")]
    NonFinite,
    /// The mass matrix was not positive definite.
    #[error("mass matrix not positive definite")]
    NotPositiveDefinite,
}

/// Preallocated storage for every dynamics quantity of one model.
#[derive(Clone, Debug)]
pub struct DynamicsWorkspace {
    n: usize,
    /// `R_i` of each segment.
    pub rotation: Vec<Mat3>,
    /// `t_i` of each segment.
    pub translation: Vec<[f64; 3]>,
    /// `S_i` (6×3) of each segment.
    pub motion_subspace: Vec<[[f64; 3]; 6]>,
    /// `c_J,i = Ṡ_i q̇_i`.
    pub bias_acceleration: Vec<Vec6>,
    /// Transform parent → body `i`.
    pub transforms: Vec<Transform>,
    /// Body twists `v_i` (body coordinates) of the last velocity pass.
    pub velocities: Vec<Vec6>,
    forces: Vec<Vec6>,
    composite: Vec<Inertia>,
    /// `M(q)`, row-major `nq × nq`.
    pub mass_matrix: Vec<f64>,
    /// `h = C(q, q̇) q̇` (from [`bias_and_gravity`]).
    pub bias: Vec<f64>,
    /// `G(q)` (from [`bias_and_gravity`]).
    pub gravity: Vec<f64>,
    /// `h + G` (from [`bias_and_gravity`] or [`nonlinear_effects`]).
    pub nonlinear: Vec<f64>,
    /// Cholesky factor of `M` (lower, row-major).
    pub cholesky: Vec<f64>,
}

impl DynamicsWorkspace {
    /// Storage sized for `model`.
    pub fn new(model: &Model) -> DynamicsWorkspace {
        let n = model.n_modules();
        let nq = model.nq();
        DynamicsWorkspace {
            n,
            rotation: vec![[[0.0; 3]; 3]; n],
            translation: vec![[0.0; 3]; n],
            motion_subspace: vec![[[0.0; 3]; 6]; n],
            bias_acceleration: vec![[0.0; 6]; n],
            transforms: vec![Transform::default(); n],
            velocities: vec![[0.0; 6]; n],
            forces: vec![[0.0; 6]; n],
            composite: vec![Inertia::default(); n],
            mass_matrix: vec![0.0; nq * nq],
            bias: vec![0.0; nq],
            gravity: vec![0.0; nq],
            nonlinear: vec![0.0; nq],
            cholesky: vec![0.0; nq * nq],
        }
    }
}

/// Evaluates the generated joint terms at `(q, q̇)`, the parent→child transforms and the
/// composite inertias. Must precede [`mass_matrix`], [`bias_and_gravity`], [`nonlinear_effects`] and
/// [`gravity_energy`].
pub fn update_joints(model: &Model, ws: &mut DynamicsWorkspace, q: &[f64], qd: &[f64]) {
    model.generated.joint_terms(
        &model.params,
        q,
        qd,
        &mut ws.rotation,
        &mut ws.translation,
        &mut ws.motion_subspace,
        &mut ws.bias_acceleration,
    );
    for ((x, rotation), translation) in ws
        .transforms
        .iter_mut()
        .zip(&ws.rotation)
        .zip(&ws.translation)
    {
        *x = Transform {
            rotation: *rotation,
            translation: *translation,
        };
    }
    // Composite inertias, tip to base: body i and everything it carries, in frame i.
    let n = ws.n;
    for i in (0..n).rev() {
        let mut composite = model.inertias[i];
        if i + 1 < n {
            composite.add(&ws.composite[i + 1].to_parent(&ws.transforms[i + 1]));
        }
        ws.composite[i] = composite;
    }
}

#[inline]
fn subspace_times(s: &[[f64; 3]; 6], x: &[f64]) -> Vec6 {
    let (a, b, c) = (x[0], x[1], x[2]);
    s.map(|row| row[0] * a + row[1] * b + row[2] * c)
}

#[inline]
fn subspace_transpose_times(s: &[[f64; 3]; 6], f: &Vec6) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (row, fr) in s.iter().zip(f) {
        out[0] += row[0] * fr;
        out[1] += row[1] * fr;
        out[2] += row[2] * fr;
    }
    out
}

/// `M(q)` by the composite-rigid-body algorithm into `ws.mass_matrix`.
pub fn mass_matrix(_model: &Model, ws: &mut DynamicsWorkspace) {
    let n = ws.n;
    let nq = 3 * n;
    let m = &mut ws.mass_matrix[..nq * nq];
    for i in 0..n {
        // F = I^c_i S_i, one column per coordinate of module i, carried to the base.
        let s = &ws.motion_subspace[i];
        let mut f: [Vec6; 3] = std::array::from_fn(|k| ws.composite[i].apply(&s.map(|row| row[k])));
        let mut j = i;
        loop {
            let s_j = &ws.motion_subspace[j];
            for (k, column) in f.iter().enumerate() {
                let block = subspace_transpose_times(s_j, column);
                // Rows 3j..3j+3 of column 3i+k, and the symmetric entries.
                for (l, &value) in block.iter().enumerate() {
                    m[(3 * j + l) * nq + 3 * i + k] = value;
                    m[(3 * i + k) * nq + 3 * j + l] = value;
                }
            }
            if j == 0 {
                break;
            }
            let x = &ws.transforms[j];
            f = f.map(|column| x.force_to_parent(&column));
            j -= 1;
        }
    }
}

/// `G(q)` into `ws.gravity` from the composite inertias of [`update_joints`]: with
/// `q̇ = q̈ = 0` every body only accelerates with the base's fictitious `−g`, so the force
/// carried by joint `i` is `I^c_i a_g,i` (`a_g,i` that acceleration in frame `i`).
fn gravity_from_composites(model: &Model, ws: &mut DynamicsWorkspace) {
    let mut acceleration = base_acceleration(model);
    for i in 0..ws.n {
        acceleration = ws.transforms[i].motion_to_child(&acceleration);
        let force = ws.composite[i].apply(&acceleration);
        let tau = subspace_transpose_times(&ws.motion_subspace[i], &force);
        ws.gravity[3 * i..3 * i + 3].copy_from_slice(&tau);
    }
}

/// One recursive Newton–Euler pass with `q̈ = 0` and the base accelerating at
/// `base_acceleration`: the generalized forces of the velocity terms and of the resulting
/// body accelerations. Writes them into `out` and the body twists into `ws.velocities`.
fn newton_euler(
    model: &Model,
    ws: &mut DynamicsWorkspace,
    qd: &[f64],
    base_acceleration: Vec6,
    out: Output,
) {
    let n = ws.n;
    let mut parent_velocity = [0.0; 6];
    let mut parent_acceleration = base_acceleration;
    for i in 0..n {
        let x = &ws.transforms[i];
        let joint_velocity = subspace_times(&ws.motion_subspace[i], &qd[3 * i..3 * i + 3]);
        let mut v = x.motion_to_child(&parent_velocity);
        for (vi, vj) in v.iter_mut().zip(&joint_velocity) {
            *vi += vj;
        }
        let mut a = x.motion_to_child(&parent_acceleration);
        let coriolis = cross_motion(&v, &joint_velocity);
        for ((ar, br), cr) in a.iter_mut().zip(&ws.bias_acceleration[i]).zip(&coriolis) {
            *ar += br + cr;
        }
        let inertia = &model.inertias[i];
        let mut f = inertia.apply(&a);
        let gyroscopic = cross_force(&v, &inertia.apply(&v));
        for (fr, gr) in f.iter_mut().zip(&gyroscopic) {
            *fr += gr;
        }
        ws.velocities[i] = v;
        ws.forces[i] = f;
        parent_velocity = v;
        parent_acceleration = a;
    }
    let target = match out {
        Output::Bias => &mut ws.bias,
        Output::Nonlinear => &mut ws.nonlinear,
    };
    for i in (0..n).rev() {
        let tau = subspace_transpose_times(&ws.motion_subspace[i], &ws.forces[i]);
        target[3 * i..3 * i + 3].copy_from_slice(&tau);
        if i > 0 {
            let to_parent = ws.transforms[i].force_to_parent(&ws.forces[i]);
            for (parent, child) in ws.forces[i - 1].iter_mut().zip(&to_parent) {
                *parent += child;
            }
        }
    }
}

#[derive(Clone, Copy)]
enum Output {
    Bias,
    Nonlinear,
}

/// Gravity as a fictitious upward acceleration of the base (Featherstone's trick).
fn base_acceleration(model: &Model) -> Vec6 {
    let g = model.robot.gravity;
    [0.0, 0.0, 0.0, -g[0], -g[1], -g[2]]
}

/// `h = C(q, q̇) q̇` into `ws.bias` (one RNEA pass), `G(q)` into `ws.gravity` (from the
/// composite inertias) and their sum into `ws.nonlinear`.
pub fn bias_and_gravity(model: &Model, ws: &mut DynamicsWorkspace, qd: &[f64]) {
    newton_euler(model, ws, qd, [0.0; 6], Output::Bias);
    gravity_from_composites(model, ws);
    for ((sum, h), g) in ws.nonlinear.iter_mut().zip(&ws.bias).zip(&ws.gravity) {
        *sum = h + g;
    }
}

/// `h + G` into `ws.nonlinear` in one RNEA pass (what forward dynamics and the controller
/// need; `ws.bias` and `ws.gravity` are left as they were).
pub fn nonlinear_effects(model: &Model, ws: &mut DynamicsWorkspace, qd: &[f64]) {
    newton_euler(model, ws, qd, base_acceleration(model), Output::Nonlinear);
}

/// `½ q̇ᵀ M q̇`, from the body twists of the last velocity pass ([`bias_and_gravity`] or
/// [`nonlinear_effects`]).
pub fn kinetic_energy(model: &Model, ws: &DynamicsWorkspace) -> f64 {
    ws.velocities
        .iter()
        .zip(&model.inertias)
        .map(|(v, inertia)| {
            let momentum = inertia.apply(v);
            0.5 * v.iter().zip(&momentum).map(|(a, b)| a * b).sum::<f64>()
        })
        .sum()
}

/// `U_g = −Σ m_i gᵀ p_i` with `p_i` the world position of module `i`'s centre of mass.
pub fn gravity_energy(model: &Model, ws: &DynamicsWorkspace) -> f64 {
    let g = model.robot.gravity;
    let mut rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut position = [0.0; 3];
    let mut energy = 0.0;
    for (i, module) in model.robot.modules.iter().enumerate() {
        let (r, t) = (&ws.rotation[i], &ws.translation[i]);
        for k in 0..3 {
            position[k] += (0..3).map(|c| rotation[k][c] * t[c]).sum::<f64>();
        }
        let mut next = [[0.0; 3]; 3];
        for a in 0..3 {
            for b in 0..3 {
                next[a][b] = (0..3).map(|c| rotation[a][c] * r[c][b]).sum();
            }
        }
        rotation = next;
        let com: [f64; 3] =
            std::array::from_fn(|k| position[k] + rotation[k][2] * module.com_offset);
        energy -= module.mass * (g[0] * com[0] + g[1] * com[1] + g[2] * com[2]);
    }
    energy
}

/// `U_e = ½ qᵀ K q`.
pub fn elastic_energy(model: &Model, q: &[f64]) -> f64 {
    0.5 * q
        .iter()
        .zip(&model.stiffness)
        .map(|(x, k)| k * x * x)
        .sum::<f64>()
}

/// Cholesky factorization of `ws.mass_matrix` into `ws.cholesky`.
pub fn factor_mass_matrix(ws: &mut DynamicsWorkspace) -> Result<(), DynamicsError> {
    let nq = 3 * ws.n;
    ws.cholesky.copy_from_slice(&ws.mass_matrix);
    if cholesky_in_place(&mut ws.cholesky, nq) {
        Ok(())
    } else {
        Err(DynamicsError::NotPositiveDefinite)
    }
}

/// Solves `M x = b` in place with the factor from [`factor_mass_matrix`].
pub fn solve_mass_matrix(ws: &DynamicsWorkspace, b: &mut [f64]) {
    cholesky_solve(&ws.cholesky, 3 * ws.n, b);
}

/// Forward dynamics: `q̈ = M⁻¹ (τ − h − G − K q − D q̇)`, allocation-free. On error `qdd`
/// is filled with NaN so it cannot be used by mistake. Leaves `M`, its factor and
/// `h + G` (in `ws.nonlinear`) at `(q, q̇)` in the workspace.
pub fn forward_dynamics(
    model: &Model,
    ws: &mut DynamicsWorkspace,
    q: &[f64],
    qd: &[f64],
    tau: &[f64],
    qdd: &mut [f64],
) -> Result<(), DynamicsError> {
    let finite = |x: &[f64]| x.iter().all(|v| v.is_finite());
    if !(finite(q) && finite(qd) && finite(tau)) {
        qdd.fill(f64::NAN);
        return Err(DynamicsError::NonFinite);
    }
    update_joints(model, ws, q, qd);
    mass_matrix(model, ws);
    nonlinear_effects(model, ws, qd);
    if let Err(error) = factor_mass_matrix(ws) {
        qdd.fill(f64::NAN);
        return Err(error);
    }
    for k in 0..q.len() {
        qdd[k] = tau[k] - ws.nonlinear[k] - model.stiffness[k] * q[k] - model.damping[k] * qd[k];
    }
    solve_mass_matrix(ws, qdd);
    if finite(qdd) {
        Ok(())
    } else {
        qdd.fill(f64::NAN);
        Err(DynamicsError::NonFinite)
    }
}
