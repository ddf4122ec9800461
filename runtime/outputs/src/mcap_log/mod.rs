//! `run.mcap`: a run as an MCAP log (the container of ROS 2 bags, read by Foxglove,
//! PlotJuggler, Rerun and the `mcap` libraries), written by `softcbf simulate --mcap`,
//! `softcbf run --mcap` and `softcbf verify replay --mcap` beside `trajectory.csv`, and
//! read back by `softcbf plot` and `softcbf identify`. This module owns the format: the
//! message types below are written and read through the same serde types, and a log read
//! back gives the records the CSV reader gives, value for value.
//!
//! Each run of the log (`filter` for a filtered run, `pd` for plain PD+: the PD+
//! comparison of `simulate --compare`, or a run without the filter) has JSON-encoded
//! channels under `/<run>/`, each with a JSON Schema, one message per recorded row,
//! stamped with the row's time in the log's own clock (`t`, ns from the run's start):
//!
//! - `joint_states` ([`JointStates`]): `t` \[s\], `name`, `position` \[m\], `velocity` \[m/s\]
//! - `commands` ([`Commands`]): `tau`, `tau_nom` \[N\]; for a log of `softcbf run` also
//!   `tension` \[N\] and `current` \[mA\], the tensions and goal currents sent (null on a
//!   tick without a reading)
//! - `barriers` ([`Barriers`]): `values`, named by the channel's metadata `labels` and
//!   `units` (JSON arrays) as the CSV's header names them
//! - `qp` ([`Qp`]): the tick's `status` (`filtered`, `relaxed`, `uncertified`,
//!   `qp-failed`, `invalid`, `unfiltered`, `no-reading`) and its `reason` where it has one
//!   (`tube`, `budget`, `out-of-domain`, …; [`crate::record::status`]), and their codes
//! - `extra` ([`ExtraColumns`]): every other column of the CSV (`status`, `reason`, and
//!   for `softcbf run` the bus timing, tensions, currents, …), named by the channel's
//!   metadata `names`
//!
//! and, when the robot is known, the robot in 3-D (`/<run>/scene`, `foxglove.SceneUpdate`,
//! and `/tf`, `foxglove.FrameTransform`; [`scene`]). A number that is not finite is
//! `null` (read back as NaN). Metadata records: `settings` (summary.json's settings) and
//! `summary` (the rest of it), and for `softcbf run` `hardware` (hardware.json), each
//! top-level field as JSON text.

pub mod scene;

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use mcap::records::{MessageHeader, Metadata};
use mcap::{WriteOptions, Writer};
use serde::{Deserialize, Deserializer, Serialize};
use serde_json::{Value, json};

use crate::model::Model;
use crate::record::status::{self, REASON, STATUS};
use crate::record::{Columns, Record, Row, as_strs};
use crate::sim::Run;

/// The file name `--mcap` writes in the output directory.
pub const FILE_NAME: &str = "run.mcap";

/// The first bytes of every MCAP file.
const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// The schema of `joint_states`.
const JOINT_STATES_SCHEMA: &str = r#"{"type":"object","title":"softcbf joint states","properties":{"t":{"type":"number","description":"time since the run's start (s)"},"name":{"type":"array","items":{"type":"string"}},"position":{"type":"array","items":{"type":["number","null"]},"description":"q (m)"},"velocity":{"type":"array","items":{"type":["number","null"]},"description":"dq/dt (m/s)"}}}"#;
/// The schema of `commands`.
const COMMANDS_SCHEMA: &str = r#"{"type":"object","title":"softcbf commands","properties":{"t":{"type":"number","description":"time since the run's start (s)"},"tau":{"type":"array","items":{"type":["number","null"]},"description":"generalized force applied (N)"},"tau_nom":{"type":"array","items":{"type":["number","null"]},"description":"nominal PD+ force (N)"},"tension":{"type":"array","items":{"type":["number","null"]},"description":"tendon tensions sent, servo 3i+k pulling tendon k of module i (N; softcbf run only)"},"current":{"type":"array","items":{"type":["number","null"]},"description":"goal currents sent, as the register is signed (mA; softcbf run only)"}}}"#;
/// The schema of `barriers`.
const BARRIERS_SCHEMA: &str = r#"{"type":"object","title":"softcbf barriers","properties":{"t":{"type":"number","description":"time since the run's start (s)"},"values":{"type":"array","items":{"type":["number","null"]},"description":"each barrier, named by the channel's metadata `labels`, in its `units`"}}}"#;
/// The schema of `qp`.
const QP_SCHEMA: &str = r#"{"type":"object","title":"softcbf QP status","properties":{"t":{"type":"number","description":"time since the run's start (s)"},"status":{"type":["string","null"],"enum":["no-reading","unfiltered","filtered","relaxed","qp-failed","invalid","uncertified",null],"description":"what the safety filter did at the tick (a row between ticks: the tick before it)"},"reason":{"type":["string","null"],"description":"why the tick was invalid or uncertified (null: no reason)"},"status_code":{"type":["number","null"],"description":"the log's `status` column"},"reason_code":{"type":["number","null"],"description":"the log's `reason` column (0: none)"}}}"#;
/// The schema of `extra`.
const EXTRA_SCHEMA: &str = r#"{"type":"object","title":"softcbf extra log columns","properties":{"t":{"type":"number","description":"time since the run's start (s)"},"values":{"type":"array","items":{"type":["number","null"]},"description":"the CSV's columns after the barriers, named by the channel's metadata `names` (with their units in brackets)"}}}"#;

