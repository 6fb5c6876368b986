"""`hrc faults`: the fault campaign against a cell running under supervisord (`hrc up`).

As the cell's operator it shuttles the robot between q_s and q_g next to a scripted person (sent as raw
tracker data, tools.actors), and, while the robot moves, injects one fault after the other:

  kill_<service>     kill -9 of scaler, tracker_ingest, planner, safety_monitor, robot_driver
  freeze_<service>   SIGSTOP of the scaler or the robot driver for HOLD seconds, then SIGCONT
  freeze_scaler_recover  the scaler's freeze, with the driver asked to recover while the scaler is held: the
                     drives stand enabled, waiting for a command to start on, when it comes back with its old path
  can_drop           one drive loses a tenth of its CAN frames both ways (emulator, SDO 0x2F00:1)
  heartbeat_stop     one drive's heartbeat stops (SDO 0x2F00:2)
  tracker_silent     the raw tracker stream stops
  tracker_nan        the tracker sends NaN coordinates
  human_jump         the person is shown 0.3 m nearer to the robot than they are (then back)
  human_glitch       every 12th sample shows the person 1.5 m farther away than they are

For each it measures, from the recorded messages and the CAN bus (pure judging in tools.faultcheck): the
time to standstill or to the first protective reaction against a bound stated from the configuration, the
monitor's violations and a re-check against the true person, whether the service is back under the
supervisor, and how long until the next shuttle completes. While a fault is active the operator does not
ask the driver to recover (the stop is what is measured); after it, it does.
"""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from evidence.scenarios import IN_PATH, Keyframe, ScriptedHuman
from hwsim.drive import DriveLimits
from hwsim.emulator import WATCHDOG_STEP
from shared.config import CellConfig
from shared.drives import driver_core
from shared.drives.prbt import EMCY_SYNC_TIMEOUT, FAULT_INJECTION, INJECT_DROP, INJECT_HEARTBEAT_OFF, PERIOD
from shared.robot.model import RobotModel
from shared.safety.monitor import SafetyMonitor
from shared.tracking.tracker import stale_bound
from shared.transport.zenoh_session import await_liveliness, open_session
from shared.wire.keys import KeySpace
from shared.wire.messages import HumanState, JointState, ScalerStatus
from tools.actors import FeedFault, HumanFeed, Recorder, Shuttle
from tools.cell import service_info
from tools.faultcheck import FaultVerdict, moving_at, nearer_seen, standstill_after, stop_timeline, truth_violations
from tools.launch import free_port
from tools.report import Recording, write_trace

HOLD = 1.5                      # s a fault stays active (kills: until the supervisor restarts the service)
RECOVER_DURING = 0.75           # s into freeze_scaler_recover: the driver is asked to recover while the scaler is held
# s: the joint state wait_moving goes by must be this recent. The latest one kept could be older: the stream
# paused (a driver or bus just back from the previous fault), and a fault was injected into a robot that
# had stood still for a while, judged "not moving at the injection" (4 of 8 campaigns)
FRESH = 0.05
MOVING = 0.3                    # rad/s: the robot counts as moving (at speed) above this joint speed
AHEAD = 1.2                     # rad still to go on the leg when a fault is injected (about a second)
SETTLE = 25.0                   # s to wait for the robot to move before a fault
RESUME = 45.0                   # s after a fault for the next shuttle to complete
FAULT_NAMES = ("kill_scaler", "kill_tracker_ingest", "kill_planner", "kill_safety_monitor", "kill_robot_driver",
               "freeze_scaler", "freeze_scaler_recover", "freeze_robot_driver", "can_drop", "heartbeat_stop",
               "tracker_silent", "tracker_nan", "human_jump", "human_glitch")
DROP_NODE, HEARTBEAT_NODE = 4, 5
# the person shown nearer by this much (m): from 1.2-1.7 m to 0.9-1.4 m off the robot's axis, still beyond
# d_min of every link on the path. A jump further in (0.6 m was tried) teleports the person next to the
# moving flange, where no system could keep d_min and the monitor rightly counts it.
JUMP = 0.3
# ... made while the person is this far (m) from the axis, so that where they are shown (1.3 m and more,
# velocity unknown, so the ISO 13855 1.6 m/s) is still beyond the protective distance of the moving robot:
# a person shown inside it has not been seen coming, which speed and separation monitoring cannot answer
JUMP_FROM = 1.6


