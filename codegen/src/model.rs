//! The robot model as symbolic expressions (docs/model.md §2–4) and its emission as a Rust file.
//! Structure decides the code; every number is read from the parameter vector at run time.

use proc_macro2::{Literal, TokenStream};
use quote::{format_ident, quote};

use crate::analytic;
use crate::diff::{Differentiator, Tangent};
use crate::emit::{FunctionSpec, Scalar, emit_function, format_file};
use crate::expr::{Arena, Id};
use crate::layout::{Param, param_layout};
use crate::program::OpCount;
use crate::robot::Structure;

pub use crate::barriers::{BarrierKind, Point};

/// One barrier `b(p, q) ≥ 0` of the model and where it sits on the robot (a row of
/// `softcbf_description::barriers::barrier_list` with its expression).
#[derive(Clone, Debug)]
pub struct Barrier {
    /// What it keeps apart.
    pub kind: BarrierKind,
    /// The module it belongs to (0-based, base first). Its value may depend on the
    /// coordinates of this module and of every module below it.
    pub module: usize,
    /// The watched point (for a plate corner: `Point::Corner(j)`); `None` for a limit.
    pub point: Option<Point>,
    /// The obstacle (0-based), for an environment barrier.
    pub obstacle: Option<usize>,
    /// A short stable name, 1-based like the reports: `module 1 corner 3`.
    pub label: String,
    /// The expression of `b`.
    pub value: Id,
    /// Parameter-vector indices `b` reads, ascending.
    pub params: Vec<usize>,
}

/// Symbols and kinematic expressions of one module.
struct ModuleExprs {
    /// `q_i = [Δx, Δy, δL]`.
    q: [Id; 3],
    /// `q̇_i`.
    qd: [Id; 3],
    /// Rotation of the tip frame in the segment base frame, rows.
    rotation: [[Id; 3]; 3],
    /// Position of the tip-frame origin in the segment base frame.
    translation: [Id; 3],
    /// `c_ij`: height of each corner above the bottom plate's plane.
    corner_heights: Vec<Id>,
    /// The bending coordinates `a = Δx/d`, `b = Δy/d` and `u = a² + b² = θ²`.
    bend: [Id; 3],
    /// `L = L0 + δL`.
    length: Id,
    /// `ε_ij`.
    margins: Vec<Id>,
}

/// The symbolic model of a structure, ready to be emitted.
pub struct SymbolicModel {
    arena: Arena,
    diff: Differentiator,
    /// Time derivative along `q̇` (with `q̈ = 0`).
    tangent: Tangent,
    modules: Vec<ModuleExprs>,
    /// Every barrier, in the order of the generated arrays.
    barriers: Vec<Barrier>,
    /// `(symbol, index)` of every parameter.
    params: Vec<(Id, usize)>,
    param_names: Vec<String>,
    structure: Structure,
}

/// Builds the symbolic kinematics of every module.
pub fn build(structure: &Structure) -> SymbolicModel {
    let mut arena = Arena::new();
    let layout = param_layout(structure);
    let mut params = Vec::with_capacity(layout.len());
    let mut param_names = Vec::with_capacity(layout.len());
    let mut symbol_of = std::collections::HashMap::new();
    for (index, p) in layout.iter().enumerate() {
        let id = arena.symbol(&p.name());
        symbol_of.insert(p.name(), id);
        params.push((id, index));
        param_names.push(p.name());
    }
    let param = |p: Param| symbol_of[&p.name()];

    let mut modules = Vec::new();
    for (i, &corners) in structure.corners.iter().enumerate() {
        let q = [
            arena.symbol(&format!("dx_{i}")),
            arena.symbol(&format!("dy_{i}")),
            arena.symbol(&format!("dl_{i}")),
        ];
        let qd = [
            arena.symbol(&format!("dx_dot_{i}")),
            arena.symbol(&format!("dy_dot_{i}")),
            arena.symbol(&format!("dl_dot_{i}")),
        ];
        let rest_length = param(Param::RestLength(i));
        let tendon_radius = param(Param::TendonRadius(i));
        let corner_radius = param(Param::CornerRadius(i));

        // a = Δx/d, b = Δy/d, u = a² + b² = θ², L = L0 + δL.
        let a = arena.div(q[0], tendon_radius);
        let b = arena.div(q[1], tendon_radius);
        let a2 = arena.powi(a, 2);
        let b2 = arena.powi(b, 2);
        let u = arena.add(a2, b2);
        let length = arena.add(rest_length, q[2]);
        let fs = arena.fs(u);
        let fc = arena.fc(u);
        let one = arena.constant(1.0);

        let a_fc = arena.mul(a, fc);
        let b_fc = arena.mul(b, fc);
        let a_fs = arena.mul(a, fs);
        let b_fs = arena.mul(b, fs);
        let a2_fc = arena.mul(a2, fc);
        let b2_fc = arena.mul(b2, fc);
        let ab_fc = arena.mul(a, b_fc);
        let u_fc = arena.mul(u, fc);
        let r00 = arena.sub(one, a2_fc);
        let r01 = arena.neg(ab_fc);
        let r11 = arena.sub(one, b2_fc);
        let r20 = arena.neg(a_fs);
        let r21 = arena.neg(b_fs);
        let r22 = arena.sub(one, u_fc);
        let rotation = [[r00, r01, a_fs], [r01, r11, b_fs], [r20, r21, r22]];
        let translation = [
            arena.mul(length, a_fc),
            arena.mul(length, b_fc),
            arena.mul(length, fs),
        ];

        // c_ij = f_s(u) · (L − r (a cos φ_j + b sin φ_j))  (docs/model.md §3).
        let mut corner_heights = Vec::with_capacity(corners);
        let mut margins = Vec::with_capacity(corners);
        for j in 0..corners {
            let cos_phi = param(Param::CornerCos(i, j));
            let sin_phi = param(Param::CornerSin(i, j));
            let along_x = arena.mul(a, cos_phi);
            let along_y = arena.mul(b, sin_phi);
            let lever = arena.add(along_x, along_y);
            let drop = arena.mul(corner_radius, lever);
            let height = arena.sub(length, drop);
            corner_heights.push(arena.mul(fs, height));
            margins.push(param(Param::Margin(i, j)));
        }
        let bend = [a, b, u];
        modules.push(ModuleExprs {
            q,
            qd,
            rotation,
            translation,
            corner_heights,
            bend,
            length,
            margins,
        });
    }
    let mut world = WorldPoses::default();
    let mut barriers = Vec::new();
    for spec in crate::barriers::barrier_list(structure) {
        let value = barrier_value(&mut arena, &modules, &mut world, &param, &spec);
        barriers.push(Barrier {
            kind: spec.kind,
            module: spec.module,
            point: spec.point,
            obstacle: spec.obstacle,
            label: spec.label,
            value,
            params: params_read(&arena, &params, value),
        });
    }
    let mut tangent = Tangent::new();
    for m in &modules {
        for k in 0..3 {
            tangent.set_rate(m.q[k], m.qd[k]);
        }
    }
    SymbolicModel {
        arena,
        diff: Differentiator::new(),
        tangent,
        modules,
        barriers,
        params,
        param_names,
        structure: structure.clone(),
    }
}

