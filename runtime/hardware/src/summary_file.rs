//! `summary.json` of a hardware run (`softcbf run --out DIR`, and the synthetic logs of
//! identification's tests and benchmark): one typed struct, [`HardwareSummary`], written
//! with [`HardwareSummary::write`] and read back with [`HardwareSummary::read`] by
//! `softcbf identify`, the line that names the next experiment and the tests. A field
//! missing from a file (one written by an older softcbf, or a synthetic log's, which has
//! no bus) reads as its default; a field of the wrong type is an error naming the file,
//! line and field.
//!
//! Times are in seconds, rates in Hz, barriers in the unit beside them (`m`, or `rad` for
//! a bend limit); a number that is not finite is written `null` and read back as NaN.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Deserializer, Serialize};

use crate::experiment::ExperimentKind;

/// The file's name in a run's directory.
pub const FILE_NAME: &str = "summary.json";

/// What a hardware run's `summary.json` holds.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct HardwareSummary {
    /// `filter`, or `pd` for a run with `--no-filter`, as `softcbf simulate` writes it.
    pub controller: String,
    /// The robot's name (its file's `name`).
    pub robot: String,
    /// Always `true`: tells a hardware run's summary from a simulation's.
    pub hardware: bool,
    /// The set point \[m\] of a run toward one; `None` in an experiment.
    pub set_point: Option<Vec<f64>>,
    /// `safe`, `unsafe: why`, `not run: why` or `fault: why`.
    pub verdict: String,
    /// Why the run ended.
    pub stopped: String,
    /// Ticks run.
    pub ticks: u64,
    /// Ticks that sent a command computed from a fresh reading.
    pub commands: u64,
    /// Ticks without a fresh reading.
    pub held: u64,
    /// Ticks whose command was the safe fallback (zero).
    pub fallbacks: u64,
    /// Of those, ticks with an invalid state.
    pub invalid_state: u64,
    /// Ticks whose barrier rows were relaxed.
    pub relaxed: u64,
    /// Ticks not proven over their hold.
    pub uncertified: u64,
    /// Those ticks per reason.
    pub uncertified_reasons: crate::control::UncertifiedCounts,
    /// Ticks computed without the filter (`--no-filter`).
    pub unfiltered: u64,
    /// Ticks whose command the filter changed.
    pub interventions: u64,
    /// Ticks that ended more than a period after they were due.
    pub deadline_overruns: u64,
    /// Commands in force longer than the hold they were computed for.
    pub hold_overruns: u64,
    /// Longest period between two ticks \[s\].
    #[serde(deserialize_with = "number_or_null")]
    pub longest_period: f64,
    /// Longest time a command was in force beyond its hold \[s\].
    #[serde(deserialize_with = "number_or_null")]
    pub longest_hold_excess: f64,
    /// Time from the first tick to the stop \[s\].
    #[serde(deserialize_with = "number_or_null")]
    pub elapsed: f64,
    /// Ticks per second reached \[Hz\].
    #[serde(deserialize_with = "number_or_null")]
    pub rate: f64,
    /// The loop rate run at \[Hz\] (`None`: not decided).
    pub loop_rate: Option<f64>,
    /// Whether `--rate auto` chose the rate from the bus.
    pub rate_from_bus: bool,
    /// The round trip measured at the start (`None`: the run stopped before).
    pub bus_check: Option<BusCheck>,
    /// The USB adapter's latency timer \[ms\] (`None`: unknown or no adapter).
    pub latency_timer_ms: Option<u32>,
    /// The lowest barrier at a reading.
    pub min_barrier: Lowest,
    /// The same per kind group (keyed as `KindGroup::key` names them).
    pub lowest_by_kind: BTreeMap<String, Lowest>,
    /// Tensions held at their limits, summed over ticks.
    pub clamps: Clamps,
    /// Bus event counts.
    pub bus: Bus,
    /// Per servo (bus order): whether its torque-off was confirmed at the stop.
    pub torque_off: Vec<TorqueOff>,
    /// The identification experiment (`None`: a run toward a set point).
    pub experiment: Option<ExperimentSummary>,
    /// The settings and where each came from, as `softcbf simulate` writes them.
    pub settings: serde_json::Value,
}

/// A lowest barrier: `value` (`None` when no reading was made), its `label`, when (`t`,
/// s) and its `unit`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Lowest {
    pub value: Option<f64>,
    pub label: String,
    #[serde(deserialize_with = "number_or_null")]
    pub t: f64,
    pub unit: String,
}

/// The bus check at the start: cycles timed and retried, their median, 90 % and longest
/// times and a command's computation \[s\], and the rate they allow \[Hz\].
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BusCheck {
    pub cycles: usize,
    pub retried: usize,
    #[serde(deserialize_with = "number_or_null")]
    pub median: f64,
    #[serde(deserialize_with = "number_or_null")]
    pub p90: f64,
    #[serde(deserialize_with = "number_or_null")]
    pub max: f64,
    #[serde(deserialize_with = "number_or_null")]
    pub compute: f64,
    #[serde(deserialize_with = "number_or_null")]
    pub rate_limit: f64,
}

