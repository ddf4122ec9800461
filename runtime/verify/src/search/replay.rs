//! The scenario file of a case a search found: a whole `softcbf simulate` scenario — the
//! robot, the group's safety mode and control period, the run's duration and record
//! period, its set point and start, the plant's factors and the sensor noise — with the
//! original scenario's `[gains]` and `[integrator]` copied, so that
//! `softcbf simulate --scenario worst-….toml` runs the very run the search made, bit for
//! bit. Numbers are written in their shortest exact form.

use std::path::Path;

use toml_edit::{Array, ArrayOfTables, DocumentMut, Item, Table, Value};

use crate::draw::Draw;
use crate::scenario::ScenarioFile;
use crate::spec::VerifySpec;

/// `v` as a TOML float that reads back as `v` bit for bit.
fn float(v: f64) -> Value {
    let text = if v.is_finite() {
        format!("{v:?}")
    } else if v.is_nan() {
        "nan".into()
    } else if v > 0.0 {
        "inf".into()
    } else {
        "-inf".into()
    };
    text.parse().unwrap_or_else(|_| Value::from(v))
}

fn floats(values: &[f64]) -> Value {
    let mut array = Array::new();
    for &v in values {
        array.push(float(v));
    }
    Value::Array(array)
}

/// A path as an absolute TOML string, without `..` where the file exists (a path that is
/// not UTF-8 is written lossily).
fn path_value(path: &Path) -> Value {
    let absolute = std::fs::canonicalize(path)
        .or_else(|_| std::path::absolute(path))
        .unwrap_or_else(|_| path.to_path_buf());
    Value::from(absolute.to_string_lossy().into_owned())
}

/// The text of the scenario file that runs `draw` of `spec` (read from `file`), headed by
/// the comment lines `header`.
pub fn scenario_text(
    file: &ScenarioFile,
    spec: &VerifySpec,
    draw: &Draw,
    name: &str,
    header: &[String],
) -> Result<String, String> {
    let original: DocumentMut = file
        .text()
        .parse()
        .map_err(|e| format!("{}: {e}", file.path().display()))?;
    let group = spec
        .groups
        .get(draw.group)
        .ok_or_else(|| format!("no group {}", draw.group))?;
    let scenario = &group.scenario;
    let mut doc = DocumentMut::new();
    doc.insert("name", Item::Value(Value::from(name)));
    if let Some(robot) = file.robot_path() {
        doc.insert("robot", Item::Value(path_value(&robot)));
    }
    doc.insert("duration", Item::Value(float(scenario.duration)));
    doc.insert(
        "control_period",
        Item::Value(float(scenario.control_period)),
    );
    doc.insert("safety", Item::Value(Value::from(group.safety.name())));
    doc.insert("filter", Item::Value(Value::from(true)));
    doc.insert("compare", Item::Value(Value::from(false)));
    if let Some(period) = scenario.record_period {
        doc.insert("record_period", Item::Value(float(period)));
    }
    if spec.parameter_errors {
        let mut tables = ArrayOfTables::new();
        for f in &draw.factors {
            let mut t = Table::new();
            t.insert("stiffness", Item::Value(floats(&f.stiffness)));
            t.insert("damping", Item::Value(floats(&f.damping)));
            t.insert("mass", Item::Value(float(f.mass)));
            tables.push(t);
        }
        doc.insert("plant_factors", Item::ArrayOfTables(tables));
    } else if let Some(plant) = file.plant_path() {
        doc.insert("plant", Item::Value(path_value(&plant)));
    }
    let mut initial = Table::new();
    initial.insert("q", Item::Value(floats(&draw.initial_q)));
    initial.insert("qd", Item::Value(floats(&draw.initial_qd)));
    doc.insert("initial", Item::Table(initial));
    if spec.set_point.is_some() {
        let mut reference = Table::new();
        reference.insert("set_point", Item::Value(floats(&draw.set_point)));
        doc.insert("reference", Item::Table(reference));
    } else if let Some(reference) = original.get("reference") {
        doc.insert("reference", reference.clone());
    }
    for table in ["gains", "integrator"] {
        if let Some(item) = original.get(table) {
            let mut item = item.clone();
            if let Some(t) = item.as_table_mut() {
                t.set_position(None);
            }
            doc.insert(table, item);
        }
    }
    if spec.sensor_noise.iter().any(|&s| s > 0.0) {
        let mut noise = Table::new();
        noise.insert("q", Item::Value(float(spec.sensor_noise[0])));
        noise.insert("qd", Item::Value(float(spec.sensor_noise[1])));
        noise.insert(
            "seed",
            Item::Value(Value::from(i64::try_from(draw.noise_seed).map_err(
                |_| format!("noise seed {} does not fit a TOML integer", draw.noise_seed),
            )?)),
        );
        doc.insert("sensor_noise", Item::Table(noise));
    }
    let mut text = String::new();
    for line in header {
        text.push_str("# ");
        text.push_str(line);
        text.push('\n');
    }
    text.push_str(&doc.to_string());
    Ok(text)
}
