"""Hardware-in-the-loop harness: the emulator and the robot driver as separate processes on a CAN bus,
driven and observed from here over Zenoh (commands, joint states, safety events) and CAN (fault
injection by SDO, EMCY frames, garbage frames). Prints one JSON object with the result of each scenario.

Run it inside a private network namespace for udp_multicast (the tests do: unshare -n as root, else -rn), or with
--interface socketcan --channel vcan0 where the kernel has vcan. Every process it starts is its child,
dies with it (PR_SET_PDEATHSIG) and is ended by PID at the end.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import can
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from evidence.scenarios import Q_GOAL, Q_START  # noqa: E402
from shared.drives.prbt import (  # noqa: E402
    INJECT_DRIVE_FAULT,
    INJECT_DROP,
    INJECT_FREEZE,
    INJECT_HEARTBEAT_OFF,
    NODE_IDS,
)
from shared.transport.zenoh_session import await_liveliness, open_session  # noqa: E402
from shared.wire.keys import KeySpace  # noqa: E402
from shared.wire.messages import DriveLagReport, DriverRequest, JointCommand, JointState, SafetyEvent, decode, encode  # noqa: E402
from tests.util import free_port  # noqa: E402
from tools.actors import HeldHuman, HumanFeed  # noqa: E402
from tools.faults import CanProbe  # noqa: E402
from tools.launch import die_with_parent  # noqa: E402
from tools.programs import BY_NAME  # noqa: E402

Q0 = Q_START
PERIOD = 0.01


class Cell:
    def __init__(self, interface: str, channel: str | None, with_scaler: bool = False,
                 with_planner: bool = False, with_tracker: bool = False) -> None:
        self.interface, self.channel = interface, channel
        self.with_tracker = with_tracker
        self.with_scaler = with_scaler or with_planner or with_tracker
        self.with_planner = with_planner
        self.port = free_port()
        self.keys = KeySpace("hil/cell")
        self.procs: dict[str, subprocess.Popen] = {}
        self.states: list[tuple[float, JointState]] = []
        self.events: list[tuple[float, SafetyEvent]] = []
        self.lock = threading.Lock()
        self.seq = 0

    def _spawn(self, name: str, args: list[str]) -> None:
        env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")
        self.procs[name] = subprocess.Popen([sys.executable, "-X", "faulthandler", "-m", *args], cwd=ROOT, env=env,
                                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                            preexec_fn=die_with_parent)

    def _start(self, name: str, *extra: str, timeout: float = 20.0) -> None:
        """One program of the cell's table (tools.programs), started and waited for as the table says; peers
        do not forward: each listens on its own port (the driver on the cell's), gossip meshes them."""
        program = BY_NAME[name]
        listen = f"tcp/127.0.0.1:{self.port if program.hub else free_port()}"
        self._spawn(name, program.argv(interface=self.interface, channel=self.channel, prefix=self.keys.prefix,
                                       listen=listen, connect=f"tcp/127.0.0.1:{self.port}",
                                       extra=[*extra, "--log-level", "WARNING"] if program.on_zenoh else extra))
        self._expect_line(name, program.ready, timeout=timeout)

    def start(self) -> None:
        self._start("hwsim")
        self._start("robot_driver", timeout=30)
        wanted = (("scaler", self.with_scaler), ("tracker_ingest", self.with_tracker),
                  ("safety_monitor", self.with_tracker), ("planner", self.with_planner))
        for name, on in wanted:
            if on:
                self._start(name, *(["--seed", "3"] if name == "planner" else []))
        self.session = open_session("peer", listen=[f"tcp/127.0.0.1:{free_port()}"],
                                    connect=[f"tcp/127.0.0.1:{self.port}"])
        self.cmd_pub = self.session.declare_publisher(self.keys.command)
        self.req_pub = self.session.declare_publisher(self.keys.driver_request)
        self.drive_lag: list[DriveLagReport] = []
        self.subs = [self.session.declare_subscriber(self.keys.joint_state, self._on_state),
                     self.session.declare_subscriber(self.keys.safety_events, self._on_event),
                     self.session.declare_subscriber(self.keys.drive_lag, self._on_drive_lag)]
        # peers do not forward: a put reaches a service only once this session is linked to it directly
        # (gossip builds the mesh a little after start); wait for each service's liveliness token
        for service in [name for name, on in (("scaler", self.with_scaler), ("tracker_ingest", self.with_tracker),
                                              ("safety_monitor", self.with_tracker), ("planner", self.with_planner))
                        if on]:
            self._await_token(service)
        self.can = CanProbe(self.interface, self.channel)        # SDO fault injection, every EMCY recorded

    def _await_token(self, service: str, timeout: float = 10.0) -> None:
        if not await_liveliness(self.session, self.keys.alive(service), timeout):
            raise RuntimeError(f"no liveliness token from {service} within {timeout:.0f} s")

    def _expect_line(self, name: str, text: str, timeout: float = 20.0) -> None:
        proc = self.procs[name]
        deadline = time.monotonic() + timeout
        seen: list[str] = []
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if text in line:
                threading.Thread(target=self._drain, args=(name,), daemon=True).start()
                return
            seen.append(line)
            if not line and proc.poll() is not None:
                break
        raise RuntimeError(f"{name} did not start (exit {proc.poll()}): " + "".join(seen[-15:]))

    def _drain(self, name: str) -> None:
        for line in self.procs[name].stdout:
            if os.environ.get("HIL_VERBOSE"):
                sys.stderr.write(f"[{name}] {line}")

    def _on_state(self, sample) -> None:
        msg = decode(sample.payload.to_bytes(), JointState)
        with self.lock:
            self.states.append((time.monotonic(), msg))

    def _on_drive_lag(self, sample) -> None:
        msg = decode(sample.payload.to_bytes(), DriveLagReport)
        with self.lock:
            self.drive_lag.append(msg)

    def _on_event(self, sample) -> None:
        msg = decode(sample.payload.to_bytes(), SafetyEvent)
        with self.lock:
            self.events.append((time.monotonic(), msg))

    # ------------------------------------------------------------------------------------------ helpers
    def latest(self) -> JointState | None:
        with self.lock:
            return self.states[-1][1] if self.states else None

    def command(self, q: np.ndarray, qd: np.ndarray | None = None) -> None:
        """A joint command as the scaler sends it: position and velocity (none given: at rest)."""
        self.seq += 1
        self.cmd_pub.put(encode(JointCommand(q=np.asarray(q, float), qd=np.zeros(6) if qd is None else np.asarray(qd, float),
                                             trajectory_version=0, s=0.0, seq=self.seq, stamp=time.monotonic())))

    def request(self, action: str) -> None:
        self.req_pub.put(encode(DriverRequest(action=action, source="hil")))

    def hold_until(self, condition, timeout: float, q: np.ndarray | None = None) -> float | None:
        """Send commands (q, or the measured position) every period until condition(); its time or None."""
        start = time.monotonic()
        while time.monotonic() - start < timeout:
            state = self.latest()
            if q is not None:
                self.command(q)
            elif state is not None:
                self.command(state.q)
            if state is not None and condition(state):
                return time.monotonic() - start
            time.sleep(PERIOD)
        return None

    def events_since(self, t0: float) -> list[tuple[float, SafetyEvent]]:
        with self.lock:
            return [(t, e) for t, e in self.events if t >= t0]

    def stop(self) -> None:
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGCONT)
                proc.terminate()
        for proc in self.procs.values():
            try:
                proc.wait(5)
            except subprocess.TimeoutExpired:
                proc.kill()
        try:
            self.can.close()
            self.session.close()
        except Exception:
            pass


