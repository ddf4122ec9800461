//! softcbf-description: what a robot file says, read and checked, and the parameter
//! vector that carries its numbers into a generated model.
//!
//! [`robot`] reads robot files (`robots/*.toml`) into an immutable [`Robot`] whose
//! [`Structure`] decides which model is generated; [`module`] declares every field of a
//! module once (name, range, default); [`limits`] holds the range of every number a user
//! gives and [`domain`] the states a model describes; [`toml_file`] reads description files and builds errors naming file, line and
//! field; [`layout`] fixes the runtime parameter vector. The `[hardware]` table of a robot
//! file is kept unread ([`robot::HardwareTable`]): the runtime's hardware path checks it.
//!
//! ```
//! use softcbf_description::Robot;
//! let robot = Robot::paper_sim();
//! assert_eq!(robot.structure().modules(), 2);
//! // Per module L0, d, r, each corner's cos φ, sin φ and margin, and its limits
//! // (δL_min, δL_max, their margin, θ_max, its margin).
//! assert_eq!(softcbf_description::layout::pack_params(&robot).len(), 2 * (3 + 6 * 3 + 5));
//! ```

mod barrier_tables;
pub mod barriers;
pub mod domain;
pub mod gains;
pub mod layout;
pub mod limits;
pub mod module;
mod module_domain;
pub mod robot;
pub mod toml_file;
pub mod uncertainty;
mod uncertainty_box;

pub use robot::{Robot, RobotError, Structure};
