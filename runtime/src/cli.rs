//! Command-line helpers shared by the subcommands: loading robots, reading vectors.
//! Every error names what the user typed and what was expected.

use std::path::{Path, PathBuf};

use softcbf_description::domain;
use softcbf_description::limits::Limit;
use softcbf_description::robot::{Robot, RobotError};

/// Text of the default robot, compiled into the binary.
pub const PAPER_SIM_ROBOT: &str = include_str!("../../robots/paper-sim.toml");

/// Loads `path`, or the embedded paper simulation robot when `None`. A `[hardware]` table
/// is checked too ([`crate::hardware::description::load`]), so that a robot file is either
/// valid as a whole or refused, whichever subcommand reads it.
pub fn load_robot(path: Option<&Path>) -> Result<Robot, RobotError> {
    let robot = match path {
        Some(path) => Robot::load(path)?,
        None => Robot::parse(
            PAPER_SIM_ROBOT,
            &PathBuf::from("<embedded robots/paper-sim.toml>"),
        )?,
    };
    crate::hardware::description::load(&robot)?;
    Ok(robot)
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

/// Checks a number given for option `name` against its [`Limit`] (the same rule as the
/// description files): `--rate: must be ≥ 1 and ≤ 10000 Hz, got -33`.
pub fn check_number(name: &str, value: f64, limit: &Limit) -> Result<f64, String> {
    limit
        .check(value)
        .map_err(|message| format!("{name}: {message}"))
}

/// Parses a number given for option `name` and checks it against `limit`.
pub fn parse_number(name: &str, text: &str, limit: &Limit) -> Result<f64, String> {
    let value: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("{name}: `{text}` is not a number"))?;
    check_number(name, value, limit)
}

/// Parses a whole number given for option `name` and checks it against `limit` (an
/// integer [`Limit`]): `--retries: must be an integer in 0..=1000, got 5000`.
pub fn parse_integer(name: &str, text: &str, limit: &Limit) -> Result<i64, String> {
    let value: i64 = text
        .trim()
        .parse()
        .map_err(|_| format!("{name}: `{text}` is not a whole number"))?;
    limit
        .check_integer(value)
        .map_err(|message| format!("{name}: {message}"))
}

/// Parses coordinates `q` of `robot` given for option `name`: `3·modules` finite values in
/// the model's domain (bend, elongation; [`softcbf_description::domain`]).
pub fn parse_coordinates(name: &str, text: &str, robot: &Robot) -> Result<Vec<f64>, String> {
    let values = parse_vector(name, text, 3 * robot.modules.len())?;
    match domain::coordinates_problem(robot, &values) {
        Some(problem) => Err(format!("{name}: {problem}")),
        None => Ok(values),
    }
}

/// Parses velocities `q̇` of `robot` given for option `name` (speeds within the domain).
pub fn parse_velocities(name: &str, text: &str, robot: &Robot) -> Result<Vec<f64>, String> {
    let values = parse_vector(name, text, 3 * robot.modules.len())?;
    match domain::velocities_problem(robot, &values) {
        Some(problem) => Err(format!("{name}: {problem}")),
        None => Ok(values),
    }
}
