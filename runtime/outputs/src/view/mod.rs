//! `softcbf view DIR` (and `softcbf simulate --view`): a run of `softcbf simulate` as one
//! self-contained HTML page, an interactive 3-D view that works offline in any browser.
//!
//! The robot is computed here, frame by frame, as the 3-D figure draws it
//! ([`crate::plot::robot_view::scene`]: backbone arcs, tendons, plates, corners with their
//! feet, watched points, obstacles), embedded as JSON ([`data::ViewData`]), and drawn by a
//! small script written for this page (`view.js`: a canvas with a perspective camera, no
//! library, nothing fetched): drag to rotate, wheel to zoom, a time slider and a play
//! button, the filtered run and the PD+ comparison side by side, corners and watched
//! points coloured by their barrier (red past the verdict's tolerance below zero, orange
//! within 0.5 mm of the margin, a colour scale above). The page's address may carry
//! `#t=SECONDS` (the slider's first time), `az=DEG`, `el=DEG` and `zoom=F`.
//!
//! Frames are the records' rows nearest to `t0 + k/fps` ([`frame_times`]), at most
//! [`MAX_FRAMES`]; the page says its rate. The paper's 10 s run at the default 30 frames
//! per second gives 301 frames, about 3 MB.

use std::path::{Path, PathBuf};

use clap::Args;
use softcbf_description::limits::Limit;

use crate::model::Model;
use crate::output::Console;
use crate::plot::PlotError;
use crate::plot::robot_view::scene::{drawable_span, scene_frames};
use crate::record::Record;
use crate::replot::{ReplotError, Runs, read_runs, run_robot};
use crate::settings::check_number;

pub mod data;

use data::ViewData;

pub use crate::frames::{DEFAULT_FPS, MAX_FRAMES, frame_times, short};

/// The page's file name in the run's directory.
pub const FILE_NAME: &str = "view.html";
/// The trajectory of the run asked for, and of its PD+ comparison, in a run's directory.
pub const TRAJECTORY: &str = "trajectory.csv";
/// See [`TRAJECTORY`].
pub const TRAJECTORY_PD: &str = "trajectory_pd.csv";
/// The range of `--fps` \[frames per second of robot time\].
pub const FPS: Limit = Limit::closed(1.0, 240.0, "frames/s");

/// The page template: style and markup, with the data and the script put in at the marks.
const TEMPLATE: &str = include_str!("page.html");
/// The page's script.
const SCRIPT: &str = include_str!("view.js");
const DATA_MARK: &str = "/*SOFTCBF-VIEW-DATA*/";
const SCRIPT_MARK: &str = "/*SOFTCBF-VIEW-SCRIPT*/";

