//! `softcbf.simulate`: a scenario (file, dict or the embedded paper scenario) with keyword
//! overrides, checked like the command line's options, run with the GIL released; the
//! result's trajectory as numpy arrays.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use numpy::ndarray::Array2;
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};

use softcbf_core::control::SafetyMode;
use softcbf_core::model::Model;
use softcbf_core::record::Record;
use softcbf_core::robot_file::load_robot;
use softcbf_core::scenario::ScenarioFile;
use softcbf_core::sim::{Run, simulate as run_simulation};
use softcbf_core::simulate_options::{SimulateOptions, check_simulate_options};
use softcbf_outputs::output::write_outputs;

use crate::convert::{dict_to_toml, finite_vector, json_to_python};
use crate::errors::{SimulationError, file_error, value_error};
use crate::robot::Robot;
use crate::robot::build_model;

/// The scenario argument: None (the paper's), a path, or a dict in the scenario format.
fn scenario_file(py: Python<'_>, scenario: Option<&Bound<'_, PyAny>>) -> PyResult<ScenarioFile> {
    let Some(scenario) = scenario else {
        return Ok(ScenarioFile::default_scenario());
    };
    if let Ok(dict) = scenario.cast::<PyDict>() {
        let text = dict_to_toml(dict)?;
        return ScenarioFile::parse(&text, Path::new("<scenario dict>"))
            .map_err(|e| file_error(py, &e));
    }
    if scenario.is_instance_of::<PyString>() || scenario.hasattr("__fspath__")? {
        let path: PathBuf = scenario.extract()?;
        return ScenarioFile::load(&path).map_err(|e| file_error(py, &e));
    }
    Err(pyo3::exceptions::PyTypeError::new_err(
        "scenario: give a path to a scenario file, a dict in the scenario format \
         (scenarios/README.md), or None for the paper's scenario",
    ))
}

/// Simulates the safe controller on a scenario, as `softcbf simulate` does, and returns
/// the run's trajectory and summary.
///
/// `scenario`: a scenario file's path, a dict with the same tables and fields
/// (scenarios/README.md), or None for the paper's simulation. The keywords override the
/// scenario as the command line's options do, with the same checks: `robot` (a `Robot` or
/// a path), `plant` (path), `set_point` (`nq` numbers), `duration`, `control_period`,
/// `record_period` \[s\], `kp`, `kd`, `p`, `p1`, `p2`, `safety` (`"certified"`, `"paper"`, `"predicted"`,
/// `"hold-correction"`), `filter` and `compare` (also run plain PD+, as
/// `result.comparison`). The GIL is released while it runs.
#[pyfunction]
#[pyo3(signature = (scenario=None, *, robot=None, plant=None, set_point=None, duration=None, control_period=None, record_period=None, kp=None, kd=None, p=None, p1=None, p2=None, safety=None, filter=None, compare=None))]
#[allow(clippy::too_many_arguments)] // the Python signature's keywords, one each
pub fn simulate(
    py: Python<'_>,
    scenario: Option<&Bound<'_, PyAny>>,
    robot: Option<&Bound<'_, PyAny>>,
    plant: Option<PathBuf>,
    set_point: Option<&Bound<'_, PyAny>>,
    duration: Option<f64>,
    control_period: Option<f64>,
    record_period: Option<f64>,
    kp: Option<f64>,
    kd: Option<f64>,
    p: Option<f64>,
    p1: Option<f64>,
    p2: Option<f64>,
    safety: Option<&str>,
    filter: Option<bool>,
    compare: Option<bool>,
) -> PyResult<SimulationResult> {
    let file = scenario_file(py, scenario)?;
    if let Some(path) = &plant
        && !path.is_file()
    {
        return Err(pyo3::exceptions::PyFileNotFoundError::new_err(format!(
            "plant: {}: no such robot file",
            path.display()
        )));
    }
    let robot = match robot {
        Some(given) => match given.cast::<Robot>() {
            Ok(robot) => robot.get().robot.clone(),
            Err(_) => {
                let path: PathBuf = given.extract().map_err(|_| {
                    pyo3::exceptions::PyTypeError::new_err(
                        "robot: give a softcbf.Robot or a robot file's path",
                    )
                })?;
                load_robot(Some(&path)).map_err(|e| file_error(py, &e))?
            }
        },
        None => file
            .load_robot()
            .and_then(|robot| robot.map_or_else(|| load_robot(None), Ok))
            .map_err(|e| file_error(py, &e))?,
    };
    let model = build_model(py, robot, true)?;
    let nq = model.nq();
    let set_point = set_point
        .map(|v| finite_vector(v, "set_point", nq).map(|v| v.as_slice().to_vec()))
        .transpose()?;
    let safety = safety
        .map(|name| SafetyMode::parse(name).map_err(|e| value_error(format!("safety: {e}"))))
        .transpose()?;
    let options = SimulateOptions {
        kp,
        kd,
        p,
        p1,
        p2,
        set_point,
        duration,
        control_period,
        record_period,
        filter,
        safety,
        compare,
        plant,
    };
    let overrides = check_simulate_options(options, &model.robot, &|name| name.to_string())
        .map_err(value_error)?;
    let scenario = file.resolve_with(&model, &overrides).map_err(|e| match e {
        softcbf_core::scenario::ScenarioError::File(e) => file_error(py, &e),
        softcbf_core::scenario::ScenarioError::Option(message)
        | softcbf_core::scenario::ScenarioError::Missing(message) => value_error(message),
    })?;
    let filter = scenario.controller.filter;
    let compare = filter && scenario.compare;
    let shared = Arc::clone(&model);
    let (main, comparison) = py
        .detach(move || {
            let main = run_simulation(&shared, &scenario, filter, &mut |_| {})?;
            let comparison = if compare {
                Some(run_simulation(&shared, &scenario, false, &mut |_| {})?)
            } else {
                None
            };
            Ok::<_, softcbf_core::sim::SimulationError>((main, comparison))
        })
        .map_err(|e| SimulationError::new_err(e.to_string()))?;
    Ok(SimulationResult {
        model,
        run: Arc::new(main),
        comparison: comparison.map(Arc::new),
    })
}

