//! Shared helpers of the integration tests: independent reference evaluations and
//! reference integrators. Nothing here uses the generated code.

pub mod alloc;
pub mod highprec;
pub mod integrators;
pub mod reference;
pub mod robots;
