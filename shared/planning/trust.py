"""Whether the planning layer's forecast of the people has held lately: a choice that trusts the forecast is
made only then.

A forecast is a guess (``shared.planning.forecast``). For someone walking steadily across the cell the constant-
velocity forecast is right for seconds; for someone who wanders, stops and turns it is wrong within one. The
planning layer's choices that only pay when the forecast is right (the straight line instead of the folded leg:
``Replanner.plan_goal``) are made only where it has held: every snapshot of the people kept over the last
`span` seconds, moved on by the same forecaster to now, lands within `tolerance` of where the people are now.
This is confidence-aware prediction (Fridovich-Keil et al., "Probabilistically safe robot planning with
confidence-based human predictions", RSS 2018) reduced to a yes or no on the forecast's own recent error; the
safety of the robot never depends on it (the scaling layer and the monitor use the people as tracked).

Pure: the clock is the caller's `now`; no I/O.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from shared.core.humans import STANDING_SPEED, HumanCapsules, end_speeds
from shared.planning.forecast import Forecaster

SNAPSHOT_EVERY = 0.1     # s between the snapshots kept


class ForecastTrust:
    """The forecaster's recent record on the people in view. `update` with every new human sample; `trusted`
    says whether the forecast has held over the last `span` s (each snapshot within `tolerance` m of now, every
    end point). Nobody in view, a change in the number of capsules or a velocity the tracker does not know: not
    trusted (the robust choice is made). Less than `span` of history (people just seen): trusted only where every
    capsule in view moves at least at the standing speed and the record there is holds. A walker's course is in
    their velocity from the first sample; someone at rest gives no sign of where they go next, so a wanderer
    pausing is not bet on (docs/measurements.md, session 73)."""

    def __init__(self, forecaster: Forecaster, span: float = 1.0, tolerance: float = 0.15) -> None:
        if not (span > 0.0 and tolerance >= 0.0):
            raise ValueError(f"ForecastTrust: span must be > 0 s and tolerance >= 0 m, not {span}, {tolerance}")
        self.forecaster, self.span, self.tolerance = forecaster, float(span), float(tolerance)
        self.snapshots: deque[tuple[float, HumanCapsules]] = deque()
        self.now: HumanCapsules | None = None

    def update(self, now: float, humans: HumanCapsules | None) -> None:
        """A new human sample at `now` (s): kept as the present, and as a snapshot every SNAPSHOT_EVERY s."""
        seen = humans is not None and humans.count > 0 and bool(np.all(humans.velocity_known))
        if not seen or (self.now is not None and humans.count != self.now.count):
            self.snapshots.clear()
        self.now = humans
        if not seen:
            return
        if not self.snapshots or now - self.snapshots[-1][0] >= SNAPSHOT_EVERY - 1e-9:
            self.snapshots.append((now, humans))
        while len(self.snapshots) > 1 and now - self.snapshots[1][0] >= self.span:
            self.snapshots.popleft()        # the oldest kept is the last one at least `span` old

    def error(self, now: float, partial: bool = False) -> float:
        """The largest distance (m) between where a snapshot's forecast has an end point now and where it is;
        inf where there is not `span` of history to judge by (partial: judged by the history there is)."""
        if self.now is None or not self.snapshots or (not partial and not self.has_span(now)):
            return np.inf
        worst = 0.0
        for t, then in self.snapshots:
            ahead = now - t
            if ahead <= 0.0:
                continue
            moved = self.forecaster.forecast(then, ahead).at(ahead)
            worst = max(worst, float(np.linalg.norm(moved - self.now.segments, axis=-1).max()))
        return worst

    def has_span(self, now: float) -> bool:
        """The snapshots kept reach `span` s back from `now`."""
        return bool(self.snapshots) and now - self.snapshots[0][0] >= self.span - 1e-9

    def trusted(self, now: float) -> bool:
        """The forecast has held over the last `span` s (``error`` within `tolerance`); with less history, where
        everyone in view walks and it has held so far."""
        if self.now is None or not self.snapshots:
            return False
        if self.has_span(now):
            return self.error(now) <= self.tolerance
        return bool(np.all(end_speeds(self.now) >= STANDING_SPEED)) and self.error(now, partial=True) <= self.tolerance