/// The kinds of channel of one run, in the order they are written.
pub const KINDS: [&str; 5] = ["joint_states", "commands", "barriers", "qp", "extra"];

/// Why a log could not be written or read. Each names the file.
#[derive(Debug, thiserror::Error)]
pub enum McapError {
    /// The file could not be created, written or read.
    #[error("{}: {message}", file.display())]
    Io {
        /// The file.
        file: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The file is no MCAP log of softcbf, or is damaged.
    #[error("{}: {message}", file.display())]
    Format {
        /// The file.
        file: PathBuf,
        /// What is wrong with it.
        message: String,
    },
}

/// `/<run>/joint_states`: one row's state.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointStates {
    /// Time since the run's start \[s\].
    #[serde(deserialize_with = "number")]
    pub t: f64,
    /// The coordinates' names (`dx1`, …).
    pub name: Vec<String>,
    /// `q` \[m\].
    #[serde(deserialize_with = "numbers")]
    pub position: Vec<f64>,
    /// `q̇` \[m/s\].
    #[serde(deserialize_with = "numbers")]
    pub velocity: Vec<f64>,
}

/// `/<run>/commands`: one row's commands.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Commands {
    /// Time since the run's start \[s\].
    #[serde(deserialize_with = "number")]
    pub t: f64,
    /// `τ` applied \[N\].
    #[serde(deserialize_with = "numbers")]
    pub tau: Vec<f64>,
    /// `τ_nom`, the PD+ command \[N\].
    #[serde(deserialize_with = "numbers")]
    pub tau_nom: Vec<f64>,
    /// The tendon tensions sent (`softcbf run` only) \[N\].
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "optional_numbers"
    )]
    pub tension: Option<Vec<f64>>,
    /// The goal currents sent (`softcbf run` only) \[mA\].
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "optional_numbers"
    )]
    pub current: Option<Vec<f64>>,
}

/// `/<run>/barriers`: one row's barriers.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Barriers {
    /// Time since the run's start \[s\].
    #[serde(deserialize_with = "number")]
    pub t: f64,
    /// Each barrier in its unit (the channel's metadata `labels`, `units`).
    #[serde(deserialize_with = "numbers")]
    pub values: Vec<f64>,
}

/// `/<run>/qp`: what the safety filter did at the row's tick.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Qp {
    /// Time since the run's start \[s\].
    #[serde(deserialize_with = "number")]
    pub t: f64,
    /// [`status::status_name`] of the code.
    pub status: Option<String>,
    /// [`status::reason_name`] of the code.
    pub reason: Option<String>,
    /// The `status` column.
    #[serde(deserialize_with = "number")]
    pub status_code: f64,
    /// The `reason` column (NaN for a log without one).
    #[serde(deserialize_with = "number")]
    pub reason_code: f64,
}

/// `/<run>/extra`: the row's columns after the barriers.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExtraColumns {
    /// Time since the run's start \[s\].
    #[serde(deserialize_with = "number")]
    pub t: f64,
    /// Their values, named by the channel's metadata `names`.
    #[serde(deserialize_with = "numbers")]
    pub values: Vec<f64>,
}

