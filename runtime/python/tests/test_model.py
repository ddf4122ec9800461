"""`Model.evaluate` against `softcbf model`'s JSON, to the last bit, at random states."""

import json

import numpy as np
import pytest

import softcbf
from conftest import run_cli

ROBOTS = ["paper-sim.toml", "three-square.toml", "paper-sim-obstacle.toml", "paper-sim-limits.toml"]


def compare(ours, theirs, where="model"):
    """Exact equality of a Python value (numpy arrays inside) with parsed JSON."""
    if isinstance(theirs, dict):
        assert isinstance(ours, dict), where
        assert sorted(ours) == sorted(theirs), where
        for key in theirs:
            compare(ours[key], theirs[key], f"{where}.{key}")
    elif isinstance(ours, np.ndarray):
        expected = np.asarray(theirs, dtype=np.float64)
        assert ours.dtype == np.float64, where
        assert ours.shape == expected.shape, where
        # Bit for bit: the same doubles, NaN nowhere.
        assert np.array_equal(ours.view(np.uint64), expected.view(np.uint64)), where
    elif isinstance(theirs, list):
        assert isinstance(ours, list) and len(ours) == len(theirs), where
        for k, (a, b) in enumerate(zip(ours, theirs)):
            compare(a, b, f"{where}[{k}]")
    else:
        assert ours == theirs and type(ours) is type(theirs), (where, ours, theirs)


@pytest.mark.parametrize("name", ROBOTS)
def test_evaluate_agrees_with_the_command_line_bit_for_bit(name, root, softcbf_bin):
    path = root / "robots" / name
    model = softcbf.Robot.load(path).model()
    rng = np.random.default_rng(20261124)
    for _ in range(4):
        # Bends up to 3 cm, elongations from -2 to +1 cm, speeds up to 0.2 m/s.
        q = np.concatenate([[rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03),
                             rng.uniform(-0.02, 0.01)] for _ in range(model.nq // 3)])
        qd = rng.uniform(-0.2, 0.2, model.nq)
        printed = run_cli(softcbf_bin, "model", "--robot", path,
                          "--q", ",".join(repr(float(x)) for x in q),
                          "--qd", ",".join(repr(float(x)) for x in qd)).stdout
        compare(model.evaluate(q, qd), json.loads(printed))


def test_evaluate_has_the_documented_shapes():
    model = softcbf.Robot.paper_sim().model()
    values = model.evaluate(np.zeros(6), [0.0] * 6)
    assert values["mass_matrix"].shape == (6, 6)
    assert values["barrier_jacobian"].shape == (model.nb, 6)
    assert values["plate_poses"].shape == (2, 4, 4)
    assert values["barriers"].shape == (model.nb,)
    assert len(model.barrier_labels) == model.nb
    # M is symmetric positive definite at the straight configuration.
    mass = values["mass_matrix"]
    assert np.allclose(mass, mass.T, rtol=0, atol=1e-15)
    assert np.all(np.linalg.eigvalsh(mass) > 0)


@pytest.mark.parametrize(
    "q, error, text",
    [
        (np.zeros(5), ValueError, "expected shape (6,)"),
        (np.zeros((6, 1)), ValueError, "expected shape (6,)"),
        (np.zeros(6, dtype=np.int64), TypeError, "float64"),
        (np.zeros(6, dtype=np.float32), TypeError, "float64"),
        ([0.0] * 5, ValueError, "expected 6 values"),
        ("000000", TypeError, "string"),
        ([0, 0, "x", 0, 0, 0], TypeError, "sequence of 6 numbers"),
        (None, TypeError, "sequence of 6 numbers"),
        (np.array([0, 0, np.nan, 0, 0, 0]), ValueError, "entry 2 is NaN"),
        (np.array([0, 0, -0.2, 0, 0, 0]), ValueError, "q: "),
        (np.array([7.0, 0, 0, 0, 0, 0]), ValueError, "q: "),
    ],
)
def test_bad_states_raise_clear_errors(q, error, text):
    model = softcbf.Robot.paper_sim().model()
    with pytest.raises(error) as caught:
        model.evaluate(q, np.zeros(6))
    assert text.lower() in str(caught.value).lower()


def test_a_strided_array_is_read_correctly():
    model = softcbf.Robot.paper_sim().model()
    wide = np.zeros(12)
    wide[::2] = [0.01, 0.0, -0.01, 0.0, 0.02, 0.0]
    strided = wide[::2]
    assert not strided.flags["C_CONTIGUOUS"]
    a = model.evaluate(strided, np.zeros(6))["barriers"]
    b = model.evaluate(np.ascontiguousarray(strided), np.zeros(6))["barriers"]
    assert np.array_equal(a, b)
