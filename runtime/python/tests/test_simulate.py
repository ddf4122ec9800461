"""`simulate` against `softcbf simulate`'s files, scenario dicts, overrides and their
checks, and the GIL released while it runs."""

import csv
import json
import threading
import time

import numpy as np
import pytest

import softcbf
from conftest import run_cli


def read_csv(path):
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    return rows[0], np.array([[float(x) for x in row] for row in rows[1:]])


def same_bits(a, b):
    return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))


@pytest.mark.parametrize(
    "args, kwargs",
    [
        ([], {}),
        (["--safety", "certified", "--set-point", "0.05,0.01,-0.02,0,-0.04,-0.01",
          "--duration", "1", "--record-period", "0.0005", "--kp", "8", "--p", "12"],
         {"safety": "certified", "set_point": [0.05, 0.01, -0.02, 0, -0.04, -0.01],
          "duration": 1.0, "record_period": 0.0005, "kp": 8.0, "p": 12.0}),
    ],
)
def test_simulate_reproduces_the_command_line(args, kwargs, softcbf_bin, tmp_path):
    run_cli(softcbf_bin, "simulate", "--out", tmp_path, *args)
    header, table = read_csv(tmp_path / "trajectory.csv")
    result = softcbf.simulate(**kwargs)
    assert result.columns == header
    # t, then q, q̇, τ, τ_nom, then one column per barrier of the model's table, then the
    # tick's status and its reason.
    nq, nb = 6, len(result.barrier_labels)
    assert len(header) == 1 + 4 * nq + nb + 2
    assert header[-2:] == ["status", "reason"]
    assert same_bits(result.t, table[:, 0])
    assert same_bits(result.q, table[:, 1:1 + nq])
    assert same_bits(result.qd, table[:, 1 + nq:1 + 2 * nq])
    assert same_bits(result.tau, table[:, 1 + 2 * nq:1 + 3 * nq])
    assert same_bits(result.tau_nom, table[:, 1 + 3 * nq:1 + 4 * nq])
    assert same_bits(result.barriers, table[:, 1 + 4 * nq:1 + 4 * nq + nb])
    summary = json.loads((tmp_path / "summary.json").read_text())
    ours = result.summary
    for key in ["min_barrier", "final_q", "set_point", "counts", "max_abs_tau",
                "integrator_steps", "integrator_rhs_evals", "settings"]:
        theirs = summary["filter"][key] if "filter" in summary else summary[key]
        mine = ours[key]
        if isinstance(mine, np.ndarray):
            mine = mine.tolist()
        if key == "settings":
            theirs = {k: v for k, v in theirs.items() if k not in ("scenario", "software")}
            mine = {k: v for k, v in mine.items() if k not in ("scenario", "software")}
        assert json.loads(json.dumps(mine, default=lambda a: a.tolist())) == theirs, key


def test_the_paper_scenario_with_comparison():
    result = softcbf.simulate(compare=True, duration=2.0)
    assert result.comparison is not None
    assert result.summary["controller"] == "filter"
    assert result.comparison.summary["controller"] == "pd"
    # The filter keeps the barriers; plain PD+ drives one below zero (README, Fig. 4).
    assert result.barriers.min() > -1e-6
    assert result.comparison.barriers.min() < -1e-3
    assert result.coordinate_names == ["dx1", "dy1", "dL1", "dx2", "dy2", "dL2"]
    assert result.barrier_labels[0] == "module 1 corner 1"


def test_a_dict_scenario_equals_its_file(root, tmp_path):
    text = (root / "scenarios" / "paper-sim.toml").read_text()
    from_file = softcbf.simulate(root / "scenarios" / "paper-sim.toml", duration=0.5)
    tomllib = pytest.importorskip("tomllib")
    as_dict = tomllib.loads(text)
    # The file gives no [reference] (the robot file's set point runs); the dict gives the
    # same set point as a numpy array.
    assert "reference" not in as_dict
    as_dict["reference"] = {"set_point": np.array([0.08, 0.0, -0.05, 0.0, -0.06, -0.07])}
    from_dict = softcbf.simulate(as_dict, duration=0.5)
    assert same_bits(from_file.q, from_dict.q)
    assert same_bits(from_file.tau, from_dict.tau)


