//! The numbers behind each barrier of a model — margin, limit, obstacle geometry, watched
//! point — looked up in the robot description through the generated barrier table's row.
//!
//! The generated table ([`softcbf_generated::BarrierInfo`]) says what barrier `k` is and
//! where it sits (kind, module, point, obstacle); the numbers are the robot's
//! ([`Model::robot`]): its modules' corner radii, angles and margins, its
//! [`Limits`](softcbf_description::barriers::Limits) and its [`Obstacle`]s. Every report
//! that shows a barrier's numbers (`softcbf model`, the figures) reads them here. A `k`
//! past the table, or a row the robot does not match, gives `None`, never a panic.

use serde_json::{Map, Value, json};
use softcbf_description::barriers::{BarrierKind, KindGroup, Obstacle, Shape, WatchedPoint};
use softcbf_generated::{BarrierInfo, Point};

use crate::model::Model;

/// Row `k` of the model's barrier table.
pub fn info(model: &Model, k: usize) -> Option<&'static BarrierInfo> {
    model.generated.barrier_table().get(k)
}

/// The obstacle barrier `k` watches for (environment barriers only).
pub fn obstacle(model: &Model, k: usize) -> Option<&Obstacle> {
    model.robot.obstacles.get(info(model, k)?.obstacle?)
}

/// The margin `ε` of barrier `k`: a corner's margin \[m\], the elongation margin \[m\], the
/// bend margin \[rad\] or the obstacle's margin \[m\].
pub fn margin(model: &Model, k: usize) -> Option<f64> {
    let info = info(model, k)?;
    let module = info.module;
    match info.kind {
        BarrierKind::PlateCorner => {
            let j = info.corner()?;
            model.robot.modules.get(module)?.margins.get(j).copied()
        }
        BarrierKind::ElongationMin | BarrierKind::ElongationMax => {
            Some(model.robot.limits.get(module)?.elongation_margin)
        }
        BarrierKind::Bend => Some(model.robot.limits.get(module)?.bend_margin),
        BarrierKind::HalfSpace | BarrierKind::Sphere => obstacle(model, k).map(|o| o.margin),
    }
}

/// The point barrier `k` watches with its numbers: a corner, the centre or a listed point
/// of its module's top plate, or a backbone point; `None` for a limit.
pub fn watched_point(model: &Model, k: usize) -> Option<WatchedPoint> {
    let info = info(model, k)?;
    match info.point? {
        Point::Corner(j) => Some(WatchedPoint::Corner(j)),
        Point::Centre => Some(WatchedPoint::Centre),
        Point::Listed(entry) | Point::Arc(entry) => {
            let watched = obstacle(model, k)?.watch.get(entry)?;
            (watched.module == info.module).then_some(watched.point)
        }
    }
}

/// The watched point of barrier `k` in its module's top-plate frame \[m\], for a point
/// fixed in the plate: corner `j` at `(r cos φ_j, r sin φ_j, 0)`, the centre at the origin,
/// a listed point as listed. `None` for a limit or a backbone point.
pub fn plate_point(model: &Model, k: usize) -> Option<[f64; 3]> {
    let module = model.robot.modules.get(info(model, k)?.module)?;
    match watched_point(model, k)? {
        WatchedPoint::Corner(j) => {
            let phi = *module.corner_angles.get(j)?;
            let r = module.corner_radius;
            Some([r * phi.cos(), r * phi.sin(), 0.0])
        }
        WatchedPoint::Centre => Some([0.0; 3]),
        WatchedPoint::Listed(point) => Some(point),
        WatchedPoint::Arc(_) => None,
    }
}

/// The arc fraction `s ∈ (0, 1]` of barrier `k`'s backbone point, if it watches one.
pub fn arc_fraction(model: &Model, k: usize) -> Option<f64> {
    match watched_point(model, k)? {
        WatchedPoint::Arc(s) => Some(s),
        _ => None,
    }
}

/// Barrier `k` as one JSON object (`softcbf model`'s `barrier_info`): `kind`
/// ([`BarrierKind::key`]), `module` (1-based), `label`, `margin`, `unit` (of its value and
/// margin); for a limit its values (`min` and `max` \[m\], or `max_bend` \[rad\]) and
/// `domain_default` (`true` when the robot file writes no such limit and the model's
/// domain default applies, docs/model.md §3); for a
/// watched corner its number (`corner`, 1-based); for an environment barrier the `obstacle`
/// (1-based) and its geometry (`center` and `radius`, or `normal` and `offset`); for a point
/// fixed in a plate `point` (plate coordinates \[m\]), for a backbone point `arc_fraction`.
pub fn describe(model: &Model, k: usize) -> Option<Value> {
    let info = info(model, k)?;
    let mut entry = Map::new();
    entry.insert("kind".into(), json!(info.kind.key()));
    entry.insert("module".into(), json!(info.module + 1));
    entry.insert("label".into(), json!(info.label));
    entry.insert("margin".into(), json!(margin(model, k)?));
    entry.insert("unit".into(), json!(info.kind.unit()));
    let limits = model.robot.limits.get(info.module);
    match info.kind {
        BarrierKind::ElongationMin | BarrierKind::ElongationMax => {
            let [min, max] = limits?.elongation;
            entry.insert("min".into(), json!(min));
            entry.insert("max".into(), json!(max));
        }
        BarrierKind::Bend => {
            entry.insert("max_bend".into(), json!(limits?.max_bend));
        }
        BarrierKind::PlateCorner | BarrierKind::HalfSpace | BarrierKind::Sphere => {}
    }
    if let Some(limits) = limits
        && matches!(info.kind.group(), KindGroup::Elongation | KindGroup::Bend)
    {
        entry.insert(
            "domain_default".into(),
            json!(limits.is_domain_default(info.kind)),
        );
    }
    if let Some(o) = info.obstacle {
        entry.insert("obstacle".into(), json!(o + 1));
        match model.robot.obstacles.get(o)?.shape {
            Shape::Sphere { center, radius } => {
                entry.insert("center".into(), json!(center));
                entry.insert("radius".into(), json!(radius));
            }
            Shape::HalfSpace { normal, offset } => {
                entry.insert("normal".into(), json!(normal));
                entry.insert("offset".into(), json!(offset));
            }
        }
    }
    if let Some(Point::Corner(j)) = info.point {
        entry.insert("corner".into(), json!(j + 1));
    }
    if info.point.is_some() {
        match (plate_point(model, k), arc_fraction(model, k)) {
            (Some(point), _) => entry.insert("point".into(), json!(point)),
            (None, Some(s)) => entry.insert("arc_fraction".into(), json!(s)),
            (None, None) => return None,
        };
    }
    Some(Value::Object(entry))
}

/// Every barrier of the model described by [`describe`], in barrier order; a barrier whose
/// numbers the robot does not have (a robot that does not match its model) is `null`.
pub fn describe_all(model: &Model) -> Value {
    (0..model.nb())
        .map(|k| describe(model, k).unwrap_or(Value::Null))
        .collect()
}
