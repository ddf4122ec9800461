//! What `softcbf identify` writes and prints: the robot file with only the identified
//! numbers and the `[uncertainty]` table changed (a text-preserving edit with `toml_edit`, a
//! comment line on each; the table's bounds from [`super::bounds`]), checked by reading it
//! back before it replaces anything; and the report.

use std::path::{Path, PathBuf};

use softcbf_description::robot::Robot;
use softcbf_description::uncertainty::ModuleUncertainty;
use toml_edit::{Array, DocumentMut, InlineTable, Item, Table, Value};

use super::bounds::{Bounds, K_SIGMA, bounds};
use super::{Identification, IdentifyError, PER_MODULE, Parameter, Status, hardware_of};

/// Refuses an `--out` that is the robot file itself (the input would be lost).
pub fn check_out_path(robot: &Path, out: &Path) -> Result<(), IdentifyError> {
    let same = match (std::fs::canonicalize(robot), std::fs::canonicalize(out)) {
        (Ok(a), Ok(b)) => a == b,
        _ => robot == out,
    };
    if same {
        return Err(IdentifyError::Io {
            file: out.to_path_buf(),
            message: "--out is the robot file itself; write the identified robot to another \
                      file (and compare before replacing the original)"
                .into(),
        });
    }
    Ok(())
}

/// `x` with `digits` significant digits.
fn round_to(x: f64, digits: usize) -> f64 {
    format!("{:.*e}", digits.saturating_sub(1), x)
        .parse()
        .unwrap_or(x)
}

/// Significant digits that show an estimate of standard error `se`: two beyond the
/// error's first, at least 3 and at most 8.
fn digits_for(value: f64, se: f64) -> usize {
    if !(se.is_finite() && se > 0.0 && value != 0.0) {
        return 6;
    }
    let digits = (value.abs() / se).log10().ceil() + 2.0;
    digits.clamp(3.0, 8.0) as usize
}

/// `x` briefly: three significant digits, plain where that is short.
pub fn short(x: f64) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    let magnitude = x.abs();
    if x == 0.0 || (1e-3..1e5).contains(&magnitude) {
        let decimals = (2 - magnitude.log10().floor() as i32).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.2e}")
    }
}

/// The value written for parameter `j`.
fn written(id: &Identification, j: usize) -> f64 {
    round_to(id.fit.theta[j], digits_for(id.fit.theta[j], id.fit.se[j]))
}

/// The origin comment's opening: `identified by softcbf identify from 2 logs (12 rest
/// states, 5400 rows)`.
fn origin(id: &Identification) -> String {
    let logs = id.logs.len();
    format!(
        "identified by softcbf identify from {logs} log{} ({} rest states, {} rows)",
        if logs == 1 { "" } else { "s" },
        id.rest_states,
        id.rows[0] + id.rows[1]
    )
}

/// The `module i` table of the document, creating the `[[module]]` array of tables when
/// the file gives `modules = N` instead.
fn module_table(doc: &mut DocumentMut, i: usize, modules: usize) -> Option<&mut Table> {
    if doc.get("module").is_none()
        && let Some(count) = doc.remove("modules")
    {
        let _ = count;
        let mut array = toml_edit::ArrayOfTables::new();
        for k in 0..modules {
            let mut table = Table::new();
            table.decor_mut().set_prefix(format!(
                "\n# module {} (was `modules = {modules}`)\n",
                k + 1
            ));
            array.push(table);
        }
        doc.insert("module", Item::ArrayOfTables(array));
    }
    doc.get_mut("module")?.as_array_of_tables_mut()?.get_mut(i)
}

/// Sets `key` of `table` to `value`, keeping an existing value's trailing comment, and
/// puts `comment` on a line above it.
fn set(table: &mut Table, key: &str, value: Value, comment: &str) {
    let mut value = value;
    if let Some(old) = table.get(key).and_then(Item::as_value) {
        *value.decor_mut() = old.decor().clone();
    }
    table.insert(key, Item::Value(value));
    if let Some(mut k) = table.key_mut(key) {
        let before = k
            .leaf_decor()
            .prefix()
            .and_then(|p| p.as_str())
            .unwrap_or("")
            .to_string();
        let indent: String = before
            .rsplit('\n')
            .next()
            .unwrap_or("")
            .chars()
            .filter(|c| *c == ' ' || *c == '\t')
            .collect();
        let head = before.strip_suffix(indent.as_str()).unwrap_or(&before);
        k.leaf_decor_mut()
            .set_prefix(format!("{head}{indent}# {comment}\n{indent}"));
    }
}

