//! `run.mcap`: a simulated run as an MCAP log (the container of ROS 2 bags, read by
//! Foxglove, PlotJuggler, Rerun and the `mcap` libraries), written by `softcbf simulate
//! --mcap` beside `trajectory.csv`.
//!
//! One JSON-encoded channel per kind of row and run (`/filter/…` for the run asked for,
//! `/pd/…` for the PD+ comparison), each with a JSON Schema, one message per recorded row,
//! stamped with the row's time in the log's own clock (`t` in ns from the run's start):
//!
//! - `joint_states`: `{"t": s, "name": [coordinate…], "position": [m…], "velocity": [m/s…]}`
//! - `commands`: `{"t": s, "tau": [N…], "tau_nom": [N…]}` (applied and nominal PD+)
//! - `barriers`: `{"t": s, "values": [m or rad…]}`; the channel's metadata `labels` and
//!   `units` (JSON arrays) name each value, as the CSV's header does
//!
//! and two metadata records, `settings` (the settings of `summary.json`) and `summary` (the
//! rest of it), each top-level field as JSON text. The rows are the CSV's, the same doubles.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use mcap::records::{MessageHeader, Metadata};
use mcap::{WriteOptions, Writer};
use serde_json::{Value, json};

use crate::record::Record;
use crate::sim::Run;

/// The file name `simulate --mcap` writes in its output directory.
pub const FILE_NAME: &str = "run.mcap";

/// The schema of `joint_states`.
const JOINT_STATES_SCHEMA: &str = r#"{"type":"object","title":"softcbf joint states","properties":{"t":{"type":"number","description":"time since the run's start (s)"},"name":{"type":"array","items":{"type":"string"}},"position":{"type":"array","items":{"type":"number"},"description":"q (m)"},"velocity":{"type":"array","items":{"type":"number"},"description":"dq/dt (m/s)"}}}"#;
/// The schema of `commands`.
const COMMANDS_SCHEMA: &str = r#"{"type":"object","title":"softcbf commands","properties":{"t":{"type":"number","description":"time since the run's start (s)"},"tau":{"type":"array","items":{"type":"number"},"description":"generalized force applied (N)"},"tau_nom":{"type":"array","items":{"type":"number"},"description":"nominal PD+ force (N)"}}}"#;
/// The schema of `barriers`.
const BARRIERS_SCHEMA: &str = r#"{"type":"object","title":"softcbf barriers","properties":{"t":{"type":"number","description":"time since the run's start (s)"},"values":{"type":"array","items":{"type":"number"},"description":"each barrier, named by the channel's metadata `labels`, in its `units`"}}}"#;

/// Writes `path` (an MCAP file) from `main` and, when given, the PD+ `comparison`, with
/// `summary` (summary.json's object) as metadata. An error names the file.
pub fn write_mcap(
    path: &Path,
    main: &Run,
    comparison: Option<&Run>,
    summary: &Value,
) -> Result<(), String> {
    let fail = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let file = File::create(path).map_err(|e| fail(&e))?;
    let mut writer = WriteOptions::new()
        .library(concat!("softcbf ", env!("CARGO_PKG_VERSION")))
        .create(BufWriter::new(file))
        .map_err(|e| fail(&e))?;
    let schemas = Schemas {
        joint_states: writer
            .add_schema(
                "softcbf.JointStates",
                "jsonschema",
                JOINT_STATES_SCHEMA.as_bytes(),
            )
            .map_err(|e| fail(&e))?,
        commands: writer
            .add_schema("softcbf.Commands", "jsonschema", COMMANDS_SCHEMA.as_bytes())
            .map_err(|e| fail(&e))?,
        barriers: writer
            .add_schema("softcbf.Barriers", "jsonschema", BARRIERS_SCHEMA.as_bytes())
            .map_err(|e| fail(&e))?,
    };
    write_run(&mut writer, &schemas, "/filter", &main.record).map_err(|e| fail(&e))?;
    if let Some(pd) = comparison {
        write_run(&mut writer, &schemas, "/pd", &pd.record).map_err(|e| fail(&e))?;
    }
    let mut rest = summary.as_object().cloned().unwrap_or_default();
    let settings = rest.remove("settings").unwrap_or(Value::Null);
    for (name, value) in [("settings", settings), ("summary", Value::Object(rest))] {
        let metadata: BTreeMap<String, String> = match value {
            Value::Object(fields) => fields
                .into_iter()
                .map(|(key, value)| (key, value.to_string()))
                .collect(),
            Value::Null => BTreeMap::new(),
            other => BTreeMap::from([("value".to_string(), other.to_string())]),
        };
        writer
            .write_metadata(&Metadata {
                name: name.to_string(),
                metadata,
            })
            .map_err(|e| fail(&e))?;
    }
    writer.finish().map_err(|e| fail(&e))?;
    Ok(())
}

/// The schema ids of the three kinds of channel.
struct Schemas {
    joint_states: u16,
    commands: u16,
    barriers: u16,
}

/// A row's time as an MCAP timestamp: ns from the run's start (negative or not finite: 0).
fn nanoseconds(t: f64) -> u64 {
    if t.is_finite() && t > 0.0 {
        (t * 1e9).round() as u64
    } else {
        0
    }
}

/// The three channels of one run under `prefix`, one message each per row of `record`.
fn write_run(
    writer: &mut Writer<BufWriter<File>>,
    schemas: &Schemas,
    prefix: &str,
    record: &Record,
) -> mcap::McapResult<()> {
    let columns = record.columns();
    let none = BTreeMap::new();
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
    let joint_states = writer.add_channel(
        schemas.joint_states,
        &format!("{prefix}/joint_states"),
        "json",
        &none,
    )?;
    let commands = writer.add_channel(
        schemas.commands,
        &format!("{prefix}/commands"),
        "json",
        &none,
    )?;
    let barriers = writer.add_channel(
        schemas.barriers,
        &format!("{prefix}/barriers"),
        "json",
        &barrier_metadata,
    )?;
    let names = columns.coordinate_names();
    for index in 0..record.len() {
        let Some(row) = record.row(index) else {
            break;
        };
        let time = nanoseconds(row.t);
        let sequence = u32::try_from(index).unwrap_or(u32::MAX);
        let messages = [
            (
                joint_states,
                json!({"t": row.t, "name": names, "position": row.q, "velocity": row.qd}),
            ),
            (
                commands,
                json!({"t": row.t, "tau": row.tau, "tau_nom": row.tau_nom}),
            ),
            (barriers, json!({"t": row.t, "values": row.b})),
        ];
        for (channel_id, message) in messages {
            writer.write_to_known_channel(
                &MessageHeader {
                    channel_id,
                    sequence,
                    log_time: time,
                    publish_time: time,
                },
                message.to_string().as_bytes(),
            )?;
        }
    }
    Ok(())
}