def test_write_gives_the_command_line_files(tmp_path):
    result = softcbf.simulate(duration=0.2, compare=True)
    written = [str(p) for p in result.write(tmp_path)]
    for name in ["trajectory.csv", "trajectory_pd.csv", "summary.json", "figure.png"]:
        assert str(tmp_path / name) in written
        assert (tmp_path / name).stat().st_size > 0
    header, table = read_csv(tmp_path / "trajectory.csv")
    assert same_bits(result.q, table[:, 1:7])


@pytest.mark.parametrize(
    "kwargs, error, text",
    [
        ({"duration": -1.0}, ValueError, "duration: must be"),
        ({"control_period": 5.0}, ValueError, "control_period"),
        ({"set_point": [0.0] * 5}, ValueError, "set_point: expected 6 values"),
        ({"set_point": [0, 0, np.nan, 0, 0, 0]}, ValueError, "set_point: entry 2 is NaN"),
        ({"set_point": [0, 0, -0.5, 0, 0, 0]}, ValueError, "set_point"),
        ({"safety": "bold"}, ValueError, "not a safety mode"),
        ({"p": 1.0, "p2": 2.0}, ValueError, "either p or p1/p2"),
        ({"robot": 3}, TypeError, "robot"),
        ({"plant": "/nonexistent/robot.toml"}, FileNotFoundError, "nonexistent"),
    ],
)
def test_bad_overrides_raise(kwargs, error, text):
    with pytest.raises(error) as caught:
        softcbf.simulate(**kwargs)
    assert text in str(caught.value)


def test_bad_scenarios_name_file_line_and_field(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("name = \"x\"\nduration = 1.0\ncontrol_period = -0.001\n")
    with pytest.raises(softcbf.DescriptionError) as caught:
        softcbf.simulate(bad)
    assert (caught.value.path, caught.value.line, caught.value.field) == (
        str(bad), 3, "control_period")
    assert f"{bad}:3: field `control_period`" in str(caught.value)

    # A type error and an unknown field name their field in `field` too, not only in the
    # message.
    with pytest.raises(softcbf.DescriptionError) as caught:
        softcbf.simulate({"duration": "long"})
    assert caught.value.path == "<scenario dict>"
    assert (caught.value.line, caught.value.field) == (1, "duration")
    with pytest.raises(softcbf.DescriptionError, match="unknown field `durration`") as caught:
        softcbf.simulate({"durration": 1.0})
    assert caught.value.field == "durration"
    robot_file = tmp_path / "robot.toml"
    robot_file.write_text("[[module]]\nmass = 0.1\n\n[[module]]\nmass = \"heavy\"\n")
    with pytest.raises(softcbf.DescriptionError) as caught:
        softcbf.Robot.load(robot_file)
    assert (caught.value.line, caught.value.field) == (5, "module[2].mass"), str(caught.value)
    robot_file.write_text("[[module]]\nmass = 0.1\nmas = 1\n")
    with pytest.raises(softcbf.DescriptionError) as caught:
        softcbf.Robot.load(robot_file)
    assert (caught.value.line, caught.value.field) == (3, "module[1].mas"), str(caught.value)
    robot_file.write_text("modules = 2\ngravity = [0, 0 -9.81]\n")
    with pytest.raises(softcbf.DescriptionError) as caught:
        softcbf.Robot.load(robot_file)
    assert caught.value.field == "gravity", str(caught.value)
    with pytest.raises(TypeError, match=r'scenario\["initial"\]'):
        softcbf.simulate({"initial": object()})
    with pytest.raises(FileNotFoundError):
        softcbf.simulate(tmp_path / "missing.toml")
    with pytest.raises(TypeError, match="scenario"):
        softcbf.simulate(42)


def test_the_gil_is_released_while_simulating():
    # A Python thread keeps counting while another simulates: it could not if the
    # simulation held the GIL.
    counts = []
    done = threading.Event()

    def count():
        n = 0
        while not done.is_set():
            n += 1
            time.sleep(0)
        counts.append(n)

    counter = threading.Thread(target=count)
    counter.start()
    start = time.perf_counter()
    before = threading.active_count()
    softcbf.simulate(safety="certified", duration=2.0)
    elapsed = time.perf_counter() - start
    done.set()
    counter.join()
    assert before == 2
    # About 0.25 s of simulation: a held GIL would allow only the switch interval's
    # handful of iterations (the interpreter forces a switch every 5 ms at most).
    assert elapsed > 0.05
    assert counts[0] > 1000
