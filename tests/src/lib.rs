//! Shared helpers of the integration tests: independent reference evaluations.
//! Nothing here uses the generated code; tests compare the two.

pub mod alloc;
pub mod highprec;
pub mod reference;
pub mod robots;
