"""Benchmark of the planning layer (not a test: it prints figures).

Seeded random humans around the paper's experiment: a person stands 0.75 to 1.2 m from the robot on the
side the shuttle sweeps, leans in and reaches a forearm across the flange's arc at a random point and height.
For each placement:
* plan: RRT-Connect + simplification + time parameterisation from q_s to q_g around the person;
* replan + merge: the robot runs the straight shuttle; at the moment the horizon check (1 s ahead) first
  sees the person, Alg. 1 + 2 build the merged trajectory.
Reported: median / p95 wall time of each, the success rate (a placement that leaves no feasible goal or
start counts as neither success nor failure), and configuration checks per second. Last line: JSON.

    python bench/planning.py [--placements N]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from shared.collision import CollisionModel
from shared.humans import HumanCapsules
from shared.planner import JointPlanner, PlannerOptions, PlanningError
from shared.replanning import HorizonOptions, ReplanFailed, Replanner, horizon_check
from shared.robot_model import default_robot
from shared.scenarios import Q_GOAL, Q_START, body_segments
from shared.scene import load_scene
from shared.ssm import SsmParameters
from shared.timing import TimingError, parameterize
from shared.trajectory import straight_line_trajectory


def placement(rng: np.random.Generator) -> HumanCapsules:
    angle = rng.uniform(np.pi * 0.6, np.pi * 1.4)             # the -x half the shuttle sweeps
    dist = rng.uniform(0.75, 1.2)
    arc = rng.uniform(np.pi * 0.6, np.pi * 1.4)
    target = np.array([0.44 * np.cos(arc), 0.44 * np.sin(arc), rng.uniform(0.45, 0.75)])
    seg, radii = body_segments(dist * np.cos(angle), dist * np.sin(angle), rng.uniform(0.7, 1.0), target,
                               lean=rng.uniform(0.5, 1.0))
    return HumanCapsules.from_arrays(seg, radii, np.zeros_like(seg), np.ones(len(radii), bool))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--placements", type=int, default=60)
    parser.add_argument("--seed", type=int, default=2026)
    args = parser.parse_args()
    robot = default_robot()
    collision = CollisionModel(robot, load_scene("deploy/scene.yaml"))
    planner = JointPlanner(collision, PlannerOptions(seed=args.seed, time_budget=1.0))
    replanner = Replanner(collision, planner, SsmParameters())
    old = straight_line_trajectory(Q_START, Q_GOAL, robot.limits.velocity, robot.limits.acceleration)
    rng = np.random.default_rng(args.seed)
    plan_ms, replan_ms, tried, ok = [], [], 0, 0
    checks, check_time = 0, 0.0
    parameterize(np.vstack([Q_START, Q_GOAL]), robot.limits)         # warm the JIT and toppra
    for _ in range(args.placements):
        humans = placement(rng)
        if not (collision.feasible(Q_START, humans) and collision.feasible(Q_GOAL, humans)):
            continue
        tried += 2
        before = collision.checks
        t0 = time.perf_counter()
        try:
            parameterize(planner.plan(Q_START, Q_GOAL, humans), robot.limits, collision=collision, humans=humans)
            plan_ms.append((time.perf_counter() - t0) * 1e3)
            ok += 1
        except (PlanningError, TimingError):
            pass
        checks += collision.checks - before
        check_time += time.perf_counter() - t0
        # replan: the first s at which a 1 s horizon sees the person
        full = horizon_check(old, 0.0, collision, humans, HorizonOptions(samples=200, spacing=0.02))
        if full.first_infeasible is None:
            tried -= 1                                               # nothing in the way: no replan needed
            continue
        s_seen = max(0.0, float(full.s[full.first_infeasible]) - 1.0)
        t0 = time.perf_counter()
        try:
            result = replanner.on_horizon(old, s_seen, Q_GOAL, humans)
            if result is not None:
                replan_ms.append((time.perf_counter() - t0) * 1e3)
                ok += 1
        except ReplanFailed:
            pass
    stats = lambda xs: {"median": round(float(np.median(xs)), 1), "p95": round(float(np.percentile(xs, 95)), 1)} \
        if xs else {"median": None, "p95": None}
    result = {"bench": "planning", "plan_ms": stats(plan_ms), "replan_ms": stats(replan_ms),
              "success_rate": round(ok / tried, 3) if tried else None,
              "checks_per_s": round(checks / check_time) if check_time else None,
              "cases": {"plans": len(plan_ms), "replans": len(replan_ms), "attempts": tried}}
    print(f"plan:          median {result['plan_ms']['median']} ms, p95 {result['plan_ms']['p95']} ms "
          f"({len(plan_ms)} plans)")
    print(f"replan+merge:  median {result['replan_ms']['median']} ms, p95 {result['replan_ms']['p95']} ms "
          f"({len(replan_ms)} replans)")
    print(f"success rate {result['success_rate']}  ({ok} of {tried}); {result['checks_per_s']} configuration checks/s")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
