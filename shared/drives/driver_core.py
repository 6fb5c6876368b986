"""The robot driver's decisions, as a pure core: no bus, no clock (the service passes `now`).

Every cycle (one SYNC period) ``DriverCore.cycle`` takes what the drives reported (statusword, position,
velocity, heartbeat age, EMCY) and returns the controlword and the position setpoint for each drive,
plus safety events. States:

* ENABLING: walk every drive to operation enabled (CiA 402, fault reset edges where needed), holding the
  setpoints at the actual positions; then RUNNING once a fresh command at rest starts where the robot is.
* RUNNING: setpoint = the latest command, passed through ``follow_step``: clamped to the joint limits
  and to what the drive follows, its velocity and acceleration limits (``shared.drives.prbt``), so no
  command, however abrupt, gives the drive a setpoint it cannot follow (each clamp is a 'warning' safety
  event, reported once per episode); a stop the scaler commands becomes the fastest stop the drive can make.
* STOPPED: quick stop on every drive, setpoints held at the actual positions. Entered on a command older
  than command_timeout, a drive in fault, an EMCY, a heartbeat older than heartbeat_timeout, a drive
  leaving operation enabled, or frames being lost (MISSED_LIMIT of the last MISSED_WINDOW SYNCs not
  answered by every drive within their period: a drive that loses frames falls behind its setpoints,
  overshoots them, and is reported late, beyond what the tracking margin covers); each with a 'stop' safety
  event. Left only on request() of 'recover', and only when no drive is in fault, all heartbeats are fresh
  and no EMCY is pending.
"""

from __future__ import annotations

import enum
import math
from collections import deque
from dataclasses import dataclass, field

import numba
import numpy as np

from shared.drives.cia402 import State, next_controlword, state_from_statusword
from shared.drives.prbt import PERIOD, describe_emcy
from shared.robot.model import JointLimits


class Mode(enum.Enum):
    ENABLING = "enabling"
    RUNNING = "running"
    STOPPED = "stopped"


@dataclass
class Feedback:
    """What one drive last reported. statusword None: nothing received yet. heartbeat_age (s)."""

    statusword: int | None = None
    position: float = math.nan
    velocity: float = 0.0
    heartbeat_age: float = math.inf
    emcy: int | None = None            # the last non-zero EMCY code not yet handled


@dataclass
class Event:
    event: str
    severity: str                      # info | warning | stop
    text: str
    value: float | None = None         # the figure the text gives, where one (stale_command: s without a command)


@dataclass
class CycleOutput:
    controlwords: list[int]
    setpoints: np.ndarray              # rad
    setpoint_velocity: np.ndarray      # rad/s: the velocity the setpoints move at (0 unless running)
    events: list[Event] = field(default_factory=list)
    mode: Mode = Mode.ENABLING
    drive_states: list[State] = field(default_factory=list)


COMMAND_TIMEOUT = 0.05         # s: a command older than this stops the drives
HEARTBEAT_TIMEOUT = 0.3        # s: a drive's heartbeat older than this stops the drives
# SYNCs not answered by every drive in their period, of the last MISSED_WINDOW, that stop the drives: frames
# are being lost. A healthy cell misses 0-3 in a 24 s demo, loaded, at most 2 within a second
# (docs/measurements.md), and 5 within a second once in the full test suite; a drive that loses a tenth of its
# frames misses about one SYNC in five.
MISSED_LIMIT, MISSED_WINDOW = 10, 100


EXACT = 1e-9                  # rad: a setpoint this close to the command is the command
# rad/s: a recovery starts only once every joint is slower than this. A quick stop or a fault reaction brakes the
# robot on the drives' own ramp; enabled again before it ends, a drive follows a setpoint where it was, overruns it
# by its braking distance (0.1 rad from 1.2 rad/s) and faults (EMCY 0x8611, seen in a loaded run on 2026-12-05)
RECOVER_BELOW = 0.02
START_WAIT = 2.0              # s the drives stand enabled without a command to start on before the driver says why
# rad: a setpoint further than this from the command is a clamp worth a warning. Below it the limiter
# absorbs timing (the scaler's ticks and the SYNC on two clocks: a late command costs one period's
# extrapolation, an early one a catch-up a few mrad long), which is not a command beyond the drives.
CLAMP_TOLERANCE = 0.02


