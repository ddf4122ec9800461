//! `hardware.json` beside a run's `trajectory.csv`: the robot structure and hardware
//! description the log was taken with — what turned servo angles into the logged `q` and
//! what a logged goal current means as a tension (modules, tendon angles and rest lengths,
//! servo IDs, directions, pulley radii, zero angles and lengths, register units, the baud
//! rate). `softcbf run` (and the synthetic logs of identification) write it through
//! [`LogDescription::write`] when the log is opened, before its first row, so a run
//! killed mid-way still has it; `softcbf identify` reads it through
//! [`LogDescription::read`] and refuses a log whose description differs from the robot
//! file it is given ([`LogDescription::first_difference`]).
//!
//! Numbers that identification estimates (stiffness, damping, actuator gains) and the
//! settings a run may change (rates, timeouts, gains, tension limits) are not part of it:
//! logs taken with the file before identification stay valid against the identified one.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use softcbf_description::robot::Robot;

use crate::hardware_description::Hardware;

/// The file's name in a run directory ([`softcbf_outputs::output::HARDWARE_DESCRIPTION_FILE`]:
/// the MCAP log reads it too, below this crate).
pub const FILE_NAME: &str = softcbf_outputs::output::HARDWARE_DESCRIPTION_FILE;

/// The version of the format this code writes and reads.
pub const FORMAT: u32 = 1;

/// Relative difference below which two numbers of a description are the same (the file
/// stores degrees where the model keeps radians: a round trip is not bit-exact).
const SAME: f64 = 1e-9;

/// One module's part of a [`LogDescription`], in the robot file's units.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModuleDescription {
    /// `tendon_angles_deg`: where each tendon passes the plate \[deg\].
    pub tendon_angles_deg: [f64; 3],
    /// `rest_length`: `L0` \[m\].
    pub rest_length_m: f64,
    /// `servo_ids` of the tendons.
    pub servo_ids: [u8; 3],
    /// `direction`: `+1` when a positive rotation winds the tendon, `−1` otherwise.
    pub direction: [i8; 3],
    /// `pulley_radius`: `ρ` \[m\].
    pub pulley_radius_m: f64,
    /// `zero_angle_deg`: servo angles at the calibration pose \[deg\].
    pub zero_angle_deg: [f64; 3],
    /// `zero_length`: tendon lengths at the calibration pose \[m\].
    pub zero_length_m: [f64; 3],
}

/// What a log was taken with (see the module's docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LogDescription {
    /// [`FORMAT`].
    pub format: u32,
    /// The robot's name.
    pub robot: String,
    /// The robot file the run read (for messages).
    pub robot_file: String,
    /// The serial baud rate of the run [bit/s] (it may differ from the file's: `--baud`);
    /// identification times a command's bytes on the wire with it.
    pub baud: u32,
    /// `current_unit_ma`: the goal-current register's unit \[mA\].
    pub current_unit_ma: f64,
    /// `position_unit_deg`: the position register's unit \[deg\].
    pub position_unit_deg: f64,
    /// `velocity_unit_rpm`: the velocity register's unit [rev/min].
    pub velocity_unit_rpm: f64,
    /// One per module, base first.
    pub modules: Vec<ModuleDescription>,
}

/// A field where a log's description and a robot's differ.
#[derive(Clone, Debug, PartialEq)]
pub struct Difference {
    /// The field, as the robot file names it (`hardware.module[1].direction[3]`).
    pub field: String,
    /// The log's value.
    pub log: String,
    /// The robot's value.
    pub robot: String,
}

/// Why a description could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum DescriptionError {
    /// The run directory has no description (a log written before they existed).
    #[error(
        "{}: not found: this log does not say which hardware description (servo IDs, \
         directions, pulley radii, zero angles, tendon angles) it was taken with, so it cannot \
         be checked against the robot file (logs written before softcbf recorded it lack it); \
         record the experiment again",
        file.display()
    )]
    Missing {
        /// The file looked for.
        file: PathBuf,
    },
    /// It could not be read, parsed or written.
    #[error("{}: {message}", file.display())]
    Io {
        /// The file.
        file: PathBuf,
        /// What went wrong.
        message: String,
    },
}

