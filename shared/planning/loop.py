"""The planning layer's cadence: when to plan what, the one loop the planner service and the simulation run.

Each turn the loop is given what the planning layer knows at that moment (``PlanningInputs``: the goal,
where the robot is, the people, the trajectory the scaler follows and where on it, the scaler's beta flag,
how long it has been held) and takes at most one action, in this order:

1. a new goal: from rest, ``Replanner.plan_goal`` as the robot leaves: the direct line (or the folded leg), or the
   plan prepared for it, published at once (a search first only where the direct line is predicted slower than
   nominal by more than ``worth_waiting``; shipped: never); while a trajectory is being followed, a merge into it
   (Alg. 2, reason 'goal');
2. a replan request (beta raised), at most every ``beta_cooldown`` (a robot brought to rest to await its plan,
   ``stop_at``, is answered at once, once for each wait): ``Replanner.on_beta``, unless the goal
   itself is out of reach while the people stay (``shared.planning.blocked``): every path then ends in the
   same wait, and the refusal says so without a search;
3. once the robot has left on a goal's direct leg (moving, or held by the SSM), the search that goal from
   rest would have waited for (action and reason 'search', ``Replanner.on_search``): searched from rest where
   the leg began and taken by the goal's own rule, then merged a moment ahead of the robot. The robot does not
   stand at a goal for a search that seldom pays (80 ms charged in the simulation, 55-190 ms in the cell at a table's edge);
4. a new human sample, at most every ``horizon_period``: the horizon check (Alg. 1) and a merge when the
   path ahead is blocked and the way round is predicted faster; after a refused one, the horizon is left
   alone for half a beta cooldown (a blocked horizon is not hammered every sample);
5. at most every ``slow_period``, the path ahead predicted slow while the robot still moves at speed
   (``Replanner.on_slow``: the planning layer's own replan request, reason 'slow'); after a refused one,
   not for a beta cooldown. A plan is only as good as the prediction it was made on: a goal planned while
   a person was still stepping in assumed they walk on, and they stopped in its way;
6. where the goal after this one is known (``PlanningInputs.then``), once the robot is within
   ``prepare_ahead`` nominal seconds of the goal: the next leg's plan, prepared and kept, not published
   (action 'prepare'). When that goal comes, ``Replanner.plan_goal`` takes it instead of a search where it
   is still good for the people as they are then: the robot leaves without waiting for a search (in `hrc
   demo` a goal's search took 60-100 ms, and the robot stood at the goal meanwhile).

Every prediction assumes the people stay at least as long as they have stood still (``StillClock``) or dwelt
where they are, working with their hands (``DwellClock``), or the robot has been held, whichever is longer, on
top of the replanner's patience (``shared.planning.presence``): someone who has stayed in the way for three
seconds is gone round sooner than someone who has just stopped.

Nothing is planned while the people are not known (no valid human state yet, or the track lost:
``PlanningLoop.ready``): a plan made then would be the empty cell's, and the scaling layer does not move the
robot without a human state anyway; a new goal waits for one.

The outcome (``PlanningOutcome``) says what was done and what came of it: a trajectory to publish, or why
none; a refused replan also says when the goal itself is out of reach while the people stay
(``shared.planning.blocked``). Pure apart from the Replanner's own wall-clock budgets: no I/O, the clock
is the caller's `now` (the service passes the monotonic clock, the simulation its simulated one).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from shared.core.humans import STANDING_SPEED, HumanCapsules, standing
from shared.core.trajectory import Trajectory, straight_line_trajectory
from shared.planning.blocked import GoalBlock, goal_block
from shared.planning.decision import ReplanFailed, ReplanResult
from shared.planning.inputs import PlanningInputs
from shared.planning.ompl_planner import PlanningError
from shared.planning.presence import DWELL_RADIUS, Presence
from shared.planning.replanner import PreparedPlan, Replanner
from shared.planning.timing import TimingError
from shared.planning.trust import ForecastTrust


@dataclass(frozen=True)
class PlanningOutcome:
    """One action of the loop. action: 'goal', 'search', 'beta', 'horizon', 'slow' or 'prepare'. result: the new trajectory
    (a goal from rest comes as a ReplanResult with from_rest and junction 0), None when there is none:
    `refused` then says why (None: nothing needed doing, the horizon was clear). prepared: the next leg's
    plan ('prepare'), kept by the loop for its goal and never published; None with `refused` saying why
    where it could not be made. searches: path searches the action ran (the simulation charges planning
    time by them)."""

    action: str
    result: ReplanResult | None = None
    refused: str | None = None
    searches: int = 0
    prepared: Trajectory | None = None


IDLE_LONGEST = 0.2     # s: the longest the planner's loop waits between turns when nothing is asked of it
PREPARE_AHEAD = 0.5    # s of nominal time before the goal: the next leg's plan is prepared from then on
PREPARE_BUDGET = 0.25  # s of wall clock the preparing may take (nothing waits on it: the robot is still on its way)
APPROACH_SPEED = 2.0   # m/s: the ISO 13855 approach speed near the robot, the fastest a person comes


def idle_time(gap: float, period: float, longest: float = IDLE_LONGEST) -> float:
    """How long (s) the loop may wait for its next turn when no goal is new and no replan is asked: the
    time the nearest person needs, at the ISO 13855 approach speed, to come within reach of any path (gap,
    m, ``shared.planning.horizon.reach_gap``), between one horizon period and `longest`. Someone within
    reach, or an unknown gap: every period. (A goal wakes the loop at once whatever this says.)"""
    if not gap > 0.0:
        return period
    return min(longest, max(period, gap / APPROACH_SPEED))


class PlanningLoop:
    """The cadence above around one Replanner. beta_replans False: the paper's ablation (no replan requests,
    the scaling layer's or the planning layer's own). still_speed: below it people count as standing
    (StillClock; None: not used). dwell_radius (m): people whose centroid stays this near count as dwelling
    (DwellClock; None: not used). slow_period (s): how often the path ahead is checked for a slow prediction
    (None: never)."""

    def __init__(self, replanner: Replanner, horizon_period: float = 0.02, beta_cooldown: float = 0.5,
                 beta_replans: bool = True, still_speed: float | None = STANDING_SPEED,
                 slow_period: float | None = 0.25, prepare_ahead: float | None = PREPARE_AHEAD,
                 dwell_radius: float | None = DWELL_RADIUS) -> None:
        self.replanner = replanner
        replanner.forget()                 # a new run: no paths remembered from another one
        self.horizon_period, self.beta_cooldown, self.beta_replans = horizon_period, beta_cooldown, beta_replans
        self.slow_period = slow_period
        self.prepare_ahead = prepare_ahead
        self.prepared: PreparedPlan | None = None     # the next leg's plan, for the goal after the current one
        self.prepared_for: tuple | None = None        # (trajectory version, the goal after) it was prepared on
        self.search_due: int | None = None            # the version left on without its goal's search (run on the way)
        self.next_beta = self.next_horizon = self.next_slow = -np.inf
        self.answered: float | None = None   # the last stop_at a replan request was answered for
        self.last_sample: int | None = None
        self.stays = Presence(still_speed, dwell_radius)    # how long the people have stayed (the clocks in use)
        self.last_people_sample: int | None = None   # the sample the people clocks last saw
        options = replanner.options             # whether the forecast has held (a new goal's line or fold)
        self.trust = ForecastTrust(replanner.cost.forecaster, options.trust_span, options.trust_tolerance) \
            if options.trust_tolerance > 0 else None

    def step(self, now: float, inputs: PlanningInputs) -> PlanningOutcome | None:
        """At most one planning action for this moment (see the module docstring); None when none is due."""
        if inputs.human_sample != self.last_people_sample:
            self.last_people_sample = inputs.human_sample
            self.stays.update(now, inputs.humans)
            if self.trust is not None:
                self.trust.update(now, inputs.humans)
        if not self.ready(inputs):
            return None
        inputs = replace(inputs, waited=max(inputs.waited, self.stays.waited(now)))
        self.replanner.take_delay(inputs.human_delay)
        before = self.replanner.searches
        self.replanner.begin()
        try:
            outcome = self._act(now, inputs)
        finally:
            self.replanner.end()
        return None if outcome is None else replace(outcome, searches=self.replanner.searches - before)

    @staticmethod
    def ready(inputs: PlanningInputs) -> bool:
        """Whether the loop can act on these inputs: the goal, where the robot is and the people are known
        (``humans`` None: no valid human state yet, or the track lost; nobody in view is an empty HumanCapsules).
        The scaling layer moves nobody without human data (``StepStatus.NO_HUMAN_DATA``), so a plan made blind buys
        no time; it only takes the empty cell's shape, the direct line, into a person the next human state would
        have shown. The cell planned its first goal a few ms after start, before tracker_ingest's first state; a
        replan request answered in a dropout would have swapped a fold round someone for the line through them."""
        return inputs.goal is not None and inputs.q is not None and inputs.humans is not None

    def _act(self, now: float, inputs: PlanningInputs) -> PlanningOutcome | None:
        if inputs.new_goal:
            return self._goal(now, inputs)
        if inputs.following is None:
            return None
        trajectory, s = inputs.following
        waits = inputs.stop_at is not None and inputs.stop_at != self.answered    # a new wait is answered at once
        if self.beta_replans and inputs.beta and (now >= self.next_beta or waits):
            self.next_beta, self.answered = now + self.beta_cooldown, inputs.stop_at
            if trajectory.version == self.search_due:      # this replan searches: the goal's search is done by it
                self.search_due = None
            block = self._block(inputs)
            if block is not None:          # no path gets there before the people move: nothing to search
                return PlanningOutcome("beta", refused=f"not searched: {block.describe()}")
            try:
                return PlanningOutcome("beta", self.replanner.on_beta(trajectory, s, inputs.goal, inputs.humans,
                                                                      inputs.speed, inputs.waited, inputs.kept_slow,
                                                                      stop_at=inputs.stop_at))
            except ReplanFailed as exc:          # (the goal is not blocked: asked just above)
                return PlanningOutcome("beta", refused=str(exc))
        if self._search_due(inputs):
            self.search_due = None
            try:
                return PlanningOutcome("search", self.replanner.on_search(
                    trajectory, s, inputs.goal, inputs.humans, inputs.speed, inputs.waited, inputs.kept_slow))
            except ReplanFailed as exc:
                return PlanningOutcome("search", refused=str(exc))
        if inputs.human_sample != self.last_sample and now >= self.next_horizon:
            self.last_sample = inputs.human_sample
            self.next_horizon = now + self.horizon_period
            try:
                result = self.replanner.on_horizon(trajectory, s, inputs.goal, inputs.humans, inputs.speed,
                                                   inputs.waited, inputs.kept_slow)
            except ReplanFailed as exc:
                self.next_horizon = now + self.beta_cooldown / 2
                return PlanningOutcome("horizon", refused=self._why(str(exc), inputs))
            if result is not None:
                return PlanningOutcome("horizon", result)
        if self.beta_replans and self.slow_period is not None and now >= self.next_slow:
            self.next_slow = now + self.slow_period
            try:
                result = self.replanner.on_slow(trajectory, s, inputs.goal, inputs.humans, inputs.speed,
                                                inputs.waited, inputs.kept_slow)
            except ReplanFailed as exc:
                self.next_slow = now + self.beta_cooldown
                return PlanningOutcome("slow", refused=str(exc))
            if result is not None:
                return PlanningOutcome("slow", result)
        return self._prepare(now, inputs)

    def _prepare(self, now: float, inputs: PlanningInputs) -> PlanningOutcome | None:
        """The next leg's plan, once per trajectory followed, within prepare_ahead of its end (None when it
        is not due): from the end of the followed trajectory (where its commands stop the robot) to the
        goal after, for the people as they are now, while they stand (``standing``: a prepared plan is taken
        only where they have not moved on, so a search for walking people would only keep the planner from
        what else is due). The replanner's remembered paths stay those of the current goal (its replans in
        the last moments of the leg recall them)."""
        trajectory, s = inputs.following
        if self.prepare_ahead is None or inputs.then is None or trajectory.duration - s > self.prepare_ahead:
            return None
        if inputs.humans is not None and not standing(inputs.humans):
            return None     # a plan for people on the move is out of date when the goal comes: not prepared
        key = (trajectory.version, np.asarray(inputs.then, dtype=float).tobytes())
        if key == self.prepared_for or not np.allclose(trajectory.positions[-1], inputs.goal, atol=1e-9):
            return None
        self.prepared_for, self.prepared = key, None
        remembered = self.replanner.remembered
        self.replanner.widen(PREPARE_BUDGET)     # its search costs every candidate, as the simulation's does
        try:
            plan = self.replanner.plan_goal(trajectory.positions[-1], inputs.then, inputs.humans, 0, inputs.waited,
                                            trusted=self._trusted(now))
        except (PlanningError, TimingError) as exc:
            return PlanningOutcome("prepare", refused=f"{type(exc).__name__}: {exc}")
        finally:
            self.replanner.remembered = remembered
        self.prepared = PreparedPlan(plan, inputs.humans)
        return PlanningOutcome("prepare", prepared=plan)

    def _trusted(self, now: float) -> bool:
        """The forecast of the people has held lately (``shared.planning.trust``; never where it is off)."""
        return self.trust is not None and self.trust.trusted(now)

    def _search_due(self, inputs: PlanningInputs) -> bool:
        """The goal's search left for the way is due: the robot follows that leg and has left (moving at
        ``rest_speed`` or more), or the SSM holds it where it stands (then the search plans from rest there)."""
        trajectory, _ = inputs.following
        return (self.search_due is not None and trajectory.version == self.search_due and inputs.speed is not None
                and (inputs.speed >= self.replanner.options.rest_speed or inputs.kept_slow))

    def _block(self, inputs: PlanningInputs) -> GoalBlock | None:
        """Why the goal is out of reach from where the robot is while the people stay, or None."""
        if inputs.humans is None:
            return None
        return goal_block(self.replanner.collision.robot, self.replanner.cost.ssm, inputs.q, inputs.goal, inputs.humans)

    def _why(self, refused: str, inputs: PlanningInputs) -> str:
        """A horizon refusal's reason, and where the goal itself is out of reach while the people stay
        (``goal_block``), that too: then no path, old or new, gets there before they move."""
        block = self._block(inputs)
        return refused if block is None else f"{refused}; {block.describe()}"

    def _goal(self, now: float, inputs: PlanningInputs) -> PlanningOutcome:
        self.replanner.forget(inputs.q if inputs.following is None else None)   # where the leg begins, at rest
        prepared, self.prepared, self.prepared_for = self.prepared, None, None
        self.search_due = None
        try:
            if inputs.following is None:
                trajectory = self.replanner.plan_goal(inputs.q, inputs.goal, inputs.humans, inputs.version,
                                                      inputs.waited, prepared, leaving=True, trusted=self._trusted(now))
                if self.replanner.search_deferred:
                    self.search_due = trajectory.version
                detail = "prepared on the way here" if self.replanner.took_prepared else \
                    "left at once, searched on the way" if self.replanner.search_deferred else \
                    "searched from rest" if self.replanner.goal_searched else \
                    "the folded leg" if self.replanner.took_fold else "the straight line"
                return PlanningOutcome("goal", ReplanResult(trajectory, 0.0, "goal", 0.0, from_rest=True, detail=detail))
            old, s = inputs.following
            return PlanningOutcome("goal", self.replanner.replan(old, s, inputs.goal, inputs.humans, "goal",
                                                                 waited=inputs.waited))
        except (PlanningError, TimingError, ReplanFailed) as exc:
            return PlanningOutcome("goal", refused=f"{type(exc).__name__}: {exc}")


def warm_up(replanner: Replanner) -> int:
    """Run every kind of planning action once on a made-up situation, so that the compiled kernels they
    call are loaded before the first real one needs them (numba loads each from its cache at its first
    call: 50-70 ms each, paid inside the first horizon check, prediction or beta replan with someone
    near). The shuttle turns the first joint by 1 rad from the middle of the joint ranges; a person stands
    beside the flange half way along it. A goal, a horizon check, and a beta replan moving, crawling and
    at rest; whatever each decides is thrown away, and the replanner forgets it all (remembered paths, the
    learnt finishing time). Returns the number of actions taken (errors count: the kernels ran)."""
    robot = replanner.collision.robot
    lim = robot.limits
    q_a = (lim.lower + lim.upper) / 2
    q_b = q_a.copy()
    q_b[0] = min(lim.upper[0], q_a[0] + 1.0)
    shuttle = straight_line_trajectory(q_a, q_b, lim.velocity, lim.acceleration)
    flange = robot.capsule_segments((q_a + q_b) / 2)[-1, 1]
    outward = np.array([flange[0] - robot.reach_centre[0], flange[1] - robot.reach_centre[1], 0.0])
    where = flange + 0.3 * outward / max(float(np.linalg.norm(outward)), 1e-9)
    person = HumanCapsules.from_arrays([[where - [0.0, 0.0, 0.5], where + [0.0, 0.0, 0.3]]], [0.12],
                                       np.zeros((1, 2, 3)), [True])
    finishing = replanner.finishing
    loop = PlanningLoop(replanner)
    nominal = float(np.abs(shuttle.sample(0.5 * shuttle.duration)[1]).max())
    turns = [(True, None, 0.0, False, False),                 # a new goal with the person beside the path
             (False, 0.3, nominal, False, False),             # the horizon check (and a merge)
             (False, 0.4, nominal, True, False),              # a replan request while moving: a merge
             (False, 0.5, 0.1 * nominal, True, True),         # crawling, held: a stop plan
             (False, 0.5, 0.0, True, True)]                   # at rest: a plan from rest
    taken = 0
    for k, (new_goal, at, speed, beta, held) in enumerate(turns):
        following = None if at is None else (shuttle, at * shuttle.duration)
        q = q_a if at is None else shuttle.sample(at * shuttle.duration)[0]
        inputs = PlanningInputs(goal=q_b, new_goal=new_goal, q=q, humans=person, human_sample=k, following=following,
                                speed=speed, beta=beta, waited=0.0, version=1, held=held)
        taken += loop.step(float(k), inputs) is not None
    replanner.forget()
    replanner.finishing = finishing
    return taken
