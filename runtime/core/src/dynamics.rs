//! Rigid-plate dynamics `M q̈ + C q̇ + G + K q + D q̇ = τ` (docs/model.md §4) by recursive
//! algorithms over the generated joint terms: CRBA for `M`, RNEA for `C q̇` and `G`.
//!
//! Why recursive rather than fully symbolic: each segment's transform, motion subspace `S_i`
//! and `c_J,i = Ṡ_i q̇_i` are generated symbolically (their cost is linear in the number of
//! modules and they hold all the small-θ care); composing bodies numerically keeps `M`
//! O(N²) and `h`, `G` O(N), whereas closed forms of `M` over the products `T_1⋯T_i` grow
//! with every module the chain gets. Bodies are composed with compact transforms and
//! inertias ([`crate::spatial`]).
//!
//! [`model_terms`] is what the control tick calls: one generated evaluation gives the joint
//! and barrier terms, then `M`, `h`, `G` follow. [`forward_dynamics`] is the plant's.
//!
//! Units: `q = (Δx, Δy, δL)` per module \[m\], `q̇` \[m/s\], generalized forces \[N\],
//! `M` \[kg\], energies \[J\]. Every function states the lengths it expects (`n` modules,
//! `nq = 3n` coordinates, `nb` barriers of the model); the checked ones return
//! [`DynamicsError::Size`] on a wrong length.

use nalgebra::{Matrix3, Matrix6x3, Vector3, Vector6};

use crate::linalg::{cholesky_in_place, cholesky_solve};
use crate::model::Model;
use crate::spatial::{Inertia, Transform, cross_force, cross_motion, spatial};

/// Why a dynamics computation gave no result.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DynamicsError {
    /// An input (state or torque) was NaN or infinite.
    #[error("non-finite input to the dynamics")]
    NonFinite,
    /// The mass matrix was not positive definite.
    #[error("mass matrix not positive definite")]
    NotPositiveDefinite,
    /// An argument had the wrong length for the model (a setup error of the caller, not a
    /// state of the robot), or the workspace was built for another model.
    #[error("{what} has length {got}, expected {expected}")]
    Size {
        /// The argument.
        what: &'static str,
        /// Its length for this model.
        expected: usize,
        /// Its length as given.
        got: usize,
    },
}

/// `Ok` if `got == expected`, else the size error naming `what`.
#[inline]
fn expect_len(what: &'static str, expected: usize, got: usize) -> Result<(), DynamicsError> {
    if got == expected {
        Ok(())
    } else {
        Err(DynamicsError::Size {
            what,
            expected,
            got,
        })
    }
}

/// Preallocated storage for every dynamics quantity of one model.
#[derive(Clone, Debug)]
pub struct DynamicsWorkspace {
    n: usize,
    /// `R_i` of each segment, rows, as the generated code writes it.
    rotation: Vec<[[f64; 3]; 3]>,
    /// `t_i` of each segment \[m\].
    translation: Vec<[f64; 3]>,
    /// `S_i` (6×3, rows) of each segment.
    motion_subspace: Vec<[[f64; 3]; 6]>,
    /// `c_J,i = Ṡ_i q̇_i`.
    bias_acceleration: Vec<[f64; 6]>,
    /// Transform parent → body `i`.
    transforms: Vec<Transform>,
    /// `S_i` as a matrix.
    subspaces: Vec<Matrix6x3<f64>>,
    /// Body twists `v_i` (body coordinates) of the last velocity pass.
    velocities: Vec<Vector6<f64>>,
    forces: Vec<Vector6<f64>>,
    composite: Vec<Inertia>,
    /// `M(q)`, row-major `nq × nq` \[kg\].
    pub mass_matrix: Vec<f64>,
    /// `h = C(q, q̇) q̇` \[N\] (from [`bias_and_gravity`] or [`model_terms`]).
    pub bias: Vec<f64>,
    /// `G(q)` \[N\] (from [`bias_and_gravity`] or [`model_terms`]).
    pub gravity: Vec<f64>,
    /// `h + G` \[N\] (from [`bias_and_gravity`], [`nonlinear_effects`] or [`model_terms`]).
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
            subspaces: vec![Matrix6x3::zeros(); n],
            velocities: vec![Vector6::zeros(); n],
            forces: vec![Vector6::zeros(); n],
            composite: vec![Inertia::default(); n],
            mass_matrix: vec![0.0; nq * nq],
            bias: vec![0.0; nq],
            gravity: vec![0.0; nq],
            nonlinear: vec![0.0; nq],
            cholesky: vec![0.0; nq * nq],
        }
    }

    /// The parent → body transforms of the last evaluation, one per module.
    pub fn transforms(&self) -> &[Transform] {
        &self.transforms
    }

    /// The body twists `v_i` (body coordinates) of the last velocity pass.
    pub fn velocities(&self) -> &[Vector6<f64>] {
        &self.velocities
    }
}

