//! softcbf runtime: the generated model put to work — the paper's safe controller in
//! simulation and on the robot's servos.
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
//! | [`qp`] | the safety-filter QP: dual active set, clarabel as reference and fallback |
//! | [`integrator`] | adaptive integrators of the plant between ticks (Rosenbrock-W) |
//! | [`plant`] | the simulated robot: the dynamics under a held command |
//! | [`reference`](mod@reference) | what the controller tracks: set points and minimum-jerk waypoints |
//! | [`scenario`] | scenario files: robot, initial state, reference, gains, period, duration |
//! | [`settings`] | which value of each setting a run uses and where it came from (command line > scenario > robot > built-in) |
//! | [`sim`] | the closed-loop simulator: ticks on the sampled state, the plant in between |
//! | [`record`] | a run's trajectory, one row per tick (CSV in and out) |
//! | [`plot`] | figures of a run like the paper's Fig. 4 (PNG, SVG) |
//! | [`replot`] | `softcbf plot`: the figures redrawn from trajectory CSVs and hardware logs |
//! | [`view`] | `softcbf view`: a run as one self-contained HTML page, an interactive 3-D view in the browser |
//! | [`output`] | what `softcbf simulate` writes and shows: CSVs, summary, figures, progress |
//! | [`inspect`] | `softcbf model`: every generated and dynamic quantity at one state, as JSON |
//! | [`protocol`] | Dynamixel Protocol 2.0 codec and bus client |
//! | [`hardware_description`] | the robot file's `[hardware]` table read and checked, the ranges of servo and bus settings |
//! | [`hardware`] | the servos driven by the same tick (`softcbf run`), and their emulator |
//! | [`identify`] | `softcbf identify`: stiffness, damping and actuator gains from run logs |
//! | [`verify`] | `softcbf verify`: many closed-loop runs drawn from declared ranges, sharded and merged |
//! | [`robot_file`] | a robot file loaded and checked as a whole (`[hardware]` included); the embedded paper robot |
//! | [`cli`] | what the subcommands share: reading vectors and numbers, the simulate options |
//! | [`verdict`] | one verdict per run (safe, unsafe, not run), whichever command computes it |
//! | [`exit`] | the command's exit statuses (safe, unsafe, fault, never started) |
//!
//! # One control tick
//!
//! ```
//! use softcbf::robot_file::load_robot;
//! use softcbf::control::{Controller, ControllerSettings, Reference, TickStatus, tick};
//! use softcbf::model::Model;
//!
//! // The paper's simulated robot (two modules), embedded in the crate.
//! let model = Model::new(load_robot(None)?)?;
//! let mut controller = Controller::new(&model, ControllerSettings::paper(&model))?;
//! let nq = model.nq();
//! // At rest in the straight configuration, asked to bend the first module by 1 cm.
//! let (q, qd, zero) = (vec![0.0; nq], vec![0.0; nq], vec![0.0; nq]);
//! let mut set_point = vec![0.0; nq];
//! set_point[0] = 0.01;
//! let reference = Reference { q: &set_point, qd: &zero, qdd: &zero };
//! let status = tick(&model, &mut controller, &q, &qd, reference);
//! assert_eq!(status, TickStatus::Filtered);
//! assert!(controller.tau().iter().all(|tau| tau.is_finite()));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

// The controller core, re-exported so that `softcbf::control` and the rest keep their paths.
pub use softcbf_core::{
    barrier_info, control, dynamics, enclosure, exit, hardware_description, hold, inspect,
    integrator, linalg, model, noise, plant, qp, record, reference, robot_file, scenario, settings,
    sim, spatial, verdict,
};

// The wings of their own: the figures and the Dynamixel codec, under their old names too.
pub use softcbf_figures::plot;
pub use softcbf_protocol as protocol;

// A run's files and views (softcbf-outputs), the hardware path (softcbf-hardware),
// identification (softcbf-identify) and verification (softcbf-verify), under the module
// names they had in this crate.
pub use softcbf_hardware as hardware;
pub use softcbf_identify as identify;
pub use softcbf_outputs::{frames, mcap_log, output, replot, view};
pub use softcbf_verify as verify;

pub mod cli;
