//! The barrier kinds beyond the plate corners (issue 12: elongation and bend limits,
//! half-space and sphere obstacles on plate and backbone points) in the generated
//! `every_barrier` model, against jets, closed forms in θ and φ, central differences and a
//! numerically integrated backbone; and its barrier table against the one barrier list.

use rand::RngExt;
use softcbf::model::Model;
use softcbf_codegen::analytic::SWITCH_POINTS;
use softcbf_codegen::registry::every_barrier;
use softcbf_description::barriers::{
    BarrierKind, KindGroup, LimitFlags, Limits, Obstacle, Point, Shape, Watched, WatchedPoint,
    barrier_list,
};
use softcbf_description::layout::pack_params;
use softcbf_description::robot::Robot;
use softcbf_tests::TestRng;
use softcbf_tests::reference::{
    self, Jet, Vec3, all_barrier_values_closed_form, all_barriers, arc_point_integrated,
    plate_poses_closed_form, sample_module, sample_theta, watched_point_closed_form,
};

/// Coordinates of the two-module `every_barrier` structure.
const NQ: usize = 6;

/// Central-difference step along a coordinate or along `q̇` (coordinates are ~0.01–0.1 m,
/// velocities ≤ 0.2 m/s). The differences at `2h` and `h` are extrapolated (Richardson):
/// the `h²/6·b'''` term cancels (it reaches 2e-7 of `J` for a point near the sphere's
/// centre, where `b''' ~ 1/|x − c|²`), the `h⁴` term is negligible, and rounding
/// `(5/3)·ε|b|/h` ≈ 1e-10.
const STEP: f64 = 1e-6;

/// Step of the second differences of `b` along `q̇`, extrapolated from `2h` and `h`
/// (Richardson): the `h²/12·d⁴b/dt⁴` term cancels (it reaches 1e-5 of `J̇q̇` for a point
/// near the sphere's centre, where `d⁴b/dt⁴ ~ |ẋ|⁴/|x − c|³`), the `h⁴` term is ≈ 1e-16
/// of the derivatives' scale, and rounding `(5/3)·4ε|b|/h²` ≈ 1.5e-7·|b|.
const STEP2: f64 = 1e-4;

/// Arc fractions of the half-space's backbone points: `[module 1, module 2]`, two each.
const HALF_SPACE_ARCS: [[f64; 2]; 2] = [[0.3, 1.0], [0.3, 1.0]];
/// Arc fractions of the sphere's backbone points.
const SPHERE_ARCS: [[f64; 2]; 2] = [[0.55, 1.0], [0.8, 1.0]];

/// Watched points per module and obstacle, in `every_barrier`'s order: corner 3, the
/// centre, one listed point, two arc points.
const PER_MODULE: usize = 5;
/// Slots of the two arc points among a module's watched points.
const ARC_SLOTS: [usize; 2] = [3, 4];

/// The paper robot with a second, different module (a mix-up of module numbers shows),
/// limits on both modules and a half-space and a sphere watching every kind of point of
/// both modules: the structure of `every_barrier`, with numbers nowhere special.
fn robot() -> Robot {
    let mut robot = reference::two_different_modules();
    robot.limits = vec![
        Limits {
            elongation: [-0.05, 0.03],
            elongation_margin: 0.004,
            max_bend: 2.5,
            bend_margin: 0.1,
            gains: [Some(8.0), None],
            written: LimitFlags {
                elongation: true,
                bend: true,
            },
            elongation_rate: 1.0,
        },
        Limits {
            elongation: [-0.04, 0.035],
            elongation_margin: 0.003,
            max_bend: 2.2,
            bend_margin: 0.05,
            gains: [None, None],
            written: LimitFlags {
                elongation: true,
                bend: true,
            },
            elongation_rate: 1.0,
        },
    ];
    let norm = (0.3f64 * 0.3 + 0.5 * 0.5 + 0.8 * 0.8).sqrt();
    let normal = [0.3 / norm, -0.5 / norm, 0.8 / norm];
    let listed = [[0.02, -0.03, 0.015], [-0.025, 0.01, -0.02]];
    let watch = |arcs: [[f64; 2]; 2]| -> Vec<Watched> {
        (0..2)
            .flat_map(|i| {
                [
                    WatchedPoint::Corner(2),
                    WatchedPoint::Centre,
                    WatchedPoint::Listed(listed[i]),
                    WatchedPoint::Arc(arcs[i][0]),
                    WatchedPoint::Arc(arcs[i][1]),
                ]
                .map(|point| Watched { module: i, point })
            })
            .collect()
    };
    robot.obstacles = vec![
        Obstacle {
            shape: Shape::HalfSpace {
                normal,
                offset: 0.02,
            },
            margin: 0.005,
            gains: [None, Some(6.0)],
            watch: watch(HALF_SPACE_ARCS),
        },
        Obstacle {
            shape: Shape::Sphere {
                center: [0.07, -0.04, 0.17],
                radius: 0.035,
            },
            margin: 0.01,
            gains: [None, None],
            watch: watch(SPHERE_ARCS),
        },
    ];
    robot
}