/// The barrier terms of one state: values `b` \[m\], Jacobian rows `J = ∂b/∂q` (row-major
/// `nb × nq`, dimensionless) and `J̇ q̇` \[m/s²\]. Written by [`model_terms`].
#[derive(Clone, Debug)]
pub struct BarrierTerms {
    nq: usize,
    values: Vec<f64>,
    jacobian: Vec<f64>,
    jdot_qd: Vec<f64>,
}

impl BarrierTerms {
    /// Storage sized for `model`'s barriers.
    pub fn new(model: &Model) -> BarrierTerms {
        let (nb, nq) = (model.nb(), model.nq());
        BarrierTerms {
            nq,
            values: vec![0.0; nb],
            jacobian: vec![0.0; nb * nq],
            jdot_qd: vec![0.0; nb],
        }
    }

    /// `b`, length `nb` \[m\].
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// `J`, row-major `nb × nq`.
    pub fn jacobian(&self) -> &[f64] {
        &self.jacobian
    }

    /// `J̇ q̇`, length `nb` \[m/s²\].
    pub fn jdot_qd(&self) -> &[f64] {
        &self.jdot_qd
    }

    /// Fills the values with NaN, so that stale numbers cannot be used by mistake.
    pub fn invalidate(&mut self) {
        self.values.fill(f64::NAN);
    }
}

/// The workspace (and the model's per-module data) fit the model: a few compares.
#[inline]
fn check_workspace(model: &Model, ws: &DynamicsWorkspace) -> Result<(), DynamicsError> {
    let (n, nq) = (model.n_modules(), model.nq());
    expect_len("workspace modules", n, ws.n)?;
    expect_len("model inertias", n, model.inertias.len())?;
    expect_len("workspace mass matrix", nq * nq, ws.mass_matrix.len())?;
    expect_len("workspace Cholesky factor", nq * nq, ws.cholesky.len())?;
    expect_len("workspace bias", nq, ws.bias.len())?;
    expect_len("workspace gravity", nq, ws.gravity.len())?;
    expect_len("workspace nonlinear", nq, ws.nonlinear.len())
}

/// The state `(q, q̇)` and the workspace fit the model.
#[inline]
fn check_state(
    model: &Model,
    ws: &DynamicsWorkspace,
    q: &[f64],
    qd: &[f64],
) -> Result<(), DynamicsError> {
    check_workspace(model, ws)?;
    expect_len("q", model.nq(), q.len())?;
    expect_len("q̇", model.nq(), qd.len())
}

/// Everything the control tick needs from the model at `(q, q̇)`, from one generated
/// evaluation: `M` into `ws.mass_matrix`, `h = C q̇` into `ws.bias`, `G` into `ws.gravity`,
/// `h + G` into `ws.nonlinear`, and every barrier's `b`, `J`, `J̇ q̇` into `barriers`.
///
/// Lengths: `q` and `q̇` have `nq` entries \[m, m/s\]; `ws` and `barriers` were built for
/// `model`. A wrong length is [`DynamicsError::Size`] and nothing is written. Allocates
/// nothing; the inputs are not checked for finiteness (the caller does, once).
pub fn model_terms(
    model: &Model,
    ws: &mut DynamicsWorkspace,
    barriers: &mut BarrierTerms,
    q: &[f64],
    qd: &[f64],
) -> Result<(), DynamicsError> {
    check_state(model, ws, q, qd)?;
    let nb = model.nb();
    expect_len("barrier values", nb, barriers.values.len())?;
    expect_len("barrier Jacobian", nb * model.nq(), barriers.jacobian.len())?;
    expect_len("barrier J̇q̇", nb, barriers.jdot_qd.len())?;
    expect_len("barrier terms' nq", model.nq(), barriers.nq)?;
    model.generated.model_terms(
        &model.params,
        q,
        qd,
        &mut ws.rotation,
        &mut ws.translation,
        &mut ws.motion_subspace,
        &mut ws.bias_acceleration,
        &mut barriers.values,
        &mut barriers.jacobian,
        &mut barriers.jdot_qd,
    );
    prepare_joints(model, ws);
    crba(ws);
    bias_gravity_sum(model, ws, qd);
    Ok(())
}

