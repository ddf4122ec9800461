//! The safety filter and what it runs on: the control tick, the QP, the integrators, the
//! predicted and certified rows in closed loop.
//!
//! Each file is a module named as the test binary it once was; one binary links the
//! runtime once for all of them.

// Counts each thread's allocations, for the tests that check a hot path allocates nothing.
#[global_allocator]
static GLOBAL: softcbf_tests::alloc::CountingAlloc = softcbf_tests::alloc::CountingAlloc;

mod certified;
mod control;
mod integrator;
mod qp;
mod sampled_data;
