//! The robot's geometry frame by frame, for a view that draws it elsewhere (`softcbf
//! view`'s page in the browser): the same shapes the 3-D figure draws (backbone arcs,
//! tendons, plates, every corner barrier's corner and its foot on the plate below, every
//! environment barrier's watched point and the nearest point of its obstacle), the
//! obstacles with a half-space's patch across the scene, the scene's box and the figure's
//! camera, all in world coordinates \[m\]. Nothing is projected here.
//!
//! ```no_run
//! # use softcbf_core::{model::Model, record::Record};
//! # fn demo(model: &Model, filtered: &Record, plain: &Record) -> Result<(), softcbf_figures::plot::PlotError> {
//! use softcbf_figures::plot::robot_view::scene::{drawable_span, scene_frames};
//! let panels = [("safety filter (HOCBF-QP)", filtered), ("PD+ only", plain)];
//! let (start, end) = drawable_span(model, &panels)?.unwrap_or((0.0, 0.0));
//! let times: Vec<f64> = (0..=10).map(|k| start + (end - start) * k as f64 / 10.0).collect();
//! let scene = scene_frames(model, &panels, &times, None)?;
//! assert_eq!(scene.runs[0].frames.len(), 11);
//! # Ok(()) }
//! ```

use plotters::style::RGBColor;

use super::draw::{self, Scenery};
use super::shape::{self, Point, Shape, Solid};
use super::{
    Camera, DEFAULT_ACTIVE_BELOW, Scene, camera_angles, check_common, choose_camera, common_span,
    plan, runs, scenes, scenes_flat,
};
use crate::model::Model;
use crate::plot::PlotError;
use crate::record::Record;

/// The geometry of every run of a view at every frame time, and what stays put.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneFrames {
    /// The frame times asked for \[s\], in order.
    pub times: Vec<f64>,
    /// One entry per run, in the order given.
    pub runs: Vec<RunFrames>,
    /// The robot's obstacles that can be drawn, in file order.
    pub obstacles: Vec<Obstacle>,
    /// A box `(low, high)` \[m\] around every frame's robot (grown by a quarter of its
    /// largest side, as the figure's) and the obstacles' nearest parts; `None` when no
    /// frame has a finite shape.
    pub bounds: Option<([f64; 3], [f64; 3])>,
    /// The camera the 3-D figure would choose for these runs (looking across the bend of
    /// the module with the lowest corner barrier of the first run's final state).
    pub camera: Camera,
    /// Length of a half-space's normal arrow as the figure draws it \[m\].
    pub arrow: f64,
}

/// One run's frames.
#[derive(Clone, Debug, PartialEq)]
pub struct RunFrames {
    /// Its title (column title of the figures).
    pub title: String,
    /// One frame per time of [`SceneFrames::times`].
    pub frames: Vec<Frame>,
}

/// One run at one frame time: the nearest drawable row of its record.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// The record's row drawn; `None` when the record has no row with finite `t` and `q`.
    pub row: Option<usize>,
    /// That row's time \[s\] (NaN without a row).
    pub t: f64,
    /// Every barrier's value at that row (the record's, or the model's where the record's
    /// is not finite) \[m, or rad for a bend limit\], in the model's table order.
    pub b: Vec<f64>,
    /// Why the row's state cannot be used (then its barrier values mean nothing).
    pub invalid: Option<String>,
    /// The robot at that row; `None` without a row or with a non-finite shape.
    pub robot: Option<RobotShape>,
}

/// A robot at one state, in world coordinates \[m\].
#[derive(Clone, Debug, PartialEq)]
pub struct RobotShape {
    /// Points along each module's backbone, base to tip (17 each).
    pub backbones: Vec<Vec<[f64; 3]>>,
    /// Points along each tendon, per module (17 each).
    pub tendons: Vec<Vec<Vec<[f64; 3]>>>,
    /// Corners of plate 0 (the base) to plate N, in order around each plate.
    pub plates: Vec<Vec<[f64; 3]>>,
    /// Each corner barrier's corner, in the model's table order.
    pub corners: Vec<CornerPoint>,
    /// Each environment barrier's watched point, in the model's table order.
    pub watched: Vec<WatchedPoint>,
}

/// A corner barrier's corner (docs/model.md §3: its height above the plate below is the
/// barrier plus its margin).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CornerPoint {
    /// The barrier (index into the model's table).
    pub barrier: usize,
    /// The module (0-based) whose top plate carries the corner.
    pub module: usize,
    /// The corner \[m\].
    pub at: [f64; 3],
    /// Its foot on the plane of the plate below \[m\].
    pub foot: [f64; 3],
}

