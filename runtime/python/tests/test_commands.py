"""`verify` and `identify` from Python: the command's outputs, byte for byte, and its
errors as exceptions; a robot this build has no compiled model for, run interpreted."""

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
    assert isinstance(runs["safety"], list) and set(runs["safety"]) <= {"paper", "certified"}
    assert result.report["runs"] == 8


def test_shards_and_their_merge_are_the_batch(root, softcbf_bin, tmp_path):
    scenario = root / "scenarios" / "verify-paper.toml"
    args = dict(runs=6, seed=3, duration=0.2)
    shards = [softcbf.verify(scenario, tmp_path / f"shard {k}", shard=f"{k}/2", threads=1, **args)
              for k in range(2)]
    # A shard has rows, no report: the report needs every shard.
    assert [shard.report for shard in shards] == [None, None]
    assert [shard.runs["run"].tolist() for shard in shards] == [[0, 1, 2], [3, 4, 5]]
    assert all(shard.status in (0, 3) for shard in shards)

    merged = softcbf.verify_merge([shard.out for shard in reversed(shards)], tmp_path / "merged")
    cli = run_cli(softcbf_bin, "verify", "--scenario", scenario, "--out", tmp_path / "cli",
                  "--runs", 6, "--seed", 3, "--duration", 0.2, check=False)
    assert merged.status == cli.returncode
    for name in ["runs.csv", "report.json"]:
        assert (tmp_path / "merged" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes()
    assert merged.report["runs"] == 6 and merged.runs["run"].tolist() == list(range(6))

    with pytest.raises(ValueError, match="run"):  # one shard of two is not the batch
        softcbf.verify_merge([shards[0].out], tmp_path / "half")
    with pytest.raises(TypeError, match="list of shard directories"):
        softcbf.verify_merge(tmp_path / "shard 0", tmp_path / "half")


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


def absent_structure(root, tmp_path):
    """The paper's robot with as many modules as make a structure this build of the package
    has no compiled model for: 3, unless the build has that one (a user may register any
    robot, `softcbf-codegen add`), then 5, 6, … Returns the file and its module count."""
    # Without the paper's set point, which has entries for two modules (comments are left).
    text = "".join("#" + line if line.startswith("set_point") else line
                   for line in (root / "robots" / "paper-sim.toml").read_text()
                   .splitlines(keepends=True))
    first = text.index("[[module]]")
    end = text.find("[[module]]", first + 1)
    module = text[first:end]
    robot_file = tmp_path / "more modules.toml"
    for modules in range(3, 64):
        robot_file.write_text(text[:end] + module * (modules - 2) + text[end:])
        try:
            softcbf.Robot.load(robot_file).model(interpreted=False)
        except softcbf.NoGeneratedModelError:
            return robot_file, modules
    pytest.fail("this build has a compiled model for every paper robot of 3 to 63 modules")


def interpreted_warning(caught, robot_file):
    """The one warning of a call that built the interpreted model: what, what it costs, how
    to build compiled code."""
    warnings = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    assert len(warnings) == 1, [str(w.message) for w in warnings]
    message = str(warnings[0].message)
    assert "interpreted at run time" in message and "times slower" in message
    assert "SOFTCBF_ROBOTS=" in message and "pip install --force-reinstall" in message
    assert "'" + str(robot_file) + "'" in message  # quoted: the name has a space
    assert "paper_sim" in message
    return message


def test_a_robot_without_a_generated_model_runs_interpreted_and_says_how_to_build_one(
        root, tmp_path):
    robot_file, modules = absent_structure(root, tmp_path)
    robot = softcbf.Robot.load(robot_file)
    nq = 3 * modules
    assert robot.modules == modules and robot.nq == nq

    with pytest.warns(RuntimeWarning) as caught:
        model = robot.model()
    interpreted_warning(caught, robot_file)
    assert model.interpreted and model.generated_model == "interpreted"
    # Six corners and three limits (the domain's defaults) per module, as the table lists.
    labels = model.barrier_labels
    assert model.nq == nq and model.nb == len(labels) == modules * (6 + 3)
    assert [l for l in labels if l.startswith(f"module {modules} ")][6:] == [
        f"module {modules} elongation min", f"module {modules} elongation max",
        f"module {modules} bend"]
    # The barrier Jacobian against central differences of the barriers.
    q = np.resize([0.004, -0.002, 0.001, -0.003, 0.001, -0.002, 0.002, 0.003, 0.0], nq)
    qd = np.resize([0.01, -0.02, 0.005, 0.0, 0.01, -0.01, 0.02, 0.0, 0.01], nq)
    values = model.evaluate(q, qd)
    jacobian = values["barrier_jacobian"]
    assert jacobian.shape == (model.nb, nq) and np.all(np.isfinite(values["mass_matrix"]))
    h = 1e-6
    for k in range(nq):
        step = np.zeros(nq)
        step[k] = h
        difference = (model.evaluate(q + step, qd)["barriers"]
                      - model.evaluate(q - step, qd)["barriers"]) / (2 * h)
        np.testing.assert_allclose(jacobian[:, k], difference, rtol=1e-6, atol=1e-8)

    # Compiled code demanded: the exception with the command that builds it.
    with pytest.raises(softcbf.NoGeneratedModelError) as refused:
        robot.model(interpreted=False)
    message = str(refused.value)
    assert "SOFTCBF_ROBOTS=" in message and "pip install --force-reinstall" in message
    assert "'" + str(robot_file) + "'" in message

    with pytest.warns(RuntimeWarning) as caught:
        controller = softcbf.Controller(robot, safety="paper")
    interpreted_warning(caught, robot_file)
    tau, status = controller.tick(q, qd, np.zeros(nq))
    assert tau.shape == (nq,) and np.all(np.isfinite(tau)) and status in softcbf.STATUSES

    with pytest.warns(RuntimeWarning) as caught:
        run = softcbf.simulate({"duration": 0.05, "safety": "paper",
                                "initial": {"q": [0.0] * nq, "qd": [0.0] * nq},
                                "reference": {"set_point": [0.02, 0.0, -0.01] * modules}},
                               robot=robot)
    interpreted_warning(caught, robot_file)
    assert run.q.shape[1] == nq and run.t[-1] == pytest.approx(0.05)
    assert np.all(np.isfinite(run.q)) and np.all(np.isfinite(run.barriers))