/// A finished run: the trajectory (one row per tick, and with a record period the rows
/// between ticks) as numpy arrays, the summary `softcbf simulate` writes to
/// `summary.json`, and the plain PD+ run when `compare` asked for it.
#[pyclass(module = "softcbf", frozen)]
pub struct SimulationResult {
    model: Arc<Model>,
    run: Arc<Run>,
    comparison: Option<Arc<Run>>,
}

/// Columns `from .. from + width` of every row of `record`, as a 2-D array.
fn block<'py>(
    py: Python<'py>,
    record: &Record,
    from: usize,
    width: usize,
) -> Bound<'py, PyArray2<f64>> {
    let stride = record.columns().width();
    let values = record.values();
    let rows = record.len();
    let array = Array2::from_shape_fn((rows, width), |(i, j)| values[i * stride + from + j]);
    PyArray2::from_owned_array(py, array)
}

#[pymethods]
impl SimulationResult {
    /// Times of the rows \[s\].
    #[getter]
    fn t<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_iter(py, self.run.record.times())
    }

    /// `q` per row \[m\], rows × nq.
    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        block(py, &self.run.record, 1, self.model.nq())
    }

    /// `q̇` per row \[m/s\], rows × nq.
    #[getter]
    fn qd<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let nq = self.model.nq();
        block(py, &self.run.record, 1 + nq, nq)
    }

    /// The applied command `τ` per row \[N\], rows × nq (held between ticks).
    #[getter]
    fn tau<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let nq = self.model.nq();
        block(py, &self.run.record, 1 + 2 * nq, nq)
    }

    /// The nominal PD+ command `τ_nom` per row \[N\], rows × nq.
    #[getter]
    fn tau_nom<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let nq = self.model.nq();
        block(py, &self.run.record, 1 + 3 * nq, nq)
    }

    /// Every barrier per row (m or rad), rows × nb, in the order of `barrier_labels`.
    #[getter]
    fn barriers<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let nq = self.model.nq();
        block(py, &self.run.record, 1 + 4 * nq, self.model.nb())
    }

    /// Names of the coordinates (`dx1`, `dy1`, `dL1`, …), the columns of `q`, `qd`, `tau`.
    #[getter]
    fn coordinate_names(&self) -> Vec<String> {
        self.run.record.columns().coordinate_names().to_vec()
    }

    /// Labels of the barriers, the columns of `barriers`.
    #[getter]
    fn barrier_labels(&self) -> Vec<String> {
        self.run.record.columns().barrier_labels().to_vec()
    }

    /// The CSV header names of every column, with units, as `trajectory.csv` has them.
    #[getter]
    fn columns(&self) -> Vec<String> {
        let columns = self.run.record.columns();
        (0..columns.width())
            .filter_map(|k| columns.name(k))
            .collect()
    }

    /// The run's summary as `summary.json` holds it (lowest barrier, QP counts, timing,
    /// settings with their sources).
    #[getter]
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let value = serde_json::to_value(&self.run.summary)
            .map_err(|e| value_error(format!("summary: {e}")))?;
        json_to_python(py, &value)
    }

    /// The plain PD+ run (`compare=True`), or None.
    #[getter]
    fn comparison(&self) -> Option<SimulationResult> {
        self.comparison.as_ref().map(|run| SimulationResult {
            model: Arc::clone(&self.model),
            run: Arc::clone(run),
            comparison: None,
        })
    }

    /// Writes what `softcbf simulate --out out` writes (trajectory CSVs, summary.json,
    /// figures, 3-D view; `robot.gif` with `animate`) and returns the paths written.
    #[pyo3(signature = (out, animate=false))]
    fn write(&self, py: Python<'_>, out: PathBuf, animate: bool) -> PyResult<Vec<PathBuf>> {
        let (model, run, comparison) = (&self.model, &self.run, &self.comparison);
        py.detach(|| write_outputs(&out, run, comparison.as_deref(), model, animate))
            .map_err(|e| pyo3::exceptions::PyOSError::new_err(e.to_string()))
    }

    fn __repr__(&self) -> String {
        softcbf_outputs::output::one_line(&self.run.summary)
    }
}
