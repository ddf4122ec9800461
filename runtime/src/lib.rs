//! softcbf runtime: the generated model put to work.
//!
//! [`model::Model`] joins a robot description to its generated functions; [`dynamics`]
//! computes `M`, `C q̇`, `G` and forward dynamics over [`spatial`] algebra; [`inspect`]
//! reports a model at one state; [`record`] keeps a run's trajectory (CSV in and out) and
//! [`plot`] draws it; [`cli`] holds what the `softcbf` command shares.

pub mod cli;
pub mod control;
pub mod dynamics;
pub mod exit;
pub mod hardware;
pub mod inspect;
pub mod integrator;
pub mod linalg;
pub mod model;
pub mod output;
pub mod plant;
pub mod plot;
pub mod protocol;
pub mod qp;
pub mod record;
pub mod reference;
pub mod scenario;
pub mod sim;
pub mod spatial;
