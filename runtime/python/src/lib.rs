//! softcbf from Python: the extension module `softcbf._softcbf` behind the `softcbf`
//! package (runtime/python/python/softcbf): robots, the generated model, the safe controller
//! and the simulator, with numpy arrays in and out. The Rust runtime does the work; this
//! crate only converts arguments and errors.

mod commands;
mod controller;
mod convert;
mod errors;
mod robot;
mod simulate;

use pyo3::prelude::*;

/// The extension module; the `softcbf` package re-exports what users need.
#[pymodule]
fn _softcbf(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add(
        "DescriptionError",
        py.get_type::<errors::DescriptionError>(),
    )?;
    m.add(
        "NoGeneratedModelError",
        py.get_type::<errors::NoGeneratedModelError>(),
    )?;
    m.add("SimulationError", py.get_type::<errors::SimulationError>())?;
    m.add_class::<robot::Robot>()?;
    m.add_class::<robot::PyModel>()?;
    m.add_class::<controller::Controller>()?;
    m.add_class::<simulate::SimulationResult>()?;
    m.add_function(wrap_pyfunction!(simulate::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(commands::run_verify, m)?)?;
    m.add_function(wrap_pyfunction!(commands::run_identify, m)?)?;
    m.add_function(wrap_pyfunction!(robot::generated_models, m)?)?;
    Ok(())
}
