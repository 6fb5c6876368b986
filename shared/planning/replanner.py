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

import time
from dataclasses import dataclass, replace

import numpy as np

from shared.core.humans import HumanCapsules
from shared.core.trajectory import Trajectory, polyline_trajectory, straight_line_trajectory
from shared.planning.collision import CollisionModel
from shared.planning.decision import ReplanFailed, ReplanResult, keep_or_replace, required_gain
from shared.planning.forecast import Forecaster
from shared.planning.horizon import HorizonOptions, horizon_check, out_of_reach, people_passing
from shared.planning.merge import merge
from shared.planning.ompl_planner import JointPlanner, PlanningError
from shared.planning.path_search import PathSearch, SearchOptions
from shared.planning.time_cost import SsmTimeCost, TimeCostOptions
from shared.planning.timing import TimingError, parameterize
from shared.safety.parameters import SsmParameters
from shared.scaling.stopping import REST_SPEED, stopping_time

REMEMBERED = 4          # searched paths to the current goal kept as seeds of the next searches
FINISHING_EASE = 0.1    # how far a planning action's learnt finishing time falls towards a shorter one (end)
# rad: how near a prepared plan's start (the goal the robot was on its way to) the robot must be to take it: its
# commands end exactly there; the scaler takes a plan from rest within 0.02 rad (services.scaler)
PREPARED_START = 0.005
# m: how far any end of the people's capsules may have moved since a plan was prepared for them for it still to be
# taken: further, and a search of the people as they are now decides
PREPARED_DRIFT = 0.1
# the most of an action's budget the learnt finishing time keeps from its searches: one rest stretched by a
# preemption on a busy machine would otherwise leave the next actions' searches no time at all
FINISHING_MOST = 0.5


@dataclass(frozen=True)
class PreparedPlan:
    """A leg's plan made before its goal came (``PlanningLoop`` prepares the next leg on the way): the
    trajectory, numbered 0, and the people it was planned for."""

    trajectory: Trajectory
    humans: HumanCapsules | None


@dataclass(frozen=True)
class ReplanOptions:
    """lookback: nominal seconds of old path kept ahead of the branch point as room to slow down (and
    tried further back when a turn is too sharp); lead: nominal seconds ahead of the current s that the
    junction must stay (the follower moves on while we plan); min_gain: the fraction of predicted time a
    beta replan must save (a blocked horizon needs only to be faster), or min_saving (s) where that is
    less (``required_gain``); rest_speed (rad/s): below it the
    robot counts as at rest for a replan; crawl: below this fraction of its nominal speed a moving robot
    gets a plan from rest a little ahead, where the scaler stops it (``_stop_plan``), instead of a merge;
    stop_lead (s): the time that stop allows the plan to be delivered in (the robot crawls on meanwhile:
    in hrc demo a plan from rest came 90-180 ms after its request, the worker's 20 ms turn included;
    against 0.15 s, with the crawl predicted by the time cost, 0.2 s kept the paper's 24 s progress, see
    ``_stop_plan``);
    patience (s): how long people in the way are expected to stay
    before the robot has waited at all; a prediction assumes they stay patience + the time already held
    (0 is pure ski rental: never worse than twice the better choice, however long the person stays; a
    cell where people are known to stay at a station may set more); rrt_budget (s): RRT-Connect's time
    when it has to seed the search; worth_searching (s): a new goal's direct line is taken without a
    search unless the people are predicted to slow it by more than this (the search itself takes up to
    its budget while the robot waits for its plan); slow_excess (s): the planning layer asks itself for a
    replan (``on_slow``) where the rest of the path followed at speed is predicted to lose more than this
    to the SSM; action_budget (s): wall clock for a whole planning
    action, searches and the rest (None: none; the simulation bounds by counts), see ``begin``; seed: the
    search's seed (each goal gets its own stream, derived from the seed and the goal, so the same query
    gives the same path in any order, see ``_rng``); search, cost:
    the search's bounds and the time cost's sampling."""

    lookback: tuple[float, ...] = (0.3, 0.6, 1.0)
    lead: float = 0.1
    min_gain: float = 0.10
    min_saving: float = 0.25
    rest_speed: float = REST_SPEED
    crawl: float = 0.25
    stop_lead: float = 0.2
    patience: float = 1.5
    rrt_budget: float = 0.2
    worth_searching: float = 0.25
    slow_excess: float = 1.0
    action_budget: float | None = None
    seed: int = 0
    search: SearchOptions = SearchOptions()
    cost: TimeCostOptions = TimeCostOptions()