def follow_step(command: np.ndarray, command_velocity: np.ndarray, setpoint: np.ndarray, velocity: np.ndarray,
                limits: JointLimits, period: float) -> tuple[np.ndarray, np.ndarray, bool]:
    """The next setpoint (rad) and its velocity (rad/s) towards `command`, and whether it had to differ.

    The setpoint moves with the command's own velocity (feed-forward) plus a braking-aware correction of
    what is left between them (at most the rest in one period, never faster than a stop at the drive's
    acceleration allows, so it lands on a command that stopped instead of overshooting it), never so fast
    that it could not stop where the command would if it braked now at that acceleration (a setpoint left
    behind a command at the velocity limit, which a drive never makes up, meets it at its stop when it
    brakes: before, 130 mrad behind, it overshot the stop by 104 mrad and came back towards a person), then the
    velocity is limited to the joint's velocity limit and its change to the drive's acceleration
    (``limits.monitor_acceleration``) and to what still stops before a position limit. A command that is
    itself followable is reproduced exactly: setpoint == command. `clamped`: the setpoint is further than
    CLAMP_TOLERANCE from the command (or the command is beyond a position limit). Pure; compiled
    (``_follow_kernel``, joint by joint: the driver runs it twice a period, and two dozen numpy calls on six
    numbers are mostly per-call overhead); a NaN anywhere propagates to that joint's setpoint as in numpy, and a
    NaN or infinite command velocity counts as 0 or the velocity limit (numpy's nan_to_num, then the clip).
    """
    new_s, new_v, clamped = _follow_kernel(np.asarray(command, dtype=np.float64),
                                           np.asarray(command_velocity, dtype=np.float64),
                                           np.asarray(setpoint, dtype=np.float64), np.asarray(velocity, dtype=np.float64),
                                           limits.lower, limits.upper, limits.velocity, limits.monitor_acceleration,
                                           float(period))
    return new_s, new_v, bool(clamped)


def warm_up(limits: JointLimits) -> None:
    """Compile (or load from numba's cache, which takes a moment) the setpoint limiter before the first SYNC:
    the first command must not wait for it while the drives' SYNC watchdog runs."""
    rest = (limits.lower + limits.upper) / 2
    follow_step(rest, np.zeros_like(rest), rest, np.zeros_like(rest), limits, PERIOD)


@numba.njit(cache=True, inline="always")
def _minimum(a, b):
    """np.minimum of two floats: NaN when either is."""
    return math.nan if a != a or b != b else (a if a < b else b)


@numba.njit(cache=True, inline="always")
def _maximum(a, b):
    """np.maximum of two floats: NaN when either is."""
    return math.nan if a != a or b != b else (a if a > b else b)