/// A number, `null` read as NaN (serde_json writes a NaN or an infinity as `null`).
fn number<'de, D: Deserializer<'de>>(deserializer: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(deserializer)?.unwrap_or(f64::NAN))
}

/// Numbers, each `null` read as NaN.
fn numbers<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Vec<f64>, D::Error> {
    let values = Vec::<Option<f64>>::deserialize(deserializer)?;
    Ok(values.into_iter().map(|v| v.unwrap_or(f64::NAN)).collect())
}

fn optional_numbers<'de, D: Deserializer<'de>>(
    deserializer: D,
) -> Result<Option<Vec<f64>>, D::Error> {
    let values = Option::<Vec<Option<f64>>>::deserialize(deserializer)?;
    Ok(values.map(|v| v.into_iter().map(|x| x.unwrap_or(f64::NAN)).collect()))
}

/// One run of a log: its name (`filter` or `pd`, the channels' prefix) and its rows.
#[derive(Clone, Copy, Debug)]
pub struct LogRun<'a> {
    /// `filter` or `pd`.
    pub name: &'a str,
    /// Its title in the 3-D scene's entities (the figures' column title).
    pub title: &'a str,
    /// Its rows, as `trajectory.csv` holds them.
    pub record: &'a Record,
}

/// What a log holds.
#[derive(Clone, Copy)]
pub struct Contents<'a> {
    /// The runs, the one asked for first.
    pub runs: &'a [LogRun<'a>],
    /// summary.json's object.
    pub summary: &'a Value,
    /// hardware.json's object (`softcbf run`).
    pub hardware: Option<&'a Value>,
    /// The robot, for the 3-D scene (none without it).
    pub model: Option<&'a Model>,
}

/// What [`write_mcap`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Written {
    /// The file.
    pub path: PathBuf,
    /// Its size \[bytes\].
    pub bytes: u64,
    /// Scene updates per run (0 without the robot).
    pub scene_frames: usize,
    /// Frames of the scene per second of robot time.
    pub scene_fps: f64,
}

impl Written {
    /// `out/run.mcap: 1.2 MB, the robot in 3-D at 30 frames per second (301 frames)`.
    pub fn line(&self) -> String {
        let scene = if self.scene_frames > 0 {
            format!(
                ", the robot in 3-D at {} frames per second of robot time ({} frames)",
                crate::frames::short(self.scene_fps),
                self.scene_frames
            )
        } else {
            String::new()
        };
        format!(
            "{}: {:.1} MB{scene}",
            self.path.display(),
            self.bytes as f64 / 1e6
        )
    }
}

/// A row's time as an MCAP timestamp: ns from the run's start (negative or not finite: 0).
pub fn nanoseconds(t: f64) -> u64 {
    if t.is_finite() && t > 0.0 {
        (t * 1e9).round() as u64
    } else {
        0
    }
}

/// The channel ids of one run.
struct RunChannels {
    joint_states: u16,
    commands: u16,
    barriers: u16,
    qp: Option<u16>,
    extra: Option<u16>,
    scene: Option<u16>,
}

/// Where the `tension` and `current` of [`Commands`] are among a record's extra columns.
struct HardwareColumns {
    tension: Vec<usize>,
    current: Vec<usize>,
}

impl HardwareColumns {
    fn of(columns: &Columns) -> Option<HardwareColumns> {
        let names = columns.extra_names();
        let find = |prefix: &str, unit: &str| -> Vec<usize> {
            (0..names.len())
                .filter(|&k| names[k].starts_with(prefix) && names[k].ends_with(unit))
                .collect()
        };
        let tension = find("f module ", " [N]");
        let current = find("I module ", " [mA]");
        (!tension.is_empty() || !current.is_empty()).then_some(HardwareColumns { tension, current })
    }
}

