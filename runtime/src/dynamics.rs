//! Rigid-plate dynamics `M q̈ + C q̇ + G + K q + D q̇ = τ` (MODEL.md §4) by recursive
//! algorithms over the generated joint terms: CRBA for `M`, RNEA for `C q̇` and `G`.
//!
//! Why recursive rather than fully symbolic: each segment's transform, motion subspace `S_i`
//! and `c_J,i = Ṡ_i q̇_i` are generated symbolically (their cost is linear in the number of
//! modules and they hold all the small-θ care); composing bodies numerically keeps `M`
//! O(N²) and `h`, `G` O(N), whereas closed forms of `M` over `T_1⋯T_i` grow much faster
//! with the chain's length (see the issue note for the measured table).

use crate::model::Model;
use crate::spatial::{
    Mat3, Mat6, Vec6, apply, apply_transpose, congruence, cross_force, cross_motion, mat_vec,
    motion_transform,
};

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
    /// Motion transform parent → body `i`.
    pub transforms: Vec<Mat6>,
    /// Body twists `v_i` (body coordinates).
    pub velocities: Vec<Vec6>,
    accelerations: Vec<Vec6>,
    forces: Vec<Vec6>,
    composite: Vec<Mat6>,
    /// `M(q)`, row-major `nq × nq`.
    pub mass_matrix: Vec<f64>,
    /// `h = C(q, q̇) q̇`.
    pub bias: Vec<f64>,
    /// `G(q)`.
    pub gravity: Vec<f64>,
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
            transforms: vec![[[0.0; 6]; 6]; n],
            velocities: vec![[0.0; 6]; n],
            accelerations: vec![[0.0; 6]; n],
            forces: vec![[0.0; 6]; n],
            composite: vec![[[0.0; 6]; 6]; n],
            mass_matrix: vec![0.0; nq * nq],
            bias: vec![0.0; nq],
            gravity: vec![0.0; nq],
            cholesky: vec![0.0; nq * nq],
        }
    }
}

/// Evaluates the generated joint terms at `(q, q̇)` and the parent→child transforms.
/// Must precede [`mass_matrix`], [`bias_and_gravity`] and [`kinetic_energy`].
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
    for i in 0..ws.n {
        ws.transforms[i] = motion_transform(&ws.rotation[i], &ws.translation[i]);
    }
}

fn subspace_times(s: &[[f64; 3]; 6], x: &[f64]) -> Vec6 {
    let mut out = [0.0; 6];
    for (o, row) in out.iter_mut().zip(s) {
        *o = row[0] * x[0] + row[1] * x[1] + row[2] * x[2];
    }
    out
}

fn subspace_transpose_times(s: &[[f64; 3]; 6], f: &Vec6) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (row, fr) in s.iter().zip(f) {
        for (o, sv) in out.iter_mut().zip(row) {
            *o += sv * fr;
        }
    }
    out
}

/// `M(q)` by the composite-rigid-body algorithm into `ws.mass_matrix`.
pub fn mass_matrix(model: &Model, ws: &mut DynamicsWorkspace) {
    let n = ws.n;
    let nq = 3 * n;
    for i in (0..n).rev() {
        ws.composite[i] = model.inertias[i];
        if i + 1 < n {
            let child = congruence(&ws.transforms[i + 1], &ws.composite[i + 1]);
            for (row, child_row) in ws.composite[i].iter_mut().zip(&child) {
                for (a, b) in row.iter_mut().zip(child_row) {
                    *a += b;
                }
            }
        }
    }
    for i in 0..n {
        // F = I^c_i S_i, one column per coordinate of module i.
        let mut f = [[0.0; 6]; 3];
        for (k, column) in f.iter_mut().enumerate() {
            let s_k: Vec6 = std::array::from_fn(|r| ws.motion_subspace[i][r][k]);
            *column = mat_vec(&ws.composite[i], &s_k);
        }
        let mut j = i;
        loop {
            for (k, column) in f.iter().enumerate() {
                let block = subspace_transpose_times(&ws.motion_subspace[j], column);
                for (l, value) in block.iter().enumerate() {
                    ws.mass_matrix[(3 * j + l) * nq + 3 * i + k] = *value;
                    ws.mass_matrix[(3 * i + k) * nq + 3 * j + l] = *value;
                }
            }
            if j == 0 {
                break;
            }
            for column in f.iter_mut() {
                *column = apply_transpose(&ws.transforms[j], column);
            }
            j -= 1;
        }
    }
}

