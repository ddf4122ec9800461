//! A robot file read as a whole: the description's tables and the `[hardware]` table, so
//! that whichever command reads a robot file takes it whole or refuses it; and the paper's
//! simulation robot, compiled in, for commands given no file.

use std::path::{Path, PathBuf};

use softcbf_description::robot::{Robot, RobotError};

/// Text of the default robot, compiled into the binary.
pub const PAPER_SIM_ROBOT: &str = include_str!("../../../robots/paper-sim.toml");

/// Loads `path`, or the embedded paper simulation robot when `None`. A `[hardware]` table
/// is checked too ([`crate::hardware_description::load`]), so that a robot file is either
/// valid as a whole or refused, whichever subcommand reads it.
pub fn load_robot(path: Option<&Path>) -> Result<Robot, RobotError> {
    let robot = match path {
        Some(path) => Robot::load(path)?,
        None => Robot::parse(
            PAPER_SIM_ROBOT,
            &PathBuf::from("<embedded robots/paper-sim.toml>"),
        )?,
    };
    crate::hardware_description::load(&robot)?;
    Ok(robot)
}