fn model_of(robot: Robot) -> Model {
    let model = Model::new(robot).expect("every_barrier is generated");
    assert_eq!(model.generated.name(), "every_barrier");
    model
}

/// Switch points in `u = θ²` of the generated `f_s`, `f_c` at the derivative orders `b`,
/// `J`, `J̇q̇` use (0–2: θ = 0.31, 2.45, 3.46 rad) and, for the backbone points at `s < 1`
/// (which evaluate them at `s² u`), where `s² u` crosses them with `θ ≤ 3` rad.
fn switch_points() -> Vec<f64> {
    let used = &SWITCH_POINTS[..3];
    let mut points = used.to_vec();
    for &s in HALF_SPACE_ARCS.iter().chain(&SPHERE_ARCS).flatten() {
        for u in used.iter().map(|u| u / (s * s)) {
            if u <= 9.0 && !points.contains(&u) {
                points.push(u);
            }
        }
    }
    points
}

/// A random state of both modules, bends from the mixture of `sample_theta` (exactly 0,
/// subnormal, tiny, at every switch point, up to 3 rad), and a random velocity.
fn sample_state(rng: &mut TestRng, robot: &Robot, switch: &[f64]) -> ([f64; NQ], [f64; NQ]) {
    let mut q = [0.0; NQ];
    for (i, module) in robot.modules.iter().enumerate() {
        let theta = sample_theta(rng, switch);
        q[3 * i..3 * i + 3].copy_from_slice(&sample_module(rng, module, theta));
    }
    let qd = std::array::from_fn(|_| rng.random_range(-0.2..0.2));
    (q, qd)
}

/// `b`, `J` (row-major `nb × nq`) and `J̇q̇` from the model's generated `barrier_terms`.
struct Terms {
    b: Vec<f64>,
    jacobian: Vec<f64>,
    jdot_qd: Vec<f64>,
}

fn terms(model: &Model, p: &[f64], q: &[f64], qd: &[f64]) -> Terms {
    let nb = model.generated.nb();
    let mut t = Terms {
        b: vec![0.0; nb],
        jacobian: vec![0.0; nb * NQ],
        jdot_qd: vec![0.0; nb],
    };
    model
        .generated
        .barrier_terms(p, q, qd, &mut t.b, &mut t.jacobian, &mut t.jdot_qd);
    t
}

fn values(model: &Model, p: &[f64], q: &[f64]) -> Vec<f64> {
    let mut b = vec![0.0; model.generated.nb()];
    model.generated.barriers(p, q, &mut b);
    b
}

fn shifted(q: &[f64; NQ], dir: &[f64; NQ], h: f64) -> [f64; NQ] {
    std::array::from_fn(|k| q[k] + h * dir[k])
}

/// The groups of the table's rows, and per group the largest `|x|` of `part` over its rows:
/// the scale the bounds are relative to (limits in rad and obstacles in m have their own).
fn group_scale(model: &Model, rows: impl Fn(usize) -> f64) -> impl Fn(usize) -> f64 {
    let table = model.generated.barrier_table();
    let groups: Vec<KindGroup> = table.iter().map(|b| b.kind.group()).collect();
    let mut scale = std::collections::HashMap::new();
    for (r, g) in groups.iter().enumerate() {
        let s: &mut f64 = scale.entry(*g).or_insert(0.0);
        *s = s.max(rows(r).abs());
    }
    move |r| scale[&groups[r]]
}

/// `(4 D(h) − D(2h))/3`: the central difference `D` with its `h²` error term removed.
fn richardson(coarse: f64, fine: f64) -> f64 {
    (4.0 * fine - coarse) / 3.0
}

/// The size of the terms a barrier's value is a difference of, where it exceeds `|b|`:
/// `θ_b` for a bend limit (`b = θ_b/2 − θ²/(2θ_b)` cancels near the limit), 0 otherwise.
fn term_sizes(model: &Model) -> Vec<f64> {
    model
        .generated
        .barrier_table()
        .iter()
        .map(|info| match (info.kind, &model.robot.limits[info.module]) {
            (BarrierKind::Bend, limits) => limits.max_bend - limits.bend_margin,
            _ => 0.0,
        })
        .collect()
}

/// The docs/model.md §8 acceptance bound `|got − exact| ≤ 1e-12·s + 1e-9·|exact|`, as a
/// ratio (≤ 1 passes).
fn bound_ratio(got: f64, exact: f64, s: f64) -> f64 {
    let err = (got - exact).abs();
    if err == 0.0 {
        0.0
    } else {
        err / (1e-12 * s + 1e-9 * exact.abs())
    }
}

/// Tracks the worst ratio of a check and where it happened.
#[derive(Default)]
struct Worst(f64, String);

impl Worst {
    fn see(&mut self, ratio: f64, at: impl FnOnce() -> String) {
        if ratio > self.0 || ratio.is_nan() {
            *self = Worst(ratio, at());
        }
    }
}

