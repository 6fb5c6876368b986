"""safety_monitor: an independent process that checks every measured joint state against the human state
of the moment it was measured (shared.safety.monitor.HumanHistory.pair: the newest sample taken at or before it;
shared.safety.monitor.SafetyMonitor.check_batch: pinocchio Jacobians and a closest-point computation of its own,
the standard's closest-point check) and counts violations of the ISO/TS 15066 speed limit (an exceedance
the robot does not answer as the formula assumes: react within T_r, then brake to a stop within T_s;
shared.safety.monitor.ReactionWindow) and of d_min (at once).

It keeps up and never guesses. Joint states and human states are queued by Zenoh as they arrive (no
Python runs per message) and taken, paired and checked in batches, vectorised, every 20 ms: two joint
states a pass, each against its own person, in one batch (a batch costs about 0.25 ms of numpy overhead
and 0.1 ms a state, where one coal query per pair cost 3.5 ms with ten human capsules, and a monitor at
100 Hz fell seconds behind; passes every 10 ms checked one state at a time and cost the cell 4-5 % of a
core more). A state that cannot be paired with the person of
its own moment, or that is reached more than 0.5 s after it was measured, is *unchecked*: counted and
reported, never a violation and never a pass (shared.safety.monitor.Backlog). A warning event 'monitor_behind'
says so when the checks run more than 0.1 s behind or states go unchecked for lateness, once per episode.

Out: each violation as a SafetyEvent (event 'ssm_violation', severity stop; at most ten a second); once a
second a summary event ('monitor_summary', value = violations so far) and a MonitorReport on
<prefix>/diag/monitor (checks, violations, unchecked, the lag's p99 and max over the run so far, smallest
margin and separation). It commands nothing: it is the witness, not the guard.

    python -m services.safety_monitor --connect tcp/127.0.0.1:7447
"""

from __future__ import annotations

import sys
import time
from collections import Counter

import numpy as np

from services.common import ServiceShell, open_service, run_paced, serve, service_parser, setup_logging
from shared.core.humans import HumanCapsules
from shared.robot.model import default_robot
from shared.safety.latency import DelayHistogram
from shared.safety.monitor import Backlog, HumanHistory, ReactionWindow, SafetyMonitor
from shared.wire.convert import capture_delay, humans_from_msg
from shared.wire.messages import HumanState, JointState, MonitorReport, SafetyEvent, encode

PASS_PERIOD = 0.02          # s between checking passes: two joint states a pass, checked in one batch
BEHIND = 0.1                # s: checks further behind than this raise 'monitor_behind'
HUGE = 1e9                  # what 'no value yet' (inf) travels as