def recover(cell: Cell, timeout: float = 5.0) -> bool:
    cell.request("recover")
    return cell.hold_until(lambda s: s.enabled, timeout) is not None


# ---------------------------------------------------------------------------------------------- scenarios
def enable(cell: Cell) -> dict:
    t = cell.hold_until(lambda s: s.enabled, 10.0)
    return {"ok": t is not None, "enable_s": t}


def follow(cell: Cell) -> dict:
    start = cell.latest().q.copy()
    errors, t0 = [], time.monotonic()
    duration = 2.0
    while (elapsed := time.monotonic() - t0) < duration + 0.5:
        u = min(elapsed / duration, 1.0)
        target = start + np.array([-0.6, 0.2, -0.2, 0.3, -0.3, 0.5]) * 0.5 * (1 - math.cos(math.pi * u))
        cell.command(target)
        state = cell.latest()
        errors.append(float(np.abs(state.q - target).max()))
        time.sleep(PERIOD)
    final = float(np.abs(cell.latest().q - target).max())
    return {"ok": final < 0.005 and max(errors) < 0.1, "max_error_rad": max(errors), "final_error_rad": final,
            "enabled": cell.latest().enabled}


def fast_following(cell: Cell) -> dict:
    """Joint 1 on a trapezoid at 0.95 of its velocity limit (3 rad/s^2), commanded with its velocity as the
    scaler does: the joints follow within two periods (the driver's drive-lag report), the drives'
    following error stays at the count level, no EMCY, no stop."""
    recover(cell)
    start = cell.latest().q.copy()
    v, a, distance = 0.95 * 1.57, 3.0, 1.2
    t_acc = v / a
    t_end = 2 * t_acc + (distance - v * t_acc) / v
    with cell.lock:
        n_reports, n_emcy = len(cell.drive_lag), len(cell.can.emcy)
    t0 = time.monotonic()
    while (t := time.monotonic() - t0) < t_end + 1.2:
        tc = min(t, t_end)
        x = 0.5 * a * min(tc, t_acc) ** 2 + v * max(0.0, min(tc, t_end - t_acc) - t_acc) \
            + (v * max(0.0, tc - (t_end - t_acc)) - 0.5 * a * max(0.0, tc - (t_end - t_acc)) ** 2)
        speed = a * tc if tc < t_acc else (v if tc < t_end - t_acc else max(0.0, a * (t_end - tc)))
        cell.seq += 1
        q = start.copy()
        q[0] -= x
        qd = np.zeros(6)
        qd[0] = -speed
        cell.cmd_pub.put(encode(JointCommand(q=q, qd=qd, trajectory_version=0, s=0.0, seq=cell.seq,
                                             stamp=time.monotonic())))
        time.sleep(PERIOD)
    cell.hold_until(lambda s: False, 1.1, q)                 # holding there until the next drive-lag report
    with cell.lock:
        reports, emcy = cell.drive_lag[n_reports:], [c for _, _, c in cell.can.emcy[n_emcy:] if c]
    lags = [r.lag[0] for r in reports if r.samples[0] > 0]
    errors = [float(r.following_error.max()) for r in reports]
    final = float(abs(cell.latest().q[0] - (start[0] - distance)))
    return {"ok": bool(lags) and max(lags) <= 2 * PERIOD and max(errors) < 0.01 and not emcy and final < 0.005
            and cell.latest().enabled,
            "lag_p99_ms": [round(x * 1e3, 2) for x in lags], "following_error_max_rad": max(errors, default=None),
            "emcy": emcy, "final_error_rad": final,
            "stops": [e.event for _, e in cell.events_since(t0) if e.severity == "stop"]}


