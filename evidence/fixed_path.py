"""The strongest simple baseline of the planning layer: one fixed path, chosen once, followed by the plain
scaling layer with no planner. The straight shuttle with the elbow (joint 3) folded over the middle of the
sweep, in parallel with the base: the folded arm's links reach less far from the base, so where people stand
at the table's edge every link is farther from them and slower, and the SSM lets the robot go faster. It costs
a little in an empty cell (a longer path); what it wins with people is what a planning layer must at least
match to earn its place (issue 38).

``FixedPath.leg(start, goal, version)`` is the timed leg (TOPP-RA through the fold's waypoints, checked free of
the static scene), made once per pair of ends and renumbered per leg; ``run_shuttle(leg=...)`` follows it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from shared.core.trajectory import Trajectory
from shared.planning.collision import CollisionModel
from shared.planning.postures import ELBOW, FOLD, FOLD_SPAN, folded_waypoints
from shared.planning.timing import parameterize


@dataclass
class FixedPath:
    """fold (rad): the elbow's offset over the middle of the sweep; span: the fractions of the straight line
    between which the offset is held (it ramps in from the start and out to the goal, with the base's turn);
    joint: the joint folded."""

    collision: CollisionModel
    fold: float = FOLD
    span: tuple[float, float] = FOLD_SPAN
    joint: int = ELBOW
    _legs: dict = field(default_factory=dict)

    def waypoints(self, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """start, the two folded points of the span, goal (4, 6) (``shared.planning.postures``)."""
        return folded_waypoints(start, goal, self.collision.robot.limits, self.fold, self.span, self.joint)

    def leg(self, start: np.ndarray, goal: np.ndarray, version: int) -> Trajectory:
        key = (np.asarray(start, dtype=float).tobytes(), np.asarray(goal, dtype=float).tobytes())
        if key not in self._legs:
            self._legs[key] = parameterize(self.waypoints(start, goal), self.collision.robot.limits,
                                           collision=self.collision)
        return replace(self._legs[key], version=version)
