"""How well the planning layer's time cost predicts what the scaling layer then does (issue 38, item 2; not a
test: it prints figures). For seeded scenarios, at a few moments each, the legs a planner would choose between
(the straight line, the fixed folded path of ``evidence.fixed_path``, and the path search's winner, each timed as
the planner times it) are predicted by the cost (``SsmTimeCost.trajectory_time``, the people tracked at that
moment, forecast as the planner forecasts them, staying as long as the planner has a new goal's leg have them
stay: ``patience`` plus how long its presence clocks, ``shared.planning.presence.Presence``, say they have stayed by
that moment, the scenario replayed from its start, and at least ``goal_stay`` (``Replanner.goal_waited``); ``--stay
S`` for a fixed stay instead) and then executed by the product's own
``ScalingLayer`` against the scripted people as they really move, until the leg's end. Per kind: the prediction's
error (predicted / executed - 1: its median, the median and p95 of its size), and how often the candidate
predicted fastest is the one executed fastest (a cost that misranks shows there), with what choosing by the
cost loses against choosing by the execution.

Two sources of error are apart here: the cost's timeline (how the robot's motion under the scaling layer is
modelled: ramps, corners, alpha's limits, waiting) and the forecast of the people. ``--truth`` predicts with the
scripted people's own future (``evidence.foresight.Foresight``, nobody assumed to stay or go): what is left is the
timeline's error alone. ``--judge scaling`` predicts by a forward run of the product's scaling layer against the
forecast (``ReplanOptions.judge``) instead of the cost's kernel.

``--futures K`` says how much of the error no forecast can take away, in the kinds whose people's future is drawn
as they go (``evidence.scenarios.WANDERING_KINDS``): each leg is also executed against K other futures the
scenario could have had from the leg's start (``other_futures``: the same past, and more than a tracker sees),
and the one prediction that has the most of those K within 5 % (15 %) of it (``evidence.prediction.best_within``)
is judged against the leg's own future, which it never saw: the share of legs it has within 5 % (15 %) is the most
a forecast can be expected to reach, where issue 38 asks for half of them (|error| median <= 5 %) and 95 % (p95 <=
15 %). Beside it, the share when the leg's own future is among those chosen from (in sample, an optimistic figure),
and the |error| of the prediction of least expected relative error (``least_relative_error``); and how often the
leg fastest on average over those futures is the fastest in the leg's own (what choosing by the best forecast of
the people's future would rank right, against the cost's ranking).

    python bench/calibration.py [--seeds 20] [--kinds two_humans,random_walk] [--seed 0] [--moments 3] [--stay inf]
                                [--truth] [--judge cost|scaling] [--worst 5] [--futures 16]
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from evidence.fixed_path import FixedPath  # noqa: E402
from evidence.foresight import Foresight, foresight_options  # noqa: E402
from evidence.prediction import best_within, least_relative_error  # noqa: E402
from evidence.scenarios import Q_GOAL, Q_START, WANDERING_KINDS, kinds_problem, make_scenario, other_futures  # noqa: E402
from shared.config import CellConfig  # noqa: E402
from shared.core.trajectory import Trajectory, straight_line_trajectory  # noqa: E402
from shared.planning.collision import CollisionModel  # noqa: E402
from shared.planning.ompl_planner import JointPlanner, PlannerOptions  # noqa: E402
from shared.planning.presence import Presence  # noqa: E402
from shared.planning.replanner import Replanner, ReplanOptions  # noqa: E402
from shared.planning.scene import DEFAULT_SCENE, load_scene  # noqa: E402
from shared.robot.model import default_robot  # noqa: E402
from shared.scaling.layer import ScalingInputs, ScalingLayer, StepStatus  # noqa: E402

LONGEST = 15.0         # s: a leg not done by then is counted as taking this long (a person who never leaves)
TOLERANCES = (0.05, 0.15)    # issue 38's calibration: |error| median <= 5 %, p95 <= 15 %


def executed(robot, config: CellConfig, trajectory: Trajectory, human, t0: float) -> float:
    """Seconds the product's scaling layer takes along `trajectory` from rest, with the scripted people from t0."""
    layer = ScalingLayer(robot, config.ssm, config.scaling)
    layer.set_trajectory(trajectory)
    period = config.scaling.period
    for k in range(int(LONGEST / period)):
        if layer.step(ScalingInputs(humans=human.at(t0 + k * period))).status is StepStatus.FINISHED:
            return k * period
    return LONGEST


def unforeseeable(outcomes: list[float], own: float) -> dict:
    """What a prediction from a leg's start can do at best, its executed times over other futures `outcomes` (s)
    against its own future's `own` (s): for each of TOLERANCES, whether the prediction that has the most outcomes
    within it has `own` within it too (held out), and the most of outcomes and own together one prediction has
    within it (in sample); and the relative error of the least-error prediction over the outcomes."""
    said = {"least_error": least_relative_error(outcomes) / own - 1.0}
    for tolerance in TOLERANCES:
        guess, _ = best_within(outcomes, tolerance)
        said[tolerance] = (abs(guess / own - 1.0) <= tolerance + 1e-12, best_within([*outcomes, own], tolerance)[1])
    return said


