"""Where a perfect forecast pays, decision by decision (issue 38; not a test: it prints figures).

The foresight strategy (``evidence.foresight``) tells the planning layer the scripted people's future in every
decision it makes. This benchmark tells it to one kind of decision at a time, and a forecast (constant velocity,
or a researcher's ``--forecaster``) to the rest: a new goal's leg (``goal``: ``Replanner.plan_goal``), the trust
gate's check that the forecast has held (``trust``: ``shared.planning.trust``), the search on the way
(``search``), the scaling layer's replan requests (``beta``), the horizon check (``horizon``) and the planning
layer's own request (``slow``); then to every decision but a new goal's leg and the trust gate, and to all (a
new goal's merge into a moving robot's trajectory among them). Each row: the shuttles made over the same
scenarios, as a ratio to the row told nothing (the same planner with the forecast in every decision). Where one
decision holds most of a perfect forecast's worth, a rule for that decision can win it back; where it is spread
over all of them, only a better forecast can.

The planner is the foreseeing one (``foresight_options``: its predictions over the forecast's whole horizon,
nobody assumed gone before the forecast says), so the row told everything is the foresight strategy itself.

    python bench/forecast_value.py [--kinds random_walk,two_humans,crossing] [--seeds 48] [--seed 20000]
                                   [--duration 12] [--forecaster module:attribute] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from evidence.scenarios import add_scenario_arguments, scenario_arguments  # noqa: E402
from shared.planning.forecast import forecaster_problem  # noqa: E402
from shared.planning.replanner import Replanner  # noqa: E402

DECISIONS = ("goal", "trust", "search", "beta", "horizon", "slow")
OTHER = "other"     # what no decision above asks: a new goal's merge into a moving robot's trajectory (reason 'goal')
ROWS = {"nothing": (), **{d: (d,) for d in DECISIONS},
        "all but a new goal's leg": ("search", "beta", "horizon", "slow", OTHER), "everything": DECISIONS + (OTHER,)}


class TruthFor:
    """A forecaster that answers the decisions in `told` with the script's future (`truth`, a ``Foresight``) and
    every other with `estimate`. `asking` names the decision under way (``DecisionReplanner``); a forecast of
    people from an earlier moment than now, asked outside any decision, is the trust gate's."""

    def __init__(self, truth, estimate, told: tuple[str, ...]) -> None:
        self.truth, self.estimate, self.told = truth, estimate, frozenset(told)
        self.asking: str | None = None

    def _answering(self, humans):
        decision = self.asking or ("trust" if self.truth.moment(humans) < self.truth.now else OTHER)
        return self.truth if decision in self.told else self.estimate

    def forecast(self, humans, horizon: float):
        return self._answering(humans).forecast(humans, horizon)

    def hypotheses(self, humans, horizon: float):
        """The answering forecaster's hypotheses (a researcher's may have several), else its one forecast."""
        answering = self._answering(humans)
        if callable(getattr(answering, "hypotheses", None)):
            return answering.hypotheses(humans, horizon)
        return [(1.0, answering.forecast(humans, horizon))]


def _asking(name: str, label: str):
    def decide(self, *args, **kwargs):
        forecaster = self.cost.forecaster
        if not isinstance(forecaster, TruthFor) or forecaster.asking is not None:
            return getattr(Replanner, name)(self, *args, **kwargs)      # on_slow's on_beta stays 'slow'
        forecaster.asking = label
        self.cost.forget_forecast()
        try:
            return getattr(Replanner, name)(self, *args, **kwargs)
        finally:
            forecaster.asking = None
            self.cost.forget_forecast()
    return decide


class DecisionReplanner(Replanner):
    """The product's Replanner, naming each decision to its forecaster while it makes it."""

    plan_goal = _asking("plan_goal", "goal")
    on_search = _asking("on_search", "search")
    on_beta = _asking("on_beta", "beta")
    on_horizon = _asking("on_horizon", "horizon")
    on_slow = _asking("on_slow", "slow")


_MADE: dict = {}


def one(job: tuple[str, int, float, str, str | None]) -> tuple[str, int, str, float, int]:
    """One scenario with the future told to one row's decisions: (kind, seed, row, shuttles, violations)."""
    kind, seed, duration, row, forecaster = job
    from evidence.foresight import Foresight, foresight_options
    from evidence.scenarios import make_scenario
    from evidence.sim import run_shuttle
    from evidence.strategies import CELL_BUDGET, Q_GOAL, Q_START, Strategies
    from shared.planning.forecast import ConstantVelocity, load_forecaster

    if forecaster not in _MADE:
        s = Strategies()
        planner = DecisionReplanner(s.collision, s.replanner.planner, s.config.ssm,
                                    options=foresight_options(s.replanner.options), scaling=s.config.scaling)
        _MADE[forecaster] = (s, planner, load_forecaster(forecaster) if forecaster else ConstantVelocity())
    s, planner, estimate = _MADE[forecaster]
    truth = Foresight(make_scenario(kind, seed, duration))
    planner.cost.forecaster = TruthFor(truth, estimate, ROWS[row])
    planner.cost.forget_forecast()
    result = run_shuttle(s.robot, s.config, truth, Q_START, Q_GOAL, duration, replanner=planner,
                         charge_planning=CELL_BUDGET, monitor=s.monitor)
    return kind, seed, row, float(result.progress), int(result.summary()["violations"])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scenario_arguments(parser, "random_walk,two_humans,crossing", 48, 20000)
    parser.add_argument("--forecaster", default=None,
                        help="the forecast told to the other decisions, module:attribute (default: constant velocity)")
    args = parser.parse_args()
    kinds = scenario_arguments(parser, args)
    if args.forecaster and (problem := forecaster_problem(args.forecaster)):
        parser.error(f"--forecaster: {problem}")
    jobs = [(k, s, args.duration, row, args.forecaster) for k in kinds
            for s in range(args.seed, args.seed + args.seeds) for row in ROWS]
    with ProcessPoolExecutor(args.workers) as pool:
        got = list(pool.map(one, jobs, chunksize=len(ROWS)))
    out = {"bench": "forecast_value", "forecaster": args.forecaster or "constant velocity", "seeds": args.seeds,
           "seed": args.seed, "duration": args.duration, "violations": sum(g[4] for g in got), "kinds": {}}
    print(f"the future told to one kind of decision, {args.forecaster or 'constant velocity'} to the rest; "
          f"{args.seeds} scenarios a kind from seed {args.seed}, {args.duration:g} s; shuttles over the row told nothing")
    for kind in kinds:
        totals = {row: sum(g[3] for g in got if g[0] == kind and g[2] == row) for row in ROWS}
        base = totals["nothing"]
        out["kinds"][kind] = {row: {"shuttles": round(v, 3), "ratio": round(v / base, 4) if base else None}
                              for row, v in totals.items()}
        print(f"{kind}: " + ", ".join(f"{row} {v / base:.3f}" if base else f"{row} -" for row, v in totals.items()),
              flush=True)
    print(f"violations: {out['violations']}")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
