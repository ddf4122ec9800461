//! Shared helpers of the integration tests: independent reference evaluations, reference
//! integrators and the seeded random source. Nothing here uses the generated code.

pub mod alloc;
pub mod highprec;
pub mod integrators;
pub mod protocol;
pub mod random;
pub mod reference;
pub mod robots;

pub use random::{TestRng, rng};