/// An environment barrier's watched point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WatchedPoint {
    /// The barrier (index into the model's table).
    pub barrier: usize,
    /// The module (0-based) that carries the point.
    pub module: usize,
    /// The obstacle (0-based, file order) it stays out of.
    pub obstacle: usize,
    /// The point \[m\].
    pub at: [f64; 3],
    /// The obstacle's surface point nearest to it \[m\], if the obstacle can be drawn.
    pub nearest: Option<[f64; 3]>,
    /// Whether it lies on the backbone (else fixed in the top plate).
    pub arc: bool,
}

/// An obstacle as drawn.
#[derive(Clone, Debug, PartialEq)]
pub enum Obstacle {
    /// The ball `|x − centre| < radius`, kept `margin` away.
    Sphere {
        /// Obstacle index in the robot file (0-based).
        index: usize,
        /// Centre \[m\].
        centre: [f64; 3],
        /// Radius \[m\].
        radius: f64,
        /// Margin `ε` \[m\].
        margin: f64,
    },
    /// The half-space `normal·x < offset` (unit normal into the allowed side), kept
    /// `margin` away.
    HalfSpace {
        /// Obstacle index in the robot file (0-based).
        index: usize,
        /// Unit normal, into the allowed side.
        normal: [f64; 3],
        /// Offset \[m\].
        offset: f64,
        /// Margin `ε` \[m\].
        margin: f64,
        /// The polygon where its plane crosses the scene's box (empty if it misses it).
        patch: Vec<[f64; 3]>,
    },
}

/// The colours the 3-D figure draws with, by name (`backbone`, `tendon`, `plate_fill`,
/// `plate_edge`, `base_fill`, `base_edge`, `active`, `violated`, `clear`, `sphere_fill`,
/// `sphere_edge`, `wall_fill`, `wall_edge`, `watched`, `text`, `muted`), as `#rrggbb`, so
/// that a view drawn elsewhere looks like it.
pub fn palette() -> Vec<(&'static str, String)> {
    let hex = |RGBColor(r, g, b): RGBColor| format!("#{r:02x}{g:02x}{b:02x}");
    [
        ("backbone", draw::BACKBONE),
        ("tendon", draw::TENDON),
        ("plate_fill", draw::PLATE_FILL),
        ("plate_edge", draw::PLATE_EDGE),
        ("base_fill", draw::BASE_FILL),
        ("base_edge", draw::BASE_EDGE),
        ("active", draw::ACTIVE),
        ("violated", draw::VIOLATED),
        ("clear", draw::CLEAR),
        ("sphere_fill", draw::SPHERE_FILL),
        ("sphere_edge", draw::SPHERE_EDGE),
        ("wall_fill", draw::WALL_FILL),
        ("wall_edge", draw::WALL_EDGE),
        ("watched", draw::WATCHED),
        ("text", draw::TEXT),
        ("muted", draw::MUTED),
    ]
    .into_iter()
    .map(|(name, colour)| (name, hex(colour)))
    .collect()
}

/// The span `(first, last)` \[s\] of the rows of `panels` that can be drawn (finite `t`
/// and `q`); `None` if no record has one. Errors as [`scene_frames`].
pub fn drawable_span(
    model: &Model,
    panels: &[(&str, &Record)],
) -> Result<Option<(f64, f64)>, PlotError> {
    Ok(common_span(&runs(model, panels)?))
}

