"""The Dask path's overhead against the local process pool, side by side on the same scenarios and workers
(not a test: it prints figures). Each executor runs the same specs into a fresh folder, alternately, `rounds`
times (this machine's speed drifts within minutes: alternating pairs each Dask run with a pool run of the same
minutes). Printed per run and as medians: elapsed seconds, scenarios per second, scenarios per worker-second
(elapsed x workers: the capacity the run held), and the Dask/pool ratio of elapsed time, split into the runs'
own time (the records' wall_s, per worker) and the time around them; that the records are identical is checked
too. A LocalCluster's start is counted in its run (it is part of what `--dask` costs on
one machine), and printed apart; with a standing scheduler (`--address`) there is none.

    python bench/sweep.py [--scenarios 40] [--duration 4] [--workers 2] [--rounds 2] [--address tcp://...]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from evidence.scenarios import SCENARIO_KINDS  # noqa: E402
from evidence.sweep import ScenarioSpec  # noqa: E402
from tools.sweep import Progress, read_records, run_sweep  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenarios", type=int, default=40)
    parser.add_argument("--duration", type=float, default=4.0, help="simulated seconds per scenario")
    parser.add_argument("--strategies", default="scale_only,full")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--chunk", type=int, default=8)
    parser.add_argument("--address", default=None, help="a running Dask scheduler instead of a LocalCluster")
    args = parser.parse_args()
    if min(args.scenarios, args.workers, args.rounds, args.chunk) < 1 or not args.duration > 0:
        parser.error("--scenarios, --workers, --rounds and --chunk must be >= 1, --duration > 0")
    kinds = sorted(SCENARIO_KINDS)
    strategies = [s.strip() for s in args.strategies.split(",") if s.strip()]
    specs = [ScenarioSpec(kinds[k % len(kinds)], k, args.duration, s) for k in range(args.scenarios)
             for s in strategies]
    runs: dict[str, list[float]] = {"local": [], "dask": []}
    tasks: dict[str, list[float]] = {"local": [], "dask": []}     # the runs' own seconds, per worker
    startup: list[float] = []
    records: dict[str, list] = {}
    scratch = Path(tempfile.mkdtemp(prefix="hrc-sweep-bench-"))
    try:
        for r in range(args.rounds):
            for executor in ("local", "dask"):
                out = scratch / f"{executor}-{r}"
                started = time.perf_counter()
                done = run_sweep(specs, out, executor=executor, workers=args.workers, address=args.address,
                                 chunk=args.chunk, progress=Progress(len(specs), stream=open(os.devnull, "w")))
                elapsed = time.perf_counter() - started
                if done.failed:
                    print(f"{executor}: chunks {done.failed} failed", file=sys.stderr)
                    return 1
                runs[executor].append(elapsed)
                if executor == "dask":
                    startup.append(done.startup_s)
                written = read_records(out)
                got = [{k: v for k, v in rec.items() if k != "wall_s"} for rec in written]
                records.setdefault(executor, got)
                tasks[executor].append(sum(rec["wall_s"] for rec in written) / args.workers)
                print(f"round {r + 1} {executor:<5} {elapsed:6.1f} s  {len(specs) / elapsed:5.2f} runs/s  "
                      f"{len(specs) / (elapsed * args.workers):5.3f} runs per worker-second; in the runs "
                      f"{tasks[executor][-1]:.1f} s a worker, around them {elapsed - tasks[executor][-1]:.1f} s"
                      + (f" (of it {done.startup_s:.1f} s starting the cluster)" if executor == "dask" else ""), flush=True)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    identical = json.dumps(records["local"], sort_keys=True) == json.dumps(records["dask"], sort_keys=True)
    local, dask = statistics.median(runs["local"]), statistics.median(runs["dask"])
    ratios = [d / lo for d, lo in zip(runs["dask"], runs["local"])]
    running = [(d - st) / lo for d, st, lo in zip(runs["dask"], startup, runs["local"])]
    in_runs = [d / lo for d, lo in zip(tasks["dask"], tasks["local"])]
    around = [(d - dt) - (lo - lt) for d, dt, lo, lt in zip(runs["dask"], tasks["dask"], runs["local"], tasks["local"])]
    print(f"median: pool {local:.1f} s, dask {dask:.1f} s; dask/pool elapsed {statistics.median(ratios):.3f} "
          f"(per round {', '.join(f'{x:.3f}' for x in ratios)}); without starting the cluster "
          f"{statistics.median(running):.3f}; records identical: {identical}")
    print(f"where: the runs themselves dask/pool {statistics.median(in_runs):.3f} (per round "
          f"{', '.join(f'{x:.3f}' for x in in_runs)}); around the runs dask - pool {statistics.median(around):+.1f} s "
          f"(per round {', '.join(f'{x:+.1f}' for x in around)}: starting, importing, closing, the last chunk's wait)")
    print(json.dumps({"bench": "sweep", "runs": len(specs), "workers": args.workers, "duration": args.duration,
                      "pool_s": runs["local"], "dask_s": runs["dask"], "dask_over_pool": round(statistics.median(ratios), 4),
                      "dask_over_pool_started": round(statistics.median(running), 4), "dask_startup_s": startup,
                      "runs_dask_over_pool": round(statistics.median(in_runs), 4),
                      "around_runs_dask_minus_pool_s": round(statistics.median(around), 2),
                      "pool_runs_per_worker_s": round(len(specs) / (local * args.workers), 4),
                      "dask_runs_per_worker_s": round(len(specs) / (dask * args.workers), 4),
                      "records_identical": identical}))
    return 0 if identical else 1


if __name__ == "__main__":
    sys.exit(main())