class MonitorService:
    def __init__(self, shell: ServiceShell, monitor: SafetyMonitor, backlog: Backlog | None = None) -> None:
        self.shell, self.monitor = shell, monitor
        self.window = ReactionWindow(monitor.ssm.reaction_time, monitor.ssm.stopping_time)
        self.humans = HumanHistory()
        self.backlog = backlog or Backlog()
        self.checks = self.violations = self.unchecked = 0
        self.unchecked_why: Counter[str] = Counter()
        self.lags = DelayHistogram()         # s: measurement -> checked, the whole run
        self.behind = False
        self.min_margin = np.inf
        self.min_separation = np.inf
        self.seq = 0
        self._event_times: list[float] = []
        self._next_summary = 0.0
        self.event_pub = shell.session.declare_publisher(shell.keys.safety_events)
        self.report_pub = shell.session.declare_publisher(shell.keys.monitor)
        # queued by Zenoh and taken at each pass: no callback thread woken 200 times a second
        self.humans_in = shell.queue(shell.keys.human_state, HumanState)
        self.joints_in = shell.queue(shell.keys.joint_state, JointState)

    def take_inputs(self) -> None:
        """The people and joint states that arrived since the last pass, into the history and the backlog."""
        for msg in self.humans_in.drain():
            self.humans.add(msg.sample_stamp, humans_from_msg(msg))
            self.backlog.note_delay(capture_delay(msg))      # its capture to the tracker's publication
        for msg in self.joints_in.drain():
            self.backlog.add(msg.stamp, msg.q, msg.qd)

    def _event(self, event: str, severity: str, text: str, value: float | None = None) -> None:
        self.seq += 1
        self.event_pub.put(encode(SafetyEvent(source="safety_monitor", event=event, severity=severity, text=text,
                                              value=value, seq=self.seq, stamp=time.monotonic())))

    def check_pass(self, now: float) -> None:
        """Check every state whose person is known, in measurement order; count the ones that cannot be."""
        self.take_inputs()
        ready, unchecked = self.backlog.take(now, self.humans)
        done = now
        if ready:
            results = self.monitor.check_batch(np.array([r[1] for r in ready]), np.array([r[2] for r in ready]),
                                               [r[3] for r in ready])
            done = time.monotonic()
            for (stamp, *_), result in zip(ready, results):
                self.lags.add(done - stamp)
                self.checks += 1
                self.min_margin = min(self.min_margin, result.min_margin)
                self.min_separation = min(self.min_separation, result.min_separation)
                self._count(self.window.update(stamp, result))
        self.unchecked += len(unchecked)
        self.unchecked_why.update(u.kind for u in unchecked)
        late = [u for u in unchecked if u.kind == "late"]
        lag = done - ready[0][0] if ready else 0.0          # the oldest state of this pass
        behind = bool(late) or lag > BEHIND + self.backlog.delay       # not the people's own latency
        if behind and not self.behind:
            self._event("monitor_behind", "warning", f"the safety monitor runs {lag * 1e3:.0f} ms behind; "
                        f"{len(late)} joint states skipped unchecked" if late else
                        f"the safety monitor runs {lag * 1e3:.0f} ms behind the robot")
        self.behind = behind

    def _count(self, violations: list) -> None:
        if not violations:
            return
        self.violations += len(violations)
        now = time.monotonic()
        self._event_times = [t for t in self._event_times if t > now - 1.0]
        if len(self._event_times) < 10:
            self._event_times.append(now)
            v = violations[0]
            self._event("ssm_violation", "stop", f"{v.link} / human capsule {v.capsule}: {v.kind}, separation "
                        f"{v.separation:.3f} m, approach {v.approach_speed:.3f} m/s, limit {v.limit:.3f} m/s",
                        float(self.violations))

    def tick(self, now: float) -> None:
        self.check_pass(now)
        if now >= self._next_summary:
            self._next_summary = now + 1.0
            self.summary()

    def summary(self) -> None:
        p99, worst = self.lags.percentile(99), self.lags.largest
        why = ", ".join(f"{n} {kind}" for kind, n in self.unchecked_why.most_common())
        text = (f"{self.checks} checks, {self.violations} violations, {self.unchecked} unchecked"
                f"{f' ({why})' if why else ''}, smallest margin "
                f"{self.min_margin:.3f} m/s, smallest separation {self.min_separation:.3f} m, checked "
                f"{p99 * 1e3:.0f} ms behind (p99; max {worst * 1e3:.0f} ms)")
        self._event("monitor_summary", "info", text, float(self.violations))
        self.seq += 1
        self.report_pub.put(encode(MonitorReport(
            checks=self.checks, violations=self.violations, unchecked=self.unchecked, lag_p99=p99, lag_max=worst,
            min_margin=float(min(self.min_margin, HUGE)), min_separation=float(min(self.min_separation, HUGE)),
            seq=self.seq, stamp=time.monotonic())))


def main(argv: list[str] | None = None) -> int:
    parser = service_parser("safety_monitor", __doc__)
    args = parser.parse_args(argv)
    setup_logging(args.log_level)
    opened = open_service("safety_monitor", args)
    if opened is None:
        return 2
    config, shell = opened
    monitor = SafetyMonitor(default_robot(), config.ssm)
    # compiled (or loaded from numba's cache, half a second) before subscribing: the joint states queued
    # meanwhile would be late at the first pass
    someone = HumanCapsules(np.array([[[1.0, 0.0, 0.5], [1.0, 0.0, 1.5]]]), np.array([0.1]), np.zeros((1, 2, 3)),
                            np.array([True]))
    monitor.check_batch(np.zeros((1, 6)), np.zeros((1, 6)), [someone])
    service = MonitorService(shell, monitor)
    return serve(shell, f"safety_monitor: ISO/TS 15066 SSM on every joint state, keys {shell.keys.prefix}/",
                 lambda stop: run_paced(PASS_PERIOD, service.tick, stop))


if __name__ == "__main__":
    sys.exit(main())
