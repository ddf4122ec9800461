//! The runtime parameter vector of a generated model: which number sits at which index.
//! Code generation reads symbols from this layout and the runtime packs a robot with it.

use crate::barriers::{PointShape, Shape, WatchedPoint};
use crate::robot::{Robot, Structure};

/// One entry of the parameter vector (module `i`, corner `j`, 0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Param {
    /// `L0` of module `i` \[m\].
    RestLength(usize),
    /// `d` of module `i` \[m\].
    TendonRadius(usize),
    /// `r` of module `i` \[m\].
    CornerRadius(usize),
    /// `cos φ_j` of corner `j` of module `i`.
    CornerCos(usize, usize),
    /// `sin φ_j` of corner `j` of module `i`.
    CornerSin(usize, usize),
    /// `ε_j` of corner `j` of module `i` \[m\].
    Margin(usize, usize),
    /// `δL_min` of module `i` \[m\].
    ElongationMin(usize),
    /// `δL_max` of module `i` \[m\].
    ElongationMax(usize),
    /// Margin of module `i`'s elongation barriers \[m\].
    ElongationMargin(usize),
    /// `θ_max` of module `i` \[rad\].
    MaxBend(usize),
    /// Margin of module `i`'s bend barrier \[rad\].
    BendMargin(usize),
    /// Component `c` of the unit normal of half-space obstacle `o`.
    ObstacleNormal(usize, usize),
    /// Offset `o` of half-space obstacle `o` (`n·x ≥ o`) \[m\].
    ObstacleOffset(usize),
    /// Component `c` of the centre of sphere obstacle `o` \[m\].
    ObstacleCenter(usize, usize),
    /// Radius of sphere obstacle `o` \[m\].
    ObstacleRadius(usize),
    /// Margin of obstacle `o` \[m\].
    ObstacleMargin(usize),
    /// Component `c` (plate frame) of watched point `k` of obstacle `o` \[m\].
    PointCoordinate(usize, usize, usize),
    /// Arc fraction `s` of watched point `k` of obstacle `o`.
    ArcFraction(usize, usize),
}

impl Param {
    /// The symbol name used in generated code.
    pub fn name(self) -> String {
        match self {
            Param::RestLength(i) => format!("rest_length_{i}"),
            Param::TendonRadius(i) => format!("tendon_radius_{i}"),
            Param::CornerRadius(i) => format!("corner_radius_{i}"),
            Param::CornerCos(i, j) => format!("corner_cos_{i}_{j}"),
            Param::CornerSin(i, j) => format!("corner_sin_{i}_{j}"),
            Param::Margin(i, j) => format!("margin_{i}_{j}"),
            Param::ElongationMin(i) => format!("elongation_min_{i}"),
            Param::ElongationMax(i) => format!("elongation_max_{i}"),
            Param::ElongationMargin(i) => format!("elongation_margin_{i}"),
            Param::MaxBend(i) => format!("max_bend_{i}"),
            Param::BendMargin(i) => format!("bend_margin_{i}"),
            Param::ObstacleNormal(o, c) => format!("obstacle_{o}_normal_{c}"),
            Param::ObstacleOffset(o) => format!("obstacle_{o}_offset"),
            Param::ObstacleCenter(o, c) => format!("obstacle_{o}_center_{c}"),
            Param::ObstacleRadius(o) => format!("obstacle_{o}_radius"),
            Param::ObstacleMargin(o) => format!("obstacle_{o}_margin"),
            Param::PointCoordinate(o, k, c) => format!("obstacle_{o}_point_{k}_{c}"),
            Param::ArcFraction(o, k) => format!("obstacle_{o}_arc_{k}"),
        }
    }

