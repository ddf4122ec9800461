//! Command-line helpers shared by the subcommands: loading robots, reading vectors.
//! Every error names what the user typed and what was expected.

use std::path::{Path, PathBuf};

use softcbf_codegen::robot::{Robot, RobotError};

/// Text of the default robot, compiled into the binary.
pub const PAPER_SIM_ROBOT: &str = include_str!("../../robots/paper-sim.toml");

/// Loads `path`, or the embedded paper simulation robot when `None`.
pub fn load_robot(path: Option<&Path>) -> Result<Robot, RobotError> {
    match path {
        Some(path) => Robot::load(path),
        None => Robot::parse(
            PAPER_SIM_ROBOT,
            &PathBuf::from("<embedded robots/paper-sim.toml>"),
        ),
    }
}

/// Parses `v,v,…` given for option `name`; it must have `expected` finite numbers.
pub fn parse_vector(name: &str, text: &str, expected: usize) -> Result<Vec<f64>, String> {
    let mut values = Vec::new();
    for (k, item) in text.split(',').enumerate() {
        let item = item.trim();
        let value: f64 = item
            .parse()
            .map_err(|_| format!("{name}: entry {} `{item}` is not a number", k + 1))?;
        if !value.is_finite() {
            return Err(format!(
                "{name}: entry {} is {value}; values must be finite",
                k + 1
            ));
        }
        values.push(value);
    }
    if values.len() != expected {
        return Err(format!(
            "{name}: {} values given, the robot has {expected} coordinates (3 per module: Δx, Δy, δL)",
            values.len()
        ));
    }
    Ok(values)
}
