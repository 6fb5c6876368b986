"""The system's reaction latency, measured, and checked against the SSM's reaction time T_r (pure).

The ISO/TS 15066 formula assumes the robot starts reacting to a new human position within T_r. Here that
reaction is: a sample enters tracker_ingest, the human state reaches the scaler, the scaler's next tick
computes a command from it, and the driver puts the resulting target frame on the CAN bus. The robot
driver measures every such chain (``JointCommand.human_sample_stamp``: one clock, CLOCK_MONOTONIC, for
all processes of the host) and feeds it here. When the p99 over the recent window exceeds T_r, the
configured T_r is too small for this installation: a warning names both numbers, once per episode, and
says so again when it is back within.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LatencyCheck:
    """A change of verdict: event 'reaction_time_exceeded' (severity warning) or 'reaction_time_ok' (info)."""

    event: str
    severity: str
    text: str
    p99: float


class LatencyMeter:
    """Rolling window of (sample_to_frame, processing) latencies in seconds, and the T_r verdict."""

    def __init__(self, reaction_time: float, window: int = 2000, min_samples: int = 100) -> None:
        if not reaction_time > 0:
            raise ValueError(f"reaction_time must be positive, got {reaction_time}")
        self.reaction_time = reaction_time
        self.min_samples = min_samples
        self._window: deque[float] = deque(maxlen=window)
        self._pending: list[tuple[float, float]] = []
        self.exceeded = False

    def add(self, sample_to_frame: float, processing: float) -> None:
        """One chain: from the sample's arrival to its frame, and the processing part of that (s).
        Non-finite or negative latencies (a clock mix-up) are not data and are ignored."""
        if not (np.isfinite(sample_to_frame) and np.isfinite(processing)) or sample_to_frame < 0:
            return
        self._window.append(sample_to_frame)
        self._pending.append((sample_to_frame, processing))

    def drain(self) -> tuple[np.ndarray, np.ndarray]:
        """The (sample_to_frame, processing) latencies added since the last drain, for a report."""
        pending, self._pending = self._pending, []
        arr = np.array(pending, dtype=float).reshape(-1, 2)
        return arr[:, 0], arr[:, 1]

    def p99(self) -> float | None:
        """p99 of sample_to_frame over the window, or None before min_samples chains."""
        if len(self._window) < self.min_samples:
            return None
        return float(np.percentile(np.fromiter(self._window, float), 99))

    def check(self) -> LatencyCheck | None:
        """A LatencyCheck when the verdict (p99 > T_r or not) changes, else None."""
        p99 = self.p99()
        if p99 is None:
            return None
        exceeded = p99 > self.reaction_time
        if exceeded == self.exceeded:
            return None
        self.exceeded = exceeded
        if exceeded:
            return LatencyCheck("reaction_time_exceeded", "warning",
                                f"measured reaction latency p99 {p99 * 1e3:.1f} ms exceeds the configured T_r "
                                f"{self.reaction_time * 1e3:.0f} ms: the SSM distances assume a faster system; "
                                f"raise ssm.reaction_time in the cell configuration", p99)
        return LatencyCheck("reaction_time_ok", "info", f"reaction latency p99 {p99 * 1e3:.1f} ms is within "
                            f"T_r {self.reaction_time * 1e3:.0f} ms again", p99)
