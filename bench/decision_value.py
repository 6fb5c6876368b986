"""What each replan the planning layer took, and each new goal's leg it chose, was worth, by running the scenario
again without it (issue 38; not a test: it prints figures).

The simulation is deterministic: the same (kind, seed) runs the same until the moment a decision is changed. For
every replan the full strategy takes (a beta, slow, horizon or search replan: every action but a new goal's leg),
the scenario is run once more with that one replan dropped (``run_shuttle``'s ``veto``: the robot keeps what it
follows, as if the replan had been refused) and everything after it decided again. Its value is the shuttles the
run made with it minus the shuttles made without it: positive, the replan paid; negative, refusing it would have
been better. Where a decision's predicted saving ("predicted A s instead of B s") is large and its value is not,
the prediction is what misleads it (the forecast of the people, or the cost's timeline: ``bench/calibration.py``).
One more run drops every replan: what the replans together are worth against none. Each new goal's leg from rest
(the line, the fold, a searched leg, the leg prepared on the way, or the line or fold left on with the search to
come on the way) is run once more replaced by the fold (``evidence.fixed_path``, the posture the planner folds
with) and once by the straight line (``run_shuttle``'s ``goal_leg``; not where the planner chose that one): its
value against each is the shuttles with the planner's leg minus the shuttles with that one. Each value is
marginal: without one replan the planner decides again and may take a like one a moment later, so a rule's worth
is not the sum of its decisions' values (the slow trigger's merges at a table's edge: 15 taken, -0.34 together,
yet ``hrc sweep --set planning.slow_excess=1,2`` loses 2 % there with fewer of them). Rank leads here, measure
rules with a sweep. The value is counted at
the scenario's end (its shuttles, the last leg's covered share among them): a detour taken in the last second or
so has not yet paid where the end cuts it off (the paper's kind at 12 s: its phase-4 replans at 11.0-11.2 s cost
-2.6 shuttles over 48 seeds; at the paper's own 24 s the same replans are worth +1.7 over 24), so judge late
decisions with a longer --duration.

Per kind and per decision (beta and slow from rest or merged, horizon, search): how many were taken, their summed
and mean value (shuttles in the scenario's time), how many paid (> +0.01) and cost (< -0.01), and the mean
predicted saving (s) of those that paid and of those that cost; per goal's leg as chosen, the summed value against
the fold and against the line and how many paid and cost against each. --list prints every decision.

    python bench/decision_value.py [--kinds two_humans,random_walk,crossing,standing,paper] [--seeds 24]
                                   [--seed 4000] [--duration 12] [--paper-formula] [--list] [--workers 2]
"""

from __future__ import annotations

import argparse
import functools
import json
import re
import sys
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from evidence.scenarios import add_scenario_arguments, scenario_arguments  # noqa: E402

PAID = 0.01            # shuttles: a value above this paid, below minus this cost
PREDICTED = re.compile(r"predicted (\d+\.\d+) s instead of (\d+\.\d+) s")


def decision_kind(action: str, detail: str) -> str:
    """The row a taken replan counts in: its action, beta and slow split by whether the plan starts from rest."""
    if action in ("beta", "slow"):
        return f"{action} {'from rest' if 'from rest' in detail else 'merged'}"
    return action


def predicted_saving(detail: str) -> float | None:
    """The seconds the decision's own prediction said it saves (old minus new), from its detail; None if it says
    none."""
    found = PREDICTED.search(detail)
    return None if found is None else float(found.group(2)) - float(found.group(1))


def goal_kind(detail: str) -> str:
    """The row a new goal's leg counts in: how the planner chose it (its detail, without what follows a colon)."""
    return detail.split(":")[0]


def alternatives(strategies, leg) -> dict:
    """The legs a new goal's leg is held against: the fold and the straight line from its start to its goal,
    numbered as it is; not the one it is (the same positions), nor a fold that cannot be timed."""
    from shared.core.trajectory import straight_line_trajectory
    from shared.planning.timing import TimingError

    start, goal, lim = leg.positions[0], leg.positions[-1], strategies.robot.limits
    others = {"line": straight_line_trajectory(start, goal, lim.velocity, lim.acceleration, version=leg.version)}
    try:
        others["fold"] = strategies.fixed_path.leg(start, goal, leg.version)
    except TimingError:
        pass
    return {name: other for name, other in others.items()
            if not (other.positions.shape == leg.positions.shape and (other.positions == leg.positions).all())}


@functools.cache
def made():
    """This process's ``Strategies`` (the robot, collision model and planners), built on first use: one serves
    full and full_paper."""
    from evidence.strategies import Strategies

    return Strategies()