/// The robot built here has `every_barrier`'s structure, `Model::new` finds that model,
/// and moving an obstacle or changing a limit is a number: the same structure key and
/// model, and only the barriers reading that number change (by the change, for a limit).
#[test]
fn robot_in_code_is_every_barrier() {
    let robot = robot();
    assert_eq!(robot.structure(), every_barrier());
    let key = robot.structure().key();
    let model = model_of(robot.clone());
    assert_eq!(model.generated.structure_key(), key);
    assert_eq!(model.params, pack_params(&robot));
    let table = model.generated.barrier_table();
    let q = [0.011, -0.007, 0.013, -0.004, 0.009, -0.021];
    let before = values(&model, &model.params, &q);

    let mut moved_sphere = robot.clone();
    moved_sphere.obstacles[1].shape = Shape::Sphere {
        center: [0.09, -0.03, 0.15],
        radius: 0.035,
    };
    let tighter = robot_with_limit();
    let mut other_arc = robot.clone();
    other_arc.obstacles[0].watch[PER_MODULE + ARC_SLOTS[0]].point = WatchedPoint::Arc(0.45);
    let mut flatter = robot.clone();
    flatter.limits[0].max_bend = 2.0;

    // What changed, the changed robot, and which rows read the changed number.
    type Change<'a> = (&'a str, Robot, &'a dyn Fn(usize) -> bool);
    let changes: [Change; 4] = [
        ("sphere centre", moved_sphere, &|r| {
            table[r].kind == BarrierKind::Sphere
        }),
        ("module 2 elongation", tighter, &|r| {
            table[r].module == 1 && table[r].kind.group() == KindGroup::Elongation
        }),
        ("an arc fraction", other_arc, &|r| {
            table[r].obstacle == Some(0)
                && table[r].point == Some(Point::Arc(PER_MODULE + ARC_SLOTS[0]))
        }),
        ("module 1 bend limit", flatter, &|r| {
            table[r].module == 0 && table[r].kind == BarrierKind::Bend
        }),
    ];
    for (what, changed, affected) in changes {
        assert_eq!(changed.structure().key(), key, "{what}: structure changed");
        let changed = model_of(changed);
        let after = values(&changed, &changed.params, &q);
        let mut seen = 0;
        for r in 0..table.len() {
            if affected(r) {
                seen += 1;
                assert_ne!(after[r], before[r], "{what}: {} unchanged", table[r].label);
            } else {
                assert_eq!(after[r], before[r], "{what}: {} changed", table[r].label);
            }
        }
        assert!(seen > 0, "{what}: no barrier reads it");
    }
    // A limit enters its barriers linearly: δL_min up by 0.01 lowers b_min by 0.01, δL_max
    // down by 0.015 lowers b_max by 0.015.
    let tighter = model_of(robot_with_limit());
    let after = values(&tighter, &tighter.params, &q);
    for (r, info) in table.iter().enumerate() {
        let shift = match (info.module, info.kind) {
            (1, BarrierKind::ElongationMin) => -0.01,
            (1, BarrierKind::ElongationMax) => -0.015,
            _ => 0.0,
        };
        assert!(
            (after[r] - (before[r] + shift)).abs() <= 1e-16,
            "{}: {} instead of {}",
            info.label,
            after[r],
            before[r] + shift
        );
    }
}

/// [`robot`] with module 2's elongation limits at `[−0.03, 0.02]`.
fn robot_with_limit() -> Robot {
    let mut r = robot();
    r.limits[1].elongation = [-0.03, 0.02];
    r
}

