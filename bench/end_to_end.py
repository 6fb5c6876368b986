"""End-to-end benchmark of the running cell (not a test: it prints figures).

Runs the paper's experiment on the real processes (`hrc demo`'s runner: the emulator on CAN, every
service over Zenoh; on udp_multicast it re-runs itself in a private network namespace) and reports:
* sample_to_frame_ms: from a human sample entering tracker_ingest to the target frame on the CAN bus
  that was computed from it (measured by the robot driver for every such chain, one monotonic clock);
* processing_ms: the part of that which is not waiting for the scaler's next tick;
* replan_stall_ms: for every replan request (beta), the time the robot stood or stayed on the old
  trajectory until it moved on the new one (or the request cleared);
* monitor_lag_ms: how far behind the independent monitor checked the joint states (p99 and max over its
  run), and how many states it left unchecked;
* drive_lag_ms: the worst per-joint p99 lag of the measured joints behind the driver's setpoints;
and whether the configured T_r covers the measured p99 (the driver warns on the bus when it does not).
The last line is one JSON object.

    python bench/end_to_end.py [--duration 24] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from shared.config import load_config  # noqa: E402
from shared.robot.model import default_robot  # noqa: E402
from tools import demo  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--duration", type=float, default=24.0, help="seconds of the experiment (default 24)")
    parser.add_argument("--out", type=Path, default=None, help="keep the report folder here")
    args = parser.parse_args()
    code = demo.reexec_in_namespace([sys.executable, str(Path(__file__).resolve()), *sys.argv[1:]])
    if code is not None:
        return code
    config = load_config(None)
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        summary = demo.run(out, args.duration, args.duration / 4, None, 1, False, True, default_robot(), config)
    lat, stalls = summary["latency"], summary["replan_stall_ms"]
    print(f"chains measured: {lat['chains']} over {summary['duration_s']:.0f} s "
          f"({summary['cycles_completed']} control cycles, mean {summary['mean_cycle_s'] * 1e3:.2f} ms)")
    print(f"sample -> frame: p50 {lat['sample_to_frame_ms']['p50']} ms, p99 {lat['sample_to_frame_ms']['p99']} ms "
          f"(goal p99 <= 13 ms at a 10 ms SYNC)")
    print(f"processing:      p50 {lat['processing_ms']['p50']} ms, p99 {lat['processing_ms']['p99']} ms (goal p99 <= 3 ms)")
    print(f"replan stalls:   {[e['stall_ms'] for e in stalls['episodes']]} ms "
          f"(median {stalls['median']}, goal <= 100 ms)")
    mon, drives = summary["monitor_check"], summary["drives"]
    drive_lag = max(drives["lag_p99_ms"] or [0.0])
    print(f"monitor:         checked {mon['lag_ms']['p99']} ms behind (p99; max {mon['lag_ms']['max']} ms; goal p99 "
          f"<= 50 ms), {mon['unchecked']} of {(mon['checks'] or 0) + (mon['unchecked'] or 0)} states unchecked, "
          f"count {'disagrees with' if mon['disagrees'] else 'matches'} the recount")
    print(f"drive lag:       p99 {drive_lag} ms (goal <= 20 ms), drive faults {len(drives['faults'])}")
    print(f"T_r = {summary['reaction_time_s'] * 1e3:.0f} ms covers the measured p99: {summary['reaction_time_covers_p99']}; "
          f"violations counted by the monitor: {summary['violations']}")
    print(json.dumps({"bench": "end_to_end",
                      "sample_to_frame_ms": lat["sample_to_frame_ms"], "processing_ms": lat["processing_ms"],
                      "replan_stall_ms": {"median": stalls["median"], "max": stalls["max"]},
                      "chains": lat["chains"], "reaction_time_ms": summary["reaction_time_s"] * 1e3,
                      "reaction_time_covers_p99": summary["reaction_time_covers_p99"],
                      "violations": summary["violations"],
                      "monitor_lag_ms": {"p99": mon["lag_ms"]["p99"], "max": mon["lag_ms"]["max"]},
                      "unchecked": mon["unchecked"], "monitor_disagrees": mon["disagrees"],
                      "drive_lag_ms": drive_lag, "drive_faults": len(drives["faults"]),
                      "exceedances_after_reaction_time": summary["exceedances_after_reaction_time"]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
