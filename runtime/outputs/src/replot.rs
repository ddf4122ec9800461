//! `softcbf plot`: the figures redrawn from trajectory CSVs or hardware logs, without
//! running anything again; titles and set point from the `summary.json` beside each file.
//!
//! ```no_run
//! use softcbf_figures::plot::FigureOptions;
//! use softcbf_outputs::replot::replot;
//! let files = ["out/trajectory.csv".into(), "out/trajectory_pd.csv".into()];
//! let written = replot(&files, None, None, &FigureOptions::default())?;
//! assert_eq!(written.len(), 2); // out/figure.png, out/figure.svg
//! # Ok::<(), softcbf_outputs::replot::ReplotError>(())
//! ```

use std::path::{Path, PathBuf};

use clap::Args;
use serde_json::Value;

use crate::mcap_log::{McapError, is_mcap, read_mcap};
use crate::model::Model;
use crate::output::Console;
use crate::plot::{FigureOptions, PlotError, Split, controller_title, write_figures};
use crate::record::{Columns, Record, RecordError, Row, as_strs};
use crate::sim::barriers_per_module;

/// Why figures could not be redrawn. Each names the file at fault.
#[derive(Debug, thiserror::Error)]
pub enum ReplotError {
    /// No file was given.
    #[error("no trajectory file given")]
    NoFiles,
    /// A trajectory file could not be read (file, line and column named).
    #[error(transparent)]
    Record(#[from] RecordError),
    /// A `summary.json` could not be read or parsed.
    #[error("{}{}: {message}", file.display(), line.map_or(String::new(), |l| format!(":{l}")))]
    Summary {
        /// The summary file.
        file: PathBuf,
        /// 1-based line, when the parser gives one.
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },
    /// A file does not have the first file's numbers of coordinates or barriers.
    #[error("{}: {found} {what}, but {} has {expected}", file.display(), first.display())]
    Mismatch {
        /// The file.
        file: PathBuf,
        /// The first file.
        first: PathBuf,
        /// `coordinates` or `barriers`.
        what: &'static str,
        /// The first file's count.
        expected: usize,
        /// This file's count.
        found: usize,
    },
    /// The robot given does not fit a file.
    #[error("{}: {found} {what}, but the robot `{robot}` has {expected}", file.display())]
    Robot {
        /// The file.
        file: PathBuf,
        /// The robot's name.
        robot: String,
        /// `coordinates` or `barriers`.
        what: &'static str,
        /// The robot's count.
        expected: usize,
        /// The file's count.
        found: usize,
    },
    /// The figures could not be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// An MCAP log could not be read.
    #[error(transparent)]
    Mcap(#[from] McapError),
}

/// The arguments of `softcbf plot`.
#[derive(Args, Debug)]
pub struct PlotArgs {
    /// Trajectory CSVs of `simulate` or logs of `run`, or MCAP logs (`run.mcap`: every
    /// run in it); several are drawn side by side.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Output directory (default: the directory of the first file).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Robot file whose barrier labels and modules the figures use (default: the labels
    /// in the files' headers).
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Time window `START,END` in seconds (default: the whole run).
    #[arg(long, value_name = "START,END", allow_hyphen_values = true)]
    pub t_range: Option<String>,
    /// Where the time axis splits into the transient and the rest: `auto` (where the
    /// motion settles), `off`, or a time in seconds.
    #[arg(long, default_value = "auto", value_name = "auto|off|SECONDS")]
    pub split: String,
    /// Also write the animation `robot.gif` (needs the robot: --robot or the run's
    /// summary.json).
    #[arg(long)]
    pub animate: bool,
}

/// `softcbf plot`: reads the files, draws the figures, says what it wrote.
pub fn plot(args: PlotArgs, console: &mut Console) -> Result<u8, String> {
    let time_range = args.t_range.as_deref().map(parse_time_range).transpose()?;
    let split = parse_split(&args.split)?;
    let model = match &args.robot {
        Some(path) => {
            let robot = crate::robot_file::load_robot(Some(path)).map_err(|e| e.to_string())?;
            Some(Model::new(robot).map_err(|e| e.to_string())?)
        }
        None => robot_of_run(&args.files),
    };
    if model.is_none() && args.animate {
        return Err(
            "--animate: the robot of these files is not known (no summary.json naming a \
             robot file that can be read beside them); give it with --robot FILE"
                .into(),
        );
    }
    let options = FigureOptions {
        time_range,
        split,
        animate: args.animate,
        ..FigureOptions::default()
    };
    let written = replot(&args.files, args.out.as_deref(), model.as_ref(), &options)
        .map_err(|e| e.to_string())?;
    let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    console.say(&format!("wrote {}", names.join(", ")));
    if let Some(error) = console.error() {
        return Err(error.to_string());
    }
    Ok(crate::exit::OK)
}

/// The model of the robot named in the `summary.json` beside the first of `files`, if
/// that file can still be read; otherwise `None` and a note on standard error (the
/// figures are drawn, the 3-D view is not).
fn robot_of_run(files: &[PathBuf]) -> Option<Model> {
    match run_robot(files.first()?) {
        Ok(model) => model,
        Err(error) => {
            eprintln!(
                "note: no 3-D view: the run's robot file cannot be used ({error}); give it \
                 with --robot FILE"
            );
            None
        }
    }
}

/// The model of the robot that the `summary.json` beside `file` names
/// (`settings.robot.file`): `Ok(None)` when there is no summary or it names no robot
/// file; an error when the summary cannot be read or the robot file cannot be used.
pub(crate) fn run_robot(file: &Path) -> Result<Option<Model>, String> {
    let facts = facts_for(file).map_err(|e| e.to_string())?;
    let Some(robot_file) = facts.robot_file else {
        return Ok(None);
    };
    let robot = if robot_file.starts_with("<embedded") {
        crate::robot_file::load_robot(None)
    } else {
        crate::robot_file::load_robot(Some(Path::new(&robot_file)))
    };
    robot
        .map_err(|e| e.to_string())
        .and_then(|robot| Model::new(robot).map_err(|e| e.to_string()))
        .map(Some)
}

/// `START,END` \[s\] of `--t-range`.
pub fn parse_time_range(text: &str) -> Result<(f64, f64), String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let [start, end] = parts[..] else {
        return Err(format!(
            "--t-range: `{text}`: give two times in seconds, START,END (e.g. 0,2)"
        ));
    };
    let number = |part: &str| {
        part.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("--t-range: `{part}` is not a finite number of seconds"))
    };
    let (start, end) = (number(start)?, number(end)?);
    if start >= end {
        return Err(format!(
            "--t-range: the start {start} s must be below the end {end} s"
        ));
    }
    Ok((start, end))
}