/// `h` by one RNEA pass, `G` from the composite inertias, and `h + G`.
#[inline]
fn bias_gravity_sum(model: &Model, ws: &mut DynamicsWorkspace, qd: &[f64]) {
    newton_euler(model, ws, qd, Vector3::zeros(), Output::Bias);
    gravity_from_composites(model, ws);
    for ((sum, h), g) in ws.nonlinear.iter_mut().zip(&ws.bias).zip(&ws.gravity) {
        *sum = h + g;
    }
}

/// Evaluates the generated joint terms at `(q, q̇)` (`nq` entries each, \[m\], \[m/s\]), the
/// parent→child transforms and the composite inertias. Must precede [`mass_matrix`],
/// [`bias_and_gravity`], [`nonlinear_effects`] and [`gravity_energy`] (which use it; prefer
/// [`model_terms`], which does all of it at once). A wrong length or a workspace of another
/// model is [`DynamicsError::Size`] and nothing is written.
pub fn update_joints(
    model: &Model,
    ws: &mut DynamicsWorkspace,
    q: &[f64],
    qd: &[f64],
) -> Result<(), DynamicsError> {
    check_state(model, ws, q, qd)?;
    evaluate_joints(model, ws, q, qd);
    Ok(())
}

/// The generated joint terms at `(q, q̇)` and what [`prepare_joints`] makes of them (sizes
/// already checked).
#[inline]
fn evaluate_joints(model: &Model, ws: &mut DynamicsWorkspace, q: &[f64], qd: &[f64]) {
    model.generated.joint_terms(
        &model.params,
        q,
        qd,
        &mut ws.rotation,
        &mut ws.translation,
        &mut ws.motion_subspace,
        &mut ws.bias_acceleration,
    );
    prepare_joints(model, ws);
}

/// The generated joint terms as nalgebra values, and the composite inertias tip to base:
/// body `i` and everything it carries, in frame `i`.
#[inline]
fn prepare_joints(model: &Model, ws: &mut DynamicsWorkspace) {
    let n = ws.n;
    let raw = ws
        .rotation
        .iter()
        .zip(&ws.translation)
        .zip(&ws.motion_subspace);
    for ((x, s), ((r, t), raw_s)) in ws.transforms.iter_mut().zip(&mut ws.subspaces).zip(raw) {
        *x = Transform {
            rotation: Matrix3::from_fn(|a, b| r[a][b]),
            translation: Vector3::from(*t),
        };
        *s = Matrix6x3::from_fn(|a, b| raw_s[a][b]);
    }
    let Some(mut carried) = model.inertias.get(n.wrapping_sub(1)).copied() else {
        return;
    };
    ws.composite[n - 1] = carried;
    for i in (0..n - 1).rev() {
        let mut composite = model.inertias[i];
        composite.add(&carried.to_parent(&ws.transforms[i + 1]));
        ws.composite[i] = composite;
        carried = composite;
    }
}

/// Writes the 3×3 block at rows `row..row+3`, columns `col..col+3` of a row-major `nq × nq`.
#[inline]
fn write_block(m: &mut [f64], nq: usize, row: usize, col: usize, block: &Matrix3<f64>) {
    for r in 0..3 {
        let start = (row + r) * nq + col;
        m[start..start + 3].copy_from_slice(&[block[(r, 0)], block[(r, 1)], block[(r, 2)]]);
    }
}

