//! The 3-D shape of a robot at one state, from the generated kinematics (backbone arcs,
//! tendons, plates, every corner barrier's corner and its foot on the plate below, every
//! environment barrier's watched point), the obstacles, and the orthographic projection
//! and clipping for drawing.
//!
//! Points along a segment come from the generated `segment_transforms` evaluated with the
//! segment's rest length and coordinates scaled by the arc fraction `s` (docs/model.md §2:
//! the arc of bend `sθ` and length `sL`), so nothing here divides by `θ`.

use softcbf_description::barriers::Shape as Region;
use softcbf_description::layout::{Param, param_layout};

use crate::barrier_info;
use crate::model::Model;

/// A homogeneous transform, row-major (`[row][column]`), as the generated functions use.
pub(super) type Pose = [[f64; 4]; 4];
/// A point or direction in 3-D \[m\].
pub(super) type Point = [f64; 3];

/// Straight pieces each backbone arc and tendon is drawn with.
pub(super) const ARC_PIECES: usize = 16;

const IDENTITY: Pose = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

/// `a · b`.
pub(super) fn compose(a: &Pose, b: &Pose) -> Pose {
    std::array::from_fn(|r| std::array::from_fn(|c| (0..4).map(|k| a[r][k] * b[k][c]).sum()))
}

/// The point `p` (in the pose's frame) in the outer frame.
pub(super) fn apply(pose: &Pose, p: Point) -> Point {
    std::array::from_fn(|r| pose[r][0] * p[0] + pose[r][1] * p[1] + pose[r][2] * p[2] + pose[r][3])
}

/// The direction `v` (in the pose's frame) in the outer frame.
pub(super) fn rotate(pose: &Pose, v: Point) -> Point {
    std::array::from_fn(|r| pose[r][0] * v[0] + pose[r][1] * v[1] + pose[r][2] * v[2])
}

pub(super) fn dot(a: Point, b: Point) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(super) fn cross(a: Point, b: Point) -> Point {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `v / |v|`, or `None` for a zero or non-finite vector.
pub(super) fn normalized(v: Point) -> Option<Point> {
    let norm = dot(v, v).sqrt();
    (norm.is_finite() && norm > 0.0).then(|| v.map(|x| x / norm))
}

/// The generated segment transforms at arc fractions, with the parameter vector and
/// coordinates scaled in buffers kept between calls.
pub(super) struct Kinematics<'m> {
    model: &'m Model,
    /// Index of `L0_i` in the parameter vector, per module.
    rest_length: Vec<usize>,
    /// Each environment barrier's watched point (table order).
    watched: Vec<Option<WatchedAt>>,
    params: Vec<f64>,
    q: Vec<f64>,
    transforms: Vec<Pose>,
}

