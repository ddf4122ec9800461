//! Enclosures of the rigid-plate dynamics over a box of states (docs/model.md §5, the
//! certified filter): each plate's share `M_i(q)` of the mass matrix (and with jets, its
//! rate `Ṁ_i` along a direction of motion), and `h(q, q̇) + G(q)` with each plate's share.
//! Every result is an interval that holds the value at every state in the boxes.
//!
//! The algorithms are those of [`crate::dynamics`] in Featherstone's compact spatial
//! operations ([`crate::spatial`]), run in outward-rounded interval arithmetic
//! ([`Interval`]) or on jets of intervals ([`Dual`]) on the generated enclosures of the joint
//! terms (`joint_terms_interval`, `joint_terms_dual`). The mass matrix comes from the body
//! Jacobians, `M = Σ_i J_iᵀ I_i J_i` (`J_i`: plate `i`'s twist per unit `q̇`, in its own
//! frame), so that each plate's share, which a mass factor scales, is at hand.
//!
//! Units: `q` \[m\], `q̇` \[m/s\] boxes of `nq = 3n` entries; `M` \[kg\] row-major `nq × nq`;
//! forces \[N\].

// The recursions below index the modules' frames, forces and matrices in step with one
// index, as their formulas do.
#![allow(clippy::needless_range_loop)]

use std::ops::{Add, AddAssign, Mul, Neg, Sub};

use softcbf_generated::{Dual, Interval};

use crate::model::Model;
use crate::spatial::Inertia;

/// The number types the enclosures run on.
pub trait Scalar:
    Copy
    + Default
    + From<f64>
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Mul<f64, Output = Self>
    + Neg<Output = Self>
    + AddAssign
{
}

impl Scalar for Interval {}
impl Scalar for Dual {}

type V3<T> = [T; 3];
type M3<T> = [[T; 3]; 3];
/// A spatial vector: angular part, then linear part.
type V6<T> = [T; 6];
/// A motion subspace or Jacobian block: 6 rows, 3 columns.
type S63<T> = [[T; 3]; 6];

#[inline(always)]
fn add3<T: Scalar>(a: &V3<T>, b: &V3<T>) -> V3<T> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline(always)]
fn sub3<T: Scalar>(a: &V3<T>, b: &V3<T>) -> V3<T> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline(always)]
fn cross<T: Scalar>(a: &V3<T>, b: &V3<T>) -> V3<T> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline(always)]
fn dot3<T: Scalar>(a: &V3<T>, b: &V3<T>) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `R a`.
#[inline(always)]
fn mul<T: Scalar>(r: &M3<T>, a: &V3<T>) -> V3<T> {
    [dot3(&r[0], a), dot3(&r[1], a), dot3(&r[2], a)]
}

/// `Rᵀ a`.
#[inline(always)]
fn tr_mul<T: Scalar>(r: &M3<T>, a: &V3<T>) -> V3<T> {
    std::array::from_fn(|i| r[0][i] * a[0] + r[1][i] * a[1] + r[2][i] * a[2])
}

#[inline(always)]
fn angular<T: Scalar>(x: &V6<T>) -> V3<T> {
    [x[0], x[1], x[2]]
}

#[inline(always)]
fn linear<T: Scalar>(x: &V6<T>) -> V3<T> {
    [x[3], x[4], x[5]]
}

#[inline(always)]
fn spatial<T: Scalar>(top: &V3<T>, bottom: &V3<T>) -> V6<T> {
    [top[0], top[1], top[2], bottom[0], bottom[1], bottom[2]]
}

#[inline(always)]
fn add6<T: Scalar>(a: &V6<T>, b: &V6<T>) -> V6<T> {
    std::array::from_fn(|i| a[i] + b[i])
}

/// Parent → child transform: the child's frame has rotation `R` and origin `t` in the
/// parent's (as [`crate::spatial::Transform`]).
#[derive(Clone, Copy, Default)]
struct Transform<T> {
    rotation: M3<T>,
    translation: V3<T>,
}

impl<T: Scalar> Transform<T> {
    #[inline(always)]
    fn motion_to_child(&self, m: &V6<T>) -> V6<T> {
        let (w, v) = (angular(m), linear(m));
        let moved = sub3(&v, &cross(&self.translation, &w));
        spatial(&tr_mul(&self.rotation, &w), &tr_mul(&self.rotation, &moved))
    }

