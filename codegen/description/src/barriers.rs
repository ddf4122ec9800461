//! The barriers of a robot beyond its plate corners (paper §II-C, docs/model.md §3):
//! elongation and bend limits of every module (the file's, else the domain's defaults), and
//! obstacles that chosen points must avoid.
//!
//! Which barriers exist is structure (code is generated for them); where an obstacle sits,
//! a limit's value and a margin are numbers (parameters read at run time). [`barrier_list`]
//! is the one definition of the barriers of a structure and their order: code generation
//! emits them in this order, and the runtime reads each barrier's numbers through it.

use std::fmt;

/// What a barrier keeps apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BarrierKind {
    /// A corner of a module's top plate above the plane of its bottom plate:
    /// `b = c_ij − ε_ij` \[m\].
    PlateCorner,
    /// A module's elongation above its lower limit: `b = δL − (δL_min + ε)` \[m\].
    ElongationMin,
    /// A module's elongation below its upper limit: `b = (δL_max − ε) − δL` \[m\].
    ElongationMax,
    /// A module's bend below its limit, smooth at `θ = 0`:
    /// `b = (θ_b² − θ²) / (2 θ_b)` with `θ_b = θ_max − ε` \[rad\].
    Bend,
    /// A point on one side of a plane: `b = n·x − o − ε` \[m\].
    HalfSpace,
    /// A point outside a sphere: `b = |x − c| − ρ − ε` \[m\].
    Sphere,
}

/// The groups the reports show a robot's barriers in, in this order.
pub const KIND_GROUPS: [KindGroup; 4] = [
    KindGroup::PlateCorner,
    KindGroup::Elongation,
    KindGroup::Bend,
    KindGroup::Obstacle,
];

/// How the reports group barriers: one lowest value per group, one figure panel per group.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum KindGroup {
    /// Plate-corner self-contact barriers.
    PlateCorner,
    /// Elongation limits, both sides.
    Elongation,
    /// Bend limits.
    Bend,
    /// Environment barriers: half-spaces and spheres.
    Obstacle,
}

impl KindGroup {
    /// A name for reports and JSON keys: `plate_corner`, `elongation`, `bend`, `obstacle`.
    pub fn key(self) -> &'static str {
        match self {
            KindGroup::PlateCorner => "plate_corner",
            KindGroup::Elongation => "elongation",
            KindGroup::Bend => "bend",
            KindGroup::Obstacle => "obstacle",
        }
    }

    /// A title for figures: `plate corners`, `elongation limits`, …
    pub fn title(self) -> &'static str {
        match self {
            KindGroup::PlateCorner => "plate corners",
            KindGroup::Elongation => "elongation limits",
            KindGroup::Bend => "bend limits",
            KindGroup::Obstacle => "obstacles",
        }
    }

    /// The unit of this group's barrier values: `m`, or `rad` for bends.
    pub fn unit(self) -> &'static str {
        match self {
            KindGroup::Bend => "rad",
            _ => "m",
        }
    }
}

impl BarrierKind {
    /// The variant's name, as generated code spells it.
    pub fn name(self) -> &'static str {
        match self {
            BarrierKind::PlateCorner => "PlateCorner",
            BarrierKind::ElongationMin => "ElongationMin",
            BarrierKind::ElongationMax => "ElongationMax",
            BarrierKind::Bend => "Bend",
            BarrierKind::HalfSpace => "HalfSpace",
            BarrierKind::Sphere => "Sphere",
        }
    }

    /// The name in JSON and robot files: `plate_corner`, `elongation_min`, `elongation_max`,
    /// `bend`, `half_space`, `sphere`.
    pub fn key(self) -> &'static str {
        match self {
            BarrierKind::PlateCorner => "plate_corner",
            BarrierKind::ElongationMin => "elongation_min",
            BarrierKind::ElongationMax => "elongation_max",
            BarrierKind::Bend => "bend",
            BarrierKind::HalfSpace => "half_space",
            BarrierKind::Sphere => "sphere",
        }
    }

    /// The group the reports show it in.
    pub fn group(self) -> KindGroup {
        match self {
            BarrierKind::PlateCorner => KindGroup::PlateCorner,
            BarrierKind::ElongationMin | BarrierKind::ElongationMax => KindGroup::Elongation,
            BarrierKind::Bend => KindGroup::Bend,
            BarrierKind::HalfSpace | BarrierKind::Sphere => KindGroup::Obstacle,
        }
    }

    /// The unit of its value: `m`, or `rad` for a bend limit.
    pub fn unit(self) -> &'static str {
        self.group().unit()
    }
}