/// Tensions held at their lower and upper limits, summed over ticks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct Clamps {
    pub low: u64,
    pub high: u64,
}

/// Bus event counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct Bus {
    pub transactions: u64,
    pub replies: u64,
    pub timeouts: u64,
    pub crc_errors: u64,
    pub decode_errors: u64,
    pub wrong_id: u64,
    pub retries: u64,
}

/// One servo's torque-off at the stop.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct TorqueOff {
    pub id: u8,
    pub confirmed: bool,
}

/// An identification experiment: its settings (`duration`, `None` for none, s), the
/// tensions per module (`base_tension`, `amplitude`, N), the counts, the level guard's
/// settings and levels, and what only one kind has ([`ExperimentDesign`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ExperimentSummary {
    pub duration: Option<f64>,
    pub base_tension: Vec<f64>,
    pub amplitude: Vec<f64>,
    pub steps: usize,
    pub steps_run: usize,
    pub steps_at_rest: usize,
    pub steps_without_rest: usize,
    pub rest_rows: u64,
    pub complete: bool,
    #[serde(deserialize_with = "number_or_null")]
    pub uncertainty: f64,
    #[serde(deserialize_with = "number_or_null")]
    pub stop_distance: f64,
    #[serde(deserialize_with = "number_or_null")]
    pub growth_distance: f64,
    #[serde(deserialize_with = "number_or_null")]
    pub growth: f64,
    #[serde(deserialize_with = "number_or_null")]
    pub start_scale: f64,
    pub levels: Vec<LevelSummary>,
    pub stopped_by_guard: bool,
    /// Whether the log was made by identification's synthetic runs, not by a robot.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub synthetic: bool,
    /// The kind (`kind`: `static` or `dynamic`) and its own settings.
    #[serde(flatten)]
    pub design: ExperimentDesign,
}

/// What only one kind of experiment has, tagged by `kind`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum ExperimentDesign {
    /// Tension sets held to rest: `step_time`, `settle_time`, `ramp`, `quiet_window`,
    /// `rest_window` (s), `rest_threshold` (m); `None` where a synthetic log has none.
    Static {
        step_time: Option<f64>,
        settle_time: Option<f64>,
        ramp: Option<f64>,
        quiet_window: Option<f64>,
        rest_window: Option<f64>,
        rest_threshold: Option<f64>,
    },
    /// Multisines: `fade` (s), `band` and `resolution` (Hz), `lines_per_servo`,
    /// `operating_points` per module (N).
    Dynamic {
        fade: Option<f64>,
        band: Option<[f64; 2]>,
        resolution: Option<f64>,
        lines_per_servo: Option<Vec<usize>>,
        operating_points: Option<Vec<Vec<f64>>>,
    },
}

impl Default for ExperimentDesign {
    fn default() -> ExperimentDesign {
        ExperimentDesign::unknown(ExperimentKind::Static)
    }
}

impl ExperimentDesign {
    /// A design of `kind` whose settings are unknown (a synthetic log's): every field
    /// `None`, as a file without them reads back.
    pub fn unknown(kind: ExperimentKind) -> ExperimentDesign {
        match kind {
            ExperimentKind::Static => ExperimentDesign::Static {
                step_time: None,
                settle_time: None,
                ramp: None,
                quiet_window: None,
                rest_window: None,
                rest_threshold: None,
            },
            ExperimentKind::Dynamic => ExperimentDesign::Dynamic {
                fade: None,
                band: None,
                resolution: None,
                lines_per_servo: None,
                operating_points: None,
            },
        }
    }

    /// `static` or `dynamic`, as the file names the kind.
    pub fn kind(&self) -> &'static str {
        match self {
            ExperimentDesign::Static { .. } => "static",
            ExperimentDesign::Dynamic { .. } => "dynamic",
        }
    }
}

/// One level of the experiment's guard: its `scale`, the `lowest` barrier at it (`None`
/// before a reading), the `next` scale and the `predicted` lowest there.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LevelSummary {
    #[serde(deserialize_with = "number_or_null")]
    pub scale: f64,
    pub lowest: Option<f64>,
    #[serde(deserialize_with = "number_or_null")]
    pub next: f64,
    pub predicted: Option<f64>,
}

/// Why a `summary.json` could not be read.
#[derive(Debug, thiserror::Error)]
pub enum SummaryError {
    /// The file is there and could not be read.
    #[error("{}: {message}", file.display())]
    Io { file: PathBuf, message: String },
    /// Not JSON, or a field of the wrong type.
    #[error("{}: line {line}: {message}", file.display())]
    Format {
        file: PathBuf,
        line: usize,
        message: String,
    },
}

impl HardwareSummary {
    /// Writes `dir/summary.json` (pretty-printed, a newline at the end); returns its path.
    pub fn write(&self, dir: &Path) -> Result<PathBuf, String> {
        let path = dir.join(FILE_NAME);
        let text = serde_json::to_string_pretty(self).map_err(|e| e.to_string())? + "\n";
        std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(path)
    }