    #[inline(always)]
    fn force_to_parent(&self, f: &V6<T>) -> V6<T> {
        let rf = mul(&self.rotation, &linear(f));
        let rn = mul(&self.rotation, &angular(f));
        spatial(&add3(&rn, &cross(&self.translation, &rf)), &rf)
    }
}

/// `I m` for a plate's (numeric) spatial inertia about its frame's origin.
#[inline(always)]
fn apply_inertia<T: Scalar>(inertia: &Inertia, m: &V6<T>) -> V6<T> {
    let (w, v) = (angular(m), linear(m));
    let h = inertia.first_moment;
    let r = inertia.rotational;
    let rw: V3<T> = std::array::from_fn(|i| w[0] * r[(i, 0)] + w[1] * r[(i, 1)] + w[2] * r[(i, 2)]);
    let h_cross = |x: &V3<T>| -> V3<T> {
        [
            x[2] * h[1] - x[1] * h[2],
            x[0] * h[2] - x[2] * h[0],
            x[1] * h[0] - x[0] * h[1],
        ]
    };
    let hv = h_cross(&v);
    let hw = h_cross(&w);
    spatial(
        &add3(&rw, &hv),
        &std::array::from_fn(|i| v[i] * inertia.mass - hw[i]),
    )
}

#[inline(always)]
fn subspace_times<T: Scalar>(s: &S63<T>, x: &V3<T>) -> V6<T> {
    std::array::from_fn(|r| s[r][0] * x[0] + s[r][1] * x[1] + s[r][2] * x[2])
}

#[inline(always)]
fn subspace_transpose<T: Scalar>(s: &S63<T>, f: &V6<T>) -> V3<T> {
    std::array::from_fn(|c| {
        let mut sum = s[0][c] * f[0];
        for (r, row) in s.iter().enumerate().skip(1) {
            sum += row[c] * f[r];
        }
        sum
    })
}

#[inline(always)]
fn cross_motion<T: Scalar>(a: &V6<T>, b: &V6<T>) -> V6<T> {
    let (w, v) = (angular(a), linear(a));
    let (bw, bv) = (angular(b), linear(b));
    spatial(&cross(&w, &bw), &add3(&cross(&w, &bv), &cross(&v, &bw)))
}

#[inline(always)]
fn cross_force<T: Scalar>(a: &V6<T>, f: &V6<T>) -> V6<T> {
    let (w, v) = (angular(a), linear(a));
    let (n, lin) = (angular(f), linear(f));
    spatial(&add3(&cross(&w, &n), &cross(&v, &lin)), &cross(&w, &lin))
}

/// Storage for one number type's joint terms and results.
struct Joints<T> {
    rotation: Vec<M3<T>>,
    translation: Vec<V3<T>>,
    subspace: Vec<S63<T>>,
    bias_acceleration: Vec<V6<T>>,
    transforms: Vec<Transform<T>>,
    /// Body Jacobian of the plate being formed, column-major by coordinate (`nq` spatial
    /// columns).
    jacobian: Vec<V6<T>>,
    /// `I_i J_i`, the same layout.
    momentum: Vec<V6<T>>,
}

impl<T: Scalar> Joints<T> {
    fn new(n: usize) -> Joints<T> {
        let zero = T::default();
        Joints {
            rotation: vec![[[zero; 3]; 3]; n],
            translation: vec![[zero; 3]; n],
            subspace: vec![[[zero; 3]; 6]; n],
            bias_acceleration: vec![[zero; 6]; n],
            transforms: vec![Transform::default(); n],
            jacobian: vec![[zero; 6]; 3 * n],
            momentum: vec![[zero; 6]; 3 * n],
        }
    }

    fn prepare(&mut self) {
        for (x, (r, t)) in self
            .transforms
            .iter_mut()
            .zip(self.rotation.iter().zip(&self.translation))
        {
            *x = Transform {
                rotation: *r,
                translation: *t,
            };
        }
    }