/// A point a barrier watches, on the module the barrier belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Point {
    /// Corner `j` (0-based) of the module's top plate.
    Corner(usize),
    /// The centre (origin) of the module's top plate.
    Centre,
    /// A point fixed in the top plate's frame, listed in the robot file: entry `k` (0-based)
    /// of its obstacle's watched points ([`Obstacle::watch`]).
    Listed(usize),
    /// A point on the module's soft backbone at an arc fraction `s ∈ (0, 1]`: entry `k`
    /// (0-based) of its obstacle's watched points.
    Arc(usize),
}

/// The shape of a watched point, without its numbers: what code generation needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PointShape {
    /// Corner `j` (0-based) of the top plate.
    Corner(usize),
    /// The top plate's centre.
    Centre,
    /// A point fixed in the top plate's frame (its coordinates are parameters).
    Listed,
    /// A point on the backbone (its arc fraction is a parameter).
    Arc,
}

/// What kind of region an obstacle is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ObstacleKind {
    /// The allowed side of a plane.
    HalfSpace,
    /// The outside of a sphere.
    Sphere,
}

impl ObstacleKind {
    /// The barrier kind of its watched points.
    pub fn barrier_kind(self) -> BarrierKind {
        match self {
            ObstacleKind::HalfSpace => BarrierKind::HalfSpace,
            ObstacleKind::Sphere => BarrierKind::Sphere,
        }
    }

    /// As robot files write it: `half-space`, `sphere`.
    pub fn written(self) -> &'static str {
        match self {
            ObstacleKind::HalfSpace => "half-space",
            ObstacleKind::Sphere => "sphere",
        }
    }
}

/// Which limits a module's robot file writes (`[limits]`, `[module.limits]`); the others
/// are the domain's defaults ([`Limits::domain`]). Every module has all
/// three limit barriers either way: this is a number of the robot, not structure.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct LimitFlags {
    /// `δL_min ≤ δL ≤ δL_max`, both sides.
    pub elongation: bool,
    /// `θ ≤ θ_max`.
    pub bend: bool,
}

/// The structure of one obstacle: its kind and the points it watches, `(module, point)`
/// with the module 0-based.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct ObstacleStructure {
    /// Half-space or sphere.
    pub kind: ObstacleKind,
    /// Watched points in file order: the module (0-based) and the point's shape.
    pub watch: Vec<(usize, PointShape)>,
}

/// The limits of one module, resolved (`[module.limits]` over the file's `[limits]`, over
/// the domain's defaults).
#[derive(Clone, Debug, PartialEq)]
pub struct Limits {
    /// `[δL_min, δL_max]` \[m\]: the file's, else [`crate::limits::default_elongation`].
    pub elongation: [f64; 2],
    /// Margin `ε` of both elongation barriers \[m\].
    pub elongation_margin: f64,
    /// `θ_max` \[rad\]: the file's, else [`crate::limits::DEFAULT_MAX_BEND_RAD`].
    pub max_bend: f64,
    /// Margin `ε` of the bend barrier \[rad\].
    pub bend_margin: f64,
    /// The class-K gains `[p1, p2]` \[1/s\] the limits tables give, each `None` when not
    /// given; they apply to the limits the file writes ([`Limits::gains_of`]).
    pub gains: [Option<f64>; 2],
    /// Which limits the file writes; the others are the domain's defaults.
    pub written: LimitFlags,
    /// `v̄` \[m/s\] of the rate row `|δL̇| ≤ v̄` (predicted and certified rows only): the
    /// file's, else [`crate::limits::DEFAULT_ELONGATION_RATE_PER_L0`] rest lengths per
    /// second.
    pub elongation_rate: f64,
}

impl Limits {
    /// The limits of a module of rest length `rest_length` \[m\] whose robot file writes
    /// none: the model's domain as a constraint (`crate::limits`): elongation
    /// [`default_elongation`](crate::limits::default_elongation), bend
    /// [`DEFAULT_MAX_BEND_RAD`](crate::limits::DEFAULT_MAX_BEND_RAD), zero margins, gains
    /// [`DOMAIN_BARRIER_GAINS`](crate::limits::DOMAIN_BARRIER_GAINS).
    pub fn domain(rest_length: f64) -> Limits {
        Limits {
            elongation: crate::limits::default_elongation(rest_length),
            elongation_margin: 0.0,
            max_bend: crate::limits::DEFAULT_MAX_BEND_RAD,
            bend_margin: 0.0,
            gains: [None, None],
            written: LimitFlags::default(),
            elongation_rate: crate::limits::DEFAULT_ELONGATION_RATE_PER_L0 * rest_length,
        }
    }