/// `Sᵀ F` for `F = I S` with `I` symmetric: the upper triangle, mirrored. As column dot
/// products (with [`transpose_product`]): the paper robot's `M` in 66 ns, against 91 ns
/// with nalgebra's `tr_mul` (minimum over batches of 200 calls).
#[inline]
fn symmetric_product(s: &Matrix6x3<f64>, f: &Matrix6x3<f64>) -> Matrix3<f64> {
    let entry = |a: usize, b: usize| s.column(a).dot(&f.column(b));
    let (d0, d1, d2) = (entry(0, 0), entry(1, 1), entry(2, 2));
    let (e01, e02, e12) = (entry(0, 1), entry(0, 2), entry(1, 2));
    Matrix3::new(d0, e01, e02, e01, d1, e12, e02, e12, d2)
}

/// `Sᵀ F` as nine column dot products (see [`symmetric_product`]).
#[inline]
fn transpose_product(s: &Matrix6x3<f64>, f: &Matrix6x3<f64>) -> Matrix3<f64> {
    Matrix3::from_fn(|a, b| s.column(a).dot(&f.column(b)))
}

/// `M` by the composite-rigid-body algorithm: `F = I^c_i S_i` carried from body `i` to the
/// base gives the blocks `M_ji = S_jᵀ F`, `j ≤ i` (and their transposes).
#[inline]
fn crba(ws: &mut DynamicsWorkspace) {
    let n = ws.n;
    let nq = 3 * n;
    let m = &mut ws.mass_matrix[..nq * nq];
    for i in 0..n {
        let mut f = ws.composite[i].apply_columns(&ws.subspaces[i]);
        write_block(
            m,
            nq,
            3 * i,
            3 * i,
            &symmetric_product(&ws.subspaces[i], &f),
        );
        for j in (0..i).rev() {
            f = ws.transforms[j + 1].forces_to_parent(&f);
            let block = transpose_product(&ws.subspaces[j], &f);
            write_block(m, nq, 3 * j, 3 * i, &block);
            write_block(m, nq, 3 * i, 3 * j, &block.transpose());
        }
    }
}

/// `M(q)` by the composite-rigid-body algorithm into `ws.mass_matrix`, from the joint terms
/// of [`update_joints`]. A workspace of another model is [`DynamicsError::Size`].
pub fn mass_matrix(model: &Model, ws: &mut DynamicsWorkspace) -> Result<(), DynamicsError> {
    check_workspace(model, ws)?;
    crba(ws);
    Ok(())
}

/// `G(q)` into `ws.gravity` from the composite inertias: with `q̇ = q̈ = 0` every body only
/// accelerates with the base's fictitious `−g` (a pure linear acceleration, which stays one
/// in every frame), so the force carried by joint `i` is `I^c_i a_g,i`.
#[inline]
fn gravity_from_composites(model: &Model, ws: &mut DynamicsWorkspace) {
    let mut acceleration = -Vector3::from(model.robot.gravity);
    for i in 0..ws.n {
        acceleration = ws.transforms[i].rotation.tr_mul(&acceleration);
        let force = ws.composite[i].apply_linear(&acceleration);
        let tau = ws.subspaces[i].tr_mul(&force);
        ws.gravity[3 * i..3 * i + 3].copy_from_slice(tau.as_slice());
    }
}

#[derive(Clone, Copy)]
enum Output {
    Bias,
    Nonlinear,
}