/// `auto`, `off` or a time \[s\] of `--split`.
pub fn parse_split(text: &str) -> Result<Split, String> {
    match text.trim() {
        "auto" => Ok(Split::Auto),
        "off" => Ok(Split::Off),
        other => other
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .map(Split::At)
            .ok_or_else(|| format!("--split: `{other}`: give `auto`, `off` or a time in seconds")),
    }
}

/// What the `summary.json` beside a file says about that file's run.
#[derive(Debug, Default)]
struct RunFacts {
    controller: Option<String>,
    set_point: Option<Vec<f64>>,
    /// The robot file the run used (`settings.robot.file`).
    robot_file: Option<String>,
    /// The names of the run's scenario and robot (`scenario`, `robot`).
    names: Option<(String, String)>,
}

/// Reads `summary.json` beside `file`, if there is one, and picks the part about `file`:
/// the `comparison` object for a `…_pd.csv` file (as `softcbf simulate` writes them), the
/// whole summary otherwise. For an MCAP log, the summary it holds, about its first run.
fn facts_for(file: &Path) -> Result<RunFacts, ReplotError> {
    if is_mcap(file) {
        let log = read_mcap(file)?;
        let first = log.runs.first().map_or("", |(name, _)| name.as_str());
        return match &log.summary {
            Some(summary) => facts_of(summary, first == "pd", file),
            None => Ok(RunFacts::default()),
        };
    }
    let summary_path = file
        .parent()
        .unwrap_or_else(|| Path::new(""))
        .join("summary.json");
    let text = match std::fs::read_to_string(&summary_path) {
        Ok(text) => text,
        Err(error) if error.kind() == std::io::ErrorKind::NotFound => {
            return Ok(RunFacts::default());
        }
        Err(error) => {
            return Err(ReplotError::Summary {
                file: summary_path,
                line: None,
                message: error.to_string(),
            });
        }
    };
    let summary: Value = serde_json::from_str(&text).map_err(|error| ReplotError::Summary {
        file: summary_path.clone(),
        line: Some(error.line()),
        message: error.to_string(),
    })?;
    let is_comparison = file
        .file_stem()
        .and_then(|s| s.to_str())
        .is_some_and(|stem| stem.ends_with("_pd"));
    facts_of(&summary, is_comparison, &summary_path)
}

