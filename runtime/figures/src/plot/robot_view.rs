//! A 3-D view of the simulated or logged robot, like the paper's Figs. 5–6: each run (row)
//! at a few snapshot times and a zoom on its final state's gaps, and an animated GIF.
//!
//! The robot is drawn from the model's generated kinematics (`docs/model.md` §2–3) in a
//! fixed orthographic projection with equal axis scales: every module's backbone arc, its
//! tendons (offset curves at the tendon radius, parallel to the backbone), the plates as
//! polygons through their corners and the base plate. The robot file's obstacles are
//! drawn with it: a sphere as a shaded ball with a dashed outline at its radius plus
//! margin, a half-space as a translucent patch of its plane across the scene with an arrow
//! to the allowed side; the points they watch are dots (backbone points at their arc
//! fractions). A corner or watched point whose barrier is at most
//! [`ViewOptions::active_below`] is ringed in orange (below its margin by more than the
//! verdict's tolerance, [`violated`]: in red), with a dashed
//! line down to its foot on the plane of the plate below (the barrier measures that
//! height) or to the nearest point of the obstacle. The zoom column looks at the final
//! state edge-on, along the bend axis of the module with the lowest corner barrier, and
//! annotates that barrier in millimetres above the margin band `ε`; its note also names
//! the lowest barrier of any kind. Only the snapshot rows of a record are evaluated.
//! [`scene`] gives the same shapes at any frame times, unprojected, for a view drawn
//! elsewhere (`softcbf view`'s page in the browser).
//!
//! ```no_run
//! # use softcbf_core::{model::Model, record::Record};
//! # fn demo(model: &Model, filtered: &Record, plain: &Record) -> Result<(), softcbf_figures::plot::PlotError> {
//! use softcbf_figures::plot::robot_view::{ViewOptions, draw_robot_views};
//! let panels = [("safety filter (HOCBF-QP)", filtered), ("PD+ only", plain)];
//! let files = draw_robot_views("out".as_ref(), "robot", model, &panels, &ViewOptions::default())?;
//! assert_eq!(files.len(), 2); // out/robot.png, out/robot.svg
//! # Ok(()) }
//! ```

use std::path::{Path, PathBuf};

use plotters::prelude::{BitMapBackend, IntoDrawingArea, SVGBackend};

#[path = "robot_draw.rs"]
mod draw;
#[path = "robot_gif.rs"]
mod gif_file;
#[path = "robot_scene.rs"]
pub mod scene;
#[path = "robot_shape.rs"]
mod shape;

use super::{PlotError, register_fonts, write_png};
use crate::model::Model;
use crate::record::Record;
use draw::{
    AnimationFrame, FRAME_CELL, FRAME_STRIP, Figure, Scenery, TITLE_HEIGHT, draw_figure,
    draw_frame, extent, fit,
};
use shape::{Kinematics, Projection, Rect, Shape};

/// Where the camera looks from, for every view of a figure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Angle from the world x axis toward +y of the direction to the camera \[deg\].
    pub azimuth_deg: f64,
    /// Angle of the camera above the base plate's plane \[deg\], in `[−90, 90]`.
    pub elevation_deg: f64,
}

/// What [`draw_robot_views`] draws.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewOptions {
    /// Snapshot times \[s\], the same for every run (a time outside a record shows its
    /// nearest row, and says so); empty: [`ViewOptions::snapshots`] times chosen
    /// automatically (see [`snapshot_times`]).
    pub times: Vec<f64>,
    /// How many snapshots to choose when `times` is empty (1 to 8).
    pub snapshots: usize,
    /// A corner or watched point is highlighted when its barrier `b ≤ active_below` \[m\]
    /// (default 0.5 mm: resting on its margin); below zero it is drawn as a violation.
    pub active_below: f64,
    /// The camera; `None` chooses one from the first run's final state: looking across
    /// the bend of the module with the lowest corner barrier, 30° around from side-on, 15°
    /// above.
    pub camera: Option<Camera>,
}