def stale_command(cell: Cell) -> dict:
    t_start = time.monotonic()
    cell.hold_until(lambda s: False, 0.5)                   # steady, then moving: a ramp on joint 1
    running_at_start = cell.latest().enabled
    q = cell.latest().q.copy()
    for k in range(50):
        q[0] -= 0.012
        cell.command(q)
        time.sleep(PERIOD)
    t_last = time.monotonic()
    time.sleep(1.0)                                          # nothing more is sent
    events = [(t - t_last, e) for t, e in cell.events_since(t_last) if e.event == "stale_command"]
    with cell.lock:
        moving_after = [t - t_last for t, s in cell.states if t > t_last and np.abs(s.qd).max() > 1e-3]
    stop_time = max(moving_after) if moving_after else 0.0
    earlier = [e.event for _, e in cell.events_since(t_start) if e.severity == "stop" and e.event != "stale_command"]
    return {"ok": bool(events) and events[0][0] <= 0.1 and stop_time <= 0.6 and not cell.latest().enabled,
            "event_after_s": events[0][0] if events else None, "standstill_after_s": stop_time,
            "running_at_start": running_at_start, "stops_before": earlier}


def _fault_scenario(cell: Cell, node_id: int, sub: int, expect: tuple[str, ...], within: float,
                    silent: bool = False) -> dict:
    ok_recover = recover(cell)
    t0 = time.monotonic()
    cell.can.inject(node_id, sub, 1)
    detected = cell.hold_until(lambda s: not s.enabled, within + 0.5)
    time.sleep(0.3)       # the stop event travels apart from the joint state that showed the stop: wait for it
    events = [(t - t0, e.event) for t, e in cell.events_since(t0) if e.severity == "stop"]
    state = cell.latest()
    if sub != 4:
        cell.can.inject(node_id, sub, 0)
    # every drive that still answers is out of operation enabled (a frozen one reports its last state;
    # it does not move either: it processes no SYNC)
    stopped_all = "operation_enabled" not in state.drive_state.split(":")[1].split("/") or (
        silent and state.drive_state.startswith("stopped:"))
    with cell.can.lock:          # CiA 301: every fault's EMCY sets the error register
        unflagged = sorted({f"0x{code:04X}" for code, register in cell.can.registers if code and not register})
    return {"ok": ok_recover and detected is not None and detected <= within + 0.1 and bool(events)
            and events[0][1] in expect and stopped_all and not unflagged, "emcy_without_register": unflagged,
            "recovered_first": ok_recover, "detected_after_s": detected, "events": events[:3],
            "drive_state": state.drive_state}


