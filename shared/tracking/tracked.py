"""A recorded motion as the cell's tracker passes it on: each frame once, at its own time, through the product's
``HumanTracker`` (pure, no I/O, no clock but the caller's t).

On the processes a motion file goes out frame by frame at its own rate (``tools.feed``) and reaches the scaling
layer through ``tracker_ingest``: velocities fitted over the tracker's window, unknown after a glitch, a change in
the capsules seen or the track's start (the ISO 13855 speeds then apply), and no person at all once no frame came
for the dropout bound. The motion's own ``at(t)`` gives each frame's velocities from the frame before, known
wherever the capsule was there before. So ``hrc demo --sim --human`` and the real-people scenario kinds
(``evidence.recorded``) run a motion through this, as the cell does (what it changed, measured: docs/real-people.md).
"""

from __future__ import annotations

import numpy as np

from shared.core.humans import HumanCapsules
from shared.tracking.tracker import HumanTracker, TrackerParameters


class TrackedMotion:
    """``at(t)``: what the tracker holds at t seconds from the motion's first frame, each frame given to it once
    at its own time (None before the first frame seen, in a dropout once no frame came for the tracker's dropout
    bound; past the motion's end, what it held at the last frame, as ``RecordedMotion.at`` holds that frame);
    ``phase(t)``, ``duration`` and ``times`` the motion's. The whole motion is tracked once, up front, so any t may
    be asked in any order (a forecast told the future reads ahead) and gives the same answer."""

    def __init__(self, motion, params: TrackerParameters | None = None) -> None:
        self.motion = motion
        self.times = motion.times
        tracker = HumanTracker(params)
        self.estimates: list[HumanCapsules | None] = []     # per frame: the tracker's output after it (None: none)
        self.seen = np.full(len(self.times), -1)           # per frame: the last frame given to the tracker by then
        self.bound = np.zeros(len(self.times))             # per frame: the dropout bound (s) the tracker had then
        self.interval = np.zeros(len(self.times))          # per frame: the sample interval (s) it had measured by then
        last, estimate = -1, None
        for k, frame in enumerate(motion.frames):
            when = float(self.times[k])
            capsules = frame.capsules()
            if not (frame.dropout or capsules is None or capsules.count == 0):   # nobody seen: no sample sent
                update = tracker.update(capsules.segments, capsules.radii, when, when)
                last, estimate = k, update if update is not None else estimate
            self.estimates.append(estimate)
            self.seen[k], self.bound[k], self.interval[k] = last, tracker.dropout, tracker.interval

    @property
    def duration(self) -> float:
        return self.motion.duration

    def _frame(self, t: float) -> int:
        """The last frame at or before t (-1: none yet)."""
        return int(np.searchsorted(self.times, t, side="right")) - 1

    def at(self, t: float) -> HumanCapsules | None:
        k = self._frame(t)
        if k < 0 or self.seen[k] < 0:
            return None
        t = min(t, float(self.times[-1]))       # past the motion's end its last frame holds, as the motion's own at
        if t - self.times[self.seen[k]] > self.bound[k]:          # tracker_ingest's check: no sample for too long
            return None
        return self.estimates[k]

    def captured(self, t: float) -> tuple[float, float]:
        """When the newest sample the tracker had by t was captured (s; -inf: none yet) and the source's sample
        interval it had measured by then (s): the data's age at t counts from the first (the scaler's stale-data
        bound, ``stale_bound``, scales with the second). Past the motion's end its last frame holds as fresh as it
        was then, as in at(t)."""
        k = self._frame(t)
        if k < 0 or self.seen[k] < 0:
            return -np.inf, 0.0
        held = max(0.0, t - float(self.times[-1]))
        return float(self.times[self.seen[k]]) + held, float(self.interval[k])

    def phase(self, t: float) -> str:
        return self.motion.phase(t)