impl<'m> Kinematics<'m> {
    pub(super) fn new(model: &'m Model) -> Kinematics<'m> {
        let layout = param_layout(&model.robot.structure());
        let index = |wanted: Param| layout.iter().position(|&p| p == wanted);
        let rest_length = (0..model.n_modules())
            .map(|i| index(Param::RestLength(i)).unwrap_or(usize::MAX))
            .collect();
        let watched = (0..model.nb()).map(|k| watched_at(model, k)).collect();
        Kinematics {
            model,
            rest_length,
            watched,
            params: model.params.clone(),
            q: vec![0.0; model.nq()],
            transforms: vec![IDENTITY; model.n_modules()],
        }
    }

    /// `T_i(s)` of every segment, each in its base frame: the pose at arc fraction `s` of
    /// the state `q` (`q.len() == nq`, checked by the caller). `s = 1` is the segment
    /// transform itself, `s = 0` the identity.
    pub(super) fn segments_at(&mut self, q: &[f64], s: f64) -> &[Pose] {
        self.params.copy_from_slice(&self.model.params);
        for &k in &self.rest_length {
            if let Some(value) = self.params.get_mut(k) {
                *value *= s;
            }
        }
        for (scaled, &value) in self.q.iter_mut().zip(q) {
            *scaled = s * value;
        }
        self.model
            .generated
            .segment_transforms(&self.params, &self.q, &mut self.transforms);
        &self.transforms
    }

    /// World frames `W_{i−1} T_i(s)` of every module's backbone at arc fraction `s`.
    pub(super) fn frames_at(&mut self, q: &[f64], s: f64) -> Vec<Pose> {
        let bases = self.plate_poses(q);
        let segments = self.segments_at(q, s);
        bases
            .iter()
            .zip(segments)
            .map(|(base, segment)| compose(base, segment))
            .collect()
    }

    /// World poses of plates `0..=N` (plate 0 is the base: the identity).
    pub(super) fn plate_poses(&mut self, q: &[f64]) -> Vec<Pose> {
        let segments = self.segments_at(q, 1.0);
        let mut poses = vec![IDENTITY];
        for segment in segments {
            let last = poses[poses.len() - 1];
            poses.push(compose(&last, segment));
        }
        poses
    }

    /// The robot at state `q` (`q.len() == nq`, checked by the caller).
    pub(super) fn shape(&mut self, q: &[f64]) -> Shape {
        let model = self.model;
        let modules = &model.robot.modules;
        let poses = self.plate_poses(q);
        let mut backbones: Vec<Vec<Point>> = vec![Vec::new(); modules.len()];
        let mut tendons: Vec<Vec<Vec<Point>>> = modules
            .iter()
            .map(|m| vec![Vec::new(); m.tendon_angles.len()])
            .collect();
        for k in 0..=ARC_PIECES {
            let s = k as f64 / ARC_PIECES as f64;
            let segments = self.segments_at(q, s);
            for (i, module) in modules.iter().enumerate() {
                let frame = compose(&poses[i], &segments[i]);
                backbones[i].push(apply(&frame, [0.0; 3]));
                let d = module.tendon_radius;
                for (tendon, psi) in tendons[i].iter_mut().zip(&module.tendon_angles) {
                    tendon.push(apply(&frame, [d * psi.cos(), d * psi.sin(), 0.0]));
                }
            }
        }
        let polygon = |pose: &Pose, r: f64, angles: &[f64]| -> Vec<Point> {
            angles
                .iter()
                .map(|phi| apply(pose, [r * phi.cos(), r * phi.sin(), 0.0]))
                .collect()
        };
        let mut plates = Vec::with_capacity(modules.len() + 1);
        if let Some(first) = modules.first() {
            plates.push(polygon(
                &poses[0],
                first.corner_radius,
                &first.corner_angles,
            ));
        }
        for (module, pose) in modules.iter().zip(&poses[1..]) {
            plates.push(polygon(pose, module.corner_radius, &module.corner_angles));
        }
        let segments = self.segments_at(q, 1.0).to_vec();
        let corners = model
            .generated
            .barrier_table()
            .iter()
            .enumerate()
            .map(|(k, info)| {
                let corner = info.corner()?;
                let module = modules.get(info.module)?;
                let phi = *module.corner_angles.get(corner)?;
                let r = module.corner_radius;
                let local = apply(
                    segments.get(info.module)?,
                    [r * phi.cos(), r * phi.sin(), 0.0],
                );
                let base = poses.get(info.module)?;
                Some(CornerGap {
                    module: info.module,
                    corner: apply(base, local),
                    foot: apply(base, [local[0], local[1], 0.0]),
                    height: local[2],
                    margin: barrier_info::margin(model, k).unwrap_or(0.0),
                })
            })
            .collect();
        let mut watched = Vec::with_capacity(self.watched.len());
        for k in 0..self.watched.len() {
            let point = match self.watched[k] {
                Some(WatchedAt {
                    module,
                    obstacle,
                    plate: Some(local),
                    ..
                }) => poses.get(module + 1).map(|top| WatchedMark {
                    module,
                    obstacle,
                    at: apply(top, local),
                    arc: false,
                }),
                Some(WatchedAt {
                    module,
                    obstacle,
                    arc: Some(s),
                    ..
                }) => {
                    let segments = self.segments_at(q, s);
                    match (poses.get(module), segments.get(module)) {
                        (Some(base), Some(segment)) => Some(WatchedMark {
                            module,
                            obstacle,
                            at: apply(&compose(base, segment), [0.0; 3]),
                            arc: true,
                        }),
                        _ => None,
                    }
                }
                _ => None,
            };
            watched.push(point);
        }
        Shape {
            backbones,
            tendons,
            plates,
            corners,
            watched,
            poses,
        }
    }
}

/// What an environment barrier watches: a point fixed in its module's top plate, or on
/// its module's backbone at an arc fraction.
#[derive(Clone, Copy, Debug)]
struct WatchedAt {
    module: usize,
    obstacle: usize,
    /// The point in the top plate's frame \[m\].
    plate: Option<Point>,
    /// The arc fraction `s`.
    arc: Option<f64>,
}

/// The watched point of barrier `k`, if it is an environment barrier of a point the
/// robot's obstacles describe (its numbers from [`barrier_info`]).
fn watched_at(model: &Model, k: usize) -> Option<WatchedAt> {
    let info = barrier_info::info(model, k)?;
    let at = WatchedAt {
        module: info.module,
        obstacle: info.obstacle?,
        plate: barrier_info::plate_point(model, k),
        arc: barrier_info::arc_fraction(model, k),
    };
    (at.plate.is_some() || at.arc.is_some()).then_some(at)
}

/// Where an environment barrier's watched point is.
#[derive(Clone, Copy, Debug)]
pub(super) struct WatchedMark {
    /// The module (0-based) whose top plate or backbone carries it.
    pub module: usize,
    /// The obstacle (0-based) it stays out of.
    pub obstacle: usize,
    /// The point in the world \[m\].
    pub at: Point,
    /// Whether it lies on the backbone (else in the top plate's frame).
    pub arc: bool,
}

/// An obstacle in world coordinates, as drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Solid {
    /// `|x − c| ≥ ρ`, kept `ε` away.
    Sphere {
        centre: Point,
        radius: f64,
        margin: f64,
    },
    /// `n·x ≥ o` (unit `n`, into the allowed side), kept `ε` away.
    HalfSpace {
        normal: Point,
        offset: f64,
        margin: f64,
    },
}