/// Every barrier's `b`, `J` and `J̇q̇` at 10 000 random states: against the jets of the
/// reference (to the docs/model.md §8 bound, per kind group), against central differences
/// of `b` (J) and of `J q̇` along `q̇` and second differences of `b` along `q̇` (J̇q̇); the
/// Jacobian row zero past the barrier's module; the elongation barriers' `J = ±e_δL` and
/// `J̇q̇ = 0` exactly (they are linear in `q`); `barriers`, `barrier_terms` and
/// `model_terms` agreeing bit for bit.
#[test]
fn barrier_terms_against_jets_and_finite_differences() {
    let robot = robot();
    let model = model_of(robot.clone());
    let p = model.params.clone();
    let table = model.generated.barrier_table();
    let nb = table.len();
    let switch = switch_points();
    let mut rng = softcbf_tests::rng(0x5eed_1201);
    let (mut worst_b, mut worst_j, mut worst_jd) =
        (Worst::default(), Worst::default(), Worst::default());
    let (mut worst_fd_j, mut worst_fd_jd, mut worst_fd2) =
        (Worst::default(), Worst::default(), Worst::default());
    let mut workspace = ModelTermsOut::new(nb);
    let terms_size = term_sizes(&model);
    let mut near_centre = 0;
    for trial in 0..10_000 {
        let (q, qd) = sample_state(&mut rng, &robot, &switch);
        let t = terms(&model, &p, &q, &qd);
        let exact: Vec<Jet<NQ>> = all_barriers(&robot, &q, &qd);
        assert_eq!(exact.len(), nb, "reference and table disagree on the count");
        let s_b = group_scale(&model, |r| exact[r].v.abs().max(terms_size[r]));
        let s_j = group_scale(&model, |r| {
            exact[r].g.iter().fold(0.0_f64, |m, v| m.max(v.abs()))
        });
        let s_jd = group_scale(&model, |r| exact[r].dd);
        let qd_max = qd.iter().fold(0.0_f64, |m, v| m.max(v.abs()));

        // Bit for bit: barriers, and model_terms' barrier part.
        let plain = values(&model, &p, &q);
        workspace.eval(&model, &p, &q, &qd);
        let ctx = |r: usize| {
            format!(
                "trial {trial}, {} (row {r}), q = {q:?}, qd = {qd:?}",
                table[r].label
            )
        };
        for (r, value) in plain.iter().enumerate() {
            assert!(
                value.to_bits() == t.b[r].to_bits(),
                "{}: barriers {value:e} vs barrier_terms {:e}",
                ctx(r),
                t.b[r]
            );
            assert!(
                workspace.b[r].to_bits() == t.b[r].to_bits()
                    && workspace.jdot_qd[r].to_bits() == t.jdot_qd[r].to_bits(),
                "{}: model_terms differs from barrier_terms",
                ctx(r)
            );
        }
        assert!(
            workspace
                .jacobian
                .iter()
                .zip(&t.jacobian)
                .all(|(x, y)| x.to_bits() == y.to_bits()),
            "trial {trial}: model_terms' Jacobian differs from barrier_terms'"
        );

        // Central differences of b along each coordinate and of J q̇ along q̇, at steps 2h
        // and h, extrapolated (see STEP).
        let mut fd_jac = vec![0.0; nb * NQ];
        for k in 0..NQ {
            let mut e = [0.0; NQ];
            e[k] = 1.0;
            let central = |h: f64| {
                let plus = values(&model, &p, &shifted(&q, &e, h));
                let minus = values(&model, &p, &shifted(&q, &e, -h));
                move |r: usize| (plus[r] - minus[r]) / (2.0 * h)
            };
            let (coarse, fine) = (central(2.0 * STEP), central(STEP));
            for r in 0..nb {
                fd_jac[r * NQ + k] = richardson(coarse(r), fine(r));
            }
        }
        let jqd_central = |h: f64| {
            let plus = terms(&model, &p, &shifted(&q, &qd, h), &qd).jacobian;
            let minus = terms(&model, &p, &shifted(&q, &qd, -h), &qd).jacobian;
            move |r: usize| {
                (0..NQ)
                    .map(|k| (plus[r * NQ + k] - minus[r * NQ + k]) * qd[k])
                    .sum::<f64>()
                    / (2.0 * h)
            }
        };
        let (jqd_coarse, jqd_fine) = (jqd_central(2.0 * STEP), jqd_central(STEP));
        // Second differences of b along q̇ at steps 2h and h.
        let second_difference = |h: f64| -> Vec<f64> {
            let plus = values(&model, &p, &shifted(&q, &qd, h));
            let minus = values(&model, &p, &shifted(&q, &qd, -h));
            (0..nb)
                .map(|r| (plus[r] - 2.0 * t.b[r] + minus[r]) / (h * h))
                .collect()
        };
        let (coarse, fine) = (second_difference(2.0 * STEP2), second_difference(STEP2));

        for r in 0..nb {
            let info = &table[r];
            let row = &t.jacobian[r * NQ..(r + 1) * NQ];
            // Within 1 cm of a sphere's centre (2.5 cm deep inside it) the derivatives of
            // |x − c| grow as |ẋ|ⁿ/|x − c|ⁿ⁻¹ and so do the difference quotients' h⁴ terms
            // (1e-6 of J̇q̇ at 3 mm): there the jets alone check the row.
            let smooth = match (info.kind, info.obstacle.map(|o| &robot.obstacles[o])) {
                (BarrierKind::Sphere, Some(obstacle)) => match obstacle.shape {
                    Shape::Sphere { radius, .. } => exact[r].v + radius + obstacle.margin > 0.01,
                    Shape::HalfSpace { .. } => true,
                },
                _ => true,
            };
            near_centre += usize::from(!smooth);
            worst_b.see(bound_ratio(t.b[r], exact[r].v, s_b(r)), || ctx(r));
            assert!(
                bound_ratio(t.b[r], exact[r].v, s_b(r)) <= 1.0,
                "{}: b = {:e}, reference {:e}",
                ctx(r),
                t.b[r],
                exact[r].v
            );
            for k in 0..NQ {
                let ratio = bound_ratio(row[k], exact[r].g[k], s_j(r));
                worst_j.see(ratio, || format!("J[{k}] at {}", ctx(r)));
                assert!(
                    ratio <= 1.0,
                    "{}: J[{k}] = {:e}, reference {:e}",
                    ctx(r),
                    row[k],
                    exact[r].g[k]
                );
                if smooth {
                    // Truncation ≲ 1e-9·s_j; rounding ≈ 2ε|b|/(2h) ≤ 1e-14·s_b/h.
                    let tol = 1e-7 * s_j(r) + 1e-14 * s_b(r) / STEP;
                    let err = (fd_jac[r * NQ + k] - row[k]).abs();
                    worst_fd_j.see(err / tol, || format!("J[{k}] at {}", ctx(r)));
                    assert!(
                        err <= tol,
                        "{}: J[{k}] = {:e}, central difference {:e}",
                        ctx(r),
                        row[k],
                        fd_jac[r * NQ + k]
                    );
                }
                if k >= 3 * (info.module + 1) {
                    assert!(
                        row[k] == 0.0,
                        "{}: J[{k}] = {:e} past its module",
                        ctx(r),
                        row[k]
                    );
                }
            }
            let ratio = bound_ratio(t.jdot_qd[r], exact[r].dd, s_jd(r));
            worst_jd.see(ratio, || ctx(r));
            assert!(
                ratio <= 1.0,
                "{}: J̇q̇ = {:e}, reference {:e}",
                ctx(r),
                t.jdot_qd[r],
                exact[r].dd
            );
            if smooth {
                // d/dt (J q̇) along q̇: rounding floor ≈ (5/3)·ε·|J|·|q̇|·nq/h ≤ 1e-9·s_j·|q̇|.
                let fd = richardson(jqd_coarse(r), jqd_fine(r));
                let tol = 1e-5 * s_jd(r) + 1e-9 * s_j(r) * qd_max;
                worst_fd_jd.see((fd - t.jdot_qd[r]).abs() / tol, || ctx(r));
                assert!(
                    (fd - t.jdot_qd[r]).abs() <= tol,
                    "{}: J̇q̇ = {:e}, central difference of J q̇ {fd:e}",
                    ctx(r),
                    t.jdot_qd[r]
                );
                // q̇ᵀ∇²b q̇ = d²/dt² b(q + t q̇), Richardson-extrapolated (see STEP2).
                let second = richardson(coarse[r], fine[r]);
                let tol = 1e-6 * s_jd(r) + 1e-6 * s_b(r);
                worst_fd2.see((second - t.jdot_qd[r]).abs() / tol, || ctx(r));
                assert!(
                    (second - t.jdot_qd[r]).abs() <= tol,
                    "{}: J̇q̇ = {:e}, second difference of b {second:e}",
                    ctx(r),
                    t.jdot_qd[r]
                );
            }
            // Linear in δL: the exact constants, whatever the state.
            let sign = match info.kind {
                BarrierKind::ElongationMin => Some(1.0),
                BarrierKind::ElongationMax => Some(-1.0),
                _ => None,
            };
            if let Some(sign) = sign {
                let mut want = [0.0; NQ];
                want[3 * info.module + 2] = sign;
                assert_eq!(row, want, "{}: elongation J", ctx(r));
                assert!(t.jdot_qd[r] == 0.0, "{}: elongation J̇q̇", ctx(r));
            }
        }
    }
    for (what, w) in [
        ("b vs jets", &worst_b),
        ("J vs jets", &worst_j),
        ("J̇q̇ vs jets", &worst_jd),
        ("J vs central differences", &worst_fd_j),
        ("J̇q̇ vs differences of J q̇", &worst_fd_jd),
        ("J̇q̇ vs second differences of b", &worst_fd2),
    ] {
        eprintln!("{what}: worst {:.2e} of the bound ({})", w.0, w.1);
    }
    eprintln!("rows within 1 cm of the sphere's centre (jets only): {near_centre}");
}