/// The text of the identified robot file: `text` (the robot file, read as `robot`) with
/// each identified number replaced and commented.
pub fn render(text: &str, robot: &Robot, id: &Identification) -> Result<String, IdentifyError> {
    let invalid = |message: String| IdentifyError::RobotFile {
        file: robot.source.clone(),
        message,
    };
    let mut doc: DocumentMut = text
        .parse()
        .map_err(|e| invalid(format!("cannot be edited: {e}")))?;
    let modules = id.modules();
    let origin = origin(id);
    for i in 0..modules {
        for parameter in [
            Parameter::BendingStiffness,
            Parameter::AxialStiffness,
            Parameter::BendingDamping,
            Parameter::AxialDamping,
        ] {
            let j = parameter.index(i);
            if id.fit.status[j] != Status::Identified {
                continue;
            }
            let value = written(id, j);
            let comment = format!(
                "{origin}: {} ± {}, file had {}",
                value,
                short(id.fit.se[j]),
                id.file[j]
            );
            let table = module_table(&mut doc, i, modules)
                .ok_or_else(|| invalid(format!("has no [[module]] table {}", i + 1)))?;
            set(table, parameter.key(), Value::from(value), &comment);
        }
        let base = PER_MODULE * i + 4;
        let gains: Vec<usize> = (base..base + 3).collect();
        if gains
            .iter()
            .all(|&j| id.fit.status[j] != Status::Identified)
        {
            continue;
        }
        let table = doc
            .get_mut("hardware")
            .and_then(|h| h.get_mut("module"))
            .and_then(Item::as_array_of_tables_mut)
            .and_then(|a| a.get_mut(i))
            .ok_or_else(|| invalid(format!("has no [[hardware.module]] table {}", i + 1)))?;
        let file_text = if id.file[base] == id.file[base + 1] && id.file[base] == id.file[base + 2]
        {
            id.file[base].to_string()
        } else {
            format!("{:?}", &id.file[base..base + 3])
        };
        // One number when the three written gains are one (tied, or the file's
        // single number kept), else one per tendon.
        let values: Vec<f64> = gains
            .iter()
            .map(|&j| match id.fit.status[j] {
                Status::Identified => written(id, j),
                Status::Kept(_) => id.file[j],
            })
            .collect();
        let errors: Vec<String> = gains
            .iter()
            .map(|&j| match &id.fit.status[j] {
                Status::Identified => short(id.fit.se[j]),
                Status::Kept(_) => "kept".into(),
            })
            .collect();
        let (value, comment) = if values.iter().all(|&v| v == values[0]) {
            (
                Value::from(values[0]),
                format!(
                    "{origin}: {} ± {}, file had {file_text}",
                    values[0], errors[0]
                ),
            )
        } else {
            let mut array = Array::new();
            for v in &values {
                array.push(*v);
            }
            (
                Value::Array(array),
                format!(
                    "{origin}: {values:?} ± [{}], file had {file_text}",
                    errors.join(", ")
                ),
            )
        };
        set(table, "actuator_gain", value, &comment);
    }
    let bounds = identified_bounds(robot, id);
    write_uncertainty(&mut doc, &bounds, &origin).map_err(|message| invalid(message.into()))?;
    for (i, own) in bounds.modules.iter().enumerate() {
        let table = module_table(&mut doc, i, modules)
            .ok_or_else(|| invalid(format!("has no [[module]] table {}", i + 1)))?;
        write_module_uncertainty(table, own);
    }
    Ok(doc.to_string())
}

/// The `[uncertainty]` table written for `id` of `robot`.
pub fn identified_bounds(robot: &Robot, id: &Identification) -> Bounds {
    bounds(id, &|j| written(id, j), &robot.uncertainty)
}

