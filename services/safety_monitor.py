"""safety_monitor: an independent process that checks every measured joint state against the human state
of the moment it was measured (shared.monitor.HumanHistory: the newest sample taken at or before it, so a
monitor that falls behind still pairs them as they were; shared.monitor: coal distances, pinocchio
Jacobians, the standard's closest-point check) and counts violations of the ISO/TS 15066 speed limit
(an exceedance the robot does not answer as the formula assumes: react within T_r, then brake to a stop
within T_s; see shared.monitor.ReactionWindow) and of d_min (at once).

Each violation goes out as a SafetyEvent (event 'ssm_violation', severity stop; at most ten a second),
and once a second a summary (event 'monitor_summary', value = violations so far, text with the checks,
the smallest margin seen, and how far behind the checks ran). It commands nothing: it is the witness,
not the guard.

    python -m services.safety_monitor --connect tcp/127.0.0.1:7447
"""

from __future__ import annotations

import sys
import threading
import time

import numpy as np

from services.common import ServiceShell, open_service, run_paced, serve, service_parser, setup_logging
from shared.convert import humans_from_msg
from shared.messages import HumanState, JointState, SafetyEvent, encode
from shared.monitor import HumanHistory, ReactionWindow, SafetyMonitor
from shared.robot_model import default_robot


class MonitorService:
    def __init__(self, shell: ServiceShell, monitor: SafetyMonitor) -> None:
        self.shell, self.monitor = shell, monitor
        self.window = ReactionWindow(monitor.ssm.reaction_time, monitor.ssm.stopping_time)
        self.lock = threading.Lock()
        self.humans = HumanHistory()
        self.checks = 0
        self.max_lag = 0.0          # s: how far behind the newest joint state checked was, since the last summary
        self.violations = 0
        self.min_margin = np.inf
        self.min_separation = np.inf
        self.seq = 0
        self._event_times: list[float] = []
        self.event_pub = shell.session.declare_publisher(shell.keys.safety_events)
        shell.subscribe(shell.keys.human_state, HumanState, self.on_humans)
        shell.subscribe(shell.keys.joint_state, JointState, self.on_joints)

    def on_humans(self, msg: HumanState) -> None:
        with self.lock:
            self.humans.add(msg.sample_stamp, humans_from_msg(msg))

    def _event(self, event: str, severity: str, text: str, value: float | None = None) -> None:
        self.seq += 1
        self.event_pub.put(encode(SafetyEvent(source="safety_monitor", event=event, severity=severity, text=text,
                                              value=value, seq=self.seq, stamp=time.monotonic())))

    def on_joints(self, msg: JointState) -> None:
        with self.lock:
            humans = self.humans.at(msg.stamp)
        result = self.monitor.check(msg.q, msg.qd, humans)
        with self.lock:
            self.checks += 1
            self.max_lag = max(self.max_lag, time.monotonic() - msg.stamp)
            self.min_margin = min(self.min_margin, result.min_margin)
            self.min_separation = min(self.min_separation, result.min_separation)
            violations = self.window.update(msg.stamp, result)
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

    def summary(self, now: float) -> None:
        with self.lock:
            text = (f"{self.checks} checks, {self.violations} violations, smallest margin "
                    f"{self.min_margin:.3f} m/s, smallest separation {self.min_separation:.3f} m, "
                    f"checked up to {self.max_lag * 1e3:.0f} ms behind")
            self.max_lag = 0.0
            self._event("monitor_summary", "info", text, float(self.violations))


def main(argv: list[str] | None = None) -> int:
    parser = service_parser("safety_monitor", __doc__)
    args = parser.parse_args(argv)
    setup_logging(args.log_level)
    opened = open_service("safety_monitor", args)
    if opened is None:
        return 2
    config, shell = opened
    service = MonitorService(shell, SafetyMonitor(default_robot(), config.ssm))
    return serve(shell, f"safety_monitor: ISO/TS 15066 SSM on every joint state, keys {shell.keys.prefix}/",
                 lambda stop: run_paced(1.0, service.summary, stop))


if __name__ == "__main__":
    sys.exit(main())
