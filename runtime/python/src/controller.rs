//! `softcbf.Controller`: PD+ filtered by the safety QP, one `tick` per sample of the
//! robot's state. The workspaces are built once; a tick allocates nothing on the Rust side.

use std::sync::Arc;

use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::intern;
use pyo3::prelude::*;
use pyo3::types::PyString;

use softcbf_core::control::{
    ControllerSettings, InvalidState, Reference, SafetyMode, TickStatus, tick,
};
use softcbf_core::model::Model;
use softcbf_core::settings::check_number;
use softcbf_core::settings::{GainOptions, ScenarioGains, resolve_gains};
use softcbf_description::limits;

use crate::convert::vector;
use crate::errors::value_error;
use crate::robot::Robot;

/// The paper's safe controller for one robot: `tick(q, qd, set_point)` gives the filtered
/// generalized force `tau` and the tick's status.
///
/// Gains default to the robot file's (`[gains]`, `[barrier]`), else the paper's
/// (`K_P = 5 I`, `K_D = I`, `p1 = p2 = 10`); `safety` to the robot file's `[hardware]
/// safety`, else `"certified"`, the guarantee over the whole hold of `control_period`
/// seconds (docs/model.md §5).
#[pyclass(module = "softcbf")]
pub struct Controller {
    model: Arc<Model>,
    controller: softcbf_core::control::Controller,
    zeros: Vec<f64>,
    status: TickStatus,
}

/// The status as an interned Python string: made once per interpreter, shared after.
fn status_name<'py>(py: Python<'py>, status: TickStatus) -> &'py Bound<'py, PyString> {
    match status {
        TickStatus::Unfiltered => intern!(py, "unfiltered"),
        TickStatus::Filtered => intern!(py, "filtered"),
        TickStatus::Relaxed => intern!(py, "relaxed"),
        TickStatus::QpFailed => intern!(py, "qp_failed"),
        TickStatus::InvalidState(_) => intern!(py, "invalid_state"),
        TickStatus::Uncertified(_) => intern!(py, "uncertified"),
    }
}

fn invalid_name(why: InvalidState) -> &'static str {
    match why {
        InvalidState::NonFinite => "non_finite",
        InvalidState::Size { .. } => "size",
        InvalidState::MassMatrix => "mass_matrix",
        InvalidState::NonFiniteModel => "non_finite_model",
        InvalidState::OutOfDomain => "out_of_domain",
    }
}

#[pymethods]
impl Controller {
    #[new]
    #[pyo3(signature = (robot, *, kp=None, kd=None, p=None, p1=None, p2=None, filter=true, safety=None, control_period=0.001))]
    #[allow(clippy::too_many_arguments)] // the Python signature's keywords, one each
    fn new(
        py: Python<'_>,
        robot: &Robot,
        kp: Option<f64>,
        kd: Option<f64>,
        p: Option<f64>,
        p1: Option<f64>,
        p2: Option<f64>,
        filter: bool,
        safety: Option<&str>,
        control_period: f64,
    ) -> PyResult<Controller> {
        let model = robot.build_model(py, true)?;
        let gains = GainOptions::checked_as(kp, kd, p, p1, p2, &|name| name.to_string())
            .map_err(value_error)?;
        let period = check_number("control_period", control_period, &limits::CONTROL_PERIOD_S)
            .map_err(value_error)?;
        let safety = match safety {
            Some(name) => {
                SafetyMode::parse(name).map_err(|e| value_error(format!("safety: {e}")))?
            }
            None => softcbf_core::hardware_description::load(&model.robot)
                .ok()
                .flatten()
                .and_then(|hardware| hardware.safety)
                .unwrap_or_default(),
        };
        let settings = ControllerSettings {
            filter,
            safety,
            hold: period,
            ..resolve_gains(&gains, &ScenarioGains::default(), &model.robot).controller_settings()
        };
        let controller = softcbf_core::control::Controller::new(&model, settings)
            .map_err(|e| value_error(e.to_string()))?;
        let zeros = vec![0.0; model.nq()];
        Ok(Controller {
            model,
            controller,
            zeros,
            status: TickStatus::Unfiltered,
        })
    }