impl Solid {
    /// The point of the obstacle's surface nearest to `p` (`None` for the centre of a
    /// sphere).
    pub(super) fn nearest(&self, p: Point) -> Option<Point> {
        match *self {
            Solid::Sphere { centre, radius, .. } => {
                let out = normalized(sub(p, centre))?;
                Some(std::array::from_fn(|k| centre[k] + radius * out[k]))
            }
            Solid::HalfSpace { normal, offset, .. } => {
                let above = dot(normal, p) - offset;
                Some(std::array::from_fn(|k| p[k] - above * normal[k]))
            }
        }
    }
}

/// The robot's obstacles, in file order, with finite geometry (a half-space's normal
/// made unit; `None` for one that cannot be drawn).
pub(super) fn solids(model: &Model) -> Vec<Option<Solid>> {
    model
        .robot
        .obstacles
        .iter()
        .map(|obstacle| {
            let margin = if obstacle.margin.is_finite() {
                obstacle.margin
            } else {
                0.0
            };
            let solid = match obstacle.shape {
                Region::Sphere { center, radius } => Solid::Sphere {
                    centre: center,
                    radius,
                    margin,
                },
                Region::HalfSpace { normal, offset } => Solid::HalfSpace {
                    normal: normalized(normal)?,
                    offset,
                    margin,
                },
            };
            let finite = match solid {
                Solid::Sphere { centre, radius, .. } => {
                    centre.iter().all(|x| x.is_finite()) && radius.is_finite() && radius >= 0.0
                }
                Solid::HalfSpace { offset, .. } => offset.is_finite(),
            };
            finite.then_some(solid)
        })
        .collect()
}

/// An axis-aligned box `(low, high)` \[m\].
pub(super) type Bounds = (Point, Point);

