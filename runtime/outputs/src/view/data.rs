//! The data a view page embeds (`<script type="application/json" id="softcbf-view-data">`):
//! one typed owner, written by [`ViewData::from_scene`] and [`super::page`], read back
//! by [`ViewData::from_page`] (the tests) and by the page's script.
//!
//! Points are flat arrays `[x, y, z, x, y, z, …]` in metres, rounded to 10 µm
//! ([`COORDINATE_STEP`]); barrier values keep four significant digits
//! ([`BARRIER_DIGITS`]), so that a value past the verdict's tolerance stays past it.
//! A number that is not finite is `null`.

use serde::{Deserialize, Serialize};

pub use crate::frames::{COORDINATE_STEP, coordinate};
use crate::model::Model;
use crate::plot::robot_view::scene::{Obstacle, RobotShape, SceneFrames, palette};

/// The version of this format; the page refuses another.
pub const FORMAT: u32 = 1;
/// Significant digits of the embedded barrier values.
pub const BARRIER_DIGITS: usize = 4;
/// The highest top of the colour scale \[m\]: the scale shows the last centimetres
/// before a boundary, not the whole travel.
pub const COLOUR_TOP_MAX: f64 = 0.02;
/// The element of the page that holds the data.
pub const ELEMENT_ID: &str = "softcbf-view-data";

/// Everything a view page shows.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewData {
    /// [`FORMAT`].
    pub format: u32,
    /// The softcbf that wrote it (`softcbf 0.1.0`).
    pub softcbf: String,
    /// The page's heading (`scenario on robot`, else the directory).
    pub title: String,
    /// The robot's name.
    pub robot: String,
    /// Frames per second of robot time.
    pub fps: f64,
    /// The frame times \[s\], increasing.
    pub times: Vec<f64>,
    /// The scene's box, `[low, high]` \[m\].
    pub bounds: [[f64; 3]; 2],
    /// Where the camera starts.
    pub camera: CameraData,
    /// Length of a half-space's normal arrow \[m\].
    pub arrow: f64,
    /// A corner or watched point with `b ≤ active_below` \[m\] is highlighted (orange).
    pub active_below: f64,
    /// A barrier below `−tolerance` is violated (red) \[m\].
    pub tolerance: f64,
    /// The top of the colour scale of corners and watched points \[m\]: the highest such
    /// barrier over the frames, rounded up, at least 1 mm and at most
    /// [`COLOUR_TOP_MAX`] (higher values take the top colour).
    pub colour_top: f64,
    /// The figure's colours by name (`#rrggbb`).
    pub colours: Vec<(String, String)>,
    /// Every barrier, in the model's table order.
    pub barriers: Vec<BarrierData>,
    /// The corner barriers, in the order of each frame's `corners`.
    pub corners: Vec<CornerData>,
    /// The environment barriers' watched points, in the order of each frame's `watched`.
    pub watched: Vec<WatchedData>,
    /// The obstacles that can be drawn.
    pub obstacles: Vec<ObstacleData>,
    /// The runs, left to right.
    pub runs: Vec<RunData>,
}

/// The starting camera, as the 3-D figure's (`softcbf_figures::plot::robot_view::Camera`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraData {
    /// From the world x axis toward +y \[deg\].
    pub azimuth_deg: f64,
    /// Above the base plate's plane \[deg\].
    pub elevation_deg: f64,
}

/// One barrier.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BarrierData {
    /// Its label (`module 1 corner 3`).
    pub label: String,
    /// Its unit, `m` or `rad`.
    pub unit: String,
    /// Its kind group: `plate_corner`, `elongation`, `bend` or `obstacle`.
    pub group: String,
}

/// A corner barrier.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CornerData {
    /// Index into [`ViewData::barriers`].
    pub barrier: usize,
    /// The module (0-based) whose top plate carries it.
    pub module: usize,
}

/// An environment barrier's watched point.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct WatchedData {
    /// Index into [`ViewData::barriers`].
    pub barrier: usize,
    /// The module (0-based) that carries it.
    pub module: usize,
    /// The obstacle (0-based, file order).
    pub obstacle: usize,
    /// On the backbone (else fixed in the top plate).
    pub arc: bool,
}

/// An obstacle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ObstacleData {
    /// `|x − centre| ≥ radius + margin` is allowed.
    Sphere {
        /// Index in the robot file (0-based).
        index: usize,
        /// \[m\].
        centre: [f64; 3],
        /// \[m\].
        radius: f64,
        /// \[m\].
        margin: f64,
    },
    /// `normal·x ≥ offset + margin` is allowed.
    HalfSpace {
        /// Index in the robot file (0-based).
        index: usize,
        /// Unit normal into the allowed side.
        normal: [f64; 3],
        /// \[m\].
        offset: f64,
        /// \[m\].
        margin: f64,
        /// Its plane across the scene's box, flat points \[m\].
        patch: Vec<f64>,
    },
}

/// One run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunData {
    /// Its column title (`safety filter (…)`, `PD+ only`).
    pub title: String,
    /// The file it was read from.
    pub file: String,
    /// One frame per time of [`ViewData::times`].
    pub frames: Vec<FrameData>,
}

