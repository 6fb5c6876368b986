"""Side by side: zone-based SSM (as deployed today), scaling only, and the full architecture, on the same
seeded scenarios in the deterministic simulation (evidence.sim, evidence.strategies; not a test: it prints
figures). Scenario kinds: the paper's four phases, a person crossing at 1.6 m/s, a person standing in
the path, two people, random walks near the robot. Per strategy: shuttles per minute (over all scenarios),
time stopped (shuttles count fractionally: the part of the current shuttle's path done at the end), the
smallest margin to the limit (conservative end-point bound, m), and violations counted
by the independent monitor's rule. The full architecture pays its planning time on the simulated clock.
Prints progress (done/total, rate, time left). Writes a plot (compare.png) into --out. The last line
is one JSON object (overall and per kind: "kinds": {kind: {strategy: shuttles per minute}}; "ratios":
{kind or "overall": {"full/scale_only": [ratio, low, high], "full/zones": [...]}}, the paired bootstrap
95 % interval of evidence.stats: how far the ratio would move with another draw of scenarios. The paper's
phases are a distribution: each seed's phase period within +-5 % (evidence.scenarios.perturbed_paper); "empty_cell": the
shuttles per minute with nobody in the cell, the most any strategy can do; "won_back": {kind or "overall":
(full - scale_only) / (empty_cell - scale_only)}, the share of what the people cost the scaling layer
alone that the planning layer wins back: a ratio's room depends on the kind, and this says how much of
it is used).

--foresight adds a fourth column, a bound rather than a strategy (evidence.foresight): full with the planning
layer told the scripted people's own future instead of its constant-velocity forecast. Its ratios
"foresight/scale_only" and "full/foresight" and "won_back_foresight" say how much of the room a perfect
prediction of human motion would use, so what is left beyond it is the planner's search and rules, or
physics (the people simply in the way). --oracle adds the planning layer at its most
(evidence.foresight.oracle_options): foresight with a search eight times as large, planning free of time and
every predicted gain taken; "oracle/scale_only", "full/oracle" and "won_back_oracle". It is a reference, not a
bound: it ranks its choices by a prediction, and bench/bound_search.py shows it falling as its search grows
(--clairvoyant below is the bound). --forecaster runs full with another forecast of the people (a
researcher's predictor, ``shared.planning.forecast.load_forecaster``); the JSON line names it. --paper adds
scale_only and full under the paper's formula (the measured human speed held: ``SsmParameters.paper_formula``;
the planning layer as shipped, so the pair isolates the model of the person), judged like every run by the
shipped model's monitor: "scale_only/scale_only_paper" and "full/full_paper" are what the shipped model of a
person who may speed up costs, the *_paper violations what the formula lets through, and
"full_paper/scale_only_paper" the planning layer's own gain under that formula (with --fixed-path too,
fixed_path_paper and "full_paper/fixed_path_paper": the goals under the paper's formula). --fixed-path adds the
strongest simple baseline (``evidence.fixed_path``): the scaling layer on one fixed path, the shuttle with the
elbow folded over the middle of the sweep, no planning; "full/fixed_path" says whether the planning layer earns its
place, "won_back_fixed_path" how much of the room that path alone uses.
--clairvoyant adds a bound that runs the real scaling layer (``evidence.clairvoyant``): the best sequence of fixed
leg shapes, one per leg, found with the people's future known by running the whole scenario with each; never below
scale_only or fixed_path on a scenario, and rising with its search; "full/clairvoyant" and "won_back_clairvoyant"
say how much of the room these shapes hold the planning layer uses.
--latency S runs every strategy with the people reaching the cell S s after their capture (a camera pipeline's;
``run_shuttle(latency=)``): the layers are given them that late, the zones are sized for it (the person's travel over
it at the ISO 13855 speed, as ISO 13855 counts a sensor's response time), and every command is judged against the
people of its moment. The JSON line says "latency_s".

Each (scenario, strategy) is one ``evidence.sweep.run_scenario``; they run in chunks on a local process pool,
or on dask.distributed with --dask [tcp://SCHEDULER:8786] (tools.sweep, docs/sweeps.md), each chunk's records
a Parquet file under --out/run-<its plan's hash>/records as it finishes: the same command again resumes a run
that was stopped, another one runs beside it, and
every figure is computed from those files.

    python bench/compare.py [--scenarios 1000] [--duration 12] [--workers N] [--out reports/compare] [--dask]
                            [--kinds two_humans,random_walk] [--seed 0] [--foresight] [--oracle]
                            [--forecaster mypackage.predict:MyForecaster] [--fixed-path] [--clairvoyant]
                            [--latency 0.03]

(--kinds: only these kinds, in turn, seeds counted from --seed: `--scenarios 200 --kinds two_humans` runs
200 two-person scenarios.)
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from evidence.scenarios import SCENARIO_KINDS, kinds_problem  # noqa: E402
from evidence.strategies import BASELINES, BOUNDS, PAPER, PAPER_BASELINES, STRATEGIES  # noqa: E402
from evidence.summary import aggregate, columns, per_kind, ratios, wide_rows, won_back  # noqa: E402
from evidence.sweep import ScenarioSpec, strategies_for  # noqa: E402
from shared.planning.forecast import forecaster_problem  # noqa: E402
from tools.arguments import sample_latency  # noqa: E402
from tools.sweep import SweepMismatch, code_version, plan_id, read_records, run_sweep  # noqa: E402


def plot(rows: list[dict], out: Path, by_kind: dict, intervals: dict) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kinds = sorted(by_kind)
    fig, axes = plt.subplots(1, 3, figsize=(18, 4.5), gridspec_kw={"width_ratios": [1, 1, 0.8]})
    shown_strategies = columns(rows)
    width = 0.8 / len(shown_strategies)
    x = np.arange(len(kinds))
    for i, strategy in enumerate(shown_strategies):
        offset = (i - (len(shown_strategies) - 1) / 2) * width
        axes[0].bar(x + offset, [by_kind[k][strategy]["shuttles_per_min"] for k in kinds], width,
                    label=strategy)
        axes[1].bar(x + offset, [by_kind[k][strategy]["stopped_fraction"] for k in kinds], width,
                    label=strategy)
    for ax, title in zip(axes, ("shuttles per minute (higher is better)", "fraction of time stopped")):
        ax.set_xticks(x, kinds)
        ax.set_title(title)
        ax.legend(fontsize=8)
    names = [k for k in kinds + ["overall"] if not isinstance(intervals[k]["full/scale_only"], str)]
    top = 1.3                       # a kind far above (a person standing in the path) is written, not drawn
    drawn = [(pair, colour, offset) for pair, colour, offset in
             (("full/scale_only", "tab:green", 0.0), ("foresight/scale_only", "tab:red", 0.15),
              ("oracle/scale_only", "tab:purple", 0.3)) if pair in intervals["overall"]]
    lowest = 0.95
    for row, (pair, colour, offset) in enumerate(drawn):
        where = [k for k, name in enumerate(names) if not isinstance(intervals[name][pair], str)]
        ratio = [intervals[names[k]][pair] for k in where]
        mid = np.array([r.ratio for r in ratio])
        shown = mid <= top
        axes[2].errorbar(np.array(where, dtype=float)[shown] + offset, mid[shown],
                         yerr=[(mid - [r.low for r in ratio])[shown], ([r.high for r in ratio] - mid)[shown]],
                         fmt="o", color=colour, capsize=4, label=pair)
        for k in np.flatnonzero(~shown):
            axes[2].annotate(f"{ratio[k].ratio:.2f}x [{ratio[k].low:.2f}, {ratio[k].high:.2f}]", (where[k], top),
                             xytext=(0, -14 - 12 * row), textcoords="offset points", ha="center",
                             fontsize=8, color=colour, arrowprops={"arrowstyle": "-|>", "color": colour})
        lowest = min([lowest] + [r.low - 0.01 for r in ratio])
    axes[2].axhline(1.0, color="tab:orange", lw=1)
    axes[2].set_ylim(lowest, top)
    axes[2].set_xticks(np.arange(len(names)), names, rotation=20)
    axes[2].set_title("against scale_only, paired bootstrap 95 % interval")
    if len(drawn) > 1:
        axes[2].legend(fontsize=8, loc="lower right")
    fig.suptitle(f"{len(rows)} seeded scenarios; violations (monitor): "
                 + ", ".join(f"{s} {sum(r[s]['violations'] for r in rows)}" for s in shown_strategies))
    fig.tight_layout()
    fig.savefig(out / "compare.png", dpi=80)
    plt.close(fig)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenarios", type=int, default=1000)
    parser.add_argument("--duration", type=float, default=12.0, help="simulated seconds per scenario")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                        help="processes on this machine (the local pool, or --dask's LocalCluster)")
    parser.add_argument("--dask", nargs="?", const="local", default=None, metavar="tcp://SCHEDULER:8786",
                        help="run on dask.distributed: this scheduler, or without an address a LocalCluster of "
                             "--workers processes (the same records as the local pool)")
    parser.add_argument("--out", type=Path, default=ROOT / "reports" / "compare")
    parser.add_argument("--seed", type=int, default=0, help="first scenario seed")
    parser.add_argument("--kinds", default=",".join(sorted(SCENARIO_KINDS)),
                        help="comma-separated scenario kinds, run in turn (default: every scripted kind; the real people's "
                             "real_table_edge and real_step_back when named, evidence.recorded)")
    parser.add_argument("--forecaster", metavar="MODULE:ATTRIBUTE",
                        help="the full strategy's forecast of the people (default: constant velocity): a "
                             "forecaster object, class or factory (shared.planning.forecast)")
    parser.add_argument("--foresight", action="store_true",
                        help="also run full told the people's scripted future: the bound on better prediction")
    parser.add_argument("--paper", action="store_true",
                        help="also run scale_only and full under the paper's formula (the measured human speed "
                             "held), judged by the shipped model's monitor: the shipped model's cost, side by side")
    parser.add_argument("--fixed-path", action="store_true",
                        help="also run the scaling layer on one fixed folded path, no planning "
                             "(evidence.fixed_path): the strongest simple baseline the planning layer must beat")
    parser.add_argument("--oracle", action="store_true",
                        help="also run the oracle (foresight, 8x the search, planning free of time): a reference "
                             "for the planning layer at its most, not a bound (several times full's run time)")
    parser.add_argument("--clairvoyant", action="store_true",
                        help="also run the clairvoyant bound (evidence.clairvoyant: the best sequence of fixed leg "
                             "shapes, found by running the whole scenario with each; about a hundred runs a scenario)")
    parser.add_argument("--latency", type=sample_latency, default=0.0, metavar="SECONDS",
                        help="the people reach the cell this long after their capture (a camera pipeline's), in "
                             "every strategy; the zones are sized for it (default 0)")
    args = parser.parse_args()
    if args.scenarios < 1 or args.duration <= 0 or args.workers < 1:
        parser.error("--scenarios and --workers must be >= 1, --duration > 0")
    kinds = sorted({k.strip() for k in args.kinds.split(",") if k.strip()})
    if problem := kinds_problem(kinds):
        parser.error(f"--kinds: {problem}")
    if args.forecaster is not None and (problem := forecaster_problem(args.forecaster)):
        parser.error(f"--forecaster: {problem}")
    run = (STRATEGIES + (BASELINES if args.fixed_path else ()) + tuple(b for b in BOUNDS if getattr(args, b))
           + (PAPER if args.paper else ()) + (PAPER_BASELINES if args.paper and args.fixed_path else ()))
    specs = [ScenarioSpec(kinds[k % len(kinds)], args.seed + k, args.duration, strategy, forecaster=args.forecaster,
                          latency=args.latency) for k in range(args.scenarios) for strategy in run]
    started = time.perf_counter()
    meta = {"bench": "compare", "code": code_version(ROOT)}
    folder = args.out / f"run-{plan_id(specs, meta=meta)}"      # the same command resumes its own run here
    try:
        done = run_sweep(specs, folder, executor="dask" if args.dask else "local", workers=args.workers,
                         address=None if args.dask in (None, "local") else args.dask, meta=meta)
    except SweepMismatch as exc:
        parser.error(str(exc))
    if done.failed:
        print(f"chunks {done.failed} failed: the figures below leave their scenarios out; rerun the same command "
              f"to fill them in", file=sys.stderr)
    print(f"{done.skipped} of {done.chunks} chunks were already in {folder / 'records'}; ran {done.ran}", flush=True)
    rows = [r for r in wide_rows(read_records(folder)) if all(s in r for s in run)]
    from shared.safety.parameters import SsmParameters
    horizon = SsmParameters().horizon
    strategies = aggregate(rows, horizon)
    nobody = strategies_for((), None).empty_cell(args.duration).summary()          # per minute as aggregate() counts it
    empty = round(nobody["shuttle_progress"] * 60.0 / nobody["duration_s"], 3)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "scenarios.json").write_text(json.dumps(rows))
    figures = per_kind(rows, horizon)
    per_kinds = {k: f["strategies"] for k, f in figures.items()}
    intervals = {k: f["ratios"] for k, f in figures.items()} | {"overall": ratios(rows)}
    print(f"empty cell: {empty:.2f}/min (nobody in it: the most any strategy can do); won back: the share of "
          f"what the people cost scale_only that full gets back")
    for kind, per in per_kinds.items():
        shares = {s: won_back(per, empty, s) for s in run if s == "full" or s in BOUNDS + BASELINES}
        print(f"{kind:<12} " + "  ".join(f"{s}: {per[s]['shuttles_per_min']:6.2f}/min stopped "
                                          f"{per[s]['stopped_fraction']:.2f} ({per[s]['stopped_s']:.1f} s, slowed "
                                          f"{per[s]['slowed_s']:.1f} s) viol {per[s]['violations']}"
                                          for s in run)
              + "".join(f"  {s} won back {100 * share:.0f} %" for s, share in shares.items() if share is not None))
    plot(rows, args.out, per_kinds, intervals)
    print("ratios of shuttles per minute with their paired bootstrap 95 % intervals:")
    for name, pairs in intervals.items():
        for pair, r in pairs.items():
            print(f"  {name:<12} {pair:<20} {r if isinstance(r, str) else r.describe()}")
    print(f"{len(rows)} scenarios x {args.duration:.0f} s in {time.perf_counter() - started:.0f} s on "
          f"{args.workers} workers; plot and per-scenario results in {args.out}")
    full, zones, scale = (strategies[s]["shuttles_per_min"] for s in ("full", "zones", "scale_only"))
    summary = {"bench": "compare", "scenarios": len(rows), "forecaster": args.forecaster or "constant velocity",
               "latency_s": args.latency,
               "strategies": strategies,
               "speedup_vs_zones": round(full / zones, 3) if zones else None,
               "speedup_vs_scale_only": round(full / scale, 3) if scale else None,
               "kinds": {k: {s: per_kinds[k][s]["shuttles_per_min"] for s in run} for k in kinds},
               "empty_cell": empty,
               "won_back": {k: won_back(per_kinds[k], empty) for k in kinds} | {"overall": won_back(strategies, empty)}}
    for bound in (b for b in run[len(STRATEGIES):] if b in BOUNDS + BASELINES):
        summary[f"won_back_{bound}"] = ({k: won_back(per_kinds[k], empty, bound) for k in kinds}
                                        | {"overall": won_back(strategies, empty, bound)})
    summary["ratios"] = {name: {pair: None if isinstance(r, str) else r.as_list() for pair, r in pairs.items()}
                         for name, pairs in intervals.items()}
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
