"""Joint-space path planning: OMPL's RRT-Connect, then OMPL's path simplification.

``JointPlanner.plan(q_start, q_goal, humans)`` returns waypoints (K, 6) from q_start to q_goal whose
every straight segment is free (checked by the collision model's conservative advancement, see
shared.planning.collision), or raises a typed PlanningError:

* StartInCollision / GoalInCollision: the end configuration is infeasible (the message names the
  limiting obstacle);
* OutOfLimits: an end is outside the joint limits;
* NoPathFound: RRT-Connect found no path within the time budget.

A partial path is never returned as a solution. OMPL's solve() holds the GIL, which is why the planner
runs in its own process (the planner service), never in a thread of a latency-critical one.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

from shared.core.errors import HrcError
from shared.core.humans import HumanCapsules
from shared.planning.collision import CollisionModel

ou.setLogLevel(ou.LOG_ERROR)
_seeded: int | None = None


def seed_ompl(seed: int) -> None:
    """Seed OMPL's process-wide RNG. OMPL honours this only before its first random number, so it is
    done once per process (a second, different seed is ignored with OMPL's own warning)."""
    global _seeded
    if _seeded is None:
        ou.RNG.setSeed(int(seed))
        _seeded = int(seed)


class PlanningError(HrcError):
    """The planner could not produce a path; the subclass says why."""


class OutOfLimits(PlanningError):
    pass


class StartInCollision(PlanningError):
    pass


class GoalInCollision(PlanningError):
    pass


class NoPathFound(PlanningError):
    pass


@dataclass(frozen=True)
class PlannerOptions:
    """time_budget (s) for RRT-Connect; range (rad): RRT-Connect's extension step (0: OMPL's default, a
    fraction of the space extent); seed: OMPL's RNG seed (None: random) for reproducible plans. The path
    is then shortened with OMPL's simplifyMax (vertex reduction and shortcutting until no gain)."""

    time_budget: float = 1.0
    range: float = 0.0
    seed: int | None = None


class _MotionValidator(ob.MotionValidator):
    """OMPL motion checks by conservative advancement (guaranteed, see shared.planning.collision)."""

    def __init__(self, si, check) -> None:
        super().__init__(si)
        self._check = check

    def checkMotion(self, s1, s2, *last_valid) -> bool:      # noqa: N802 (OMPL's name)
        return self._check(np.array(s1[0:6]), np.array(s2[0:6]))


class JointPlanner:
    """RRT-Connect in the PRBT's joint space against a collision model and a snapshot of the humans."""

    def __init__(self, collision: CollisionModel, options: PlannerOptions | None = None) -> None:
        self.collision = collision
        self.options = options or PlannerOptions()
        lim = collision.robot.limits
        self._dof = collision.robot.nq
        self.space = ob.RealVectorStateSpace(self._dof)
        bounds = ob.RealVectorBounds(self._dof)
        for k in range(self._dof):
            bounds.setLow(k, float(lim.lower[k]))
            bounds.setHigh(k, float(lim.upper[k]))
        self.space.setBounds(bounds)
        self.last_stats: dict = {}
        if self.options.seed is not None:
            seed_ompl(self.options.seed)

    def check_ends(self, q_start: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None,
                    inflation: float) -> None:
        lim = self.collision.robot.limits
        for label, q in (("start", q_start), ("goal", q_goal)):
            if q.shape != (self._dof,) or not np.all(np.isfinite(q)):
                raise OutOfLimits(f"{label} must be {self._dof} finite joint angles, got {q!r}")
            if not lim.within(q):
                bad = [self.collision.robot.joint_names[k] for k in range(self._dof)
                       if not lim.lower[k] <= q[k] <= lim.upper[k]]
                raise OutOfLimits(f"{label} configuration outside the joint limits of {', '.join(bad)}")
        for label, q, error in (("start", q_start, StartInCollision), ("goal", q_goal, GoalInCollision)):
            contact = self.collision.contact(q, humans, inflation)
            if not contact.feasible:
                raise error(f"{label} configuration too close to {contact.kind} ({contact.which}): "
                            f"clearance {contact.clearance * 1000:.0f} mm")

    def plan(self, q_start: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None = None,
             inflation: float = 0.0, time_budget: float | None = None) -> np.ndarray:
        """Waypoints (K, 6), q_start first and q_goal last, every segment free; or a PlanningError."""
        q_start = np.asarray(q_start, dtype=float)
        q_goal = np.asarray(q_goal, dtype=float)
        self.check_ends(q_start, q_goal, humans, inflation)
        started = time.perf_counter()
        checks_before = self.collision.checks
        if self.collision.motion_free(q_start, q_goal, humans, inflation)[0]:
            self.last_stats = {"planner": "direct", "plan_s": time.perf_counter() - started, "waypoints": 2,
                               "checks": self.collision.checks - checks_before}
            return np.vstack([q_start, q_goal])
        ss = og.SimpleSetup(self.space)
        si = ss.getSpaceInformation()
        collision = self.collision
        tol = collision.margins.tolerance
        ss.setStateValidityChecker(lambda s: collision.clearance(np.array(s[0:6]), humans, inflation) > tol)
        validator = _MotionValidator(si, lambda a, b: collision.motion_free(a, b, humans, inflation)[0])
        si.setMotionValidator(validator)
        start, goal = si.allocState(), si.allocState()
        for k in range(self._dof):
            start[k], goal[k] = float(q_start[k]), float(q_goal[k])
        ss.setStartAndGoalStates(start, goal)
        planner = og.RRTConnect(si)
        if self.options.range > 0:
            planner.setRange(self.options.range)
        ss.setPlanner(planner)
        ss.setup()
        budget = self.options.time_budget if time_budget is None else time_budget
        solved = ss.solve(float(budget))
        if not (bool(solved) and ss.haveExactSolutionPath()):
            raise NoPathFound(f"RRT-Connect found no collision-free path within {budget:.2f} s")
        path = ss.getSolutionPath()
        simplifier = og.PathSimplifier(si)
        simplifier.simplifyMax(path)
        waypoints = np.array([path.getState(i)[0:6] for i in range(path.getStateCount())])
        waypoints[0], waypoints[-1] = q_start, q_goal
        # The simplifier checks motions with our validator; re-check every segment anyway, so that
        # nothing unchecked ever leaves the planner.
        if not collision.path_free(waypoints, humans, inflation):
            raise NoPathFound("the simplified path failed the final motion check")
        self.last_stats = {"planner": "rrt_connect", "plan_s": time.perf_counter() - started,
                           "waypoints": len(waypoints), "checks": self.collision.checks - checks_before}
        return waypoints
