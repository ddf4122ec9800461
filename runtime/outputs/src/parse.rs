//! Numbers and coordinates read from what the user typed, checked against their ranges
//! and the model's domain; shared by the subcommands of every crate above (re-exported
//! under their old path, `softcbf::cli`). Every error names what the user typed and what
//! was expected.

use softcbf_core::settings::check_number;
use softcbf_description::domain;
use softcbf_description::limits::Limit;
use softcbf_description::robot::Robot;

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
