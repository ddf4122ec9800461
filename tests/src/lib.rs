//! Shared helpers of the integration tests: independent reference evaluations (nothing
//! here uses the generated models; tests compare the two), reference integrators, the
//! seeded random source and the emitted series under test.

pub mod alloc;
pub mod evaluate;
pub mod highprec;
pub mod integrators;
pub mod protocol;
pub mod random;
pub mod reference;
pub mod robots;

pub use random::{TestRng, rng};

/// `pcc_fs_fc_6(u)`: `f_s`, `f_c` and their derivatives up to order 6, emitted by
/// `softcbf_codegen::analytic::emit(6)` in this crate's build script.
#[allow(clippy::all, clippy::pedantic, unused)]
pub mod analytic {
    include!(concat!(env!("OUT_DIR"), "/analytic.rs"));
}