HELD_FOR = 1.0                  # s: a human state older than this no longer says the tracker's interval
HUMAN_STOPS = ("kill_tracker_ingest", "tracker_silent", "tracker_nan")    # faults of the human data: a stale-data stop
# faults that leave nothing behind when lifted at once: injected into a robot that, by the recorded joint states,
# stood at that instant (it paused between the check that it moves and the injection: a plan taken at rest, this
# process descheduled), they are lifted and injected again, at most INJECTIONS times. (A person's jump injected
# into a robot that had stood for 40 ms was judged "not moving at the injection" on a loaded machine.)
REVERSIBLE = ("tracker_silent", "tracker_nan", "human_jump", "human_glitch")
INJECTIONS = 3


@dataclass(frozen=True)
class Expectation:
    expect: str              # stop | slow | any
    bound_s: float | None
    why: str


def fault_service(name: str) -> str | None:
    """The service a kill or a freeze acts on (None for the other faults)."""
    if name == "freeze_scaler_recover":
        return "scaler"
    return name.split("_", 1)[1] if name.startswith(("kill_", "freeze_")) else None


def inject_again(name: str, attempt: int, moving: bool, moved_at_injection: Callable[[], bool]) -> bool:
    """Whether the fault just injected (attempt 0, 1, ...) is to be lifted at once and injected again: a
    ``REVERSIBLE`` one, with attempts left, into a robot seen moving before (`moving`) that by the recorded joint
    states stood at the injection (moved_at_injection(), asked last: it waits for the states)."""
    return name in REVERSIBLE and attempt < INJECTIONS - 1 and moving and not moved_at_injection()


def braking_time(robot: RobotModel) -> float:
    """s: the longest stop from full speed at the drives' deceleration (the fastest joint's)."""
    return float(np.max(robot.limits.velocity / robot.limits.monitor_acceleration))


def human_stop(config: CellConfig, robot: RobotModel, interval: float = 0.0) -> Expectation:
    """The stop a human-data fault must cause: the data's stale bound (the cell's rule, ``stale_bound``: the
    configured 50 ms, or 2.5 of the source's measured sample interval where that is longer, as under load when
    the feed skips samples), a scaler tick, a SYNC and a report, and the braking."""
    p, brake = PERIOD, braking_time(robot)
    human = stale_bound(max(config.scaling.human_timeout, 0.05), interval)
    source = f" (the source's measured interval {interval * 1e3:.1f} ms)" if human > config.scaling.human_timeout else ""
    return Expectation("stop", human + 3 * p + brake,
                       f"human data timeout {human * 1e3:.0f} ms{source} + tick, SYNC and report {3 * p * 1e3:.0f} ms + "
                       f"braking {brake * 1e3:.0f} ms")


def held_interval(states: list[HumanState], now: float, oldest: float = HELD_FOR) -> float:
    """s: the source's sample interval the tracker held at `now`: the newest human state's (the tracker's
    median of its last intervals, which stays as it was once the samples stop), if it was published within
    `oldest` seconds; 0 (the configured bound alone) when there is none. Not a window of the last 0.1 s: a
    campaign that fell behind on a loaded machine had none there and judged a 94 ms dropout by 50 ms."""
    fresh = [h for h in states if now - oldest <= h.stamp <= now]
    return max(fresh, key=lambda h: h.stamp).sample_interval if fresh else 0.0


