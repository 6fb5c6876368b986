"""Benchmark of the planning layer (not a test: it prints figures).

Seeded random humans around the paper's experiment: a person stands 0.75 to 1.2 m from the robot on the
side the shuttle sweeps, leans in and reaches a forearm across the flange's arc at a random point and height.
For each placement:
* a new goal, side by side: RRT-Connect + simplification + TOPP-RA (a collision-free path, clearance only)
  against the planning layer's search (the path fastest under the SSM, shared.planning.path_search), each
  predicted by the SSM-aware time cost with the person staying --stay seconds, and the straight line;
* replan + merge: the robot runs the straight shuttle; at the moment the horizon check (1 s ahead) first
  sees the person, Alg. 1 + 2 and the keep-or-replace decision (taken, old kept, failed);
* time laws: the compiled TOPP-RA (shared.planning.topp) against toppra's own on each RRT-Connect detour;
* the cell's budget against the counts: the same search (same seed) bounded as the planner service bounds
  it (CELL_BUDGET per search inside ACTION_BUDGET per action, wall clock) and by its counts alone, as the
  simulation runs it: how many of the count-bounded search's candidates the budget costed, and the
  predicted times of both winners (a ratio above 1: the cell plans worse paths than the simulation's
  evidence assumes). Run it beside a CPU-bound process too: the cell shares two cores with six processes.
Reported: median / p95 wall time of each, the predicted times and their ratios. Last line: JSON.

    python bench/planning.py [--placements N]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from evidence.scenarios import Q_GOAL, Q_START, body_segments
from shared.core.humans import HumanCapsules
from shared.core.trajectory import straight_line_trajectory
from shared.planning.collision import CollisionModel
from shared.planning.decision import ReplanFailed
from shared.planning.horizon import HorizonOptions, horizon_check
from shared.planning.ompl_planner import JointPlanner, PlannerOptions, PlanningError
from shared.planning.path_search import ACTION_BUDGET, CELL_BUDGET, SearchOptions
from shared.planning.replanner import Replanner, ReplanOptions
from shared.planning.scene import DEFAULT_SCENE, load_scene
from shared.planning.timing import ACCELERATION_HEADROOM, TimingError, chord_points, chord_spline, parameterize
from shared.planning.topp import fastest_law, toppra_law
from shared.robot.model import default_robot
from shared.safety.parameters import SsmParameters


def placement(rng: np.random.Generator) -> HumanCapsules:
    angle = rng.uniform(np.pi * 0.6, np.pi * 1.4)             # the -x half the shuttle sweeps
    dist = rng.uniform(0.75, 1.2)
    arc = rng.uniform(np.pi * 0.6, np.pi * 1.4)
    target = np.array([0.44 * np.cos(arc), 0.44 * np.sin(arc), rng.uniform(0.45, 0.75)])
    seg, radii = body_segments(dist * np.cos(angle), dist * np.sin(angle), rng.uniform(0.7, 1.0), target,
                               lean=rng.uniform(0.5, 1.0))
    return HumanCapsules.from_arrays(seg, radii, np.zeros_like(seg), np.ones(len(radii), bool))


def time_laws(waypoints: np.ndarray, limits) -> tuple[float, float, float]:
    """The same time law along the waypoints' spline, compiled (the product's) and toppra's own: (compiled
    ms, toppra ms, relative difference of their durations)."""
    pts, chord = chord_points(waypoints, np.inf)
    path = chord_spline(pts, chord, (pts[1] - pts[0]) / chord[1])
    grid = np.linspace(0.0, chord[-1], 201)
    acceleration = limits.acceleration * ACCELERATION_HEADROOM
    t0 = time.perf_counter()
    ours = fastest_law(path, grid, limits.velocity, acceleration, 0.0)
    t1 = time.perf_counter()
    theirs = toppra_law(path, grid, limits.velocity, acceleration, 0.0)
    t2 = time.perf_counter()
    differ = abs(ours.duration / theirs.duration - 1.0) if ours is not None and theirs is not None else 0.0
    return (t1 - t0) * 1e3, (t2 - t1) * 1e3, differ


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--placements", type=int, default=60)
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--stay", type=float, default=5.0, help="how long the person is assumed to stay (s)")
    args = parser.parse_args()
    if args.placements < 1 or args.stay < 0:
        parser.error("--placements must be >= 1 and --stay >= 0")
    robot = default_robot()
    collision = CollisionModel(robot, load_scene(DEFAULT_SCENE))
    planner = JointPlanner(collision, PlannerOptions(seed=args.seed, time_budget=1.0))
    replanner = Replanner(collision, planner, SsmParameters(), options=ReplanOptions(patience=args.stay))
    in_cell = Replanner(collision, planner, SsmParameters(), options=ReplanOptions(
        patience=args.stay, search=SearchOptions(time_budget=CELL_BUDGET), action_budget=ACTION_BUDGET))
    old = straight_line_trajectory(Q_START, Q_GOAL, robot.limits.velocity, robot.limits.acceleration)
    rng = np.random.default_rng(args.seed)
    rrt_ms, search_ms, replan_ms = [], [], []
    rrt_time, search_time, direct_time = [], [], []
    taken = kept = failed = 0
    counted_ms, counted_time, budget_time, costed_share = [], [], [], []
    law_ms: list[tuple[float, float, float]] = []
    parameterize(np.vstack([Q_START, Q_GOAL]), robot.limits)         # warm the JIT
    time_laws(np.vstack([Q_START, (Q_START + Q_GOAL) / 2 + 0.3, Q_GOAL]), robot.limits)
    replanner.path(Q_START, Q_GOAL, placement(np.random.default_rng(0)))
    for _ in range(args.placements):
        humans = placement(rng)
        if not (collision.feasible(Q_START, humans) and collision.feasible(Q_GOAL, humans)):
            continue
        # a new goal with the person there: RRT-Connect (clearance only) against the search (time under SSM)
        t0 = time.perf_counter()
        try:
            detour = planner.plan(Q_START, Q_GOAL, humans)
            rrt = parameterize(detour, robot.limits, collision=collision, humans=humans)
        except (PlanningError, TimingError):
            detour = rrt = None
        rrt_ms.append((time.perf_counter() - t0) * 1e3)
        if detour is not None and len(detour) > 2:
            law_ms.append(time_laws(detour, robot.limits))
        t0 = time.perf_counter()
        try:
            searched = replanner.plan_fresh(Q_START, Q_GOAL, humans, 0)
        except (PlanningError, TimingError):
            searched = None
        search_ms.append((time.perf_counter() - t0) * 1e3)
        if rrt is not None and searched is not None:
            rrt_time.append(replanner.predicted_time(rrt, 0.0, humans))
            search_time.append(replanner.predicted_time(searched, 0.0, humans))
            direct_time.append(replanner.predicted_time(old, 0.0, humans))
        # the same search bounded by the cell's wall-clock budget and by its counts alone (the simulation)
        counted, budgeted, wall = both_bounds(replanner, in_cell, humans, args.stay)
        if counted is not None and budgeted is not None:
            counted_ms.append(wall)
            counted_time.append(counted.predicted)
            budget_time.append(budgeted.predicted)
            costed_share.append(budgeted.costed / counted.costed)
        # a replan: the robot on the straight shuttle, the moment a 1 s horizon first sees the person
        full = horizon_check(old, 0.0, collision, humans, HorizonOptions(samples=200, spacing=0.02))
        if full.first_infeasible is None:
            continue                                                 # nothing in the way: no replan needed
        s_seen = max(0.0, float(full.s[full.first_infeasible]) - 1.0)
        t0 = time.perf_counter()
        try:
            speed = float(np.abs(old.sample(s_seen)[1]).max())          # on the shuttle at full speed
            taken += replanner.on_horizon(old, s_seen, Q_GOAL, humans, speed_now=speed) is not None
        except ReplanFailed as exc:
            kept += "kept the old" in str(exc)
            failed += "kept the old" not in str(exc)
        replan_ms.append((time.perf_counter() - t0) * 1e3)
    stats = lambda xs: {"median": round(float(np.median(xs)), 1), "p95": round(float(np.percentile(xs, 95)), 1)} \
        if xs else {"median": None, "p95": None}
    ratio = lambda a, b: round(float(np.sum(a) / np.sum(b)), 3) if a else None
    result = {"bench": "planning", "stay_s": args.stay, "rrt_plan_ms": stats(rrt_ms), "search_plan_ms": stats(search_ms),
              "replan_ms": stats(replan_ms),
              "predicted_s": {"direct": stats(direct_time), "rrt_connect": stats(rrt_time), "search": stats(search_time)},
              "search_vs_rrt_connect": ratio(search_time, rrt_time), "search_vs_direct": ratio(search_time, direct_time),
              "replans": {"taken": taken, "kept_old": kept, "failed": failed},
              "cell_budget": {"counted_search_ms": stats(counted_ms), "costed_share": stats(costed_share),
                              "budget_vs_counts": ratio(budget_time, counted_time),
                              "worse_in_budget": int(np.sum(np.array(budget_time) > np.array(counted_time) + 1e-9))},
              "time_law_ms": {"compiled": stats([c for c, _, _ in law_ms]), "toppra": stats([t for _, t, _ in law_ms]),
                              "toppra_vs_compiled": ratio([t for _, t, _ in law_ms], [c for c, _, _ in law_ms]),
                              "duration_rel_diff_max": float(max((d for _, _, d in law_ms), default=0.0))},
              "cases": {"placements": len(rrt_ms), "compared": len(rrt_time), "replans": len(replan_ms)}}
    print(f"new goal, predicted time under the SSM (person staying {args.stay:g} s), median over "
          f"{len(rrt_time)} placements: direct {result['predicted_s']['direct']['median']} s, RRT-Connect "
          f"{result['predicted_s']['rrt_connect']['median']} s, search {result['predicted_s']['search']['median']} s")
    print(f"  search / RRT-Connect {result['search_vs_rrt_connect']}, search / direct {result['search_vs_direct']} "
          f"(sums); compute median RRT-Connect {result['rrt_plan_ms']['median']} ms, search "
          f"{result['search_plan_ms']['median']} ms (p95 {result['search_plan_ms']['p95']} ms)")
    print(f"horizon replans: {taken} taken, {kept} kept the old trajectory, {failed} failed; compute median "
          f"{result['replan_ms']['median']} ms, p95 {result['replan_ms']['p95']} ms")
    laws = result["time_law_ms"]
    print(f"time laws on {len(law_ms)} RRT-Connect detours (200 grid points, from rest): compiled median "
          f"{laws['compiled']['median']} ms, toppra {laws['toppra']['median']} ms, toppra / compiled "
          f"{laws['toppra_vs_compiled']} (sums); durations differ by at most {laws['duration_rel_diff_max']:.1e}")
    cell = result["cell_budget"]
    print(f"the cell's budget ({CELL_BUDGET * 1e3:.0f} ms a search, {ACTION_BUDGET * 1e3:.0f} ms an action) against "
          f"the counts alone (the simulation's search, median {cell['counted_search_ms']['median']} ms, p95 "
          f"{cell['counted_search_ms']['p95']} ms): costed {cell['costed_share']['median']} of the candidates "
          f"(median), predicted times {cell['budget_vs_counts']} (sums), worse in {cell['worse_in_budget']} of "
          f"{len(budget_time)}")
    print(json.dumps(result))


def both_bounds(counted: Replanner, budgeted: Replanner, humans: HumanCapsules, stay: float):
    """The new goal's search, seeded alike, bounded by its counts (counted) and by the cell's wall-clock
    budget (budgeted, within one planning action): (SearchResult, SearchResult, counted wall ms)."""
    seeds = (np.vstack([Q_START, Q_GOAL]),)
    t0 = time.perf_counter()
    full = counted.search.search(Q_START, Q_GOAL, humans, counted.paths.rng(Q_START, Q_GOAL), stay, seeds)
    wall = (time.perf_counter() - t0) * 1e3
    budgeted.begin()
    cut = budgeted.search.search(Q_START, Q_GOAL, humans, budgeted.paths.rng(Q_START, Q_GOAL), stay, seeds)
    budgeted.end()
    return full, cut, wall


if __name__ == "__main__":
    main()