impl LogDescription {
    /// The description of `robot` driven through `hardware` (its `[hardware]` table with a
    /// run's overrides).
    pub fn of(robot: &Robot, hardware: &Hardware) -> LogDescription {
        let modules = robot
            .modules
            .iter()
            .zip(&hardware.modules)
            .map(|(module, hw)| {
                let angle = |k: usize| {
                    module
                        .tendon_angles
                        .get(k)
                        .map_or(f64::NAN, |a| a.to_degrees())
                };
                ModuleDescription {
                    tendon_angles_deg: [angle(0), angle(1), angle(2)],
                    rest_length_m: module.rest_length,
                    servo_ids: hw.servo_ids,
                    direction: hw.directions.map(|s| if s < 0.0 { -1 } else { 1 }),
                    pulley_radius_m: hw.pulley_radius,
                    zero_angle_deg: hw.zero_angles.map(f64::to_degrees),
                    zero_length_m: hw.zero_lengths,
                }
            })
            .collect();
        LogDescription {
            format: FORMAT,
            robot: robot.name.clone(),
            robot_file: robot.source.display().to_string(),
            baud: hardware.baud,
            current_unit_ma: hardware.current_unit,
            position_unit_deg: hardware.position_unit,
            velocity_unit_rpm: hardware.velocity_unit,
            modules,
        }
    }

    /// Writes `dir/hardware.json`.
    pub fn write(&self, dir: &Path) -> Result<PathBuf, DescriptionError> {
        let file = dir.join(FILE_NAME);
        let io = |message: String| DescriptionError::Io {
            file: file.clone(),
            message,
        };
        let text = serde_json::to_string_pretty(self).map_err(|e| io(e.to_string()))?;
        std::fs::write(&file, text + "\n").map_err(|e| io(e.to_string()))?;
        Ok(file)
    }

    /// Reads `dir/hardware.json`.
    pub fn read(dir: &Path) -> Result<LogDescription, DescriptionError> {
        let file = dir.join(FILE_NAME);
        let io = |message: String| DescriptionError::Io {
            file: file.clone(),
            message,
        };
        let text = match std::fs::read_to_string(&file) {
            Ok(text) => text,
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => {
                return Err(DescriptionError::Missing { file });
            }
            Err(error) => return Err(io(error.to_string())),
        };
        let description: LogDescription = serde_json::from_str(&text).map_err(|e| {
            io(format!(
                "line {}: not a hardware description of softcbf: {e}",
                e.line()
            ))
        })?;
        if description.format != FORMAT {
            return Err(io(format!(
                "format {}, this softcbf reads format {FORMAT}",
                description.format
            )));
        }
        Ok(description)
    }