/// World poses `W_i = T_1 ⋯ T_i` of the top plates as expressions, built on first use.
#[derive(Default)]
struct WorldPoses {
    /// `(R, t)` of `W_i`, for `i` below the length.
    poses: Vec<([[Id; 3]; 3], [Id; 3])>,
}

impl WorldPoses {
    /// `W_i` of module `i`'s top plate.
    fn pose(
        &mut self,
        arena: &mut Arena,
        modules: &[ModuleExprs],
        i: usize,
    ) -> ([[Id; 3]; 3], [Id; 3]) {
        while self.poses.len() <= i {
            let k = self.poses.len();
            let m = &modules[k];
            let pose = match self.poses.last() {
                None => (m.rotation, m.translation),
                Some(&(parent_r, parent_t)) => {
                    let rotation = std::array::from_fn(|r| {
                        std::array::from_fn(|c| {
                            let column = [m.rotation[0][c], m.rotation[1][c], m.rotation[2][c]];
                            arena.dot(&parent_r[r], &column)
                        })
                    });
                    (rotation, apply(arena, (parent_r, parent_t), m.translation))
                }
            };
            self.poses.push(pose);
        }
        self.poses[i]
    }

    /// `W_{i−1}`, the pose of module `i`'s base (`None`: the world itself, for `i = 0`).
    fn base(
        &mut self,
        arena: &mut Arena,
        modules: &[ModuleExprs],
        i: usize,
    ) -> Option<([[Id; 3]; 3], [Id; 3])> {
        i.checked_sub(1)
            .map(|below| self.pose(arena, modules, below))
    }
}

/// `R x + t`.
fn apply(
    arena: &mut Arena,
    (rotation, translation): ([[Id; 3]; 3], [Id; 3]),
    x: [Id; 3],
) -> [Id; 3] {
    std::array::from_fn(|r| {
        let rotated = arena.dot(&rotation[r], &x);
        arena.add(rotated, translation[r])
    })
}

