//! The robot in 3-D in an MCAP log, in the schemas Foxglove's 3-D panel (and other
//! viewers of Foxglove's schemas) draw: `/<run>/scene` (`foxglove.SceneUpdate`) and `/tf`
//! (`foxglove.FrameTransform`), JSON-encoded with JSON Schemas written here for the fields
//! used.
//!
//! The geometry is the 3-D figure's, as `softcbf view` takes it
//! ([`crate::plot::robot_view::scene::scene_frames`]): every module's backbone arc,
//! tendons and plates, each corner barrier's corner with its foot on the plate below and
//! each watched point with the nearest point of its obstacle (coloured by its barrier as
//! the figure colours them: red past the verdict's tolerance, orange within 0.5 mm of the
//! margin), and the obstacles. Coordinates are rounded to 10 µm, as in the view.
//!
//! Frames are taken as the view takes them ([`crate::frames::frame_times`]): 30 per second
//! of robot time ([`crate::frames::DEFAULT_FPS`]), at most [`crate::frames::MAX_FRAMES`] for a
//! long run, each the record's row nearest to its time, stamped with that row's time; a
//! frame that would draw the row the frame before it drew is left out. A viewer plays at
//! about that rate, and the rows themselves (every tick) stay in the joint state and
//! barrier channels; a scene per row would make the log up to thirty times larger (a
//! 1 kHz dense record) for no frame a screen shows.
//!
//! Each run has its own frame (`filter`, `pd`), a child of `world` (the robot's base
//! frame), the runs placed side by side along `y`, the one asked for at the origin. Each
//! update replaces two entities: `robot` (lines, triangles, spheres and the run's title;
//! on a frame whose state cannot be drawn it is deleted) and `obstacles`.

use serde_json::{Value, json};

use super::{LogRun, nanoseconds};
use crate::frames::{DEFAULT_FPS, coordinate, frame_times};
use crate::model::Model;
use crate::plot::PlotError;
use crate::plot::robot_view::scene::{
    Obstacle, RobotShape, SceneFrames, drawable_span, palette, scene_frames,
};
use crate::plot::robot_view::{DEFAULT_ACTIVE_BELOW, violated};
use crate::record::Record;

/// The topic of the frame transforms.
pub const TF_TOPIC: &str = "/tf";
/// The fixed frame: the robot's base.
pub const WORLD: &str = "world";