    /// Each plate's share of the mass matrix, `M_i = J_iᵀ I_i J_i`, into `shares`
    /// (`n` blocks of `nq × nq`, row-major): the body Jacobian grows by one module per plate
    /// (the parent's columns carried into the child's frame, then `S_i`).
    fn mass_shares(&mut self, inertias: &[Inertia], shares: &mut [T]) {
        let n = self.transforms.len();
        let nq = 3 * n;
        let zero = T::default();
        shares.fill(zero);
        for i in 0..n {
            for column in 0..3 * i {
                self.jacobian[column] = self.transforms[i].motion_to_child(&self.jacobian[column]);
            }
            for c in 0..3 {
                self.jacobian[3 * i + c] = std::array::from_fn(|r| self.subspace[i][r][c]);
            }
            let columns = 3 * (i + 1);
            for c in 0..columns {
                self.momentum[c] = apply_inertia(&inertias[i], &self.jacobian[c]);
            }
            let share = &mut shares[i * nq * nq..(i + 1) * nq * nq];
            for a in 0..columns {
                for b in a..columns {
                    let (ja, mb) = (&self.jacobian[a], &self.momentum[b]);
                    let mut value = ja[0] * mb[0];
                    for k in 1..6 {
                        value += ja[k] * mb[k];
                    }
                    share[a * nq + b] = value;
                    share[b * nq + a] = value;
                }
            }
        }
    }
}

/// Preallocated storage for the enclosures of one model's dynamics.
pub struct EnclosureWorkspace {
    n: usize,
    intervals: Joints<Interval>,
    duals: Joints<Dual>,
    forces: Vec<V6<Interval>>,
    dual_shares: Vec<Dual>,
    dual_q: Vec<Dual>,
    dual_qd: Vec<Dual>,
    /// [`enclose_mismatch`]'s plate wrenches (`n`) and `h + G` (`nq`) on jets.
    dual_forces: Vec<V6<Dual>>,
    dual_bias: Vec<Dual>,
    /// Each plate's share of `M` over the box: `n` blocks of `nq × nq` \[kg\] (after
    /// [`enclose_mass`]).
    pub mass_shares: Vec<Interval>,
    /// Each plate's share of `Ṁ` along the direction box over the box (after
    /// [`enclose_mass_rate`]) \[kg/s\], the same layout.
    pub mass_rate_shares: Vec<Interval>,
    /// `h(q, q̇) + G(q)` over the boxes \[N\] (after [`enclose_bias`]).
    pub nonlinear: Vec<Interval>,
    /// `Σ_i |τ_i|` per coordinate: each plate's own velocity-product and weight wrench,
    /// carried to every joint below it, at the worst state in the boxes \[N\] — what scaling
    /// each plate's mass and inertia by `1 ± σ` can change `h + G` by, over `σ`.
    pub per_body: Vec<f64>,
}

impl EnclosureWorkspace {
    /// Storage sized for `model`.
    pub fn new(model: &Model) -> EnclosureWorkspace {
        let n = model.n_modules();
        let nq = model.nq();
        EnclosureWorkspace {
            n,
            intervals: Joints::new(n),
            duals: Joints::new(n),
            forces: vec![[Interval::ZERO; 6]; n],
            dual_shares: vec![Dual::default(); n * nq * nq],
            dual_q: vec![Dual::default(); nq],
            dual_qd: vec![Dual::default(); nq],
            dual_forces: vec![[Dual::default(); 6]; n],
            dual_bias: vec![Dual::default(); nq],
            mass_shares: vec![Interval::ZERO; n * nq * nq],
            mass_rate_shares: vec![Interval::ZERO; n * nq * nq],
            nonlinear: vec![Interval::ZERO; nq],
            per_body: vec![0.0; nq],
        }
    }

    /// Number of modules.
    pub fn modules(&self) -> usize {
        self.n
    }
}

fn sizes_fit(model: &Model, ws: &EnclosureWorkspace, boxes: &[&[Interval]]) -> bool {
    let nq = 3 * ws.n;
    model.n_modules() == ws.n && boxes.iter().all(|b| b.len() == nq)
}