/// The expression of one barrier of the list (docs/model.md §3).
fn barrier_value(
    arena: &mut Arena,
    modules: &[ModuleExprs],
    world: &mut WorldPoses,
    param: &dyn Fn(Param) -> Id,
    spec: &crate::barriers::BarrierSpec,
) -> Id {
    let i = spec.module;
    let m = &modules[i];
    match spec.kind {
        BarrierKind::PlateCorner => {
            let Some(Point::Corner(j)) = spec.point else {
                unreachable!("a plate-corner barrier watches a corner")
            };
            arena.sub(m.corner_heights[j], m.margins[j])
        }
        BarrierKind::ElongationMin => {
            // b = δL − (δL_min + ε)
            let min = param(Param::ElongationMin(i));
            let margin = param(Param::ElongationMargin(i));
            let bound = arena.add(min, margin);
            arena.sub(m.q[2], bound)
        }
        BarrierKind::ElongationMax => {
            // b = (δL_max − ε) − δL
            let max = param(Param::ElongationMax(i));
            let margin = param(Param::ElongationMargin(i));
            let bound = arena.sub(max, margin);
            arena.sub(bound, m.q[2])
        }
        BarrierKind::Bend => {
            // b = (θ_b² − θ²) / (2 θ_b), θ_b = θ_max − ε, with θ² = u: smooth at θ = 0 and
            // ≈ θ_b − θ near the limit.
            let max = param(Param::MaxBend(i));
            let margin = param(Param::BendMargin(i));
            let bound = arena.sub(max, margin);
            let bound2 = arena.powi(bound, 2);
            let gap = arena.sub(bound2, m.bend[2]);
            let two = arena.constant(2.0);
            let twice = arena.mul(two, bound);
            arena.div(gap, twice)
        }
        BarrierKind::HalfSpace | BarrierKind::Sphere => {
            let o = spec
                .obstacle
                .expect("an environment barrier has an obstacle");
            let x = watched_point(arena, modules, world, param, spec);
            let margin = param(Param::ObstacleMargin(o));
            if spec.kind == BarrierKind::HalfSpace {
                // b = n·x − o − ε
                let normal: [Id; 3] = std::array::from_fn(|c| param(Param::ObstacleNormal(o, c)));
                let offset = param(Param::ObstacleOffset(o));
                let height = arena.dot(&normal, &x);
                let bound = arena.add(offset, margin);
                arena.sub(height, bound)
            } else {
                // b = |x − c| − ρ − ε
                let d: [Id; 3] = std::array::from_fn(|c| {
                    let center = param(Param::ObstacleCenter(o, c));
                    arena.sub(x[c], center)
                });
                let squared = arena.dot(&d, &d);
                let distance = arena.sqrt(squared);
                let radius = param(Param::ObstacleRadius(o));
                let bound = arena.add(radius, margin);
                arena.sub(distance, bound)
            }
        }
    }
}

/// World coordinates of the point an environment barrier watches.
fn watched_point(
    arena: &mut Arena,
    modules: &[ModuleExprs],
    world: &mut WorldPoses,
    param: &dyn Fn(Param) -> Id,
    spec: &crate::barriers::BarrierSpec,
) -> [Id; 3] {
    let i = spec.module;
    let o = spec
        .obstacle
        .expect("an environment barrier has an obstacle");
    let zero = arena.constant(0.0);
    let in_plate = |arena: &mut Arena, world: &mut WorldPoses, local: [Id; 3]| {
        let pose = world.pose(arena, modules, i);
        apply(arena, pose, local)
    };
    match spec.point.expect("an environment barrier watches a point") {
        Point::Corner(j) => {
            let r = param(Param::CornerRadius(i));
            let x = arena.mul(r, param(Param::CornerCos(i, j)));
            let y = arena.mul(r, param(Param::CornerSin(i, j)));
            in_plate(arena, world, [x, y, zero])
        }
        Point::Centre => in_plate(arena, world, [zero, zero, zero]),
        Point::Listed(k) => {
            let local = std::array::from_fn(|c| param(Param::PointCoordinate(o, k, c)));
            in_plate(arena, world, local)
        }
        Point::Arc(k) => {
            // The PCC arc up to fraction s has bend coordinates (s a, s b), u_s = s² u, and
            // length s L: its end is s L (s a f_c(u_s), s b f_c(u_s), f_s(u_s)) in the
            // segment's base frame.
            let s = param(Param::ArcFraction(o, k));
            let m = &modules[i];
            let [a, b, u] = m.bend;
            let s2 = arena.powi(s, 2);
            let u_s = arena.mul(s2, u);
            let fs = arena.fs(u_s);
            let fc = arena.fc(u_s);
            let length = arena.mul(s, m.length);
            let sa = arena.mul(s, a);
            let sb = arena.mul(s, b);
            let sa_fc = arena.mul(sa, fc);
            let sb_fc = arena.mul(sb, fc);
            let local = [
                arena.mul(length, sa_fc),
                arena.mul(length, sb_fc),
                arena.mul(length, fs),
            ];
            match world.base(arena, modules, i) {
                Some(pose) => apply(arena, pose, local),
                None => local,
            }
        }
    }
}

/// The parameter-vector indices among the symbols `expr` reads, ascending.
fn params_read(arena: &Arena, params: &[(Id, usize)], expr: Id) -> Vec<usize> {
    let index: std::collections::HashMap<Id, usize> = params.iter().copied().collect();
    let mut seen = vec![false; expr.index() + 1];
    let mut stack = vec![expr];
    let mut found = std::collections::BTreeSet::new();
    while let Some(id) = stack.pop() {
        if std::mem::replace(&mut seen[id.index()], true) {
            continue;
        }
        if let Some(&k) = index.get(&id) {
            found.insert(k);
        }
        stack.extend(arena.node(id).children());
    }
    found.into_iter().collect()
}

/// The outputs of each generated function, in the order its emitted code writes them
/// ([`SymbolicModel::function_outputs`]).
#[derive(Clone, Debug)]
pub struct FunctionOutputs {
    /// `segment_transforms`: per module, per row `r` of 0–2, `R[r][0..3]` then `t[r]`.
    pub segment_transforms: Vec<Id>,
    /// `barriers`: each barrier's value.
    pub barriers: Vec<Id>,
    /// `barrier_terms`: per barrier, `b`, its Jacobian row (`nq` entries), `J̇q̇`.
    pub barrier_terms: Vec<Id>,
    /// `joint_terms`: per module, per row `r` of 0–2 `R[r][0..3]` then `t[r]`, then per
    /// row `r` of 0–5 `S[r][0..3]` then `c_J[r]`.
    pub joint_terms: Vec<Id>,
    /// `model_terms`: the joint terms, then the barrier terms.
    pub model_terms: Vec<Id>,
}