/// The box around every point of `shapes`, grown by a quarter of its largest side (at
/// least 2 cm) on each side; `None` without a finite point.
pub(super) fn scene_box<'s>(shapes: impl Iterator<Item = &'s Shape>) -> Option<Bounds> {
    let mut bounds: Option<Bounds> = None;
    for p in shapes.flat_map(Shape::points) {
        if !p.iter().all(|x| x.is_finite()) {
            continue;
        }
        let (low, high) = bounds.get_or_insert((p, p));
        *low = std::array::from_fn(|k| low[k].min(p[k]));
        *high = std::array::from_fn(|k| high[k].max(p[k]));
    }
    let (low, high) = bounds?;
    let side = (0..3).map(|k| high[k] - low[k]).fold(0.0, f64::max);
    let grow = (0.25 * side).max(0.02);
    Some((low.map(|x| x - grow), high.map(|x| x + grow)))
}

/// The polygon where the plane `n·x = offset` (unit `n`) cuts the box `bounds`, its
/// corners in order around it; empty if the plane misses the box.
pub(super) fn plane_patch(normal: Point, offset: f64, bounds: &Bounds) -> Vec<Point> {
    let (low, high) = bounds;
    let corner = |k: usize| -> Point {
        std::array::from_fn(|c| if k >> c & 1 == 1 { high[c] } else { low[c] })
    };
    let mut points: Vec<Point> = Vec::new();
    for a in 0..8usize {
        for c in 0..3 {
            let b = a | 1 << c;
            if b == a {
                continue;
            }
            let (pa, pb) = (corner(a), corner(b));
            let (da, db) = (dot(normal, pa) - offset, dot(normal, pb) - offset);
            if (da <= 0.0 && db >= 0.0 || da >= 0.0 && db <= 0.0) && da != db {
                let t = da / (da - db);
                points.push(std::array::from_fn(|k| pa[k] + t * (pb[k] - pa[k])));
            }
        }
    }
    if points.len() < 3 {
        return Vec::new();
    }
    let n = points.len() as f64;
    let centre: Point = std::array::from_fn(|k| points.iter().map(|p| p[k]).sum::<f64>() / n);
    // Two directions in the plane, to order the points by angle about their centre.
    let helper = if normal[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let Some(u) = normalized(cross(normal, helper)) else {
        return Vec::new();
    };
    let v = cross(normal, u);
    let angle = |p: &Point| {
        let d = sub(*p, centre);
        dot(d, v).atan2(dot(d, u))
    };
    points.sort_by(|a, b| angle(a).total_cmp(&angle(b)));
    points.dedup_by(|a, b| (0..3).all(|k| (a[k] - b[k]).abs() < 1e-12));
    points
}

/// `a − b`.
pub(super) fn sub(a: Point, b: Point) -> Point {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Where a corner barrier's corner is and how high it sits above the plate below
/// (docs/model.md §3: `c_ij`, and `b_ij = c_ij − ε_ij`).
#[derive(Clone, Debug)]
pub(super) struct CornerGap {
    /// The module (0-based) whose top plate carries the corner.
    pub module: usize,
    /// The corner in the world \[m\].
    pub corner: Point,
    /// Its foot on the plane of the plate below \[m\].
    pub foot: Point,
    /// `c_ij`: its height above that plane \[m\].
    pub height: f64,
    /// `ε_ij` \[m\].
    pub margin: f64,
}

/// A robot at one state, in world coordinates.
#[derive(Clone, Debug)]
pub(super) struct Shape {
    /// Points along each module's backbone, base to tip.
    pub backbones: Vec<Vec<Point>>,
    /// Points along each tendon (offset curves at radius `d`, angle `ψ_k`), per module.
    pub tendons: Vec<Vec<Vec<Point>>>,
    /// Corners of plate 0 (the base, drawn with module 1's polygon) to plate N.
    pub plates: Vec<Vec<Point>>,
    /// Each corner barrier's corner, by barrier index (`None` for other barriers).
    pub corners: Vec<Option<CornerGap>>,
    /// Each environment barrier's watched point, by barrier index (`None` for others).
    pub watched: Vec<Option<WatchedMark>>,
    /// World poses of plates 0 to N.
    pub poses: Vec<Pose>,
}

impl Shape {
    /// Every point of the drawing (for the extent of a view).
    pub(super) fn points(&self) -> impl Iterator<Item = Point> + '_ {
        self.backbones
            .iter()
            .flatten()
            .chain(self.tendons.iter().flatten().flatten())
            .chain(self.plates.iter().flatten())
            .copied()
            .chain(self.watched.iter().flatten().map(|w| w.at))
    }

    /// The corner of barrier `j`, if it is a corner barrier.
    pub(super) fn corner(&self, j: usize) -> Option<&CornerGap> {
        self.corners.get(j)?.as_ref()
    }

    /// Whether every coordinate is finite.
    pub(super) fn is_finite(&self) -> bool {
        self.points().all(|p| p.iter().all(|x| x.is_finite()))
    }
}

/// An orthographic camera: screen axes and the direction toward the viewer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Projection {
    pub right: Point,
    pub up: Point,
    /// Unit vector from the scene toward the viewer; larger `dot` is nearer.
    pub toward: Point,
}