impl Default for ViewOptions {
    fn default() -> ViewOptions {
        ViewOptions {
            times: Vec::new(),
            snapshots: 4,
            active_below: DEFAULT_ACTIVE_BELOW,
            camera: None,
        }
    }
}

/// Default [`ViewOptions::active_below`] \[m\].
pub const DEFAULT_ACTIVE_BELOW: f64 = 5e-4;

/// What [`animate_robot`] draws.
#[derive(Clone, Debug, PartialEq)]
pub struct AnimationOptions {
    /// Frames per second of playback (1 to 50; GIF delays are whole hundredths).
    pub fps: f64,
    /// Playback length \[s\] (0.1 to 120).
    pub duration: f64,
    /// Share of playback spread evenly over the run's time; the rest follows how far the
    /// robot moves, which slows the transient down (1: uniform time, default 0.3).
    pub uniform: f64,
    /// As [`ViewOptions::active_below`].
    pub active_below: f64,
    /// As [`ViewOptions::camera`].
    pub camera: Option<Camera>,
}

impl Default for AnimationOptions {
    fn default() -> AnimationOptions {
        AnimationOptions {
            fps: 25.0,
            duration: 6.0,
            uniform: 0.3,
            active_below: DEFAULT_ACTIVE_BELOW,
            camera: None,
        }
    }
}

/// One snapshot of one run as it is drawn.
#[derive(Clone, Debug, PartialEq)]
pub struct Snapshot {
    /// The time asked for \[s\].
    pub asked: f64,
    /// The record's row drawn (the nearest row with finite `t` and `q`); `None` if the
    /// record has none.
    pub row: Option<usize>,
    /// That row's time \[s\] (NaN without a row).
    pub t: f64,
    /// Each barrier's value at that row \[m\]: the record's, or the model's where the
    /// record's is not finite.
    pub b: Vec<f64>,
    /// Barriers (indices into the model's barrier table) with `b ≤ active_below`,
    /// including those below zero.
    pub active: Vec<usize>,
    /// Barriers below their margin beyond rounding ([`violated`]).
    pub violated: Vec<usize>,
    /// Why the state of that row cannot be used ([`super::invalid::state_problem`]: not
    /// finite, or outside the model's domain); then its barrier values mean nothing and
    /// none is counted active or violated. `None`: a valid state.
    pub invalid: Option<String>,
}

/// Whether a barrier value `b` \[m or rad\] is drawn as violated: below zero by more than
/// [`softcbf_description::limits::BARRIER_TOLERANCE_M`], the tolerance of the verdict
/// (`softcbf verify`'s default threshold). A barrier held at zero to rounding (−1.6e-12 m)
/// is on its margin, not past it.
pub fn violated(b: f64) -> bool {
    b < -softcbf_description::limits::BARRIER_TOLERANCE_M
}

/// The violation tolerance as the figures print it: `1 µm`.
pub(crate) fn tolerance_text() -> String {
    let micrometres = softcbf_description::limits::BARRIER_TOLERANCE_M * 1e6;
    format!("{} µm", super::series::short_number(micrometres))
}

/// World frames `W_{i−1} T_i(s)` of every module's backbone at arc fraction `s` (0: the
/// module's bottom plate, 1: its top plate, `docs/model.md` §2), at state `q` (`3N`
/// values), row-major 4×4. Evaluated with the generated segment transforms at rest length
/// `s·L0` and coordinates `s·q`: the arc of bend `sθ` and length `sL`.
pub fn backbone_frames(model: &Model, q: &[f64], s: f64) -> Result<Vec<[[f64; 4]; 4]>, PlotError> {
    if q.len() != model.nq() {
        return Err(PlotError::Mismatch {
            title: model.robot.name.clone(),
            what: "the number of coordinates",
            expected: model.nq(),
            found: q.len(),
        });
    }
    Ok(Kinematics::new(model).frames_at(q, s))
}

