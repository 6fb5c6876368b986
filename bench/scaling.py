"""Benchmark of the scaling layer's control cycle (not a test: it prints figures).

One cycle = ScalingLayer.step: trajectory sampling, PRBT kinematics and point Jacobians, every robot
link x human capsule distance and SSM row, the LP (piqp, or the closed form, after the exact presolve),
and the verification of the command. Random but seeded states: a point on the paper's shuttle, a
previous path speed, and human capsules placed around the robot so that the safety rows are active (a
random previous speed makes an acceleration row bind in most cases, so the solver runs more often than
in a run, where 70-80 % of the cycles are presolved; the share is printed). The last line is one JSON object.

    python bench/scaling.py [--cycles N]
"""

from __future__ import annotations

import argparse
import gc
import json
import time

import numpy as np

from evidence.scenarios import Q_GOAL, Q_START
from shared.core.humans import HumanCapsules
from shared.core.trajectory import straight_line_trajectory
from shared.robot.model import default_robot
from shared.safety.parameters import SsmParameters
from shared.scaling.layer import ScalingInputs, ScalingLayer
from shared.scaling.parameters import ScalingParameters


def random_humans(rng: np.random.Generator, m: int) -> HumanCapsules:
    """m capsules around the robot: centres 0.8 to 2.5 m from the base axis, 0.2 to 1.6 m high, moving
    at up to about 1 m/s, 5 % untracked (which then count at the ISO 13855 speed)."""
    radius, angle = rng.uniform(0.8, 2.5, m), rng.uniform(0, 2 * np.pi, m)
    centre = np.stack([radius * np.cos(angle), radius * np.sin(angle), rng.uniform(0.2, 1.6, m)], axis=1)[:, None, :]
    return HumanCapsules.from_arrays(centre + rng.normal(scale=0.15, size=(m, 2, 3)), rng.uniform(0.04, 0.15, m),
                                     rng.normal(scale=0.5, size=(m, 2, 3)), rng.random(m) < 0.95)


def measure(solver: str, capsules: int, cycles: int, seed: int) -> dict:
    robot = default_robot()
    layer = ScalingLayer(robot, SsmParameters(), ScalingParameters(solver=solver))
    traj = straight_line_trajectory(Q_START, Q_GOAL, robot.limits.velocity, robot.limits.acceleration)
    layer.set_trajectory(traj)
    rng = np.random.default_rng(seed)
    cases = [(random_humans(rng, capsules), float(rng.uniform(0, traj.duration * 0.95)), float(rng.uniform(0, 1)))
             for _ in range(64)]
    times = np.empty(cycles)
    alphas = np.empty(cycles)
    presolved = 0
    for k in range(cycles + 200):                 # the first 200 warm caches and JIT
        humans, s, sdot = cases[k % len(cases)]
        layer.s, layer.sdot = s, sdot
        t0 = time.perf_counter_ns()
        step = layer.step(ScalingInputs(humans=humans))
        t1 = time.perf_counter_ns()
        if k >= 200:
            times[k - 200] = (t1 - t0) / 1e3
            alphas[k - 200] = step.alpha
            presolved += step.method.startswith("presolved")
    p50, p99 = float(np.percentile(times, 50)), float(np.percentile(times, 99))
    return {"human_capsules": capsules, "p50_us": round(p50, 1), "p99_us": round(p99, 1),
            "p99_fraction_of_1khz": round(p99 / 1000.0, 3), "mean_alpha": round(float(alphas.mean()), 3),
            "presolved_fraction": round(presolved / cycles, 3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cycles", type=int, default=5000)
    args = parser.parse_args()
    gc.disable()                                  # measure the computation, not the collector
    result = {"bench": "scaling", "cases": [], "closed_form": []}
    for solver, key in (("piqp", "cases"), ("closed_form", "closed_form")):
        for m in (2, 10, 50):
            row = measure(solver, m, args.cycles, seed=m)
            result[key].append(row)
            print(f"{solver:12s} {m:3d} human capsules: p50 {row['p50_us']:7.1f} us  p99 {row['p99_us']:7.1f} us"
                  f"  ({100 * row['p99_fraction_of_1khz']:.1f}% of a 1 kHz period)  mean alpha {row['mean_alpha']}"
                  f"  presolved {100 * row['presolved_fraction']:.0f}%")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