/// Writes `path` (an MCAP file) of `contents`. An error names the file.
pub fn write_mcap(path: &Path, contents: &Contents<'_>) -> Result<Written, McapError> {
    let io = |e: &dyn std::fmt::Display| McapError::Io {
        file: path.to_path_buf(),
        message: e.to_string(),
    };
    let scene = match contents.model {
        Some(model) => scene::scene_log(model, contents.runs).map_err(|e| io(&e))?,
        None => None,
    };
    let file = File::create(path).map_err(|e| io(&e))?;
    let mut writer = WriteOptions::new()
        .library(concat!("softcbf ", env!("CARGO_PKG_VERSION")))
        .create(BufWriter::new(file))
        .map_err(|e| io(&e))?;
    write_all(&mut writer, contents, scene.as_ref()).map_err(|e| io(&e))?;
    writer.finish().map_err(|e| io(&e))?;
    drop(writer);
    let bytes = std::fs::metadata(path).map_err(|e| io(&e))?.len();
    Ok(Written {
        path: path.to_path_buf(),
        bytes,
        scene_frames: scene
            .as_ref()
            .map_or(0, |s| s.runs.first().map_or(0, Vec::len)),
        scene_fps: scene.as_ref().map_or(0.0, |s| s.fps),
    })
}

/// Writes the log of a simulated run `main` and its PD+ `comparison` (the runs `simulate`
/// and `verify replay` write to `trajectory.csv` and `trajectory_pd.csv`), with
/// summary.json's object ([`crate::output::summary_value`]) as metadata and the robot of
/// `model` in 3-D.
pub fn write_simulation(
    path: &Path,
    main: &Run,
    comparison: Option<&Run>,
    model: &Model,
) -> Result<Written, McapError> {
    let summary = crate::output::summary_value(main, comparison);
    let runs: Vec<LogRun<'_>> = std::iter::once(main)
        .chain(comparison)
        .map(|run| LogRun {
            name: run.summary.controller,
            title: crate::plot::controller_title(run.summary.controller),
            record: &run.record,
        })
        .collect();
    write_mcap(
        path,
        &Contents {
            runs: &runs,
            summary: &summary,
            hardware: None,
            model: Some(model),
        },
    )
}

/// Writes `dir/run.mcap` of the run in `dir`: `trajectory.csv` (and `trajectory_pd.csv`
/// when there), `summary.json` and, for a log of `softcbf run`, `hardware.json` as
/// metadata, and the robot of `model` in 3-D. `softcbf run --mcap` writes its log so,
/// once the run has ended and its files are closed.
pub fn write_directory(dir: &Path, model: &Model) -> Result<Written, McapError> {
    let read_json = |name: &str| -> Result<Option<Value>, McapError> {
        let file = dir.join(name);
        match std::fs::read_to_string(&file) {
            Ok(text) => serde_json::from_str(&text)
                .map(Some)
                .map_err(|e| McapError::Format {
                    file,
                    message: format!("line {}: {e}", e.line()),
                }),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(McapError::Io {
                file,
                message: e.to_string(),
            }),
        }
    };
    let summary = read_json("summary.json")?.unwrap_or(Value::Null);
    let hardware = read_json(crate::output::HARDWARE_DESCRIPTION_FILE)?;
    let read_csv = |name: &str| {
        Record::read_csv(&dir.join(name)).map_err(|e| McapError::Io {
            file: dir.join(name),
            message: e.to_string(),
        })
    };
    let main = read_csv("trajectory.csv")?;
    let comparison = dir
        .join("trajectory_pd.csv")
        .is_file()
        .then(|| read_csv("trajectory_pd.csv"))
        .transpose()?;
    let controller = summary
        .get("controller")
        .and_then(Value::as_str)
        .unwrap_or("filter");
    let on_hardware = summary.get("hardware") == Some(&Value::Bool(true));
    let title = |name: &str| {
        let title = crate::plot::controller_title(name);
        if on_hardware {
            format!("{title}, hardware")
        } else {
            title.to_string()
        }
    };
    let titles = [title(controller), title("pd")];
    let mut runs = vec![LogRun {
        name: if controller == "pd" { "pd" } else { "filter" },
        title: &titles[0],
        record: &main,
    }];
    if let Some(record) = &comparison {
        runs.push(LogRun {
            name: "pd",
            title: &titles[1],
            record,
        });
    }
    write_mcap(
        &dir.join(FILE_NAME),
        &Contents {
            runs: &runs,
            summary: &summary,
            hardware: hardware.as_ref(),
            model: Some(model),
        },
    )
}

/// Something to write at a time: a row of run `run`, a scene update of run `run`, or
/// the transforms of scene frame `index`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Item {
    Row { run: usize, index: usize },
    Scene { run: usize, index: usize },
    Transforms { index: usize },
}

