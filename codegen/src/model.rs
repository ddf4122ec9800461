//! The robot model as symbolic expressions (docs/model.md §2–4): PCC kinematics, barriers
//! and joint terms of a structure. Structure decides the expressions; every number is a
//! parameter symbol, read from the parameter vector at run time. Its Rust source is
//! [`crate::source`]'s.

use crate::diff::{Differentiator, Tangent};
use crate::expr::{Arena, Id};
use crate::layout::{Param, param_layout};
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
pub(crate) struct ModuleExprs {
    /// `q_i = [Δx, Δy, δL]`.
    pub(crate) q: [Id; 3],
    /// `q̇_i`.
    pub(crate) qd: [Id; 3],
    /// Rotation of the tip frame in the segment base frame, rows.
    pub(crate) rotation: [[Id; 3]; 3],
    /// Position of the tip-frame origin in the segment base frame.
    pub(crate) translation: [Id; 3],
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
    pub(crate) arena: Arena,
    diff: Differentiator,
    /// Time derivative along `q̇` (with `q̈ = 0`).
    tangent: Tangent,
    pub(crate) modules: Vec<ModuleExprs>,
    /// Every barrier, in the order of the generated arrays.
    pub(crate) barriers: Vec<Barrier>,
    /// `(symbol, index)` of every parameter.
    pub(crate) params: Vec<(Id, usize)>,
    pub(crate) param_names: Vec<String>,
    pub(crate) structure: Structure,
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
}