    /// This parameter's value for a robot of the matching structure (NaN where the robot
    /// does not match, which [`pack_params`] never asks for).
    pub fn value(self, robot: &Robot) -> f64 {
        let limits = |i: usize| robot.limits.get(i);
        let obstacle = |o: usize| robot.obstacles.get(o);
        let watched =
            |o: usize, k: usize| obstacle(o).and_then(|ob| ob.watch.get(k)).map(|w| w.point);
        match self {
            Param::ElongationMin(i) => limits(i).map_or(f64::NAN, |l| l.elongation[0]),
            Param::ElongationMax(i) => limits(i).map_or(f64::NAN, |l| l.elongation[1]),
            Param::ElongationMargin(i) => limits(i).map_or(f64::NAN, |l| l.elongation_margin),
            Param::MaxBend(i) => limits(i).map_or(f64::NAN, |l| l.max_bend),
            Param::BendMargin(i) => limits(i).map_or(f64::NAN, |l| l.bend_margin),
            Param::ObstacleNormal(o, c) => match obstacle(o).map(|ob| ob.shape) {
                Some(Shape::HalfSpace { normal, .. }) => normal[c],
                _ => f64::NAN,
            },
            Param::ObstacleOffset(o) => match obstacle(o).map(|ob| ob.shape) {
                Some(Shape::HalfSpace { offset, .. }) => offset,
                _ => f64::NAN,
            },
            Param::ObstacleCenter(o, c) => match obstacle(o).map(|ob| ob.shape) {
                Some(Shape::Sphere { center, .. }) => center[c],
                _ => f64::NAN,
            },
            Param::ObstacleRadius(o) => match obstacle(o).map(|ob| ob.shape) {
                Some(Shape::Sphere { radius, .. }) => radius,
                _ => f64::NAN,
            },
            Param::ObstacleMargin(o) => obstacle(o).map_or(f64::NAN, |ob| ob.margin),
            Param::PointCoordinate(o, k, c) => match watched(o, k) {
                Some(WatchedPoint::Listed(p)) => p[c],
                _ => f64::NAN,
            },
            Param::ArcFraction(o, k) => match watched(o, k) {
                Some(WatchedPoint::Arc(s)) => s,
                _ => f64::NAN,
            },
            Param::RestLength(i) => robot.modules[i].rest_length,
            Param::TendonRadius(i) => robot.modules[i].tendon_radius,
            Param::CornerRadius(i) => robot.modules[i].corner_radius,
            Param::CornerCos(i, j) => robot.modules[i].corner_angles[j].cos(),
            Param::CornerSin(i, j) => robot.modules[i].corner_angles[j].sin(),
            Param::Margin(i, j) => robot.modules[i].margins[j],
        }
    }
}

/// The parameter layout of a structure: module-major, corner-minor; then every module's
/// limits (written or the domain's defaults); then each obstacle's geometry, margin and watched points' numbers.
pub fn param_layout(structure: &Structure) -> Vec<Param> {
    let mut layout = Vec::new();
    for (i, &corners) in structure.corners.iter().enumerate() {
        layout.extend([
            Param::RestLength(i),
            Param::TendonRadius(i),
            Param::CornerRadius(i),
        ]);
        for j in 0..corners {
            layout.extend([
                Param::CornerCos(i, j),
                Param::CornerSin(i, j),
                Param::Margin(i, j),
            ]);
        }
    }
    for i in 0..structure.modules() {
        layout.extend([
            Param::ElongationMin(i),
            Param::ElongationMax(i),
            Param::ElongationMargin(i),
            Param::MaxBend(i),
            Param::BendMargin(i),
        ]);
    }
    for (o, obstacle) in structure.obstacles.iter().enumerate() {
        match obstacle.kind {
            crate::barriers::ObstacleKind::HalfSpace => {
                layout.extend((0..3).map(|c| Param::ObstacleNormal(o, c)));
                layout.push(Param::ObstacleOffset(o));
            }
            crate::barriers::ObstacleKind::Sphere => {
                layout.extend((0..3).map(|c| Param::ObstacleCenter(o, c)));
                layout.push(Param::ObstacleRadius(o));
            }
        }
        layout.push(Param::ObstacleMargin(o));
        for (k, &(_, shape)) in obstacle.watch.iter().enumerate() {
            match shape {
                PointShape::Listed => {
                    layout.extend((0..3).map(|c| Param::PointCoordinate(o, k, c)));
                }
                PointShape::Arc => layout.push(Param::ArcFraction(o, k)),
                PointShape::Corner(_) | PointShape::Centre => {}
            }
        }
    }
    layout
}

/// The parameter vector of a robot, in the order of [`param_layout`].
pub fn pack_params(robot: &Robot) -> Vec<f64> {
    param_layout(&robot.structure())
        .into_iter()
        .map(|p| p.value(robot))
        .collect()
}
