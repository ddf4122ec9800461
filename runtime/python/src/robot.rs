//! `softcbf.Robot` (a checked robot file) and `softcbf.Model` (the robot joined to its model
//! functions, compiled or else interpreted with a warning, evaluated as `softcbf model` does).

use std::path::PathBuf;
use std::sync::Arc;

use pyo3::prelude::*;
use pyo3::types::PyDict;

use softcbf_core::inspect::model_report;
use softcbf_core::record::Columns;
use softcbf_description::domain;

use crate::convert::{finite_vector, json_to_python};
use softcbf_core::model::{Model, ModelError};

use crate::errors::{file_error, interpreted_warning, model_error, value_error};

/// A robot file, read and checked: modules, plates, limits, obstacles, gains, hardware.
///
/// Load one with `Robot.load(path)`, or take the paper's simulated two-module robot with
/// `Robot.paper_sim()`. Errors keep the file, line and field (`softcbf.DescriptionError`).
#[pyclass(module = "softcbf", frozen)]
pub struct Robot {
    pub robot: softcbf_description::robot::Robot,
}

impl Robot {
    /// The model of this robot; see [`build_model`].
    pub fn build_model(&self, py: Python<'_>, interpreted: bool) -> PyResult<Arc<Model>> {
        build_model(py, self.robot.clone(), interpreted)
    }
}

/// The model of `robot`: its compiled model if this build has one; else, with
/// `interpreted`, the model interpreted at run time (`softcbf_interpreter::interpreted`),
/// with a `RuntimeWarning` that says so, what it costs and how to build compiled code;
/// else `NoGeneratedModelError` with that command.
pub fn build_model(
    py: Python<'_>,
    robot: softcbf_description::robot::Robot,
    interpreted: bool,
) -> PyResult<Arc<Model>> {
    match Model::new(robot.clone()) {
        Ok(model) => Ok(Arc::new(model)),
        Err(error @ ModelError::NoGeneratedModel { .. }) if interpreted => {
            interpreted_warning(py, &error)?;
            let structure = robot.structure();
            let generated = py.detach(|| softcbf_interpreter::interpreted(&structure));
            Model::with_generated(robot, generated)
                .map(Arc::new)
                .map_err(|e| model_error(&e))
        }
        Err(error) => Err(model_error(&error)),
    }
}

#[pymethods]
impl Robot {
    /// Reads and checks the robot file at `path` (TOML; format in robots/README.md).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Robot> {
        softcbf_core::robot_file::load_robot(Some(&path))
            .map(|robot| Robot { robot })
            .map_err(|e| file_error(py, &e))
    }

    /// The paper's simulated robot (two modules), embedded in the package.
    #[staticmethod]
    fn paper_sim(py: Python<'_>) -> PyResult<Robot> {
        softcbf_core::robot_file::load_robot(None)
            .map(|robot| Robot { robot })
            .map_err(|e| file_error(py, &e))
    }

    /// The name given in the file (else the file's stem).
    #[getter]
    fn name(&self) -> String {
        self.robot.name.clone()
    }

    /// The file it was read from.
    #[getter]
    fn path(&self) -> String {
        self.robot.source.display().to_string()
    }

    /// Number of modules.
    #[getter]
    fn modules(&self) -> usize {
        self.robot.modules.len()
    }

    /// Number of coordinates, 3 per module (`Δx, Δy, δL`).
    #[getter]
    fn nq(&self) -> usize {
        3 * self.robot.modules.len()
    }

    /// The coordinates' names as the CSV columns give them: `dx1`, `dy1`, `dL1`, `dx2`, ….
    #[getter]
    fn coordinate_names(&self) -> Vec<String> {
        softcbf_core::record::coordinate_names(3 * self.robot.modules.len())
    }

    /// The robot joined to its generated model. A structure this build has no compiled
    /// model for gets its model interpreted at run time (same values, several times slower)
    /// with a `RuntimeWarning` giving the command that builds compiled code; with
    /// `interpreted=False` it raises `NoGeneratedModelError` with that command instead.
    #[pyo3(signature = (*, interpreted=true))]
    fn model(&self, py: Python<'_>, interpreted: bool) -> PyResult<PyModel> {
        Ok(PyModel {
            model: self.build_model(py, interpreted)?,
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "Robot({:?}, {} modules, from {})",
            self.robot.name,
            self.robot.modules.len(),
            self.robot.source.display()
        )
    }
}

/// A robot joined to its generated functions: barriers, Jacobians and dynamics at any state.
#[pyclass(module = "softcbf", name = "Model", frozen)]
pub struct PyModel {
    pub model: Arc<Model>,
}

#[pymethods]
impl PyModel {
    /// Number of coordinates.
    #[getter]
    fn nq(&self) -> usize {
        self.model.nq()
    }

    /// Number of barriers.
    #[getter]
    fn nb(&self) -> usize {
        self.model.nb()
    }

    /// The generated model's name (the structure it was generated for), `"interpreted"`
    /// for a model interpreted at run time.
    #[getter]
    fn generated_model(&self) -> &'static str {
        self.model.generated.name()
    }

    /// Whether the model is interpreted at run time rather than compiled code.
    #[getter]
    fn interpreted(&self) -> bool {
        self.model.generated.name() == "interpreted"
    }

    /// Each barrier's label, in the order of the barrier arrays (`module 1 corner 1`, …).
    #[getter]
    fn barrier_labels(&self) -> PyResult<Vec<String>> {
        let columns =
            Columns::for_model(&self.model, &[]).map_err(|e| value_error(e.to_string()))?;
        Ok(columns.barrier_labels().to_vec())
    }

    /// Every generated and dynamic quantity at `(q, qd)` as `softcbf model --q … --qd …`
    /// prints it, with the same keys: `plate_poses` (n×4×4), `barriers`,
    /// `barrier_jacobian` (nb×nq), `barrier_jdot_qd`, `mass_matrix` (nq×nq), `bias`
    /// (`C q̇`), `gravity`, `elastic` (`K q`), `damping` (`D q̇`), `energy`, and the barrier
    /// tables. Arrays are float64 numpy arrays. `q`, `qd`: `nq` finite numbers each, in
    /// the model's domain (else `ValueError`).
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let nq = self.model.nq();
        let q = finite_vector(q, "q", nq)?;
        let qd = finite_vector(qd, "qd", nq)?;
        let robot = &self.model.robot;
        if let Some(problem) = domain::coordinates_problem(robot, q.as_slice()) {
            return Err(value_error(format!("q: {problem}")));
        }
        if let Some(problem) = domain::velocities_problem(robot, qd.as_slice()) {
            return Err(value_error(format!("qd: {problem}")));
        }
        let report = model_report(&self.model, q.as_slice(), qd.as_slice())
            .map_err(|e| value_error(e.to_string()))?;
        json_to_python(py, &report)?
            .cast_into::<PyDict>()
            .map_err(Into::into)
    }

    fn __repr__(&self) -> String {
        format!(
            "Model({:?}, generated {:?}, nq = {}, nb = {})",
            self.model.robot.name,
            self.model.generated.name(),
            self.model.nq(),
            self.model.nb()
        )
    }
}

/// The generated models this build of the package has, by name.
#[pyfunction]
pub fn generated_models() -> Vec<&'static str> {
    softcbf_generated::MODELS.iter().map(|m| m.name()).collect()
}