/// One recursive Newton–Euler pass with `q̈ = 0`: generalized forces of the body
/// accelerations caused by `base_acceleration` and, if `with_velocity`, by `q̇`.
fn newton_euler(
    model: &Model,
    ws: &mut DynamicsWorkspace,
    qd: &[f64],
    base_acceleration: Vec6,
    with_velocity: bool,
    out: Selector,
) {
    let n = ws.n;
    let mut parent_velocity = [0.0; 6];
    let mut parent_acceleration = base_acceleration;
    for i in 0..n {
        let x = &ws.transforms[i];
        let mut a = apply(x, &parent_acceleration);
        let mut v = [0.0; 6];
        if with_velocity {
            let joint_velocity = subspace_times(&ws.motion_subspace[i], &qd[3 * i..3 * i + 3]);
            v = apply(x, &parent_velocity);
            for (vi, vj) in v.iter_mut().zip(&joint_velocity) {
                *vi += vj;
            }
            let coriolis = cross_motion(&v, &joint_velocity);
            for r in 0..6 {
                a[r] += ws.bias_acceleration[i][r] + coriolis[r];
            }
        }
        let inertia = &model.inertias[i];
        let mut f = mat_vec(inertia, &a);
        if with_velocity {
            let momentum = mat_vec(inertia, &v);
            let gyroscopic = cross_force(&v, &momentum);
            for r in 0..6 {
                f[r] += gyroscopic[r];
            }
            ws.velocities[i] = v;
        }
        ws.accelerations[i] = a;
        ws.forces[i] = f;
        parent_velocity = v;
        parent_acceleration = a;
    }
    for i in (0..n).rev() {
        let tau = subspace_transpose_times(&ws.motion_subspace[i], &ws.forces[i]);
        let target = match out {
            Selector::Bias => &mut ws.bias,
            Selector::Gravity => &mut ws.gravity,
        };
        target[3 * i..3 * i + 3].copy_from_slice(&tau);
        if i > 0 {
            let to_parent = apply_transpose(&ws.transforms[i], &ws.forces[i]);
            for (parent, child) in ws.forces[i - 1].iter_mut().zip(&to_parent) {
                *parent += child;
            }
        }
    }
}

#[derive(Clone, Copy)]
enum Selector {
    Bias,
    Gravity,
}

/// `h = C(q, q̇) q̇` into `ws.bias` and `G(q)` into `ws.gravity` (two RNEA passes).
pub fn bias_and_gravity(model: &Model, ws: &mut DynamicsWorkspace, qd: &[f64]) {
    newton_euler(model, ws, qd, [0.0; 6], true, Selector::Bias);
    let g = model.robot.gravity;
    // Gravity as a fictitious upward acceleration of the base (Featherstone's trick).
    let base = [0.0, 0.0, 0.0, -g[0], -g[1], -g[2]];
    newton_euler(model, ws, qd, base, false, Selector::Gravity);
}

/// `½ q̇ᵀ M q̇`, from the body twists of the last [`bias_and_gravity`] call.
pub fn kinetic_energy(model: &Model, ws: &DynamicsWorkspace) -> f64 {
    ws.velocities
        .iter()
        .zip(&model.inertias)
        .map(|(v, inertia)| {
            let momentum = mat_vec(inertia, v);
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
    let (m, l) = (&ws.mass_matrix, &mut ws.cholesky);
    for j in 0..nq {
        let mut diagonal = m[j * nq + j];
        for k in 0..j {
            diagonal -= l[j * nq + k] * l[j * nq + k];
        }
        // NaN is not finite, so it is rejected too.
        if !diagonal.is_finite() || diagonal <= 0.0 {
            return Err(DynamicsError::NotPositiveDefinite);
        }
        let pivot = diagonal.sqrt();
        l[j * nq + j] = pivot;
        for i in (j + 1)..nq {
            let mut sum = m[i * nq + j];
            for k in 0..j {
                sum -= l[i * nq + k] * l[j * nq + k];
            }
            l[i * nq + j] = sum / pivot;
        }
        for i in 0..j {
            l[i * nq + j] = 0.0;
        }
    }
    Ok(())
}

/// Solves `M x = b` in place with the factor from [`factor_mass_matrix`].
pub fn solve_mass_matrix(ws: &DynamicsWorkspace, b: &mut [f64]) {
    let nq = 3 * ws.n;
    let l = &ws.cholesky;
    for i in 0..nq {
        let mut sum = b[i];
        for k in 0..i {
            sum -= l[i * nq + k] * b[k];
        }
        b[i] = sum / l[i * nq + i];
    }
    for i in (0..nq).rev() {
        let mut sum = b[i];
        for k in (i + 1)..nq {
            sum -= l[k * nq + i] * b[k];
        }
        b[i] = sum / l[i * nq + i];
    }
}

/// Forward dynamics: `q̈ = M⁻¹ (τ − h − G − K q − D q̇)`, allocation-free. On error `qdd`
/// is filled with NaN so it cannot be used by mistake.
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
    bias_and_gravity(model, ws, qd);
    if let Err(error) = factor_mass_matrix(ws) {
        qdd.fill(f64::NAN);
        return Err(error);
    }
    for k in 0..q.len() {
        qdd[k] = tau[k]
            - ws.bias[k]
            - ws.gravity[k]
            - model.stiffness[k] * q[k]
            - model.damping[k] * qd[k];
    }
    solve_mass_matrix(ws, qdd);
    if finite(qdd) {
        Ok(())
    } else {
        qdd.fill(f64::NAN);
        Err(DynamicsError::NonFinite)
    }
}
