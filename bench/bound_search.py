"""Does the oracle bound rise with its own search? (issue 38, item 7; not a test: it prints figures.) A bound on
what any planning layer could add must not fall when it is allowed to search more: run the oracle strategy
(``evidence.foresight.oracle_options``: the people's future known, planning free of time) with its search 1, 2,
4 and 8 times the planning layer's, on the same seeded scenarios, and print per kind the shuttles of each and
how many scenarios got fewer shuttles with the larger search. Where it falls, the "bound" is not one: its
choices are ranked by the time cost's prediction, not by what the scaling layer then executes (the
calibration benchmark, bench/calibration.py, measures that misranking).

    python bench/bound_search.py [--seeds 6] [--kinds two_humans,random_walk,paper] [--duration 12] [--paper]
                                 [--judge cost|scaling]
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from functools import lru_cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from evidence.scenarios import SCENARIO_KINDS  # noqa: E402
from shared.config import CellConfig  # noqa: E402

SEARCHES = (1, 2, 4, 8)


@lru_cache(maxsize=len(SEARCHES) * 2)
def strategies(times: int, paper: bool, judge: str):
    from evidence.strategies import Strategies

    config = CellConfig()
    if paper:
        from dataclasses import replace

        config = replace(config, ssm=config.ssm.paper_formula())
    return Strategies(config, oracle_search=times, oracle_judge=judge)


def one(job: tuple[int, bool, str, str, int, float]) -> tuple[int, str, int, float, int]:
    times, paper, judge, kind, seed, duration = job
    summary = strategies(times, paper, judge).run("oracle", kind, seed, duration).summary()
    return times, kind, seed, float(summary["shuttle_progress"]), int(summary["violations"])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=6)
    parser.add_argument("--seed", type=int, default=300)
    parser.add_argument("--kinds", default="two_humans,random_walk,paper")
    parser.add_argument("--duration", type=float, default=12.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--paper", action="store_true", help="under the paper's formula (the measured speed held)")
    parser.add_argument("--judge", choices=("cost", "scaling"), default="cost",
                        help="what the oracle's decisions are predicted by: the time cost, or a forward run of the "
                             "scaling layer against the known future (shared.planning.executed)")
    args = parser.parse_args()
    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    if any(k not in SCENARIO_KINDS for k in kinds) or args.seeds < 1 or not args.duration > 0 or args.workers < 1:
        parser.error(f"--kinds from {sorted(SCENARIO_KINDS)}; --seeds, --workers >= 1; --duration > 0")
    jobs = [(t, args.paper, args.judge, k, s, args.duration) for t in SEARCHES for k in kinds
            for s in range(args.seed, args.seed + args.seeds)]
    with ProcessPoolExecutor(args.workers) as pool:
        got = list(pool.map(one, jobs))
    progress = {(t, k, s): p for t, k, s, p, _ in got}
    violations = sum(v for *_, v in got)
    out = {"bench": "bound_search", "paper_formula": args.paper, "judge": args.judge, "seeds": args.seeds,
           "duration": args.duration,
           "searches": list(SEARCHES), "kinds": {}, "violations": violations}
    for kind in kinds:
        seeds = range(args.seed, args.seed + args.seeds)
        totals = {t: sum(progress[(t, kind, s)] for s in seeds) for t in SEARCHES}
        falls = {f"{a}x->{b}x": sum(progress[(b, kind, s)] < progress[(a, kind, s)] - 1e-9 for s in seeds)
                 for a, b in zip(SEARCHES, SEARCHES[1:])}
        out["kinds"][kind] = {"shuttles": {f"{t}x": round(v, 3) for t, v in totals.items()}, "fell_in": falls}
        print(f"{kind:<12} shuttles over {args.seeds} scenarios: "
              + ", ".join(f"{t}x {totals[t]:.2f}" for t in SEARCHES)
              + "; scenarios where a larger search gave fewer: " + ", ".join(f"{k} {v}" for k, v in falls.items()),
              flush=True)
    print(f"violations: {violations}")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