/// One recursive Newton–Euler pass with `q̈ = 0` and the base accelerating linearly at
/// `base_acceleration`: the generalized forces of the velocity terms and of the resulting
/// body accelerations. Writes them into `out` and the body twists into `ws.velocities`.
#[inline]
fn newton_euler(
    model: &Model,
    ws: &mut DynamicsWorkspace,
    qd: &[f64],
    base_acceleration: Vector3<f64>,
    out: Output,
) {
    let n = ws.n;
    let mut parent_velocity = Vector6::zeros();
    let mut parent_acceleration = Vector6::zeros();
    for (i, qd_i) in qd.chunks_exact(3).take(n).enumerate() {
        let x = &ws.transforms[i];
        let joint_velocity = ws.subspaces[i] * Vector3::new(qd_i[0], qd_i[1], qd_i[2]);
        let (v, a) = if i == 0 {
            // The base is at rest: v = v_J, and v ×ₘ v_J = 0. Its linear acceleration
            // stays linear in every frame.
            let a = spatial(&Vector3::zeros(), &x.rotation.tr_mul(&base_acceleration));
            (joint_velocity, a + Vector6::from(ws.bias_acceleration[0]))
        } else {
            let v = x.motion_to_child(&parent_velocity) + joint_velocity;
            let a = x.motion_to_child(&parent_acceleration)
                + Vector6::from(ws.bias_acceleration[i])
                + cross_motion(&v, &joint_velocity);
            (v, a)
        };
        let inertia = &model.inertias[i];
        let f = inertia.apply(&a) + cross_force(&v, &inertia.apply(&v));
        ws.velocities[i] = v;
        ws.forces[i] = f;
        parent_velocity = v;
        parent_acceleration = a;
    }
    let target = match out {
        Output::Bias => &mut ws.bias,
        Output::Nonlinear => &mut ws.nonlinear,
    };
    let mut carried = Vector6::zeros();
    for i in (0..n).rev() {
        let f = ws.forces[i] + carried;
        let tau = ws.subspaces[i].tr_mul(&f);
        target[3 * i..3 * i + 3].copy_from_slice(tau.as_slice());
        carried = ws.transforms[i].force_to_parent(&f);
    }
}

/// Gravity as a fictitious upward acceleration of the base (Featherstone's trick).
fn base_acceleration(model: &Model) -> Vector3<f64> {
    -Vector3::from(model.robot.gravity)
}

/// `h = C(q, q̇) q̇` into `ws.bias` (one RNEA pass), `G(q)` into `ws.gravity` (from the
/// composite inertias) and their sum into `ws.nonlinear`, after [`update_joints`]. `q̇` has
/// `nq` entries \[m/s\]; a wrong length or a workspace of another model is
/// [`DynamicsError::Size`] and nothing is written.
pub fn bias_and_gravity(
    model: &Model,
    ws: &mut DynamicsWorkspace,
    qd: &[f64],
) -> Result<(), DynamicsError> {
    check_workspace(model, ws)?;
    expect_len("q̇", model.nq(), qd.len())?;
    bias_gravity_sum(model, ws, qd);
    Ok(())
}

/// `h + G` into `ws.nonlinear` in one RNEA pass, after [`update_joints`] (what forward
/// dynamics needs; `ws.bias` and `ws.gravity` are left as they were). `q̇` has `nq` entries
/// \[m/s\].
pub fn nonlinear_effects(
    model: &Model,
    ws: &mut DynamicsWorkspace,
    qd: &[f64],
) -> Result<(), DynamicsError> {
    check_workspace(model, ws)?;
    expect_len("q̇", model.nq(), qd.len())?;
    newton_euler(model, ws, qd, base_acceleration(model), Output::Nonlinear);
    Ok(())
}

/// `½ q̇ᵀ M q̇` \[J\], from the body twists of the last velocity pass ([`model_terms`],
/// [`bias_and_gravity`] or [`nonlinear_effects`]); [`DynamicsError::Size`] for a workspace
/// of another model.
pub fn kinetic_energy(model: &Model, ws: &DynamicsWorkspace) -> Result<f64, DynamicsError> {
    check_workspace(model, ws)?;
    Ok(ws
        .velocities
        .iter()
        .zip(&model.inertias)
        .map(|(v, inertia)| 0.5 * v.dot(&inertia.apply(v)))
        .sum())
}

/// `U_g = −Σ m_i gᵀ p_i` \[J\] with `p_i` the world position of module `i`'s centre of mass,
/// from the joint terms of the last [`update_joints`] or [`model_terms`];
/// [`DynamicsError::Size`] for a workspace of another model.
pub fn gravity_energy(model: &Model, ws: &DynamicsWorkspace) -> Result<f64, DynamicsError> {
    check_workspace(model, ws)?;
    let g = Vector3::from(model.robot.gravity);
    let mut rotation = Matrix3::identity();
    let mut position = Vector3::zeros();
    let mut energy = 0.0;
    for (x, module) in ws.transforms.iter().zip(&model.robot.modules) {
        position += rotation * x.translation;
        rotation *= x.rotation;
        let com = position + rotation.column(2) * module.com_offset;
        energy -= module.mass * g.dot(&com);
    }
    Ok(energy)
}