    /// Whether the limit of barrier kind `kind` is the domain's default (`false` for a
    /// written limit and for kinds that are not limits).
    pub fn is_domain_default(&self, kind: BarrierKind) -> bool {
        match kind {
            BarrierKind::ElongationMin | BarrierKind::ElongationMax => !self.written.elongation,
            BarrierKind::Bend => !self.written.bend,
            _ => false,
        }
    }

    /// The class-K gains `[p1, p2]` \[1/s\] of this module's barrier of kind `kind`: a
    /// written limit takes its table's (`None`: the run's), a domain default
    /// [`crate::limits::DOMAIN_BARRIER_GAINS`].
    pub fn gains_of(&self, kind: BarrierKind) -> [Option<f64>; 2] {
        if self.is_domain_default(kind) {
            crate::limits::DOMAIN_BARRIER_GAINS.map(Some)
        } else {
            self.gains
        }
    }
}

/// An obstacle's region, in world (= base) coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// `n·x ≥ o`: the allowed side of the plane with unit normal `n` (pointing into the
    /// allowed side) at offset `o` \[m\].
    HalfSpace {
        /// Unit normal.
        normal: [f64; 3],
        /// `o` \[m\].
        offset: f64,
    },
    /// `|x − c| ≥ ρ`: the outside of a sphere.
    Sphere {
        /// `c` \[m\].
        center: [f64; 3],
        /// `ρ` \[m\].
        radius: f64,
    },
}

impl Shape {
    /// The kind of region.
    pub fn kind(&self) -> ObstacleKind {
        match self {
            Shape::HalfSpace { .. } => ObstacleKind::HalfSpace,
            Shape::Sphere { .. } => ObstacleKind::Sphere,
        }
    }
}

/// A watched point with its numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum WatchedPoint {
    /// Corner `j` (0-based) of the module's top plate.
    Corner(usize),
    /// The top plate's centre.
    Centre,
    /// A point in the top plate's frame \[m\].
    Listed([f64; 3]),
    /// A point on the backbone at arc fraction `s ∈ (0, 1]`.
    Arc(f64),
}

impl WatchedPoint {
    /// Its shape without numbers.
    pub fn shape(&self) -> PointShape {
        match *self {
            WatchedPoint::Corner(j) => PointShape::Corner(j),
            WatchedPoint::Centre => PointShape::Centre,
            WatchedPoint::Listed(_) => PointShape::Listed,
            WatchedPoint::Arc(_) => PointShape::Arc,
        }
    }
}

/// One watched point of an obstacle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Watched {
    /// The module (0-based) whose plate or backbone carries the point.
    pub module: usize,
    /// The point.
    pub point: WatchedPoint,
}

/// An obstacle of a robot file (`[[obstacle]]`): a region the watched points stay out of.
#[derive(Clone, Debug, PartialEq)]
pub struct Obstacle {
    /// The region.
    pub shape: Shape,
    /// Margin `ε` \[m\].
    pub margin: f64,
    /// Class-K gains `[p1, p2]` \[1/s\], each `None` when not given.
    pub gains: [Option<f64>; 2],
    /// The points it watches, one barrier each, in file order.
    pub watch: Vec<Watched>,
}

impl Obstacle {
    /// Its structure (kind and watched point shapes).
    pub fn structure(&self) -> ObstacleStructure {
        ObstacleStructure {
            kind: self.shape.kind(),
            watch: self
                .watch
                .iter()
                .map(|w| (w.module, w.point.shape()))
                .collect(),
        }
    }
}

/// One barrier of a structure: what it is and where it sits.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BarrierSpec {
    /// What it keeps apart.
    pub kind: BarrierKind,
    /// The module it belongs to (0-based): its value depends on this module's coordinates
    /// and those below it only.
    pub module: usize,
    /// The watched point, for corner and environment barriers.
    pub point: Option<Point>,
    /// The obstacle (0-based, file order), for environment barriers.
    pub obstacle: Option<usize>,
    /// A short stable name, 1-based: `module 1 corner 3`, `module 2 elongation max`,
    /// `module 1 bend`, `obstacle 1 module 2 corner 4`, `obstacle 2 module 1 arc 1`
    /// (written and read by [`label`]).
    pub label: String,
}

