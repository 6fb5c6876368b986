"""Benchmark of the cell's CPU budget (not a test: it prints figures).

The whole cell on its processes, as `hrc demo` runs it (the PRBT emulator on CAN, the robot driver,
tracker_ingest, the scaler, the planner, the safety monitor), at 100 Hz, shuttling between q_s and q_g
while two scripted people (10 capsules: one crossing, one wandering) move through the cell. After a
warm-up, each process's CPU time (user + system, /proc) is read at the start and the end of the measured
window: its steady-state share of one core. Goals (the safety-chain issue): robot_driver + scaler +
tracker_ingest + safety_monitor together <= 40 % of one core, the emulator <= 10 %, the planner idle when
nothing needs planning. With people moving through the cell it also counts the drive faults (EMCY) and
the driver's clamp warnings: a robot that trips its drives in ordinary work is not usable. Each process's
share is split by thread (the OS's thread names: zenoh's runtime threads rx/tx/net/acc, zenoh-callback,
can-receive, can-cycle; 'python' is the main thread), so a hot spot is found before anything is tuned.
A fixed pure-Python loop is timed before the cell starts and after it stops (``reference_loop_ms``): this
VM's cores change speed from minute to minute, and two runs' shares compare only next to it.

udp_multicast runs inside a private network namespace: the script re-runs itself in one when needed.
Last line: one JSON object.

With --people far, one person stands 2.8 m away the whole time: nothing needs planning but each new
shuttle's direct line, and the planner's share says what it costs at rest.

With --ros2 the ROS 2 bridge runs too, with a subscriber of every ROS 2 topic: its own share, and the safety
chain's beside it.

    python bench/cell_cpu.py [--seconds 60] [--warmup 8] [--seed 1] [--people two|far] [--ros2]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from evidence.scenarios import IN_PATH, Keyframe, ScriptedHuman, make_scenario  # noqa: E402
from shared.transport.zenoh_session import open_session  # noqa: E402
from shared.wire.keys import KeySpace  # noqa: E402
from tools.actors import HumanFeed, Recorder, Shuttle  # noqa: E402
from tools.cell import choose_bus  # noqa: E402
from tools.demo import reexec_in_namespace  # noqa: E402
from tools.launch import CellProcesses, free_port  # noqa: E402
from tools.programs import SERVICES  # noqa: E402
from tools.report import Recording  # noqa: E402

SAFETY_CHAIN = ("robot_driver", "scaler", "tracker_ingest", "safety_monitor")


def reference_loop_ms(repeats: int = 5) -> float:
    """How fast this machine runs Python right now: the median time (ms) of a fixed pure-Python loop. A VM's
    cores change speed within minutes (docs/measurements.md), so shares of a
    core from two runs compare only next to this figure."""
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        total = 0
        for k in range(200_000):
            total += k & 7
        times.append((time.perf_counter() - started) * 1e3)
    return round(sorted(times)[repeats // 2], 2)


def far_person(duration: float) -> ScriptedHuman:
    """One person standing 2.8 m from the robot's axis, out of its reach, for `duration` seconds."""
    return ScriptedHuman([Keyframe(0.0, -2.8, 0.0, 0.0, IN_PATH, "far away"),
                          Keyframe(duration, -2.8, 0.0, 0.0, IN_PATH, "far away")])


