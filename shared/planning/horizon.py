"""Alg. 1 of the paper: the horizon check. The next configurations of the trajectory from the current path
parameter, all checked at once against the latest human capsules; the first infeasible one, if any. And
whether the people who block it are passing: in the planning layer's forecast of them, gone by the time the
robot gets there (then waiting is quicker than a detour).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from shared.core.geometry import capsule_pair_distances
from shared.core.humans import HumanCapsules
from shared.core.trajectory import Trajectory
from shared.planning.collision import CollisionModel
from shared.planning.forecast import PeopleForecast


@dataclass(frozen=True)
class HorizonOptions:
    """samples: how many configurations ahead; spacing: nominal seconds between them."""

    samples: int = 25
    spacing: float = 0.04


@dataclass(frozen=True)
class HorizonResult:
    s: np.ndarray                  # path parameters checked (nominal s)
    clearance: np.ndarray          # clearance of each (m)
    first_infeasible: int | None   # index into s, or None when all are feasible

    @property
    def last_feasible_s(self) -> float | None:
        """s of the last feasible sample before the first infeasible one (None if the first is infeasible)."""
        if self.first_infeasible is None:
            return float(self.s[-1])
        return None if self.first_infeasible == 0 else float(self.s[self.first_infeasible - 1])


def reach_gap(collision: CollisionModel, humans: HumanCapsules | None) -> float:
    """How far (m) the nearest human capsule is beyond the distance at which it could block a configuration:
    the robot's reach sphere (``RobotModel.reach_radius``: the robot lies inside it in every configuration)
    plus the planner's margin. inf without people; negative when someone is within it."""
    if humans is None or humans.count == 0:
        return np.inf
    robot = collision.robot
    sphere = np.stack([robot.reach_centre, robot.reach_centre])[None]         # a capsule of zero length
    gap = capsule_pair_distances(sphere, np.array([robot.reach_radius]), humans.segments, humans.radii).distance
    required = collision.min_separation + collision.margins.human + collision.margins.tolerance
    return float(gap.min() - required)


def out_of_reach(collision: CollisionModel, humans: HumanCapsules | None) -> bool:
    """Every human capsule is beyond ``reach_gap``'s distance: no configuration of any path is blocked by
    them now, so the horizon is clear without checking it (a few microseconds where a check costs hundreds:
    the planner's idle cadence; figures in docs/measurements.md)."""
    return reach_gap(collision, humans) > 0.0


def horizon_check(trajectory: Trajectory, s: float, collision: CollisionModel, humans: HumanCapsules | None,
                  options: HorizonOptions = HorizonOptions()) -> HorizonResult:
    """Alg. 1: the first infeasible configuration among the next samples of the trajectory (one batch)."""
    samples = np.minimum(s + options.spacing * np.arange(options.samples + 1), trajectory.duration)
    samples = np.unique(samples)
    q, _, _ = trajectory.sample(samples)
    clearance = collision.clearances(q, humans)
    bad = np.flatnonzero(clearance <= collision.margins.tolerance)
    return HorizonResult(samples, clearance, int(bad[0]) if bad.size else None)


def people_passing(old: Trajectory, s_now: float, check: HorizonResult, humans: HumanCapsules | None,
                   collision: CollisionModel, ahead: PeopleForecast) -> bool:
    """The horizon is blocked now, but the people in the way are moving out of it: where the planning
    layer's forecast of them (``ahead``, the time cost's own) has them at the nominal time the robot would
    reach each blocked sample, none blocks any more (a person crossing the path). Waiting for them (the
    scaling layer slows the robot as needed) is then quicker than a detour."""
    if humans is None or not humans.velocity_known.any():
        return False
    blocked = check.s[check.first_infeasible:]
    q = old.sample(blocked)[0]
    for qk, sk in zip(q, blocked):
        later = HumanCapsules(ahead.at(float(sk - s_now)), humans.radii, humans.velocities, humans.velocity_known)
        if collision.clearances(qk[None, :], later)[0] <= collision.margins.tolerance:
            return False
    return True
