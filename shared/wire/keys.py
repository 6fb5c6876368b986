"""The Zenoh key space of one robot cell, built from its prefix (e.g. ``hrc/cell1``).

Every service takes its keys from here, so the topic layout lives in one place:

    <prefix>/human/raw            tracker -> tracker_ingest        HumanRaw
    <prefix>/human/state          tracker_ingest -> planner, scaler, monitor   HumanState
    <prefix>/robot/goal           CLI -> planner                   Goal
    <prefix>/planner/trajectory   planner -> scaler                TrajectoryMsg
    <prefix>/scaler/command       scaler -> robot_driver           JointCommand
    <prefix>/scaler/status        scaler -> planner, CLI           ScalerStatus
    <prefix>/robot/joint_state    robot_driver -> scaler, planner, monitor     JointState
    <prefix>/robot/request        CLI -> robot_driver              DriverRequest (stop, recover)
    <prefix>/safety/events        every service -> CLI, logs       SafetyEvent
    <prefix>/diag/latency         robot_driver -> CLI, benchmarks  LatencyReport
    <prefix>/diag/drive_lag       robot_driver -> CLI, reports     DriveLagReport
    <prefix>/diag/monitor         safety_monitor -> CLI, reports   MonitorReport
    <prefix>/alive/<service>      liveliness token of each service
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from shared.core.errors import KeyError_

_CHUNK = re.compile(r"^[A-Za-z0-9_\-]+$")
SERVICES = ("tracker_ingest", "planner", "scaler", "robot_driver", "safety_monitor", "router", "cli", "ros2_bridge")


def validate_prefix(prefix: str) -> str:
    """A prefix is one or more '/'-separated chunks of letters, digits, '_' and '-' (no wildcards)."""
    if not isinstance(prefix, str) or not prefix:
        raise KeyError_(f"cell prefix: expected a non-empty string, got {prefix!r}")
    chunks = prefix.split("/")
    bad = [c for c in chunks if not _CHUNK.match(c)]
    if bad:
        raise KeyError_(f"cell prefix {prefix!r}: chunk(s) {bad} may only hold letters, digits, '_' and '-'")
    return prefix


@dataclass(frozen=True)
class KeySpace:
    """All keys of one cell."""

    prefix: str = "hrc/cell1"

    def __post_init__(self) -> None:
        validate_prefix(self.prefix)

    def _key(self, suffix: str) -> str:
        return f"{self.prefix}/{suffix}"

    @property
    def human_raw(self) -> str:
        return self._key("human/raw")

    @property
    def human_state(self) -> str:
        return self._key("human/state")

    @property
    def goal(self) -> str:
        return self._key("robot/goal")

    @property
    def trajectory(self) -> str:
        return self._key("planner/trajectory")

    @property
    def command(self) -> str:
        return self._key("scaler/command")

    @property
    def scaler_status(self) -> str:
        return self._key("scaler/status")

    @property
    def joint_state(self) -> str:
        return self._key("robot/joint_state")

    @property
    def driver_request(self) -> str:
        return self._key("robot/request")

    @property
    def safety_events(self) -> str:
        return self._key("safety/events")

    @property
    def latency(self) -> str:
        return self._key("diag/latency")

    @property
    def drive_lag(self) -> str:
        return self._key("diag/drive_lag")

    @property
    def monitor(self) -> str:
        return self._key("diag/monitor")

    def alive(self, service: str) -> str:
        """Liveliness token key of a service."""
        if service not in SERVICES:
            raise KeyError_(f"unknown service {service!r}; known: {SERVICES}")
        return self._key(f"alive/{service}")

    @property
    def alive_all(self) -> str:
        return self._key("alive/*")