/// Every barrier of `structure`, in the order of the generated arrays: the plate corners
/// (module by module, corner by corner), then each module's three limits (elongation min,
/// max, bend: every module has them, written or the domain's defaults), then each
/// obstacle's watched points in file order.
pub fn barrier_list(structure: &crate::Structure) -> Vec<BarrierSpec> {
    let mut list = Vec::new();
    for (i, &corners) in structure.corners.iter().enumerate() {
        for j in 0..corners {
            list.push(BarrierSpec {
                kind: BarrierKind::PlateCorner,
                module: i,
                point: Some(Point::Corner(j)),
                obstacle: None,
                label: label::corner(i, j),
            });
        }
    }
    // Every module's limits, written or the domain's defaults: the model's domain is a
    // constraint of every robot (crate::domain).
    for i in 0..structure.modules() {
        for kind in [
            BarrierKind::ElongationMin,
            BarrierKind::ElongationMax,
            BarrierKind::Bend,
        ] {
            let words = label::limit_words(kind).unwrap_or_default();
            list.push(BarrierSpec {
                kind,
                module: i,
                point: None,
                obstacle: None,
                label: label::limit(i, words),
            });
        }
    }
    for (o, obstacle) in structure.obstacles.iter().enumerate() {
        // Listed points and arc points are numbered per module, from 1, for the labels.
        let mut listed = vec![0usize; structure.corners.len()];
        let mut arcs = vec![0usize; structure.corners.len()];
        for (k, &(module, shape)) in obstacle.watch.iter().enumerate() {
            let (point, name) = match shape {
                PointShape::Corner(j) => (Point::Corner(j), format!("corner {}", j + 1)),
                PointShape::Centre => (Point::Centre, "centre".to_string()),
                PointShape::Listed => {
                    let n = bump(&mut listed, module);
                    (Point::Listed(k), format!("point {n}"))
                }
                PointShape::Arc => {
                    let n = bump(&mut arcs, module);
                    (Point::Arc(k), format!("arc {n}"))
                }
            };
            list.push(BarrierSpec {
                kind: obstacle.kind.barrier_kind(),
                module,
                point: Some(point),
                obstacle: Some(o),
                label: label::obstacle_point(o, module, &name),
            });
        }
    }
    list
}

/// Increments the counter of `module` (if it exists) and returns its new value.
fn bump(counters: &mut [usize], module: usize) -> usize {
    match counters.get_mut(module) {
        Some(n) => {
            *n += 1;
            *n
        }
        None => 0,
    }
}

impl fmt::Display for PointShape {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PointShape::Corner(j) => write!(f, "corner {}", j + 1),
            PointShape::Centre => f.write_str("centre"),
            PointShape::Listed => f.write_str("point"),
            PointShape::Arc => f.write_str("arc"),
        }
    }
}

pub mod label {
    //! Barrier labels, written and read in one place: the short stable names that
    //! [`barrier_list`](super::barrier_list) gives every barrier and that CSV headers,
    //! reports, figures and the 3-D view carry (1-based numbers):
    //!
    //! - `module K corner J` — a plate corner;
    //! - `module K elongation min`, `module K elongation max`, `module K bend` — a module's limits;
    //! - `obstacle O module K corner J|centre|point N|arc N` — a watched point of an obstacle.
    //!
    //! A new barrier kind changes [`limit`] or [`KindGroup`]'s words here and nowhere else;
    //! [`kind_group`] reads every label back (a test below writes every kind and reads it).
    use super::{BarrierKind, KindGroup};

    /// The label of corner `corner` of module `module` (both 0-based): `module 1 corner 3`.
    pub fn corner(module: usize, corner: usize) -> String {
        format!("module {} corner {}", module + 1, corner + 1)
    }