    /// Reads `dir/summary.json`; `Ok(None)` when there is none (a run killed before it
    /// was written).
    pub fn read(dir: &Path) -> Result<Option<HardwareSummary>, SummaryError> {
        let file = dir.join(FILE_NAME);
        let text = match std::fs::read_to_string(&file) {
            Ok(text) => text,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => {
                return Err(SummaryError::Io {
                    file,
                    message: e.to_string(),
                });
            }
        };
        let mut json = serde_json::Deserializer::from_str(&text);
        serde_path_to_error::deserialize(&mut json)
            .map(Some)
            .map_err(|e| SummaryError::Format {
                file,
                line: e.inner().line(),
                message: format!("field `{}`: {}", e.path(), e.inner()),
            })
    }

    /// The experiment's kind, `static` or `dynamic` (`None` for a run toward a set point).
    pub fn experiment_kind(&self) -> Option<&'static str> {
        self.experiment.as_ref().map(|e| e.design.kind())
    }
}

/// A number, or `null` (how serde_json writes a number that is not finite) as NaN.
fn number_or_null<'de, D: Deserializer<'de>>(deserializer: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(deserializer)?.unwrap_or(f64::NAN))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("softcbf-summary-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// A summary written and read back is the same, a non-finite number coming back as
    /// NaN; each kind of experiment keeps its own settings under its `kind`.
    #[test]
    fn a_summary_reads_back_as_written() {
        let dir = temp_dir("round-trip");
        for design in [
            ExperimentDesign::Static {
                step_time: Some(2.0),
                settle_time: Some(6.0),
                ramp: Some(0.2),
                quiet_window: Some(0.5),
                rest_window: Some(1.0),
                rest_threshold: Some(3e-4),
            },
            ExperimentDesign::Dynamic {
                fade: Some(0.5),
                band: Some([0.2, 8.0]),
                resolution: Some(0.1),
                lines_per_servo: Some(vec![3, 3]),
                operating_points: Some(vec![vec![0.2, 0.5], vec![0.3, 0.6]]),
            },
        ] {
            let summary = HardwareSummary {
                controller: "filter".into(),
                robot: "hardware-example".into(),
                hardware: true,
                verdict: "safe".into(),
                ticks: 330,
                relaxed: 1,
                uncertified_reasons: crate::control::UncertifiedCounts {
                    tube: 3,
                    ..Default::default()
                },
                longest_period: 0.0437,
                // Not finite: written `null`, read back as NaN.
                longest_hold_excess: f64::INFINITY,
                min_barrier: Lowest {
                    value: Some(7.5e-3),
                    label: "module 1 elongation min".into(),
                    t: 0.487,
                    unit: "m".into(),
                },
                torque_off: vec![TorqueOff {
                    id: 1,
                    confirmed: true,
                }],
                experiment: Some(ExperimentSummary {
                    steps: 25,
                    levels: vec![LevelSummary {
                        scale: 0.125,
                        lowest: None,
                        next: 0.25,
                        predicted: Some(4e-3),
                    }],
                    design,
                    ..ExperimentSummary::default()
                }),
                settings: serde_json::json!({"robot": {"name": "hardware-example"}}),
                ..HardwareSummary::default()
            };
            summary.write(&dir).unwrap();
            let mut read = HardwareSummary::read(&dir).unwrap().unwrap();
            let text = std::fs::read_to_string(dir.join(FILE_NAME)).unwrap();
            assert!(text.contains("\"longest_hold_excess\": null"), "{text}");
            assert!(read.longest_hold_excess.is_nan(), "{text}");
            read.longest_hold_excess = summary.longest_hold_excess;
            assert_eq!(read, summary, "{text}");
            let kind = summary.experiment_kind().unwrap();
            assert!(text.contains(&format!("\"kind\": \"{kind}\"")), "{text}");
        }
    }

    /// A file with only some fields (an older softcbf's, a synthetic log's) reads with
    /// defaults for the rest; a field of the wrong type names the file, line and field; no file
    /// is `None`.
    #[test]
    fn partial_wrong_and_missing_files() {
        let dir = temp_dir("partial");
        std::fs::write(
            dir.join(FILE_NAME),
            "{\"robot\": \"r\", \"experiment\": {\"kind\": \"dynamic\"}}\n",
        )
        .unwrap();
        let read = HardwareSummary::read(&dir).unwrap().unwrap();
        assert_eq!(read.robot, "r");
        assert_eq!(read.experiment_kind(), Some("dynamic"));
        std::fs::write(dir.join(FILE_NAME), "{\n\"ticks\": \"many\"\n}\n").unwrap();
        let error = HardwareSummary::read(&dir).unwrap_err().to_string();
        assert!(
            error.contains("summary.json: line 2: field `ticks`: invalid type"),
            "{error}"
        );
        std::fs::remove_file(dir.join(FILE_NAME)).unwrap();
        assert!(HardwareSummary::read(&dir).unwrap().is_none());
    }
}