/// `model_terms`' outputs, allocated once.
struct ModelTermsOut {
    rotation: Vec<[[f64; 3]; 3]>,
    translation: Vec<[f64; 3]>,
    motion_subspace: Vec<[[f64; 3]; 6]>,
    bias: Vec<[f64; 6]>,
    b: Vec<f64>,
    jacobian: Vec<f64>,
    jdot_qd: Vec<f64>,
}

impl ModelTermsOut {
    fn new(nb: usize) -> Self {
        ModelTermsOut {
            rotation: vec![[[0.0; 3]; 3]; 2],
            translation: vec![[0.0; 3]; 2],
            motion_subspace: vec![[[0.0; 3]; 6]; 2],
            bias: vec![[0.0; 6]; 2],
            b: vec![0.0; nb],
            jacobian: vec![0.0; nb * NQ],
            jdot_qd: vec![0.0; nb],
        }
    }

    fn eval(&mut self, model: &Model, p: &[f64], q: &[f64], qd: &[f64]) {
        model.generated.model_terms(
            p,
            q,
            qd,
            &mut self.rotation,
            &mut self.translation,
            &mut self.motion_subspace,
            &mut self.bias,
            &mut self.b,
            &mut self.jacobian,
            &mut self.jdot_qd,
        );
    }
}