/// One run at one frame time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameData {
    /// The time of the record's row drawn \[s\]; `null` without one.
    pub t: Option<f64>,
    /// Every barrier's value \[m or rad\] (`null`: not finite).
    pub b: Vec<Option<f64>>,
    /// Why the state cannot be used, if it cannot.
    pub invalid: Option<String>,
    /// The robot; `null` without a drawable state.
    pub robot: Option<RobotData>,
}

/// A robot at one state, flat points \[m\].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RobotData {
    /// Each module's backbone, base to tip.
    pub backbones: Vec<Vec<f64>>,
    /// Every tendon, module by module.
    pub tendons: Vec<Vec<f64>>,
    /// Plate 0 (the base) to plate N, corners in order.
    pub plates: Vec<Vec<f64>>,
    /// Per corner of [`ViewData::corners`]: the corner, then its foot on the plate below
    /// (six numbers).
    pub corners: Vec<f64>,
    /// Per point of [`ViewData::watched`]: the point, then the nearest point of its
    /// obstacle (the point again if the obstacle cannot be drawn; six numbers).
    pub watched: Vec<f64>,
}

/// `x` to [`BARRIER_DIGITS`] significant digits (`None` if not finite).
fn barrier_value(x: f64) -> Option<f64> {
    x.is_finite()
        .then(|| format!("{x:.*e}", BARRIER_DIGITS - 1).parse().unwrap_or(x))
}

/// Flat rounded coordinates of `points` (a non-finite coordinate becomes 0: a shape is
/// embedded only when all its points are finite).
fn flat<'p>(points: impl IntoIterator<Item = &'p [f64; 3]>) -> Vec<f64> {
    points
        .into_iter()
        .flatten()
        .map(|&x| coordinate(x).unwrap_or(0.0))
        .collect()
}

fn point(p: [f64; 3]) -> [f64; 3] {
    p.map(|x| coordinate(x).unwrap_or(0.0))
}

/// `value` rounded up to 1, 2 or 5 × 10ᵏ.
fn nice_ceil(value: f64) -> f64 {
    let unit = 10f64.powf(value.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * unit)
        .find(|&v| v >= value * (1.0 - 1e-12))
        .unwrap_or(10.0 * unit)
}

impl ViewData {
    /// The data of `scene` (computed with `model`), each run read from the file of the
    /// same index in `files`, with heading `title`, at `fps` frames per second of robot
    /// time.
    pub fn from_scene(
        model: &Model,
        scene: &SceneFrames,
        files: &[String],
        title: &str,
        fps: f64,
    ) -> ViewData {
        let table = model.generated.barrier_table();
        let barriers = table
            .iter()
            .map(|info| {
                let group = info.kind.group();
                BarrierData {
                    label: info.label.to_string(),
                    unit: group.unit().to_string(),
                    group: group.key().to_string(),
                }
            })
            .collect();
        // The corners and watched points are the same in every drawable frame.
        let shapes = || {
            scene
                .runs
                .iter()
                .flat_map(|run| &run.frames)
                .filter_map(|frame| frame.robot.as_ref())
        };
        let (corners, watched) = match shapes().next() {
            Some(robot) => (
                robot
                    .corners
                    .iter()
                    .map(|c| CornerData {
                        barrier: c.barrier,
                        module: c.module,
                    })
                    .collect(),
                robot
                    .watched
                    .iter()
                    .map(|w| WatchedData {
                        barrier: w.barrier,
                        module: w.module,
                        obstacle: w.obstacle,
                        arc: w.arc,
                    })
                    .collect(),
            ),
            None => (Vec::new(), Vec::new()),
        };
        let marked: Vec<usize> = scene_marks(&corners, &watched);
        let highest = scene
            .runs
            .iter()
            .flat_map(|run| &run.frames)
            .filter(|frame| frame.invalid.is_none())
            .flat_map(|frame| marked.iter().filter_map(|&j| frame.b.get(j).copied()))
            .filter(|b| b.is_finite())
            .fold(0.0, f64::max);
        let colour_top = nice_ceil(highest.max(1e-3)).min(COLOUR_TOP_MAX);
        let obstacles = scene
            .obstacles
            .iter()
            .map(|obstacle| match obstacle {
                Obstacle::Sphere {
                    index,
                    centre,
                    radius,
                    margin,
                } => ObstacleData::Sphere {
                    index: *index,
                    centre: point(*centre),
                    radius: *radius,
                    margin: *margin,
                },
                Obstacle::HalfSpace {
                    index,
                    normal,
                    offset,
                    margin,
                    patch,
                } => ObstacleData::HalfSpace {
                    index: *index,
                    normal: *normal,
                    offset: *offset,
                    margin: *margin,
                    patch: flat(patch),
                },
            })
            .collect();
        let runs = scene
            .runs
            .iter()
            .enumerate()
            .map(|(k, run)| RunData {
                title: run.title.clone(),
                file: files.get(k).cloned().unwrap_or_default(),
                frames: run
                    .frames
                    .iter()
                    .map(|frame| FrameData {
                        t: frame.t.is_finite().then_some(frame.t),
                        b: frame.b.iter().map(|&b| barrier_value(b)).collect(),
                        invalid: frame.invalid.clone(),
                        robot: frame.robot.as_ref().map(robot_data),
                    })
                    .collect(),
            })
            .collect();
        let bounds = scene.bounds.unwrap_or(([-0.1, -0.1, 0.0], [0.1, 0.1, 0.2]));
        ViewData {
            format: FORMAT,
            softcbf: concat!("softcbf ", env!("CARGO_PKG_VERSION")).to_string(),
            title: title.to_string(),
            robot: model.robot.name.clone(),
            fps,
            times: scene.times.clone(),
            bounds: [point(bounds.0), point(bounds.1)],
            camera: CameraData {
                azimuth_deg: scene.camera.azimuth_deg,
                elevation_deg: scene.camera.elevation_deg,
            },
            arrow: scene.arrow,
            active_below: crate::plot::robot_view::DEFAULT_ACTIVE_BELOW,
            tolerance: softcbf_description::limits::BARRIER_TOLERANCE_M,
            colour_top,
            colours: palette()
                .into_iter()
                .map(|(name, hex)| (name.to_string(), hex))
                .collect(),
            barriers,
            corners,
            watched,
            obstacles,
            runs,
        }
    }

