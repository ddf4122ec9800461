//! Command-line helpers shared by the subcommands: reading vectors and numbers (robots are
//! loaded by [`crate::robot_file`]), and the simulate options.
//! Every error names what the user typed and what was expected.
//!
//! The parsers of vectors, numbers and coordinates live in [`softcbf_outputs::parse`], below
//! the hardware and verification crates that use them too, and the simulate options in
//! [`softcbf_core::simulate_options`], where the Python package finds them as well; both
//! are re-exported here.

pub use softcbf_core::simulate_options::{SimulateOptions, check_simulate_options};
pub use softcbf_outputs::parse::{
    parse_coordinates, parse_integer, parse_number, parse_vector, parse_velocities,
};