def heartbeat_loss(cell: Cell) -> dict:
    return _fault_scenario(cell, 5, INJECT_HEARTBEAT_OFF, ("heartbeat_lost",), 0.3 + 0.1)


def drive_fault(cell: Cell) -> dict:
    return _fault_scenario(cell, 7, INJECT_DRIVE_FAULT, ("emcy", "drive_fault"), 0.05)


def frozen_node(cell: Cell) -> dict:
    # a frozen node answers no SYNC: the frames lost stop it within MISSED_LIMIT SYNCs, before its heartbeat ages
    result = _fault_scenario(cell, 6, INJECT_FREEZE, ("frames_lost", "heartbeat_lost"), 0.3 + 0.1, silent=True)
    result["ok"] = result["ok"] and recover(cell)                # unfrozen (0x2F00:3 = 0): back to work
    return result


def dropped_frames(cell: Cell) -> dict:
    """A fifth of node 4's frames lost both ways while joint 2 moves: the robot follows (the drive
    interpolates to the last setpoint it got; a lost TPDO is one cycle of stale feedback) until the driver
    stops the drives for the frames being lost (``frames_lost``: a drive losing frames falls behind and
    overshoots its setpoints, beyond the tracking margin), with no drive fault; once the frames come again, a
    recovery request has the robot follow again."""
    ok_recover = recover(cell)
    cell.can.inject(4, INJECT_DROP, 200)
    start, t0, errors = cell.latest().q.copy(), time.monotonic(), []
    while (elapsed := time.monotonic() - t0) < 1.5:
        target = start + np.array([0.0, 0.15, 0, 0, 0, 0]) * math.sin(math.pi * elapsed / 1.5)
        cell.command(target)
        state = cell.latest()
        if state.enabled:                   # following: how far from the target (after the stop it stands)
            errors.append(float(np.abs(state.q - target).max()))
        time.sleep(PERIOD)
    cell.can.inject(4, INJECT_DROP, 0)
    stops = [e.event for _, e in cell.events_since(t0) if e.severity == "stop"]
    emcy = sorted({f"node {n}: 0x{c:04X}" for t, n, c in cell.can.emcy_since(t0) if c})
    back = recover(cell)
    return {"ok": ok_recover and stops[:1] == ["frames_lost"] and not emcy and max(errors, default=0.0) < 0.05 and back,
            "max_error_rad": max(errors, default=0.0), "stops": stops, "emcy": emcy, "recovered_after": back}