/// A run as drawn: its title, record and the rows that can be drawn.
struct Run<'a> {
    title: &'a str,
    record: &'a Record,
    /// Each coordinate's column.
    q: Vec<Vec<f64>>,
    /// `(row, t)` of the rows with finite `t` and `q`, in time order.
    valid: Vec<(usize, f64)>,
    /// Distance travelled in `q` up to each valid row, over the total (0 to 1; all 0 if
    /// the robot never moves).
    travelled: Vec<f64>,
}

impl<'a> Run<'a> {
    fn new(title: &'a str, record: &'a Record, model: &Model) -> Result<Run<'a>, PlotError> {
        let (n, m) = (record.columns().n(), record.columns().m());
        let times: Vec<f64> = record.times().collect();
        if times.is_empty() {
            return Err(PlotError::EmptyRecord {
                title: title.to_string(),
            });
        }
        for (what, expected, found) in [
            ("the number of coordinates", model.nq(), n),
            ("the number of barriers", model.nb(), m),
        ] {
            if expected != found {
                return Err(PlotError::Mismatch {
                    title: title.to_string(),
                    what,
                    expected,
                    found,
                });
            }
        }
        let q: Vec<Vec<f64>> = (0..n).map(|i| record.q(i).collect()).collect();
        let mut valid: Vec<(usize, f64)> = times
            .iter()
            .enumerate()
            .filter(|&(row, t)| t.is_finite() && q.iter().all(|c| c[row].is_finite()))
            .map(|(row, &t)| (row, t))
            .collect();
        valid.sort_by(|a, b| a.1.total_cmp(&b.1));
        let mut travelled = Vec::with_capacity(valid.len());
        let mut total = 0.0;
        for (k, &(row, _)) in valid.iter().enumerate() {
            if k > 0 {
                let previous = valid[k - 1].0;
                let step: f64 = q.iter().map(|c| (c[row] - c[previous]).powi(2)).sum();
                total += step.sqrt();
            }
            travelled.push(total);
        }
        if total > 0.0 && total.is_finite() {
            travelled.iter_mut().for_each(|x| *x /= total);
        } else {
            travelled.iter_mut().for_each(|x| *x = 0.0);
        }
        Ok(Run {
            title,
            record,
            q,
            valid,
            travelled,
        })
    }

    /// The valid row nearest to `t` (the first of equals), with its time.
    fn nearest(&self, t: f64) -> Option<(usize, f64)> {
        if !t.is_finite() {
            return None;
        }
        let after = self.valid.partition_point(|&(_, s)| s < t);
        let candidates = [after.checked_sub(1), Some(after)];
        candidates
            .into_iter()
            .flatten()
            .filter_map(|k| self.valid.get(k).copied())
            .min_by(|a, b| (a.1 - t).abs().total_cmp(&(b.1 - t).abs()))
    }

    fn q_at(&self, row: usize) -> Vec<f64> {
        self.q.iter().map(|c| c[row]).collect()
    }

    /// Share of the run's travel done by time `t` (linear between rows).
    fn travelled_at(&self, t: f64) -> f64 {
        let after = self.valid.partition_point(|&(_, s)| s < t);
        match (after.checked_sub(1), self.valid.get(after)) {
            (None, _) => 0.0,
            (Some(k), None) => self.travelled[k],
            (Some(k), Some(&(_, t1))) => {
                let t0 = self.valid[k].1;
                let (p0, p1) = (self.travelled[k], self.travelled[k + 1]);
                if t1 > t0 {
                    p0 + (p1 - p0) * (t - t0) / (t1 - t0)
                } else {
                    p1
                }
            }
        }
    }

    fn span(&self) -> Option<(f64, f64)> {
        Some((self.valid.first()?.1, self.valid.last()?.1))
    }
}

fn runs<'a>(model: &Model, panels: &'a [(&'a str, &'a Record)]) -> Result<Vec<Run<'a>>, PlotError> {
    if panels.is_empty() {
        return Err(PlotError::NoPanels);
    }
    panels
        .iter()
        .map(|(title, record)| Run::new(title, record, model))
        .collect()
}

