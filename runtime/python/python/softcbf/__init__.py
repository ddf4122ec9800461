"""softcbf from Python: safe control of soft-rigid robots with self-contact.

The generated model, the paper's safe controller (PD+ filtered by a QP over High-Order
Control Barrier Functions on the plate corners) and the simulator, from numpy. The work is
done by the Rust runtime (``softcbf._softcbf``); this module adds the batch commands'
result types.

    import softcbf
    robot = softcbf.Robot.paper_sim()
    values = robot.model().evaluate(q, qd)      # dict of numpy arrays
    controller = softcbf.Controller(robot)
    tau, status = controller.tick(q, qd, set_point)
    result = softcbf.simulate(duration=2.0)     # the paper's scenario
"""

from __future__ import annotations

import csv
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Optional, Sequence, Union

import numpy as np

from ._softcbf import (
    Controller,
    DescriptionError,
    Model,
    NoGeneratedModelError,
    Robot,
    SimulationError,
    SimulationResult,
    __version__,
    simulate,
    generated_models,
)
from ._softcbf import run_identify as _run_identify
from ._softcbf import run_verify as _run_verify

__all__ = [
    "Controller",
    "DescriptionError",
    "IdentifyResult",
    "Model",
    "NoGeneratedModelError",
    "Robot",
    "STATUSES",
    "SimulationError",
    "SimulationResult",
    "VerifyResult",
    "__version__",
    "identify",
    "simulate",
    "generated_models",
    "verify",
    "verify_merge",
]

#: Every status `Controller.tick` returns. ``"qp_failed"`` and ``"invalid_state"`` come
#: with the safe command (zero).
STATUSES = ("filtered", "unfiltered", "relaxed", "qp_failed", "invalid_state")

PathLike = Union[str, "os.PathLike[str]"]


@dataclass(frozen=True)
class VerifyResult:
    """A finished ``verify`` batch, shard or merge: its exit status, report and one row per
    run."""

    #: 0 when every run is safe, 3 when some run is unsafe (as the command's exit status).
    status: int
    #: The output directory (runs.csv, shard.json, timing.csv; a whole batch's also
    #: report.json and figures).
    out: Path
    #: ``report.json``: counts, quantiles and the worst runs with their replay commands.
    #: ``None`` for a shard (``shard="K/M"``, M > 1): the report needs every shard, and
    #: ``verify_merge`` of the shards' directories writes it.
    report: Optional[Dict[str, Any]]
    #: ``runs.csv`` by column: numbers as numpy arrays (int64/uint64 or float64), labels
    #: as lists of strings.
    runs: Dict[str, Any]

    @property
    def safe(self) -> bool:
        """Whether every run kept its lowest barrier above the threshold."""
        return self.status == 0


@dataclass(frozen=True)
class IdentifyResult:
    """A finished ``identify``: its exit status and the robot file it wrote."""

    #: The command's exit status (0: identified).
    status: int
    #: The identified robot file.
    out: Path
    #: The identified robot, loaded.
    robot: Robot


def _column(values: Sequence[str]) -> Any:
    """A CSV column as a numpy array when every entry is a number, else strings."""
    try:
        integers = [int(v) for v in values]
    except ValueError:
        integers = None
    if integers is not None:
        dtype = np.uint64 if integers and max(integers) >= 2**63 else np.int64
        return np.array(integers, dtype=dtype)
    try:
        return np.array([float(v) for v in values], dtype=np.float64)
    except ValueError:
        return list(values)


def _read_runs(path: Path) -> Dict[str, Any]:
    with open(path, newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    if not rows:
        return {}
    header, body = rows[0], rows[1:]
    return {name: _column([row[k] for row in body]) for k, name in enumerate(header)}


def verify(
    scenario: PathLike,
    out: PathLike = "verify",
    *,
    runs: Optional[int] = None,
    seed: Optional[int] = None,
    shard: Optional[str] = None,
    threads: Optional[int] = None,
    duration: Optional[float] = None,
) -> VerifyResult:
    """Runs ``softcbf verify``: the closed-loop runs a scenario's ``[verify]`` table
    declares, on every core (``threads``), with the GIL released.

    ``runs``, ``seed`` and ``duration`` replace the table's; ``shard="K/M"`` runs the K-th
    of M slices. Writes ``out`` as the command does and returns its report and rows. An
    unsafe run is a result (``status`` 3), not an exception; a bad file or argument raises
    ``ValueError`` naming the file, line and field or the argument.
    """
    args = ["--scenario", os.fspath(scenario), "--out", os.fspath(out)]
    for flag, value in (("--runs", runs), ("--seed", seed), ("--shard", shard),
                        ("--threads", threads), ("--duration", duration)):
        if value is not None:
            args += [flag, str(value)]
    return _verify_result(_run_verify(args), Path(out))


def verify_merge(shards: Sequence[PathLike], out: PathLike) -> VerifyResult:
    """Runs ``softcbf verify merge``: checks that the shard directories ``shards`` hold one
    batch's runs, each exactly once, and writes into ``out`` the ``runs.csv``,
    ``report.json`` and figures one process would have written (the same bytes). Returns
    the whole batch's result; shards that do not make one batch raise ``ValueError``."""
    if isinstance(shards, (str, os.PathLike)):
        raise TypeError("verify_merge takes a list of shard directories, not one path")
    args = ["merge", *(os.fspath(shard) for shard in shards), "--out", os.fspath(out)]
    return _verify_result(_run_verify(args), Path(out))


def _verify_result(status: int, out: Path) -> VerifyResult:
    """The result in ``out``: its report when ``shard.json`` says the directory holds the
    whole batch (a shard's directory may keep a report.json of an earlier batch)."""
    with open(out / "shard.json", encoding="utf-8") as handle:
        slices = json.load(handle)["shard"][1]
    report = None
    if slices == 1:
        with open(out / "report.json", encoding="utf-8") as handle:
            report = json.load(handle)
    return VerifyResult(status=status, out=out, report=report, runs=_read_runs(out / "runs.csv"))


def identify(
    robot: PathLike,
    logs: Sequence[PathLike],
    out: PathLike,
    *,
    figures: Optional[PathLike] = None,
    half_width: Optional[float] = None,
    timing_uncertainty_ms: Optional[float] = None,
) -> IdentifyResult:
    """Runs ``softcbf identify``: stiffness, damping and actuator gains of ``robot`` from
    the run directories ``logs`` (each with trajectory.csv and summary.json, or its
    ``run.mcap`` of ``softcbf run --mcap``), written to
    the robot file ``out`` with the figure beside it (or in ``figures``). The GIL is
    released while it fits."""
    status = _run_identify(
        os.fspath(robot),
        [os.fspath(log) for log in logs],
        os.fspath(out),
        figures=None if figures is None else os.fspath(figures),
        half_width=half_width,
        timing_uncertainty_ms=timing_uncertainty_ms,
    )
    return IdentifyResult(status=status, out=Path(out), robot=Robot.load(os.fspath(out)))
