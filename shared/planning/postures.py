"""Postures the planning layer takes on purpose while people are near: the straight leg with the elbow folded over
the middle of the sweep, in parallel with the base's turn. A folded arm keeps every link nearer the base, so people
at the table's edge are farther from every link and every link is slower, and the SSM lets the robot go faster;
with nobody near it costs a little (a longer path). People walking near the cell cannot be forecast seconds ahead
(``bench/calibration.py``: the cost's choice among candidates is the executed fastest in about half the choices
where people walk), and the fold pays wherever they turn out to be. It is a new goal's default leg while someone
is within ``ReplanOptions.posture_gap`` of the robot's reach (``Replanner.plan_goal``; shipped at 2.5 m,
``PlanningParameters``), unless everyone stands still beyond ``still_gap`` of it; the search may still find a
faster one."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from shared.core.trajectory import Trajectory
from shared.planning.collision import CollisionModel
from shared.planning.timing import TimingError, parameterize
from shared.robot.model import JointLimits

ELBOW = 2                   # joint 3 (0-based index): the PRBT's elbow
FOLD = 0.8                  # rad: the elbow's fold over the middle of the sweep
FOLD_SPAN = (0.35, 0.65)    # the fractions of the straight line between which the fold is held
LEGS_KEPT = 16              # timed folded legs kept (a shuttle needs two)


def folded_waypoints(start: np.ndarray, goal: np.ndarray, limits: JointLimits, fold: float | tuple[float, ...] = FOLD,
                     span: tuple[float, float] = FOLD_SPAN, joint: int | tuple[int, ...] = ELBOW) -> np.ndarray:
    """start, the two folded points of the span, goal (4, 6): the straight line with `joint` offset by `fold` (rad)
    between the fractions `span`, ramping in from the start and out to the goal; within the joint limits. Several
    joints take a tuple of joints and one of their offsets (the arm raised: shoulder and elbow)."""
    start, goal = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
    offset = np.zeros(start.size)
    offset[np.atleast_1d(joint)] = fold
    via = [np.clip(start + f * (goal - start) + offset, limits.lower, limits.upper) for f in span]
    return np.vstack([start, *via, goal])


class FoldedLegs:
    """The folded leg between two ends, timed once (TOPP-RA, free of the static scene) and kept (the newest
    LEGS_KEPT pairs of ends): the planning layer's posture (``Replanner._posture``) and the fixed-path baseline
    (``evidence.fixed_path``) follow the same trajectory. fold, span, joint: as ``folded_waypoints``."""

    def __init__(self, collision: CollisionModel, fold: float | tuple[float, ...] = FOLD,
                 span: tuple[float, float] = FOLD_SPAN, joint: int | tuple[int, ...] = ELBOW) -> None:
        self.collision, self.fold, self.span, self.joint = collision, fold, span, joint
        self._legs: dict[tuple[bytes, bytes], Trajectory | TimingError] = {}

    def waypoints(self, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
        return folded_waypoints(start, goal, self.collision.robot.limits, self.fold, self.span, self.joint)

    def leg(self, start: np.ndarray, goal: np.ndarray, version: int) -> Trajectory:
        """The folded leg from start to goal, numbered `version` (TimingError where it cannot be timed)."""
        key = (np.asarray(start, dtype=float).tobytes(), np.asarray(goal, dtype=float).tobytes())
        if key not in self._legs:
            try:
                self._legs[key] = parameterize(self.waypoints(start, goal), self.collision.robot.limits,
                                               collision=self.collision)
            except TimingError as exc:
                self._legs[key] = exc
            if len(self._legs) > LEGS_KEPT:
                self._legs.pop(next(iter(self._legs)))
        made = self._legs[key]
        if isinstance(made, TimingError):
            raise made
        return replace(made, version=version)