/// The JSON Schema of `foxglove.SceneUpdate`, for the fields written here.
pub const SCENE_UPDATE_SCHEMA: &str = r##"{"title":"foxglove.SceneUpdate","description":"An update to the entities of a 3-D scene (the fields softcbf writes)","type":"object","$defs":{"time":{"type":"object","properties":{"sec":{"type":"integer","minimum":0},"nsec":{"type":"integer","minimum":0,"maximum":999999999}}},"vector3":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}},"quaternion":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}},"pose":{"type":"object","properties":{"position":{"$ref":"#/$defs/vector3"},"orientation":{"$ref":"#/$defs/quaternion"}}},"color":{"type":"object","properties":{"r":{"type":"number"},"g":{"type":"number"},"b":{"type":"number"},"a":{"type":"number"}}},"line":{"type":"object","properties":{"type":{"type":"integer","description":"0 LINE_STRIP, 1 LINE_LOOP, 2 LINE_LIST"},"pose":{"$ref":"#/$defs/pose"},"thickness":{"type":"number"},"scale_invariant":{"type":"boolean"},"points":{"type":"array","items":{"$ref":"#/$defs/vector3"}},"color":{"$ref":"#/$defs/color"},"colors":{"type":"array","items":{"$ref":"#/$defs/color"}},"indices":{"type":"array","items":{"type":"integer","minimum":0}}}},"triangles":{"type":"object","properties":{"pose":{"$ref":"#/$defs/pose"},"points":{"type":"array","items":{"$ref":"#/$defs/vector3"}},"color":{"$ref":"#/$defs/color"},"colors":{"type":"array","items":{"$ref":"#/$defs/color"}},"indices":{"type":"array","items":{"type":"integer","minimum":0}}}},"sphere":{"type":"object","properties":{"pose":{"$ref":"#/$defs/pose"},"size":{"$ref":"#/$defs/vector3"},"color":{"$ref":"#/$defs/color"}}},"arrow":{"type":"object","properties":{"pose":{"$ref":"#/$defs/pose"},"shaft_length":{"type":"number"},"shaft_diameter":{"type":"number"},"head_length":{"type":"number"},"head_diameter":{"type":"number"},"color":{"$ref":"#/$defs/color"}}},"text":{"type":"object","properties":{"pose":{"$ref":"#/$defs/pose"},"billboard":{"type":"boolean"},"font_size":{"type":"number"},"scale_invariant":{"type":"boolean"},"color":{"$ref":"#/$defs/color"},"text":{"type":"string"}}}},"properties":{"deletions":{"type":"array","items":{"type":"object","properties":{"timestamp":{"$ref":"#/$defs/time"},"type":{"type":"integer","description":"0 MATCHING_ID, 1 ALL"},"id":{"type":"string"}}}},"entities":{"type":"array","items":{"type":"object","properties":{"timestamp":{"$ref":"#/$defs/time"},"frame_id":{"type":"string"},"id":{"type":"string"},"lifetime":{"$ref":"#/$defs/time"},"frame_locked":{"type":"boolean"},"metadata":{"type":"array","items":{"type":"object","properties":{"key":{"type":"string"},"value":{"type":"string"}}}},"arrows":{"type":"array","items":{"$ref":"#/$defs/arrow"}},"cubes":{"type":"array","items":{"$ref":"#/$defs/sphere"}},"spheres":{"type":"array","items":{"$ref":"#/$defs/sphere"}},"cylinders":{"type":"array","items":{"$ref":"#/$defs/sphere"}},"lines":{"type":"array","items":{"$ref":"#/$defs/line"}},"triangles":{"type":"array","items":{"$ref":"#/$defs/triangles"}},"texts":{"type":"array","items":{"$ref":"#/$defs/text"}},"models":{"type":"array","items":{"type":"object"}}}}}}}"##;

/// The JSON Schema of `foxglove.FrameTransform`.
pub const FRAME_TRANSFORM_SCHEMA: &str = r##"{"title":"foxglove.FrameTransform","description":"A transform between two frames of reference","type":"object","properties":{"timestamp":{"type":"object","properties":{"sec":{"type":"integer","minimum":0},"nsec":{"type":"integer","minimum":0,"maximum":999999999}}},"parent_frame_id":{"type":"string"},"child_frame_id":{"type":"string"},"translation":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}},"rotation":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}}}"##;

/// One scene update of a run, JSON text, at `time` \[ns\].
pub struct Update {
    /// Its time in the log's clock \[ns\].
    pub time: u64,
    /// The `foxglove.SceneUpdate`.
    pub data: Vec<u8>,
}

/// The scene of a log.
pub struct SceneLog {
    /// Frames per second of robot time.
    pub fps: f64,
    /// Per run, its updates in time order.
    pub runs: Vec<Vec<Update>>,
    /// At each frame time \[ns\], one `foxglove.FrameTransform` per run (`world` → run).
    pub transforms: Vec<(u64, Vec<Vec<u8>>)>,
}