/// What `summary` (summary.json's object, read from `summary_path`) says about its run, or
/// with `is_comparison` about its PD+ comparison when it has one.
fn facts_of(
    summary: &Value,
    is_comparison: bool,
    summary_path: &Path,
) -> Result<RunFacts, ReplotError> {
    let summary_path = summary_path.to_path_buf();
    let part = match summary.get("comparison") {
        Some(comparison) if is_comparison => comparison,
        _ => summary,
    };
    let controller = part
        .get("controller")
        .and_then(Value::as_str)
        .map(str::to_string);
    let set_point = match part.get("set_point").or_else(|| summary.get("set_point")) {
        None | Some(Value::Null) => None,
        Some(value) => {
            let numbers: Option<Vec<f64>> = value
                .as_array()
                .and_then(|items| items.iter().map(Value::as_f64).collect());
            Some(numbers.ok_or_else(|| ReplotError::Summary {
                file: summary_path.clone(),
                line: None,
                message: "field `set_point`: expected an array of numbers".to_string(),
            })?)
        }
    };
    let robot_file = summary
        .pointer("/settings/robot/file")
        .and_then(Value::as_str)
        .map(str::to_string);
    let name = |key: &str| summary.get(key).and_then(Value::as_str).map(str::to_string);
    let names = name("scenario").zip(name("robot"));
    Ok(RunFacts {
        controller,
        set_point,
        robot_file,
        names,
    })
}

/// Whether `record` is a log of `softcbf run` (it has the bus timing columns).
fn is_hardware_log(record: &Record) -> bool {
    let extra = record.columns().extra_names();
    extra
        .iter()
        .any(|name| name == "read [us]" || name == "read_us")
}

/// The controller of a hardware log from its `status` column (1–3: the QP ran).
fn controller_from_status(record: &Record) -> Option<&'static str> {
    let index = record.columns().index_of("status")?;
    let mut any = false;
    for status in record.column(index) {
        if (1.0..=3.0).contains(&status) {
            return Some("filter");
        }
        any |= status == 0.0;
    }
    any.then_some("pd")
}

/// The column title of `file`: its controller (from `summary.json`, or for a hardware log
/// from its `status` column), with `, hardware` for a log of `softcbf run`; else the file
/// name.
fn title_for(file: &Path, record: &Record, facts: &RunFacts) -> String {
    let hardware = is_hardware_log(record);
    // (A trajectory of `simulate` has a status column too, but its title is its file's.)
    let controller = facts.controller.clone().or_else(|| {
        hardware
            .then(|| controller_from_status(record))
            .flatten()
            .map(str::to_string)
    });
    match controller {
        Some(controller) => {
            let title = controller_title(&controller).to_string();
            if hardware {
                format!("{title}, hardware")
            } else {
                title
            }
        }
        None => file.file_name().map_or_else(
            || file.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        ),
    }
}

/// The runs of some files as `softcbf plot` reads them: records, column titles and what
/// their `summary.json` says.
pub(crate) struct Runs {
    /// One record per file, in order.
    pub records: Vec<Record>,
    /// Each record's column title (told apart by file where two are the same).
    pub titles: Vec<String>,
    /// The first file's set point, if its summary gives one of the records' length.
    pub set_point: Vec<f64>,
    /// `scenario on robot`, from the first file's summary.
    pub heading: Option<String>,
}

