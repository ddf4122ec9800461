//! The package's exceptions, and the one conversion of each runtime error into them, so
//! that a Python caller sees the file, line and field a command-line user would see.

use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyAnyMethods;

use softcbf_core::model::ModelError;
use softcbf_description::toml_file::{FileError, shell_word};

pyo3::create_exception!(
    _softcbf,
    DescriptionError,
    PyValueError,
    "A robot or scenario file (or dict) that cannot be used: `path`, `line`, `column` \
     (0 when unknown) and `field` (None when the problem is not one field's) say where."
);
pyo3::create_exception!(
    _softcbf,
    NoGeneratedModelError,
    PyRuntimeError,
    "The robot's structure (modules, corners, tendons) has no generated model in this build \
     of the package; the message gives the command that builds one."
);
pyo3::create_exception!(
    _softcbf,
    SimulationError,
    PyRuntimeError,
    "A simulation that could not run (integrator failure, a plant of another structure)."
);

/// A description file's error as an exception: `FileNotFoundError`/`OSError` when it could
/// not be read, else [`DescriptionError`] with its place as attributes.
pub fn file_error(py: Python<'_>, error: &FileError) -> PyErr {
    let message = error.to_string();
    let (path, line, column, field) = match error {
        FileError::Io { path, source, .. } => {
            return if source.kind() == std::io::ErrorKind::NotFound {
                PyFileNotFoundError::new_err(message)
            } else {
                let _ = path;
                PyOSError::new_err(message)
            };
        }
        FileError::Syntax {
            path,
            line,
            column,
            field,
            ..
        } => (path, *line, *column, field.clone()),
        FileError::Invalid {
            path, line, field, ..
        } => (path, *line, 0, Some(field.clone())),
    };
    let err = DescriptionError::new_err(message);
    let value = err.value(py);
    // Setting attributes on a fresh exception instance cannot fail short of memory; the
    // message alone still names the place if it does.
    let _ = value.setattr("path", path.display().to_string());
    let _ = value.setattr("line", line);
    let _ = value.setattr("column", column);
    let _ = value.setattr("field", field);
    err
}

/// A robot whose structure this build has no model for: the message names the one command
/// that builds the package with it (the checkout the package was built from, if it is
/// still there). A model given for another structure (a programming error) is a
/// `RuntimeError`.
pub fn model_error(error: &ModelError) -> PyErr {
    match error {
        ModelError::NoGeneratedModel { .. } => {
            NoGeneratedModelError::new_err(format!("{}. {}", no_model(error), rebuild(error)))
        }
        ModelError::StructureMismatch { .. } => PyRuntimeError::new_err(error.to_string()),
    }
}

/// How much slower the interpreted model is than compiled code, as the warning says it:
/// medians of `cargo bench -p softcbf-tests --bench interpreter` (`model_terms` of 1 to 8
/// paper modules ≈ 25×; the paper scenario's closed loop for 1 s ≈ 2.3×).
pub const INTERPRETED_COST: &str = "about 25 times slower per model evaluation than compiled \
     code; a control tick or a simulation about 2 to 3 times slower";

/// The warning of a robot run on the interpreted model: what is missing, what it costs and
/// the command that builds compiled code for it.
pub fn interpreted_warning(py: Python<'_>, error: &ModelError) -> PyResult<()> {
    let message = format!(
        "{}; using its model interpreted at run time instead ({INTERPRETED_COST}). {}",
        no_model(error),
        rebuild(error)
    );
    // A NUL cannot come from a path shell_word quoted; replace it rather than fail.
    let message =
        std::ffi::CString::new(message.replace('\0', "?")).expect("no NUL left in the message");
    let category = py.get_type::<pyo3::exceptions::PyRuntimeWarning>();
    // stacklevel 1: the warning points at the Python line that made the model.
    PyErr::warn(py, category.as_any(), &message, 1)
}

/// `FILE: no generated model for … in this build of the softcbf package, which has: …`.
fn no_model(error: &ModelError) -> String {
    match error {
        ModelError::NoGeneratedModel {
            source_file,
            modules,
            corners,
            tendons,
            routing,
            available,
        } => format!(
            "{source_file}: no generated model for {modules} modules with corners {corners:?} \
             and tendons {tendons:?} ({routing}) in this build of the softcbf package, which \
             has: {available}"
        ),
        other => other.to_string(),
    }
}

/// The command that builds the package with the robot's model compiled in.
fn rebuild(error: &ModelError) -> String {
    let (ModelError::NoGeneratedModel { source_file, .. }
    | ModelError::StructureMismatch { source_file, .. }) = error;
    let file = std::path::absolute(source_file).unwrap_or_else(|_| source_file.into());
    let file = shell_word(&file);
    let package = env!("CARGO_MANIFEST_DIR");
    let package = if std::path::Path::new(package)
        .join("pyproject.toml")
        .is_file()
    {
        package.to_string()
    } else {
        "<your softcbf checkout>/runtime/python".to_string()
    };
    format!(
        "Build the package with this robot's model (needs a Rust toolchain; a few \
         minutes):\n  SOFTCBF_ROBOTS={file} pip install --force-reinstall {package}\n\
         (to keep it in every later build, register it once: cargo run --release -p \
         softcbf-codegen -- add {file})"
    )
}

/// A message of the runtime's option checks (ranges, sizes) as a `ValueError`.
pub fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}