def emulator_watchdog(cell: Cell) -> dict:
    ok_recover = recover(cell)
    cell.hold_until(lambda s: False, 0.2)                    # running, commands flowing
    t0 = time.monotonic()
    cell.procs["robot_driver"].send_signal(signal.SIGSTOP)        # SYNC and targets stop
    time.sleep(0.5)
    emcy = [(t - t0, node, code) for t, node, code in cell.can.emcy_since(t0) if code]
    cell.procs["robot_driver"].send_signal(signal.SIGCONT)
    time.sleep(0.5)
    nodes = sorted({node for _, node, code in emcy if code == 0x8100})
    first = min((t for t, _, code in emcy if code == 0x8100), default=None)
    return {"ok": ok_recover and nodes == list(NODE_IDS) and first is not None and first <= 0.06 + 0.05,
            "recovered_first": ok_recover, "sync_timeout_emcy_nodes": nodes, "first_after_s": first, "emcy": emcy[:8],
            "driver_alive": cell.procs["robot_driver"].poll() is None}


def garbage_frames(cell: Cell) -> dict:
    rng = random.Random(7)
    # a raw bus of its own: sending on the tool's filtered bus would make it drop real frames with those ids
    bus = can.Bus(interface=cell.interface, channel=cell.channel or "239.74.163.2")
    ids = [0x000, 0x080, 0x700 + 3] + [base + nid for base in (0x180, 0x200, 0x300, 0x380, 0x600, 0x580)
                                        for nid in NODE_IDS] + [rng.randrange(0x800) for _ in range(20)]
    sent = 0
    t_end = time.monotonic() + 1.0
    while time.monotonic() < t_end:
        cid = rng.choice(ids)
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(9)))
        if cid == 0x000:                  # never a valid NMT command: those would legitimately act
            data = bytes([0x55, 0x00])
        bus.send(can.Message(arbitration_id=cid, data=data, is_extended_id=False))
        sent += 1
        time.sleep(0.0005)
    bus.shutdown()
    time.sleep(0.3)
    alive = {name: proc.poll() is None for name, proc in cell.procs.items()}
    try:
        answer = cell.can.nodes[3].sdo[0x1018][1].raw
    except Exception as exc:
        answer = f"no SDO answer: {exc}"
    before = len(cell.states)
    time.sleep(0.3)
    publishing = len(cell.states) > before
    recovered = recover(cell)
    return {"ok": all(alive.values()) and answer == 1547 and publishing and recovered,
            "frames": sent, "alive": alive, "sdo_after": answer, "driver_publishing": publishing,
            "recovered_after": recovered}


def bad_messages(cell: Cell) -> dict:
    """Garbage, wrong kinds and a NaN command on the keys the driver reads, between good commands: the
    driver drops them (and logs why), keeps following and keeps publishing."""
    import msgpack
    ok_recover = recover(cell)
    good = encode(JointCommand(q=cell.latest().q, qd=np.zeros(6), trajectory_version=0, s=0.0))
    nan_command = msgpack.unpackb(good, raw=False)
    nan_command["q"] = np.array([math.nan] * 6).tobytes()
    bad = [b"", b"\xff" * 40, b"garbage", msgpack.packb({"kind": "joint_command", "v": 1}),
           msgpack.packb(nan_command, use_bin_type=True), encode(DriverRequest(action="stop", source="x"))[:-3]]
    t0 = time.monotonic()
    before = len(cell.states)
    for k in range(60):
        cell.command(cell.latest().q)
        cell.cmd_pub.put(bad[k % len(bad)])
        cell.req_pub.put(bad[(k + 1) % len(bad)])
        time.sleep(PERIOD)
    stops = [e.event for _, e in cell.events_since(t0) if e.severity == "stop"]
    return {"ok": ok_recover and cell.latest().enabled and not stops and len(cell.states) - before > 40
            and cell.procs["robot_driver"].poll() is None, "stops": stops, "states_published": len(cell.states) - before}


# ------------------------------------------------------------------ with the scaler (robot + scaling layer)
def human_feed(cell: Cell) -> HumanFeed:
    """The person a scenario puts in place (``feed.human.capsules``; nobody at first), fed as tracker_ingest's
    raw input at 240 Hz when it runs, else as the tracker's own output (a valid human state) at 50 Hz."""
    feed = HumanFeed(cell.session, cell.keys, HeldHuman(), time.monotonic(), source="hil",
                     rate=240.0 if cell.with_tracker else 50.0, tracked=not cell.with_tracker)
    feed.start()
    return feed