    /// The words a module's limit of `kind` adds to `module K`, `None` for the kinds that are not
    /// a module's limit: `elongation min`, `elongation max`, `bend`.
    pub fn limit_words(kind: BarrierKind) -> Option<&'static str> {
        match kind {
            BarrierKind::ElongationMin => Some("elongation min"),
            BarrierKind::ElongationMax => Some("elongation max"),
            BarrierKind::Bend => Some("bend"),
            BarrierKind::PlateCorner | BarrierKind::HalfSpace | BarrierKind::Sphere => None,
        }
    }

    /// The label of module `module`'s (0-based) limit `words` ([`limit_words`]):
    /// `module 2 elongation max`.
    pub fn limit(module: usize, words: &str) -> String {
        format!("module {} {words}", module + 1)
    }

    /// The label of obstacle `obstacle`'s (0-based) watched point on module `module` (0-based),
    /// named `point` (`corner 4`, `centre`, `point 1`, `arc 2`): `obstacle 1 module 2 corner 4`.
    pub fn obstacle_point(obstacle: usize, module: usize, point: &str) -> String {
        format!("obstacle {} module {} {point}", obstacle + 1, module + 1)
    }

    /// The kind group and module (0-based) a label names; `None` for text that is not a label
    /// [`barrier_list`](super::barrier_list) writes.
    pub fn kind_group(label: &str) -> Option<(KindGroup, usize)> {
        if let Some(rest) = label.strip_prefix("obstacle ") {
            let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
            let (module, _) = split_module(rest[digits..].trim_start())?;
            return (digits > 0).then_some((KindGroup::Obstacle, module - 1));
        }
        let (module, rest) = split_module(label)?;
        let group = match rest.split(' ').next()? {
            "corner" => KindGroup::PlateCorner,
            "elongation" => KindGroup::Elongation,
            "bend" => KindGroup::Bend,
            _ => return None,
        };
        Some((group, module - 1))
    }

    /// `(K, rest)` of a label `module K rest` (`K` ≥ 1, 1-based as written; `rest` may be empty).
    pub fn split_module(label: &str) -> Option<(usize, &str)> {
        let after = label.strip_prefix("module ")?;
        let digits = after.bytes().take_while(u8::is_ascii_digit).count();
        let module: usize = after[..digits].parse().ok()?;
        let rest = &after[digits..];
        if !(rest.is_empty() || rest.starts_with(' ')) || module == 0 {
            return None;
        }
        Some((module, rest.trim_start()))
    }

    /// The label without its `module K` words (`obstacle 1 module 2 arc 1` → `obstacle 1 arc
    /// 1`, `module 2 bend` → `bend`); the label itself if it has none.
    pub fn without_module(label: &str) -> String {
        let words: Vec<&str> = label.split(' ').collect();
        let at = words.windows(2).position(|pair| {
            pair[0] == "module"
                && !pair[1].is_empty()
                && pair[1].bytes().all(|b| b.is_ascii_digit())
        });
        match at {
            Some(k) => [&words[..k], &words[k + 2..]].concat().join(" "),
            None => label.to_string(),
        }
    }

    #[cfg(test)]
    mod tests {
        use super::*;
        use crate::Robot;
        use crate::barriers::barrier_list;

        #[test]
        fn every_label_written_reads_back_as_its_kind_and_module() {
            // Every kind at once: corners, the three limits, both obstacle shapes with corner,
            // centre, listed and arc points.
            let text = r#"
    name = "labels"
    [[module]]
    [[module]]
    [[module]]
    [[obstacle]]
    kind = "sphere"
    center = [0.0, 0.0, 0.5]
    radius = 0.05
    watch = [
      { module = 3, points = ["corners", "centre"] },
      { module = 2, plate_points = [[0.01, 0.0, 0.0]], arc = [0.5] },
    ]
    [[obstacle]]
    kind = "half-space"
    normal = [1.0, 0.0, 0.0]
    offset = -0.5
    watch = [{ module = 1, points = ["corner 2"], arc = [0.3, 0.7] }]
    "#;
            let robot = Robot::parse(text, std::path::Path::new("labels.toml"))
                .expect("the test's robot reads");
            let list = barrier_list(&robot.structure());
            let mut groups = std::collections::BTreeSet::new();
            for spec in &list {
                assert_eq!(
                    kind_group(&spec.label),
                    Some((spec.kind.group(), spec.module)),
                    "{}",
                    spec.label
                );
                groups.insert(spec.kind.group());
            }
            assert_eq!(groups.len(), crate::barriers::KIND_GROUPS.len(), "{list:?}");
        }

        #[test]
        fn text_that_is_no_label_is_refused() {
            for text in [
                "module 0 corner 1",
                "module 1 twist",
                "obstacle module 1 arc 2",
                "corner 1",
                "#1",
                "module x corner 1",
                "module 1corner 1",
                "",
            ] {
                assert_eq!(kind_group(text), None, "{text}");
            }
            assert_eq!(
                kind_group("module 12 elongation min"),
                Some((KindGroup::Elongation, 11))
            );
            assert_eq!(
                kind_group("obstacle 10 module 1 arc 2"),
                Some((KindGroup::Obstacle, 0))
            );
        }

        #[test]
        fn the_module_words_come_off() {
            assert_eq!(without_module("module 2 corner 6"), "corner 6");
            assert_eq!(without_module("module 2 bend"), "bend");
            assert_eq!(
                without_module("obstacle 1 module 2 arc 1"),
                "obstacle 1 arc 1"
            );
            assert_eq!(without_module("b1"), "b1");
            assert_eq!(split_module("module 3"), Some((3, "")));
        }
    }
}
