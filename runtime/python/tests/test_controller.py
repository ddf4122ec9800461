"""`Controller.tick` against the Rust tick inside the simulator, statuses, and bad inputs."""

import numpy as np
import pytest

import softcbf

SET_POINT = np.array([0.08, 0.0, -0.05, 0.0, -0.06, -0.07])  # the paper's, beyond contact


@pytest.mark.parametrize("safety", ["paper", "certified", "hold-correction", "predicted"])
def test_tick_reproduces_the_simulator_bit_for_bit(safety):
    # The simulator ticks the Rust controller on the plant's state and records both; fed
    # the recorded states in order, a controller built from Python gives the same commands.
    run = softcbf.simulate(safety=safety, duration=0.6)
    robot = softcbf.Robot.paper_sim()
    controller = softcbf.Controller(robot, safety=safety, control_period=0.001)
    statuses = set()
    filtered_rows = 0
    for q, qd, tau in zip(run.q[:-1], run.qd[:-1], run.tau[:-1]):
        ours, status = controller.tick(q, qd, SET_POINT)
        statuses.add(status)
        assert np.array_equal(ours.view(np.uint64), tau.view(np.uint64))
        filtered_rows += not np.array_equal(controller.tau_nom, ours)
    assert statuses == {"filtered"}
    # The filter acted on this run (the set point lies beyond plate contact).
    assert filtered_rows > 10


def test_statuses_and_the_safe_command():
    robot = softcbf.Robot.paper_sim()
    controller = softcbf.Controller(robot, safety="paper")
    zero = np.zeros(6)
    tau, status = controller.tick(zero, zero, SET_POINT)
    assert status == "filtered" and status in softcbf.STATUSES
    assert controller.invalid_reason is None
    assert np.all(np.isfinite(tau)) and np.any(tau != 0)

    for bad_q, reason in [(np.full(6, np.nan), "non_finite"),
                          (np.array([0, 0, np.inf, 0, 0, 0.0]), "non_finite"),
                          (np.array([0, 0, -0.5, 0, 0, 0.0]), "out_of_domain")]:
        tau, status = controller.tick(bad_q, zero, SET_POINT)
        assert status == "invalid_state"
        assert controller.invalid_reason == reason
        assert np.array_equal(tau, zero)
    tau, status = controller.tick(zero, zero, np.full(6, np.nan))
    assert status == "invalid_state" and np.array_equal(tau, zero)

    plain = softcbf.Controller(robot, filter=False)
    tau, status = plain.tick(zero, zero, SET_POINT)
    assert status == "unfiltered"
    assert np.array_equal(tau, plain.tau_nom)


def test_out_receives_tau():
    controller = softcbf.Controller(softcbf.Robot.paper_sim(), safety="paper")
    zero = np.zeros(6)
    out = np.empty(6)
    tau, _ = controller.tick(zero, zero, SET_POINT, out=out)
    assert tau is out
    # A fresh controller at the same state (a second tick of this one would start its QP
    # from the first one's active set, which may round differently).
    fresh = softcbf.Controller(softcbf.Robot.paper_sim(), safety="paper")
    again, _ = fresh.tick(zero, zero, SET_POINT)
    assert np.array_equal(out, again)
    with pytest.raises(ValueError, match="out: expected 6"):
        controller.tick(zero, zero, SET_POINT, out=np.empty(5))
    with pytest.raises(ValueError, match="contiguous"):
        controller.tick(zero, zero, SET_POINT, out=np.empty(12)[::2])


def test_gains_default_to_the_robot_file_and_are_checked():
    robot = softcbf.Robot.paper_sim()
    assert softcbf.Controller(robot).safety == "certified"
    assert softcbf.Controller(robot, control_period=0.03).control_period == 0.03
    for kwargs, text in [({"kp": -1.0}, "kp: must be"),
                         ({"kd": float("nan")}, "kd: must be"),
                         ({"p": 2.0, "p1": 3.0}, "give either p or p1/p2"),
                         ({"control_period": 0.0}, "control_period: must be"),
                         ({"safety": "careful"}, "safety: `careful` is not a safety mode")]:
        with pytest.raises(ValueError, match=text.replace("(", r"\(")):
            softcbf.Controller(robot, **kwargs)
    with pytest.raises(TypeError):
        softcbf.Controller("robots/paper-sim.toml")


@pytest.mark.parametrize(
    "argument, value, error",
    [
        ("q", np.zeros(7), ValueError),
        ("qd", np.zeros((2, 3)), ValueError),
        ("set_point", np.zeros(6, dtype=np.int32), TypeError),
        ("q", "zeros", TypeError),
        ("qd", {"a": 1}, TypeError),
    ],
)
def test_wrong_shapes_and_dtypes_raise(argument, value, error):
    controller = softcbf.Controller(softcbf.Robot.paper_sim(), safety="paper")
    args = {"q": np.zeros(6), "qd": np.zeros(6), "set_point": SET_POINT}
    args[argument] = value
    with pytest.raises(error, match=argument):
        controller.tick(**args)


def test_a_set_point_outside_the_domain_is_refused():
    # A finite set point the model cannot describe (module 1 compressed past zero length) is
    # refused, as the command line refuses it, rather than filtered toward.
    controller = softcbf.Controller(softcbf.Robot.paper_sim())
    zero = np.zeros(6)
    with pytest.raises(ValueError, match="set_point: outside the model's domain"):
        controller.tick(zero, zero, np.array([0, 0, -0.5, 0, 0, 0.0]))