/// Reads `files` (trajectory CSVs, hardware logs or MCAP logs, every run in one) with the
/// `summary.json` beside each (an MCAP log holds its own);
/// with `model`, the barrier labels and their modules come from that robot instead of
/// the files' headers (for logs written before the headers named them). Refuses files
/// whose numbers of coordinates or barriers differ from the first's or the model's.
pub(crate) fn read_runs(files: &[PathBuf], model: Option<&Model>) -> Result<Runs, ReplotError> {
    let first = files.first().ok_or(ReplotError::NoFiles)?;
    let mut records: Vec<Record> = Vec::with_capacity(files.len());
    let mut titles = Vec::with_capacity(files.len());
    let mut set_point = None;
    let mut heading = None;
    // Every run of every file: a CSV holds one, an MCAP log one per run in it.
    let mut runs: Vec<(PathBuf, Record, RunFacts)> = Vec::with_capacity(files.len());
    for file in files {
        if is_mcap(file) {
            let log = read_mcap(file)?;
            for (name, record) in log.runs {
                let facts = match &log.summary {
                    Some(summary) => facts_of(summary, name == "pd", file)?,
                    None => RunFacts::default(),
                };
                runs.push((file.clone(), record, facts));
            }
        } else {
            runs.push((file.clone(), Record::read_csv(file)?, facts_for(file)?));
        }
    }
    let files: Vec<PathBuf> = runs.iter().map(|(file, ..)| file.clone()).collect();
    for (file, mut record, facts) in runs {
        let file = &file;
        if let Some(model) = model {
            apply_robot(file, &mut record, model)?;
        }
        if let Some(head) = records.first().map(Record::columns) {
            for (what, expected, found) in [
                ("coordinates", head.n(), record.columns().n()),
                ("barriers", head.m(), record.columns().m()),
            ] {
                if expected != found {
                    return Err(ReplotError::Mismatch {
                        file: file.clone(),
                        first: first.clone(),
                        what,
                        expected,
                        found,
                    });
                }
            }
        }
        if records.is_empty() {
            set_point = facts.set_point.clone();
            heading = facts
                .names
                .as_ref()
                .map(|(scenario, robot)| format!("{scenario} on {robot}"));
        }
        titles.push(title_for(file, &record, &facts));
        records.push(record);
    }
    // Two columns of the same title: tell them apart by file.
    for k in 0..titles.len() {
        if titles.iter().filter(|t| **t == titles[k]).count() > 1 {
            titles[k] = format!("{} ({})", titles[k], files[k].display());
        }
    }
    let n = records[0].columns().n();
    let set_point = set_point.filter(|s| s.len() == n).unwrap_or_default();
    Ok(Runs {
        records,
        titles,
        set_point,
        heading,
    })
}

/// Redraws the figures of the runs in `files` (one column each, left to right) into
/// `out_dir` (default: the first file's directory) and returns the files written. Titles
/// and the set point come from the `summary.json` beside each file when there is one
/// (the set point from the first file's); with `model`, the barrier labels and their
/// modules come from that robot instead of the files' headers (for logs written before
/// the headers named them).
pub fn replot(
    files: &[PathBuf],
    out_dir: Option<&Path>,
    model: Option<&Model>,
    options: &FigureOptions,
) -> Result<Vec<PathBuf>, ReplotError> {
    let first = files.first().ok_or(ReplotError::NoFiles)?;
    let Runs {
        records,
        titles,
        set_point,
        ..
    } = read_runs(files, model)?;
    let per_module = model
        .map(|model| barriers_per_module(model.generated.barrier_table(), model.n_modules()))
        .unwrap_or_default();
    let options = FigureOptions {
        barriers_per_module: &per_module,
        model,
        ..*options
    };
    let panels: Vec<(&str, &Record)> = titles.iter().map(String::as_str).zip(&records).collect();
    let out_dir = match out_dir {
        Some(dir) => dir.to_path_buf(),
        None => first
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or_else(|| Path::new("."))
            .to_path_buf(),
    };
    Ok(write_figures(&out_dir, &panels, &set_point, &options)?)
}

/// Names the columns of `record` (read from `file`) after `model`: its coordinates and
/// barrier labels, the extra columns kept. A record written before every module carried
/// the domain's limit barriers (docs/model.md §3) has the model's barriers without the
/// limits its robot file does not write; those rows are added, computed from each row's
/// `q`, so that the record has the model's columns.
fn apply_robot(file: &Path, record: &mut Record, model: &Model) -> Result<(), ReplotError> {
    let columns = record.columns();
    let table = model.generated.barrier_table();
    // The barriers a log of this robot had before the domain's limits: all but those.
    let written: Vec<usize> = (0..table.len())
        .filter(|&k| {
            let info = &table[k];
            !model
                .robot
                .limits
                .get(info.module)
                .is_some_and(|limits| limits.is_domain_default(info.kind))
        })
        .collect();
    let older = columns.m() != model.nb() && columns.m() == written.len();
    let barriers = if older { written.len() } else { model.nb() };
    for (what, expected, found) in [
        ("coordinates", model.nq(), columns.n()),
        ("barriers", barriers, columns.m()),
    ] {
        if expected != found {
            return Err(ReplotError::Robot {
                file: file.to_path_buf(),
                robot: model.robot.name.clone(),
                what,
                expected,
                found,
            });
        }
    }
    let extra = columns.extra_names().to_vec();
    let named = Columns::for_model(model, &as_strs(&extra))?;
    if !older {
        record.relabel(named)?;
        return Ok(());
    }
    let mut full = Record::for_columns(named, record.len());
    let mut b = vec![0.0; model.nb()];
    for row in record.rows() {
        model.generated.barriers(&model.params, row.q, &mut b);
        for (&k, &value) in written.iter().zip(row.b) {
            b[k] = value;
        }
        full.push_row(&Row { b: &b, ..row })?;
    }
    *record = full;
    Ok(())
}