impl Projection {
    /// Looking from azimuth `azimuth` (from +x toward +y) and elevation `elevation` above
    /// the x–y plane \[rad\]; world z is up on the screen.
    pub(super) fn from_angles(azimuth: f64, elevation: f64) -> Projection {
        let (sa, ca) = azimuth.sin_cos();
        let (se, ce) = elevation.sin_cos();
        Projection {
            right: [-sa, ca, 0.0],
            up: [-se * ca, -se * sa, ce],
            toward: [ce * ca, ce * sa, se],
        }
    }

    /// Looking from `toward` with `up` as near the screen's up as it can be; `None` when
    /// the two are parallel or not finite.
    pub(super) fn looking_from(toward: Point, up: Point) -> Option<Projection> {
        let toward = normalized(toward)?;
        let along = dot(up, toward);
        let up = normalized([
            up[0] - along * toward[0],
            up[1] - along * toward[1],
            up[2] - along * toward[2],
        ])?;
        Some(Projection {
            right: cross(up, toward),
            up,
            toward,
        })
    }

    /// Screen coordinates `(x, y)` \[m\] and depth (larger is nearer) of `p`.
    pub(super) fn project(&self, p: Point) -> (f64, f64, f64) {
        (dot(p, self.right), dot(p, self.up), dot(p, self.toward))
    }
}

/// A rectangle in pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Rect {
    pub x0: f64,
    pub y0: f64,
    pub x1: f64,
    pub y1: f64,
}

/// The part of the segment `a`–`b` inside `rect` (Liang–Barsky), if any.
pub(super) fn clip_segment(
    a: (f64, f64),
    b: (f64, f64),
    rect: &Rect,
) -> Option<((f64, f64), (f64, f64))> {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
    for (p, q) in [
        (-dx, a.0 - rect.x0),
        (dx, rect.x1 - a.0),
        (-dy, a.1 - rect.y0),
        (dy, rect.y1 - a.1),
    ] {
        if !(p.is_finite() && q.is_finite()) {
            return None;
        }
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let t = q / p;
            if p < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
    }
    (t0 <= t1).then_some((
        (a.0 + t0 * dx, a.1 + t0 * dy),
        (a.0 + t1 * dx, a.1 + t1 * dy),
    ))
}