def _publish_trajectory(cell: Cell, goal: np.ndarray, version: int):
    from shared.core.trajectory import straight_line_trajectory
    from shared.robot.model import default_robot
    from shared.wire.convert import trajectory_to_msg
    lim = default_robot().limits
    traj = straight_line_trajectory(cell.latest().q, goal, lim.velocity, lim.acceleration, version=version)
    cell.session.put(cell.keys.trajectory, encode(trajectory_to_msg(traj, goal_id=version, reason="goal")))
    return traj


def system_goal(cell: Cell) -> dict:
    feed = human_feed(cell)
    t_enable = _wait(lambda: cell.latest() is not None and cell.latest().enabled, 10.0)
    goal = Q0 + np.array([-0.8, 0.2, -0.2, 0.4, -0.3, 0.5])
    traj = _publish_trajectory(cell, goal, 1)
    t0 = time.monotonic()
    reached = _wait(lambda: np.abs(cell.latest().q - goal).max() < 0.005, traj.duration + 3.0)
    feed.running = False
    return {"ok": t_enable is not None and reached is not None, "enable_s": t_enable,
            "nominal_s": traj.duration, "reached_after_s": reached,
            "final_error_rad": float(np.abs(cell.latest().q - goal).max()), "started_s": round(time.monotonic() - t0, 3)}


def system_stale_humans(cell: Cell) -> dict:
    feed = human_feed(cell)
    _wait(lambda: cell.latest().enabled, 5.0)
    # a plan from rest only from where the robot stands: the last scenario's goal counted as reached 5 mrad
    # short, and on a loaded machine a plan from there was refused (1 mrad from the command at most)
    _wait(lambda: np.abs(cell.latest().qd).max() < 1e-3, 5.0)
    traj = _publish_trajectory(cell, Q0, 2)                    # back to the start, a long motion
    # mid-motion, at speed: 40 % of the leg's nominal time after its publication, and not before the robot
    # moves (on a slow machine the first commands came late and a fixed sleep found it still at rest)
    started = _wait(lambda: np.abs(cell.latest().qd).max() > 0.3, traj.duration)
    time.sleep(max(0.0, traj.duration * 0.4 - (started or 0.0)))
    moving = float(np.abs(cell.latest().qd).max())
    feed.running = False                                       # the tracker goes silent
    seen = _wait(lambda: np.abs(cell.latest().qd).max() < 1e-3, 2.0)
    time.sleep(0.3)
    q_stop = cell.latest().q.copy()
    time.sleep(0.5)
    drift = float(np.abs(cell.latest().q - q_stop).max())
    # from the last human message to the first joint state at a standstill, as the driver stamped it (the
    # same monotonic clock): the cell's own reaction, not how late this process received the states
    with cell.lock:
        stamps = [m.stamp for _, m in cell.states if m.stamp > feed.last_sent and np.abs(m.qd).max() < 1e-3]
    still = round(stamps[0] - feed.last_sent, 3) if seen is not None and stamps else None
    return {"ok": moving > 0.3 and still is not None and still <= 0.05 + 0.5 and drift < 1e-4,
            "speed_before_rad_s": moving, "standstill_after_s": still, "seen_still_after_s": seen,
            "drift_after_rad": drift}