fn write_all(
    writer: &mut Writer<BufWriter<File>>,
    contents: &Contents<'_>,
    scene: Option<&scene::SceneLog>,
) -> mcap::McapResult<()> {
    let none = BTreeMap::new();
    let schema = |writer: &mut Writer<_>, name: &str, text: &str| {
        writer.add_schema(name, "jsonschema", text.as_bytes())
    };
    let joint_states = schema(writer, "softcbf.JointStates", JOINT_STATES_SCHEMA)?;
    let commands = schema(writer, "softcbf.Commands", COMMANDS_SCHEMA)?;
    let barriers = schema(writer, "softcbf.Barriers", BARRIERS_SCHEMA)?;
    let qp = schema(writer, "softcbf.QpStatus", QP_SCHEMA)?;
    let extra = schema(writer, "softcbf.ExtraColumns", EXTRA_SCHEMA)?;
    let (scene_schema, tf) = match scene {
        Some(_) => {
            let update = schema(writer, "foxglove.SceneUpdate", scene::SCENE_UPDATE_SCHEMA)?;
            let transform = schema(
                writer,
                "foxglove.FrameTransform",
                scene::FRAME_TRANSFORM_SCHEMA,
            )?;
            let tf = writer.add_channel(transform, scene::TF_TOPIC, "json", &none)?;
            (Some(update), Some(tf))
        }
        None => (None, None),
    };
    let mut channels = Vec::with_capacity(contents.runs.len());
    for run in contents.runs {
        let columns = run.record.columns();
        let prefix = run.name;
        let barrier_metadata = BTreeMap::from([
            (
                "labels".to_string(),
                json!(columns.barrier_labels()).to_string(),
            ),
            (
                "units".to_string(),
                json!(columns.barrier_units()).to_string(),
            ),
        ]);
        let extra_names = columns.extra_names();
        let extra_metadata =
            BTreeMap::from([("names".to_string(), json!(extra_names).to_string())]);
        let has_status = columns.extra_names().iter().any(|n| n == STATUS);
        let mut add = |kind: &str, schema: u16, metadata: &BTreeMap<String, String>| {
            writer.add_channel(schema, &format!("/{prefix}/{kind}"), "json", metadata)
        };
        channels.push(RunChannels {
            joint_states: add("joint_states", joint_states, &none)?,
            commands: add("commands", commands, &none)?,
            barriers: add("barriers", barriers, &barrier_metadata)?,
            qp: has_status.then(|| add("qp", qp, &none)).transpose()?,
            extra: (!extra_names.is_empty())
                .then(|| add("extra", extra, &extra_metadata))
                .transpose()?,
            scene: scene_schema.map(|s| add("scene", s, &none)).transpose()?,
        });
    }

    // Every message in the order of its time (rows before the scene at the same time).
    let mut items: Vec<(u64, Item)> = Vec::new();
    for (run, log_run) in contents.runs.iter().enumerate() {
        items.extend(
            log_run
                .record
                .times()
                .enumerate()
                .map(|(index, t)| (nanoseconds(t), Item::Row { run, index })),
        );
    }
    if let Some(scene) = scene {
        for (run, updates) in scene.runs.iter().enumerate() {
            items.extend(
                updates
                    .iter()
                    .enumerate()
                    .map(|(index, u)| (u.time, Item::Scene { run, index })),
            );
        }
        items.extend(
            scene
                .transforms
                .iter()
                .enumerate()
                .map(|(index, t)| (t.0, Item::Transforms { index })),
        );
    }
    items.sort();

    let hardware: Vec<Option<HardwareColumns>> = contents
        .runs
        .iter()
        .map(|run| HardwareColumns::of(run.record.columns()))
        .collect();
    for (time, item) in items {
        match item {
            Item::Row { run, index } => {
                let record = contents.runs[run].record;
                let Some(row) = record.row(index) else {
                    continue;
                };
                let ids = &channels[run];
                let number = u32::try_from(index).unwrap_or(u32::MAX);
                for (id, message) in row_messages(record.columns(), &row, hardware[run].as_ref()) {
                    let id = match id {
                        Kind::JointStates => Some(ids.joint_states),
                        Kind::Commands => Some(ids.commands),
                        Kind::Barriers => Some(ids.barriers),
                        Kind::Qp => ids.qp,
                        Kind::Extra => ids.extra,
                    };
                    if let Some(id) = id {
                        write(writer, id, number, time, &message)?;
                    }
                }
            }
            Item::Scene { run, index } => {
                if let (Some(scene), Some(id)) = (scene, channels[run].scene) {
                    let update = &scene.runs[run][index];
                    let number = u32::try_from(index).unwrap_or(u32::MAX);
                    write(writer, id, number, time, &update.data)?;
                }
            }
            Item::Transforms { index } => {
                if let (Some(scene), Some(id)) = (scene, tf) {
                    let number = u32::try_from(index).unwrap_or(u32::MAX);
                    for data in &scene.transforms[index].1 {
                        write(writer, id, number, time, data)?;
                    }
                }
            }
        }
    }

    let mut summary = contents.summary.as_object().cloned().unwrap_or_default();
    let settings = summary.remove("settings").unwrap_or(Value::Null);
    let mut records = vec![("settings", settings), ("summary", Value::Object(summary))];
    if let Some(hardware) = contents.hardware {
        records.push(("hardware", hardware.clone()));
    }
    for (name, value) in records {
        let metadata: BTreeMap<String, String> = match value {
            Value::Object(fields) => fields
                .into_iter()
                .map(|(key, value)| (key, value.to_string()))
                .collect(),
            Value::Null => BTreeMap::new(),
            other => BTreeMap::from([("value".to_string(), other.to_string())]),
        };
        writer.write_metadata(&Metadata {
            name: name.to_string(),
            metadata,
        })?;
    }
    Ok(())
}