/// The polygon `points` clipped to `rect` (Sutherland–Hodgman); empty if outside.
pub(super) fn clip_polygon(points: &[(f64, f64)], rect: &Rect) -> Vec<(f64, f64)> {
    let mut polygon: Vec<(f64, f64)> = points.to_vec();
    if polygon
        .iter()
        .any(|p| !(p.0.is_finite() && p.1.is_finite()))
    {
        return Vec::new();
    }
    // Each edge of the rectangle: which side is inside, and the crossing with a segment.
    type Inside = fn(&Rect, (f64, f64)) -> bool;
    type Cross = fn(&Rect, (f64, f64), (f64, f64)) -> (f64, f64);
    let edges: [(Inside, Cross); 4] = [
        (|r, p| p.0 >= r.x0, |r, a, b| at_x(a, b, r.x0)),
        (|r, p| p.0 <= r.x1, |r, a, b| at_x(a, b, r.x1)),
        (|r, p| p.1 >= r.y0, |r, a, b| at_y(a, b, r.y0)),
        (|r, p| p.1 <= r.y1, |r, a, b| at_y(a, b, r.y1)),
    ];
    for (inside, crossing) in edges {
        let input = std::mem::take(&mut polygon);
        for (k, &current) in input.iter().enumerate() {
            let previous = input[(k + input.len() - 1) % input.len()];
            match (inside(rect, previous), inside(rect, current)) {
                (true, true) => polygon.push(current),
                (true, false) => polygon.push(crossing(rect, previous, current)),
                (false, true) => {
                    polygon.push(crossing(rect, previous, current));
                    polygon.push(current);
                }
                (false, false) => {}
            }
        }
    }
    polygon
}

fn at_x(a: (f64, f64), b: (f64, f64), x: f64) -> (f64, f64) {
    let t = (x - a.0) / (b.0 - a.0);
    (x, a.1 + t * (b.1 - a.1))
}