def expectations(config: CellConfig, robot: RobotModel) -> dict[str, Expectation]:
    """What each fault must cause, with its bound stated from the configuration and the drives' timings (a
    human-data fault's again at its injection, from the source's measured rate: ``human_stop``)."""
    brake = braking_time(robot)
    # the robot driver's and the emulated drives' own defaults, as the cell runs them (hrc up)
    p, ct, hb = PERIOD, driver_core.COMMAND_TIMEOUT, driver_core.HEARTBEAT_TIMEOUT
    # the drives look when the time-out is due; a wake-up up to a braking step late is allowed
    wd = DriveLimits(lower=0.0, upper=0.0).sync_timeout + WATCHDOG_STEP
    horizon = config.ssm.reaction_time + config.ssm.stopping_time
    # + one SYNC more everywhere the drives keep reporting: a drive reports the position of the SYNC
    # instant, so a standstill reached between two SYNCs is seen at the next one
    command_stop = Expectation("stop", ct + 2 * p + brake, f"command timeout {ct * 1e3:.0f} ms + SYNC and report "
                                                           f"{2 * p * 1e3:.0f} ms + braking from full speed "
                                                           f"{brake * 1e3:.0f} ms")
    human_data = human_stop(config, robot)
    driver_stop = Expectation("stop", wd + brake, f"drives' SYNC watchdog {wd * 1e3:.0f} ms (timeout and poll) + braking "
                                                  f"{brake * 1e3:.0f} ms")
    carry_on = Expectation("any", None, "not in the chain that stops the robot: the motion stays scaled")
    return {
        "kill_scaler": command_stop, "freeze_scaler": command_stop, "freeze_scaler_recover": command_stop,
        **{name: human_data for name in HUMAN_STOPS},
        "kill_robot_driver": driver_stop, "freeze_robot_driver": driver_stop,
        "heartbeat_stop": Expectation("stop", hb + 2 * p + brake, f"heartbeat timeout {hb * 1e3:.0f} ms + SYNC and "
                                                                  f"report + braking {brake * 1e3:.0f} ms"),
        "kill_planner": carry_on, "kill_safety_monitor": carry_on,
        "can_drop": Expectation("any", None, "lost frames: the driver stops for them (frames_lost), or the drive lags "
                                               "or faults; either is safe"),
        "human_jump": Expectation("slow", config.ssm.reaction_time,
                                  "the scaler takes the nearer person within T_r = "
                                  f"{config.ssm.reaction_time * 1e3:.0f} ms"),
        "human_glitch": Expectation("any", None, "a glitch away must not speed the robot up (judged against the "
                                                 f"true person over T_r + T_s = {horizon * 1e3:.0f} ms windows)"),
    }


def campaign_human(duration: float = 3600.0) -> ScriptedHuman:
    """The person of the campaign: walks back and forth 1.2 to 1.7 m from the robot's axis, 0.5 m/s."""
    frames, t, k = [], 0.0, 0
    while t <= duration:
        frames.append(Keyframe(t, -1.2 if k % 2 else -1.7, 0.0, 0.0, IN_PATH, "walking beside the cell"))
        t, k = t + 1.0, k + 1
    return ScriptedHuman(frames)


class InjectionError(RuntimeError):
    """A fault could not be injected or lifted (the emulator did not answer its SDO requests)."""


class CanProbe:
    """The campaign's own node on the CAN bus: fault injection into the emulated drives by SDO (0x2F00) and
    a record of every EMCY, independent of the robot driver."""

    def __init__(self, interface: str, channel: str | None) -> None:
        import canopen

        from shared.drives.bus import open_bus
        from shared.drives.prbt import EDS_PATH, NODE_IDS

        self.network = canopen.Network(open_bus(interface, channel))
        self.network.connect()
        self.nodes = {nid: self.network.add_node(nid, str(EDS_PATH)) for nid in NODE_IDS}
        self.lock = threading.Lock()
        self.emcy: list[tuple[float, int, int]] = []           # (monotonic time, node, code)
        self.registers: list[tuple[int, int | None]] = []      # (code, error register or None) of each EMCY
        for nid in NODE_IDS:
            self.network.subscribe(0x80 + nid, lambda can_id, data, ts, nid=nid: self._on_emcy(nid, data, ts))

    def _on_emcy(self, nid: int, data: bytes, received: float) -> None:
        """Record an EMCY at the moment it reached this process's socket: the frame's receive time (wall
        clock; the kernel's for udp_multicast) taken back onto the monotonic clock the cell's events use.
        This thread's own delay in getting to the frame (a loaded campaign process: up to half a second
        seen) is the observer's, not the drives' reaction; a receive time that is missing or implausible
        counts no delay."""
        if len(data) >= 2:
            delay = time.time() - received if received else 0.0
            now = time.monotonic() - (delay if 0.0 <= delay < 5.0 else 0.0)
            code = int.from_bytes(data[:2], "little")
            with self.lock:
                self.emcy.append((now, nid, code))
                self.registers.append((code, data[2] if len(data) > 2 else None))

    def inject(self, node: int, subindex: int, value: int, tries: int = 3) -> None:
        """SDO write 0x2F00:subindex = value, tried `tries` times (a busy emulator can miss one request);
        InjectionError with what was asked and the last answer if none went through."""
        import canopen

        for attempt in range(tries):
            try:
                self.nodes[node].sdo[FAULT_INJECTION][subindex].raw = value
                return
            except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
                last = exc
                time.sleep(0.05 * (attempt + 1))
        raise InjectionError(f"node {node}: SDO write 0x2F00:{subindex} = {value} not answered after {tries} tries "
                             f"({last})")

    def emcy_since(self, t: float) -> list[tuple[float, int, int]]:
        with self.lock:
            return [e for e in self.emcy if e[0] >= t]

    def close(self) -> None:
        self.network.disconnect()