/// A generated model file and what it costs.
pub struct GeneratedSource {
    /// The formatted Rust source.
    pub text: String,
    /// Operation count of each emitted function.
    pub ops: Vec<(String, OpCount)>,
}

impl SymbolicModel {
    /// Number of generalized coordinates.
    pub fn nq(&self) -> usize {
        3 * self.modules.len()
    }

    /// Number of barriers.
    pub fn nb(&self) -> usize {
        self.barriers.len()
    }

    /// The arena holding every expression.
    pub fn arena(&self) -> &Arena {
        &self.arena
    }

    fn bindings(&self, with_velocity: bool) -> Vec<(Id, TokenStream)> {
        let mut inputs = Vec::new();
        for &(id, index) in &self.params {
            let index = Literal::usize_unsuffixed(index);
            inputs.push((id, quote!(p[#index])));
        }
        for (i, m) in self.modules.iter().enumerate() {
            for k in 0..3 {
                let index = Literal::usize_unsuffixed(3 * i + k);
                inputs.push((m.q[k], quote!(q[#index])));
                if with_velocity {
                    inputs.push((m.qd[k], quote!(qd[#index])));
                }
            }
        }
        inputs
    }

    /// The barriers, in the order of the generated arrays.
    pub fn barrier_list(&self) -> &[Barrier] {
        &self.barriers
    }

    /// Barrier values, in the order of [`SymbolicModel::barrier_list`].
    pub fn barrier_exprs(&self) -> Vec<Id> {
        self.barriers.iter().map(|b| b.value).collect()
    }

    /// For every barrier: its value, its gradient with respect to the coordinates of its
    /// module and of every module below it (`3(i+1)` entries; a barrier depends on no
    /// coordinate above its module) and `q̇ᵀ ∇²b q̇`.
    pub fn barrier_term_exprs(&mut self) -> Vec<(Id, Vec<Id>, Id)> {
        let mut out = Vec::with_capacity(self.barriers.len());
        for barrier in &self.barriers {
            let coordinates: Vec<Id> = self.modules[..=barrier.module]
                .iter()
                .flat_map(|m| m.q)
                .collect();
            let b = barrier.value;
            let gradient = self.diff.gradient(&mut self.arena, b, &coordinates);
            let rate = self.tangent.tangent(&mut self.arena, b);
            let jdot_qd = self.tangent.tangent(&mut self.arena, rate);
            out.push((b, gradient, jdot_qd));
        }
        out
    }

    /// Joint quantities of module `i` for the recursive dynamics: the motion subspace `S`
    /// (6×3, rows ω then v, tip coordinates) and `c_J = Ṡ q̇` (apparent derivative).
    ///
    /// The tip's body twist `V = S q̇` has the angular part in closed form: `R = exp([w]×)`
    /// with `w = (−b, a, 0)`, so `Rᵀ Ṙ = [J_r(w) ẇ]×` with the right Jacobian
    /// `J_r = I − f_c [w]× + g [w]×²`, `g = (θ − sin θ)/θ³ = f_c + 2 f_s'` (from
    /// `2u f_s' = cos θ − f_s`). With `w·ẇ = aȧ + bḃ` and `w × ẇ = (aḃ − bȧ) ẑ` this is
    /// `ω = f_s ẇ + g (aȧ + bḃ) w + f_c (bȧ − aḃ) ẑ` (`1 − g u = f_s`). The linear part
    /// is `Rᵀ ṫ`.
    /// `S` is `∂V/∂q̇` and `c_J` the time derivative of `V` at `q̈ = 0`.
    pub fn joint_exprs(&mut self, i: usize) -> ([[Id; 3]; 6], [Id; 6]) {
        let m = &self.modules[i];
        let (qd, translation, [a, b, u]) = (m.qd, m.translation, m.bend);
        let arena = &mut self.arena;
        let a_rate = self.tangent.tangent(arena, a);
        let b_rate = self.tangent.tangent(arena, b);
        let fs = arena.fs(u);
        let fc = arena.fc(u);
        let fs1 = arena.analytic(crate::expr::Analytic::Fs, 1, u);
        let two = arena.constant(2.0);
        let two_fs1 = arena.mul(two, fs1);
        let g = arena.add(fc, two_fs1);
        let a_a_rate = arena.mul(a, a_rate);
        let b_b_rate = arena.mul(b, b_rate);
        let radial_rate = arena.add(a_a_rate, b_b_rate);
        let radial = arena.mul(g, radial_rate);
        let b_a_rate = arena.mul(b, a_rate);
        let a_b_rate = arena.mul(a, b_rate);
        let twist_rate = arena.sub(b_a_rate, a_b_rate);
        // ω_x = −f_s ḃ − g (aȧ + bḃ) b, ω_y = f_s ȧ + g (aȧ + bḃ) a.
        let x_along = arena.mul(fs, b_rate);
        let x_radial = arena.mul(radial, b);
        let x_sum = arena.add(x_along, x_radial);
        let y_along = arena.mul(fs, a_rate);
        let y_radial = arena.mul(radial, a);
        let angular = [
            arena.neg(x_sum),
            arena.add(y_along, y_radial),
            arena.mul(fc, twist_rate),
        ];
        let zero = self.arena.constant(0.0);
        let mut twist = [angular[0], angular[1], angular[2], zero, zero, zero];
        let translation_rate: Vec<Id> = translation
            .iter()
            .map(|&t| self.tangent.tangent(&mut self.arena, t))
            .collect();
        // v = Rᵀ ṫ = ṗ + ω × p with p = Rᵀ t = (−t_x, −t_y, t_z): the tip's origin seen
        // from the tip frame (f_s² + u f_c² = 2 f_c gives the closed form), so no product
        // with R is needed.
        let arena = &mut self.arena;
        let [w0, w1, w2] = angular;
        let [t0, t1, t2] = translation;
        let [r0, r1, r2] = [
            translation_rate[0],
            translation_rate[1],
            translation_rate[2],
        ];
        let mut cross = |x: Id, y: Id, z: Id, w: Id| {
            let xy = arena.mul(x, y);
            let zw = arena.mul(z, w);
            arena.add(xy, zw)
        };
        let vx = cross(w1, t2, w2, t1);
        let vy = cross(w2, t0, w0, t2);
        let vy = arena.neg(vy);
        let wx_ty = arena.mul(w0, t1);
        let wy_tx = arena.mul(w1, t0);
        let vz = arena.sub(wy_tx, wx_ty);
        twist[3] = arena.sub(vx, r0);
        twist[4] = arena.sub(vy, r1);
        twist[5] = arena.add(r2, vz);
        let mut subspace = [[self.arena.constant(0.0); 3]; 6];
        for (r, row) in subspace.iter_mut().enumerate() {
            for (k, entry) in row.iter_mut().enumerate() {
                *entry = self.diff.derivative(&mut self.arena, twist[r], qd[k]);
            }
        }
        let bias = twist.map(|v| self.tangent.tangent(&mut self.arena, v));
        (subspace, bias)
    }

    /// The places and values `segment_transforms` writes (rows 0–2 of each `T_i`).
    fn segment_outputs(&self) -> Vec<(TokenStream, Id)> {
        let mut outputs = Vec::new();
        for (i, m) in self.modules.iter().enumerate() {
            let i_lit = Literal::usize_unsuffixed(i);
            for r in 0..3 {
                let r_lit = Literal::usize_unsuffixed(r);
                for c in 0..3 {
                    let c_lit = Literal::usize_unsuffixed(c);
                    outputs.push((quote!(transforms[#i_lit][#r_lit][#c_lit]), m.rotation[r][c]));
                }
                outputs.push((quote!(transforms[#i_lit][#r_lit][3]), m.translation[r]));
            }
        }
        outputs
    }

    /// The outputs of every generated function as expressions, built exactly as
    /// [`SymbolicModel::emit`] builds them and in the order its code writes them: what the
    /// interpreter of the generated model evaluates.
    pub fn function_outputs(&mut self) -> FunctionOutputs {
        let ids = |outputs: Vec<(TokenStream, Id)>| outputs.into_iter().map(|(_, id)| id).collect();
        let segment_transforms = ids(self.segment_outputs());
        let barriers = self.barrier_exprs();
        // The order `emit` follows: barrier terms first, then the joint terms.
        let barrier_terms: Vec<Id> = ids(self.barrier_term_outputs());
        let joint_terms: Vec<Id> = ids(self.joint_outputs());
        let model_terms = joint_terms.iter().chain(&barrier_terms).copied().collect();
        FunctionOutputs {
            segment_transforms,
            barriers,
            barrier_terms,
            joint_terms,
            model_terms,
        }
    }

    /// The input symbols: the parameters in parameter-vector order, then `q` and `q̇`
    /// (`3·module + k` order, like the generated functions' arrays).
    pub fn input_symbols(&self) -> (Vec<Id>, Vec<Id>, Vec<Id>) {
        let params = self.params.iter().map(|&(id, _)| id).collect();
        let q = self.modules.iter().flat_map(|m| m.q).collect();
        let qd = self.modules.iter().flat_map(|m| m.qd).collect();
        (params, q, qd)
    }

    /// Parameter names in parameter-vector order.
    pub fn param_names(&self) -> &[String] {
        &self.param_names
    }

    /// The structure this model was built for.
    pub fn structure(&self) -> &Structure {
        &self.structure
    }

    /// The places and values `barrier_terms` writes: each barrier, its Jacobian row (zero
    /// past the barrier's module) and `J̇q̇`.
    fn barrier_term_outputs(&mut self) -> Vec<(TokenStream, Id)> {
        let nq = self.nq();
        let zero = self.arena.constant(0.0);
        let mut outputs = Vec::new();
        for (k, (b, gradient, jdot)) in self.barrier_term_exprs().into_iter().enumerate() {
            let k_lit = Literal::usize_unsuffixed(k);
            outputs.push((quote!(barriers[#k_lit]), b));
            for col in 0..nq {
                let c_lit = Literal::usize_unsuffixed(col);
                let value = gradient.get(col).copied().unwrap_or(zero);
                outputs.push((quote!(jacobian[#k_lit][#c_lit]), value));
            }
            outputs.push((quote!(jdot_qd[#k_lit]), jdot));
        }
        outputs
    }

    /// The places and values `joint_terms` writes, module by module.
    fn joint_outputs(&mut self) -> Vec<(TokenStream, Id)> {
        let mut outputs = Vec::new();
        for i in 0..self.modules.len() {
            let (subspace, bias) = self.joint_exprs(i);
            let m = &self.modules[i];
            let i_lit = Literal::usize_unsuffixed(i);
            for r in 0..3 {
                let r_lit = Literal::usize_unsuffixed(r);
                for c in 0..3 {
                    let c_lit = Literal::usize_unsuffixed(c);
                    outputs.push((quote!(rotation[#i_lit][#r_lit][#c_lit]), m.rotation[r][c]));
                }
                outputs.push((quote!(translation[#i_lit][#r_lit]), m.translation[r]));
            }
            for (r, row) in subspace.iter().enumerate() {
                let r_lit = Literal::usize_unsuffixed(r);
                for (c, &value) in row.iter().enumerate() {
                    let c_lit = Literal::usize_unsuffixed(c);
                    outputs.push((quote!(motion_subspace[#i_lit][#r_lit][#c_lit]), value));
                }
                outputs.push((quote!(bias_acceleration[#i_lit][#r_lit]), bias[r]));
            }
        }
        outputs
    }

    /// Emits the whole model as one Rust source file (items only, to be `include!`d).
    pub fn emit(&mut self, source_label: &str) -> GeneratedSource {
        let n = Literal::usize_unsuffixed(self.modules.len());
        let nq_value = self.nq();
        let nq = Literal::usize_unsuffixed(nq_value);
        let nb = Literal::usize_unsuffixed(self.nb());
        let np = Literal::usize_unsuffixed(self.params.len());
        let n_modules = self.modules.len();
        let mut functions = Vec::new();
        let mut ops = Vec::new();
        let mut orders = std::collections::BTreeSet::new();
        let mut interval_emitted = Vec::new();
        let mut push = |name: &str, emitted: crate::emit::Emitted| {
            ops.push((name.to_string(), emitted.ops));
            orders.extend(emitted.analytic_orders);
            functions.push(emitted.tokens);
        };

        // Segment transforms T_i.
        let outputs = self.segment_outputs();
        let spec = FunctionSpec {
            name: format_ident!("segment_transforms"),
            doc: vec![
                " Segment transforms `T_i` (4×4, rows): tip coordinates → segment base coordinates.".into(),
            ],
            args: quote!(p: &[f64; NP], q: &[f64; NQ], transforms: &mut [[[f64; 4]; 4]; N_MODULES]),
            inputs: self.bindings(false),
            outputs,
            epilogue: quote! {
                for transform in transforms.iter_mut() {
                    transform[3] = [0.0, 0.0, 0.0, 1.0];
                }
            },
            scalar: Scalar::F64,
        };
        push("segment_transforms", emit_function(&self.arena, &spec));

        // Barriers alone.
        let barriers = self.barrier_exprs();
        let outputs = barriers
            .iter()
            .enumerate()
            .map(|(k, &b)| {
                let k = Literal::usize_unsuffixed(k);
                (quote!(barriers[#k]), b)
            })
            .collect();
        let spec = FunctionSpec {
            name: format_ident!("barriers"),
            doc: vec![
                " Every barrier value \\[m\\], in the order of [`BARRIERS`] (a plate corner's is"
                    .into(),
                " `b_ij = c_ij − ε_ij`).".into(),
            ],
            args: quote!(p: &[f64; NP], q: &[f64; NQ], barriers: &mut [f64; NB]),
            inputs: self.bindings(false),
            outputs,
            epilogue: TokenStream::new(),
            scalar: Scalar::F64,
        };
        push("barriers", emit_function(&self.arena, &spec));

        // The argument groups the three term functions share.
        let state_args = quote!(p: &[f64; NP], q: &[f64; NQ], qd: &[f64; NQ]);
        let joint_args = quote!(
            rotation: &mut [[[f64; 3]; 3]; N_MODULES],
            translation: &mut [[f64; 3]; N_MODULES],
            motion_subspace: &mut [[[f64; 3]; 6]; N_MODULES],
            bias_acceleration: &mut [[f64; 6]; N_MODULES]
        );
        let barrier_args = quote!(
            barriers: &mut [f64; NB],
            jacobian: &mut [[f64; NQ]; NB],
            jdot_qd: &mut [f64; NB]
        );

        // Barriers with Jacobian rows and J̇q̇.
        let barrier_outputs = self.barrier_term_outputs();
        let spec = FunctionSpec {
            name: format_ident!("barrier_terms"),
            doc: vec![
                " Every barrier `b` \\[m\\], its gradient row `J = ∂b/∂q` and `J̇q̇ = q̇ᵀ ∇²b q̇`."
                    .into(),
            ],
            args: quote!(#state_args, #barrier_args),
            inputs: self.bindings(true),
            outputs: barrier_outputs.clone(),
            epilogue: TokenStream::new(),
            scalar: Scalar::F64,
        };
        push("barrier_terms", emit_function(&self.arena, &spec));

        // Joint quantities for the recursive dynamics.
        let joint_outputs = self.joint_outputs();
        let spec = FunctionSpec {
            name: format_ident!("joint_terms"),
            doc: vec![
                " Per segment: rotation `R_i` and translation `t_i` of `T_i`, the motion subspace".into(),
                " `S_i` (6×3; rows ω then v, in tip coordinates, so the tip's body twist relative".into(),
                " to the segment base is `S_i q̇_i`) and `c_J,i = Ṡ_i q̇_i` (derivative in tip coordinates).".into(),
            ],
            args: quote!(#state_args, #joint_args),
            inputs: self.bindings(true),
            outputs: joint_outputs.clone(),
            epilogue: TokenStream::new(),
            scalar: Scalar::F64,
        };
        push("joint_terms", emit_function(&self.arena, &spec));

        // Both at once: one program, the kinematics and series shared.
        let spec = FunctionSpec {
            name: format_ident!("model_terms"),
            doc: vec![
                " Everything the control tick needs at one state in one pass: the outputs of"
                    .into(),
                " [`joint_terms`] and of [`barrier_terms`], same layouts, every shared term".into(),
                " (segment kinematics, `f_s`, `f_c` and their derivatives) computed once.".into(),
            ],
            args: quote!(#state_args, #joint_args, #barrier_args),
            inputs: self.bindings(true),
            outputs: joint_outputs
                .iter()
                .cloned()
                .chain(barrier_outputs.iter().cloned())
                .collect(),
            epilogue: TokenStream::new(),
            scalar: Scalar::F64,
        };
        push("model_terms", emit_function(&self.arena, &spec));

        let dual_joint_outputs = joint_outputs.clone();
        // Enclosures over boxes of states: the certified filter's remainder bounds
        // (docs/model.md §5). Parameters stay numbers; q and q̇ are intervals.
        let interval_state_args = quote!(p: &[f64; NP], q: &[Interval; NQ], qd: &[Interval; NQ]);
        let spec = FunctionSpec {
            name: format_ident!("barrier_terms_interval"),
            doc: vec![
                " Enclosures of [`barrier_terms`]' outputs over every state in the boxes `q`, `q̇`."
                    .into(),
            ],
            args: quote!(
                #interval_state_args,
                barriers: &mut [Interval; NB],
                jacobian: &mut [[Interval; NQ]; NB],
                jdot_qd: &mut [Interval; NB]
            ),
            inputs: self.bindings(true),
            outputs: barrier_outputs,
            epilogue: TokenStream::new(),
            scalar: Scalar::Interval,
        };
        interval_emitted.push(("barrier_terms_interval", emit_function(&self.arena, &spec)));
        let spec = FunctionSpec {
            name: format_ident!("joint_terms_interval"),
            doc: vec![
                " Enclosures of [`joint_terms`]' outputs over every state in the boxes `q`, `q̇`."
                    .into(),
            ],
            args: quote!(
                #interval_state_args,
                rotation: &mut [[[Interval; 3]; 3]; N_MODULES],
                translation: &mut [[Interval; 3]; N_MODULES],
                motion_subspace: &mut [[[Interval; 3]; 6]; N_MODULES],
                bias_acceleration: &mut [[Interval; 6]; N_MODULES]
            ),
            inputs: self.bindings(true),
            outputs: joint_outputs.clone(),
            epilogue: TokenStream::new(),
            scalar: Scalar::Interval,
        };
        interval_emitted.push(("joint_terms_interval", emit_function(&self.arena, &spec)));
        let spec = FunctionSpec {
            name: format_ident!("joint_terms_dual"),
            doc: vec![
                " Jets of [`joint_terms`]' outputs: enclosures over every state in the boxes"
                    .into(),
                " `q`, `q̇` (the jets' values) and of their derivatives along the jets' slopes."
                    .into(),
            ],
            args: quote!(
                p: &[f64; NP],
                q: &[Dual; NQ],
                qd: &[Dual; NQ],
                rotation: &mut [[[Dual; 3]; 3]; N_MODULES],
                translation: &mut [[Dual; 3]; N_MODULES],
                motion_subspace: &mut [[[Dual; 3]; 6]; N_MODULES],
                bias_acceleration: &mut [[Dual; 6]; N_MODULES]
            ),
            inputs: self.bindings(true),
            outputs: dual_joint_outputs,
            epilogue: TokenStream::new(),
            scalar: Scalar::Dual,
        };
        let dual = emit_function(&self.arena, &spec);
        let dual_orders: Vec<usize> = dual.analytic_orders.iter().copied().collect();
        interval_emitted.push(("joint_terms_dual", dual));
        let mut interval_orders = std::collections::BTreeSet::new();
        for (name, emitted) in interval_emitted {
            ops.push((name.to_string(), emitted.ops));
            if name != "joint_terms_dual" {
                interval_orders.extend(emitted.analytic_orders);
            }
            functions.push(emitted.tokens);
        }
        for &k in &dual_orders {
            orders.insert(k + 1);
            interval_orders.insert(k + 1);
        }

        let plate_poses = quote! {
            /// World poses `W_i = T_1 ⋯ T_i` of every module's top plate (4×4, rows).
            pub fn plate_poses(p: &[f64; NP], q: &[f64; NQ], poses: &mut [[[f64; 4]; 4]; N_MODULES]) {
                segment_transforms(p, q, poses);
                for i in 1..N_MODULES {
                    let parent = poses[i - 1];
                    let local = poses[i];
                    for r in 0..3 {
                        for c in 0..4 {
                            let mut sum = if c == 3 { parent[r][3] } else { 0.0 };
                            for k in 0..3 {
                                sum += parent[r][k] * local[k][c];
                            }
                            poses[i][r][c] = sum;
                        }
                    }
                }
            }
        };

        let analytic_functions = orders
            .iter()
            .map(|&k| analytic::emit(k))
            .chain(interval_orders.iter().map(|&k| analytic::emit_interval(k)))
            .chain(dual_orders.iter().map(|&k| analytic::emit_dual(k)));
        let names = self.param_names.iter().map(String::as_str);
        let corners = self
            .structure
            .corners
            .iter()
            .map(|&c| Literal::usize_unsuffixed(c));
        let tendons = self
            .structure
            .tendons
            .iter()
            .map(|&c| Literal::usize_unsuffixed(c));
        let barrier_table = self.barriers.iter().map(|b| {
            let kind = format_ident!("{}", b.kind.name());
            let module = Literal::usize_unsuffixed(b.module);
            let point = match b.point {
                None => quote!(None),
                Some(Point::Corner(j)) => {
                    let j = Literal::usize_unsuffixed(j);
                    quote!(Some(Point::Corner(#j)))
                }
                Some(Point::Centre) => quote!(Some(Point::Centre)),
                Some(Point::Listed(k)) => {
                    let k = Literal::usize_unsuffixed(k);
                    quote!(Some(Point::Listed(#k)))
                }
                Some(Point::Arc(k)) => {
                    let k = Literal::usize_unsuffixed(k);
                    quote!(Some(Point::Arc(#k)))
                }
            };
            let obstacle = match b.obstacle {
                None => quote!(None),
                Some(o) => {
                    let o = Literal::usize_unsuffixed(o);
                    quote!(Some(#o))
                }
            };
            let label = &b.label;
            let params = b.params.iter().map(|&k| Literal::usize_unsuffixed(k));
            quote! {
                BarrierInfo {
                    kind: BarrierKind::#kind,
                    module: #module,
                    point: #point,
                    obstacle: #obstacle,
                    label: #label,
                    params: &[#(#params),*],
                }
            }
        });
        let tokens = quote! {
            use crate::{BarrierInfo, BarrierKind, Dual, Interval, Point};
            /// Number of modules.
            pub const N_MODULES: usize = #n;
            /// Number of generalized coordinates (3 per module).
            pub const NQ: usize = #nq;
            /// Number of barriers.
            pub const NB: usize = #nb;
            /// Length of the parameter vector.
            pub const NP: usize = #np;
            /// Name of each parameter, in parameter-vector order.
            pub const PARAM_NAMES: [&str; NP] = [#(#names),*];
            /// Corners per plate, one entry per module.
            pub const CORNERS: [usize; N_MODULES] = [#(#corners),*];
            /// Tendons per module.
            pub const TENDONS: [usize; N_MODULES] = [#(#tendons),*];
            /// Every barrier, in the order of the barrier arrays (module and point 0-based).
            pub const BARRIERS: [BarrierInfo; NB] = [#(#barrier_table),*];
            #(#analytic_functions)*
            #(#functions)*
            #plate_poses
        };
        let mut header = format!(
            "// Generated by softcbf-codegen from {source_label}; do not edit by hand.\n\
             // Regenerate: cargo run -p softcbf-codegen -- --robot {source_label} --out FILE.rs\n\
             // Structure: {n_modules} modules, corners {:?}, tendons {:?}, routing {:?}.\n\
             // Operations per call (add, mul, div, sqrt/trig, analytic):\n",
            self.structure.corners, self.structure.tendons, self.structure.routing
        );
        {
            let corners: usize = self.structure.corners.iter().sum();
            let watched: usize = self.structure.obstacles.iter().map(|o| o.watch.len()).sum();
            let at = header.find("// Operations").unwrap_or(header.len());
            header.insert_str(
                at,
                &format!(
                    "// Barriers: {} ({corners} plate corners, {} limits: 3 per module, \
                     {watched} obstacle points).\n",
                    self.barriers.len(),
                    3 * n_modules,
                ),
            );
        }
        for (name, count) in &ops {
            header.push_str(&format!(
                "//   {name}: {} ({}, {}, {}, {}, {})\n",
                count.total(),
                count.add,
                count.mul,
                count.div,
                count.special,
                count.analytic
            ));
        }
        header.push('\n');
        GeneratedSource {
            text: header + &format_file(tokens),
            ops,
        }
    }
}

/// Generates the model source for a structure in one call.
pub fn generate(structure: &Structure, source_label: &str) -> GeneratedSource {
    build(structure).emit(source_label)
}