def system_near_human(cell: Cell) -> dict:
    """A person stands beside the shuttle's path, tracked: the robot slows near them, still reaches the
    goal, and the independent monitor (measured states) counts no violation."""
    from evidence.scenarios import body_segments
    from shared.core.humans import HumanCapsules
    feed = human_feed(cell)
    _wait(lambda: cell.latest().enabled, 5.0)
    # near enough that the shipped model (their possible start at 50 m/s^2 up to the ISO 13855 speed, over
    # T_r + the T_s of the robot's speed) slows the robot past a person standing with an arm out: the straight
    # shuttle takes 2.84 s for its nominal 2.45 s in the simulation (ExecutedTime)
    seg, radii = body_segments(-1.57, 0.0, 0.6, np.array([-0.92, 0.0, 0.6]), lean=0.3)
    feed.human.capsules = HumanCapsules.from_arrays(seg, radii, np.zeros_like(seg), np.ones(len(radii), bool))
    time.sleep(0.3)
    # a trajectory from rest is only for a robot at rest: an earlier scenario's motion (resumed now that
    # human data flows again) ends first; a new one published mid-motion would make the drives reverse
    # (the planner service never does that: it merges)
    _wait(lambda: np.abs(cell.latest().qd).max() < 1e-3, 5.0)
    goal = Q_GOAL.copy()
    traj = _publish_trajectory(cell, goal, 5)
    reached = _wait(lambda: np.abs(cell.latest().q - goal).max() < 0.005, traj.duration * 8)
    time.sleep(1.2)
    feed.running = False
    with cell.lock:
        summaries = [e for _, e in cell.events if e.source == "safety_monitor" and e.event == "monitor_summary"]
        violations = [e.text for _, e in cell.events if e.source == "safety_monitor" and e.event == "ssm_violation"]
    last = summaries[-1]
    return {"ok": reached is not None and reached > traj.duration * 1.05 and last.value == 0
            and "inf" not in last.text, "nominal_s": traj.duration, "reached_after_s": reached,
            "monitor": last.text, "violations": violations[:3]}


def monitor_report(cell: Cell) -> dict:
    """The monitor's last summary (it runs with the tracker): checks and violations counted."""
    time.sleep(1.2)
    with cell.lock:
        summaries = [e for _, e in cell.events if e.source == "safety_monitor" and e.event == "monitor_summary"]
        violations = [e.text for _, e in cell.events if e.source == "safety_monitor" and e.event == "ssm_violation"]
    last = summaries[-1] if summaries else None
    return {"ok": last is not None and last.value == 0 and not violations and "checks" in last.text
            and not last.text.startswith("0 checks"), "summary": last.text if last else None, "violations": violations[:3]}


def _wait(condition, timeout: float) -> float | None:
    start = time.monotonic()
    while time.monotonic() - start < timeout:
        try:
            if condition():
                return time.monotonic() - start
        except (AttributeError, TypeError):
            pass
        time.sleep(0.01)
    return None


def system_replan(cell: Cell) -> dict:
    """Goal through the planner; an arm appears across the path while the robot moves: the planner
    replans (horizon check) and the goal is still reached, never closer to the arm than d_min."""
    from shared.core.geometry import capsule_pair_distances
    from shared.core.humans import HumanCapsules
    from shared.robot.model import default_robot
    from shared.wire.messages import Goal
    robot = default_robot()
    feed = human_feed(cell)
    _wait(lambda: cell.latest().enabled, 5.0)
    goal = Q_GOAL.copy()
    arm = HumanCapsules.from_arrays([[[-0.75, -0.15, 0.55], [-0.35, 0.15, 0.55]],
                                     [[-1.0, -0.2, 0.9], [-1.0, -0.2, 1.45]]], [0.05, 0.17],
                                    np.zeros((2, 2, 3)), [True, True])
    t0 = time.monotonic()
    cell.session.put(cell.keys.goal, encode(Goal(goal_id=7, name="q_g", q=goal)))
    _wait(lambda: np.abs(cell.latest().qd).max() > 0.2, 3.0)
    time.sleep(0.2)
    feed.human.capsules = arm                                          # steps in while the robot moves
    reached = _wait(lambda: np.abs(cell.latest().q - goal).max() < 0.01, 15.0)
    feed.running = False
    events = [e.event for t, e in cell.events_since(t0) if e.source == "planner"]
    texts = [e.text[:160] for t, e in cell.events_since(t0) if e.source == "planner"]
    with cell.lock:
        qs = [s.q for t, s in cell.states if t >= t0]
    closest = min(float(capsule_pair_distances(robot.capsule_segments(q), robot.radii, arm.segments,
                                               arm.radii).distance.min()) for q in qs[::5])
    return {"ok": reached is not None and "trajectory_horizon" in events and closest >= 0.05,
            "reached_after_s": reached, "planner_events": events[:6], "texts": texts[:8], "closest_to_arm_m": closest}