/// Writes one message of `channel_id`, its sequence number `sequence`, at `time` \[ns\].
fn write(
    writer: &mut Writer<BufWriter<File>>,
    channel_id: u16,
    sequence: u32,
    time: u64,
    data: &[u8],
) -> mcap::McapResult<()> {
    writer.write_to_known_channel(
        &MessageHeader {
            channel_id,
            sequence,
            log_time: time,
            publish_time: time,
        },
        data,
    )
}

/// The kind of a run's channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    JointStates,
    Commands,
    Barriers,
    Qp,
    Extra,
}

/// The messages of one row, JSON text, one per kind (`qp` only with a status column,
/// `extra` only with extra columns).
fn row_messages(
    columns: &Columns,
    row: &Row<'_>,
    hardware: Option<&HardwareColumns>,
) -> Vec<(Kind, Vec<u8>)> {
    let pick = |indices: &[usize]| -> Vec<f64> { indices.iter().map(|&k| row.extra[k]).collect() };
    let mut messages = vec![
        (
            Kind::JointStates,
            to_json(&JointStates {
                t: row.t,
                name: columns.coordinate_names().to_vec(),
                position: row.q.to_vec(),
                velocity: row.qd.to_vec(),
            }),
        ),
        (
            Kind::Commands,
            to_json(&Commands {
                t: row.t,
                tau: row.tau.to_vec(),
                tau_nom: row.tau_nom.to_vec(),
                tension: hardware.map(|h| pick(&h.tension)),
                current: hardware.map(|h| pick(&h.current)),
            }),
        ),
        (
            Kind::Barriers,
            to_json(&Barriers {
                t: row.t,
                values: row.b.to_vec(),
            }),
        ),
    ];
    let names = columns.extra_names();
    let column = |name: &str| names.iter().position(|n| n == name).map(|k| row.extra[k]);
    if let Some(code) = column(STATUS) {
        let reason = column(REASON).unwrap_or(f64::NAN);
        messages.push((
            Kind::Qp,
            to_json(&Qp {
                t: row.t,
                status: status::status_name(code).map(str::to_string),
                reason: status::reason_name(reason).map(str::to_string),
                status_code: code,
                reason_code: reason,
            }),
        ));
    }
    if !names.is_empty() {
        messages.push((
            Kind::Extra,
            to_json(&ExtraColumns {
                t: row.t,
                values: row.extra.to_vec(),
            }),
        ));
    }
    messages
}

/// `value` as JSON text (a message of a type of this module always serializes).
fn to_json<T: Serialize>(value: &T) -> Vec<u8> {
    serde_json::to_vec(value).unwrap_or_default()
}