def stamps_and_speeds(states: list[JointState]) -> tuple[np.ndarray, np.ndarray]:
    """The joint states' stamps (s) and largest joint speeds (rad/s), as the judging functions take them."""
    return np.array([js.stamp for js in states]), np.array([np.abs(js.qd).max() for js in states])


class Campaign:
    """One operator session against the running cell; run(name) injects one fault and judges it."""

    def __init__(self, prefix: str, endpoint: str, interface: str, channel: str | None, config: CellConfig,
                 robot: RobotModel, say: Callable[[str], None] = print) -> None:
        self.prefix, self.keys, self.config, self.robot, self.say = prefix, KeySpace(prefix), config, robot, say
        self.expect = expectations(config, robot)
        self.session = open_session("peer", listen=[f"tcp/127.0.0.1:{free_port()}"], connect=[endpoint])
        self.rec = Recording(t0=time.monotonic())
        self.recorder = Recorder(self.session, self.keys, self.rec)
        self.human = campaign_human()
        self.feed = HumanFeed(self.session, self.keys, self.human, self.rec.t0, source="hrc faults")
        self.shuttle = Shuttle(self.session, self.keys, self.recorder, self.rec, source="hrc faults")
        self.can = CanProbe(interface, channel)
        self.monitor = SafetyMonitor(robot, config.ssm)
        self.running = True
        self.feed.start()
        self.shuttle.start(time.monotonic())
        self.operator = threading.Thread(target=self._operate, daemon=True, name="operator")
        self.operator.start()

    def _operate(self) -> None:
        while self.running:
            self.shuttle.step(time.monotonic())
            self.recorder.wait_finished(0.02)

    def close(self) -> None:
        self.running = False
        self.feed.running = False
        self.operator.join(2.0)
        self.recorder.close()
        self.can.close()
        self.session.close()

    # ------------------------------------------------------------------------------------------ observing
    def _speed(self) -> float:
        js = self.recorder.get(JointState)
        return float(np.abs(js.qd).max()) if js is not None and js.enabled else 0.0

    def wait_moving(self, timeout: float = SETTLE, person_beyond: float = 0.0) -> bool:
        """Wait until the robot moves at speed with most of a leg still ahead (so that a stop is the fault's
        doing, not the end of the shuttle) and, at the same moment, the scripted person is at least
        `person_beyond` (m) from the robot's axis; False after timeout. (Waiting for the two one after the
        other let the robot finish its leg while the person walked out: a fault injected into a robot at
        rest judges nothing.)"""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            st, js = self.recorder.get(ScalerStatus), self.recorder.get(JointState)
            ahead = float(np.abs(js.q - self.shuttle.target).max()) if js is not None else 0.0
            fresh = js is not None and time.monotonic() - js.stamp < FRESH
            if fresh and self._speed() > MOVING and st is not None and st.alpha > 0.2 and ahead > AHEAD \
                    and (person_beyond <= 0.0 or self._person_distance() >= person_beyond):
                return True
            time.sleep(0.005)
        return False

    def _person_distance(self) -> float:
        """How far (m) the scripted person is from the robot's axis now (the person walks back and forth
        in 2 s)."""
        ends = self.human.at(time.monotonic() - self.rec.t0).segments.reshape(-1, 3)
        return float(np.linalg.norm(ends[:, :2], axis=1).min())

    def _service_back(self, service: str, old_pid: int, killed: bool, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            pid, state = service_info(self.prefix, service)
            if state == "RUNNING" and (pid != old_pid or not killed) and pid and \
                    await_liveliness(self.session, self.keys.alive(service), 0.5):
                return True
            time.sleep(0.3)
        return False

    def _wait_shuttle(self, after: int, deadline: float) -> float | None:
        """The time the next shuttle after `after` completed, or None at the deadline."""
        while time.monotonic() < deadline:
            if self.rec.shuttles > after:
                return time.monotonic()
            time.sleep(0.05)
        return None

    def _recorded_moving(self, t: float) -> bool:
        """The robot moves at time t by the recorded joint states (the judge's own test, ``moving_at``)."""
        return moving_at(*stamps_and_speeds(self._joint_samples(t - 1.0)), t)

    def _samples_around(self, t: float) -> str:
        """The recorded joint states around time t, in arrival order (stamp - t in ms, seq, largest joint speed,
        enabled): why the judge and the latest state disagreed."""
        states = self._joint_samples(t - 0.05)
        return ", ".join(f"{(js.stamp - t) * 1e3:+.0f}ms #{js.seq} {np.abs(js.qd).max():.2f} {'on' if js.enabled else 'off'}"
                         for js in states[:12])

    def _joint_samples(self, t_from: float) -> list[JointState]:
        with self.recorder.lock:
            return [js for js in self.rec.joint_states if js.stamp >= t_from]

    # ------------------------------------------------------------------------------------------ one fault
    def _await_motion(self, verdict: FaultVerdict, name: str) -> None:
        """Wait until the robot moves (``wait_moving``) and the recorded joint states agree that it does, or the
        verdict cannot judge it (3 tries, each disagreement noted); verdict.moving_at_injection says whether it
        does."""
        for attempt in range(3):
            verdict.moving_at_injection = self.wait_moving(person_beyond=JUMP_FROM if name == "human_jump" else 0.0)
            now = time.monotonic()
            if not verdict.moving_at_injection or self._recorded_moving(now):
                return
            verdict.notes.append(f"attempt {attempt + 1}: moving by the latest joint state, not by the recorded "
                                 f"ones before now: {self._samples_around(now)}")

    def _moved_at(self, t: float, wait: float = 0.2) -> bool:
        """Whether the recorded joint states say the robot moved at time t, once one stamped after t has come
        (at most `wait` s: then by those recorded so far)."""
        deadline = time.monotonic() + wait
        while time.monotonic() < deadline:
            latest = self.recorder.get(JointState)
            if latest is not None and latest.stamp > t:
                break
            time.sleep(0.005)
        return self._recorded_moving(t)

    def run(self, name: str) -> FaultVerdict:
        if name not in FAULT_NAMES:
            raise ValueError(f"unknown fault {name!r}; known: {', '.join(FAULT_NAMES)}")
        exp = self.expect[name]
        verdict = FaultVerdict(name, exp.expect, exp.bound_s, exp.why)
        service = fault_service(name)
        # asked of supervisorctl before the wait for motion, not between it and the injection (a subprocess)
        old_pid = service_info(self.prefix, service)[0] if service else 0
        if service and old_pid <= 0:              # never signal pid 0 (that is this whole process group)
            verdict.notes.append(f"{service} was not running under supervisord: nothing injected")
            return verdict
        first_inject: float | None = None
        for attempt in range(INJECTIONS):
            self._await_motion(verdict, name)        # (not moving after SETTLE: injected all the same, judged)
            before = self.recorder.get(ScalerStatus)
            if name in HUMAN_STOPS:    # the stale bound at the source's rate as the cell held it at the injection
                now = time.monotonic()
                with self.recorder.lock:
                    interval = held_interval(self.rec.human_states[-64:], now)
                exp = human_stop(self.config, self.robot, interval)
                verdict.bound_s, verdict.bound_why = exp.bound_s, exp.why
            self.shuttle.recovering = False
            t_inject = time.monotonic()
            first_inject = t_inject if first_inject is None else first_inject
            verdict.t_inject = round(t_inject - self.rec.t0, 3)
            try:
                lift = self._inject(name, old_pid)
            except InjectionError as exc:           # nothing was injected: no verdict to give, said so
                self.shuttle.recovering = True
                verdict.notes.append(f"not injected: {exc}")
                return verdict
            if not inject_again(name, attempt, verdict.moving_at_injection, lambda: self._moved_at(t_inject)):
                break
            lift()                  # the robot paused (a plan taken at rest) as it came: a fault that leaves
            self.shuttle.recovering = True          # nothing behind is lifted at once and injected again
            verdict.notes.append(f"injection {attempt + 1}: the robot stood at the injection, lifted at once: "
                                 f"{self._samples_around(t_inject)}")
        time.sleep(HOLD)
        try:
            lift()
        except InjectionError as exc:
            verdict.notes.append(f"not lifted: {exc}")
        t_lift = time.monotonic()
        shuttles = self.rec.shuttles
        self.shuttle.recovering = True
        verdict.back = self._service_back(service, old_pid, name.startswith("kill_"), 40.0) if service else True
        done = self._wait_shuttle(shuttles, t_lift + RESUME)
        verdict.resumed_s = None if done is None else round(done - t_lift, 2)
        self._judge(verdict, t_inject, t_lift, before, first_inject)
        return verdict

    def _inject(self, name: str, pid: int) -> Callable[[], None]:
        """Start the fault now; returns what lifts it."""
        nothing = lambda: None  # noqa: E731
        if name.startswith("kill_"):
            os.kill(pid, signal.SIGKILL)
            return nothing
        if name.startswith("freeze_"):
            os.kill(pid, signal.SIGSTOP)
            if name == "freeze_scaler_recover":     # the robot at rest by then (the stop takes 0.1-0.3 s)
                threading.Timer(RECOVER_DURING, lambda: self.shuttle.recover(time.monotonic())).start()
            return lambda: os.kill(pid, signal.SIGCONT)
        if name == "can_drop":
            self.can.inject(DROP_NODE, INJECT_DROP, 100)
            return lambda: self.can.inject(DROP_NODE, INJECT_DROP, 0)
        if name == "heartbeat_stop":
            self.can.inject(HEARTBEAT_NODE, INJECT_HEARTBEAT_OFF, 1)
            return lambda: self.can.inject(HEARTBEAT_NODE, INJECT_HEARTBEAT_OFF, 0)
        faults = {"tracker_silent": FeedFault("silent"), "tracker_nan": FeedFault("nan"),
                  "human_jump": FeedFault("jump", (JUMP, 0.0, 0.0)),
                  "human_glitch": FeedFault("jump", (-1.5, 0.0, 0.0), every=12)}
        self.feed.fault = faults[name]

        def healthy() -> None:
            self.feed.fault = FeedFault()
        return healthy

    def _judge(self, v: FaultVerdict, t_inject: float, t_lift: float, before: ScalerStatus | None,
               first_inject: float | None = None) -> None:
        """The verdict of the fault injected at t_inject and lifted at t_lift; violations are counted from
        first_inject on (an injection lifted at once and made again, ``REVERSIBLE``, counts too)."""
        first_inject = t_inject if first_inject is None else first_inject
        states = self._joint_samples(min(t_inject, first_inject) - 1.0)
        times, speeds = stamps_and_speeds(states)
        during = times <= t_lift
        if v.moving_at_injection and not moving_at(times, speeds, t_inject):
            v.notes.append(f"not moving at the injection by the recorded joint states: {self._samples_around(t_inject)}")
            v.moving_at_injection = False
        with self.recorder.lock:
            events = [e for e in self.rec.events if e.stamp >= first_inject - 0.5]
            statuses = [s for s in self.rec.statuses if s.stamp >= t_inject]
        reactions = [(e.stamp - t_inject, f"{e.source}: {e.event}") for e in events
                     if e.severity == "stop" and e.stamp >= t_inject and e.source != "safety_monitor"]
        reactions += [(s.stamp - t_inject, f"scaler: {s.status}") for s in statuses
                      if s.status in ("stale_human_data", "no_human_data")][:1]
        if v.name.endswith("robot_driver"):
            emcy = self.can.emcy_since(t_inject)
            first = {}
            for t, node, code in emcy:
                if code == EMCY_SYNC_TIMEOUT:
                    first.setdefault(node, t)
            if len(first) == len(self.can.nodes):
                reactions.append((max(first.values()) - t_inject, "drives: SYNC timeout EMCY on every node"))
            before_fault = [js for js in states if js.stamp <= t_inject]
            last = before_fault[-1] if before_fault else None
            if reactions and last is not None:
                # no TPDO without SYNC: the drives brake at their limit once their watchdog fires, unseen
                brake = float(np.max(np.abs(last.qd) / self.robot.limits.monitor_acceleration))
                v.stop_s = round(min(r[0] for r in reactions) + brake, 3)
                v.notes.append("stop_s = SYNC-watchdog EMCY + braking from the last measured speed at the "
                               "drives' deceleration (without SYNC the drives send no TPDO to measure it by)")
        elif v.name == "human_jump" and before is not None:
            seen = nearer_seen(before.min_separation, [(s.stamp, s.min_separation) for s in statuses
                                                       if s.min_separation is not None], JUMP)
            if seen is not None:
                reactions.append((seen - t_inject, "scaler: the nearer person is in the scaling problem"))
        else:
            stop = standstill_after(times[during], speeds[during], t_inject)
            v.stop_s = None if stop is None else round(stop, 3)
            if v.bound_s is not None and (v.stop_s is None or v.stop_s > v.bound_s):
                rows = [(s.stamp, s.status, s.method, s.trajectory_version, s.alpha) for s in statuses]
                v.notes += stop_timeline(t_inject, rows, times, speeds, t_inject + (v.stop_s or v.bound_s) + 0.1)
        if reactions:
            first = min(reactions)
            v.detected_s, v.detected_by = round(first[0], 3), first[1]
        if v.expect == "slow":
            v.stop_s = v.detected_s               # the bound is on the reaction: the speed follows within T_r
        reported = [e for e in events if e.source == "safety_monitor" and e.event == "ssm_violation"]
        v.monitor_violations = len(reported)
        v.notes += [f"monitor: t+{e.stamp - t_inject:.2f}s {e.text}" for e in reported[:3]]
        samples = [(js.stamp, js.q, js.qd) for js in states if js.stamp >= first_inject - 0.5]
        found = truth_violations(self.monitor, samples, lambda t: self.human.at(t - self.rec.t0))
        v.truth_violations = len(found)
        v.notes += [f"truth: t+{t - t_inject:.2f}s {text}" for t, text in found[:3]]


# ---------------------------------------------------------------------------------------------- output
def markdown_table(verdicts: list[FaultVerdict]) -> str:
    rows = ["| fault | expected | bound | stop / reaction measured | first reaction | back | next shuttle after | "
            "violations (monitor / truth) |", "|---|---|---|---|---|---|---|---|"]
    ms = lambda x: "-" if x is None else f"{x * 1e3:.0f} ms"  # noqa: E731
    for v in verdicts:
        rows.append(f"| {v.name} | {v.expect} | {ms(v.bound_s)} | {ms(v.stop_s)} | {v.detected_by or '-'} "
                    f"({ms(v.detected_s)}) | {'yes' if v.back else 'NO'} | "
                    f"{'-' if v.resumed_s is None else f'{v.resumed_s:.1f} s'} | {v.monitor_violations} / "
                    f"{v.truth_violations} |")
    return "\n".join(rows)


def time_left(done: int, total: int, elapsed: float) -> str:
    """' (N s so far, about M s left)' from the mean time of the faults done; '' before the first."""
    if done <= 0:
        return ""
    return f" ({elapsed:.0f} s so far, about {elapsed / done * (total - done):.0f} s left)"


def run_campaign(prefix: str, endpoint: str, interface: str, channel: str | None, config: CellConfig,
                 robot: RobotModel, names: list[str], out: Path | None,
                 say: Callable[[str], None] = print, trace: bool = False) -> list[FaultVerdict]:
    """Inject each fault of `names` in turn and judge it; with `out`, write faults.json, faults.md and, when a
    verdict failed (or `trace`), the campaign's trace (every message it recorded, ``write_trace``)."""
    campaign = Campaign(prefix, endpoint, interface, channel, config, robot, say)
    verdicts = []
    started = time.monotonic()
    try:
        for k, name in enumerate(names):
            say(f"hrc faults: [{k + 1}/{len(names)}] {name} ...{time_left(k, len(names), time.monotonic() - started)}")
            verdict = campaign.run(name)
            verdicts.append(verdict)
            say(json.dumps({"fault": verdict.as_dict()}))
    finally:
        campaign.close()
    table = markdown_table(verdicts)
    say(table)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "faults.json").write_text(json.dumps([v.as_dict() for v in verdicts], indent=1))
        (out / "faults.md").write_text(table + "\n")
        failed = not all(v.ok for v in verdicts)
        if failed or trace:           # where a failed verdict's stop went: the whole campaign's messages
            where = out / "trace"
            where.mkdir(exist_ok=True)
            with campaign.recorder.lock:
                write_trace(where, campaign.rec)
            say(f"hrc faults: {'a verdict failed; ' if failed else ''}the campaign's trace is in {where}")
    return verdicts