@numba.njit(cache=True)
def _follow_kernel(command, command_velocity, setpoint, velocity, lower, upper, v_max, a, period):
    n = command.shape[0]
    out_s, out_v = np.empty(n), np.empty(n)
    clamped = False
    for j in range(n):
        target = _minimum(_maximum(command[j], lower[j]), upper[j])
        w = command_velocity[j]
        w = 0.0 if w != w else w                               # nan_to_num; the clip takes infinities
        w = _minimum(_maximum(w, -v_max[j]), v_max[j])
        rest = target - setpoint[j] - w * period
        sign = math.nan if rest != rest else (1.0 if rest > 0.0 else (-1.0 if rest < 0.0 else 0.0))
        correction = sign * _minimum(abs(rest) / period, math.sqrt(2.0 * a[j] * abs(rest)))
        wanted = w + correction
        # never past where the command stops if it brakes now at the drives' deceleration (plus its period's
        # travel and a[j] T^2 of slack, which no followable command reaches): a setpoint behind a command that
        # brakes meets it at its stop instead of overshooting it and coming back
        step = a[j] * period
        ahead = target + w * abs(w) / (2.0 * a[j]) + w * period - setpoint[j]
        forward = math.sqrt(step * step + 2.0 * a[j] * _maximum(ahead + step * period, 0.0)) - step
        backward = math.sqrt(step * step + 2.0 * a[j] * _maximum(step * period - ahead, 0.0)) - step
        wanted = _minimum(_maximum(wanted, -backward), forward)
        new_v = _minimum(_maximum(wanted, velocity[j] - a[j] * period), velocity[j] + a[j] * period)
        # still able to stop inside the position limits (this wins over the acceleration limit)
        room_up = math.sqrt(2.0 * a[j] * _maximum(upper[j] - setpoint[j], 0.0))
        room_down = math.sqrt(2.0 * a[j] * _maximum(setpoint[j] - lower[j], 0.0))
        new_v = _minimum(_maximum(new_v, -_minimum(v_max[j], room_down)), _minimum(v_max[j], room_up))
        new_s = _minimum(_maximum(setpoint[j] + new_v * period, lower[j]), upper[j])
        out_v[j] = (new_s - setpoint[j]) / period
        clamped = clamped or abs(new_s - command[j]) > CLAMP_TOLERANCE or target != command[j]
        out_s[j] = target if abs(new_s - target) <= EXACT else new_s
    return out_s, out_v, clamped