/// A log read back.
#[derive(Clone, Debug, PartialEq)]
pub struct McapLog {
    /// Its runs in the order their channels were written (`filter`, then `pd`), each with
    /// the record `trajectory.csv` (or `trajectory_pd.csv`) holds.
    pub runs: Vec<(String, Record)>,
    /// summary.json's object (`settings` and the rest), if the log has it.
    pub summary: Option<Value>,
    /// hardware.json's object, if the log has it.
    pub hardware: Option<Value>,
}

impl McapLog {
    /// The run named `name` (`filter`, `pd`).
    pub fn run(&self, name: &str) -> Option<&Record> {
        self.runs.iter().find(|(n, _)| n == name).map(|(_, r)| r)
    }
}

/// Whether `path` is an MCAP file (it starts with the format's magic bytes).
pub fn is_mcap(path: &Path) -> bool {
    use std::io::Read;
    let mut start = [0u8; 8];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut start))
        .is_ok_and(|()| &start == MAGIC)
}

/// The messages of one run's channels, in order.
#[derive(Default)]
struct RunMessages {
    joint_states: Vec<(u32, Vec<u8>)>,
    commands: Vec<(u32, Vec<u8>)>,
    barriers: Vec<(u32, Vec<u8>)>,
    extra: Vec<(u32, Vec<u8>)>,
    labels: Option<String>,
    units: Option<String>,
    extra_names: Option<String>,
}