    /// One control tick at the sampled state `(q, qd)` toward `set_point` (with its
    /// velocity and acceleration, zero by default): returns `(tau, status)`.
    ///
    /// `status` is `"filtered"` (the QP kept every barrier row), `"unfiltered"` (filter
    /// off), `"relaxed"` (the rows had no common point: the slack-relaxed optimum),
    /// `"qp_failed"` or `"invalid_state"` (a NaN or infinite state, a state outside the
    /// model's domain: `invalid_reason` says which). The last two give the safe command,
    /// zero, rather than raising, so that a control loop always has a command to send.
    /// Arguments of the wrong shape or dtype raise. With `out` (a float64 array of `nq`
    /// entries), `tau` is written there and returned, and the tick allocates nothing.
    #[pyo3(signature = (q, qd, set_point, set_point_velocity=None, set_point_acceleration=None, out=None))]
    #[allow(clippy::too_many_arguments)] // the Python signature's keywords, one each
    fn tick<'py>(
        &mut self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        set_point: &Bound<'py, PyAny>,
        set_point_velocity: Option<&Bound<'py, PyAny>>,
        set_point_acceleration: Option<&Bound<'py, PyAny>>,
        out: Option<Bound<'py, PyArray1<f64>>>,
    ) -> PyResult<(Bound<'py, PyArray1<f64>>, Bound<'py, PyString>)> {
        let nq = self.model.nq();
        let q = vector(q, "q", nq)?;
        let qd = vector(qd, "qd", nq)?;
        let set_point = vector(set_point, "set_point", nq)?;
        // A finite set point outside the model's domain is no reference the filter can keep
        // safe toward (the command line refuses it too); a non-finite one is a fault the
        // tick answers with the safe command (status "invalid_state").
        let finite = set_point.as_slice().iter().all(|x| x.is_finite());
        if let Some(problem) = softcbf_description::domain::coordinates_problem(
            &self.model.robot,
            set_point.as_slice(),
        )
        .filter(|_| finite)
        {
            return Err(PyValueError::new_err(format!(
                "set_point: outside the model's domain: {problem}"
            )));
        }
        let velocity = set_point_velocity
            .map(|v| vector(v, "set_point_velocity", nq))
            .transpose()?;
        let acceleration = set_point_acceleration
            .map(|v| vector(v, "set_point_acceleration", nq))
            .transpose()?;
        let reference = Reference {
            q: set_point.as_slice(),
            qd: velocity.as_ref().map_or(&self.zeros[..], |v| v.as_slice()),
            qdd: acceleration
                .as_ref()
                .map_or(&self.zeros[..], |v| v.as_slice()),
        };
        let status = tick(
            &self.model,
            &mut self.controller,
            q.as_slice(),
            qd.as_slice(),
            reference,
        );
        self.status = status;
        let tau = match out {
            Some(out) => {
                let mut write = out.try_readwrite().map_err(|_| {
                    PyValueError::new_err("out: the array is not writeable or is in use")
                })?;
                let slice = write.as_slice_mut().map_err(|_| {
                    PyValueError::new_err("out: must be a contiguous float64 array")
                })?;
                if slice.len() != nq {
                    return Err(PyValueError::new_err(format!(
                        "out: expected {nq} entries, got {}",
                        slice.len()
                    )));
                }
                slice.copy_from_slice(self.controller.tau());
                drop(write);
                out
            }
            None => PyArray1::from_slice(py, self.controller.tau()),
        };
        Ok((tau, status_name(py, status).clone()))
    }

    /// Why the last tick's state was invalid (`"non_finite"`, `"out_of_domain"`,
    /// `"mass_matrix"`, `"non_finite_model"`), or None.
    #[getter]
    fn invalid_reason(&self) -> Option<&'static str> {
        match self.status {
            TickStatus::InvalidState(why) => Some(invalid_name(why)),
            _ => None,
        }
    }

    /// The last tick's nominal PD+ command `tau_nom`.
    #[getter]
    fn tau_nom<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.controller.tau_nom())
    }

    /// The barriers at the last tick's state, in the model's barrier order.
    #[getter]
    fn barriers<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.controller.barriers())
    }

    /// The safety mode (`"certified"`, `"paper"`, `"hold-correction"`, `"predicted"`).
    #[getter]
    fn safety(&self) -> &'static str {
        self.controller.settings().safety.name()
    }

    /// The hold the safety rows assume \[s\].
    #[getter]
    fn control_period(&self) -> f64 {
        self.controller.settings().hold
    }

    fn __repr__(&self) -> String {
        let settings = self.controller.settings();
        format!(
            "Controller({:?}, safety {:?}, control period {} s, filter {})",
            self.model.robot.name,
            settings.safety.name(),
            settings.hold,
            if settings.filter { "on" } else { "off" }
        )
    }
}
