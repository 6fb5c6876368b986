"""The candidate trajectories of a replan, by the robot's state (``Candidates.start``): a merge into the followed
trajectory (Alg. 2: continuous through a junction, else stop-and-go; ``merge``), a plan from rest where the robot
stands (``rest_plan``), a plan from rest where the scaler stops a crawling robot (``stop_plan``); each with its
predicted time, and the old trajectory's prediction from the same state (``baseline``), so that the planning
layer's triggers (``shared.planning.replanner``) compare like with like. Paths come from the replanner's search
(``path``); predictions from its one time cost (``predict``)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from shared.core.humans import HumanCapsules
from shared.core.trajectory import Trajectory, polyline_trajectory, straight_line_trajectory
from shared.planning.budget import ActionBudget
from shared.planning.collision import CollisionModel
from shared.planning.decision import ReplanFailed, ReplanResult, required_gain
from shared.planning.merge import merge
from shared.planning.ompl_planner import PlanningError
from shared.planning.options import ReplanOptions
from shared.planning.path_search import ACTION_BUDGET
from shared.planning.time_cost import SsmTimeCost
from shared.planning.timing import TimingError, parameterize
from shared.scaling.stopping import stopping_time

RETREAT_FROM = 0.05     # rad (largest joint): nearer to where the leg began than this, no way back is offered


REST_ALTERNATIVES = 3     # runners-up of the search timed beside its winner for a plan from rest (``rest_plan``)


class Candidates:
    """path(q_from, q_goal, humans, waited, from_rest=True) -> waypoints: the searched path; predict(trajectory,
    s_from, humans, waited) -> s: the one prediction; stay(waited) -> s: how long the people are assumed to stay;
    leg(q_start, q_goal, humans, version) -> the leg a new goal takes from rest there without a search (None where
    there is none); paths(q_from, q_goal, humans, waited, alternatives) -> [waypoints, ...]: the searched path
    from rest and its runners-up (None: the searched path alone); budget: the action's wall clock (a merge tries
    no further junction once it is spent, a plan from rest times no further runner-up). leg_start: where the
    robot stood when its goal's leg began (None: not known, or the goal came while it moved), which a plan from
    rest may go back to (``retreat``)."""

    def __init__(self, collision: CollisionModel, options: ReplanOptions, cost: SsmTimeCost, budget: ActionBudget,
                 path: Callable[..., np.ndarray], predict: Callable[..., float], stay: Callable[[float], float],
                 leg: Callable[..., Trajectory | None] | None = None,
                 paths: Callable[..., list[np.ndarray]] | None = None) -> None:
        self.collision, self.options, self.cost, self.budget = collision, options, cost, budget
        self.path, self.predict, self.stay, self.leg, self.paths = path, predict, stay, leg, paths
        self.limits = collision.robot.limits
        self.leg_start: np.ndarray | None = None

    def from_rest(self, waypoints: np.ndarray, humans: HumanCapsules | None, version: int,
                  waited: float | None = None) -> Trajectory:
        """Rest to rest through waypoints. A direct connection gets the exact trapezoid, which is
        time-optimal for a straight line and needs none of the acceleration headroom TOPP-RA's grid calls
        for where a path bends (2 % faster on the paper's shuttle); a bent path gets TOPP-RA, its smoothed
        path checked never to come closer to the people than its ends are, or, where the smoothing cuts a
        corner too close, the exact polyline with a stop at each corner (its segments are checked free).
        waited (s, the time held so far; None: not weighed): with people present, a bent path's exact polyline
        is taken instead of its smoothing where the one prediction has it faster by what a replan must save
        (``required_gain``). Why: smoothing cuts the corners, and where the SSM lets a robot beside a person start
        only one motion at a time (the search's staged lifts: the elbow first), the smoothed start makes both at
        once, which may not start until they leave (held 2 s beside a person: the staged path predicted 5.4 s
        with its corners, 7.1 s smoothed)."""
        return self._from_rest(waypoints, humans, version, waited)[0]

    def _from_rest(self, waypoints: np.ndarray, humans: HumanCapsules | None, version: int,
                   waited: float | None) -> tuple[Trajectory, float | None]:
        """``from_rest``, and its prediction (s) where weighing the corners made one (else None)."""
        if len(waypoints) == 2:
            return straight_line_trajectory(waypoints[0], waypoints[1], self.limits.velocity,
                                            self.limits.acceleration, version=version), None
        limits = self.limits
        try:
            smooth = parameterize(waypoints, limits, collision=self.collision, humans=humans,
                                  inflation=self.collision.capped_inflation(0.0, waypoints[[0, -1]], humans),
                                  version=version)
        except TimingError:          # the smoothed path cuts a corner into a person: stop at the corners
            return polyline_trajectory(waypoints, limits.velocity, limits.acceleration, version=version), None
        if waited is None or humans is None or humans.count == 0:
            return smooth, None
        corners = polyline_trajectory(waypoints, limits.velocity, limits.acceleration, version=version)
        smooth_time = self.predict(smooth, 0.0, humans, waited)
        corners_time = self.predict(corners, 0.0, humans, waited)
        gain = required_gain(smooth_time, self.options.min_gain, self.options.min_saving)
        return (corners, corners_time) if corners_time < (1.0 - gain) * smooth_time else (smooth, smooth_time)

    def branch(self, old: Trajectory, s_now: float, s_branch: float, q_goal: np.ndarray,
                humans: HumanCapsules | None, version: int, waited: float,
                route: np.ndarray | None = None) -> tuple[Trajectory, float]:
        """Merge at a junction s_j before s_branch: from s_j the old geometry to the branch point, then the
        searched path to the goal (route: waypoints already searched, from near the branch point, taken from
        the branch point instead of a search of its own). First continuously through the branch point (junctions
        further back give more room to slow down before turning); else stop-and-go: decelerate along the old
        path to rest at the branch point, then the new path from rest. Each further try needs time left in the
        planning action (each one times a whole law, up to three smoothings: a merge that failed at two
        junctions took 685 ms in a demo); out of it, ReplanFailed says what was tried. Returns (merged, s_j)."""
        s_first = min(s_now + self.options.lead, s_branch)     # never before the planning lead
        junctions = sorted({max(s_first, s_branch - lb) for lb in self.options.lookback}, reverse=True)
        q_branch = old.sample(float(s_branch))[0]
        tail = self.path(q_branch, q_goal, humans, waited, from_rest=False) if route is None else \
            np.vstack([q_branch, route[1:]])
        # the lead-in is the old, already accepted path: the smoothed whole is verified at what it has
        check = min(0.0, self.collision.capped_inflation(0.0, old.sample(np.linspace(s_first, s_branch, 8))[0], humans))
        errors = []

        def lead_in(s_j: float) -> np.ndarray:
            return old.sample(np.linspace(s_j, s_branch, max(2, int(np.ceil((s_branch - s_j) / 0.05)) + 1)))[0]

        for s_j in junctions:                       # continuous through the branch point
            if errors and self.budget.out_of_time():
                raise ReplanFailed("no merge within the action's time: " + "; ".join(errors))
            lead = lead_in(s_j)
            try:
                inflation = min(check, self.collision.capped_inflation(check, lead, humans))
                part = parameterize(np.vstack([lead, tail[1:]]), self.limits,
                                    start_velocity=old.sample(float(s_j))[1], collision=self.collision,
                                    humans=humans, inflation=inflation)
                return merge(old, s_j, part, version), s_j
            except TimingError as exc:
                errors.append(f"through at s={s_j:.2f}: {exc}")
        s_j = junctions[-1]                          # stop-and-go, with the most room to stop
        if self.budget.out_of_time():
            raise ReplanFailed("no merge within the action's time: " + "; ".join(errors))
        lead = lead_in(s_j)
        try:
            stop = parameterize(lead, self.limits, start_velocity=old.sample(float(s_j))[1],
                                collision=self.collision, humans=humans,
                                inflation=min(check, self.collision.capped_inflation(check, lead, humans)))
            go = self.from_rest(tail, humans, version)
        except TimingError as exc:
            raise ReplanFailed("no junction allows a continuous merge: "
                               + "; ".join(errors + [f"stop-and-go: {exc}"])) from None
        return merge(merge(old, s_j, stop, version), s_j + stop.duration, go, version), s_j

    def merge(self, old: Trajectory, s_now: float, q_goal: np.ndarray, humans: HumanCapsules | None,
               reason: str, s_branch: float | None = None, waited: float = 0.0,
               route: np.ndarray | None = None) -> ReplanResult:
        """Alg. 2 from s_branch (default: the current s plus the lead), on the searched path, or on `route`
        (waypoints searched elsewhere: ``branch``)."""
        started = time.perf_counter()
        s_branch = min(old.duration, s_now + self.options.lead) if s_branch is None else s_branch
        try:
            if s_branch >= old.duration - 1e-9:          # at the end, at rest: a fresh plan from there
                fresh = self.from_rest(self.path(old.positions[-1], q_goal, humans, waited), humans, 0, waited)
                merged, s_j = merge(old, old.duration, fresh, old.version + 1), old.duration
            else:
                merged, s_j = self.branch(old, s_now, s_branch, q_goal, humans, old.version + 1, waited, route)
        except (PlanningError, TimingError) as exc:
            raise ReplanFailed(f"{type(exc).__name__}: {exc}") from None
        return ReplanResult(merged, s_j, reason, time.perf_counter() - started,
                            self.predict(merged, s_now, humans, waited))

    def rest_plan(self, old: Trajectory, s_now: float, q_goal: np.ndarray, humans: HumanCapsules | None,
                   reason: str, waited: float) -> ReplanResult:
        """A trajectory from rest where the robot stands (old at s_now) to the goal, on the searched path or one
        of its runners-up, whichever is predicted fastest as timed (``timed_best``; raises ReplanFailed)."""
        started = time.perf_counter()
        q_now = old.sample(float(s_now))[0]
        failed = None
        try:                       # the search first: the way back takes no time from its budget
            if self.paths is None or humans is None or humans.count == 0:
                routes = [self.path(q_now, q_goal, humans, waited)]
            else:
                routes = self.paths(q_now, q_goal, humans, waited, REST_ALTERNATIVES)
            traj, predicted = self.timed_best(routes, humans, old.version + 1, waited)
        except (PlanningError, TimingError) as exc:
            failed, traj, predicted = f"from rest: {type(exc).__name__}: {exc}", None, np.inf
        back = self.retreat(q_now, q_goal, humans, old.version + 1)
        back_time = np.inf if back is None else self.predict(back, 0.0, humans, waited)
        if back is None and failed is not None:
            raise ReplanFailed(failed)
        if traj is None or back_time < predicted:
            return ReplanResult(back, s_now, reason, time.perf_counter() - started, back_time,
                                detail="back by where the leg began", from_rest=True)
        return ReplanResult(traj, s_now, reason, time.perf_counter() - started, predicted, from_rest=True)

    def timed_best(self, routes: list[np.ndarray], humans: HumanCapsules | None, version: int,
                   waited: float) -> tuple[Trajectory, float]:
        """Of the routes (waypoints, the search's winner first), the one whose trajectory from rest is predicted
        fastest, and that prediction (s). The search ranks its paths by the cost of their waypoints with a stop
        at each corner; the trajectory driven smooths them, and that can change the time by up to a tenth, so
        which of a few nearly equal winners drives fastest is a matter of the search's seed unless each is timed
        (a robot held beside a person: the winner predicted 3.31-3.71 s by seed; docs/measurements.md, session
        73). The runners-up are timed only while the action has time left."""
        best, best_time = None, np.inf
        for k, route in enumerate(routes):
            if k and self.budget.out_of_time():
                break
            try:
                traj, predicted = self._from_rest(route, humans, version, waited)
            except TimingError:
                if k == 0:
                    raise
                continue
            if predicted is None:
                predicted = self.predict(traj, 0.0, humans, waited)
            if best is None or predicted < best_time:
                best, best_time = traj, predicted
        return best, best_time

    def retreat(self, q_now: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None,
                version: int) -> Trajectory | None:
        """Back on the straight line to where the leg began (``leg_start``), at rest there, then the leg a new
        goal takes from there (the fold or the line, ``leg``), or None where there is no such way: no start
        known, the robot (nearly) there, the way back not free of the scene or of the people (never closer to
        them than its ends are), or no leg. Why: a robot whose replans led it into a person's slowdown can be
        where every path on to the goal passes them, so that each plan searched from there waits for them as
        the old one does, and is refused by a hair for as long as they stay (a real recording at the table's
        edge: held for 41 s, every plan from rest 0.19 s faster, each growing with the wait), while the way
        back leads out of their slowdown and the leg from its start passes them, slowly but without waiting.
        A rest plan takes it only where predicted faster (``rest_plan``)."""
        start = self.leg_start
        if start is None or self.leg is None or np.abs(start - q_now).max() < RETREAT_FROM:
            return None
        clearance = self.collision.capped_inflation(0.0, np.vstack([q_now, start]), humans)
        if not self.collision.motion_free(q_now, start, humans, clearance)[0]:
            return None
        try:
            leg = self.leg(start, q_goal, humans, version)
        except (PlanningError, TimingError):
            return None
        if leg is None:
            return None
        back = straight_line_trajectory(q_now, start, self.limits.velocity, self.limits.acceleration, version=version)
        return merge(back, back.duration, leg, version)

    def stop_plan(self, old: Trajectory, s_now: float, rate: float, q_goal: np.ndarray,
                   humans: HumanCapsules | None, reason: str, waited: float) -> ReplanResult:
        """For a robot crawling at `rate` of its nominal path speed: a plan from rest at the point of its path where the
        scaler brings it to rest (``ScalingLayer.take``), allowing stop_lead for the plan to arrive and the scaler's
        stop (``shared.scaling.stopping``). A merge would have to leave its junction at the old
        *nominal* velocity and so keep a nominal stopping distance of old path, into the person's slowdown that makes the
        robot crawl; a crawling robot can stop in a few millimetres and then leave in any direction. The prediction
        counts the crawl to that point. Where the crawl gets by then is the time cost's (``SsmTimeCost.reached``), never
        further than its present rate: the SSM slows a crawl towards a person further, and at the present rate the robot
        crawled on for 150-200 ms after its plan had come (hrc demo, phase 3: stall 380-400 ms; 300-320 ms now). A start
        the robot has passed when the plan comes cannot be taken, so stop_lead errs long. Raises ReplanFailed."""
        started = time.perf_counter()
        v_nominal = np.abs(old.sample(float(s_now))[1])
        stopping = rate * stopping_time(v_nominal, self.limits.acceleration)                      # s, robot time
        lead = self.options.stop_lead + 0.5 * stopping                                    # with a linear stop
        # where the crawl gets to by then: at most its present rate, less where the SSM slows it further, and
        # never within the robot's own stopping distance (the scaler could not stop it there)
        crawl = min(s_now + rate * lead, self.cost.reached(old, s_now, humans, lead, self.stay(waited)))
        # ... and at least where its present rate takes it while the plan is made (ACTION_BUDGET): beside a person the
        # SSM's bound and the robot's speed chatter (no motion at a frame's end, a little on a fresh frame), the cost
        # sees the crawl stand, and the robot crept past a start put where it stood (real_table_edge seed 6, 30 ms late)
        crawl = max(crawl, s_now + rate * ACTION_BUDGET)
        s_stop = min(old.duration, max(s_now + rate * 0.5 * stopping, crawl))
        result = self.rest_plan(old, s_stop, q_goal, humans, reason, waited)
        return replace(result, junction=s_stop, plan_s=time.perf_counter() - started,
                       predicted=result.predicted + self.options.stop_lead + stopping)

    def rate(self, old: Trajectory, s_now: float, speed_now: float | None) -> float:
        """The robot's path speed as a fraction of the nominal one at s_now (1 when unknown, or where the
        nominal trajectory itself stands)."""
        nominal = float(np.max(np.abs(old.sample(float(s_now))[1])))
        if speed_now is None or nominal < 1e-6:
            return 1.0
        return min(1.0, max(0.0, speed_now / nominal))

    def start(self, old: Trajectory, s_now: float, speed_now: float | None, q_goal: np.ndarray,
               humans: HumanCapsules | None, reason: str, waited: float,
               held: bool, stop_at: float | None = None) -> tuple[ReplanResult | None, float]:
        """Where a new trajectory starts, by the robot's state: brought to rest by the scaler to await it
        (stop_at, ``ScalingLayer.awaiting``), from rest there; at rest, from rest where it stands; crawling
        (below `crawl` of its nominal speed, and held there by the SSM: not speeding up again), from rest
        where the scaler stops it. Returns (that plan, the old trajectory's prediction from the
        same state), or (None, the baseline) for a robot moving near its nominal speed (a merge, the
        caller's; both sides then in nominal time)."""
        if stop_at is not None and s_now - 1e-9 <= stop_at <= old.duration:
            return (self.rest_plan(old, stop_at, q_goal, humans, reason, waited),
                    self.baseline(old, stop_at, humans, waited, 0.0))
        at_rest = speed_now is not None and speed_now < self.options.rest_speed
        rate = 0.0 if at_rest else self.rate(old, s_now, speed_now)
        if at_rest:
            return (self.rest_plan(old, s_now, q_goal, humans, reason, waited),
                    self.baseline(old, s_now, humans, waited, 0.0))
        if held and rate < self.options.crawl:
            return (self.stop_plan(old, s_now, rate, q_goal, humans, reason, waited),
                    self.baseline(old, s_now, humans, waited, rate))
        return None, self.baseline(old, s_now, humans, waited, 1.0)

    def baseline(self, old: Trajectory, s_now: float, humans: HumanCapsules | None, waited: float,
                  rate: float) -> float:
        """The old trajectory's predicted time from s_now, like the new one's: a robot below its nominal
        speed (rate, a fraction of it; 0 at rest) must first get back to it, (1 - rate) v / 2a more than the
        prediction at that speed, as a new trajectory from rest has to."""
        baseline = self.predict(old, s_now, humans, waited)
        if rate < 1.0:
            v = np.abs(old.sample(float(s_now))[1])
            baseline += (1.0 - rate) * float(np.max(v / (2.0 * self.limits.acceleration)))
        return baseline