/// The span of time covered by the valid rows of all runs.
fn common_span(runs: &[Run]) -> Option<(f64, f64)> {
    runs.iter()
        .filter_map(Run::span)
        .reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))
}

/// A time warp `w(t)` in `[0, 1]`: the share `uniform` of it linear in `t`, the rest the
/// mean share of travel done by `t`; `inverse(u)` finds `t` with `w(t) = u` by bisection.
struct Warp<'r, 'a> {
    runs: &'r [Run<'a>],
    span: (f64, f64),
    uniform: f64,
}

impl Warp<'_, '_> {
    fn at(&self, t: f64) -> f64 {
        let (t0, t1) = self.span;
        let linear = if t1 > t0 { (t - t0) / (t1 - t0) } else { 1.0 };
        let moving: Vec<&Run> = self
            .runs
            .iter()
            .filter(|r| r.travelled.last().is_some_and(|&x| x > 0.0))
            .collect();
        let travel = if moving.is_empty() {
            linear
        } else {
            moving.iter().map(|r| r.travelled_at(t)).sum::<f64>() / moving.len() as f64
        };
        self.uniform * linear + (1.0 - self.uniform) * travel
    }

    fn inverse(&self, u: f64) -> f64 {
        let (mut low, mut high) = self.span;
        for _ in 0..60 {
            let mid = 0.5 * (low + high);
            if self.at(mid) < u {
                low = mid;
            } else {
                high = mid;
            }
        }
        high
    }
}

/// `t` rounded to two significant digits (snapshot times read as `0.15 s`, not
/// `0.1487 s`), kept within `[low, high]`.
fn round_time(t: f64, low: f64, high: f64) -> f64 {
    if t == 0.0 || !t.is_finite() {
        return t;
    }
    // Divide by an exact power of ten so that 3.26 becomes the double nearest 3.3.
    let exponent = t.abs().log10().floor() as i32 - 1;
    let rounded = if exponent < 0 {
        let scale = 10f64.powi(-exponent);
        (t * scale).round() / scale
    } else {
        let unit = 10f64.powi(exponent);
        (t / unit).round() * unit
    };
    rounded.clamp(low, high)
}

/// The snapshot times chosen when none are given: the first and last times of the runs
/// and `count − 2` times in between at equal shares of the robot's travel in `q` (mean
/// over the runs, with 10% weight on elapsed time), so that a fast transient gets most
/// snapshots; rounded to two significant digits. Fewer if the runs span one instant.
pub fn snapshot_times(
    model: &Model,
    panels: &[(&str, &Record)],
    count: usize,
) -> Result<Vec<f64>, PlotError> {
    let runs = runs(model, panels)?;
    Ok(choose_times(&runs, count))
}

fn choose_times(runs: &[Run], count: usize) -> Vec<f64> {
    let Some(span) = common_span(runs) else {
        return Vec::new();
    };
    let count = count.max(1);
    let warp = Warp {
        runs,
        span,
        uniform: 0.1,
    };
    let mut times = Vec::with_capacity(count);
    for k in 0..count {
        let t = if k == 0 {
            span.0
        } else if k == count - 1 {
            span.1
        } else {
            round_time(warp.inverse(k as f64 / (count - 1) as f64), span.0, span.1)
        };
        if times.last() != Some(&t) {
            times.push(t);
        }
    }
    times
}

/// The snapshots [`draw_robot_views`] draws for each run (outer: runs, inner: times):
/// the nearest drawable row to each of `times` (non-finite times are left out), its
/// barrier values and which barriers count as active (`b ≤ active_below`) or violated.
pub fn plan_snapshots(
    model: &Model,
    panels: &[(&str, &Record)],
    times: &[f64],
    active_below: f64,
) -> Result<Vec<Vec<Snapshot>>, PlotError> {
    let runs = runs(model, panels)?;
    Ok(plan(model, &runs, times, active_below))
}

fn plan(model: &Model, runs: &[Run], times: &[f64], active_below: f64) -> Vec<Vec<Snapshot>> {
    runs.iter()
        .map(|run| {
            times
                .iter()
                .filter(|t| t.is_finite())
                .map(|&asked| snapshot(model, run, asked, active_below))
                .collect()
        })
        .collect()
}

