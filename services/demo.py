"""`hrc demo`: the paper's experiment on the real processes (the project's main job).

Starts the PRBT emulator and every service as child processes (services.launch), on kernel CAN (vcan0)
where there is one, else on udp_multicast inside a private network namespace that it makes for itself
(it re-runs itself under `unshare -rn`). Then, as the cell's operator and witness:
* a scripted human (shared.scenarios.paper_phases) goes out as raw tracker data at 120 Hz;
* goals shuttle the robot between q_s and q_g: the next goal when the robot has arrived, the same goal
  again when the planner refused it (the way may be blocked for now);
* everything the cell publishes is recorded; progress twice a second;
* at the end, the report folder (services.report; format in docs/report-format.md).
`--no-beta` runs the planner with replans on the scaling layer's request switched off.
"""

from __future__ import annotations

import os
import subprocess
import threading
import time
from pathlib import Path

import numpy as np

from services.launch import CellProcesses, LaunchError, free_port
from services.report import Recording, write_report
from shared.canbus import in_private_namespace
from shared.errors import MessageError
from shared.keys import KeySpace
from shared.messages import (DriverRequest, Goal, HumanRaw, HumanState, JointCommand, JointState, LatencyReport,
                             SafetyEvent, ScalerStatus, TrajectoryMsg, decode, encode)
from shared.scenarios import Q_GOAL, Q_START, ScriptedHuman, paper_phases
from shared.zenoh_session import open_session

PREFIX = "hrc/demo"
HUMAN_RATE = 120.0          # Hz, raw tracker samples
ARRIVED = 0.01              # rad: the robot is at its goal
GOAL_RETRY = 1.0            # s without a trajectory for the current goal: send it again


class Recorder:
    """Subscribes to every key of the cell and keeps what arrives (bad messages are counted, not kept)."""

    def __init__(self, session, keys: KeySpace, rec: Recording) -> None:
        self.rec, self.lock, self.bad = rec, threading.Lock(), 0
        self.latest: dict[type, object] = {}
        table = [(keys.scaler_status, ScalerStatus, rec.statuses), (keys.command, JointCommand, rec.commands),
                 (keys.joint_state, JointState, rec.joint_states), (keys.human_state, HumanState, rec.human_states),
                 (keys.trajectory, TrajectoryMsg, rec.trajectories), (keys.safety_events, SafetyEvent, rec.events),
                 (keys.latency, LatencyReport, rec.latency)]
        self.subs = [session.declare_subscriber(key, self._keeper(kind, store)) for key, kind, store in table]

    def _keeper(self, kind, store: list):
        def on_sample(sample):
            try:
                msg = decode(sample.payload.to_bytes(), kind)
            except MessageError:
                with self.lock:
                    self.bad += 1
                return
            with self.lock:
                store.append(msg)
                self.latest[kind] = msg
        return on_sample

    def get(self, kind):
        with self.lock:
            return self.latest.get(kind)

    def close(self) -> None:
        for sub in self.subs:
            sub.undeclare()


class HumanFeed(threading.Thread):
    """Publishes the scripted human as raw tracker data at HUMAN_RATE, time measured from t0."""

    def __init__(self, session, keys: KeySpace, human: ScriptedHuman, t0: float) -> None:
        super().__init__(daemon=True, name="human-feed")
        self.pub = session.declare_publisher(keys.human_raw)
        self.human, self.t0, self.running = human, t0, True

    def run(self) -> None:
        k = 0
        while self.running:
            k += 1
            due = self.t0 + k / HUMAN_RATE
            time.sleep(max(0.0, due - time.monotonic()))
            now = time.monotonic()
            caps = self.human.at(now - self.t0)
            self.pub.put(encode(HumanRaw(source="hrc demo", sample_time=now, segments=caps.segments,
                                         radii=caps.radii, seq=k, stamp=now)))


def choose_bus() -> tuple[str, str | None]:
    """Kernel CAN when vcan0 exists, else udp_multicast (which needs a private network namespace)."""
    return ("socketcan", "vcan0") if os.path.exists("/sys/class/net/vcan0") else ("udp_multicast", None)


def reexec_in_namespace(argv: list[str]) -> int | None:
    """When udp_multicast is needed and this process is not in a private namespace: run argv in a new one
    and return its exit code; None when no re-run is needed. Raises RuntimeError when none can be made."""
    from services.cell import in_new_namespace, namespace_reason

    if choose_bus()[0] != "udp_multicast" or in_private_namespace():
        return None
    reason = namespace_reason()
    if reason:
        raise RuntimeError(f"no kernel CAN (vcan0), and no private network namespace for udp_multicast ({reason}); "
                           "run 'hrc demo --sim' (in-process) instead")
    return subprocess.call(in_new_namespace(argv))