/// Encloses each plate's share of `M(q)` over the box `q` into `ws.mass_shares`. Returns
/// `false` (results unusable) for wrong lengths or a result that is not finite.
pub fn enclose_mass(model: &Model, ws: &mut EnclosureWorkspace, q: &[Interval]) -> bool {
    if !sizes_fit(model, ws, &[q]) {
        return false;
    }
    let zero = vec_zero(q.len());
    let joints = &mut ws.intervals;
    model.generated.joint_terms_interval(
        &model.params,
        q,
        &zero,
        &mut joints.rotation,
        &mut joints.translation,
        &mut joints.subspace,
        &mut joints.bias_acceleration,
    );
    joints.prepare();
    joints.mass_shares(&model.inertias, &mut ws.mass_shares);
    ws.mass_shares.iter().all(|x| x.is_finite())
}

/// A box of zeros without allocating for the usual sizes.
fn vec_zero(nq: usize) -> ZeroBox {
    ZeroBox { nq }
}

/// `nq` zero intervals, borrowed from a static array (robots of up to 20 modules).
struct ZeroBox {
    nq: usize,
}

static ZEROS: [Interval; 60] = [Interval::ZERO; 60];

impl std::ops::Deref for ZeroBox {
    type Target = [Interval];
    fn deref(&self) -> &[Interval] {
        &ZEROS[..self.nq.min(ZEROS.len())]
    }
}

/// Encloses each plate's share of `Ṁ = Σ_k ∂M/∂q_k v_k` over every `q` in the box `q` and
/// `v` in the box `direction` into `ws.mass_rate_shares` (and the shares of `M` into
/// `ws.mass_shares`). Returns `false` for wrong lengths or a result that is not finite.
pub fn enclose_mass_rate(
    model: &Model,
    ws: &mut EnclosureWorkspace,
    q: &[Interval],
    direction: &[Interval],
) -> bool {
    if !sizes_fit(model, ws, &[q, direction]) {
        return false;
    }
    for ((d, &x), &v) in ws.dual_q.iter_mut().zip(q).zip(direction) {
        *d = Dual::new(x, v);
    }
    for (d, &v) in ws.dual_qd.iter_mut().zip(direction) {
        *d = Dual::constant(v);
    }
    let joints = &mut ws.duals;
    model.generated.joint_terms_dual(
        &model.params,
        &ws.dual_q,
        &ws.dual_qd,
        &mut joints.rotation,
        &mut joints.translation,
        &mut joints.subspace,
        &mut joints.bias_acceleration,
    );
    joints.prepare();
    joints.mass_shares(&model.inertias, &mut ws.dual_shares);
    for ((m, r), d) in ws
        .mass_shares
        .iter_mut()
        .zip(&mut ws.mass_rate_shares)
        .zip(&ws.dual_shares)
    {
        *m = d.value;
        *r = d.slope;
    }
    ws.dual_shares.iter().all(|x| x.is_finite())
}

/// The forward and backward passes of Newton–Euler with `q̈ = 0` on joint terms already in
/// `joints`: each plate's own wrench `I a + v ×* I v` into `forces` and the generalized force
/// `h + G` (with `gravity`, the base accelerating upward at `−g`; else `h` alone) into `out`.
fn newton_euler<T: Scalar>(
    model: &Model,
    joints: &Joints<T>,
    qd: &[T],
    gravity: bool,
    forces: &mut [V6<T>],
    out: &mut [T],
) {
    let n = joints.transforms.len();
    let zero = T::default();
    let g = model.robot.gravity;
    let base: V3<T> = if gravity {
        std::array::from_fn(|k| T::from(-g[k]))
    } else {
        [zero; 3]
    };
    let mut parent_velocity = [zero; 6];
    let mut parent_acceleration = [zero; 6];
    for i in 0..n {
        let x = joints.transforms[i];
        let qd_i = [qd[3 * i], qd[3 * i + 1], qd[3 * i + 2]];
        let joint_velocity = subspace_times(&joints.subspace[i], &qd_i);
        let (v, a) = if i == 0 {
            let a = spatial(&[zero; 3], &tr_mul(&x.rotation, &base));
            (joint_velocity, add6(&a, &joints.bias_acceleration[0]))
        } else {
            let v = add6(&x.motion_to_child(&parent_velocity), &joint_velocity);
            let a = add6(
                &add6(
                    &x.motion_to_child(&parent_acceleration),
                    &joints.bias_acceleration[i],
                ),
                &cross_motion(&v, &joint_velocity),
            );
            (v, a)
        };
        let inertia = &model.inertias[i];
        forces[i] = add6(
            &apply_inertia(inertia, &a),
            &cross_force(&v, &apply_inertia(inertia, &v)),
        );
        parent_velocity = v;
        parent_acceleration = a;
    }
    let mut carried = [zero; 6];
    for i in (0..n).rev() {
        let f = add6(&forces[i], &carried);
        let tau = subspace_transpose(&joints.subspace[i], &f);
        out[3 * i..3 * i + 3].copy_from_slice(&tau);
        carried = joints.transforms[i].force_to_parent(&f);
    }
}