/// `U_e = ½ qᵀ K q` \[J\], `q` of `nq` entries \[m\] ([`DynamicsError::Size`] for another
/// length).
pub fn elastic_energy(model: &Model, q: &[f64]) -> Result<f64, DynamicsError> {
    expect_len("q", model.stiffness.len(), q.len())?;
    Ok(0.5
        * q.iter()
            .zip(&model.stiffness)
            .map(|(x, k)| k * x * x)
            .sum::<f64>())
}

/// Cholesky factorization of `ws.mass_matrix` into `ws.cholesky`.
pub fn factor_mass_matrix(ws: &mut DynamicsWorkspace) -> Result<(), DynamicsError> {
    let nq = 3 * ws.n;
    expect_len("workspace mass matrix", nq * nq, ws.mass_matrix.len())?;
    expect_len("workspace Cholesky factor", nq * nq, ws.cholesky.len())?;
    ws.cholesky.copy_from_slice(&ws.mass_matrix);
    if cholesky_in_place(&mut ws.cholesky, nq) {
        Ok(())
    } else {
        Err(DynamicsError::NotPositiveDefinite)
    }
}

/// Solves `M x = b` in place with the factor from [`factor_mass_matrix`]; `b` has `nq`
/// entries \[N\] and becomes `x` \[m/s²\] (another length: [`DynamicsError::Size`], `b`
/// untouched).
pub fn solve_mass_matrix(ws: &DynamicsWorkspace, b: &mut [f64]) -> Result<(), DynamicsError> {
    let nq = 3 * ws.n;
    expect_len("right-hand side", nq, b.len())?;
    expect_len("workspace Cholesky factor", nq * nq, ws.cholesky.len())?;
    cholesky_solve(&ws.cholesky, nq, b);
    Ok(())
}

/// Forward dynamics: `q̈ = M⁻¹ (τ − h − G − K q − D q̇)`, allocation-free. `q` \[m\], `q̇`
/// \[m/s\], `τ` \[N\] and `q̈` \[m/s²\] have `nq` entries each (else [`DynamicsError::Size`],
/// nothing written). On any other error `qdd` is filled with NaN so it cannot be used by
/// mistake. Leaves `M`, its factor and `h + G` (in `ws.nonlinear`) at `(q, q̇)` in the
/// workspace.
pub fn forward_dynamics(
    model: &Model,
    ws: &mut DynamicsWorkspace,
    q: &[f64],
    qd: &[f64],
    tau: &[f64],
    qdd: &mut [f64],
) -> Result<(), DynamicsError> {
    check_state(model, ws, q, qd)?;
    let nq = model.nq();
    expect_len("τ", nq, tau.len())?;
    expect_len("q̈", nq, qdd.len())?;
    expect_len("model stiffness", nq, model.stiffness.len())?;
    expect_len("model damping", nq, model.damping.len())?;
    let finite = |x: &[f64]| x.iter().all(|v| v.is_finite());
    if !(finite(q) && finite(qd) && finite(tau)) {
        qdd.fill(f64::NAN);
        return Err(DynamicsError::NonFinite);
    }
    evaluate_joints(model, ws, q, qd);
    crba(ws);
    newton_euler(model, ws, qd, base_acceleration(model), Output::Nonlinear);
    if let Err(error) = factor_mass_matrix(ws) {
        qdd.fill(f64::NAN);
        return Err(error);
    }
    for k in 0..nq {
        qdd[k] = tau[k] - ws.nonlinear[k] - model.stiffness[k] * q[k] - model.damping[k] * qd[k];
    }
    cholesky_solve(&ws.cholesky, nq, qdd);
    if finite(qdd) {
        Ok(())
    } else {
        qdd.fill(f64::NAN);
        Err(DynamicsError::NonFinite)
    }
}