/// Replaces the document's `[uncertainty]` table (or adds one) with `bounds`, each value
/// under a comment saying where it came from; the table's own comment says how it was made.
fn write_uncertainty(
    doc: &mut DocumentMut,
    bounds: &Bounds,
    origin: &str,
) -> Result<(), &'static str> {
    // An inline table (`uncertainty = { … }`) becomes a table of its own.
    if doc.get("uncertainty").is_some_and(|item| !item.is_table()) {
        doc.remove("uncertainty");
    }
    if doc.get("uncertainty").is_none() {
        doc.insert("uncertainty", Item::Table(Table::new()));
    }
    let table = doc
        .get_mut("uncertainty")
        .and_then(Item::as_table_mut)
        .ok_or("its [uncertainty] cannot be edited")?;
    table.decor_mut().set_prefix(format!(
        "\n# How far the numbers of this file may be off (docs/model.md §5), written by softcbf \
         identify: {origin}.\n# Stiffness and damping: {K_SIGMA} standard errors (each with its \
         timing, filter and noise parts, docs/model.md §10); what it did not measure is kept \
         from the input file, as each line says.\n# The {}.\n",
        bounds.gains
    ));
    let fields = [
        ("stiffness", &bounds.stiffness),
        ("damping", &bounds.damping),
        ("mass", &bounds.mass),
        ("force", &bounds.force),
    ];
    for (key, bound) in fields {
        set(table, key, Value::from(bound.value), &bound.source);
    }
    Ok(())
}

/// Writes a module's own bounds as its `uncertainty = { … }` (replacing one the input
/// had), or removes the key where it identified none (the table's bounds hold there).
fn write_module_uncertainty(table: &mut Table, own: &ModuleUncertainty) {
    let numbers = [
        ("bending_stiffness", own.bending_stiffness),
        ("axial_stiffness", own.axial_stiffness),
        ("bending_damping", own.bending_damping),
        ("axial_damping", own.axial_damping),
        ("mass", own.mass),
    ];
    let mut inline = InlineTable::new();
    for (key, value) in numbers {
        if let Some(value) = value {
            inline.insert(key, Value::from(value));
        }
    }
    if inline.is_empty() {
        table.remove("uncertainty");
        return;
    }
    set(
        table,
        "uncertainty",
        Value::InlineTable(inline),
        &format!(
            "this module's own bounds: {K_SIGMA} standard errors of its identified numbers, \
             rounded up ([uncertainty] holds for the rest)"
        ),
    );
}

/// Checks that `parsed` (the rendered file) is `robot` with exactly the numbers of `id` and
/// its `[uncertainty]` table.
fn check_rendered(parsed: &Robot, robot: &Robot, id: &Identification) -> Result<(), String> {
    let uncertainty = identified_bounds(robot, id).uncertainty();
    if parsed.uncertainty != uncertainty {
        return Err(format!(
            "its [uncertainty] reads back as {:?}, not {uncertainty:?}",
            parsed.uncertainty
        ));
    }
    let bounds = identified_bounds(robot, id);
    for (i, own) in bounds.modules.iter().enumerate() {
        let expected = own.over(&uncertainty);
        if parsed.module_box(i) != expected {
            return Err(format!(
                "module {}'s uncertainty reads back as {:?}, not {expected:?}",
                i + 1,
                parsed.module_box(i)
            ));
        }
    }
    let mut restored = parsed.clone();
    restored.uncertainty = robot.uncertainty;
    for (module, original) in restored.modules.iter_mut().zip(&robot.modules) {
        module.uncertainty = original.uncertainty;
    }
    for (i, module) in restored.modules.iter_mut().enumerate() {
        let fields = [
            (Parameter::BendingStiffness, &mut module.bending_stiffness),
            (Parameter::AxialStiffness, &mut module.axial_stiffness),
            (Parameter::BendingDamping, &mut module.bending_damping),
            (Parameter::AxialDamping, &mut module.axial_damping),
        ];
        for (parameter, field) in fields {
            let j = parameter.index(i);
            let expected = match id.fit.status[j] {
                Status::Identified => written(id, j),
                Status::Kept(_) => id.file[j],
            };
            if *field != expected {
                return Err(format!(
                    "{} of module {} reads back as {}, not {expected}",
                    parameter.key(),
                    i + 1,
                    field
                ));
            }
            *field = id.file[j];
        }
    }
    restored.source = robot.source.clone();
    restored.hardware = robot.hardware.clone();
    if restored != *robot {
        return Err("it differs from the input in more than the identified numbers".into());
    }
    let hardware = hardware_of(parsed).map_err(|e| e.to_string())?;
    let mut original = hardware_of(robot).map_err(|e| e.to_string())?;
    for (i, module) in original.modules.iter_mut().enumerate() {
        for k in 0..3 {
            let j = Parameter::ActuatorGain(k).index(i);
            if id.fit.status[j] == Status::Identified {
                module.actuator_gain[k] = written(id, j);
            }
        }
    }
    if hardware != original {
        return Err(
            "its [hardware] table differs from the input in more than the actuator gains".into(),
        );
    }
    Ok(())
}