fn at_y(a: (f64, f64), b: (f64, f64), y: f64) -> (f64, f64) {
    let t = (y - a.1) / (b.1 - a.1);
    (a.0 + t * (b.0 - a.0), y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use softcbf_description::barriers::WatchedPoint;
    use softcbf_description::robot::Robot;
    use softcbf_generated::{BarrierKind, Point as Watch};

    fn paper() -> Model {
        Model::new(Robot::paper_sim()).expect("the paper robot has a model")
    }

    /// The paper robot with the structure `every_barrier` (softcbf-codegen's registry):
    /// elongation and bend limits on both modules, a half-space and a sphere each watching
    /// corner 3, the centre, a listed point and two backbone points of each module.
    fn every_barrier() -> Model {
        use softcbf_description::barriers::{LimitFlags, Limits, Obstacle, Watched};
        let mut robot = Robot::paper_sim();
        robot.limits = vec![
            Limits {
                elongation: [-0.05, 0.03],
                elongation_margin: 0.002,
                max_bend: 1.7,
                bend_margin: 0.02,
                gains: [None, None],
                written: LimitFlags {
                    elongation: true,
                    bend: true,
                },
                elongation_rate: 1.0,
            };
            2
        ];
        let watch: Vec<Watched> = (0..2)
            .flat_map(|module| {
                [
                    WatchedPoint::Corner(2),
                    WatchedPoint::Centre,
                    WatchedPoint::Listed([0.01, 0.03, -0.02]),
                    WatchedPoint::Arc(0.3),
                    WatchedPoint::Arc(0.7),
                ]
                .map(|point| Watched { module, point })
            })
            .collect();
        let obstacle = |shape, margin| Obstacle {
            shape,
            margin,
            gains: [None, None],
            watch: watch.clone(),
        };
        robot.obstacles = vec![
            obstacle(
                Region::HalfSpace {
                    normal: [-0.6, 0.0, 0.8],
                    offset: -0.3,
                },
                0.004,
            ),
            obstacle(
                Region::Sphere {
                    center: [0.1, -0.05, 0.12],
                    radius: 0.03,
                },
                0.005,
            ),
        ];
        Model::new(robot).expect("every_barrier is generated")
    }

    #[test]
    fn watched_points_are_where_the_generated_barriers_measure() {
        let model = every_barrier();
        let solids = solids(&model);
        let table = model.generated.barrier_table();
        let mut kinematics = Kinematics::new(&model);
        for q in [
            [0.0; 6],
            [0.03, -0.02, -0.01, -0.01, 0.05, 0.02],
            [0.08, 0.0, -0.05, 0.0, -0.06, -0.07],
        ] {
            let shape = kinematics.shape(&q);
            let mut b = vec![0.0; model.nb()];
            model.generated.barriers(&model.params, &q, &mut b);
            let mut watched = 0;
            for (j, info) in table.iter().enumerate() {
                match (info.kind, &shape.watched[j], shape.corner(j)) {
                    (BarrierKind::PlateCorner, None, Some(gap)) => {
                        assert!((gap.height - gap.margin - b[j]).abs() < 1e-14, "{j}");
                    }
                    (BarrierKind::HalfSpace | BarrierKind::Sphere, Some(mark), None) => {
                        watched += 1;
                        assert_eq!(mark.module, info.module);
                        assert_eq!(Some(mark.obstacle), info.obstacle);
                        assert_eq!(mark.arc, matches!(info.point, Some(Watch::Arc(_))));
                        // The docs/model.md formulas, on the point as drawn.
                        let p = mark.at;
                        let expected = match solids[mark.obstacle].unwrap() {
                            Solid::Sphere {
                                centre,
                                radius,
                                margin,
                            } => dot(sub(p, centre), sub(p, centre)).sqrt() - radius - margin,
                            Solid::HalfSpace {
                                normal,
                                offset,
                                margin,
                            } => dot(normal, p) - offset - margin,
                        };
                        assert!((expected - b[j]).abs() < 1e-14, "{}", info.label);
                    }
                    (_, None, None) => assert!(info.obstacle.is_none() && info.corner().is_none()),
                    _ => panic!("barrier {j} ({}) drawn as the wrong kind", info.label),
                }
            }
            assert_eq!(watched, 20);
        }
    }

    #[test]
    fn a_plane_cuts_the_box_in_a_convex_polygon_on_the_plane() {
        let bounds: Bounds = ([-0.1, -0.2, 0.0], [0.3, 0.2, 0.25]);
        let normal = normalized([-0.6, 0.2, 0.8]).unwrap();
        let patch = plane_patch(normal, -0.05, &bounds);
        assert!(patch.len() >= 3 && patch.len() <= 6, "{patch:?}");
        for p in &patch {
            assert!((dot(normal, *p) + 0.05).abs() < 1e-14);
            for (k, x) in p.iter().enumerate() {
                assert!(*x >= bounds.0[k] - 1e-14 && *x <= bounds.1[k] + 1e-14);
            }
        }
        // Convex and in order: every turn has the same sign about the normal.
        let turns: Vec<f64> = (0..patch.len())
            .map(|k| {
                let (a, b, c) = (
                    patch[k],
                    patch[(k + 1) % patch.len()],
                    patch[(k + 2) % patch.len()],
                );
                dot(cross(sub(b, a), sub(c, b)), normal)
            })
            .collect();
        assert!(turns.iter().all(|&t| t > 0.0) || turns.iter().all(|&t| t < 0.0));
        // A plane past the box, or an axis plane through it.
        assert!(plane_patch([0.0, 0.0, 1.0], 1.0, &bounds).is_empty());
        assert_eq!(plane_patch([0.0, 0.0, 1.0], 0.1, &bounds).len(), 4);
    }

    #[test]
    fn arc_at_one_is_the_plate_pose_and_at_zero_the_base() {
        let model = paper();
        let mut kinematics = Kinematics::new(&model);
        let q = [0.03, -0.02, -0.01, -0.01, 0.05, 0.02];
        let mut poses = vec![IDENTITY; 2];
        model.generated.plate_poses(&model.params, &q, &mut poses);
        let tips = kinematics.frames_at(&q, 1.0);
        let bases = kinematics.frames_at(&q, 0.0);
        let plates = kinematics.plate_poses(&q);
        for i in 0..2 {
            for r in 0..4 {
                for c in 0..4 {
                    assert!((tips[i][r][c] - poses[i][r][c]).abs() < 1e-15);
                    assert!((bases[i][r][c] - plates[i][r][c]).abs() < 1e-15);
                }
            }
        }
    }

    #[test]
    fn tendons_have_the_length_of_docs_model_section_6() {
        let model = paper();
        let mut kinematics = Kinematics::new(&model);
        let q = [0.08, 0.0, -0.05, 0.01, -0.06, 0.02];
        let shape = kinematics.shape(&q);
        for (i, module) in model.robot.modules.iter().enumerate() {
            let (dx, dy, dl) = (q[3 * i], q[3 * i + 1], q[3 * i + 2]);
            for (tendon, psi) in shape.tendons[i].iter().zip(&module.tendon_angles) {
                // ℓ_k = L0 + δL − (Δx cos ψ_k + Δy sin ψ_k), the signed length of the offset
                // arc (negative past the centre of curvature, as in the paper's set point);
                // the polyline of 16 chords is shorter by at most (θ/16)²/24 of it.
                let expected = (module.rest_length + dl - (dx * psi.cos() + dy * psi.sin())).abs();
                let drawn: f64 = tendon
                    .windows(2)
                    .map(|w| {
                        let d = [w[1][0] - w[0][0], w[1][1] - w[0][1], w[1][2] - w[0][2]];
                        dot(d, d).sqrt()
                    })
                    .sum();
                assert!(
                    drawn <= expected + 1e-15 && drawn > expected * (1.0 - 1e-3),
                    "module {i}, ψ = {psi}: {drawn} vs {expected}"
                );
                // Its ends are at radius d, angle ψ_k on the plates below and above.
                let d = module.tendon_radius;
                let anchor = [d * psi.cos(), d * psi.sin(), 0.0];
                for (end, plate) in [(tendon[0], i), (tendon[ARC_PIECES], i + 1)] {
                    let expected = apply(&shape.poses[plate], anchor);
                    assert!((0..3).all(|k| (end[k] - expected[k]).abs() < 1e-15));
                }
            }
        }
        // Corner heights are the barriers plus their margins; the limits have no corner.
        let mut b = vec![0.0; model.nb()];
        model.generated.barriers(&model.params, &q, &mut b);
        assert_eq!(shape.corners.len(), b.len());
        let table = model.generated.barrier_table();
        for ((gap, b), info) in shape.corners.iter().zip(&b).zip(table) {
            match gap {
                Some(gap) => assert!((gap.height - gap.margin - b).abs() < 1e-15),
                None => assert_ne!(info.kind, BarrierKind::PlateCorner, "{}", info.label),
            }
        }
        assert_eq!(shape.corners.iter().flatten().count(), 12);
    }

    #[test]
    fn clipping_keeps_inside_and_cuts_at_the_edges() {
        let rect = Rect {
            x0: 0.0,
            y0: 0.0,
            x1: 10.0,
            y1: 10.0,
        };
        assert_eq!(
            clip_segment((-5.0, 5.0), (5.0, 5.0), &rect),
            Some(((0.0, 5.0), (5.0, 5.0)))
        );
        assert_eq!(clip_segment((-5.0, -5.0), (-1.0, 20.0), &rect), None);
        assert_eq!(clip_segment((f64::NAN, 0.0), (1.0, 1.0), &rect), None);
        let clipped = clip_polygon(&[(-5.0, -5.0), (5.0, -5.0), (5.0, 5.0), (-5.0, 5.0)], &rect);
        assert_eq!(clipped.len(), 4);
        for corner in [(0.0, 0.0), (5.0, 0.0), (5.0, 5.0), (0.0, 5.0)] {
            assert!(clipped.contains(&corner), "{corner:?} in {clipped:?}");
        }
        assert!(clip_polygon(&[(20.0, 20.0), (30.0, 20.0), (25.0, 30.0)], &rect).is_empty());
    }

    #[test]
    fn projection_is_right_handed_and_z_is_up() {
        let view = Projection::from_angles(-1.0, 0.3);
        assert!((dot(cross(view.right, view.up), view.toward) - 1.0).abs() < 1e-15);
        assert!(view.up[2] > 0.0);
        let looking = Projection::looking_from([0.0, -1.0, 0.0], [0.0, 0.0, 1.0]).unwrap();
        assert_eq!(looking.right, [1.0, 0.0, 0.0]);
        assert!(Projection::looking_from([0.0, 0.0, 1.0], [0.0, 0.0, 2.0]).is_none());
    }
}
