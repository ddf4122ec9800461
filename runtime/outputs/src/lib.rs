//! softcbf outputs: what writes, reads and shows a run's files, below the commands that make
//! them (simulation, hardware, verification, identification).
//!
//! | module | what it is for |
//! |---|---|
//! | [`output`] | what `softcbf simulate` writes and shows: CSVs, summary, figures, progress; the console |
//! | [`frames`] | the frame times and point rounding the browser view and the MCAP scene share |
//! | [`mcap_log`] | a run directory as one MCAP log and back (Foxglove, `softcbf mcap`) |
//! | [`replot`] | `softcbf plot`: the figures redrawn from trajectory CSVs and hardware logs |
//! | [`view`] | `softcbf view`: a run as one self-contained HTML page, an interactive 3-D view in the browser |
//! | [`parse`] | numbers, vectors and coordinates read from the command line and checked |
//! | [`signal`] | terminating signals as flags the run loops and verification batches poll |

// The controller core's and the figures' modules at the root, so that the paths the files
// had in `softcbf` (`crate::model`, `crate::plot`, …) keep resolving.
use softcbf_core::{exit, model, record, robot_file, settings, sim};
use softcbf_figures::plot;

pub mod frames;
pub mod mcap_log;
pub mod output;
pub mod parse;
pub mod replot;
pub mod signal;
pub mod view;