/// Writes the identified robot file to `out`: rendered from `text` (the robot file, read
/// as `robot`), checked in memory, written beside `out` and read back with
/// [`Robot::load`], then moved into place. Nothing is left at `out` on an error.
pub fn write_robot(
    text: &str,
    robot: &Robot,
    id: &Identification,
    out: &Path,
) -> Result<PathBuf, IdentifyError> {
    let rendered = render(text, robot, id)?;
    let failed = |message: String| IdentifyError::Io {
        file: out.to_path_buf(),
        message: format!("the identified robot file is not right, nothing written: {message}"),
    };
    let parsed = Robot::parse(&rendered, out).map_err(|e| failed(e.to_string()))?;
    check_rendered(&parsed, robot, id).map_err(failed)?;
    let name = out.file_name().map_or_else(
        || "identified.toml".into(),
        |n| n.to_string_lossy().into_owned(),
    );
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| IdentifyError::Io {
            file: parent.to_path_buf(),
            message: format!("cannot create the directory of --out: {e}"),
        })?;
    }
    let temporary = out.with_file_name(format!(".{name}.partial"));
    let io = |e: std::io::Error| IdentifyError::Io {
        file: temporary.clone(),
        message: e.to_string(),
    };
    std::fs::write(&temporary, &rendered).map_err(io)?;
    let reread = Robot::load(&temporary)
        .map_err(|e| e.to_string())
        .and_then(|mut back| {
            back.source = parsed.source.clone();
            if back == parsed {
                Ok(())
            } else {
                Err("it reads back differently".to_string())
            }
        });
    if let Err(message) = reread {
        let _ = std::fs::remove_file(&temporary);
        return Err(failed(message));
    }
    std::fs::rename(&temporary, out).map_err(|e| {
        let _ = std::fs::remove_file(&temporary);
        IdentifyError::Io {
            file: out.to_path_buf(),
            message: e.to_string(),
        }
    })?;
    Ok(out.to_path_buf())
}