/// Reads a log written by [`write_mcap`]: its runs as records (the rows of the CSV it was
/// written beside, value for value), summary.json and hardware.json from its metadata.
pub fn read_mcap(path: &Path) -> Result<McapLog, McapError> {
    let bytes = std::fs::read(path).map_err(|e| McapError::Io {
        file: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let bad = |message: String| McapError::Format {
        file: path.to_path_buf(),
        message,
    };
    if !bytes.starts_with(MAGIC) {
        return Err(bad(
            "not an MCAP file (it does not start with MCAP's magic bytes)".into(),
        ));
    }
    let mut runs: Vec<(String, RunMessages)> = Vec::new();
    let stream = mcap::MessageStream::new(&bytes).map_err(|e| bad(e.to_string()))?;
    for message in stream {
        let message = message.map_err(|e| bad(format!("{e} (a damaged or cut log)")))?;
        let topic = &message.channel.topic;
        let Some((run, kind)) = topic
            .strip_prefix('/')
            .and_then(|rest| rest.split_once('/'))
        else {
            continue;
        };
        if !KINDS.contains(&kind) {
            continue;
        }
        let index = match runs.iter().position(|(name, _)| name == run) {
            Some(index) => index,
            None => {
                runs.push((run.to_string(), RunMessages::default()));
                runs.len() - 1
            }
        };
        let entry = &mut runs[index].1;
        let metadata = &message.channel.metadata;
        let data = (message.sequence, message.data.into_owned());
        match kind {
            "joint_states" => entry.joint_states.push(data),
            "commands" => entry.commands.push(data),
            "barriers" => {
                entry.labels = metadata.get("labels").cloned();
                entry.units = metadata.get("units").cloned();
                entry.barriers.push(data);
            }
            "extra" => {
                entry.extra_names = metadata.get("names").cloned();
                entry.extra.push(data);
            }
            _ => {}
        }
    }
    if runs.is_empty() {
        return Err(bad(
            "no run in it (no `/<run>/joint_states` channel with a message)".into(),
        ));
    }
    // Rows in the order of their sequence numbers (the record's), whatever the order of
    // their times.
    for (_, messages) in &mut runs {
        for channel in [
            &mut messages.joint_states,
            &mut messages.commands,
            &mut messages.barriers,
            &mut messages.extra,
        ] {
            channel.sort_by_key(|(sequence, _)| *sequence);
        }
    }
    let runs = runs
        .into_iter()
        .map(|(name, messages)| {
            let record = run_record(&name, &messages).map_err(&bad)?;
            Ok((name, record))
        })
        .collect::<Result<Vec<_>, McapError>>()?;

    let mut metadata: BTreeMap<String, serde_json::Map<String, Value>> = BTreeMap::new();
    let reader = mcap::read::LinearReader::new(&bytes).map_err(|e| bad(e.to_string()))?;
    for record in reader {
        let record = record.map_err(|e| bad(format!("{e} (a damaged or cut log)")))?;
        if let mcap::records::Record::Metadata(Metadata {
            name,
            metadata: map,
        }) = record
        {
            let fields = map
                .into_iter()
                .map(|(key, text)| {
                    let value = serde_json::from_str(&text).map_err(|e| {
                        bad(format!("metadata `{name}`, field `{key}`: not JSON: {e}"))
                    })?;
                    Ok((key, value))
                })
                .collect::<Result<serde_json::Map<_, _>, McapError>>()?;
            metadata.insert(name, fields);
        }
    }
    let summary = match (metadata.remove("summary"), metadata.remove("settings")) {
        (None, None) => None,
        (summary, settings) => {
            let mut object = summary.unwrap_or_default();
            if let Some(settings) = settings {
                object.insert("settings".into(), Value::Object(settings));
            }
            Some(Value::Object(object))
        }
    };
    let hardware = metadata.remove("hardware").map(Value::Object);
    Ok(McapLog {
        runs,
        summary,
        hardware,
    })
}

/// Message `k` (0-based) of channel `/<name>/<kind>` as a `T`.
fn parse<T: serde::de::DeserializeOwned>(
    name: &str,
    kind: &str,
    k: usize,
    data: &[u8],
) -> Result<T, String> {
    serde_json::from_slice(data).map_err(|e| format!("/{name}/{kind}, message {}: {e}", k + 1))
}

/// The record of run `name` from its messages.
fn run_record(name: &str, messages: &RunMessages) -> Result<Record, String> {
    let rows = messages.joint_states.len();
    for (kind, found) in [
        ("commands", messages.commands.len()),
        ("barriers", messages.barriers.len()),
        ("extra", messages.extra.len()),
    ] {
        if found != rows && !(kind == "extra" && found == 0) {
            return Err(format!(
                "/{name}/{kind} has {found} messages, /{name}/joint_states {rows}"
            ));
        }
    }
    let list = |what: &str, text: Option<&String>| -> Result<Vec<String>, String> {
        text.map_or(Ok(Vec::new()), |text| {
            serde_json::from_str(text)
                .map_err(|e| format!("/{name}/{what}: not a JSON list of names: {e}"))
        })
    };
    let labels = list("barriers metadata `labels`", messages.labels.as_ref())?;
    let mut units = list("barriers metadata `units`", messages.units.as_ref())?;
    if units.is_empty() {
        units = vec!["m".to_string(); labels.len()];
    }
    let extra_names = list("extra metadata `names`", messages.extra_names.as_ref())?;
    let mut record: Option<Record> = None;
    let empty = Vec::new();
    for k in 0..rows {
        let state: JointStates = parse(name, "joint_states", k, &messages.joint_states[k].1)?;
        let command: Commands = parse(name, "commands", k, &messages.commands[k].1)?;
        let barrier: Barriers = parse(name, "barriers", k, &messages.barriers[k].1)?;
        let extra: Option<ExtraColumns> = messages
            .extra
            .get(k)
            .map(|(_, data)| parse(name, "extra", k, data))
            .transpose()?;
        let record = match &mut record {
            Some(record) => record,
            None => {
                let columns = Columns::named_with_units(
                    &as_strs(&state.name),
                    &as_strs(&labels),
                    &as_strs(&units),
                    &as_strs(&extra_names),
                )
                .map_err(|e| format!("/{name}: the columns it names: {e}"))?;
                record.insert(Record::for_columns(columns, rows))
            }
        };
        let times = [
            ("commands", command.t),
            ("barriers", barrier.t),
            ("extra", extra.as_ref().map_or(state.t, |e| e.t)),
        ];
        for (kind, t) in times {
            if !(t == state.t || (t.is_nan() && state.t.is_nan())) {
                return Err(format!(
                    "/{name}/{kind}, message {}: t = {t}, /{name}/joint_states has {}",
                    k + 1,
                    state.t
                ));
            }
        }
        record
            .push_row(&Row {
                t: state.t,
                q: &state.position,
                qd: &state.velocity,
                tau: &command.tau,
                tau_nom: &command.tau_nom,
                b: &barrier.values,
                extra: extra.as_ref().map_or(&empty, |e| &e.values),
            })
            .map_err(|e| format!("/{name}, message {}: {e}", k + 1))?;
    }
    record.ok_or_else(|| format!("/{name}: no row"))
}
