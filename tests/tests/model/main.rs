//! The generated model and the robot files: symbolic engine, kinematics, dynamics,
//! barriers, descriptions, the interpreter, the golden source.
//!
//! Each file is a module named as the test binary it once was; one binary links the
//! runtime once for all of them.

// Counts each thread's allocations, for the tests that check a hot path allocates nothing.
#[global_allocator]
static GLOBAL: softcbf_tests::alloc::CountingAlloc = softcbf_tests::alloc::CountingAlloc;

mod analytic;
mod barrier_kinds;
mod descriptions;
mod domain_limits;
mod dynamics;
mod energy;
mod engine;
mod general_barriers;
mod golden;
mod interpreter;
mod kinematics;
mod own_robot;
mod uncertainty;
