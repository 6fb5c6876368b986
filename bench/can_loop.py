"""Benchmark of the CAN loop: the PRBT emulator and the robot driver as separate processes (not a test:
it prints figures).

* SYNC jitter: |interval - period| of the SYNC frames as seen on the bus;
* command to frame: a joint command published on Zenoh until the RPDO1 frame carrying that setpoint is
  on the bus (its kernel receive stamp; the driver forwards a command at once while running; the drives
  latch it at the next SYNC);
* state to Zenoh: the TPDO3 frame with a new position until the joint state with that position arrives;
* following at 0.95 of the velocity limit (the HIL harness's fast_following: joint 1 on a trapezoid at
  1.49 rad/s, 3 rad/s^2): the lag of the measured joint behind the driver's setpoints (the driver's own
  DriveLagReport, p99 per second) and the drives' largest following error (0x60F4), and any EMCY.

udp_multicast runs inside a private network namespace: the script re-runs itself under `unshare -n`
(`-rn` when not root) when it is not in one, as `hrc demo` and `hrc up` run the cell, so the driver and
the emulator get the SCHED_FIFO they get there (a user namespace would take it away). Last line: one JSON object.

    python bench/can_loop.py [--seconds 10] [--interface socketcan --channel vcan0]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "hil"))

from shared.drives.bus import in_private_namespace  # noqa: E402
from shared.drives.prbt import to_counts  # noqa: E402


def pct(values, p):
    return round(float(np.percentile(values, p)), 3) if len(values) else None


def measure(interface: str, channel: str | None, seconds: float) -> dict:
    import harness  # the HIL harness's process management, reused

    from shared.scheduling import realtime
    # this process plays the scaler (it sends the commands and takes the joint states): it runs as the
    # scaler does in the cell (the GIL handed over every 0.5 ms too), so what is measured is the loop, not this
    # process waiting behind a busy CPU
    scheduling = realtime("scaler")

    if interface == "udp_multicast":
        for cmd in (["ip", "link", "set", "lo", "up"], ["ip", "link", "set", "lo", "multicast", "on"],
                    ["ip", "route", "add", "224.0.0.0/4", "dev", "lo"]):
            subprocess.run(cmd, check=True)
    cell = harness.Cell(interface, channel)
    cell.start()
    frames: dict[int, list[float]] = {}     # setpoint counts -> times RPDO1 of node 3 carried it
    tpdo: dict[int, list[float]] = {}       # position counts -> times TPDO3 of node 3 carried it
    syncs_seen: list[float] = []            # receive stamps (CLOCK_REALTIME) of every SYNC frame
    lock = threading.Lock()

    # a frame is timed by its kernel receive stamp (CLOCK_REALTIME, as the SYNC jitter is), brought onto the
    # monotonic clock the command was timed on: when it was on the bus, not when this process's listener
    # thread got round to it (under load that wake-up was most of the measured p99)
    realtime_ahead = time.time() - time.monotonic()

    def on_rpdo(can_id, data, ts):
        if len(data) == 8:
            counts = int.from_bytes(data[4:8], "little", signed=True)
            with lock:
                frames.setdefault(counts, []).append(ts - realtime_ahead)

    def on_tpdo(can_id, data, ts):
        if len(data) >= 4:
            counts = int.from_bytes(data[0:4], "little", signed=True)
            with lock:
                tpdo.setdefault(counts, []).append(time.monotonic())

    def on_sync(can_id, data, ts):
        with lock:
            syncs_seen.append(ts)

    # the campaign's own CAN node (the harness's CanProbe) listens beside the driver: the frames as on the bus
    cell.can.network.subscribe(0x203, on_rpdo)
    cell.can.network.subscribe(0x383, on_tpdo)
    cell.can.network.subscribe(0x080, on_sync)
    try:
        if cell.hold_until(lambda s: s.enabled, 10.0) is None:
            raise RuntimeError("the drives did not enable")
        q = cell.latest().q.copy()
        sent: list[tuple[int, float]] = []
        with lock:
            sync_start = len(syncs_seen)
        state_start = len(cell.states)
        t_end = time.monotonic() + seconds
        k = 0
        while time.monotonic() < t_end:          # a slow sine on joint 1, a new setpoint every 10 ms
            k += 1
            q[0] = 1.57 - 0.2 * np.sin(k * 0.01)
            qd = np.zeros(6)
            qd[0] = -0.2 * np.cos(k * 0.01)           # rad/s: the sine's own velocity, as the scaler sends it
            counts = to_counts(q[0])
            t_pub = time.monotonic()
            cell.command(q, qd)
            sent.append((counts, t_pub))
            time.sleep(0.01 - (time.monotonic() - t_pub) % 0.01)
        time.sleep(0.1)
        with lock:
            syncs = np.diff(np.array(syncs_seen[sync_start:])) * 1e3
        jitter = np.abs(syncs - 10.0)
        with lock:
            # the first frame with that setpoint after it was published; the last TPDO3 with that
            # position before the state arrived (positions and setpoints recur along the sine)
            cmd = [(min(f for f in frames[c] if f >= t) - t) * 1e3 for c, t in sent
                   if any(f >= t for f in frames.get(c, []))]
            lat = []
            for t_state, st in list(cell.states[state_start:]):
                before = [f for f in tpdo.get(to_counts(float(st.q[0])), []) if f <= t_state]
                if before:
                    lat.append((t_state - max(before)) * 1e3)
        following = harness.fast_following(cell)
    finally:
        cell.stop()
    return {"bench": "can_loop", "transport": f"{interface}:{channel or ''}", "bench_scheduling": scheduling,
            "sync_jitter_ms": {"p50": pct(jitter, 50), "p99": pct(jitter, 99), "max": round(float(jitter.max()), 3)},
            "command_to_frame_ms": {"p50": pct(cmd, 50), "p99": pct(cmd, 99)},
            "state_to_zenoh_ms": {"p50": pct(lat, 50), "p99": pct(lat, 99)},
            "following_095": {"lag_p99_ms": max(following["lag_p99_ms"], default=None),
                              "following_error_max_rad": following["following_error_max_rad"],
                              "drive_faults": following["emcy"], "ok": following["ok"]},
            "samples": {"syncs": int(len(syncs)), "commands": len(cmd), "states": len(lat)}}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--interface", default="udp_multicast")
    parser.add_argument("--channel", default=None)
    parser.add_argument("--seconds", type=float, default=10.0)
    args = parser.parse_args()
    if args.interface == "udp_multicast" and not in_private_namespace():
        from tools.cell import unshare_flags

        # as the cell runs: root keeps SCHED_FIFO (no user namespace)
        return subprocess.call(["unshare", unshare_flags(), sys.executable, __file__, *sys.argv[1:]])
    result = measure(args.interface, args.channel, args.seconds)
    print(f"this process (in the scaler's place): {result['bench_scheduling']}")
    print(f"SYNC jitter: p50 {result['sync_jitter_ms']['p50']} ms, p99 {result['sync_jitter_ms']['p99']} ms, "
          f"max {result['sync_jitter_ms']['max']} ms ({result['samples']['syncs']} periods)")
    print(f"command to frame: p50 {result['command_to_frame_ms']['p50']} ms, p99 {result['command_to_frame_ms']['p99']} ms")
    print(f"state to Zenoh:   p50 {result['state_to_zenoh_ms']['p50']} ms, p99 {result['state_to_zenoh_ms']['p99']} ms")
    f = result["following_095"]
    print(f"following at 0.95 v_max: lag p99 {f['lag_p99_ms']} ms (goal <= 20), following error max "
          f"{f['following_error_max_rad']} rad, drive faults {f['drive_faults'] or 'none'}")
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
