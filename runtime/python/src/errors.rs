//! The package's exceptions, and the one conversion of each runtime error into them, so
//! that a Python caller sees the file, line and field a command-line user would see.

use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyAnyMethods;

use softcbf::model::ModelError;
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
            path, line, column, ..
        } => (path, *line, *column, None),
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
/// still there).
pub fn model_error(error: &ModelError) -> PyErr {
    let ModelError::NoGeneratedModel {
        source_file,
        modules,
        corners,
        tendons,
        routing,
        available,
    } = error;
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
    NoGeneratedModelError::new_err(format!(
        "{source_file}: no generated model for {modules} modules with corners {corners:?} and \
         tendons {tendons:?} ({routing}) in this build of the softcbf package, which has: \
         {available}. Build the package with this robot's model (needs a Rust toolchain; a \
         few minutes):\n  SOFTCBF_ROBOTS={file} pip install --force-reinstall {package}\n\
         (to keep it in every later build, register it once: cargo run --release -p \
         softcbf-codegen -- add {file})",
    ))
}

/// A message of the runtime's option checks (ranges, sizes) as a `ValueError`.
pub fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}