/// Why a view could not be written. Each names the directory or file at fault.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// The run's directory does not exist or is not a directory.
    #[error(
        "{}: {problem}; give the output directory of `softcbf simulate` (it holds {TRAJECTORY})",
        dir.display()
    )]
    Directory {
        /// The directory given.
        dir: PathBuf,
        /// What is wrong with it.
        problem: &'static str,
    },
    /// The run's directory has no trajectory.
    #[error(
        "{}: not found; `softcbf view` reads the output directory of `softcbf simulate` \
         ({TRAJECTORY}, and {TRAJECTORY_PD} and summary.json when there)",
        file.display()
    )]
    NoTrajectory {
        /// The file looked for.
        file: PathBuf,
    },
    /// The run's robot is not known.
    #[error(
        "{}: the run's robot is not known (no summary.json naming its robot file beside \
         it); give it with --robot FILE",
        file.display()
    )]
    NoRobot {
        /// The trajectory.
        file: PathBuf,
    },
    /// The robot file named by the summary or given could not be used.
    #[error("{0}")]
    Robot(String),
    /// A setting out of its range.
    #[error("{0}")]
    Setting(String),
    /// A trajectory or summary could not be read.
    #[error(transparent)]
    Read(#[from] ReplotError),
    /// A trajectory has no row, or no row of any can be drawn.
    #[error("{}: no row with a finite time and state to draw", file.display())]
    Empty {
        /// The trajectory.
        file: PathBuf,
    },
    /// The geometry could not be computed.
    #[error(transparent)]
    Scene(#[from] PlotError),
    /// The page could not be written.
    #[error("{}: {source}", file.display())]
    Write {
        /// The page.
        file: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The data could not be put in JSON.
    #[error("{}: {message}", file.display())]
    Data {
        /// The page.
        file: PathBuf,
        /// serde_json's message.
        message: String,
    },
}

/// The arguments of `softcbf view`.
#[derive(Args, Debug)]
pub struct ViewArgs {
    /// Output directory of `softcbf simulate` (trajectory.csv; trajectory_pd.csv and
    /// summary.json when there).
    pub dir: PathBuf,
    /// The page to write (default: DIR/view.html).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Robot file of the run (default: the one DIR/summary.json names).
    #[arg(long, value_name = "FILE")]
    pub robot: Option<PathBuf>,
    /// Frames per second of robot time (1 to 240; fewer for a run so long that it would
    /// need more than 1500 frames).
    #[arg(long, default_value_t = DEFAULT_FPS, allow_negative_numbers = true)]
    pub fps: f64,
}

/// What [`write_view`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Written {
    /// The page.
    pub path: PathBuf,
    /// Frames in it.
    pub frames: usize,
    /// Frames per second of robot time.
    pub fps: f64,
    /// Its size \[bytes\].
    pub bytes: usize,
}

impl Written {
    /// `view.html: 301 frames, 30 per second of robot time, 2.9 MB`.
    pub fn line(&self) -> String {
        format!(
            "{}: {} frames, {} per second of robot time, {:.1} MB",
            self.path.display(),
            self.frames,
            short(self.fps),
            self.bytes as f64 / 1e6
        )
    }
}

/// `softcbf view`: writes the page, says what it wrote.
pub fn view(args: ViewArgs, console: &mut Console) -> Result<u8, String> {
    let fps = check_number("--fps", args.fps, &FPS)?;
    let model = match &args.robot {
        Some(path) => {
            let robot = crate::robot_file::load_robot(Some(path)).map_err(|e| e.to_string())?;
            Some(Model::new(robot).map_err(|e| e.to_string())?)
        }
        None => None,
    };
    let out = args.out.unwrap_or_else(|| args.dir.join(FILE_NAME));
    let written = write_view(&args.dir, &out, model.as_ref(), fps).map_err(|e| e.to_string())?;
    console.say(&format!("wrote {}", written.line()));
    if let Some(error) = console.error() {
        return Err(error.to_string());
    }
    Ok(crate::exit::OK)
}

/// Writes the page `out` (its directory created if missing) of the run in `dir`:
/// `trajectory.csv`, beside it `trajectory_pd.csv` when there, titles from `summary.json`.
/// The robot is `model`, else the one the summary names. `fps` (checked against [`FPS`])
/// frames per second of robot time, fewer beyond [`MAX_FRAMES`].
pub fn write_view(
    dir: &Path,
    out: &Path,
    model: Option<&Model>,
    fps: f64,
) -> Result<Written, ViewError> {
    if !dir.exists() {
        return Err(ViewError::Directory {
            dir: dir.to_path_buf(),
            problem: "no such directory",
        });
    }
    if !dir.is_dir() {
        return Err(ViewError::Directory {
            dir: dir.to_path_buf(),
            problem: "not a directory",
        });
    }
    let first = dir.join(TRAJECTORY);
    if !first.is_file() {
        return Err(ViewError::NoTrajectory { file: first });
    }
    let mut files = vec![first.clone()];
    let comparison = dir.join(TRAJECTORY_PD);
    if comparison.is_file() {
        files.push(comparison);
    }
    let found;
    let model = match model {
        Some(model) => model,
        None => {
            found = run_robot(&first)
                .map_err(ViewError::Robot)?
                .ok_or_else(|| ViewError::NoRobot {
                    file: first.clone(),
                })?;
            &found
        }
    };
    let fps = check_number("fps", fps, &FPS).map_err(ViewError::Setting)?;
    let Runs {
        records,
        titles,
        heading,
        ..
    } = read_runs(&files, Some(model))?;
    if let Some((file, _)) = files.iter().zip(&records).find(|(_, r)| r.is_empty()) {
        return Err(ViewError::Empty { file: file.clone() });
    }
    let panels: Vec<(&str, &Record)> = titles.iter().map(String::as_str).zip(&records).collect();
    let span = drawable_span(model, &panels)?.ok_or(ViewError::Empty {
        file: first.clone(),
    })?;
    let (times, fps) = frame_times(span, fps);
    let scene = scene_frames(model, &panels, &times, None)?;
    let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
    let title = heading.unwrap_or_else(|| dir.display().to_string());
    let data = ViewData::from_scene(model, &scene, &names, &title, fps);
    let html = page(&data).map_err(|message| ViewError::Data {
        file: out.to_path_buf(),
        message,
    })?;
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|source| ViewError::Write {
            file: out.to_path_buf(),
            source,
        })?;
    }
    std::fs::write(out, &html).map_err(|source| ViewError::Write {
        file: out.to_path_buf(),
        source,
    })?;
    Ok(Written {
        path: out.to_path_buf(),
        frames: times.len(),
        fps,
        bytes: html.len(),
    })
}