    /// The first field (in the order the fields are declared, module by module) where this
    /// description, a log's, differs from `robot`'s; `None` when they agree. The baud rate
    /// and the robot file's path are not compared: a run may change the first, and the
    /// second names a file, not a robot.
    pub fn first_difference(&self, robot: &LogDescription) -> Option<Difference> {
        let differ =
            |field: String, log: String, robot: String| Some(Difference { field, log, robot });
        if self.robot != robot.robot {
            return differ("name".into(), self.robot.clone(), robot.robot.clone());
        }
        if self.modules.len() != robot.modules.len() {
            return differ(
                "number of modules".into(),
                self.modules.len().to_string(),
                robot.modules.len().to_string(),
            );
        }
        let units = [
            (
                "hardware.current_unit_ma",
                self.current_unit_ma,
                robot.current_unit_ma,
            ),
            (
                "hardware.position_unit_deg",
                self.position_unit_deg,
                robot.position_unit_deg,
            ),
            (
                "hardware.velocity_unit_rpm",
                self.velocity_unit_rpm,
                robot.velocity_unit_rpm,
            ),
        ];
        for (i, (log, own)) in self.modules.iter().zip(&robot.modules).enumerate() {
            let m = format!("module[{}]", i + 1);
            let h = format!("hardware.module[{}]", i + 1);
            for k in 0..3 {
                if log.servo_ids[k] != own.servo_ids[k] {
                    return differ(
                        format!("{h}.servo_ids[{}]", k + 1),
                        log.servo_ids[k].to_string(),
                        own.servo_ids[k].to_string(),
                    );
                }
            }
            for k in 0..3 {
                if log.direction[k] != own.direction[k] {
                    return differ(
                        format!("{h}.direction[{}]", k + 1),
                        log.direction[k].to_string(),
                        own.direction[k].to_string(),
                    );
                }
            }
            let numbers = (0..3)
                .map(|k| {
                    (
                        format!("{m}.tendon_angles_deg[{}]", k + 1),
                        log.tendon_angles_deg[k],
                        own.tendon_angles_deg[k],
                    )
                })
                .chain([(
                    format!("{m}.rest_length"),
                    log.rest_length_m,
                    own.rest_length_m,
                )])
                .chain([(
                    format!("{h}.pulley_radius"),
                    log.pulley_radius_m,
                    own.pulley_radius_m,
                )])
                .chain((0..3).map(|k| {
                    (
                        format!("{h}.zero_angle_deg[{}]", k + 1),
                        log.zero_angle_deg[k],
                        own.zero_angle_deg[k],
                    )
                }))
                .chain((0..3).map(|k| {
                    (
                        format!("{h}.zero_length[{}]", k + 1),
                        log.zero_length_m[k],
                        own.zero_length_m[k],
                    )
                }));
            for (field, a, b) in numbers {
                if !same(a, b) {
                    return differ(field, a.to_string(), b.to_string());
                }
            }
        }
        for (field, a, b) in units {
            if !same(a, b) {
                return differ(field.into(), a.to_string(), b.to_string());
            }
        }
        None
    }
}

/// Whether two numbers of a description are the same (within [`SAME`] of each other,
/// relative; an angle of 0 within 1e-9 degrees).
fn same(a: f64, b: f64) -> bool {
    a == b || (a - b).abs() <= SAME * a.abs().max(b.abs()).max(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hardware_description as description;

    fn example() -> (Robot, Hardware) {
        let path = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../robots/hardware-example.toml"
        ));
        let robot = Robot::load(path).unwrap();
        let hardware = description::load(&robot).unwrap().unwrap();
        (robot, hardware)
    }

    #[test]
    fn a_description_reads_back_as_written_and_names_its_first_difference() {
        let (robot, hardware) = example();
        let dir =
            std::env::temp_dir().join(format!("softcbf-log-description-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let written = LogDescription::of(&robot, &hardware);
        written.write(&dir).unwrap();
        let back = LogDescription::read(&dir).unwrap();
        assert_eq!(back.first_difference(&written), None);
        assert_eq!(back.modules[0].direction, [1, -1, 1]);
        assert_eq!(back.modules[1].servo_ids, [4, 5, 6]);
        assert!((back.modules[0].zero_angle_deg[0] - 180.0).abs() < 1e-12);

        // One tendon turned the other way, then (as well) another pulley: the direction
        // comes first.
        let mut other = hardware.clone();
        other.modules[1].directions[2] = 1.0;
        let turned = LogDescription::of(&robot, &other);
        let difference = turned.first_difference(&written).unwrap();
        assert_eq!(
            difference,
            Difference {
                field: "hardware.module[2].direction[3]".into(),
                log: "1".into(),
                robot: "-1".into(),
            }
        );
        other.modules[0].pulley_radius = 0.05;
        let difference = LogDescription::of(&robot, &other)
            .first_difference(&written)
            .unwrap();
        assert_eq!(difference.field, "hardware.module[1].pulley_radius");
        // The baud rate is the run's, not the robot's.
        let mut faster = hardware.clone();
        faster.baud = 2_000_000;
        assert_eq!(
            LogDescription::of(&robot, &faster).first_difference(&written),
            None
        );

        std::fs::remove_file(dir.join(FILE_NAME)).unwrap();
        let missing = LogDescription::read(&dir).unwrap_err().to_string();
        assert!(missing.contains("hardware.json: not found"), "{missing}");
        std::fs::write(dir.join(FILE_NAME), "{\"format\": 2}").unwrap();
        let wrong = LogDescription::read(&dir).unwrap_err().to_string();
        assert!(wrong.contains("not a hardware description"), "{wrong}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
