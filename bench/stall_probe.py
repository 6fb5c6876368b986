"""Who holds the CPUs when the cell hiccups: wake-up probes at several scheduling priorities (not a test: it prints
figures).

On a slow day the cell's timing has hiccups: the person feed (SCHED_FIFO 40) woke 75 ms late in a real-people run,
the robot driver (FIFO 60) missed SYNC answers, the scaler (FIFO 50) sent a command 20 ms apart. Either the
machine itself stopped (the hypervisor took the virtual CPUs away: nothing on it can do anything about that), or
the cell's own real-time processes held both cores for that long and starved those below them. One process per
priority sleeps to a deadline every `--period` and records how late it woke and every wake-up later than `--stall`
with its monotonic time (``tools.stalls``, the witness the demo runs at FIFO 99): a stall seen at every priority,
FIFO 99 included, is the machine's; one seen only below some priority is the work of the processes above it
(``shared.scheduling.PRIORITY``: robot_driver 60, hwsim 55, scaler 50, tracker_ingest 45, human_feed 40,
safety_monitor 30). Priority 0 is the normal class, where the planner and the demo's recorder run. The machine's steal time
(/proc/stat, per virtual CPU) over the window is printed beside it, and the CPU each probe woke on after a stall.

Run it beside the cell: ``python bench/stall_probe.py --seconds 60 & hrc demo ...``; the stall times are monotonic
seconds, the clock of every process on the machine (the demo's report counts from its own t0, printed in its log).

    python bench/stall_probe.py [--seconds 30] [--period 0.002] [--stall 0.005] [--priorities 99,57,52,47,42,32,0]

Last line: one JSON object.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tools.stalls import StallLog, fifo, steal_seconds, steal_ticks, witness  # noqa: E402

STALLS_KEPT = 200                  # the longest stalls listed per probe


def probe(priority: int, seconds: float, period: float, stall: float, phase: float, out) -> None:
    """One probe: this process at `priority` (SCHED_FIFO; 0: the normal class), waking every `period` s for
    `seconds`, `phase` s after the others' deadlines (probes that woke together would delay each other); puts its
    figures on the queue `out`."""
    scheduling = fifo(priority)
    log = StallLog(stall, STALLS_KEPT)
    start = round(time.monotonic(), 1) + 0.2 + phase      # a common grid: the probes' deadlines interleave
    witness(log, period, lambda: True, start=start, until=start + seconds)
    out.put({"priority": priority, "scheduling": scheduling, **log.figures()})


def arguments(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--period", type=float, default=0.002, help="s between a probe's wake-ups")
    parser.add_argument("--stall", type=float, default=0.005, help="s late: a wake-up listed as a stall")
    parser.add_argument("--priorities", default="99,57,52,47,42,32,0",
                        help="SCHED_FIFO priorities, one probe each (0: the normal class)")
    args = parser.parse_args(argv)
    try:
        args.priorities = [int(p) for p in args.priorities.split(",")]
    except ValueError:
        parser.error(f"--priorities: comma-separated integers 0..99, not {args.priorities!r}")
    if not all(0 <= p <= 99 for p in args.priorities):
        parser.error("--priorities: each in 0..99")
    if not (args.seconds > 0 and args.period > 0 and args.stall > 0):
        parser.error("--seconds, --period and --stall must be positive")
    return args


def main(argv: list[str] | None = None) -> int:
    args = arguments(argv)
    out = multiprocessing.Queue()
    steal0, t0 = steal_ticks(), time.monotonic()
    spread = args.period / len(args.priorities)
    procs = [multiprocessing.Process(target=probe, args=(p, args.seconds, args.period, args.stall, k * spread, out),
                                     daemon=True) for k, p in enumerate(args.priorities)]
    for proc in procs:
        proc.start()
    results = sorted((out.get() for _ in procs), key=lambda r: -r["priority"])
    for proc in procs:
        proc.join()
    window = time.monotonic() - t0
    steal = steal_seconds(steal0, steal_ticks())
    print(f"window {window:.1f} s from monotonic {t0:.3f}; steal (the hypervisor's, CPU-s): "
          + ", ".join(f"{cpu} {s:.2f}" for cpu, s in steal.items()))
    for r in results:
        top = ", ".join(f"{t:.3f}: {ms} ms on cpu{c}, steal {st:.0f} ms"
                        for t, ms, c, st in sorted(r["longest"], key=lambda s: -s[1])[:5])
        print(f"{r['scheduling']:>14}: late p99 {r['late_ms_p99']} ms, "
              f"max {r['late_ms_max']} ms; {r['stalls']} stalls > {1e3 * args.stall:.0f} ms  [{top}]")
    print(json.dumps({"bench": "stall_probe", "window_s": round(window, 2), "t0_monotonic": round(t0, 3),
                      "steal_cpu_s": steal, "period_s": args.period, "stall_s": args.stall,
                      "probes": results}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
