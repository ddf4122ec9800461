//! softcbf's figures of a run: the time series of Fig. 4 ([`plot::write_figures`]: PNG
//! and SVG with an embedded font), the 3-D view of the robot with its obstacles and the
//! animated GIF, drawn from a model and a record. Built on the controller core
//! (`softcbf-core`); `softcbf` re-exports [`plot`] under the same name.

pub mod plot;

// The core modules the figures read, under the names their files use (`crate::model`).
use softcbf_core::{barrier_info, model, record};