/// Every barrier's value against the plain closed forms in the bend angle θ and direction
/// φ (sin/cos, no `f_s`, `f_c`, no jets) at 20 000 random states: within a few ulp of each
/// group's scale (1e-14·s, ≈ 50 ulp of the largest value, for the products of up to two
/// segment transforms and a square root).
#[test]
fn barrier_values_against_closed_forms() {
    let robot = robot();
    let model = model_of(robot.clone());
    let table = model.generated.barrier_table();
    let switch = switch_points();
    let mut rng = softcbf_tests::rng(0x5eed_1202);
    let mut worst = Worst::default();
    let terms_size = term_sizes(&model);
    for trial in 0..20_000 {
        let (q, _) = sample_state(&mut rng, &robot, &switch);
        let b = values(&model, &model.params, &q);
        let plain = all_barrier_values_closed_form(&robot, &q);
        assert_eq!(plain.len(), b.len());
        let s = group_scale(&model, |r| plain[r].abs().max(terms_size[r]));
        for r in 0..b.len() {
            let tol = 1e-14 * s(r);
            let err = (b[r] - plain[r]).abs();
            worst.see(err / tol, || {
                format!("trial {trial}, {}, q = {q:?}", table[r].label)
            });
            assert!(
                err <= tol,
                "trial {trial}, {}: b = {:e}, closed form {:e}, q = {q:?}",
                table[r].label,
                b[r],
                plain[r]
            );
        }
    }
    eprintln!(
        "closed forms: worst {:.2e} of the bound ({})",
        worst.0, worst.1
    );
}

/// The generated world position of a watched point: the half-space's barrier at slot
/// `slot` of its watch list with `point` put there (the same kind of point, so the same
/// model), normal `e_c`, offset and margin 0, is `x_c`.
fn generated_point(model: &Model, q: &[f64], slot: usize, point: WatchedPoint) -> Vec3<f64> {
    let table = model.generated.barrier_table();
    let first = table
        .iter()
        .position(|b| b.obstacle == Some(0))
        .expect("the half-space has barriers");
    let mut probe = model.robot.clone();
    let obstacle = &mut probe.obstacles[0];
    assert_eq!(obstacle.watch[slot].point.shape(), point.shape());
    obstacle.watch[slot].point = point;
    obstacle.margin = 0.0;
    std::array::from_fn(|c| {
        let mut normal = [0.0; 3];
        normal[c] = 1.0;
        probe.obstacles[0].shape = Shape::HalfSpace {
            normal,
            offset: 0.0,
        };
        values(model, &pack_params(&probe), q)[first + slot]
    })
}

fn distance(x: &Vec3<f64>, y: &Vec3<f64>) -> f64 {
    (0..3).map(|c| (x[c] - y[c]).powi(2)).sum::<f64>().sqrt()
}

fn plate_origins(model: &Model, q: &[f64]) -> Vec<Vec3<f64>> {
    let mut poses = vec![[[0.0; 4]; 4]; 2];
    model.generated.plate_poses(&model.params, q, &mut poses);
    poses.iter().map(|w| [w[0][3], w[1][3], w[2][3]]).collect()
}

/// The backbone point at `s = 1` is the top plate's origin (`plate_poses`): in the
/// generated code (read through the half-space), in the closed form, and as barriers:
/// the arc-at-1 barriers equal the centre barriers of the same obstacle and module, with
/// their `J` and `J̇q̇`.
#[test]
fn arc_point_at_one_is_the_plate_origin() {
    let robot = robot();
    let model = model_of(robot.clone());
    let table = model.generated.barrier_table();
    let switch = switch_points();
    let mut rng = softcbf_tests::rng(0x5eed_1203);
    let mut worst = 0.0_f64;
    for trial in 0..2000 {
        let (q, qd) = sample_state(&mut rng, &robot, &switch);
        let origins = plate_origins(&model, &q);
        let closed = plate_poses_closed_form(&robot, &q);
        let t = terms(&model, &model.params, &q, &qd);
        for i in 0..2usize {
            let slot = PER_MODULE * i + ARC_SLOTS[1];
            let arc = WatchedPoint::Arc(1.0);
            let generated = generated_point(&model, &q, slot, arc);
            let plain = watched_point_closed_form(&robot, &q, i, &arc);
            // Positions ≤ 0.5 m: a few ulp (1.1e-16 at 0.5) through two transforms.
            let e1 = distance(&generated, &origins[i]);
            let e2 = distance(&plain, &closed[i].1);
            worst = worst.max(e1);
            assert!(
                e1 <= 1e-15,
                "trial {trial}, module {}: {generated:?} vs plate {:?}",
                i + 1,
                origins[i]
            );
            assert!(
                e2 <= 1e-15,
                "trial {trial}, module {}: closed form {plain:?} vs {:?}",
                i + 1,
                closed[i].1
            );
            for o in 0..2 {
                let row = |point: Point| {
                    table
                        .iter()
                        .position(|b| {
                            b.obstacle == Some(o) && b.module == i && b.point == Some(point)
                        })
                        .expect("the table has the row")
                };
                let (arc_row, centre_row) = (row(Point::Arc(slot)), row(Point::Centre));
                let scale = t.jacobian[centre_row * NQ..(centre_row + 1) * NQ]
                    .iter()
                    .fold(t.b[centre_row].abs(), |m, v| m.max(v.abs()));
                let close = |x: f64, y: f64| (x - y).abs() <= 1e-14 * (scale + y.abs());
                assert!(close(t.b[arc_row], t.b[centre_row]), "trial {trial}: b");
                assert!(
                    close(t.jdot_qd[arc_row], t.jdot_qd[centre_row]),
                    "trial {trial}, obstacle {o}, module {i}: J̇q̇ {:e} vs {:e}",
                    t.jdot_qd[arc_row],
                    t.jdot_qd[centre_row]
                );
                for k in 0..NQ {
                    assert!(
                        close(
                            t.jacobian[arc_row * NQ + k],
                            t.jacobian[centre_row * NQ + k]
                        ),
                        "trial {trial}, obstacle {o}, module {i}: J[{k}]"
                    );
                }
            }
        }
    }
    eprintln!("arc at s = 1: worst distance to the plate origin {worst:.2e} m");
}