fn snapshot(model: &Model, run: &Run, asked: f64, active_below: f64) -> Snapshot {
    let m = model.nb();
    let Some((row, t)) = run.nearest(asked) else {
        return Snapshot {
            asked,
            row: None,
            t: f64::NAN,
            b: vec![f64::NAN; m],
            active: Vec::new(),
            violated: Vec::new(),
            invalid: None,
        };
    };
    let q = run.q_at(row);
    let qd: Vec<f64> = run
        .record
        .row(row)
        .map_or_else(|| vec![f64::NAN; q.len()], |r| r.qd.to_vec());
    let invalid = super::invalid::state_problem(Some(&model.robot), &q, &qd);
    let mut b: Vec<f64> = (0..m)
        .map(|j| run.record.b(j).nth(row).unwrap_or(f64::NAN))
        .collect();
    if b.iter().any(|v| !v.is_finite()) {
        let mut from_model = vec![0.0; m];
        model
            .generated
            .barriers(&model.params, &run.q_at(row), &mut from_model);
        for (value, computed) in b.iter_mut().zip(from_model) {
            if !value.is_finite() {
                *value = computed;
            }
        }
    }
    let (active, violated) = if invalid.is_some() {
        (Vec::new(), Vec::new())
    } else {
        (
            (0..m).filter(|&j| b[j] <= active_below).collect(),
            (0..m).filter(|&j| violated(b[j])).collect(),
        )
    };
    Snapshot {
        asked,
        row: Some(row),
        t,
        b,
        active,
        violated,
        invalid,
    }
}

/// A snapshot with its shape.
struct Scene {
    snapshot: Snapshot,
    shape: Option<Shape>,
}

fn scenes(model: &Model, runs: &[Run], plan: Vec<Vec<Snapshot>>) -> Vec<Vec<Scene>> {
    let mut kinematics = Kinematics::new(model);
    plan.into_iter()
        .zip(runs)
        .map(|(snapshots, run)| {
            snapshots
                .into_iter()
                .map(|snapshot| {
                    let shape = snapshot
                        .row
                        .map(|row| kinematics.shape(&run.q_at(row)))
                        .filter(Shape::is_finite);
                    Scene { snapshot, shape }
                })
                .collect()
        })
        .collect()
}

