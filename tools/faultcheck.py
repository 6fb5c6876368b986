"""Judging one injected fault from what was recorded around it (pure: arrays and messages in, numbers out).

The fault campaign (tools.faults) injects a fault into the running cell at t_inject, lifts it at t_lift,
and records the measured joint states. Here:
* ``standstill_after``: how long after the injection the robot first stood still (every joint slower than
  STILL rad/s, as the drives report it);
* ``truth_violations``: the monitor's rule (shared.safety.monitor: the ISO/TS 15066 limit, the reaction window,
  d_min) applied to the measured joint states against the *true* human (the scripted person the campaign
  sends, not the tracker's view of them), so a fault that blinds the tracker or the monitor itself is still
  judged;
* ``nearer_seen``: when the scaler took in a person shown nearer than they are (the jump fault);
* ``stop_timeline``: what the scaler did and how fast the robot went after an injection, for a stop that
  missed its bound (the verdict's notes carry it, so a failure on a busy machine can be read afterwards);
* ``FaultVerdict``: the whole verdict for one fault, as the campaign prints it and the tests assert it.
Times in seconds (one CLOCK_MONOTONIC for the host), speeds in rad/s.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Callable

import numpy as np

from shared.core.humans import HumanCapsules
from shared.safety.monitor import ReactionWindow, SafetyMonitor

STILL = 0.02                 # rad/s: every joint slower than this is a standstill


def standstill_after(times: np.ndarray, speeds: np.ndarray, t_inject: float, still: float = STILL) -> float | None:
    """Seconds from t_inject to the first sample at or after it with the robot still (speeds: the largest
    joint speed of each sample), or None when it never stood still in the samples given."""
    times, speeds = np.asarray(times, dtype=float), np.asarray(speeds, dtype=float)
    idx = np.flatnonzero((times >= t_inject) & (speeds < still))
    return float(times[idx[0]] - t_inject) if idx.size else None


def stop_timeline(t_inject: float, statuses: list[tuple[float, str, str, int, float]], times: np.ndarray,
                  speeds: np.ndarray, until: float) -> list[str]:
    """What happened between an injection and `until` (s, same clock), for a stop that missed its bound:
    each change of the scaler's (status, method, trajectory version) with its alpha, and the robot's
    largest joint speed every 50 ms. statuses: (stamp, status, method, version, alpha). Times in ms after
    the injection."""
    lines, last = [], None
    for stamp, status, method, version, alpha in statuses:
        if t_inject <= stamp <= until and (status, method, version) != last:
            lines.append(f"t+{(stamp - t_inject) * 1e3:.0f}ms scaler {status} {method} v{version} alpha {alpha:.2f}")
            last = (status, method, version)
    times, speeds = np.asarray(times, dtype=float), np.asarray(speeds, dtype=float)
    marks = np.arange(t_inject, until + 1e-9, 0.05)
    picks = np.searchsorted(times, marks)
    shown = [f"{(m - t_inject) * 1e3:.0f}:{speeds[k]:.2f}" for m, k in zip(marks, picks) if k < times.size]
    if shown:
        lines.append("largest joint speed (ms: rad/s) " + " ".join(shown))
    return lines


def moving_at(times: np.ndarray, speeds: np.ndarray, t: float, still: float = STILL) -> bool:
    """The robot was moving at time t (the last sample before it)."""
    times = np.asarray(times, dtype=float)
    k = int(np.searchsorted(times, t, side="right")) - 1
    return k >= 0 and float(np.asarray(speeds)[k]) >= still


def nearer_seen(before: float | None, separations: list[tuple[float, float]], jump: float) -> float | None:
    """When (s, the statuses' clock) the scaler first took in a person shown `jump` (m) nearer than they are:
    the first status after the injection whose smallest separation (separations: (stamp, m) in order) is
    nearer than before it by two thirds of the jump. before: the last status's before the injection, None
    where it had nobody in its problem (no SSM rows: the status says no separation): then the first
    separation at all is the nearer person taken in. (That case was judged as a stop that never came, and
    the campaign failed a scaler that had taken the person in within 4 ms.) None: not seen."""
    for stamp, separation in separations:
        if before is None or separation < before - 2.0 * jump / 3.0:
            return stamp
    return None


def truth_violations(monitor: SafetyMonitor, samples: list[tuple[float, np.ndarray, np.ndarray]],
                     human_at: Callable[[float], HumanCapsules]) -> list[tuple[float, str]]:
    """(time, description) of every violation of the monitor's rule over `samples` (time, q, qd), sorted by
    time, with the human as human_at(time) says they really were."""
    window = ReactionWindow(monitor.ssm.reaction_time, monitor.ssm.stopping_time)
    found = []
    for t, q, qd in sorted(samples, key=lambda s: s[0]):
        for v in window.update(t, monitor.check(q, qd, human_at(t))):
            found.append((t, f"{v.link} / capsule {v.capsule}: {v.kind}, separation {v.separation:.3f} m, "
                             f"approach {v.approach_speed:.3f} m/s, limit {v.limit:.3f} m/s"))
    return found


@dataclass
class FaultVerdict:
    """One fault's outcome. expect: 'stop' (the robot must stand still within bound_s), 'slow' (the scaling
    must take the fault's effect within bound_s; stop_s then holds that reaction time) or 'any' (no stop is
    needed: the fault is outside the chain that keeps the robot safe, which goes on working, or either a
    stop or going on is safe). stop_s: measured injection -> standstill (None: not observed). detected_s:
    injection -> the first protective reaction seen (a driver stop event, an EMCY, the scaler's alpha at
    0). back: the service is running again (restarted under the supervisor, or resumed). resumed_s: lift -> the next
    completed
    shuttle. t_inject: when (s since the campaign began; its logs are stamped). violations: the monitor
    service's reports plus the check against the true human."""

    name: str
    expect: str
    bound_s: float | None
    bound_why: str
    moving_at_injection: bool = False
    t_inject: float = 0.0                 # s since the campaign started (to find the fault in the logs)
    stop_s: float | None = None
    detected_s: float | None = None
    detected_by: str = ""
    back: bool = False
    resumed_s: float | None = None
    monitor_violations: int = 0
    truth_violations: int = 0
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        stopped_in_time = self.expect == "any" or (self.stop_s is not None and self.bound_s is not None
                                                   and self.stop_s <= self.bound_s)
        return (self.moving_at_injection and stopped_in_time and self.back and self.resumed_s is not None
                and self.monitor_violations == 0 and self.truth_violations == 0)

    def as_dict(self) -> dict:
        return {**asdict(self), "ok": self.ok}