/// As `s → 0` the backbone point comes to the segment's base (the plate below, or the
/// world origin for module 1): within the arc length `s L`, along the base's z axis (the
/// tangent) to `sθ/2 + 1e-5` (rounding of `x − base` at `s L ≈ 1e-10` m); at `s = 1e-300`
/// on the base to rounding.
#[test]
fn arc_point_near_zero_is_the_segment_base() {
    let robot = robot();
    let model = model_of(robot.clone());
    let switch = switch_points();
    let mut rng = softcbf_tests::rng(0x5eed_1204);
    for trial in 0..2000 {
        let (q, _) = sample_state(&mut rng, &robot, &switch);
        let mut poses = vec![[[0.0; 4]; 4]; 2];
        model.generated.plate_poses(&model.params, &q, &mut poses);
        for i in 0..2usize {
            let (base, axis) = match i.checked_sub(1) {
                None => ([0.0; 3], [0.0, 0.0, 1.0]),
                Some(b) => (
                    [poses[b][0][3], poses[b][1][3], poses[b][2][3]],
                    [poses[b][0][2], poses[b][1][2], poses[b][2][2]],
                ),
            };
            let module = &robot.modules[i];
            let length = module.rest_length + q[3 * i + 2];
            let (theta, _) =
                reference::bend_angle_direction(module, [q[3 * i], q[3 * i + 1], q[3 * i + 2]]);
            for slot in ARC_SLOTS.map(|k| PER_MODULE * i + k) {
                let s = 1e-9;
                let x = generated_point(&model, &q, slot, WatchedPoint::Arc(s));
                let d = distance(&x, &base);
                assert!(
                    d <= s * length * (1.0 + 1e-6) + 1e-15,
                    "trial {trial}, module {}: |x − base| = {d:e}, s L = {:e}",
                    i + 1,
                    s * length
                );
                let direction: Vec3<f64> = std::array::from_fn(|c| (x[c] - base[c]) / (s * length));
                let off = distance(&direction, &axis);
                assert!(
                    off <= 0.5 * s * theta + 1e-5,
                    "trial {trial}, module {}: chord direction {direction:?} vs tangent {axis:?}",
                    i + 1
                );
                let x = generated_point(&model, &q, slot, WatchedPoint::Arc(1e-300));
                assert!(
                    distance(&x, &base) <= 1e-15,
                    "trial {trial}, module {}: s = 1e-300 gives {x:?}, base {base:?}",
                    i + 1
                );
            }
        }
    }
}