/// The lowest barrier of a snapshot, `(index, value)`.
fn lowest(snapshot: &Snapshot) -> Option<(usize, f64)> {
    snapshot
        .b
        .iter()
        .copied()
        .enumerate()
        .filter(|(_, b)| b.is_finite())
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// The lowest corner barrier of a scene, `(index, value)`: the gap its zoom shows.
fn lowest_corner(scene: &Scene) -> Option<(usize, f64)> {
    let shape = scene.shape.as_ref()?;
    scene
        .snapshot
        .b
        .iter()
        .copied()
        .enumerate()
        .filter(|&(j, b)| b.is_finite() && shape.corner(j).is_some())
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// The camera of `options`, or one looking across the bend of the module with the lowest
/// corner barrier in `scene`, 30° around from side-on and 15° above.
fn choose_camera(camera: Option<Camera>, scene: Option<&Scene>) -> Projection {
    if let Some(camera) = camera {
        return Projection::from_angles(
            camera.azimuth_deg.to_radians(),
            camera.elevation_deg.to_radians(),
        );
    }
    let elevation = 15f64.to_radians();
    let bend = scene.and_then(|scene| {
        let shape = scene.shape.as_ref()?;
        let (j, _) = lowest_corner(scene)?;
        let gap = shape.corner(j)?;
        // The corner's horizontal direction from its module's base: where the module bends.
        let base = shape.poses.get(gap.module)?;
        let origin = shape::apply(base, [0.0; 3]);
        let toward = [gap.foot[0] - origin[0], gap.foot[1] - origin[1], 0.0];
        shape::normalized(toward)
    });
    let azimuth = match bend {
        Some(d) => d[1].atan2(d[0]) - 60f64.to_radians(),
        None => -60f64.to_radians(),
    };
    Projection::from_angles(azimuth, elevation)
}

/// The edge-on camera of a zoom on barrier `j`'s corner: looking along the bend axis of
/// its module (both plates then show as lines), from the side facing `main`.
fn zoom_camera(shape: &Shape, j: usize, main: &Projection) -> Option<Projection> {
    let gap = shape.corner(j)?;
    let base = shape.poses.get(gap.module)?;
    let tip = shape.poses.get(gap.module + 1)?;
    let normal = shape::rotate(base, [0.0, 0.0, 1.0]);
    let tip_normal = shape::rotate(tip, [0.0, 0.0, 1.0]);
    // The bend axis is normal × tip normal; straight, use the corner's sideways direction.
    let axis = shape::normalized(shape::cross(normal, tip_normal)).or_else(|| {
        let origin = shape::apply(base, [0.0; 3]);
        let out = [
            gap.foot[0] - origin[0],
            gap.foot[1] - origin[1],
            gap.foot[2] - origin[2],
        ];
        shape::normalized(shape::cross(normal, out))
    })?;
    let sign = if shape::dot(axis, main.toward) < 0.0 {
        -1.0
    } else {
        1.0
    };
    Projection::looking_from(axis.map(|x| sign * x), normal)
}

/// The camera angles \[deg\] of a projection made by [`Projection::from_angles`].
fn camera_angles(projection: &Projection) -> Camera {
    let t = projection.toward;
    Camera {
        azimuth_deg: t[1].atan2(t[0]).to_degrees(),
        elevation_deg: t[2].clamp(-1.0, 1.0).asin().to_degrees(),
    }
}

/// Checks the settings shared by views and animations.
fn check_common(active_below: f64, camera: Option<Camera>) -> Result<(), String> {
    if !active_below.is_finite() {
        return Err(format!(
            "active_below is {active_below}: give a finite barrier value in metres"
        ));
    }
    if let Some(camera) = camera {
        if !camera.azimuth_deg.is_finite() {
            return Err(format!(
                "camera azimuth_deg is {}: give a finite angle",
                camera.azimuth_deg
            ));
        }
        if !(-90.0..=90.0).contains(&camera.elevation_deg) {
            return Err(format!(
                "camera elevation_deg is {}: give an angle in [-90, 90]",
                camera.elevation_deg
            ));
        }
    }
    Ok(())
}

/// Draws `<stem>.png` and `<stem>.svg` in `out_dir` (created if missing) and returns
/// their paths: one row per run of `panels` (title, record with `model`'s coordinates and
/// barriers), one column per snapshot time, and a zoom on each run's final state. The
/// figure is `270·snapshots + 400` pixels wide (at least 900) and `40 + 514·runs` high plus
/// the legend: 76 pixels with 4 or more snapshots, 104 with 3, 132 with fewer; for a robot
/// with obstacles (three entries more) 104, 132 and 188.
pub fn draw_robot_views(
    out_dir: &Path,
    stem: &str,
    model: &Model,
    panels: &[(&str, &Record)],
    options: &ViewOptions,
) -> Result<Vec<PathBuf>, PlotError> {
    let png = out_dir.join(format!("{stem}.png"));
    let svg = out_dir.join(format!("{stem}.svg"));
    let failed = |file: &Path| {
        let file = file.to_path_buf();
        move |message: String| PlotError::Draw { file, message }
    };
    check_common(options.active_below, options.camera).map_err(failed(&png))?;
    if !(1..=8).contains(&options.snapshots) && options.times.is_empty() {
        return Err(failed(&png)(format!(
            "snapshots is {}: choose 1 to 8",
            options.snapshots
        )));
    }
    let times: Vec<f64> = options
        .times
        .iter()
        .copied()
        .filter(|t| t.is_finite())
        .take(8)
        .collect();
    register_fonts()?;
    let runs = runs(model, panels)?;
    let times = if times.is_empty() {
        choose_times(&runs, options.snapshots)
    } else {
        times
    };
    let times = if times.is_empty() { vec![0.0] } else { times };
    let scenes = scenes(
        model,
        &runs,
        plan(model, &runs, &times, options.active_below),
    );
    let final_plan = plan(
        model,
        &runs,
        &[common_span(&runs).map_or(0.0, |s| s.1)],
        options.active_below,
    );
    let finals: Vec<Scene> = scenes_flat(model, &runs, final_plan);
    let projection = choose_camera(options.camera, finals.first());
    let scenery = Scenery::new(
        model,
        scenes.iter().flatten().filter_map(|s| s.shape.as_ref()),
    );
    let figure = Figure {
        scenery,
        model,
        titles: runs.iter().map(|r| r.title).collect(),
        scenes,
        finals,
        projection,
        camera: options.camera.unwrap_or(camera_angles(&projection)),
        active_below: options.active_below,
    };
    std::fs::create_dir_all(out_dir).map_err(|source| PlotError::Io {
        dir: out_dir.to_path_buf(),
        source,
    })?;
    let size = figure.size();
    let mut pixels = vec![0u8; 3 * size.0 as usize * size.1 as usize];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area();
        draw_figure(&root, &figure).map_err(failed(&png))?;
        root.present()
            .map_err(|e| e.to_string())
            .map_err(failed(&png))?;
    }
    write_png(&png, &pixels, size).map_err(failed(&png))?;
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        draw_figure(&root, &figure).map_err(failed(&svg))?;
        root.present()
            .map_err(|e| e.to_string())
            .map_err(failed(&svg))?;
    }
    Ok(vec![png, svg])
}