/// The scene of `runs` of `model`; `None` when a run has no row or no row can be drawn.
pub fn scene_log(model: &Model, runs: &[LogRun<'_>]) -> Result<Option<SceneLog>, PlotError> {
    if runs.is_empty() || runs.iter().any(|run| run.record.is_empty()) {
        return Ok(None);
    }
    let panels: Vec<(&str, &Record)> = runs.iter().map(|r| (r.title, r.record)).collect();
    let Some(span) = drawable_span(model, &panels)? else {
        return Ok(None);
    };
    let (times, fps) = frame_times(span, DEFAULT_FPS);
    let scene = scene_frames(model, &panels, &times, None)?;
    let style = Style::of(&scene);
    let mut updates = Vec::with_capacity(runs.len());
    for (run, frames) in runs.iter().zip(&scene.runs) {
        let mut list = Vec::with_capacity(frames.frames.len());
        let mut last_row = None;
        for frame in &frames.frames {
            if frame.row.is_none() || frame.row == last_row || !frame.t.is_finite() {
                continue;
            }
            last_row = frame.row;
            let time = nanoseconds(frame.t);
            let robot = frame.robot.as_ref().map(|robot| {
                robot_entity(run, robot, &frame.b, frame.invalid.as_deref(), time, &style)
            });
            let obstacles = obstacle_entity(run.name, &scene, time, &style);
            let update = match robot {
                Some(robot) => json!({"deletions": [], "entities": [robot, obstacles]}),
                None => json!({
                    "deletions": [{"timestamp": stamp(time), "type": 0, "id": "robot"}],
                    "entities": [obstacles],
                }),
            };
            list.push(Update {
                time,
                data: serde_json::to_vec(&update).unwrap_or_default(),
            });
        }
        updates.push(list);
    }
    let transforms = times
        .iter()
        .map(|&t| {
            let time = nanoseconds(t);
            let messages = runs
                .iter()
                .enumerate()
                .map(|(k, run)| {
                    let message = json!({
                        "timestamp": stamp(time),
                        "parent_frame_id": WORLD,
                        "child_frame_id": run.name,
                        "translation": {"x": 0.0, "y": k as f64 * style.spacing, "z": 0.0},
                        "rotation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
                    });
                    serde_json::to_vec(&message).unwrap_or_default()
                })
                .collect();
            (time, messages)
        })
        .collect();
    Ok(Some(SceneLog {
        fps,
        runs: updates,
        transforms,
    }))
}

/// Colours and sizes of a scene.
struct Style {
    colours: Vec<(&'static str, String)>,
    /// Diameter of a corner's or watched point's sphere \[m\].
    marker: f64,
    /// Distance between the runs' frames along `y` \[m\].
    spacing: f64,
    /// Where a run's title stands, above the scene's box \[m\].
    title_at: [f64; 3],
    /// Length of a half-space's normal arrow \[m\].
    arrow: f64,
}

impl Style {
    fn of(scene: &SceneFrames) -> Style {
        let (low, high) = scene.bounds.unwrap_or(([0.0; 3], [0.0; 3]));
        let side = (0..3)
            .map(|k| high[k] - low[k])
            .fold(0.0, f64::max)
            .max(1e-3);
        Style {
            colours: palette(),
            marker: side / 60.0,
            spacing: 1.25 * (high[1] - low[1]).max(side),
            title_at: [
                0.5 * (low[0] + high[0]),
                0.5 * (low[1] + high[1]),
                high[2] + 0.05 * side,
            ],
            arrow: scene.arrow,
        }
    }

    /// The figure's colour `name` with opacity `alpha`, as a `foxglove.Color`.
    fn colour(&self, name: &str, alpha: f64) -> Value {
        let hex = self
            .colours
            .iter()
            .find(|(n, _)| *n == name)
            .map_or("#000000", |(_, hex)| hex.as_str());
        // Three decimals: finer than a screen's 256 levels, and short.
        let channel = |k: usize| {
            u8::from_str_radix(hex.get(1 + 2 * k..3 + 2 * k).unwrap_or("00"), 16)
                .map_or(0.0, |c| (f64::from(c) / 255.0 * 1e3).round() / 1e3)
        };
        json!({"r": channel(0), "g": channel(1), "b": channel(2), "a": alpha})
    }

    /// The colour of a corner or watched point whose barrier is `b` \[m\]: as the figure
    /// draws it.
    fn barrier_colour(&self, b: Option<f64>) -> Value {
        match b {
            Some(b) if violated(b) => self.colour("violated", 1.0),
            Some(b) if b <= DEFAULT_ACTIVE_BELOW => self.colour("active", 1.0),
            Some(_) => self.colour("clear", 1.0),
            None => self.colour("muted", 1.0),
        }
    }
}

/// A time in the log's clock as Foxglove's `time`.
fn stamp(ns: u64) -> Value {
    json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000})
}

/// A point, rounded as the view rounds it (a coordinate that is not finite: 0).
fn point(p: &[f64; 3]) -> Value {
    let c = |x: f64| coordinate(x).unwrap_or(0.0);
    json!({"x": c(p[0]), "y": c(p[1]), "z": c(p[2])})
}

