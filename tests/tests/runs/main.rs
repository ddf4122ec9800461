//! Whole runs and what they leave: the simulator, records, the command-line options,
//! reports and figures of barriers, the 3-D view.
//!
//! Each file is a module named as the test binary it once was; one binary links the
//! runtime once for all of them.

// Counts each thread's allocations, for the tests that check a hot path allocates nothing.
#[global_allocator]
static GLOBAL: softcbf_tests::alloc::CountingAlloc = softcbf_tests::alloc::CountingAlloc;

mod barrier_figures;
mod barrier_reports;
mod cli;
mod dense_records;
mod plot;
mod record;
mod robot_view;
mod simulate;
mod test_command;