/// The report, one line each: the data, a table of the estimates, what was kept and why,
/// the residuals and conditioning, the held-out predictions.
pub fn report(id: &Identification) -> Vec<String> {
    let fit = &id.fit;
    let mut lines = vec![format!(
        "identify: {} logs ({}), {} rest states and {} filtered instants ({} static + {} \
         dynamic rows); filter half-width {:.3} s; {}",
        id.logs.len(),
        id.logs
            .iter()
            .map(|l| format!(
                "{}: {} readings{}",
                l.name,
                l.readings,
                if l.dynamic {
                    ", last 20 % held out"
                } else {
                    ""
                }
            ))
            .collect::<Vec<_>>()
            .join("; "),
        id.rest_states,
        id.instants,
        id.rows[0],
        id.rows[1],
        id.half_width,
        match id.timing_uncertainty {
            Some(sigma) => format!(
                "each standard error combines a delete-one-block jackknife over {} blocks with \
                 the change {}under a filter {}× wider and with the readings' noise doubled in \
                 variance (each part in % of the estimate, on the right)",
                fit.blocks,
                if sigma > 0.0 {
                    format!("under landing times moved by ±{:.2} ms and ", 1e3 * sigma)
                } else {
                    String::new()
                },
                super::FILTER_CHECK
            ),
            None => format!(
                "standard errors by delete-one-block jackknife over {} blocks",
                fit.blocks
            ),
        }
    )];
    lines.push(format!(
        "{:<24} {:>26} {:>12} {:>9}   {:>6} {:>6} {:>6} {:>6}",
        "parameter",
        "estimate ± std. error",
        "file",
        "change",
        "jack.",
        "timing",
        "filter",
        "noise"
    ));
    for j in 0..id.file.len() {
        let (module, parameter) = Parameter::of_index(j);
        let name = format!(
            "module {} {} [{}]",
            module + 1,
            parameter.symbol(),
            parameter.unit()
        );
        let share = |part: f64| {
            if part.is_nan() || fit.status[j] != Status::Identified {
                String::new()
            } else {
                format!("{:.2}", 100.0 * part / fit.theta[j].abs())
            }
        };
        let parts = format!(
            "{:>6} {:>6} {:>6} {:>6}",
            share(fit.jackknife_se[j]),
            share(fit.timing_error[j]),
            share(fit.filter_error[j]),
            share(fit.noise_error[j])
        );
        let (estimate, change) = match &fit.status[j] {
            Status::Identified => {
                let tie = matches!(parameter, Parameter::ActuatorGain(_)) && fit.tied[module];
                (
                    format!(
                        "{} ± {}{}",
                        written(id, j),
                        short(fit.se[j]),
                        if tie { " (tied)" } else { "" }
                    ),
                    format!("{:+.1} %", 100.0 * (fit.theta[j] / id.file[j] - 1.0)),
                )
            }
            Status::Kept(_) => ("kept".into(), String::new()),
        };
        lines.push(format!(
            "{name:<24} {estimate:>26} {:>12} {change:>9}   {parts}",
            short(id.file[j])
        ));
    }
    for j in 0..id.file.len() {
        if let Status::Kept(reason) = &fit.status[j] {
            lines.push(format!(
                "{}: {reason}; kept the file's {}",
                Parameter::describe(j),
                id.file[j]
            ));
        }
    }
    lines.extend(fit.notes.iter().cloned());
    let kind = |k: usize| {
        let s = &fit.stats[k];
        if s.rows == 0 {
            "none".to_string()
        } else {
            format!(
                "RMS {} N, R² {:.5} ({} rows)",
                short(s.rms),
                s.r_squared,
                s.rows
            )
        }
    };
    lines.push(format!(
        "residual: static {}; dynamic {}; condition number {} (column-scaled, weighted)",
        kind(0),
        kind(1),
        short(fit.condition)
    ));
    for p in &id.predictions {
        lines.push(format!(
            "held out {} ({:.1} s simulated from its measured start): RMS error of q {} mm \
             with the identified numbers, {} mm with the file's",
            p.log,
            p.t.last().unwrap_or(&0.0) - p.t.first().unwrap_or(&0.0),
            short(1e3 * p.rms[0]),
            short(1e3 * p.rms[1])
        ));
    }
    if !id.logs.iter().any(|log| log.dynamic) {
        lines.push("no dynamic log: no held-out part was predicted (no figure)".into());
    }
    lines.extend(id.notes.iter().cloned());
    lines
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::regression::Config;
    use crate::{Fit, KindStats, LogFacts, file_values};

    /// An identification of `robot` that scales every number by 1.2, but keeps module 2's
    /// bending damping, with gains tied.
    fn scaled(robot: &Robot) -> Identification {
        let hardware = hardware_of(robot).unwrap();
        let file = file_values(robot, &hardware);
        let kept = Parameter::BendingDamping.index(1);
        let status: Vec<Status> = (0..file.len())
            .map(|j| {
                if j == kept {
                    Status::Kept("not excited".into())
                } else {
                    Status::Identified
                }
            })
            .collect();
        let theta = file
            .iter()
            .enumerate()
            .map(|(j, v)| if j == kept { *v } else { 1.2 * v })
            .collect();
        let stats = KindStats {
            rows: 0,
            rms: f64::NAN,
            r_squared: f64::NAN,
        };
        Identification {
            fit: Fit {
                theta,
                se: vec![1e-5; file.len()],
                jackknife_se: vec![1e-5; file.len()],
                timing_error: vec![f64::NAN; file.len()],
                filter_error: vec![f64::NAN; file.len()],
                noise_error: vec![f64::NAN; file.len()],
                config: Config {
                    unknowns: Vec::new(),
                    held: Vec::new(),
                },
                weights: Vec::new(),
                textbook_se: vec![1e-5; file.len()],
                status,
                tied: vec![true; 2],
                notes: Vec::new(),
                stats: [stats; 2],
                condition: 1.0,
                blocks: 20,
            },
            file,
            logs: vec![LogFacts {
                name: "run".into(),
                readings: 100,
                dynamic: true,
            }],
            instants: 10,
            rest_states: 2,
            rows: [12, 60],
            half_width: 0.08,
            period: 0.01,
            timing_uncertainty: None,
            holdout: 0.2,
            predictions: Vec::new(),
            notes: Vec::new(),
        }
    }

    #[test]
    fn a_file_with_modules_n_gets_module_tables_and_reads_back() {
        let path = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../robots/hardware-example.toml"
        ));
        let text = std::fs::read_to_string(path).unwrap();
        // The two [[module]] tables (masses only) replaced by `modules = 2`, a top-level
        // key (before the first table).
        let start = text.find("[[module]]").unwrap();
        let end = text.find("[hardware]").unwrap();
        let text = format!("{}{}", &text[..start], &text[end..]).replacen(
            "name = \"hardware-example\"\n",
            "name = \"hardware-example\"\nmodules = 2\n",
            1,
        );
        let robot = Robot::parse(&text, path).unwrap();
        let id = scaled(&robot);
        let dir =
            std::env::temp_dir().join(format!("softcbf-identify-output-{}", std::process::id()));
        let out = dir.join("identified.toml");
        write_robot(&text, &robot, &id, &out).unwrap();
        let back = Robot::load(&out).unwrap();
        let hardware = hardware_of(&back).unwrap();
        for (i, module) in back.modules.iter().enumerate() {
            let original = &robot.modules[i];
            assert_eq!(module.bending_stiffness, 1.2 * original.bending_stiffness);
            assert_eq!(module.axial_damping, 1.2 * original.axial_damping);
            let damping = if i == 1 { 1.0 } else { 1.2 };
            assert_eq!(module.bending_damping, damping * original.bending_damping);
            assert_eq!(module.mass, original.mass);
            assert_eq!(hardware.modules[i].actuator_gain, [1.2 * 0.04; 3]);
        }
        let written = std::fs::read_to_string(&out).unwrap();
        assert!(
            !written.lines().any(|l| l.starts_with("modules")),
            "{written}"
        );
        assert_eq!(written.matches("[[module]]").count(), 2, "{written}");
        assert!(!dir.join(".identified.toml.partial").exists());
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A file without `[uncertainty]` gets one, after its last table; a kind with a number
    /// not identified keeps the input's bound for it (none here) and says so.
    #[test]
    fn a_file_without_uncertainty_gets_the_identified_table() {
        let path = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../robots/hardware-example.toml"
        ));
        let text = std::fs::read_to_string(path).unwrap();
        let start = text.find("# How far these unmeasured").unwrap();
        let end = text.find("[defaults]").unwrap();
        let text = format!("{}{}", &text[..start], &text[end..]);
        let robot = Robot::parse(&text, path).unwrap();
        assert!(!robot.uncertainty.is_declared());
        let id = scaled(&robot);
        let rendered = render(&text, &robot, &id).unwrap();
        let back = Robot::parse(&rendered, path).unwrap();
        // 3 standard errors of 1e-5 over the least of the numbers (module 2's κθ, 0.6).
        let stiffness = 3e-5 / 0.6;
        assert!(
            back.uncertainty.stiffness >= (1.0 - 1e-9) * stiffness
                && back.uncertainty.stiffness < 1.1 * stiffness,
            "{:?}",
            back.uncertainty
        );
        assert_eq!((back.uncertainty.mass, back.uncertainty.force), (0.0, 0.0));
        let table = &rendered[rendered.find("[uncertainty]").unwrap()..];
        assert!(
            table.contains(
                "module 2 βθ not identified (the logs do not excite it): the input \
                 file's 0.00 % kept"
            ),
            "{table}"
        );
        assert!(
            table.contains("none declared, as in the input file"),
            "{table}"
        );
        // Each module's own box: 3 standard errors over its own identified number (1.2
        // times the file's), rounded up; where a number was not identified (module 2's βθ),
        // the table's bound.
        for (i, module) in robot.modules.iter().enumerate() {
            let own = back.module_box(i);
            let numbers = [
                (own.stiffness[0], module.bending_stiffness),
                (own.stiffness[1], module.axial_stiffness),
                (own.damping[0], module.bending_damping),
                (own.damping[1], module.axial_damping),
            ];
            for (k, (bound, file)) in numbers.into_iter().enumerate() {
                if (i, k) == (1, 2) {
                    assert_eq!(bound, back.uncertainty.damping);
                    continue;
                }
                let expected = 3e-5 / (1.2 * file);
                assert!(
                    bound >= (1.0 - 1e-9) * expected && bound < 1.1 * expected,
                    "module {} number {k}: {bound} against {expected}",
                    i + 1
                );
            }
            assert_eq!(own.mass, 0.0);
        }
        // The least certain module's bound is the table's.
        let widest = (0..robot.modules.len())
            .flat_map(|i| back.module_box(i).stiffness)
            .fold(0.0, f64::max);
        assert_eq!(widest, back.uncertainty.stiffness);
        assert!(
            rendered.contains("# this module's own bounds: 3 standard errors"),
            "{rendered}"
        );
    }
}