/// The page of `data`: the template with the data and the script put in.
pub fn page(data: &ViewData) -> Result<String, String> {
    let json = data.to_script_json().map_err(|e| e.to_string())?;
    let (head, rest) = TEMPLATE
        .split_once(DATA_MARK)
        .ok_or("the page template has no data mark")?;
    let (middle, tail) = rest
        .split_once(SCRIPT_MARK)
        .ok_or("the page template has no script mark")?;
    let mut html = String::with_capacity(TEMPLATE.len() + SCRIPT.len() + json.len());
    html.push_str(head);
    html.push_str(&json);
    html.push_str(middle);
    html.push_str(SCRIPT);
    html.push_str(tail);
    Ok(html)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_at_the_rate_and_end_on_the_last_row() {
        let (times, fps) = frame_times((0.0, 1.0), 30.0);
        assert_eq!(fps, 30.0);
        assert_eq!(times.len(), 31);
        assert_eq!(times[0], 0.0);
        assert_eq!(times[30], 1.0);
        assert!((times[1] - 1.0 / 30.0).abs() < 1e-15);
        // A span that is no whole number of frames ends on its end.
        let (times, _) = frame_times((0.5, 0.61), 30.0);
        assert_eq!(times.len(), 5);
        assert_eq!(*times.last().unwrap(), 0.61);
        assert!((times[3] - 0.6).abs() < 1e-12);
        // One that is (to rounding) ends on its end, without a frame 1e-16 s before it.
        let (times, _) = frame_times((0.5, 0.6), 30.0);
        assert_eq!(times.len(), 4);
        assert_eq!(*times.last().unwrap(), 0.6);
        assert!(times.windows(2).all(|w| w[0] < w[1]));
        // A long run is thinned to the most frames a page holds.
        let (times, fps) = frame_times((0.0, 1000.0), 30.0);
        assert_eq!(times.len(), MAX_FRAMES);
        assert_eq!(*times.last().unwrap(), 1000.0);
        assert!((fps - (MAX_FRAMES - 1) as f64 / 1000.0).abs() < 1e-9);
        // One instant: one frame.
        assert_eq!(frame_times((2.0, 2.0), 30.0).0, vec![2.0]);
    }

    #[test]
    fn the_template_has_each_mark_once_and_the_script_no_closing_tag() {
        assert_eq!(TEMPLATE.matches(DATA_MARK).count(), 1);
        assert_eq!(TEMPLATE.matches(SCRIPT_MARK).count(), 1);
        assert!(TEMPLATE.find(DATA_MARK) < TEMPLATE.find(SCRIPT_MARK));
        assert!(!SCRIPT.to_ascii_lowercase().contains("</script"));
        for text in [TEMPLATE, SCRIPT] {
            assert!(!text.contains("http://") && !text.contains("https://"));
        }
    }
}
