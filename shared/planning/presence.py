"""How long the people have stayed: the planning layer's predictions assume they stay at least that long more.

Every prediction of the planning layer has the people in the way stay ``patience`` seconds, plus how long the robot
has already been held (``shared.planning.decision.HoldClock``), or the people have stayed, whichever is longer: ski
rental, someone who has stayed three seconds is likely to stay a while longer, and the robot goes round them sooner
than round someone who has just stopped. Two clocks say how long the people have stayed:

* ``StillClock``: everyone stands still (every capsule's known velocity below ``STANDING_SPEED`` at both ends);
* ``DwellClock``: the people stay where they are while they work: their capsules' centroid within ``DWELL_RADIUS``
  of where it was when they settled, and moving slower than ``DWELL_SPEED``. A person assembling at a table's edge
  moves their hands all the time (the still clock starts again at every reach) but does not leave: in the
  human-assembly recordings the centroid stays within 6 cm of its median over 12 s windows. A walker at 0.6 m/s
  leaves the radius within a third of a second. The centroid's speed bound is the standing speed: the paper's
  person stepping in at 0.17 m/s beside the path has not settled (with 0.3 m/s they had, from their lean on, and
  a replan taken on the longer stay cost the paper's kind 3 %: docs/measurements.md, session 69). The number of
  capsules may change (a tracked state is the union of the states since the consumer's last step,
  ``HumanCapsules.union``: a person seen twice has twice the capsules, at the same place; the still clock starts
  again there).

For planning only (what a prediction assumes): the scaling layer and the monitor use the people as tracked. Pure.
"""

from __future__ import annotations

import numpy as np

from shared.core.humans import STANDING_SPEED, HumanCapsules, standing
from shared.planning.decision import HoldClock

DWELL_RADIUS = 0.2    # m: the people's centroid stays this near where they settled while they dwell
DWELL_SPEED = STANDING_SPEED   # m/s: ... and moves slower than this (the mean of the known end-point velocities)


class StillClock:
    """How long the people have stood still (s): the same number of capsules, every one with a known
    velocity below `speed` (m/s) at both ends. Anyone moving, appearing or leaving, or a velocity the
    tracker does not know, starts it again."""

    def __init__(self, speed: float = STANDING_SPEED) -> None:
        self.speed = speed
        self.count = -1
        self.clock = HoldClock()           # the same timing as the robot's hold, fed "standing" instead of beta

    def update(self, now: float, humans: HumanCapsules | None) -> None:
        count = -1 if humans is None else humans.count
        still = count > 0 and count == self.count and standing(humans, self.speed)
        self.count = count
        self.clock.update(now, still)

    def waited(self, now: float) -> float:
        return self.clock.waited(now)


def centroid_motion(humans: HumanCapsules) -> tuple[np.ndarray, float]:
    """The capsules' centroid (m, the mean of their end points) and the speed (m/s) of the mean of their known
    end-point velocities (0 where none is known)."""
    centre = humans.segments.reshape(-1, 3).mean(axis=0)
    known = humans.velocities[humans.velocity_known]
    speed = float(np.linalg.norm(known.reshape(-1, 3).mean(axis=0))) if known.size else 0.0
    return centre, speed


class DwellClock:
    """How long the people have dwelt where they are (s): seen, their centroid within `radius` (m) of where it was
    when they settled and moving slower than `speed` (m/s). Nobody seen starts it again; so does the centroid
    leaving the radius or moving faster, and the people settle anew where they are then."""

    def __init__(self, radius: float = DWELL_RADIUS, speed: float = DWELL_SPEED) -> None:
        self.radius, self.speed = radius, speed
        self.anchor: np.ndarray | None = None
        self.clock = HoldClock()

    def update(self, now: float, humans: HumanCapsules | None) -> None:
        if humans is None or humans.count == 0:
            self.anchor = None
            self.clock.update(now, False)
            return
        centre, speed = centroid_motion(humans)
        dwelling = (self.anchor is not None and speed < self.speed
                    and float(np.linalg.norm(centre - self.anchor)) <= self.radius)
        if not dwelling:
            self.anchor = centre
        self.clock.update(now, dwelling)

    def waited(self, now: float) -> float:
        return self.clock.waited(now)


class Presence:
    """How long the people have stayed by every clock in use, the longest (s): what the planning loop adds to every
    prediction's stay (``PlanningLoop``), and what ``bench/calibration.py`` replays over a scenario up to the moment a
    leg is predicted. still_speed (m/s): the still clock's bound (None: not used); dwell_radius (m): the dwell
    clock's (None: not used)."""

    def __init__(self, still_speed: float | None = STANDING_SPEED, dwell_radius: float | None = DWELL_RADIUS) -> None:
        self.clocks = tuple(clock for clock in (StillClock(still_speed) if still_speed is not None else None,
                                                DwellClock(dwell_radius) if dwell_radius is not None else None)
                            if clock is not None)

    def update(self, now: float, humans: HumanCapsules | None) -> None:
        for clock in self.clocks:
            clock.update(now, humans)

    def waited(self, now: float) -> float:
        """The longest any clock in use has counted (0 with none in use)."""
        return max((clock.waited(now) for clock in self.clocks), default=0.0)