/// One scene per run from a plan of one time per run.
fn scenes_flat(model: &Model, runs: &[Run], plan: Vec<Vec<Snapshot>>) -> Vec<Scene> {
    scenes(model, runs, plan)
        .into_iter()
        .filter_map(|mut row| row.pop())
        .collect()
}

/// Writes an animated GIF of the runs of `panels` side by side (each a record with
/// `model`'s coordinates and barriers) to `out_path` (its directory is created if
/// missing) and returns the path. Each frame shows every run at the same robot time, with
/// its obstacles, active corners and points, the time and a time line; frame times follow
/// [`AnimationOptions::uniform`]. The animation loops; it is `440·runs` × 534 pixels.
pub fn animate_robot(
    out_path: &Path,
    model: &Model,
    panels: &[(&str, &Record)],
    options: &AnimationOptions,
) -> Result<PathBuf, PlotError> {
    let failed = |message: String| PlotError::Draw {
        file: out_path.to_path_buf(),
        message,
    };
    check_common(options.active_below, options.camera).map_err(failed)?;
    if !(options.fps >= 1.0 && options.fps <= 50.0) {
        return Err(failed(format!("fps is {}: choose 1 to 50", options.fps)));
    }
    if !(options.duration >= 0.1 && options.duration <= 120.0) {
        return Err(failed(format!(
            "duration is {} s: choose 0.1 to 120 s",
            options.duration
        )));
    }
    if !(0.0..=1.0).contains(&options.uniform) {
        return Err(failed(format!(
            "uniform is {}: choose 0 to 1",
            options.uniform
        )));
    }
    register_fonts()?;
    let runs = runs(model, panels)?;
    let frames = (options.duration * options.fps).round().max(1.0) as usize;
    let span = common_span(&runs).unwrap_or((0.0, 0.0));
    let warp = Warp {
        runs: &runs,
        span,
        uniform: options.uniform,
    };
    let times: Vec<f64> = (0..frames)
        .map(|k| {
            if frames == 1 {
                span.1
            } else {
                warp.inverse(k as f64 / (frames - 1) as f64)
            }
        })
        .collect();
    let scenes = scenes(
        model,
        &runs,
        plan(model, &runs, &times, options.active_below),
    );
    let finals = scenes_flat(
        model,
        &runs,
        plan(model, &runs, &[span.1], options.active_below),
    );
    let projection = choose_camera(options.camera, finals.first());
    let rect = Rect {
        x0: 4.0,
        y0: 52.0,
        x1: FRAME_CELL.0 as f64 - 4.0,
        y1: FRAME_CELL.1 as f64 - 6.0,
    };
    let scenery = Scenery::new(
        model,
        scenes.iter().flatten().filter_map(|s| s.shape.as_ref()),
    );
    let bounds = extent(
        scenes.iter().flatten().filter_map(|s| s.shape.as_ref()),
        &projection,
        &scenery,
    )
    .unwrap_or(((-0.1, 0.1), (0.0, 0.2)));
    let mapping = fit(projection, bounds, rect);
    let size = (
        FRAME_CELL.0 * runs.len() as u32,
        TITLE_HEIGHT + FRAME_CELL.1 + FRAME_STRIP,
    );
    if size.0 > u16::MAX as u32 {
        return Err(failed(format!(
            "{} runs side by side are {} pixels wide, more than a GIF allows",
            runs.len(),
            size.0
        )));
    }
    if let Some(dir) = out_path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| PlotError::Io {
            dir: dir.to_path_buf(),
            source,
        })?;
    }
    let delay = (100.0 / options.fps).round().max(2.0) as u16;
    let mut writer = gif_file::GifWriter::create(
        out_path,
        (size.0 as u16, size.1 as u16),
        delay,
        &scenery.palette(),
    )
    .map_err(failed)?;
    let mut pixels = vec![0u8; 3 * size.0 as usize * size.1 as usize];
    let titles: Vec<&str> = runs.iter().map(|r| r.title).collect();
    for (k, &t) in times.iter().enumerate() {
        let column: Vec<&Scene> = scenes.iter().map(|row| &row[k]).collect();
        let speed = if frames > 1 {
            let (a, b) = (times[k.saturating_sub(1)], times[(k + 1).min(frames - 1)]);
            let steps = ((k + 1).min(frames - 1) - k.saturating_sub(1)) as f64;
            (b - a) / steps * options.fps
        } else {
            f64::NAN
        };
        {
            let root = BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area();
            let frame = AnimationFrame {
                model,
                titles: &titles,
                scenes: &column,
                mapping: &mapping,
                t,
                span,
                speed,
                active_below: options.active_below,
                scenery: &scenery,
            };
            draw_frame(&root, &frame).map_err(failed)?;
            root.present().map_err(|e| failed(e.to_string()))?;
        }
        writer.push(&pixels).map_err(failed)?;
    }
    writer.finish().map_err(failed)?;
    Ok(out_path.to_path_buf())
}