class DriverCore:
    def __init__(self, limits: JointLimits, period: float = PERIOD, command_timeout: float = COMMAND_TIMEOUT,
                 heartbeat_timeout: float = HEARTBEAT_TIMEOUT, start_tolerance: float = 0.02) -> None:
        self.limits = limits
        self.period = period
        self.command_timeout = command_timeout
        self.heartbeat_timeout = heartbeat_timeout
        self.start_tolerance = start_tolerance
        self.mode = Mode.ENABLING
        self._command: np.ndarray | None = None
        self._command_velocity: np.ndarray | None = None
        self._command_used = False          # a SYNC has already taken the latest command
        self._command_time = -math.inf
        self._setpoint: np.ndarray | None = None
        self._setpoint_velocity = np.zeros(limits.lower.size)
        self._reset_phase = False
        self._enabled_since: float | None = None    # while enabling: since when every drive is enabled
        self._start_told = False                     # ... and why it has not started, said (once per wait)
        self._clamping = False
        self._recover = False
        self.stop_reason = ""
        self._answers: deque[bool] = deque(maxlen=MISSED_WINDOW)      # while running: each SYNC answered or not

    @property
    def stopped_by(self) -> str:
        """Why the drives are stopped (the stop event's text), '' while they are not."""
        return self.stop_reason if self.mode is Mode.STOPPED else ""

    # ------------------------------------------------------------------------------------------ inputs
    def command(self, q: np.ndarray, now: float, qd: np.ndarray | None = None) -> np.ndarray | None:
        """Take a new command: position q (rad) and velocity qd (rad/s; None: estimated from the last
        command). While running, returns the setpoint it gives right away (``follow_step`` from the last
        SYNC's setpoint, exactly as the next cycle will), so the service can put it on the bus before the
        SYNC; None otherwise."""
        q = np.asarray(q, dtype=float).copy()
        if qd is None:
            elapsed = now - self._command_time
            qd = (q - self._command) / elapsed if self._command is not None and 0.0 < elapsed <= 2 * self.period \
                else np.zeros_like(q)
        self._command, self._command_velocity = q, np.asarray(qd, dtype=float).copy()
        self._command_time, self._command_used = now, False
        if self.mode is not Mode.RUNNING or self._setpoint is None:
            return None
        return self._next()[0]

    def request(self, action: str) -> None:
        if action == "recover":
            self._recover = True
        elif action == "stop":
            self._stop("requested", "stop requested")

    # ------------------------------------------------------------------------------------------ cycle
    def _stop(self, event: str, text: str, value: float | None = None) -> list[Event]:
        if self.mode is Mode.STOPPED:
            return []
        self.mode, self.stop_reason, self._recover = Mode.STOPPED, text, False
        return [Event(event, "stop", text, value)]

    def _faults(self, feedback: list[Feedback], states: list[State]) -> tuple[str, str] | None:
        for k, (fb, st) in enumerate(zip(feedback, states)):
            if fb.heartbeat_age > self.heartbeat_timeout:
                return "heartbeat_lost", f"joint {k + 1}: no heartbeat for {fb.heartbeat_age * 1000:.0f} ms"
            if fb.emcy:
                return "emcy", f"joint {k + 1}: {describe_emcy(fb.emcy)}"
            if st in (State.FAULT, State.FAULT_REACTION_ACTIVE):
                return "drive_fault", f"joint {k + 1}: drive in {st.value}"
        return None

    def cycle(self, now: float, feedback: list[Feedback], answered: bool = True,
              judged: list[bool] | None = None) -> CycleOutput:
        """One SYNC period. answered: every drive's answer to the last SYNC has been read (the master's word;
        False: some drive's frames did not come, or not yet, and `feedback` holds its older ones). judged: the
        SYNCs the master has judged since the last cycle by their frames' stamps (``AnswerWindows``: an
        answer read late is not a lost one), counted for frames being lost in `answered`'s place; None: count
        `answered`."""
        states = [state_from_statusword(fb.statusword) if fb.statusword is not None else State.NOT_READY
                  for fb in feedback]
        actual = np.array([fb.position for fb in feedback])
        events: list[Event] = []
        if self._setpoint is None or not np.all(np.isfinite(self._setpoint)):
            self._setpoint = actual.copy()
        fault = self._faults(feedback, states)
        # while enabling, a drive still in fault is expected (it is being reset); a lost heartbeat or a new
        # EMCY is not
        if fault is not None and (self.mode is Mode.RUNNING or fault[0] in ("heartbeat_lost", "emcy")):
            events += self._stop(*fault)
        if self.mode is Mode.RUNNING:
            self._answers.extend([answered] if judged is None else judged)
            missed = len(self._answers) - sum(self._answers)
            if missed >= MISSED_LIMIT:
                self._answers.clear()
                events += self._stop("frames_lost", f"{missed} of the last {MISSED_WINDOW} SYNCs not answered by "
                                                    f"every drive in time: frames are being lost")
            elif now - self._command_time > self.command_timeout:
                events += self._stop("stale_command", f"no command for {(now - self._command_time) * 1000:.0f} ms",
                                     now - self._command_time)
            elif any(st is not State.OPERATION_ENABLED for st in states):
                events += self._stop("drive_disabled", "a drive left operation enabled")
        if self.mode is Mode.STOPPED:
            if self._recover:
                if fault is None or fault[0] in ("drive_fault", "emcy"):
                    # still braking: the recovery stays asked for, and starts once the robot is at rest
                    if max(abs(fb.velocity) for fb in feedback) < RECOVER_BELOW:
                        self.mode, self._recover = Mode.ENABLING, False
                        events.append(Event("recovering", "info", "recovery requested: resetting and enabling"))
                else:
                    events.append(Event("recover_refused", "warning", f"recovery refused: {fault[1]}"))
                    self._recover = False
        if self.mode is not Mode.RUNNING:
            self._setpoint_velocity = np.zeros_like(self._setpoint_velocity)
        if self.mode is Mode.ENABLING:
            enabled = all(st is State.OPERATION_ENABLED for st in states)
            if enabled and self._fresh(now) and self._starts_here(actual):
                self.mode, self._setpoint = Mode.RUNNING, actual.copy()
                self._answers.clear()           # the frames lost are counted while it runs, from now
                self._enabled_since, self._start_told = None, False
                events.append(Event("running", "info", "all drives enabled, following commands"))
            elif enabled:
                events += self._not_started(now, actual)
            else:
                self._enabled_since, self._start_told = None, False
        if self.mode is Mode.RUNNING:
            events += self._follow()
            controlwords = [next_controlword(st, State.OPERATION_ENABLED) for st in states]
        elif self.mode is Mode.ENABLING:
            self._setpoint = np.where(np.isfinite(actual), actual, self._setpoint)
            self._reset_phase = not self._reset_phase
            controlwords = [next_controlword(st, State.OPERATION_ENABLED, ip_running=True,
                                             reset_phase=self._reset_phase) for st in states]
        else:
            self._setpoint = np.where(np.isfinite(actual), actual, self._setpoint)
            controlwords = [next_controlword(st, State.QUICK_STOP_ACTIVE) if st is State.OPERATION_ENABLED
                            else next_controlword(st, State.SWITCH_ON_DISABLED) for st in states]
        return CycleOutput(controlwords, self._setpoint.copy(), self._setpoint_velocity.copy(), events, self.mode,
                           states)

    def _not_started(self, now: float, actual: np.ndarray) -> list[Event]:
        """Once the drives have stood enabled for START_WAIT without a command to start on: why (a warning, once
        per wait): no fresh command, one away from the robot, or one that moves (``_starts_here``)."""
        if self._enabled_since is None:
            self._enabled_since = now
        if now - self._enabled_since < START_WAIT or self._start_told:
            return []
        self._start_told = True
        if not self._fresh(now):
            why = ("no command yet" if self._command is None
                   else f"the last command came {(now - self._command_time) * 1e3:.0f} ms ago")
        else:
            off = float(np.abs(self._command - actual).max())
            speed = float(np.abs(self._command_velocity).max())
            why = (f"the command is {off * 1e3:.1f} mrad from the robot (at most {self.start_tolerance * 1e3:.0f})"
                   if not off <= self.start_tolerance else                # (NaN: a drive's position unknown)
                   f"the command moves at {speed:.3f} rad/s (a start is a command at rest, below {RECOVER_BELOW})")
        return [Event("not_started", "warning", f"drives enabled for {now - self._enabled_since:.1f} s, not "
                                                f"started: {why}")]

    def _starts_here(self, actual: np.ndarray) -> bool:
        """Whether the latest command is one the drives may start following from `actual` (rad): where the robot
        is (start_tolerance) and at rest (every joint's commanded velocity below RECOVER_BELOW). A command that
        moves is a path already under way, which the robot at rest would chase at its limits, faster than any
        command an SSM check has seen: a scaler held up 1.5 s ran its old path on for a few ticks on the joint
        states of that time, and a recovery taking such a command as it passed by would start the robot mid-
        motion (the scaler holds the robot where it stands, velocity 0, whenever the driver does not run)."""
        return bool(np.abs(self._command - actual).max() <= self.start_tolerance
                    and np.abs(self._command_velocity).max() < RECOVER_BELOW)

    def _fresh(self, now: float) -> bool:
        return self._command is not None and now - self._command_time <= self.command_timeout

    def _next(self) -> tuple[np.ndarray, np.ndarray, bool]:
        """The setpoint the latest command gives from the last SYNC's setpoint (see follow_step). The scaler
        ticks on its own clock: now and then a SYNC comes before its next command. A command a SYNC has
        already taken then goes on one period along its own velocity (the motion it describes, inside the
        reaction time T_r the SSM allows for), and no further: a second miss brakes."""
        command = self._command + self._command_velocity * self.period if self._command_used else self._command
        return follow_step(command, self._command_velocity, self._setpoint, self._setpoint_velocity,
                           self.limits, self.period)

    def _follow(self) -> list[Event]:
        self._setpoint, self._setpoint_velocity, clamped = self._next()
        self._command_used = True
        events = []
        if clamped and not self._clamping:
            events.append(Event("command_clamped", "warning",
                                "a command beyond the joint limits or faster or more abrupt than the drives "
                                "follow was limited to what they follow"))
        self._clamping = clamped
        return events