def garbage_everywhere(cell: Cell) -> dict:
    """Garbage on every key a service reads (raw and filtered human data, goals, trajectories, commands,
    scaler status, joint states, driver requests) for a second, between good human samples: every
    service lives on, the robot does not move, and afterwards a goal is still followed."""
    import msgpack
    feed = human_feed(cell)
    _wait(lambda: cell.latest().enabled, 5.0)
    keys = cell.keys
    targets = [keys.human_raw, keys.human_state, keys.goal, keys.trajectory, keys.command, keys.scaler_status,
               keys.joint_state, keys.driver_request]
    rng = random.Random(11)
    garbage = [b"", b"\x00", b"\xff" * 64, msgpack.packb({"kind": "human_state", "v": 1}),
               msgpack.packb({"kind": "trajectory", "v": 1, "seq": 0, "stamp": 0.0, "times": b"\x00" * 7}),
               msgpack.packb([1, 2, 3]), bytes(rng.randrange(256) for _ in range(300))]
    q0 = cell.latest().q.copy()
    t0 = time.monotonic()
    while time.monotonic() - t0 < 1.0:
        for key in targets:
            cell.session.put(key, rng.choice(garbage))
        time.sleep(0.002)
    time.sleep(0.2)
    drift = float(np.abs(cell.latest().q - q0).max())
    alive = {name: proc.poll() is None for name, proc in cell.procs.items()}
    traj = _publish_trajectory(cell, q0 + np.array([-0.3, 0.1, 0.0, 0.0, 0.0, 0.2]), 9)
    reached = _wait(lambda: np.abs(cell.latest().q - traj.positions[-1]).max() < 0.005, traj.duration + 3.0)
    feed.running = False
    return {"ok": all(alive.values()) and drift < 1e-3 and reached is not None, "alive": alive,
            "drift_rad": drift, "goal_after_s": reached}


SYSTEM_SCENARIOS = {"garbage_everywhere": garbage_everywhere, "system_goal": system_goal,
                    "system_stale_humans": system_stale_humans,
                    "system_replan": system_replan, "system_near_human": system_near_human,
                    "monitor_report": monitor_report}

SCENARIOS = {"enable": enable, "follow": follow, "fast_following": fast_following, "stale_command": stale_command,
             "heartbeat_loss": heartbeat_loss,
             "drive_fault": drive_fault, "frozen_node": frozen_node, "dropped_frames": dropped_frames,
             "bad_messages": bad_messages, "emulator_watchdog": emulator_watchdog, "garbage_frames": garbage_frames}


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--interface", default="udp_multicast")
    parser.add_argument("--channel", default=None)
    parser.add_argument("--scenarios", nargs="*", default=None)
    parser.add_argument("--with-scaler", action="store_true", help="also run the scaler service")
    parser.add_argument("--with-planner", action="store_true", help="also run the scaler and planner services")
    parser.add_argument("--with-tracker", action="store_true", help="also run the scaler and tracker_ingest services")
    args = parser.parse_args()
    table = SYSTEM_SCENARIOS if (args.with_scaler or args.with_planner or args.with_tracker) else SCENARIOS
    args.scenarios = args.scenarios or list(table)
    if args.interface == "udp_multicast":
        for cmd in (["ip", "link", "set", "lo", "up"], ["ip", "link", "set", "lo", "multicast", "on"],
                    ["ip", "route", "add", "224.0.0.0/4", "dev", "lo"]):
            subprocess.run(cmd, check=True)
    cell = Cell(args.interface, args.channel, with_scaler=args.with_scaler, with_planner=args.with_planner,
                with_tracker=args.with_tracker)
    results = {"transport": f"{args.interface}:{args.channel or ''}"}
    try:
        cell.start()
        for name in args.scenarios:
            try:
                results[name] = table[name](cell)
            except Exception as exc:                     # a scenario's own failure, reported, not hidden
                results[name] = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
    finally:
        cell.stop()
    print(json.dumps(results, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