#[cfg(test)]
mod tests {
    use super::*;
    use softcbf_description::robot::Robot;

    #[test]
    fn times_round_to_two_digits_within_the_span() {
        assert_eq!(round_time(0.14873, 0.0, 10.0), 0.15);
        assert_eq!(round_time(3.26, 0.0, 10.0), 3.3);
        assert_eq!(round_time(9.97, 0.0, 9.97), 9.97);
        assert_eq!(round_time(0.0, 0.0, 1.0), 0.0);
    }

    #[test]
    fn zoom_looks_edge_on_at_both_plates_of_a_bent_module() {
        let model = Model::new(Robot::paper_sim()).unwrap();
        let mut kinematics = Kinematics::new(&model);
        let shape = kinematics.shape(&[0.08, 0.0, -0.05, 0.0, -0.06, -0.07]);
        let main = Projection::from_angles(-1.0, 0.26);
        for j in [0, 10] {
            let view = zoom_camera(&shape, j, &main).unwrap();
            let module = shape.corner(j).unwrap().module;
            for plate in [module, module + 1] {
                let normal = shape::rotate(&shape.poses[plate], [0.0, 0.0, 1.0]);
                // Edge-on: the view direction lies in the plate's plane.
                assert!(shape::dot(normal, view.toward).abs() < 1e-12);
            }
        }
    }
}