def measure(seconds: float, warmup: float, seed: int, people_kind: str = "two", ros2: bool = False) -> dict:
    speed = [reference_loop_ms()]              # the machine's speed before the cell starts and after it stops
    interface, channel = choose_bus()
    keys = KeySpace("bench/cpu")
    with tempfile.TemporaryDirectory(prefix="hrc-cell-cpu-") as tmp:
        services = SERVICES + (("ros2_bridge",) if ros2 else ())
        cell = CellProcesses(Path(tmp), keys.prefix, interface, channel, planner_seed=seed, services=services)
        session = open_session("peer", listen=[f"tcp/127.0.0.1:{free_port()}"], connect=[cell.endpoint])
        feed = recorder = None
        try:
            cell.start(session)
            rec = Recording(t0=time.monotonic())
            recorder = Recorder(session, keys, rec)
            length = warmup + seconds + 5.0
            people = make_scenario("two_humans", seed, length) if people_kind == "two" else far_person(length)
            capsules = people.at(0.0).count
            feed = HumanFeed(session, keys, people, rec.t0, source="bench")
            feed.start()
            ros_samples = [0]
            ros_subs = [session.declare_subscriber("0/**", lambda s: ros_samples.__setitem__(0, ros_samples[0] + 1))] \
                if ros2 else []                      # a ROS 2 subscriber of every topic, so the bridge's puts go somewhere
            shuttle = Shuttle(session, keys, recorder, rec)
            shuttle.start(time.monotonic())
            t_start = rec.t0 + warmup
            before = None
            while (now := time.monotonic()) < t_start + seconds:
                if before is None and now >= t_start:
                    before, t_before, threads_before = cell.cpu_seconds(), now, cell.thread_cpu_seconds()
                shuttle.step(now)
                recorder.wait_finished(0.02)
            after, t_after, threads_after = cell.cpu_seconds(), time.monotonic(), cell.thread_cpu_seconds()
            shuttles, statuses = rec.shuttles, len(rec.statuses)
            faults = [e.text for e in rec.events if e.source == "robot_driver" and e.event in ("emcy", "drive_fault")]
            clamps = sum(e.event == "command_clamped" for e in rec.events)
            for sub in ros_subs:
                sub.undeclare()
        finally:
            if feed is not None:
                feed.running = False
            if recorder is not None:
                recorder.close()
            cell.stop()
            session.close()
    speed.append(reference_loop_ms())
    span = t_after - t_before
    share = {name: round(100.0 * (after[name] - before[name]) / span, 1) for name in after if name in before}
    threads = {name: {t: round(100.0 * (cpu - threads_before.get(name, {}).get(t, 0.0)) / span, 1)
                      for t, cpu in sorted(per.items(), key=lambda kv: -kv[1])}
               for name, per in threads_after.items()}
    return {"bench": "cell_cpu", "seconds": round(span, 1), "people": people_kind, "capsules": capsules, "can": interface,
            "percent_of_core": share, "threads": threads,
            "services_total": round(sum(share.get(n, 0.0) for n in SAFETY_CHAIN), 1),
            "emulator": share.get("hwsim"), "planner": share.get("planner"), "ros2_bridge": share.get("ros2_bridge"),
            "ros2_samples_per_s": round(ros_samples[0] / (t_after - rec.t0), 1) if ros2 else None,
            "total": round(sum(share.values()), 1), "shuttles": shuttles, "drive_faults": faults,
            "command_clamped": clamps, "reference_loop_ms": speed,
            "control_rate_hz": round(statuses / (t_after - rec.t0), 1)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=60.0, help="measured window (s)")
    parser.add_argument("--warmup", type=float, default=8.0, help="running before the window opens (s)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--people", choices=("two", "far"), default="two",
                        help="two people moving through the cell (default), or one standing far away")
    parser.add_argument("--ros2", action="store_true",
                        help="also run the ROS 2 bridge (services.ros2_bridge) with a subscriber of every ROS 2 topic: "
                             "its share, and whether the safety chain keeps its own")
    args = parser.parse_args()
    if args.seconds <= 0 or args.warmup < 0:
        parser.error("--seconds must be positive and --warmup not negative")
    code = reexec_in_namespace([sys.executable, __file__, *sys.argv[1:]])
    if code is not None:
        return code
    result = measure(args.seconds, args.warmup, args.seed, args.people, args.ros2)
    for name, pct in sorted(result["percent_of_core"].items(), key=lambda kv: -kv[1]):
        busiest = sorted(result["threads"].get(name, {}).items(), key=lambda kv: -kv[1])[:4]
        print(f"{name:<16} {pct:5.1f} % of one core   ({', '.join(f'{t} {p}' for t, p in busiest if p > 0)})")
    print(f"safety chain (driver + scaler + tracker + monitor): {result['services_total']} % (goal <= 40); "
          f"emulator {result['emulator']} % (goal <= 10); all {result['total']} %; {result['capsules']} capsules, "
          f"{result['shuttles']} shuttles, control {result['control_rate_hz']} Hz; drive faults "
          f"{len(result['drive_faults'])}, clamp warnings {result['command_clamped']}")
    print(f"machine speed: a fixed Python loop took {result['reference_loop_ms'][0]} ms before the cell started and "
          f"{result['reference_loop_ms'][1]} ms after it stopped (compare shares of a core only between runs where "
          "it took about as long)")
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