    /// The data embedded in a page `html` written by [`super::page`].
    pub fn from_page(html: &str) -> Result<ViewData, String> {
        let open = format!(r#"<script type="application/json" id="{ELEMENT_ID}">"#);
        let start = html
            .find(&open)
            .ok_or_else(|| format!("no element `{ELEMENT_ID}` in the page"))?
            + open.len();
        let end = html[start..]
            .find("</script>")
            .ok_or_else(|| format!("the element `{ELEMENT_ID}` is not closed"))?;
        serde_json::from_str(&html[start..start + end])
            .map_err(|e| format!("the element `{ELEMENT_ID}`: {e}"))
    }

    /// The data as JSON that can stand inside a `<script>` element: every `<` written
    /// `\u003c` (JSON has `<` only inside strings, where the escape reads back the same).
    pub fn to_script_json(&self) -> Result<String, serde_json::Error> {
        Ok(serde_json::to_string(self)?.replace('<', "\\u003c"))
    }
}

/// The barriers drawn as coloured points: the corners and the watched points.
fn scene_marks(corners: &[CornerData], watched: &[WatchedData]) -> Vec<usize> {
    corners
        .iter()
        .map(|c| c.barrier)
        .chain(watched.iter().map(|w| w.barrier))
        .collect()
}

fn robot_data(robot: &RobotShape) -> RobotData {
    RobotData {
        backbones: robot.backbones.iter().map(flat).collect(),
        tendons: robot.tendons.iter().flatten().map(flat).collect(),
        plates: robot.plates.iter().map(flat).collect(),
        corners: robot
            .corners
            .iter()
            .flat_map(|c| point(c.at).into_iter().chain(point(c.foot)))
            .collect(),
        watched: robot
            .watched
            .iter()
            .flat_map(|w| {
                point(w.at)
                    .into_iter()
                    .chain(point(w.nearest.unwrap_or(w.at)))
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_rounded_as_documented() {
        assert_eq!(coordinate(0.123_456_7), Some(0.12346));
        assert_eq!(coordinate(-0.000_004), Some(-0.0));
        assert_eq!(coordinate(f64::NAN), None);
        assert_eq!(barrier_value(-1.049e-6), Some(-1.049e-6));
        assert_eq!(barrier_value(6.330_49e-5), Some(6.330e-5));
        assert_eq!(barrier_value(f64::INFINITY), None);
        assert_eq!(nice_ceil(0.0283), 0.05);
        assert_eq!(nice_ceil(0.001), 0.001);
        assert_eq!(nice_ceil(0.0011), 0.002);
    }

    #[test]
    fn the_script_json_has_no_tag_and_reads_back() {
        let data = ViewData {
            format: FORMAT,
            softcbf: "softcbf test".into(),
            title: "</script><script>alert(1)</script>".into(),
            robot: "r".into(),
            fps: 30.0,
            times: vec![0.0],
            bounds: [[0.0; 3], [1.0; 3]],
            camera: CameraData {
                azimuth_deg: 0.0,
                elevation_deg: 15.0,
            },
            arrow: 0.03,
            active_below: 5e-4,
            tolerance: 1e-6,
            colour_top: 0.01,
            colours: Vec::new(),
            barriers: Vec::new(),
            corners: Vec::new(),
            watched: Vec::new(),
            obstacles: Vec::new(),
            runs: Vec::new(),
        };
        let json = data.to_script_json().unwrap();
        assert!(!json.contains('<'));
        let html = format!(r#"<script type="application/json" id="{ELEMENT_ID}">{json}</script>"#);
        assert_eq!(ViewData::from_page(&html).unwrap(), data);
    }
}
