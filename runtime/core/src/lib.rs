//! softcbf's controller core: the generated model put to work — dynamics, the paper's safety
//! filter, its QP, the integrators, the simulated plant and the closed-loop simulator, with
//! the scenario and settings files they read. No plotting, serial ports, least squares,
//! thread pools or argument parsing: the `softcbf` crate builds those on top and re-exports
//! every module here under the same name (`softcbf::control` is [`control`]).
//!
//! | module | what it is for |
//! |---|---|
//! | [`model`] | [`model::Model`]: a robot description joined to its generated functions, immutable |
//! | [`barrier_info`] | each barrier's numbers (margin, limits, obstacle geometry, watched point) from the robot |
//! | [`spatial`] | spatial (6-D) vectors, compact transforms and rigid-body inertias (nalgebra) |
//! | [`dynamics`] | `M`, `h = C q̇`, `G` by CRBA and RNEA, [`dynamics::model_terms`] for a tick, forward dynamics |
//! | [`noise`] | seeded Gaussian draws: the one standard normal sampler |
//! | [`linalg`] | small dense Cholesky and LU on preallocated slices, the one `dot` |
//! | [`control`] | PD+, the HOCBF rows and the safety QP as one allocation-free [`control::tick`] |
//! | [`enclosure`] | interval and jet enclosures of the model's mismatch terms (the certified rows) |
//! | [`hold`] | the excursion over one hold, affine in the held command |
//! | [`qp`] | the safety-filter QP: dual active set, clarabel as reference and fallback |
//! | [`integrator`] | adaptive integrators of the plant between ticks (Rosenbrock-W) |
//! | [`plant`] | the simulated robot: the dynamics under a held command |
//! | [`reference`](mod@reference) | what the controller tracks: set points and minimum-jerk waypoints |
//! | [`scenario`] | scenario files: robot, initial state, reference, gains, period, duration |
//! | [`settings`] | which value of each setting a run uses and where it came from (command line > scenario > robot > built-in) |
//! | [`simulate_options`] | what a simulation is told besides its scenario file (command line, Python), checked |
//! | [`inspect`] | `softcbf model`: every generated and dynamic quantity at one state, as JSON |
//! | [`sim`] | the closed-loop simulator: ticks on the sampled state, the plant in between |
//! | [`record`] | a run's trajectory, one row per tick (CSV in and out) |
//! | [`robot_file`] | a robot file loaded and checked as a whole (`[hardware]` included); the embedded paper robot |
//! | [`hardware_description`] | the robot file's `[hardware]` table read and checked, the ranges of servo and bus settings |
//! | [`verdict`] | one verdict per run (safe, unsafe, not run), whichever command computes it |
//! | [`exit`] | the command's exit statuses (safe, unsafe, fault, never started) |

pub mod barrier_info;
pub mod control;
pub mod dynamics;
pub mod enclosure;
pub mod exit;
pub mod hardware_description;
pub mod hold;
pub mod inspect;
pub mod integrator;
pub mod linalg;
pub mod model;
pub mod noise;
pub mod plant;
pub mod qp;
pub mod record;
pub mod reference;
pub mod robot_file;
pub mod scenario;
pub mod settings;
pub mod sim;
pub mod simulate_options;
pub mod spatial;
pub mod verdict;
