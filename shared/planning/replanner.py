"""The planning layer's online part, the replanner: every new trajectory, planned for time under the SSM.
The paper's pieces have their own modules: the horizon check (Alg. 1, ``shared.planning.horizon``), the
splice of a merge (Alg. 2, ``shared.planning.merge``), the keep-or-replace rule
(``shared.planning.decision``); when to call which is the planning loop's (``shared.planning.loop``).

* Every new path is the one a seeded search finds fastest under the SSM (``shared.planning.path_search`` on the
  time cost of ``shared.planning.time_cost``): a person near the direct line gets a small detour that keeps the
  robot out of their slowdown, or none when crawling past is quicker. RRT-Connect (``shared.planning.ompl_planner``)
  seeds the search only where no simple detour is free (a cluttered static scene).
* Keep or replace (``keep_or_replace``): both trajectories predicted by the same cost, from the same
  moment, with the same people staying ``patience`` plus the time already held. A person who passes
  (tracked velocity) clears the old path in the prediction and is waited for; one who stays makes it
  slow and is gone round.
* ``Replanner.plan_goal``: a new goal: the direct line (the exact trapezoid) unless the searched path is
  predicted faster.
* ``Replanner.replan``: keeps the old trajectory unchanged up to a junction s_j, and from there follows
  the old path geometry to a branch point, then the searched path to the goal. The new part is
  time-parameterised starting with the old nominal velocity at s_j, so position and velocity are
  continuous at the junction; following the old geometry for a while gives the time law room to slow down
  before any turn. Junctions further back are tried when a turn is too sharp, then stop-and-go. The
  result gets the next version number; a follower anywhere before s_j continues at the same s. A robot
  at rest gets a trajectory from rest where it stands instead (free to leave in any direction), and one
  that the SSM holds to a crawl a trajectory from rest a few millimetres ahead, where the scaling layer
  stops it (``ScalingLayer.take``).
* ``Replanner.on_horizon`` (the path ahead is blocked) and ``Replanner.on_beta`` (the scaling layer
  asks: alpha too low) build such a trajectory and keep it only when predicted faster than the old one
  (a beta replan by at least ``min_gain``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from shared.core.humans import HumanCapsules, standing
from shared.core.trajectory import Trajectory, straight_line_trajectory
from shared.planning.budget import ActionBudget
from shared.planning.candidates import Candidates
from shared.planning.collision import CollisionModel
from shared.planning.decision import ReplanFailed, ReplanResult, keep_or_replace, required_gain
from shared.planning.executed import ExecutedTime
from shared.planning.forecast import Forecaster
from shared.planning.horizon import HorizonOptions, horizon_check, out_of_reach, people_passing, reach_gap
from shared.planning.ompl_planner import JointPlanner, PlanningError
from shared.planning.options import ReplanOptions
from shared.planning.path_search import PathSearch
from shared.planning.paths import SearchedPaths
from shared.planning.postures import FoldedLegs
from shared.planning.time_cost import SsmTimeCost
from shared.planning.timing import TimingError
from shared.safety.parameters import SsmParameters
from shared.scaling.parameters import ScalingParameters

# rad: how near a prepared plan's start (the goal the robot was on its way to) the robot must be to take it: its
# commands end exactly there; the scaler takes a plan from rest within 0.02 rad (services.scaler)
PREPARED_START = 0.005
# m: how far any end of the people's capsules may have moved since a plan was prepared for them for it still to be
# taken: further, and a search of the people as they are now decides
PREPARED_DRIFT = 0.1


@dataclass(frozen=True)
class PreparedPlan:
    """A leg's plan made before its goal came (``PlanningLoop`` prepares the next leg on the way): the
    trajectory, numbered 0, and the people it was planned for."""

    trajectory: Trajectory
    humans: HumanCapsules | None


class Replanner:
    """Builds merged trajectories that are fastest under the SSM; pure apart from the clock (the search's
    optional wall-clock budget) and OMPL's sampling where RRT-Connect seeds it. Its parts: the searched paths
    (``paths``, ``shared.planning.paths``), the action's wall clock (``budget``, ``shared.planning.budget``), the
    candidate trajectories (``candidates``, ``shared.planning.candidates``); what is left here is the one
    prediction, a new goal's plan and the triggers (horizon, slow, beta), which share one pattern (``_decide``).
    About 260 lines, most of them the docstrings of the triggers and of a goal's plan, which say when each
    replans and why: the public face of the planning layer, kept in one place."""

    def __init__(self, collision: CollisionModel, planner: JointPlanner, ssm: SsmParameters,
                 horizon: HorizonOptions = HorizonOptions(), options: ReplanOptions = ReplanOptions(),
                 forecaster: Forecaster | None = None, scaling: ScalingParameters | None = None) -> None:
        """forecaster: where the time cost has the people go (None: ``ConstantVelocity``, see
        ``shared.planning.forecast``); scaling: the scaling layer's parameters, for a forward run of it
        (``options.judge`` "scaling"; None: the defaults)."""
        self.collision = collision
        self.planner = planner
        self.ssm = ssm
        self.horizon = horizon
        self.options = options
        self.limits = collision.robot.limits
        self.cost = SsmTimeCost(collision.robot, ssm, options.cost, forecaster)
        self.executed = ExecutedTime(collision.robot, ssm, scaling or ScalingParameters()) \
            if options.judge == "scaling" else None
        self.search = PathSearch(collision, self.cost, options.search)
        self.paths = SearchedPaths(collision, planner, self.search, options)
        self.budget = ActionBudget(self.search, options.action_budget)
        self.candidates = Candidates(collision, options, self.cost, self.budget, self.path, self.predicted_time,
                                     self.stay, self.default_leg, self.path_and_others)
        self.took_prepared = False     # the last plan_goal took the prepared trajectory it was given
        self.search_deferred = False   # the last plan_goal left a search to be run on the way (leaving)
        self.goal_searched = False     # the last plan_goal took the leg its search found
        self.took_fold = False         # the last plan_goal's leg, where not searched, is the folded one
        self.postures = FoldedLegs(collision)     # the folded legs a new goal may take (``_posture``)

    def take_delay(self, delay: float) -> None:
        """The people's data's age as the scaling layer counts it on average (s, ``PlanningInputs.human_delay``,
        ``shared.tracking.tracker.mean_age``): the time cost, the path search and the forward run of the scaling
        layer count their travel over it, as the scaling layer does (``SsmParameters.aged``), so the planning layer
        does not take a way the scaler will not go (a path predicted passable that the scaler holds at rest stood
        a camera 30 ms behind still for half its run)."""
        delay = delay if math.isfinite(delay) and delay > 0.0 else 0.0
        self.cost.ssm = self.ssm.aged(delay)
        if self.executed is not None:
            self.executed.delay = delay

    def begin(self) -> None:
        """One planning action starts (``ActionBudget.begin``)."""
        self.budget.begin()

    def end(self) -> None:
        """The action is done (``ActionBudget.end``)."""
        self.budget.end()

    def widen(self, seconds: float) -> None:
        """This action may take `seconds`, its searches too (``ActionBudget.widen``)."""
        self.budget.widen(seconds)

    @property
    def finishing(self) -> float:
        """s: the recent wall time of an action's work besides its searches (``ActionBudget``)."""
        return self.budget.finishing

    @finishing.setter
    def finishing(self, value: float) -> None:
        self.budget.finishing = value

    def forget(self, leg_start: np.ndarray | None = None) -> None:
        """Drop the remembered paths (a new goal, or a new run: the same inputs give the same plans). leg_start:
        where the robot stands as the new goal's leg begins (None: unknown, or it moves), the place a plan
        from rest may go back to (``Candidates.retreat``)."""
        self.paths.forget()
        self.candidates.leg_start = None if leg_start is None else np.array(leg_start, dtype=float)

    @property
    def searches(self) -> int:
        """Path searches run (the simulation charges planning time by them)."""
        return self.paths.searches

    @property
    def remembered(self) -> list[np.ndarray]:
        """The latest searches' winners to the current goal (each (K, 6)), the seeds of the next searches."""
        return self.paths.remembered

    @remembered.setter
    def remembered(self, paths: list[np.ndarray]) -> None:
        self.paths.remembered = paths

    # ------------------------------------------------------------------------------------ predictions
    def stay(self, waited: float) -> float:
        """How long (s) a prediction assumes the people present stay: patience + the time already held."""
        return self.options.patience + max(0.0, waited)

    def goal_waited(self, waited: float) -> float:
        """The `waited` a new goal's decisions take (``plan_goal``): the people assumed to stay at least
        options.goal_stay, however short the robot has been held (``stay(goal_waited(w)) >= goal_stay``)."""
        return max(max(0.0, waited), self.options.goal_stay - self.options.patience)

    def predicted_time(self, trajectory: Trajectory, s_from: float, humans: HumanCapsules | None,
                       waited: float = 0.0) -> float:
        """Time (s) from s_from to the end of the trajectory under the SSM (shared.planning.time_cost), the people
        staying patience + waited seconds: the one prediction both sides of every decision get; with
        ``options.judge`` "scaling", the scaling layer's own forward run against the same forecast
        (shared.planning.executed)."""
        if self.executed is not None:               # the cost's forecast: one for both (a bound sets its own per run)
            return self.executed.time(trajectory, s_from, humans, self.stay(waited), self.cost.forecaster)
        return self.cost.trajectory_time(trajectory, s_from, humans, self.stay(waited))

    def path(self, q_from: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None, waited: float = 0.0,
             from_rest: bool = True) -> np.ndarray:
        """Waypoints (K, 6) of the path the search finds fastest under the SSM, the people staying
        patience + waited (``SearchedPaths.path``; raises PlanningError when nothing is found)."""
        return self.paths.path(q_from, q_goal, humans, self.stay(waited), from_rest)

    def path_and_others(self, q_from: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None,
                        waited: float, alternatives: int) -> list[np.ndarray]:
        """The searched path from rest (``path``) and up to `alternatives` runners-up (``SearchedPaths.paths``)."""
        return self.paths.paths(q_from, q_goal, humans, self.stay(waited), True, alternatives)

    def plan_fresh(self, q_start: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None, version: int,
                   waited: float = 0.0) -> Trajectory:
        """A rest-to-rest trajectory to a new goal on the searched path (raises PlanningError or TimingError)."""
        return self._fresh(q_start, q_goal, humans, version, waited)[0]

    def _fresh(self, q_start: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None, version: int,
               waited: float) -> tuple[Trajectory, float]:
        """``plan_fresh`` and its prediction (s), made once (``Candidates.timed_best`` of the one route)."""
        return self.candidates.timed_best([self.path(q_start, q_goal, humans, waited)], humans, version, waited)

    def plan_goal(self, q_start: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None, version: int,
                  waited: float = 0.0, prepared: PreparedPlan | None = None, leaving: bool = False,
                  trusted: bool = False) -> Trajectory:
        """A new goal from rest: the direct line (the exact trapezoid) when the static scene allows it, even
        if a person is in its way now (the scaling layer holds the robot back), unless the searched path is
        predicted faster by what a replan must save (``required_gain``); else the searched path (raises
        PlanningError or TimingError). prepared: this leg's
        plan made a moment before, while the robot was still on its way here (``PlanningLoop`` prepares the
        next leg): it takes the search's place where it is still good (``_still_good``), and the robot
        leaves without waiting for a search. While someone is within ``posture_gap`` of the robot's reach, the
        folded leg (``shared.planning.postures``) takes the direct line's place, where it is free, unless the
        forecast has held lately (trusted: ``shared.planning.trust``, the planning loop's) and the cost predicts the
        line faster: a walker's steady course is worth betting on, a wanderer's is not. leaving:
        where a search would decide but the direct line is predicted slower than nominal by no more than
        ``worth_waiting`` (None: whatever it is predicted), the direct line (or the fold) is returned at once and
        ``search_deferred`` says so: the robot leaves on it and the search runs on the way (``PlanningLoop``,
        action 'search', ``on_search``), so nobody waits at the goal for a search that seldom pays. The search and
        whether it (or the prepared plan) beats the line or the fold are judged with the people assumed to stay
        at least ``goal_stay`` (``goal_waited``): the robot commits to a whole leg."""
        q_start, q_goal = np.asarray(q_start, dtype=float), np.asarray(q_goal, dtype=float)
        self.took_prepared = self.search_deferred = self.goal_searched = self.took_fold = False
        staying = self.goal_waited(waited)       # the whole leg ahead: the people assumed to stay goal_stay
        if not self.collision.motion_free(q_start, q_goal)[0]:
            ready = self._still_good(prepared, q_start, q_goal, humans, staying, np.inf, version)
            if ready is not None:
                return ready
            self.goal_searched = True
            return self.plan_fresh(q_start, q_goal, humans, version, staying)
        direct = straight_line_trajectory(q_start, q_goal, self.limits.velocity, self.limits.acceleration,
                                          version=version)
        if humans is None or humans.count == 0:
            return direct
        posture = self._posture(q_start, q_goal, humans, version)
        if posture is not None and not trusted:      # someone near: the folded leg is the one to beat ...
            direct = posture
        direct_time = self.predicted_time(direct, 0.0, humans, waited)
        if posture is not None and trusted:          # ... unless a forecast that has held says the line is faster
            posture_time = self.predicted_time(posture, 0.0, humans, waited)
            if posture_time <= direct_time:
                direct, direct_time = posture, posture_time
        self.took_fold = direct is posture           # (what the goal's detail says where it is not searched)
        if staying != waited:       # the line against the fold as every decision (the bet on a walker's course) ...
            direct_time = self.predicted_time(direct, 0.0, humans, staying)    # ... the search against them: goal_stay
        if direct_time <= direct.duration + self.options.worth_searching:
            return direct                   # the people hardly slow it: a search would cost more than it saves
        # a searched leg must beat it as a replan must beat the trajectory it would replace (min_gain, or
        # min_saving seconds): a forecast's error is no reason to leave the line or the fold
        beat = (1.0 - required_gain(direct_time, self.options.min_gain, self.options.min_saving)) * direct_time
        ready = self._still_good(prepared, q_start, q_goal, humans, staying, beat, version)
        if ready is not None:
            return ready
        if leaving and (self.options.worth_waiting is None or direct_time <= direct.duration + self.options.worth_waiting):
            self.search_deferred = True
            return direct
        try:
            searched, searched_time = self._fresh(q_start, q_goal, humans, version, staying)
        except (PlanningError, TimingError):
            return direct
        self.goal_searched = searched_time < beat
        return searched if self.goal_searched else direct

    def default_leg(self, q_start: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None,
                    version: int) -> Trajectory | None:
        """The leg a new goal takes from rest at q_start without a search, numbered `version`: the folded one
        where someone is near (``_posture``), else the direct line; None where the line is not free of the
        static scene."""
        posture = None if humans is None or humans.count == 0 else self._posture(q_start, q_goal, humans, version)
        if posture is not None:
            return posture
        if not self.collision.motion_free(q_start, q_goal)[0]:
            return None
        return straight_line_trajectory(q_start, q_goal, self.limits.velocity, self.limits.acceleration,
                                        version=version)

    def _posture(self, q_start: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules,
                 version: int) -> Trajectory | None:
        """The folded leg from q_start to q_goal, numbered `version`, where someone is within options.posture_gap
        (m) of the robot's reach, unless everyone stands still beyond options.still_gap (m) of it, and it is
        free of them (never closer to them than its ends are); else None. Timed once per pair of ends
        (``FoldedLegs``)."""
        gap = self.options.posture_gap
        nearest = reach_gap(self.collision, humans)
        if gap is None or nearest >= gap or (nearest >= self.options.still_gap and standing(humans)):
            return None
        try:
            leg = self.postures.leg(q_start, q_goal, version)
        except TimingError:
            return None
        clearance = self.collision.capped_inflation(0.0, leg.positions[[0, -1]], humans)
        return leg if self.collision.path_free(leg.positions, humans, clearance) else None

    def _still_good(self, prepared: PreparedPlan | None, q_start: np.ndarray, q_goal: np.ndarray,
                    humans: HumanCapsules | None, waited: float, beat: float, version: int) -> Trajectory | None:
        """The prepared trajectory, numbered `version`, where it goes from here (within PREPARED_START) to
        this goal, the people are where it was planned for them (the same capsules, none moved more than
        PREPARED_DRIFT: a search now would see what that one saw), it is still collision-free against them
        (never closer to them than its ends are) and is predicted, with them, faster than `beat` (s: the
        direct line's prediction); else None (then a search decides, as without it)."""
        if prepared is None or not _people_stayed(prepared.humans, humans):
            return None
        plan = prepared.trajectory
        if np.abs(plan.positions[0] - q_start).max() > PREPARED_START \
                or not np.allclose(plan.positions[-1], q_goal, atol=1e-9):
            return None
        clearance = self.collision.capped_inflation(0.0, plan.positions[[0, -1]], humans)
        if not self.collision.path_free(plan.positions, humans, clearance):
            return None
        if self.predicted_time(plan, 0.0, humans, waited) >= beat:
            return None
        self.took_prepared = True
        return replace(plan, version=version)

    def replan(self, old: Trajectory, s_now: float, q_goal: np.ndarray, humans: HumanCapsules | None,
               reason: str, s_branch: float | None = None, waited: float = 0.0,
               route: np.ndarray | None = None) -> ReplanResult:
        """Alg. 2 from s_branch (default: the current s plus the lead), on the searched path, or on `route`
        (waypoints searched elsewhere; ``Candidates.merge``)."""
        return self.candidates.merge(old, s_now, q_goal, humans, reason, s_branch, waited, route)

    def _decide(self, started: float, old: Trajectory, s_now: float, q_goal: np.ndarray,
                humans: HumanCapsules | None, speed_now: float | None, waited: float, held: bool, reason: str,
                branch_at: Callable[[], float], gain: Callable[[float], float], why: str,
                stop_at: float | None = None, route: np.ndarray | None = None) -> ReplanResult:
        """The one pattern of every trigger: the candidate the robot's state calls for (``Candidates.start``: from
        rest where it stands, waits or is stopped), else a merge branching at branch_at(); kept only when predicted
        faster than the old trajectory from the same state by gain(baseline) seconds (``keep_or_replace``; else
        ReplanFailed saying why, with both times). started: when the trigger began (its compute time)."""
        result, baseline = self.candidates.start(old, s_now, speed_now, q_goal, humans, reason, waited, held, stop_at)
        if result is None:
            result = self.replan(old, s_now, q_goal, humans, reason, branch_at(), waited, route)
        return keep_or_replace(result, baseline, gain(baseline), started, why)

    def on_horizon(self, old: Trajectory, s_now: float, q_goal: np.ndarray, humans: HumanCapsules | None,
                   speed_now: float | None = None, waited: float = 0.0, held: bool = False) -> ReplanResult | None:
        """Alg. 1 + 2: None when the horizon is clear, or when the people in the way are passing
        (``passing``); else a new trajectory branching at the last feasible horizon configuration, kept
        only when predicted to reach the goal sooner than the old one (ReplanFailed saying why, with both
        predicted times). speed_now: the robot's joint speed (rad/s); at rest, the new trajectory starts
        from rest where the robot stands (a merge in nominal time would have to leave at the old nominal
        speed, which a stopped robot cannot); crawling and held, from rest a little ahead (as on_beta).
        waited: as in predicted_time."""
        started = time.perf_counter()
        if out_of_reach(self.collision, humans):        # nobody near enough to block any configuration
            return None
        check = horizon_check(old, s_now, self.collision, humans, self.horizon)
        # blocked where the robot already is: no branch ahead can help (the scaling layer holds the robot;
        # a beta replan plans the way out, and only when it is predicted to pay)
        if check.first_infeasible in (None, 0) or people_passing(old, s_now, check, humans, self.collision,
                                                                 self.cost.forecast(humans)):
            return None
        blocked = float(check.s[check.first_infeasible])

        def branch_at() -> float:
            s_branch = check.last_feasible_s
            if s_branch is None or s_branch < s_now + self.options.lead:
                s_branch = min(old.duration, s_now + self.options.lead)
            return s_branch

        return self._decide(started, old, s_now, q_goal, humans, speed_now, waited, held, "horizon", branch_at,
                            lambda baseline: 0.0, f"path blocked at s={blocked:.2f}")

    def on_slow(self, old: Trajectory, s_now: float, q_goal: np.ndarray, humans: HumanCapsules | None,
                speed_now: float | None = None, waited: float = 0.0, held: bool = False) -> ReplanResult | None:
        """The planning layer's own replan request, for a path predicted slow *ahead* while the robot still
        moves at speed. None when the robot is already slowed (below half its nominal speed: beta's case, the
        scaling layer asks there), when nobody is near enough to block anything, or when the rest of the old
        trajectory is predicted to lose less than slow_excess (s) to the SSM (the people staying patience +
        waited); else as on_beta, reason 'slow': a replan only where it is predicted to pay, ReplanFailed
        saying why not. Its case: a goal planned while a person was still stepping in, predicted along their
        velocity, and followed at speed after they stopped in its way; the longer they stand, the longer the
        prediction has them stay (the paper's phase 4, a goal planned 40 ms before the person stopped:
        predicted 2.66 s, 4.22 s against the person as they stayed; the robot crawled into their slowdown
        for 1.5 s before the scaling layer asked)."""
        if out_of_reach(self.collision, humans) or self.candidates.rate(old, s_now, speed_now) < 0.5:
            return None
        nominal = old.duration - s_now
        predicted = self.predicted_time(old, s_now, humans, waited)
        if predicted - nominal < self.options.slow_excess:
            return None
        return self.on_beta(old, s_now, q_goal, humans, speed_now, waited, held, reason="slow",
                            why=f"path predicted slow ({predicted:.2f} s for {nominal:.2f} s nominal)")


    def on_beta(self, old: Trajectory, s_now: float, q_goal: np.ndarray, humans: HumanCapsules | None,
                speed_now: float | None = None, waited: float = 0.0, held: bool = False, reason: str = "beta",
                why: str = "replan request", stop_at: float | None = None) -> ReplanResult:
        """A replan that is worth it (min_gain), or ReplanFailed saying why the old trajectory stays.

        speed_now: the robot's actual joint speed (rad/s, max over joints; None: moving at the nominal
        speed). At rest (below rest_speed) the new trajectory starts at rest from where the robot is:
        continuous in the actual velocity, and free to leave in any direction. Crawling and held there by
        the SSM (held; below `crawl` of the nominal speed), from rest a little ahead, where the scaling layer
        stops it (``Candidates.stop_plan``). Moving, the merge must be
        continuous in nominal time, so the new part starts with the old nominal velocity: the branch point
        is then put one nominal stopping time ahead, so the old path gives room to come to rest before the
        new path leaves it. waited (s): how long the scaling layer has been asking (see predicted_time).
        held: the SSM keeps the robot's speed down, not a ramp back to speed (the loop passes
        ``PlanningInputs.kept_slow``: the speed is the SSM's bound, or the bound is below alpha_min). reason and why: the
        result's reason and what the decision's detail calls the request (on_slow's own). stop_at: where the
        scaler brings the robot to rest to await this plan (``ScalingStep.awaiting``): the plan starts from
        rest there, and the old trajectory is predicted from rest there too."""
        started = time.perf_counter()
        return self._decide(started, old, s_now, q_goal, humans, speed_now, waited, held, reason,
                            lambda: self._branch_ahead(old, s_now),
                            lambda baseline: required_gain(baseline, self.options.min_gain, self.options.min_saving),
                            why, stop_at)

    def on_search(self, old: Trajectory, s_now: float, q_goal: np.ndarray, humans: HumanCapsules | None,
                  speed_now: float | None = None, waited: float = 0.0, held: bool = False) -> ReplanResult:
        """A new goal's search, run once the robot has left on the goal's direct leg (old, followed from its
        start; ``PlanningLoop``, action 'search'): decided as waiting at the goal would have decided it, then
        made from where the robot is. The search from rest where the leg began, taken where predicted faster
        than the leg from there by what a replan must save (``required_gain``, as ``plan_goal`` takes a searched
        leg); then merged into the leg a moment ahead of the robot (a few centimetres from that start: the merge
        along its waypoints, at rest or crawling a plan from rest where the robot is) and kept where that is
        still predicted faster than the leg from here. Else ReplanFailed saying why. Why not a search of the
        merge's own, judged as a replan: the turn onto a way round costs the robot that has left some of the
        saving, and a person standing beside the path was then passed on the fold (5.54 s) where the goal's search
        went round (4.30 s; docs/measurements.md, session 63). Unlike ``plan_goal`` it has the people stay the
        patience plus the time held, not ``goal_stay``: with the goal's stay here too the standing person's kind lost
        1.8 % (docs/measurements.md, session 74)."""
        started = time.perf_counter()
        try:
            waypoints = self.path(old.positions[0], q_goal, humans, waited)
            searched_time = self.candidates.timed_best([waypoints], humans, old.version + 1, waited)[1]
        except (PlanningError, TimingError) as exc:
            raise ReplanFailed(f"the new goal's search, on the way: {type(exc).__name__}: {exc}") from None
        leg_time = self.predicted_time(old, 0.0, humans, waited)
        need = required_gain(leg_time, self.options.min_gain, self.options.min_saving)
        if searched_time >= (1.0 - need) * leg_time:
            raise ReplanFailed(f"the new goal's search, on the way, kept the old trajectory: the new one (searched "
                               f"from the leg's start) predicted {searched_time:.2f} s, not {100 * need:.0f} % faster "
                               f"than the old {leg_time:.2f} s from there")
        return self._decide(started, old, s_now, q_goal, humans, speed_now, waited, held, "search",
                            lambda: self._branch_ahead(old, s_now), lambda baseline: 0.0,
                            "the new goal's search, on the way", route=waypoints)

    def _branch_ahead(self, old: Trajectory, s_now: float) -> float:
        """Where a merge into a moving robot's trajectory branches: one nominal stopping time past the planning
        lead, so that the old path gives room to come to rest before the new one leaves it."""
        stopping = float(np.max(np.abs(old.sample(float(s_now))[1]) / (self.limits.acceleration * 0.9)))
        return min(old.duration, s_now + self.options.lead + stopping)


def _people_stayed(then: HumanCapsules | None, now: HumanCapsules | None) -> bool:
    """The same people as then, each capsule end within PREPARED_DRIFT (m) of where it was (nobody, both times:
    True)."""
    if then is None or now is None or then.count == 0 or now.count == 0:
        return (then is None or then.count == 0) and (now is None or now.count == 0)
    if then.count != now.count:
        return False
    return float(np.linalg.norm(now.segments - then.segments, axis=2).max()) <= PREPARED_DRIFT
