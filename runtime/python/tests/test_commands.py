"""`verify` and `identify` from Python: the command's outputs, byte for byte, and its
errors as exceptions; a robot this build has no model for."""

import numpy as np
import pytest

import softcbf
from conftest import run_cli


def test_verify_writes_what_the_command_writes(root, softcbf_bin, tmp_path):
    scenario = root / "scenarios" / "verify-paper.toml"
    args = dict(runs=8, seed=7, duration=0.2)
    result = softcbf.verify(scenario, tmp_path / "py", threads=2, **args)
    cli = run_cli(softcbf_bin, "verify", "--scenario", scenario, "--out", tmp_path / "cli",
                  "--runs", 8, "--seed", 7, "--duration", 0.2, "--threads", 1, check=False)
    assert cli.returncode == result.status
    for name in ["runs.csv", "report.json"]:
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes()
    assert result.status in (0, 3) and result.safe == (result.status == 0)
    runs = result.runs
    assert runs["run"].tolist() == list(range(8))
    assert runs["seed"].dtype in (np.int64, np.uint64)
    assert runs["lowest_barrier [m]"].dtype == np.float64
    assert isinstance(runs["safety"], list) and set(runs["safety"]) <= {"paper", "sampled"}
    assert result.report["runs"] == 8


def test_verify_errors_are_exceptions(root, tmp_path):
    with pytest.raises(ValueError, match="--runs"):
        softcbf.verify(root / "scenarios" / "verify-paper.toml", tmp_path, runs=0)
    with pytest.raises(ValueError, match="--shard"):
        softcbf.verify(root / "scenarios" / "verify-paper.toml", tmp_path, shard="3/2")
    bad = tmp_path / "bad.toml"
    bad.write_text("duration = 0.1\n\n[verify]\nruns = 10\nthreshold = 5.0\n")
    with pytest.raises(ValueError, match=f"{bad}:5: field `verify.threshold`"):
        softcbf.verify(bad, tmp_path / "out")


def test_identify_errors_are_exceptions(root, tmp_path):
    with pytest.raises(ValueError, match="missing-run"):
        softcbf.identify(root / "robots" / "hardware-example.toml", [tmp_path / "missing-run"],
                         tmp_path / "identified.toml")
    with pytest.raises(ValueError, match="timing"):
        softcbf.identify(root / "robots" / "hardware-example.toml", [tmp_path],
                         tmp_path / "identified.toml", timing_uncertainty_ms=-1.0)


def test_a_robot_without_a_generated_model_says_how_to_build_one(root, tmp_path):
    # The paper's robot with a third module: a structure no build has.
    text = (root / "robots" / "paper-sim.toml").read_text()
    first = text.index("[[module]]")
    end = text.find("[[module]]", first + 1)
    module = text[first:end]
    robot_file = tmp_path / "three modules.toml"
    robot_file.write_text(text[:end] + module + text[end:])
    robot = softcbf.Robot.load(robot_file)
    assert robot.modules == 3 and robot.nq == 9
    with pytest.raises(softcbf.NoGeneratedModelError) as caught:
        robot.model()
    message = str(caught.value)
    assert "SOFTCBF_ROBOTS=" in message and "pip install --force-reinstall" in message
    assert "'" + str(robot_file) + "'" in message  # quoted: the name has a space
    assert "paper_sim" in message
    with pytest.raises(softcbf.NoGeneratedModelError):
        softcbf.Controller(robot)
    with pytest.raises(softcbf.NoGeneratedModelError):
        softcbf.simulate(robot=robot)
