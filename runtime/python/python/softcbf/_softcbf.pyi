"""Type stubs of the Rust extension behind the ``softcbf`` package."""

import os
from typing import Any, Dict, List, Literal, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Vector = Union[npt.NDArray[np.float64], Sequence[float]]
_Path = Union[str, "os.PathLike[str]"]
Status = Literal["filtered", "unfiltered", "relaxed", "qp_failed", "invalid_state", "uncertified"]
Safety = Literal["certified", "paper", "hold-correction", "predicted"]

class DescriptionError(ValueError):
    """A robot or scenario file (or dict) that cannot be used."""

    path: str
    """The file (``<scenario dict>`` for a dict)."""
    line: int
    """The line of the problem (1-based; 0 when unknown)."""
    column: int
    """The column of a syntax error (0 otherwise)."""
    field: Optional[str]
    """The field at fault (``module[2].mass``), or None for a syntax error."""

class NoGeneratedModelError(RuntimeError):
    """The robot's structure has no compiled model in this build and the interpreted one
    was refused (``Robot.model(interpreted=False)``); the message gives the command that
    builds the package with one."""

class SimulationError(RuntimeError):
    """A simulation that could not run (integrator failure, plant of another structure)."""

class Robot:
    """A robot file, read and checked."""

    @staticmethod
    def load(path: _Path) -> Robot:
        """Reads and checks the robot file at ``path``; ``DescriptionError`` names the
        file, line and field of a problem, ``FileNotFoundError`` a missing file."""
    @staticmethod
    def paper_sim() -> Robot:
        """The paper's simulated two-module robot, embedded in the package."""
    @property
    def name(self) -> str:
        """The name given in the file, else its stem."""
    @property
    def path(self) -> str:
        """The file it was read from."""
    @property
    def modules(self) -> int:
        """Number of modules."""
    @property
    def nq(self) -> int:
        """Number of coordinates, 3 per module (Δx, Δy, δL)."""
    @property
    def coordinate_names(self) -> List[str]:
        """``dx1``, ``dy1``, ``dL1``, ``dx2``, …"""
    def model(self, *, interpreted: bool = True) -> Model:
        """The robot joined to its generated model. A structure this build has no
        compiled model for gets its model interpreted at run time (the same numbers,
        about 25 times slower per evaluation, a tick 2–3 times) with a ``RuntimeWarning``
        that gives the command building compiled code; with ``interpreted=False`` that is
        a ``NoGeneratedModelError`` instead."""

class Model:
    """A robot joined to its generated functions."""

    @property
    def nq(self) -> int:
        """Number of coordinates."""
    @property
    def nb(self) -> int:
        """Number of barriers."""
    @property
    def generated_model(self) -> str:
        """The generated model's name (``"interpreted"`` for one run at run time)."""
    @property
    def interpreted(self) -> bool:
        """Whether the model is interpreted at run time rather than compiled code."""
    @property
    def barrier_labels(self) -> List[str]:
        """Each barrier's label, in the order of the barrier arrays."""
    def evaluate(self, q: _Vector, qd: _Vector) -> Dict[str, Any]:
        """Every generated and dynamic quantity at ``(q, qd)``, with the keys of
        ``softcbf model`` (``plate_poses``, ``barriers``, ``barrier_jacobian``,
        ``barrier_jdot_qd``, ``mass_matrix``, ``bias``, ``gravity``, ``elastic``,
        ``damping``, ``energy``, ``barrier_table``, ``barrier_info``, …); arrays are float64
        numpy arrays. ``q``, ``qd``: ``nq`` finite numbers in the model's domain."""

