//! `softcbf verify` and `softcbf identify` behind the package's `verify()` and
//! `identify()`: the command's own argument checks and outputs, with the GIL released.

use std::path::PathBuf;

use clap::Parser;
use pyo3::prelude::*;

use softcbf_identify::IdentifyArgs;
use softcbf_outputs::output::Console;
use softcbf_verify::cli::VerifyArgs;

use crate::errors::value_error;

/// `softcbf verify`'s arguments, parsed by its own definitions.
#[derive(Parser)]
#[command(name = "verify", no_binary_name = true)]
struct VerifyCommand {
    #[command(flatten)]
    args: VerifyArgs,
}

/// Runs `softcbf verify ARGS…` (the package's `verify()` builds `args` from its keywords)
/// and returns its exit status: 0 every run safe, 3 some run unsafe.
#[pyfunction]
pub fn run_verify(py: Python<'_>, args: Vec<String>) -> PyResult<u8> {
    let command = VerifyCommand::try_parse_from(&args).map_err(|e| {
        value_error(
            e.render()
                .to_string()
                .trim_end()
                .replace("\n\nFor more information, try '--help'.", ""),
        )
    })?;
    py.detach(|| softcbf_verify::cli::verify(command.args, &mut Console::new()))
        .map_err(value_error)
}

/// Runs `softcbf identify` on the run directories `logs` of `robot`, writing the
/// identified robot file `out`; returns the exit status.
#[pyfunction]
#[pyo3(signature = (robot, logs, out, figures=None, half_width=None, timing_uncertainty_ms=None))]
pub fn run_identify(
    py: Python<'_>,
    robot: PathBuf,
    logs: Vec<PathBuf>,
    out: PathBuf,
    figures: Option<PathBuf>,
    half_width: Option<f64>,
    timing_uncertainty_ms: Option<f64>,
) -> PyResult<u8> {
    let args = IdentifyArgs {
        robot,
        logs,
        out,
        figures,
        half_width,
        timing_uncertainty_ms,
    };
    py.detach(|| softcbf_identify::run(args, &mut Console::new()))
        .map_err(value_error)
}