def floor_summary(floors: list[dict]) -> dict:
    """Per kind: the shares of legs (held out; in sample) within each of TOLERANCES, and the least-error
    prediction's |error| median and p95."""
    least = np.abs([f["least_error"] for f in floors])
    summary = {f"within_{round(100 * tol)}pc": [round(float(np.mean([f[tol][0] for f in floors])), 3),
                                                 round(float(np.mean([f[tol][1] for f in floors])), 3)]
               for tol in TOLERANCES}
    summary.update(least_error_abs_median=round(float(np.median(least)), 3),
                   least_error_abs_p95=round(float(np.percentile(least, 95)), 3), legs=len(floors))
    return summary


def presence_waited(human, moments, period: float) -> list[float]:
    """How long the planning layer's presence clocks say the people have stayed (s) at each of the ascending
    `moments` (s), the scenario's people replayed once from 0 every `period` s (the planning loop updates them on
    every new people state)."""
    presence, waits, k = Presence(), [], 0
    for t0 in moments:
        while k * period <= t0 + 1e-9:
            presence.update(k * period, human.at(k * period))
            k += 1
        waits.append(presence.waited(t0))
    return waits


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=20, help="scenarios per kind")
    parser.add_argument("--seed", type=int, default=0, help="first scenario seed")
    parser.add_argument("--kinds", default="crossing,random_walk,standing,two_humans")
    parser.add_argument("--moments", type=int, default=3, help="moments per scenario a leg starts at")
    parser.add_argument("--stay", type=float, default=None,
                        help="s the prediction has the people stay (default: as the planner has them stay for a new "
                             "goal's leg, its patience plus how long they have stayed by then, at least its goal_stay; "
                             "inf: for good)")
    parser.add_argument("--truth", action="store_true",
                        help="predict with the people's own future (the timeline's error alone, no forecast's)")
    parser.add_argument("--judge", choices=("cost", "scaling"), default="cost",
                        help="what predicts: the time cost's kernel, or a forward run of the scaling layer")
    parser.add_argument("--worst", type=int, default=0, metavar="N",
                        help="also print the N legs predicted worst of each kind (where to look in the cost)")
    parser.add_argument("--futures", type=int, default=0, metavar="K",
                        help="in the wandering kinds, also execute each leg against K other futures of its people: "
                             "the error no forecast can take away (0: not)")
    args = parser.parse_args()
    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    if args.seeds < 1 or args.moments < 1 or args.worst < 0 or args.futures < 0:
        parser.error("--seeds and --moments >= 1, --worst and --futures >= 0")
    if problem := kinds_problem(kinds):
        parser.error(f"--kinds: {problem}")
    if args.truth and args.stay is not None:
        parser.error("--truth knows when the people go: it takes no --stay")
    robot, config = default_robot(), CellConfig()
    collision = CollisionModel(robot, load_scene(DEFAULT_SCENE), config.ssm.min_separation)
    options = replace(ReplanOptions(**config.planning.replan_fields()), judge=args.judge)
    if args.truth:       # the future over the longest leg counted (after its horizon a forecast holds its last frame)
        options = foresight_options(options)
        options = replace(options, cost=replace(options.cost, extrapolation=LONGEST))
    if args.stay is not None:          # exactly S: no goal_stay above it
        options = replace(options, patience=args.stay, goal_stay=0.0)
    replanner = Replanner(collision, JointPlanner(collision, PlannerOptions(seed=1)), config.ssm, options=options,
                          scaling=config.scaling)
    fixed = FixedPath(collision)
    clocks = not args.truth and args.stay is None       # the stay as the planning loop has it at each moment
    moments = [float(t0) for t0 in np.linspace(0.0, 10.0, args.moments)]    # s: when the legs start
    waits = []
    lim = robot.limits
    summary = {}
    for kind in kinds:
        ranked, loss, legs_said, floors, choices = [], [], [], [], []
        futures = args.futures if kind in WANDERING_KINDS else 0
        for seed in range(args.seed, args.seed + args.seeds):
            human = make_scenario(kind, seed, 12.0 + LONGEST)
            if args.truth:
                human = replanner.cost.forecaster = Foresight(human)
            stayed = presence_waited(human, moments, config.scaling.period) if clocks else [0.0] * len(moments)
            waits += stayed
            for moment, (t0, held) in enumerate(zip(moments, stayed)):
                waited = replanner.goal_waited(held)         # a new goal's leg, as plan_goal has the people stay
                others = other_futures(kind, seed, 12.0 + LONGEST, t0, np.random.default_rng([seed, moment]),
                                       futures) if futures else []
                for a, b in ((Q_START, Q_GOAL), (Q_GOAL, Q_START)):
                    people = human.at(t0)
                    legs = {"straight": straight_line_trajectory(a, b, lim.velocity, lim.acceleration),
                            "fixed_path": fixed.leg(a, b, 0)}
                    try:
                        replanner.forget()
                        legs["searched"] = replanner.plan_fresh(a, b, people, 0, waited)
                    except Exception as exc:          # noqa: BLE001 (a search may find nothing: said, not fatal)
                        print(f"{kind} {seed} t={t0:.1f}: no search ({type(exc).__name__})", file=sys.stderr)
                    predicted = {n: replanner.predicted_time(t, 0.0, people, waited) for n, t in legs.items()}
                    done = {n: executed(robot, config, t, human, t0) for n, t in legs.items()}
                    legs_said += [(predicted[n] / done[n] - 1.0, seed, t0, "out" if a is Q_START else "back", n,
                                   predicted[n], done[n]) for n in legs if done[n] < LONGEST]
                    chosen, best = min(predicted, key=predicted.get), min(done, key=done.get)
                    if others:
                        outcomes = {n: [executed(robot, config, t, other, t0) for other in others]
                                    for n, t in legs.items()}
                        floors += [unforeseeable(outcomes[n], done[n]) for n in legs if done[n] < LONGEST]
                        foreseen = min(outcomes, key=lambda n: np.mean(outcomes[n]))   # fastest over the futures
                        choices.append((foreseen == best, done[foreseen] - done[best]))
                    ranked.append(chosen == best)
                    loss.append(done[chosen] - done[best])
        e = np.asarray([said[0] for said in legs_said])       # the finished legs' errors
        figure = (lambda f: round(float(f), 3)) if e.size else (lambda f: None)    # no leg finished: no error
        summary[kind] = {"legs": len(ranked), "finished": int(e.size),
                         "error_median": figure(np.median(e) if e.size else 0),
                         "abs_error_median": figure(np.median(np.abs(e)) if e.size else 0),
                         "abs_error_p95": figure(np.percentile(np.abs(e), 95) if e.size else 0),
                         "ranked_right": round(float(np.mean(ranked)), 3),
                         "loss_by_the_cost_s": round(float(np.mean(loss)), 3)}
        # |error| by the moment a leg starts at, over the moments a leg finished from (its own name: `moments` is
        # every kind's, and a kind with no leg finished from one moment took that moment from the kinds after it)
        finished_from = sorted({said[2] for said in legs_said})
        summary[kind]["by_moment"] = {f"{t0:g}": [round(float(np.median(np.abs(m))), 3),
                                                  round(float(np.percentile(np.abs(m), 95)), 3)]
                                      for t0 in finished_from
                                      for m in [np.asarray([said[0] for said in legs_said if said[2] == t0])]}
        s = summary[kind]
        errors_said = (f"error median {s['error_median']:+.3f}, |error| median {s['abs_error_median']:.3f} p95 "
                       f"{s['abs_error_p95']:.3f}" if s["finished"] else f"no leg finished within {LONGEST:.0f} s")
        print(f"{kind:<12} {s['legs']} choices, {s['finished']} legs finished: {errors_said}; "
              f"the predicted fastest the executed fastest in "
              f"{100 * s['ranked_right']:.0f} %, {s['loss_by_the_cost_s']:.3f} s lost a leg on average", flush=True)
        print("  |error| median, p95 by the moment a leg starts at: " + ", ".join(
            f"{t0} s {m[0]:.3f}, {m[1]:.3f}" for t0, m in s["by_moment"].items()), flush=True)
        if floors:
            s["unforeseeable"] = f = floor_summary(floors)
            f["ranked_right"] = round(float(np.mean([right for right, _ in choices])), 3)
            f["loss_s"] = round(float(np.mean([lost for _, lost in choices])), 3)
            print(f"  over {args.futures} other futures of its people, the best one prediction from each leg's start "
                  f"has its own future within 5 % in {100 * f['within_5pc'][0]:.0f} % of {f['legs']} legs (in sample "
                  f"{100 * f['within_5pc'][1]:.0f} %), within 15 % in {100 * f['within_15pc'][0]:.0f} % "
                  f"({100 * f['within_15pc'][1]:.0f} %); the least-error prediction's |error| median "
                  f"{f['least_error_abs_median']:.3f}, p95 {f['least_error_abs_p95']:.3f}; the leg fastest over "
                  f"them is its own future's fastest in {100 * f['ranked_right']:.0f} % of the choices, "
                  f"{f['loss_s']:.3f} s lost a leg on average", flush=True)
        for err, seed, t0, way, name, said, took in sorted(legs_said, key=lambda r: -abs(r[0]))[:args.worst]:
            print(f"  worst: seed {seed} from {t0:.1f} s, the leg {way}, {name}: predicted {said:.2f} s, "
                  f"executed {took:.2f} s ({err:+.3f})", flush=True)
    stay = "the planner's for a new goal: patience + the presence clocks, at least goal_stay" if clocks \
        else replanner.stay(0.0)
    if clocks:
        print(f"the people's stay: patience {replanner.stay(0.0):.2f} s plus the presence clocks' count at each "
              f"moment (median {np.median(waits):.2f} s, max {max(waits):.2f} s), at least the goal's stay "
              f"{replanner.options.goal_stay:.2f} s")
    print(json.dumps({"bench": "calibration", "seeds": args.seeds, "moments": args.moments, "stay_s": stay,
                      "truth": args.truth, "judge": args.judge, "futures": args.futures, "kinds": summary}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