def one(job: tuple[str, int, float, str]) -> dict:
    """One scenario: the full run, then the run without each of its replans, then without any; then each new
    goal's leg replaced by the fold and by the line."""
    kind, seed, duration, strategy = job
    strategies = made()
    meant, goals = [], []
    base = strategies.run(strategy, kind, seed, duration, veto=lambda n, event: meant.append(event) or False,
                          goal_leg=lambda n, event, leg: goals.append((event, leg)) and None)
    decisions = []
    for n, event in enumerate(meant, start=1):
        without = strategies.run(strategy, kind, seed, duration, veto=lambda m, _, n=n: m == n)
        decisions.append({"t": round(event.t, 2), "action": event.reason, "detail": event.detail,
                          "value": round(base.progress - without.progress, 4)})
    none = strategies.run(strategy, kind, seed, duration, veto=lambda n, event: True) if meant else base
    legs = []
    for n, (event, leg) in enumerate(goals, start=1):
        values = {}
        for name, other in alternatives(strategies, leg).items():
            with_other = strategies.run(strategy, kind, seed, duration,
                                        goal_leg=lambda m, _, __, n=n, other=other: other if m == n else None)
            values[name] = round(base.progress - with_other.progress, 4)
        legs.append({"t": round(event.t, 2), "detail": event.detail, "against": values})
    return {"kind": kind, "seed": seed, "shuttles": base.progress, "without_any": none.progress,
            "violations": base.violations, "decisions": decisions, "goals": legs}


def table(scenarios: list[dict]) -> dict:
    """Per decision kind: count, summed and mean value, how many paid and cost, the mean predicted saving of each."""
    rows: dict = defaultdict(list)
    for scenario in scenarios:
        for d in scenario["decisions"]:
            rows[decision_kind(d["action"], d["detail"])].append(d)
    out = {}
    for name, ds in sorted(rows.items()):
        values = [d["value"] for d in ds]
        paid = [d for d in ds if d["value"] > PAID]
        cost = [d for d in ds if d["value"] < -PAID]

        def saving(group: list[dict]) -> float | None:
            said = [s for s in (predicted_saving(d["detail"]) for d in group) if s is not None]
            return round(sum(said) / len(said), 3) if said else None

        out[name] = {"taken": len(ds), "value": round(sum(values), 3), "mean": round(sum(values) / len(ds), 4),
                     "paid": len(paid), "cost": len(cost), "saving_paid": saving(paid), "saving_cost": saving(cost)}
    return out


def goal_table(scenarios: list[dict]) -> dict:
    """Per goal's leg as chosen: how many, and against the fold and the line: the summed value, how many paid and
    cost."""
    rows: dict = defaultdict(list)
    for scenario in scenarios:
        for g in scenario["goals"]:
            rows[goal_kind(g["detail"])].append(g)
    out = {}
    for name, gs in sorted(rows.items()):
        out[name] = {"chosen": len(gs)}
        for other in ("fold", "line"):
            values = [g["against"][other] for g in gs if other in g["against"]]
            out[name][other] = {"held": len(values), "value": round(sum(values), 3),
                                "paid": sum(v > PAID for v in values), "cost": sum(v < -PAID for v in values)}
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scenario_arguments(parser, "two_humans,random_walk,crossing,standing,paper", 24, 4000)
    parser.add_argument("--paper-formula", action="store_true",
                        help="the planning layer under the paper's formula (full_paper) instead of the shipped model")
    parser.add_argument("--list", action="store_true", help="print every decision with its value")
    args = parser.parse_args()
    kinds = scenario_arguments(parser, args)
    strategy = "full_paper" if args.paper_formula else "full"
    jobs = [(k, s, args.duration, strategy) for k in kinds for s in range(args.seed, args.seed + args.seeds)]
    with ProcessPoolExecutor(args.workers) as pool:
        scenarios = list(pool.map(one, jobs))
    out = {"bench": "decision_value", "strategy": strategy, "seeds": args.seeds, "seed": args.seed,
           "duration": args.duration, "violations": sum(s["violations"] for s in scenarios), "kinds": {}}
    print(f"{strategy}: each replan taken, run again without it; value = shuttles with it - without it "
          f"({args.seeds} scenarios a kind from seed {args.seed}, {args.duration:g} s)")
    for kind in kinds:
        mine = [s for s in scenarios if s["kind"] == kind]
        shuttles, without = sum(s["shuttles"] for s in mine), sum(s["without_any"] for s in mine)
        rows = table(mine)
        out["kinds"][kind] = {"shuttles": round(shuttles, 3), "without_any": round(without, 3), "decisions": rows}
        print(f"{kind}: {shuttles:.2f} shuttles, {without:.2f} without any replan "
              f"({shuttles / without:.3f}x)" if without else f"{kind}: no shuttles")
        for name, r in rows.items():
            print(f"  {name:<16} taken {r['taken']:3d}  value {r['value']:+7.3f} (mean {r['mean']:+.3f})  "
                  f"paid {r['paid']:3d}, cost {r['cost']:3d}  predicted saving: paid {r['saving_paid']} s, "
                  f"cost {r['saving_cost']} s")
        legs = goal_table(mine)
        out["kinds"][kind]["goals"] = legs
        for name, r in legs.items():
            print(f"  goal: {name:<34} {r['chosen']:3d}  " + "  ".join(
                f"against the {o} ({r[o]['held']}) {r[o]['value']:+7.3f}, paid {r[o]['paid']}, cost {r[o]['cost']}"
                for o in ("fold", "line")))
        if args.list:
            for s in mine:
                for d in s["decisions"]:
                    print(f"    seed {s['seed']} {d['t']:6.2f} s {d['action']:<8} {d['value']:+.3f}  {d['detail']}")
                for g in s["goals"]:
                    print(f"    seed {s['seed']} {g['t']:6.2f} s goal     " + " ".join(
                        f"vs {o} {v:+.3f}" for o, v in g["against"].items()) + f"  {g['detail']}")
    print(f"violations: {out['violations']}")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
