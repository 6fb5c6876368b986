"""A recorded motion as the cell's tracker passes it on: each frame once, at its own time, through the product's
``HumanTracker`` (pure, no I/O, no clock but the caller's t).

On the processes a motion file goes out frame by frame at its own rate (``tools.feed``) and reaches the scaling
layer through ``tracker_ingest``: velocities fitted over the tracker's window, unknown after a glitch, a change in
the capsules seen or the track's start (the ISO 13855 speeds then apply), and no person at all once no frame came
for the dropout bound. The motion's own ``at(t)`` gives each frame's velocities from the frame before, known
wherever the capsule was there before. So ``hrc demo --sim --human`` runs the motion through this, as the cell
does: at the table's edge the tracker cost a real recording 11.36 -> 10.72 shuttles a minute in the simulation,
against 10.60 on the processes (docs/real-people.md, session 64).
"""

from __future__ import annotations

import numpy as np

from shared.core.humans import HumanCapsules
from shared.tracking.tracker import HumanTracker, TrackerParameters


class TrackedMotion:
    """``at(t)``: what the tracker holds at t seconds from the motion's first frame, each frame taken once when
    its time comes (None before the first frame is taken, in a dropout and once no frame came for the tracker's
    dropout bound); ``phase(t)`` and ``duration`` the motion's. Times must not go back (a simulation's clock):
    an earlier t gives the estimate of the latest frame taken."""

    def __init__(self, motion, params: TrackerParameters | None = None) -> None:
        self.motion = motion
        self.tracker = HumanTracker(params)
        self.taken = -1                                   # index of the last frame given to the tracker
        self.estimate: HumanCapsules | None = None

    @property
    def duration(self) -> float:
        return self.motion.duration

    def at(self, t: float) -> HumanCapsules | None:
        due = int(np.searchsorted(self.motion.times, t, side="right")) - 1
        while self.taken < due:
            self.taken += 1
            frame, when = self.motion.frames[self.taken], float(self.motion.times[self.taken])
            capsules = frame.capsules()
            if frame.dropout or capsules is None or capsules.count == 0:
                continue                                  # nobody seen: no sample, as the feed sends none
            estimate = self.tracker.update(capsules.segments, capsules.radii, when, when)
            if estimate is not None:
                self.estimate = estimate
        if self.estimate is None or not self.tracker.valid(t):
            return None
        return self.estimate

    def phase(self, t: float) -> str:
        return self.motion.phase(t)