class Replanner:
    """Builds merged trajectories that are fastest under the SSM; pure apart from the clock (the search's
    optional wall-clock budget) and OMPL's sampling where RRT-Connect seeds it."""

    def __init__(self, collision: CollisionModel, planner: JointPlanner, ssm: SsmParameters,
                 horizon: HorizonOptions = HorizonOptions(), options: ReplanOptions = ReplanOptions(),
                 forecaster: Forecaster | None = None) -> None:
        """forecaster: where the time cost has the people go (None: ``ConstantVelocity``, see
        ``shared.planning.forecast``)."""
        self.collision = collision
        self.planner = planner
        self.ssm = ssm
        self.horizon = horizon
        self.options = options
        self.limits = collision.robot.limits
        self.cost = SsmTimeCost(collision.robot, ssm, options.cost, forecaster)
        self.search = PathSearch(collision, self.cost, options.search)
        self.searches = 0          # path searches run (the simulation charges planning time by them)
        self.finishing = 0.02      # s: recent wall time of an action's work besides its searches (see begin)
        self._began: float | None = None
        self.remembered: list[np.ndarray] = []     # the latest searches' winners to the current goal (K, 6)
        self.took_prepared = False     # the last plan_goal took the prepared trajectory it was given

    def begin(self) -> None:
        """One planning action starts (the planning loop calls it): with an action_budget, its searches stop
        in time for the rest of the action (the timing, the merge, the predictions: ``finishing``, their
        recent wall time) to end within the budget. Anytime: when time is up the best path found so far is
        used. On a loaded machine the rest takes longer, and the searches get less of the budget: the plan
        still comes when the budget says, not a preemption later. No-op without an action_budget."""
        self.search.spent = 0.0
        if self.options.action_budget is None:
            self.search.deadline = self._began = None
            return
        self._began = time.perf_counter()
        self.search.deadline = self._began + self.options.action_budget - self.finishing

    def end(self) -> None:
        """The action is done: learn how long its work besides the searches took, over the actions that
        searched: up at once to a longer one, down by a tenth of the gap after a shorter one. The rest of
        a refused replan is a millisecond, of a taken one the time laws of the new trajectory with their
        collision checks (4-6 ms on this machine, a merge's some 20; 20-45 ms while toppra timed them); an
        average of both (a third of the gap each time) let the searches of the next taken plan run into its
        time: in the paper's 24 s, wall-clock, every taken replan ended 4-17 ms past the 100 ms budget and
        the first 17 ms, and in `hrc demo` the median of the replans was 107-118 ms. At most FINISHING_MOST
        of the budget."""
        if self._began is not None and self.search.spent > 0.0:
            rest = min(max(0.0, time.perf_counter() - self._began - self.search.spent),
                       FINISHING_MOST * self.options.action_budget)
            self.finishing = rest if rest > self.finishing else self.finishing + FINISHING_EASE * (rest - self.finishing)
        self.search.deadline = self._began = None

    def forget(self) -> None:
        """Drop the remembered paths (a new goal, or a new run: the same inputs give the same plans)."""
        self.remembered = []

    def _recalled(self, q_from: np.ndarray, q_goal: np.ndarray) -> list[np.ndarray]:
        """Seeds from the remembered paths to this goal: from q_from on to each of their later waypoints,
        then along them. A search has a small budget; one that starts from what the last ones found keeps
        improving while the situation stays, instead of drawing its luck anew at every replan."""
        out = []
        for w in self.remembered:
            if np.allclose(w[-1], q_goal, atol=1e-9):
                out += [np.vstack([q_from, w[i:]]) for i in range(1, len(w) - 1)]
        return out

    def _remember(self, waypoints: np.ndarray) -> None:
        """Keep a search's winner (the newest REMEMBERED to its goal, each once)."""
        kept = [w for w in self.remembered if np.allclose(w[-1], waypoints[-1], atol=1e-9)
                and not (w.shape == waypoints.shape and np.array_equal(w, waypoints))]
        self.remembered = kept[-(REMEMBERED - 1):] + [waypoints]

    # ------------------------------------------------------------------------------------ predictions
    def stay(self, waited: float) -> float:
        """How long (s) a prediction assumes the people present stay: patience + the time already held."""
        return self.options.patience + max(0.0, waited)

    def predicted_time(self, trajectory: Trajectory, s_from: float, humans: HumanCapsules | None,
                       waited: float = 0.0) -> float:
        """Time (s) from s_from to the end of the trajectory under the SSM (shared.planning.time_cost), the people
        staying patience + waited seconds: the one prediction both sides of every decision get."""
        return self.cost.trajectory_time(trajectory, s_from, humans, self.stay(waited))

    def _rng(self, q_from: np.ndarray, q_goal: np.ndarray) -> np.random.Generator:
        """The search's random stream for a query: from the seed and the goal (to 1 mrad) only, so that
        nearby queries to the same goal get the same candidates, bent the same way from their own start.
        Seeded by both ends (before), a start a milliradian away drew a different set, and a different
        winner: whether the paper's phase 3 was gone round depended on when, to the millisecond, a leg
        ended (9 of 15 runs with the phase period 0.5 % longer or shorter and planning charged 0, 60,
        70, 80 or 90 ms; 15 of 15 now, the 24 s runs' progress 8.18 +- 0.37 shuttles -> 8.57 +- 0.15).
        The same query still gives the same path in any order."""
        goal = np.round(np.asarray(q_goal) * 1000.0).astype(np.int64) + 100_000
        return np.random.default_rng([self.options.seed, *goal.tolist()])

    # ----------------------------------------------------------------------------------------- paths
    def path(self, q_from: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None, waited: float = 0.0,
             from_rest: bool = True) -> np.ndarray:
        """Waypoints (K, 6) of the path the search finds fastest under the SSM, every segment free of the
        scene and the people (never closer to them than the ends already are); RRT-Connect seeds a second
        search where no simple detour is free (raises PlanningError when nothing is found)."""
        q_from, q_goal = np.asarray(q_from, dtype=float), np.asarray(q_goal, dtype=float)
        direct = np.vstack([q_from, q_goal])
        inflation = self._capped(0.0, direct, humans)      # < 0 where a person has come closer already
        self.planner.check_ends(q_from, q_goal, humans, inflation)
        rng = self._rng(q_from, q_goal)
        stay = self.stay(waited)
        self.searches += 1
        found = self.search.search(q_from, q_goal, humans, rng, stay, (direct, *self._recalled(q_from, q_goal)),
                                   from_rest, inflation)
        if found is None:
            budget = self.options.rrt_budget
            if self.search.deadline is not None:           # within the action's budget, but never nothing
                budget = min(budget, max(0.02, self.search.deadline - time.perf_counter()))
            rrt = self.planner.plan(q_from, q_goal, humans, inflation, time_budget=budget)
            self.searches += 1
            found = self.search.search(q_from, q_goal, humans, rng, stay, (rrt,), from_rest, inflation)
            if found is None:                               # out of time before reaching it: it is free
                return rrt
        if len(found.waypoints) > 2:
            self._remember(found.waypoints)
        return found.waypoints

    def plan_fresh(self, q_start: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None, version: int,
                   waited: float = 0.0) -> Trajectory:
        """A rest-to-rest trajectory to a new goal on the searched path (raises PlanningError or TimingError)."""
        return self._from_rest(self.path(q_start, q_goal, humans, waited), humans, version)

    def plan_goal(self, q_start: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None, version: int,
                  waited: float = 0.0, prepared: PreparedPlan | None = None) -> Trajectory:
        """A new goal from rest: the direct line (the exact trapezoid) when the static scene allows it, even
        if a person is in its way now (the scaling layer holds the robot back), unless the searched path is
        predicted faster; else the searched path (raises PlanningError or TimingError). prepared: this leg's
        plan made a moment before, while the robot was still on its way here (``PlanningLoop`` prepares the
        next leg): it takes the search's place where it is still good (``_still_good``), and the robot
        leaves without waiting for a search."""
        q_start, q_goal = np.asarray(q_start, dtype=float), np.asarray(q_goal, dtype=float)
        self.took_prepared = False
        if not self.collision.motion_free(q_start, q_goal)[0]:
            ready = self._still_good(prepared, q_start, q_goal, humans, waited, np.inf, version)
            return ready if ready is not None else self.plan_fresh(q_start, q_goal, humans, version, waited)
        direct = straight_line_trajectory(q_start, q_goal, self.limits.velocity, self.limits.acceleration,
                                          version=version)
        if humans is None or humans.count == 0:
            return direct
        direct_time = self.predicted_time(direct, 0.0, humans, waited)
        if direct_time <= direct.duration + self.options.worth_searching:
            return direct                   # the people hardly slow it: a search would cost more than it saves
        ready = self._still_good(prepared, q_start, q_goal, humans, waited, direct_time, version)
        if ready is not None:
            return ready
        try:
            searched = self.plan_fresh(q_start, q_goal, humans, version, waited)
        except (PlanningError, TimingError):
            return direct
        return searched if self.predicted_time(searched, 0.0, humans, waited) < direct_time else direct

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
        if not self.collision.path_free(plan.positions, humans, self._capped(0.0, plan.positions[[0, -1]], humans)):
            return None
        if self.predicted_time(plan, 0.0, humans, waited) >= beat:
            return None
        self.took_prepared = True
        return replace(plan, version=version)

    def _from_rest(self, waypoints: np.ndarray, humans: HumanCapsules | None, version: int) -> Trajectory:
        """Rest to rest through waypoints. A direct connection gets the exact trapezoid, which is
        time-optimal for a straight line and needs none of the acceleration headroom TOPP-RA's grid calls
        for where a path bends (2 % faster on the paper's shuttle); a bent path gets TOPP-RA, its smoothed
        path checked never to come closer to the people than its ends are, or, where the smoothing cuts a
        corner too close, the exact polyline with a stop at each corner (its segments are checked free)."""
        if len(waypoints) == 2:
            return straight_line_trajectory(waypoints[0], waypoints[1], self.limits.velocity,
                                            self.limits.acceleration, version=version)
        try:
            return parameterize(waypoints, self.limits, collision=self.collision, humans=humans,
                                inflation=self._capped(0.0, waypoints[[0, -1]], humans), version=version)
        except TimingError:          # the smoothed path cuts a corner into a person: stop at the corners
            return polyline_trajectory(waypoints, self.limits.velocity, self.limits.acceleration, version=version)

    def _capped(self, inflation: float, configs: np.ndarray, humans: HumanCapsules | None) -> float:
        """The inflation, lowered to the clearance that the configurations a plan must start or end in
        already have (so it may turn negative: a robot a person has walked up to is not refused a way
        out). The smoothed trajectory is then checked never to come closer to a human than that."""
        if humans is None or humans.count == 0:
            return max(0.0, inflation)
        have = float(self.collision.clearances(configs, humans, inflation=0.0).min()) - 2 * self.collision.margins.tolerance
        return min(inflation, have)

    def _out_of_time(self) -> bool:
        """The planning action's budget is spent (never without an action budget: the simulation)."""
        return self._began is not None and time.perf_counter() > self._began + self.options.action_budget

    def _branch(self, old: Trajectory, s_now: float, s_branch: float, q_goal: np.ndarray,
                humans: HumanCapsules | None, version: int, waited: float) -> tuple[Trajectory, float]:
        """Merge at a junction s_j before s_branch: from s_j the old geometry to the branch point, then the
        searched path to the goal. First continuously through the branch point (junctions further back give
        more room to slow down before turning); else stop-and-go: decelerate along the old path to rest at
        the branch point, then the new path from rest. Each further try needs time left in the planning
        action (each one times a whole law, up to three smoothings: a merge that failed at two junctions took
        685 ms in a demo); out of it, ReplanFailed says what was tried. Returns (merged, s_j)."""
        s_first = min(s_now + self.options.lead, s_branch)     # never before the planning lead
        junctions = sorted({max(s_first, s_branch - lb) for lb in self.options.lookback}, reverse=True)
        q_branch = old.sample(float(s_branch))[0]
        tail = self.path(q_branch, q_goal, humans, waited, from_rest=False)
        # the lead-in is the old, already accepted path: the smoothed whole is verified at what it has
        check = min(0.0, self._capped(0.0, old.sample(np.linspace(s_first, s_branch, 8))[0], humans))
        errors = []

        def lead_in(s_j: float) -> np.ndarray:
            return old.sample(np.linspace(s_j, s_branch, max(2, int(np.ceil((s_branch - s_j) / 0.05)) + 1)))[0]

        for s_j in junctions:                       # continuous through the branch point
            if errors and self._out_of_time():
                raise ReplanFailed("no merge within the action's time: " + "; ".join(errors))
            try:
                part = parameterize(np.vstack([lead_in(s_j), tail[1:]]), self.limits,
                                    start_velocity=old.sample(float(s_j))[1], collision=self.collision,
                                    humans=humans, inflation=min(check, self._capped(check, lead_in(s_j), humans)))
                return merge(old, s_j, part, version), s_j
            except TimingError as exc:
                errors.append(f"through at s={s_j:.2f}: {exc}")
        s_j = junctions[-1]                          # stop-and-go, with the most room to stop
        if self._out_of_time():
            raise ReplanFailed("no merge within the action's time: " + "; ".join(errors))
        try:
            stop = parameterize(lead_in(s_j), self.limits, start_velocity=old.sample(float(s_j))[1],
                                collision=self.collision, humans=humans,
                                inflation=min(check, self._capped(check, lead_in(s_j), humans)))
            go = self._from_rest(tail, humans, version)
        except TimingError as exc:
            raise ReplanFailed("no junction allows a continuous merge: "
                               + "; ".join(errors + [f"stop-and-go: {exc}"])) from None
        return merge(merge(old, s_j, stop, version), s_j + stop.duration, go, version), s_j

    def replan(self, old: Trajectory, s_now: float, q_goal: np.ndarray, humans: HumanCapsules | None,
               reason: str, s_branch: float | None = None, waited: float = 0.0) -> ReplanResult:
        """Alg. 2 from s_branch (default: the current s plus the lead), on the searched path."""
        started = time.perf_counter()
        s_branch = min(old.duration, s_now + self.options.lead) if s_branch is None else s_branch
        try:
            if s_branch >= old.duration - 1e-9:          # at the end, at rest: a fresh plan from there
                fresh = self.plan_fresh(old.positions[-1], q_goal, humans, 0, waited)
                merged, s_j = merge(old, old.duration, fresh, old.version + 1), old.duration
            else:
                merged, s_j = self._branch(old, s_now, s_branch, q_goal, humans, old.version + 1, waited)
        except (PlanningError, TimingError) as exc:
            raise ReplanFailed(f"{type(exc).__name__}: {exc}") from None
        return ReplanResult(merged, s_j, reason, time.perf_counter() - started,
                            self.predicted_time(merged, s_now, humans, waited))

    def _rest_plan(self, old: Trajectory, s_now: float, q_goal: np.ndarray, humans: HumanCapsules | None,
                   reason: str, waited: float) -> ReplanResult:
        """A trajectory from rest where the robot stands (old at s_now) to the goal, on the searched path
        (raises ReplanFailed)."""
        started = time.perf_counter()
        q_now = old.sample(float(s_now))[0]
        try:
            waypoints = self.path(q_now, q_goal, humans, waited)
            traj = self._from_rest(waypoints, humans, old.version + 1)
        except (PlanningError, TimingError) as exc:
            raise ReplanFailed(f"from rest: {type(exc).__name__}: {exc}") from None
        return ReplanResult(traj, s_now, reason, time.perf_counter() - started,
                            self.predicted_time(traj, 0.0, humans, waited), from_rest=True)

    def _stop_plan(self, old: Trajectory, s_now: float, rate: float, q_goal: np.ndarray,
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
        s_stop = min(old.duration, max(s_now + rate * 0.5 * stopping, crawl))
        result = self._rest_plan(old, s_stop, q_goal, humans, reason, waited)
        return replace(result, junction=s_stop, plan_s=time.perf_counter() - started,
                       predicted=result.predicted + self.options.stop_lead + stopping)

    def _rate(self, old: Trajectory, s_now: float, speed_now: float | None) -> float:
        """The robot's path speed as a fraction of the nominal one at s_now (1 when unknown, or where the
        nominal trajectory itself stands)."""
        nominal = float(np.max(np.abs(old.sample(float(s_now))[1])))
        if speed_now is None or nominal < 1e-6:
            return 1.0
        return min(1.0, max(0.0, speed_now / nominal))

    def _start(self, old: Trajectory, s_now: float, speed_now: float | None, q_goal: np.ndarray,
               humans: HumanCapsules | None, reason: str, waited: float,
               held: bool, stop_at: float | None = None) -> tuple[ReplanResult | None, float]:
        """Where a new trajectory starts, by the robot's state: brought to rest by the scaler to await it
        (stop_at, ``ScalingLayer.awaiting``), from rest there; at rest, from rest where it stands; crawling
        (below `crawl` of its nominal speed, and held there by the SSM: not speeding up again), from rest
        where the scaler stops it. Returns (that plan, the old trajectory's prediction from the
        same state), or (None, the baseline) for a robot moving near its nominal speed (a merge, the
        caller's; both sides then in nominal time)."""
        if stop_at is not None and s_now - 1e-9 <= stop_at <= old.duration:
            return (self._rest_plan(old, stop_at, q_goal, humans, reason, waited),
                    self._baseline(old, stop_at, humans, waited, 0.0))
        at_rest = speed_now is not None and speed_now < self.options.rest_speed
        rate = 0.0 if at_rest else self._rate(old, s_now, speed_now)
        if at_rest:
            return (self._rest_plan(old, s_now, q_goal, humans, reason, waited),
                    self._baseline(old, s_now, humans, waited, 0.0))
        if held and rate < self.options.crawl:
            return (self._stop_plan(old, s_now, rate, q_goal, humans, reason, waited),
                    self._baseline(old, s_now, humans, waited, rate))
        return None, self._baseline(old, s_now, humans, waited, 1.0)

    def _baseline(self, old: Trajectory, s_now: float, humans: HumanCapsules | None, waited: float,
                  rate: float) -> float:
        """The old trajectory's predicted time from s_now, like the new one's: a robot below its nominal
        speed (rate, a fraction of it; 0 at rest) must first get back to it, (1 - rate) v / 2a more than the
        prediction at that speed, as a new trajectory from rest has to."""
        baseline = self.predicted_time(old, s_now, humans, waited)
        if rate < 1.0:
            v = np.abs(old.sample(float(s_now))[1])
            baseline += (1.0 - rate) * float(np.max(v / (2.0 * self.limits.acceleration)))
        return baseline

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
        result, baseline = self._start(old, s_now, speed_now, q_goal, humans, "horizon", waited, held)
        if result is None:
            s_branch = check.last_feasible_s
            if s_branch is None or s_branch < s_now + self.options.lead:
                s_branch = min(old.duration, s_now + self.options.lead)
            result = self.replan(old, s_now, q_goal, humans, "horizon", s_branch, waited)
        return keep_or_replace(result, baseline, 0.0, started, f"path blocked at s={blocked:.2f}")

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
        if out_of_reach(self.collision, humans) or self._rate(old, s_now, speed_now) < 0.5:
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
        stops it (``_stop_plan``). Moving, the merge must be
        continuous in nominal time, so the new part starts with the old nominal velocity: the branch point
        is then put one nominal stopping time ahead, so the old path gives room to come to rest before the
        new path leaves it. waited (s): how long the scaling layer has been asking (see predicted_time).
        held: the robot's speed is the SSM's bound (or it brakes), not a ramp below it. reason and why: the
        result's reason and what the decision's detail calls the request (on_slow's own). stop_at: where the
        scaler brings the robot to rest to await this plan (``ScalingLayer.awaiting``): the plan starts from
        rest there, and the old trajectory is predicted from rest there too."""
        started = time.perf_counter()
        result, baseline = self._start(old, s_now, speed_now, q_goal, humans, reason, waited, held, stop_at)
        if result is None:
            v_now = old.sample(float(s_now))[1]
            stopping = float(np.max(np.abs(v_now) / (self.limits.acceleration * 0.9)))
            s_branch = min(old.duration, s_now + self.options.lead + stopping)
            result = self.replan(old, s_now, q_goal, humans, reason, s_branch, waited)
        gain = required_gain(baseline, self.options.min_gain, self.options.min_saving)
        return keep_or_replace(result, baseline, gain, started, why)


def _people_stayed(then: HumanCapsules | None, now: HumanCapsules | None) -> bool:
    """The same people as then, each capsule end within PREPARED_DRIFT (m) of where it was (nobody, both times:
    True)."""
    if then is None or now is None or then.count == 0 or now.count == 0:
        return (then is None or then.count == 0) and (now is None or now.count == 0)
    if then.count != now.count:
        return False
    return float(np.linalg.norm(now.segments - then.segments, axis=2).max()) <= PREPARED_DRIFT