def run(out: Path, duration: float, phase_length: float, config_path: Path | None, seed: int, no_beta: bool,
        quiet: bool, robot, config) -> dict:
    """The experiment on the real processes; returns the summary (written to out/summary.json)."""
    interface, channel = choose_bus()
    keys = KeySpace(PREFIX)
    cell = CellProcesses(out / "logs", PREFIX, interface, channel, config_path, seed,
                         extra_args={"planner": ["--no-beta"]} if no_beta else {})
    say = (lambda *a: None) if quiet else (lambda text: print(text, flush=True))
    say(f"hrc demo: starting the cell (emulator + 5 services, CAN {interface}{' ' + channel if channel else ''}, "
        f"Zenoh {cell.endpoint}); logs in {out / 'logs'}")
    session = open_session("peer", listen=[f"tcp/127.0.0.1:{free_port()}"], connect=[cell.endpoint])
    rec = Recording(t0=time.monotonic())
    recorder = feed = None
    try:
        started = time.monotonic()
        cell.start(session)
        say(f"hrc demo: all services up in {time.monotonic() - started:.1f} s; {duration:.0f} s of the paper's four "
            f"phases{' (no beta replans)' if no_beta else ''}")
        recorder = Recorder(session, keys, rec)
        human = paper_phases(phase_length)
        rec.phase = human.phase
        rec.t0 = time.monotonic()
        feed = HumanFeed(session, keys, human, rec.t0)
        feed.start()
        _direct(session, keys, recorder, rec, duration, say)
        feed.running = False
        time.sleep(1.2)                             # the monitor's last summary (once a second)
        alive, cpu = cell.alive(), cell.cpu_seconds()
    except LaunchError as exc:
        raise RuntimeError(f"the cell did not start: {exc}") from None
    finally:
        if feed is not None:
            feed.running = False
        if recorder is not None:
            recorder.close()
        codes = cell.stop()
        session.close()
    say(f"hrc demo: cell stopped (exit codes {codes}); writing the report to {out}")
    extra = {"mode": "processes", "can": interface, "services_alive_at_end": alive, "exit_codes": codes,
             "cpu_s": cpu, "cpus": os.cpu_count(),
             "bad_messages_seen": recorder.bad, "no_beta": no_beta}
    return write_report(out, robot, config, rec, extra)


def _direct(session, keys: KeySpace, recorder: Recorder, rec: Recording, duration: float, say) -> None:
    """Shuttle goals, recovery requests and progress until duration has passed."""
    goal_pub = session.declare_publisher(keys.goal)
    req_pub = session.declare_publisher(keys.driver_request)
    ends = [Q_START, Q_GOAL]
    leg, goal_id = 0, 0
    goal_sent = last_recover = last_print = -1e9

    def send_goal(now: float) -> None:
        nonlocal goal_sent
        goal_sent = now
        goal_pub.put(encode(Goal(goal_id=goal_id, name="q_g" if leg % 2 == 0 else "q_s", q=ends[(leg + 1) % 2],
                                 seq=goal_id, stamp=now)))

    goal_id = 1
    send_goal(time.monotonic())
    seen_events = 0
    while (now := time.monotonic()) - rec.t0 < duration:
        with recorder.lock:
            new_events, seen_events = rec.events[seen_events:], len(rec.events)
        for e in new_events:
            if e.source == "planner" and e.event != "trajectory_goal" or e.severity != "info":
                say(f"t={e.stamp - rec.t0:6.2f}s  {e.source}: {e.event}: {e.text[:110]}")
        js, st = recorder.get(JointState), recorder.get(ScalerStatus)
        with recorder.lock:
            planned = any(t.goal_id == goal_id for t in rec.trajectories[-5:])
        target = ends[(leg + 1) % 2]
        if js is not None and st is not None and st.status == "finished" and np.abs(js.q - target).max() < ARRIVED \
                and planned:
            rec.shuttles += 1
            leg += 1
            goal_id += 1
            send_goal(now)
        elif not planned and now - goal_sent > GOAL_RETRY:
            send_goal(now)
        if js is not None and js.drive_state.startswith("stopped") and now - last_recover > 1.0:
            last_recover = now
            req_pub.put(encode(DriverRequest(action="recover", source="hrc demo", stamp=now)))
            say(f"t={now - rec.t0:6.2f}s  robot stopped ({js.drive_state}): asking the driver to recover")
        if now - last_print >= 0.5:
            last_print = now
            t = now - rec.t0
            sep = f"{st.min_separation:5.2f}" if st is not None and st.min_separation is not None else "  -  "
            say(f"t={t:6.2f}s  {rec.phase(t):<18} alpha={st.alpha if st else 0:4.2f} beta={int(st.beta) if st else 0} "
                f"sep={sep} m  v{st.trajectory_version if st else '-'}  shuttles={rec.shuttles}  "
                f"robot={js.drive_state.split(':')[0] if js else '-'}")
        time.sleep(0.02)