class Controller:
    """PD+ filtered by the safety QP; one ``tick`` per sample of the state."""

    def __init__(
        self,
        robot: Robot,
        *,
        kp: Optional[float] = None,
        kd: Optional[float] = None,
        p: Optional[float] = None,
        p1: Optional[float] = None,
        p2: Optional[float] = None,
        filter: bool = True,
        safety: Optional[Safety] = None,
        control_period: float = 0.001,
    ) -> None:
        """Gains default to the robot file's, else the paper's (K_P = 5 I, K_D = I,
        p1 = p2 = 10); ``safety`` to the robot file's ``[hardware] safety``, else
        ``"certified"`` over a hold of ``control_period`` seconds. Every number is checked
        against the range of its file field (``ValueError``). A robot without a compiled
        model runs on its interpreted one, with a ``RuntimeWarning`` (see ``Robot.model``)."""
    def tick(
        self,
        q: _Vector,
        qd: _Vector,
        set_point: _Vector,
        set_point_velocity: Optional[_Vector] = None,
        set_point_acceleration: Optional[_Vector] = None,
        out: Optional[npt.NDArray[np.float64]] = None,
    ) -> Tuple[npt.NDArray[np.float64], Status]:
        """One control tick: ``(tau, status)``. A NaN or out-of-domain state gives the safe
        command (zero) with status ``"invalid_state"``; a set point outside the model's
        domain, wrong shapes or dtypes raise. With the certified rows, a tick whose bound
        over the hold did not close has status ``"uncertified"`` (its command is the
        predicted rows'). With ``out``, ``tau`` is written there and returned."""
    @property
    def invalid_reason(self) -> Optional[str]:
        """Why the last tick's state was invalid, or None."""
    @property
    def tau_nom(self) -> npt.NDArray[np.float64]:
        """The last tick's nominal PD+ command."""
    @property
    def barriers(self) -> npt.NDArray[np.float64]:
        """The barriers at the last tick's state."""
    @property
    def safety(self) -> Safety:
        """The safety mode."""
    @property
    def control_period(self) -> float:
        """The hold the safety rows assume [s]."""

class SimulationResult:
    """A finished run: trajectory arrays, summary, and the PD+ comparison if asked."""

    @property
    def t(self) -> npt.NDArray[np.float64]:
        """Times of the rows [s]."""
    @property
    def q(self) -> npt.NDArray[np.float64]:
        """Coordinates per row [m], rows × nq."""
    @property
    def qd(self) -> npt.NDArray[np.float64]:
        """Velocities per row [m/s], rows × nq."""
    @property
    def tau(self) -> npt.NDArray[np.float64]:
        """Applied command per row [N], rows × nq."""
    @property
    def tau_nom(self) -> npt.NDArray[np.float64]:
        """Nominal PD+ command per row [N], rows × nq."""
    @property
    def barriers(self) -> npt.NDArray[np.float64]:
        """Barriers per row (m or rad), rows × nb."""
    @property
    def coordinate_names(self) -> List[str]:
        """Names of the columns of q, qd, tau."""
    @property
    def barrier_labels(self) -> List[str]:
        """Labels of the columns of barriers."""
    @property
    def columns(self) -> List[str]:
        """trajectory.csv's column names with units."""
    @property
    def summary(self) -> Dict[str, Any]:
        """summary.json of the run."""
    @property
    def comparison(self) -> Optional[SimulationResult]:
        """The plain PD+ run (``compare=True``), or None."""
    def write(self, out: _Path, animate: bool = False) -> List[str]:
        """Writes what ``softcbf simulate --out`` writes; returns the paths."""

def simulate(
    scenario: Union[None, _Path, Dict[str, Any]] = None,
    *,
    robot: Union[None, Robot, _Path] = None,
    plant: Optional[_Path] = None,
    set_point: Optional[_Vector] = None,
    duration: Optional[float] = None,
    control_period: Optional[float] = None,
    record_period: Optional[float] = None,
    kp: Optional[float] = None,
    kd: Optional[float] = None,
    p: Optional[float] = None,
    p1: Optional[float] = None,
    p2: Optional[float] = None,
    safety: Optional[Safety] = None,
    filter: Optional[bool] = None,
    compare: Optional[bool] = None,
) -> SimulationResult:
    """Simulates the safe controller on a scenario (a file, a dict in the scenario
    format, or None for the paper's), the keywords overriding it as the command line's
    options do. The GIL is released while it runs. A robot without a compiled model
    runs on its interpreted one, with a ``RuntimeWarning`` (see ``Robot.model``)."""

def generated_models() -> List[str]:
    """The generated models this build has."""

def run_verify(args: List[str]) -> int: ...
def run_identify(
    robot: str,
    logs: List[str],
    out: str,
    figures: Optional[str] = None,
    half_width: Optional[float] = None,
    timing_uncertainty_ms: Optional[float] = None,
) -> int: ...