fn pose_at(p: &[f64; 3]) -> Value {
    json!({"position": point(p), "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}})
}

fn identity() -> Value {
    pose_at(&[0.0; 3])
}

/// A `foxglove.LinePrimitive` of `kind` (0 strip, 1 loop, 2 list), `thickness` pixels.
fn line<'p>(
    kind: u8,
    points: impl IntoIterator<Item = &'p [f64; 3]>,
    colour: Value,
    thickness: f64,
) -> Value {
    let points: Vec<Value> = points.into_iter().map(point).collect();
    json!({
        "type": kind,
        "pose": identity(),
        "thickness": thickness,
        "scale_invariant": true,
        "points": points,
        "color": colour,
        "colors": [],
        "indices": [],
    })
}

/// A polygon as a fan of triangles (`foxglove.TriangleListPrimitive`).
fn polygon(corners: &[[f64; 3]], colour: Value) -> Value {
    let mut points = Vec::with_capacity(3 * corners.len().saturating_sub(2));
    for k in 1..corners.len().saturating_sub(1) {
        points.extend([
            point(&corners[0]),
            point(&corners[k]),
            point(&corners[k + 1]),
        ]);
    }
    json!({"pose": identity(), "points": points, "color": colour, "colors": [], "indices": []})
}

fn sphere(centre: &[f64; 3], diameter: f64, colour: Value) -> Value {
    let diameter = coordinate(diameter).unwrap_or(0.0);
    json!({
        "pose": pose_at(centre),
        "size": {"x": diameter, "y": diameter, "z": diameter},
        "color": colour,
    })
}

/// An entity with every primitive list, empty where not given.
fn entity(id: &str, frame: &str, time: u64, metadata: Vec<Value>, parts: Value) -> Value {
    let mut entity = json!({
        "timestamp": stamp(time),
        "frame_id": frame,
        "id": id,
        "lifetime": {"sec": 0, "nsec": 0},
        "frame_locked": true,
        "metadata": metadata,
        "arrows": [], "cubes": [], "spheres": [], "cylinders": [],
        "lines": [], "triangles": [], "texts": [], "models": [],
    });
    if let (Some(object), Value::Object(parts)) = (entity.as_object_mut(), parts) {
        object.extend(parts);
    }
    entity
}

/// The robot of one frame.
fn robot_entity(
    run: &LogRun<'_>,
    robot: &RobotShape,
    b: &[f64],
    invalid: Option<&str>,
    time: u64,
    style: &Style,
) -> Value {
    let mut lines = Vec::new();
    for backbone in &robot.backbones {
        lines.push(line(0, backbone, style.colour("backbone", 1.0), 4.0));
    }
    for tendon in robot.tendons.iter().flatten() {
        lines.push(line(0, tendon, style.colour("tendon", 1.0), 1.5));
    }
    let mut triangles = Vec::new();
    for (k, plate) in robot.plates.iter().enumerate() {
        let (fill, edge) = if k == 0 {
            ("base_fill", "base_edge")
        } else {
            ("plate_fill", "plate_edge")
        };
        triangles.push(polygon(plate, style.colour(fill, 0.6)));
        lines.push(line(1, plate, style.colour(edge, 1.0), 1.5));
    }
    let value = |barrier: usize| b.get(barrier).copied().filter(|v| v.is_finite());
    let mut spheres = Vec::new();
    let mut gaps = Vec::new();
    for corner in &robot.corners {
        let colour =
            style.barrier_colour(invalid.is_none().then(|| value(corner.barrier)).flatten());
        spheres.push(sphere(&corner.at, style.marker, colour));
        gaps.extend([corner.at, corner.foot]);
    }
    for watched in &robot.watched {
        let colour =
            style.barrier_colour(invalid.is_none().then(|| value(watched.barrier)).flatten());
        spheres.push(sphere(&watched.at, style.marker, colour));
        if let Some(nearest) = watched.nearest {
            gaps.extend([watched.at, nearest]);
        }
    }
    if !gaps.is_empty() {
        lines.push(line(2, &gaps, style.colour("muted", 0.8), 1.0));
    }
    let title = json!({
        "pose": pose_at(&style.title_at),
        "billboard": true,
        "font_size": 14.0,
        "scale_invariant": true,
        "color": style.colour("text", 1.0),
        "text": run.title,
    });
    let mut metadata = vec![json!({"key": "t [s]", "value": format!("{}", time as f64 * 1e-9)})];
    if let Some(why) = invalid {
        metadata.push(json!({"key": "invalid state", "value": why}));
    }
    entity(
        "robot",
        run.name,
        time,
        metadata,
        json!({"lines": lines, "triangles": triangles, "spheres": spheres, "texts": [title]}),
    )
}

/// The rotation that takes the x axis to the unit vector `n`, as a quaternion.
fn x_to(n: [f64; 3]) -> Value {
    let w = 1.0 + n[0];
    let (x, y, z) = (0.0, -n[2], n[1]);
    let norm = (w * w + x * x + y * y + z * z).sqrt();
    if norm < 1e-9 {
        // n = −x: half a turn about z.
        return json!({"x": 0.0, "y": 0.0, "z": 1.0, "w": 0.0});
    }
    json!({"x": x / norm, "y": y / norm, "z": z / norm, "w": w / norm})
}

/// The obstacles (the same in every frame).
fn obstacle_entity(frame: &str, scene: &SceneFrames, time: u64, style: &Style) -> Value {
    let (mut spheres, mut triangles, mut lines, mut arrows) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for obstacle in &scene.obstacles {
        match obstacle {
            Obstacle::Sphere { centre, radius, .. } => {
                spheres.push(sphere(
                    centre,
                    2.0 * radius,
                    style.colour("sphere_fill", 0.35),
                ));
            }
            Obstacle::HalfSpace { normal, patch, .. } => {
                if patch.len() >= 3 {
                    triangles.push(polygon(patch, style.colour("wall_fill", 0.3)));
                    lines.push(line(1, patch, style.colour("wall_edge", 1.0), 1.5));
                    let n = patch.len() as f64;
                    let middle: [f64; 3] =
                        std::array::from_fn(|k| patch.iter().map(|p| p[k]).sum::<f64>() / n);
                    arrows.push(json!({
                        "pose": {"position": point(&middle), "orientation": x_to(*normal)},
                        "shaft_length": 0.7 * style.arrow,
                        "shaft_diameter": 0.05 * style.arrow,
                        "head_length": 0.3 * style.arrow,
                        "head_diameter": 0.15 * style.arrow,
                        "color": style.colour("wall_edge", 1.0),
                    }));
                }
            }
        }
    }
    entity(
        "obstacles",
        frame,
        time,
        Vec::new(),
        json!({"spheres": spheres, "triangles": triangles, "lines": lines, "arrows": arrows}),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_arrow_turns_the_x_axis_onto_the_normal() {
        for n in [
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [-1.0, 0.0, 0.0],
            [0.6, 0.0, -0.8],
        ] {
            let q = x_to(n);
            let q: [f64; 4] = ["x", "y", "z", "w"].map(|k| q[k].as_f64().unwrap());
            let (x, y, z, w) = (q[0], q[1], q[2], q[3]);
            // The first column of the rotation matrix of q.
            let image = [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y + w * z),
                2.0 * (x * z - w * y),
            ];
            for k in 0..3 {
                assert!((image[k] - n[k]).abs() < 1e-12, "{n:?}: {image:?}");
            }
        }
    }

    #[test]
    fn colours_are_the_figures() {
        let style = Style {
            colours: palette(),
            marker: 0.0,
            spacing: 0.0,
            title_at: [0.0; 3],
            arrow: 0.0,
        };
        assert_eq!(
            style.barrier_colour(Some(-1e-3)),
            style.colour("violated", 1.0)
        );
        assert_eq!(
            style.barrier_colour(Some(1e-4)),
            style.colour("active", 1.0)
        );
        assert_eq!(style.barrier_colour(Some(1e-2)), style.colour("clear", 1.0));
        let white = Style {
            colours: vec![("x", "#ff8000".into())],
            ..style
        };
        assert_eq!(
            white.colour("x", 0.5),
            json!({"r": 1.0, "g": 0.502, "b": 0.0, "a": 0.5})
        );
    }
}