/// The geometry of every run of `panels` (title, record with `model`'s coordinates and
/// barriers) at each of `times` \[s\] (each frame the nearest drawable row, as the 3-D
/// figure's snapshots), with `camera` or the figure's choice of one. Refuses no panels, an
/// empty record, a record of other sizes than the model's, a non-finite time and a camera
/// out of range.
pub fn scene_frames(
    model: &Model,
    panels: &[(&str, &Record)],
    times: &[f64],
    camera: Option<Camera>,
) -> Result<SceneFrames, PlotError> {
    let invalid = |message: String| PlotError::Draw {
        file: "<scene>".into(),
        message,
    };
    check_common(DEFAULT_ACTIVE_BELOW, camera).map_err(invalid)?;
    if let Some(t) = times.iter().find(|t| !t.is_finite()) {
        return Err(invalid(format!("frame time {t}: give finite times")));
    }
    let runs = runs(model, panels)?;
    let scenes = scenes(
        model,
        &runs,
        plan(model, &runs, times, DEFAULT_ACTIVE_BELOW),
    );
    let finals = scenes_flat(
        model,
        &runs,
        plan(
            model,
            &runs,
            &[common_span(&runs).map_or(0.0, |s| s.1)],
            DEFAULT_ACTIVE_BELOW,
        ),
    );
    let projection = choose_camera(camera, finals.first());
    let shapes = || scenes.iter().flatten().filter_map(|s| s.shape.as_ref());
    let scenery = Scenery::new(model, shapes());
    let bounds = scene_bounds(shapes(), &scenery);
    let obstacles = obstacles(&scenery);
    let runs = runs
        .iter()
        .zip(&scenes)
        .map(|(run, scenes)| RunFrames {
            title: run.title.to_string(),
            frames: scenes.iter().map(|scene| frame(scene, &scenery)).collect(),
        })
        .collect();
    Ok(SceneFrames {
        times: times.to_vec(),
        runs,
        obstacles,
        bounds,
        camera: camera.unwrap_or(camera_angles(&projection)),
        arrow: scenery.arrow,
    })
}

/// The scene's box: every shape's points as `shape::scene_box` grows them, widened to
/// each sphere's near side and each half-space's patch.
fn scene_bounds<'s>(
    shapes: impl Iterator<Item = &'s Shape>,
    scenery: &Scenery,
) -> Option<([f64; 3], [f64; 3])> {
    let (low, high) = shape::scene_box(shapes)?;
    let middle: Point = std::array::from_fn(|k| 0.5 * (low[k] + high[k]));
    let side = (0..3).map(|k| high[k] - low[k]).fold(0.0, f64::max);
    let mut extra: Vec<Point> = Vec::new();
    for (solid, patch) in &scenery.solids {
        match *solid {
            Solid::Sphere { centre, radius, .. } => {
                // The sphere whole when it is small beside the robot, else its near part.
                if radius <= side {
                    for k in 0..3 {
                        for sign in [-1.0, 1.0] {
                            let mut p = centre;
                            p[k] += sign * radius;
                            extra.push(p);
                        }
                    }
                } else if let Some(near) = solid.nearest(middle) {
                    extra.push(near);
                }
            }
            Solid::HalfSpace { .. } => extra.extend_from_slice(patch),
        }
    }
    let (mut low, mut high) = (low, high);
    for p in extra
        .into_iter()
        .filter(|p| p.iter().all(|x| x.is_finite()))
    {
        low = std::array::from_fn(|k| low[k].min(p[k]));
        high = std::array::from_fn(|k| high[k].max(p[k]));
    }
    Some((low, high))
}

fn obstacles(scenery: &Scenery) -> Vec<Obstacle> {
    scenery
        .by_index
        .iter()
        .enumerate()
        .filter_map(|(index, solid)| {
            let solid = (*solid)?;
            Some(match solid {
                Solid::Sphere {
                    centre,
                    radius,
                    margin,
                } => Obstacle::Sphere {
                    index,
                    centre,
                    radius,
                    margin,
                },
                Solid::HalfSpace {
                    normal,
                    offset,
                    margin,
                } => Obstacle::HalfSpace {
                    index,
                    normal,
                    offset,
                    margin,
                    patch: scenery
                        .solids
                        .iter()
                        .find(|(s, _)| *s == solid)
                        .map(|(_, patch)| patch.clone())
                        .unwrap_or_default(),
                },
            })
        })
        .collect()
}

fn frame(scene: &Scene, scenery: &Scenery) -> Frame {
    let snapshot = &scene.snapshot;
    Frame {
        row: snapshot.row,
        t: snapshot.t,
        b: snapshot.b.clone(),
        invalid: snapshot.invalid.clone(),
        robot: scene
            .shape
            .as_ref()
            .map(|shape| robot_shape(shape, scenery)),
    }
}