/// Encloses `h(q, q̇) + G(q)` over the box `q` and every `q̇ = v_c + δ`, `δ` in the box
/// `delta`, into `ws.nonlinear`, and the sum of the plates' own shares' magnitudes into
/// `ws.per_body`. `h` is quadratic in `q̇`, so `h(q, v_c + δ) = h(q, v_c) + 2Γ_q(v_c, δ) +
/// h(q, δ)` exactly (`Γ` its polar form): the first two terms come from one pass on jets
/// (`q̇ = v_c + ε δ`, whose slope is `2Γ(v_c, δ)`, linear in `δ` and so free of the
/// dependency that squares a wide box), the last from a pass on the small box `δ`. Returns
/// `false` for wrong lengths or a result that is not finite.
pub fn enclose_bias(
    model: &Model,
    ws: &mut EnclosureWorkspace,
    q: &[Interval],
    center: &[f64],
    delta: &[Interval],
) -> bool {
    if !sizes_fit(model, ws, &[q, delta]) || center.len() != q.len() {
        return false;
    }
    let nq = q.len();
    // Jets: value at v_c (with gravity), slope along δ.
    for (d, &x) in ws.dual_q.iter_mut().zip(q) {
        *d = Dual::constant(x);
    }
    for ((d, &c), &e) in ws.dual_qd.iter_mut().zip(center).zip(delta) {
        *d = Dual::new(Interval::point(c), e);
    }
    let joints = &mut ws.duals;
    model.generated.joint_terms_dual(
        &model.params,
        &ws.dual_q,
        &ws.dual_qd,
        &mut joints.rotation,
        &mut joints.translation,
        &mut joints.subspace,
        &mut joints.bias_acceleration,
    );
    joints.prepare();
    let mut dual_forces = [[Dual::default(); 6]; MAX_MODULES];
    let mut dual_out = [Dual::default(); 3 * MAX_MODULES];
    if ws.n > MAX_MODULES {
        return false;
    }
    newton_euler(
        model,
        joints,
        &ws.dual_qd,
        true,
        &mut dual_forces[..ws.n],
        &mut dual_out[..nq],
    );
    // The small box: h(q, δ) without gravity.
    let joints = &mut ws.intervals;
    model.generated.joint_terms_interval(
        &model.params,
        q,
        delta,
        &mut joints.rotation,
        &mut joints.translation,
        &mut joints.subspace,
        &mut joints.bias_acceleration,
    );
    joints.prepare();
    newton_euler(
        model,
        joints,
        delta,
        false,
        &mut ws.forces,
        &mut ws.nonlinear,
    );
    for (out, jet) in ws.nonlinear.iter_mut().zip(&dual_out) {
        *out = jet.value + jet.slope + *out;
    }
    // Each plate's own share (velocity product and weight) at the worst state: from the
    // jets' wrenches (value and slope) and the small box's.
    ws.per_body.fill(0.0);
    let n = ws.n;
    for i in 0..n {
        let dual_wrench = dual_forces[i];
        let mut g: V6<Interval> =
            std::array::from_fn(|k| dual_wrench[k].value + dual_wrench[k].slope + ws.forces[i][k]);
        for j in (0..=i).rev() {
            let tau = subspace_transpose(&ws.intervals.subspace[j], &g);
            for (r, value) in tau.iter().enumerate() {
                ws.per_body[3 * j + r] += value.mag();
            }
            if j > 0 {
                g = ws.intervals.transforms[j].force_to_parent(&g);
            }
        }
    }
    ws.nonlinear.iter().all(|x| x.is_finite()) && ws.per_body.iter().all(|x| x.is_finite())
}

