"""Does a bound rise with its own search? (issue 38, item 7; not a test: it prints figures.) A bound on
what any planning layer could add must not fall when it is allowed to search more.

--bound oracle (the default): run the oracle strategy
(``evidence.foresight.oracle_options``: the people's future known, planning free of time) with its search 1, 2,
4 and 8 times the planning layer's, on the same seeded scenarios, and print per kind the shuttles of each and
how many scenarios got fewer shuttles with the larger search. Where it falls, the "bound" is not one: its
choices are ranked by the time cost's prediction, not by what the scaling layer then executes (the
calibration benchmark, bench/calibration.py, measures that misranking).

--bound clairvoyant: the clairvoyant bound of ``evidence.clairvoyant`` (the best sequence of fixed leg shapes,
found by running the whole scenario with each) at 2, 4, 8, 16 and 20 shapes, beside scale_only, fixed_path and full on
the same scenarios: per kind the shuttles of each, the scenarios where a larger search fell (0 by construction:
a check), the runs it took, the shapes its best sequences use, and the share of the bound's room over
scale_only that full and fixed_path use ((x - scale_only) / (bound - scale_only)). --greedy adds the clairvoyant
chooser one leg ahead (``evidence.clairvoyant.greedy_sequence``): whether the bound's room needs looking further
than the leg being driven.

    python bench/bound_search.py [--seeds 6] [--kinds two_humans,random_walk,paper] [--duration 12] [--paper]
                                 [--judge cost|scaling] [--bound oracle|clairvoyant] [--greedy]
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

from evidence.scenarios import add_scenario_arguments, scenario_arguments  # noqa: E402
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


# beside the clairvoyant bound: the baselines, the product, and the product told the people's future (which also
# bends within a leg, so it may pass a bound of one shape a leg: a share above 1 says it did)
BESIDE = ("scale_only", "fixed_path", "full", "foresight")


def clairvoyant_one(job: tuple[bool, str, int, float, bool]) -> dict:
    """The clairvoyant bound's nested searches and the strategies beside it on one scenario (with greedy, the
    clairvoyant chooser one leg ahead too)."""
    paper, kind, seed, duration, greedy = job
    s = strategies(1, paper, "cost")
    choices, runs = s.clairvoyant(kind, seed, duration)
    beside = {name: s.run(name, kind, seed, duration).progress for name in BESIDE}
    if greedy:
        beside["greedy"] = s.greedy(kind, seed, duration)[0].shuttles
    return {"kind": kind, "seed": seed, "runs": runs, "beside": beside,
            "bound": {size: (c.shuttles, c.shapes[:c.legs]) for size, c in choices.items()}}


def clairvoyant_report(got: list[dict], kinds: list[str], args) -> dict:
    from collections import Counter

    from evidence.clairvoyant import SEARCHES, SHAPES

    out = {"bench": "bound_search", "bound": "clairvoyant", "paper_formula": args.paper, "seeds": args.seeds,
           "duration": args.duration, "searches": list(SEARCHES), "kinds": {}}
    for kind in kinds:
        rows = [g for g in got if g["kind"] == kind]
        totals = {size: sum(r["bound"][size][0] for r in rows) for size in SEARCHES}
        falls = {f"{a}->{b}": sum(r["bound"][b][0] < r["bound"][a][0] - 1e-9 for r in rows)
                 for a, b in zip(SEARCHES, SEARCHES[1:])}
        names = BESIDE + (("greedy",) if args.greedy else ())
        beside = {name: sum(r["beside"][name] for r in rows) for name in names}
        room = totals[max(SEARCHES)] - beside["scale_only"]
        share = {name: round((beside[name] - beside["scale_only"]) / room, 3) if room > 1e-9 else None
                 for name in names[1:]}
        base = beside["scale_only"]          # the goals are ratios over scale_only: each, and the bound, so
        ratio = {name: round(beside[name] / base, 4) if base > 1e-9 else None for name in names[1:]}
        ratio["bound"] = round(totals[max(SEARCHES)] / base, 4) if base > 1e-9 else None
        used = Counter(SHAPES[k].name for r in rows for k in r["bound"][max(SEARCHES)][1])
        runs = [r["runs"] for r in rows]
        out["kinds"][kind] = {"bound": {str(k): round(v, 3) for k, v in totals.items()}, "fell_in": falls,
                              "beside": {k: round(v, 3) for k, v in beside.items()}, "share_of_room": share,
                              "over_scale_only": ratio,
                              "shapes_used": dict(used.most_common()), "runs_median": float(sorted(runs)[len(runs) // 2])}
        print(f"{kind:<12} shuttles over {len(rows)} scenarios: scale_only {beside['scale_only']:.2f}, fixed_path "
              f"{beside['fixed_path']:.2f}, full {beside['full']:.2f}, foresight {beside['foresight']:.2f}; the bound at "
              + ", ".join(f"{k} shapes {v:.2f}" for k, v in totals.items())
              + f" (fell in {sum(falls.values())}); of its room over scale_only fixed_path uses "
              f"{share['fixed_path']}, full {share['full']}, foresight {share['foresight']} (above 1: beyond the bound, "
              f"by replanning within a leg); runs per scenario (median) "
              f"{out['kinds'][kind]['runs_median']:.0f}", flush=True)
        print(f"{'':<12} over scale_only: " + ", ".join(f"{n} {v}" for n, v in ratio.items()), flush=True)
        print(f"{'':<12} the bound's legs: " + ", ".join(f"{n} {c}" for n, c in used.most_common()), flush=True)
        if args.greedy:
            print(f"{'':<12} the clairvoyant chooser one leg ahead: {beside['greedy']:.2f}, {share['greedy']} of the "
                  f"bound's room", flush=True)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scenario_arguments(parser, "two_humans,random_walk,paper", 6, 300)
    parser.add_argument("--paper", action="store_true", help="under the paper's formula (the measured speed held)")
    parser.add_argument("--judge", choices=("cost", "scaling"), default="cost",
                        help="what the oracle's decisions are predicted by: the time cost, or a forward run of the "
                             "scaling layer against the known future (shared.planning.executed)")
    parser.add_argument("--bound", choices=("oracle", "clairvoyant"), default="oracle",
                        help="the oracle (the planning layer told the future) or the clairvoyant sequence of fixed "
                             "leg shapes (evidence.clairvoyant)")
    parser.add_argument("--greedy", action="store_true",
                        help="with --bound clairvoyant: also the clairvoyant chooser one leg ahead (each leg the shape "
                             "whose leg ends first; evidence.clairvoyant.greedy_sequence), as many runs again")
    args = parser.parse_args()
    kinds = scenario_arguments(parser, args)
    if args.greedy and args.bound != "clairvoyant":
        parser.error("--greedy goes with --bound clairvoyant")
    if args.bound == "clairvoyant":
        cjobs = [(args.paper, k, s, args.duration, args.greedy) for k in kinds
                 for s in range(args.seed, args.seed + args.seeds)]
        with ProcessPoolExecutor(args.workers) as pool:
            got = list(pool.map(clairvoyant_one, cjobs))
        print(json.dumps(clairvoyant_report(got, kinds, args)))
        return 0
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