/// At intermediate `s` the backbone point equals the integral of the tangent
/// `dp/dσ = R(σ) e_z` (Simpson, 4000 intervals: error `< sL (sθ/4000)⁴/180 < 1e-17` m),
/// placed in the world by the closed-form pose of the plate below: the generated point
/// (read through the half-space), the closed form and the jets, to 2e-15 m (a few ulp of
/// positions below 0.5 m; the quadrature's sums are compensated).
#[test]
fn arc_point_against_integrated_arc() {
    let robot = robot();
    let model = model_of(robot.clone());
    let switch = switch_points();
    let mut rng = softcbf_tests::rng(0x5eed_1205);
    let mut worst = 0.0_f64;
    for trial in 0..2000 {
        let (q, qd) = sample_state(&mut rng, &robot, &switch);
        let poses = plate_poses_closed_form(&robot, &q);
        let kinematics = reference::chain(&robot, &q, &qd);
        for i in 0..2usize {
            let module = &robot.modules[i];
            let qi = [q[3 * i], q[3 * i + 1], q[3 * i + 2]];
            let s = match trial % 4 {
                0 => 0.3,
                1 => 0.5,
                _ => rng.random_range(1e-3..1.0),
            };
            let local = arc_point_integrated(module, qi, s, 4000);
            let integrated = match i.checked_sub(1) {
                None => local,
                Some(b) => {
                    let (r, t) = &poses[b];
                    std::array::from_fn(|c| reference::dot(&r[c], &local) + t[c])
                }
            };
            let arc = WatchedPoint::Arc(s);
            let generated = generated_point(&model, &q, PER_MODULE * i + ARC_SLOTS[0], arc);
            let closed = watched_point_closed_form(&robot, &q, i, &arc);
            let [dx, dy, dl] = qi.map(Jet::<0>::constant);
            let jets_local = reference::arc_point(module, s, dx, dy, dl).map(|x| x.v);
            let jets_world: Vec3<f64> = match i.checked_sub(1) {
                None => jets_local,
                Some(b) => std::array::from_fn(|c| {
                    (0..3)
                        .map(|k| kinematics.world_rotation[b][c][k].v * jets_local[k])
                        .sum::<f64>()
                        + kinematics.world_position[b][c].v
                }),
            };
            for (what, x) in [
                ("generated", generated),
                ("closed form", closed),
                ("jets", jets_world),
            ] {
                let e = distance(&x, &integrated);
                worst = worst.max(e);
                assert!(
                    e <= 2e-15,
                    "trial {trial}, module {}, s = {s}: {what} {x:?} vs integrated {integrated:?}, q = {q:?}",
                    i + 1
                );
            }
        }
    }
    eprintln!("arc points vs the integrated arc: worst {worst:.2e} m");
}

/// The generated table is `barrier_list` of the structure, row by row; and the list is the
/// documented order and labels: 12 corners, then per module elongation min, max and bend,
/// then each obstacle's ten watched points.
#[test]
fn barrier_table_is_the_barrier_list() {
    let model = model_of(robot());
    let table = model.generated.barrier_table();
    let list = barrier_list(&every_barrier());
    assert_eq!(table.len(), list.len());
    for (r, (info, spec)) in table.iter().zip(&list).enumerate() {
        assert_eq!(info.kind, spec.kind, "row {r}");
        assert_eq!(info.module, spec.module, "row {r}");
        assert_eq!(info.point, spec.point, "row {r}");
        assert_eq!(info.obstacle, spec.obstacle, "row {r}");
        assert_eq!(info.label, spec.label, "row {r}");
    }
    assert_eq!(table.len(), 12 + 2 * 3 + 2 * 2 * PER_MODULE);
    let labels: Vec<&str> = table.iter().map(|b| b.label).collect();
    assert_eq!(labels[0], "module 1 corner 1");
    assert_eq!(labels[11], "module 2 corner 6");
    assert_eq!(
        labels[12..18],
        [
            "module 1 elongation min",
            "module 1 elongation max",
            "module 1 bend",
            "module 2 elongation min",
            "module 2 elongation max",
            "module 2 bend",
        ]
    );
    assert_eq!(
        labels[18..28],
        [
            "obstacle 1 module 1 corner 3",
            "obstacle 1 module 1 centre",
            "obstacle 1 module 1 point 1",
            "obstacle 1 module 1 arc 1",
            "obstacle 1 module 1 arc 2",
            "obstacle 1 module 2 corner 3",
            "obstacle 1 module 2 centre",
            "obstacle 1 module 2 point 1",
            "obstacle 1 module 2 arc 1",
            "obstacle 1 module 2 arc 2",
        ]
    );
    assert_eq!(labels[37], "obstacle 2 module 2 arc 2");
    assert!(
        table[18..28]
            .iter()
            .all(|b| b.kind == BarrierKind::HalfSpace && b.obstacle == Some(0))
    );
    assert!(
        table[28..]
            .iter()
            .all(|b| b.kind == BarrierKind::Sphere && b.obstacle == Some(1))
    );
    assert_eq!(table[20].point, Some(Point::Listed(2)));
    assert_eq!(table[22].point, Some(Point::Arc(4)));
    assert_eq!(table[26].point, Some(Point::Arc(8)));
}

/// Each row's `params` are exactly the parameters its value depends on: changing any
/// other one leaves `b` bit for bit, changing a listed one moves it (at a state where no
/// parameter's effect vanishes: both modules bent in general directions).
#[test]
fn barrier_params_are_those_it_reads() {
    let model = model_of(robot());
    let table = model.generated.barrier_table();
    let q = [0.021, -0.013, 0.011, -0.017, 0.024, -0.009];
    let before = values(&model, &model.params, &q);
    let np = model.params.len();
    for k in 0..np {
        let mut p = model.params.clone();
        p[k] += 1e-3 * (1.0 + p[k].abs());
        let after = values(&model, &p, &q);
        for (r, info) in table.iter().enumerate() {
            let listed = info.params.contains(&k);
            let moved = after[r].to_bits() != before[r].to_bits();
            assert_eq!(
                moved,
                listed,
                "{}: parameter {k} ({}) {} in params, and b {}",
                info.label,
                model.generated.param_names()[k],
                if listed { "is" } else { "is not" },
                if moved { "moves" } else { "does not move" }
            );
        }
    }
}
