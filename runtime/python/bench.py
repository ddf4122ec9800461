"""Timing of the package from Python (a benchmark, not a test): `Controller.tick`,
`Model.evaluate` and the paper scenario through `simulate`. Prints medians with the
spread (25th-75th percentile) over repeated batches.

    python runtime/python/bench.py [--quick]
"""

import argparse
import statistics
import time

import numpy as np

import softcbf


def batches(call, per_batch, count):
    """Seconds per call of `call`, one figure per batch of `per_batch` calls."""
    figures = []
    for _ in range(count):
        start = time.perf_counter()
        for _ in range(per_batch):
            call()
        figures.append((time.perf_counter() - start) / per_batch)
    return figures


def show(name, figures, unit=1e-6, unit_name="µs"):
    q = statistics.quantiles(figures, n=4)
    print(f"{name:<44} median {statistics.median(figures) / unit:9.2f} {unit_name}"
          f"  [{q[0] / unit:.2f}, {q[2] / unit:.2f}]")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repetitions")
    args = parser.parse_args()
    count = 5 if args.quick else 15

    robot = softcbf.Robot.paper_sim()
    model = robot.model()
    set_point = np.array([0.08, 0.0, -0.05, 0.0, -0.06, -0.07])
    print(f"softcbf {softcbf.__version__}, numpy {np.__version__}")

    # Each safety mode's tick replays the states of its own run of the paper scenario, in
    # order, as a control loop would see them (the first second: the filter acts from
    # 0 s with the paper's rows, with the certified rows).
    out = np.empty(6)
    for safety in ["paper", "certified"]:
        run = softcbf.simulate(safety=safety, duration=1.0)
        rows = [(q.copy(), qd.copy()) for q, qd in zip(run.q[:-1], run.qd[:-1])]

        def replay(use_out):
            controller = softcbf.Controller(robot, safety=safety)
            start = time.perf_counter()
            if use_out:
                for q, qd in rows:
                    controller.tick(q, qd, set_point, out=out)
            else:
                for q, qd in rows:
                    controller.tick(q, qd, set_point)
            return (time.perf_counter() - start) / len(rows)

        show(f"tick ({safety}), per tick over 1 s of its run", [replay(False) for _ in range(count)])
        show(f"tick ({safety}, out=), per tick", [replay(True) for _ in range(count)])
    q, qd = run.q[50].copy(), run.qd[50].copy()
    show("evaluate (every quantity, as dict)", batches(lambda: model.evaluate(q, qd), 300, count))
    # The filtered run alone, as `cargo bench --bench control` times it (the scenario
    # file also asks for the PD+ comparison).
    show("simulate: paper scenario, 10 s at 1 kHz",
         batches(lambda: softcbf.simulate(compare=False), 1, count), 1e-3, "ms")
    show("simulate: the same with certified rows",
         batches(lambda: softcbf.simulate(safety="certified", compare=False), 1,
                 max(3, count // 3)), 1e-3, "ms")


if __name__ == "__main__":
    main()