/// Most modules the jet passes hold on the stack.
const MAX_MODULES: usize = 20;

/// Jets of the nominal model's force mismatch `g(q, v, a) = (M₀ − M(q)) a + f₀ − h(q, v) −
/// G(q)` over the jets `q`, `v`, `a` (values: boxes; slopes: the direction) into `out`, and
/// the plates' shares' magnitudes `Σ_i |M_i a + h_i + G_i|` at the worst point of the value
/// boxes into `ws.per_body` (what a mass factor `1 ± σ` on each plate changes `M a + h + G`
/// by, over `σ`). `mass` is `M₀` (row-major `nq × nq`), `nonlinear` is `f₀`. Returns `false`
/// for wrong lengths or a result that is not finite. Allocates nothing.
#[allow(clippy::too_many_arguments)]
pub fn enclose_mismatch(
    model: &Model,
    ws: &mut EnclosureWorkspace,
    q: &[Dual],
    v: &[Dual],
    a: &[Dual],
    mass: &[f64],
    nonlinear: &[f64],
    out: &mut [Dual],
) -> bool {
    let n = ws.n;
    let nq = 3 * n;
    if model.n_modules() != n
        || [
            q.len(),
            v.len(),
            a.len(),
            mass.len() / nq.max(1),
            nonlinear.len(),
            out.len(),
        ]
        .iter()
        .any(|&len| len != nq)
        || n > MAX_MODULES
    {
        return false;
    }
    let joints = &mut ws.duals;
    model.generated.joint_terms_dual(
        &model.params,
        q,
        v,
        &mut joints.rotation,
        &mut joints.translation,
        &mut joints.subspace,
        &mut joints.bias_acceleration,
    );
    joints.prepare();
    joints.mass_shares(&model.inertias, &mut ws.dual_shares);
    let (forces, bias) = (&mut ws.dual_forces, &mut ws.dual_bias);
    newton_euler(model, joints, v, true, forces, bias);
    let nn = nq * nq;
    ws.per_body.fill(0.0);
    for (r, o) in out.iter_mut().enumerate() {
        let mut value = Dual::from(nonlinear[r]) - bias[r];
        for c in 0..nq {
            let mut m = Dual::default();
            for i in 0..n {
                let share = ws.dual_shares[i * nn + r * nq + c];
                m += share;
            }
            value += (Dual::from(mass[r * nq + c]) - m) * a[c];
        }
        *o = value;
    }
    // Plate i's share of M a + h + G: its mass share times a, and its own wrench carried
    // down (values only).
    let joints = &ws.duals;
    for i in 0..n {
        for r in 0..nq {
            let mut inertial = Interval::ZERO;
            for c in 0..nq {
                inertial += ws.dual_shares[i * nn + r * nq + c].value * a[c].value;
            }
            ws.per_body[r] += inertial.mag();
        }
        let mut g: V6<Interval> = std::array::from_fn(|k| forces[i][k].value);
        for j in (0..=i).rev() {
            let s: S63<Interval> = std::array::from_fn(|row| {
                std::array::from_fn(|col| joints.subspace[j][row][col].value)
            });
            let tau = subspace_transpose(&s, &g);
            for (r, value) in tau.iter().enumerate() {
                ws.per_body[3 * j + r] += value.mag();
            }
            if j > 0 {
                let x = joints.transforms[j];
                let xi = Transform {
                    rotation: std::array::from_fn(|row| {
                        std::array::from_fn(|col| x.rotation[row][col].value)
                    }),
                    translation: std::array::from_fn(|k| x.translation[k].value),
                };
                g = xi.force_to_parent(&g);
            }
        }
    }
    for i in 0..n * nn {
        ws.mass_shares[i] = ws.dual_shares[i].value;
        ws.mass_rate_shares[i] = ws.dual_shares[i].slope;
    }
    out.iter().all(|x| x.is_finite()) && ws.per_body.iter().all(|x| x.is_finite())
}