fn robot_shape(shape: &Shape, scenery: &Scenery) -> RobotShape {
    let corners = shape
        .corners
        .iter()
        .enumerate()
        .filter_map(|(barrier, gap)| {
            let gap = gap.as_ref()?;
            Some(CornerPoint {
                barrier,
                module: gap.module,
                at: gap.corner,
                foot: gap.foot,
            })
        })
        .collect();
    let watched = shape
        .watched
        .iter()
        .enumerate()
        .filter_map(|(barrier, mark)| {
            let mark = mark.as_ref()?;
            let solid = scenery.by_index.get(mark.obstacle).copied().flatten();
            Some(WatchedPoint {
                barrier,
                module: mark.module,
                obstacle: mark.obstacle,
                at: mark.at,
                nearest: solid.and_then(|s| s.nearest(mark.at)),
                arc: mark.arc,
            })
        })
        .collect();
    RobotShape {
        backbones: shape.backbones.clone(),
        tendons: shape.tendons.clone(),
        plates: shape.plates.clone(),
        corners,
        watched,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::{Columns, Record, Row};
    use softcbf_description::robot::Robot;

    /// A record of `model` with the rows `(t, q)`, barriers from the model.
    fn record(model: &Model, rows: &[(f64, Vec<f64>)]) -> Record {
        let columns = Columns::for_model(model, &[]).unwrap();
        let mut record = Record::for_columns(columns, rows.len());
        let zero = vec![0.0; model.nq()];
        let mut b = vec![0.0; model.nb()];
        for (t, q) in rows {
            model.generated.barriers(&model.params, q, &mut b);
            record
                .push_row(&Row {
                    t: *t,
                    q,
                    qd: &zero,
                    tau: &zero,
                    tau_nom: &zero,
                    b: &b,
                    extra: &[],
                })
                .unwrap();
        }
        record
    }

    #[test]
    fn frames_take_the_nearest_row_and_a_straight_robot_stands_on_z() {
        let model = Model::new(Robot::paper_sim()).unwrap();
        let bent = vec![0.03, -0.02, -0.01, -0.01, 0.05, 0.02];
        let rec = record(&model, &[(0.0, vec![0.0; 6]), (1.0, bent.clone())]);
        let panels = [("run", &rec)];
        assert_eq!(drawable_span(&model, &panels).unwrap(), Some((0.0, 1.0)));
        let scene = scene_frames(&model, &panels, &[0.2, 0.7], None).unwrap();
        let frames = &scene.runs[0].frames;
        assert_eq!(frames[0].row, Some(0));
        assert_eq!(frames[1].row, Some(1));
        assert_eq!(frames[1].t, 1.0);
        // Straight: the backbone runs up the z axis to the sum of the rest lengths, the
        // base plate's corners lie at the corner radius in z = 0.
        let straight = frames[0].robot.as_ref().unwrap();
        let mut z = 0.0;
        for (i, module) in model.robot.modules.iter().enumerate() {
            let backbone = &straight.backbones[i];
            assert_eq!(backbone.len(), 17);
            for (k, p) in backbone.iter().enumerate() {
                let expected = z + module.rest_length * k as f64 / 16.0;
                assert!(p[0].abs() < 1e-15 && p[1].abs() < 1e-15, "{p:?}");
                assert!((p[2] - expected).abs() < 1e-12, "{p:?} vs {expected}");
            }
            z += module.rest_length;
        }
        let r = model.robot.modules[0].corner_radius;
        for p in &straight.plates[0] {
            assert!(p[2].abs() < 1e-15);
            assert!(((p[0] * p[0] + p[1] * p[1]).sqrt() - r).abs() < 1e-12);
        }
        // Every corner barrier has its corner, whose height above the foot is b + ε.
        let bent_robot = frames[1].robot.as_ref().unwrap();
        assert_eq!(bent_robot.corners.len(), 12);
        for corner in &bent_robot.corners {
            let b = frames[1].b[corner.barrier];
            let margin = crate::barrier_info::margin(&model, corner.barrier).unwrap();
            let d: f64 = (0..3)
                .map(|k| (corner.at[k] - corner.foot[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(
                (d - (b + margin).abs()).abs() < 1e-12,
                "{d} vs {b} + {margin}"
            );
        }
        let (low, high) = scene.bounds.unwrap();
        for p in bent_robot.backbones.iter().flatten() {
            assert!((0..3).all(|k| low[k] < p[k] && p[k] < high[k]));
        }
        assert!(scene.obstacles.is_empty());
    }

    #[test]
    fn bad_times_and_empty_runs_are_refused() {
        let model = Model::new(Robot::paper_sim()).unwrap();
        let rec = record(&model, &[(0.0, vec![0.0; 6])]);
        assert!(scene_frames(&model, &[("run", &rec)], &[f64::NAN], None).is_err());
        assert!(matches!(
            scene_frames(&model, &[], &[0.0], None),
            Err(PlotError::NoPanels)
        ));
        let empty = record(&model, &[]);
        assert!(matches!(
            scene_frames(&model, &[("empty", &empty)], &[0.0], None),
            Err(PlotError::EmptyRecord { .. })
        ));
    }
}
