"""The planning layer's online part: horizon check (Alg. 1), replan and merge (Alg. 2), beta replans.

* ``horizon_check``: the next n configurations of the trajectory from the current path parameter (n and
  spacing configurable), all checked at once against the latest human capsules; returns the first
  infeasible one.
* ``Replanner.on_horizon``: the path ahead is blocked: a merge that keeps, where it can, the separation
  at which the human allows full speed (then half of it, then the bare margin), kept only when
  predicted faster than the old path (on which the scaling layer holds the robot back). Predictions
  cap the wait for a person in the way at the time already waited (``HoldClock``; ski rental: go
  round once waiting has cost what the way round costs extra).
* ``Replanner.plan_goal``: a new goal: the direct line unless going round the people is predicted faster.
* ``Replanner.replan``: keeps the old trajectory unchanged up to a junction s_j, and from there follows
  the old path geometry to a branch point (the last feasible horizon configuration), then a new
  RRT-Connect path to the goal. The new part is time-parameterised starting with the old nominal
  velocity at s_j (its spline starts tangent to the old path), so position and velocity are continuous
  at the junction; following the old geometry for a while gives toppra room to slow down before any turn.
  Junctions further back are tried when a turn is too sharp. The result gets the next version number;
  a follower anywhere before s_j continues at the same s.
* ``Replanner.on_beta``: the scaling layer asked (alpha too low): plan against humans inflated by the
  separation that would allow full speed, then by less, and keep the new trajectory only when its
  predicted time to the goal, executed under the SSM limit with the humans where they are now, beats
  the old one's by at least ``min_gain`` (10 %).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from shared.collision import CollisionModel
from shared.errors import HrcError
from shared.humans import HumanCapsules
from shared.planner import JointPlanner, PlanningError
from shared.scaling import ssm_alpha_bound
from shared.ssm import SsmParameters, protective_separation_distance
from shared.timing import TimingError, parameterize
from shared.trajectory import Trajectory, straight_line_trajectory


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


def horizon_check(trajectory: Trajectory, s: float, collision: CollisionModel, humans: HumanCapsules | None,
                  options: HorizonOptions = HorizonOptions()) -> HorizonResult:
    """Alg. 1: the first infeasible configuration among the next samples of the trajectory (one batch)."""
    samples = np.minimum(s + options.spacing * np.arange(options.samples + 1), trajectory.duration)
    samples = np.unique(samples)
    q, _, _ = trajectory.sample(samples)
    clearance = collision.clearances(q, humans)
    bad = np.flatnonzero(clearance <= collision.margins.tolerance)
    return HorizonResult(samples, clearance, int(bad[0]) if bad.size else None)


def merge(old: Trajectory, s_junction: float, new_part: Trajectory, version: int) -> Trajectory:
    """The old trajectory's knots up to s_junction (exactly, plus the junction itself), then new_part
    shifted to start at s_junction. Continuity is the caller's: new_part must start at q(s_j), q'(s_j)."""
    keep = old.times < s_junction - 1e-3    # a knot closer than 1 ms would make a needle-thin interval; the
    # interval that replaces it, from exact values and tangents at both ends, is the same cubic
    q_j, dq_j, _ = old.sample(float(s_junction))
    times = np.concatenate([old.times[keep], [s_junction], s_junction + new_part.times[1:]])
    positions = np.vstack([old.positions[keep], q_j, new_part.positions[1:]])
    velocities = np.vstack([old.velocities[keep], dq_j, new_part.velocities[1:]])
    return Trajectory(times, positions, velocities, version)


@dataclass(frozen=True)
class ReplanResult:
    trajectory: Trajectory
    junction: float       # s where the new trajectory starts to differ from the old one
    reason: str           # 'horizon', 'beta' or 'goal'
    plan_s: float         # wall time spent (s)
    inflation: float      # extra clearance (m) the accepted plan kept from the humans
    detail: str = ""
    from_rest: bool = False   # True: a new trajectory from the robot's configuration at rest (junction =
    # the s it was planned at); take it only while the robot is still there, with path speed 0


class ReplanFailed(HrcError):
    """No acceptable new trajectory; the old one stays (and the scaling layer keeps the robot safe)."""


class HoldClock:
    """How long the scaling layer has been asking for a replan (beta raised without a break), in s: the
    `waited` of a prediction (Replanner.predicted_time). Pure; fed the beta flag of each status."""

    def __init__(self) -> None:
        self.since: float | None = None

    def update(self, now: float, beta: bool) -> None:
        if not beta:
            self.since = None
        elif self.since is None:
            self.since = now

    def waited(self, now: float) -> float:
        return 0.0 if self.since is None else max(0.0, now - self.since)


@dataclass(frozen=True)
class ReplanOptions:
    """lookback: nominal seconds of old path kept ahead of the branch point as room to slow down (and
    tried further back when a turn is too sharp); lead: nominal seconds ahead of the current s that the
    junction must stay (the follower moves on while we plan); min_gain: the fraction of predicted time a
    beta replan must save; prediction_step: nominal seconds between the samples of that prediction;
    inflated_budget (s): RRT-Connect's time for an attempt with extra clearance (when such a path exists
    it is found fast; the bare-margin attempt keeps the planner's full budget);
    rest_speed (rad/s): below it the robot counts as at rest for a replan; extrapolation (s): how far
    ahead the prediction moves people on at their tracked velocities; patience (s): how long people in
    the way are expected to stay there before the robot has waited at all (the cap on a prediction's
    delay is patience + the time already held, see predicted_time). 0 is the ski-rental rule: keep the
    old path, and once held as long as the way round costs extra, go round; never worse than twice the
    better of the two, however long the person stays (a cell where people are known to stay at a station
    may set more); escape_*: how the escape waypoint is searched (random joint offsets of growing
    radius, seeded)."""

    lookback: tuple[float, ...] = (0.3, 0.6, 1.0)
    lead: float = 0.1
    min_gain: float = 0.10
    prediction_step: float = 0.05
    alpha_floor: float = 0.02
    inflated_budget: float = 0.1
    rest_speed: float = 0.02
    extrapolation: float = 1.0
    patience: float = 0.0
    escape_radii: tuple[float, ...] = (0.2, 0.4, 0.8)
    escape_alpha: float = 0.2
    escape_samples: int = 64
    seed: int = 0


class Replanner:
    """Builds merged trajectories; pure apart from OMPL's random sampling (seed it for repeatability)."""

    def __init__(self, collision: CollisionModel, planner: JointPlanner, ssm: SsmParameters,
                 horizon: HorizonOptions = HorizonOptions(), options: ReplanOptions = ReplanOptions()) -> None:
        self.collision = collision
        self.planner = planner
        self.ssm = ssm
        self.horizon = horizon
        self.options = options
        self.limits = collision.robot.limits
        self._rng = np.random.default_rng(options.seed)

    def _escape(self, q: np.ndarray, humans: HumanCapsules | None, inflation: float, kept: float) -> np.ndarray | None:
        """A configuration near q with the full inflation's clearance that q reaches without coming closer
        to a human than it is now (motion checked at the kept inflation), and towards which the SSM lets the
        robot set off at a useful speed (alpha >= escape_alpha with the humans where they are: a person
        close by allows only motions that approach none of their capsules); None if none is found. The
        nearest such candidate (in joint distance) is taken."""
        for radius in self.options.escape_radii:
            cands = q + self._rng.uniform(-radius, radius, size=(self.options.escape_samples, q.size))
            cands = cands[np.all((cands >= self.limits.lower) & (cands <= self.limits.upper), axis=1)]
            ok = cands[self.collision.clearances(cands, humans, inflation) > self.collision.margins.tolerance]
            for cand in ok[np.argsort(np.abs(ok - q).sum(axis=1))][:16]:
                heading = (cand - q) / np.abs(cand - q).max() * float(self.limits.velocity.min())
                if humans is not None and ssm_alpha_bound(self.collision.robot, q, heading, humans,
                                                          self.ssm) < self.options.escape_alpha:
                    continue
                if self.collision.motion_free(q, cand, humans, kept)[0]:
                    return cand
        return None

    # ----------------------------------------------------------------------------------------- plans
    def plan_fresh(self, q_start: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None, version: int,
                   inflation: float = 0.0) -> Trajectory:
        """A rest-to-rest trajectory to a new goal (raises PlanningError or TimingError)."""
        waypoints = self.planner.plan(q_start, q_goal, humans, inflation)
        return self._from_rest(waypoints, humans, inflation, version)

    def plan_goal(self, q_start: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None, version: int,
                  waited: float = 0.0) -> Trajectory:
        """A new goal from rest. The direct line (the exact trapezoid) when the static scene allows it,
        even if a person is in its way now, unless a way round the people is predicted faster: the same
        ski-rental rule as replans (predicted_time; the scaling layer keeps the robot back from a person
        who stays, and the horizon and beta replans go round once the wait has cost as much). Else, with
        the direct line blocked by the scene, a plan around everything (raises PlanningError or
        TimingError)."""
        q_start, q_goal = np.asarray(q_start, dtype=float), np.asarray(q_goal, dtype=float)
        if not self.collision.motion_free(q_start, q_goal)[0]:
            return self.plan_fresh(q_start, q_goal, humans, version)
        direct = straight_line_trajectory(q_start, q_goal, self.limits.velocity, self.limits.acceleration,
                                          version=version)
        if humans is None or humans.count == 0 or self.collision.motion_free(q_start, q_goal, humans)[0]:
            return direct
        try:
            around = self.plan_fresh(q_start, q_goal, humans, version)
        except (PlanningError, TimingError):
            return direct
        faster = self.predicted_time(around, 0.0, humans, waited) < self.predicted_time(direct, 0.0, humans, waited)
        return around if faster else direct

    def _from_rest(self, waypoints: np.ndarray, humans: HumanCapsules | None, inflation: float,
                   version: int) -> Trajectory:
        """Rest to rest through waypoints. A direct connection (two waypoints, already checked free by the
        planner) gets the exact trapezoid, which is time-optimal for a straight line and needs none of the
        acceleration headroom toppra's grid calls for where a path bends (2 % faster on the paper's
        shuttle); a bent path gets toppra."""
        if len(waypoints) == 2:
            return straight_line_trajectory(waypoints[0], waypoints[1], self.limits.velocity,
                                            self.limits.acceleration, version=version)
        return parameterize(waypoints, self.limits, collision=self.collision, humans=humans,
                            inflation=inflation, version=version)

    def _capped(self, inflation: float, configs: np.ndarray, humans: HumanCapsules | None) -> float:
        """The inflation, lowered to the clearance that the configurations a plan must start or end in
        already have (so it may turn negative: a robot a person has walked up to is not refused a way
        out). The plan then never comes closer to a human than it is now."""
        if humans is None or humans.count == 0:
            return max(0.0, inflation)
        have = float(self.collision.clearances(configs, humans, inflation=0.0).min()) - 2 * self.collision.margins.tolerance
        return min(inflation, have)

    def _tail(self, q_from: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None, inflation: float,
              kept: float) -> np.ndarray:
        budget = self.options.inflated_budget if inflation > 0 else None
        """Waypoints from q_from to the goal: when q_from cannot have the full inflation (kept < inflation),
        first to an escape configuration that has it, then planned with the inflation all the way."""
        escape = self._escape(q_from, humans, self._capped(inflation, q_goal[None, :], humans), kept) \
            if kept < inflation else None
        if escape is None:
            return self.planner.plan(q_from, q_goal, humans, kept, time_budget=budget)
        rest = self.planner.plan(escape, q_goal, humans, self._capped(inflation, np.vstack([escape, q_goal]), humans),
                                 time_budget=budget)
        return np.vstack([q_from, rest])

    def _branch(self, old: Trajectory, s_now: float, s_branch: float, q_goal: np.ndarray,
                humans: HumanCapsules | None, inflation: float, version: int) -> tuple[Trajectory, float, float]:
        """Merge at a junction s_j before s_branch: from s_j the old geometry to the branch point, then a
        new path to the goal. First continuously through the branch point (junctions further back give
        more room to slow down before turning); else stop-and-go: decelerate along the old path to rest at
        the branch point, then the new path from rest. Returns (merged, s_j, inflation kept)."""
        s_first = min(s_now + self.options.lead, s_branch)     # never before the planning lead
        junctions = sorted({max(s_first, s_branch - lb) for lb in self.options.lookback}, reverse=True)
        q_branch = old.sample(float(s_branch))[0]
        # the new part is planned with the inflation the branch point and the goal allow; the lead-in is
        # the old, already checked path, so the smoothed whole is verified at what the lead-in has too
        kept = self._capped(inflation, np.vstack([q_branch, q_goal]), humans)
        tail = self._tail(q_branch, q_goal, humans, inflation, kept)
        check = min(kept, self._capped(kept, old.sample(np.linspace(s_first, s_branch, 8))[0], humans))
        errors = []

        def lead_in(s_j: float) -> np.ndarray:
            return old.sample(np.linspace(s_j, s_branch, max(2, int(np.ceil((s_branch - s_j) / 0.05)) + 1)))[0]

        for s_j in junctions:                       # continuous through the branch point
            try:
                part = parameterize(np.vstack([lead_in(s_j), tail[1:]]), self.limits,
                                    start_velocity=old.sample(float(s_j))[1], collision=self.collision,
                                    humans=humans, inflation=min(check, self._capped(check, lead_in(s_j), humans)))
                return merge(old, s_j, part, version), s_j, kept
            except TimingError as exc:
                errors.append(f"through at s={s_j:.2f}: {exc}")
        s_j = junctions[-1]                          # stop-and-go, with the most room to stop
        try:
            stop = parameterize(lead_in(s_j), self.limits, start_velocity=old.sample(float(s_j))[1],
                                collision=self.collision, humans=humans,
                                inflation=min(check, self._capped(check, lead_in(s_j), humans)))
            go = parameterize(tail, self.limits, collision=self.collision, humans=humans, inflation=min(kept, check))
        except TimingError as exc:
            raise ReplanFailed("no junction allows a continuous merge: "
                               + "; ".join(errors + [f"stop-and-go: {exc}"])) from None
        return merge(merge(old, s_j, stop, version), s_j + stop.duration, go, version), s_j, kept

    def replan(self, old: Trajectory, s_now: float, q_goal: np.ndarray, humans: HumanCapsules | None,
               reason: str, inflation: float = 0.0, s_branch: float | None = None) -> ReplanResult:
        """Alg. 2 from s_branch (default: the current s plus the lead)."""
        started = time.perf_counter()
        s_branch = min(old.duration, s_now + self.options.lead) if s_branch is None else s_branch
        try:
            if s_branch >= old.duration - 1e-9:          # at the end, at rest: a fresh plan from there
                q_end = old.positions[-1]
                kept = self._capped(inflation, np.vstack([q_end, q_goal]), humans)
                merged = merge(old, old.duration, self.plan_fresh(q_end, q_goal, humans, 0, kept), old.version + 1)
                s_j = old.duration
            else:
                merged, s_j, kept = self._branch(old, s_now, s_branch, q_goal, humans, inflation, old.version + 1)
        except (PlanningError, TimingError) as exc:
            raise ReplanFailed(f"{type(exc).__name__}: {exc}") from None
        return ReplanResult(merged, s_j, reason, time.perf_counter() - started, kept)

    def passing(self, old: Trajectory, s_now: float, check: HorizonResult, humans: HumanCapsules) -> bool:
        """The horizon is blocked now, but the people in the way are moving out of it: with their tracked
        velocities, at the nominal time the robot would reach each blocked sample, none blocks any more
        (a person crossing the path). Waiting for them (the scaling layer slows the robot as needed) is
        then quicker than a detour."""
        if humans is None or not humans.velocity_known.any():
            return False
        blocked = check.s[check.first_infeasible:]
        q = old.sample(blocked)[0]
        for qk, sk in zip(q, blocked):
            later = humans.extrapolated(float(sk - s_now))
            if self.collision.clearances(qk[None, :], later)[0] <= self.collision.margins.tolerance:
                return False
        return True

    def on_horizon(self, old: Trajectory, s_now: float, q_goal: np.ndarray, humans: HumanCapsules | None,
                   speed_now: float | None = None, waited: float = 0.0) -> ReplanResult | None:
        """Alg. 1 + 2: None when the horizon is clear, or when the people in the way are passing
        (``passing``); else a merged trajectory branching at the last feasible horizon configuration
        (ReplanFailed when none can be built, saying why). speed_now: the robot's joint speed (rad/s); at
        rest, the new trajectory starts from rest where the robot stands (a merge in nominal time would have
        to leave at the old nominal speed, which a stopped robot cannot). Either way the new trajectory is
        kept only when predicted to reach the goal sooner than the old one (on which the scaling layer holds
        the robot back from the person for as long as they stay: safe, only slower). waited: as in
        predicted_time."""
        started = time.perf_counter()
        check = horizon_check(old, s_now, self.collision, humans, self.horizon)
        # blocked where the robot already is: no branch ahead can help (the scaling layer holds the robot;
        # a beta replan plans the way out, and only when it is predicted to pay)
        if check.first_infeasible in (None, 0) or self.passing(old, s_now, check, humans):
            return None
        blocked = float(check.s[check.first_infeasible])
        at_rest = speed_now is not None and speed_now < self.options.rest_speed
        baseline = self.predicted_time(old, s_now, humans, waited)
        # A path that only just clears the human is collision-free but slow: within the SSM's fixed distance
        # an approaching link gets alpha = 0. So the inflation ladder of a beta replan (the separation that
        # allows full speed, half of it, the bare margin), each branching at the last horizon sample that
        # still has that clearance: earlier, with room to keep it.
        q_horizon = old.sample(check.s)[0]

        def branch_at(inflation: float) -> float:
            ok = self.collision.clearances(q_horizon, humans, inflation) > self.collision.margins.tolerance
            first_bad = int(np.argmin(ok)) if not ok.all() else len(ok)
            s_branch = float(check.s[first_bad - 1]) if first_bad > 0 else s_now
            if s_branch < s_now + self.options.lead:
                # too close to branch in front of it: branch at the planning lead; the new path may not come
                # closer to the human than that point is (the scaling layer keeps the speed safe)
                s_branch = min(old.duration, s_now + self.options.lead)
            return s_branch

        errors = []
        for inflation, result, why in self._ladder(old, s_now, q_goal, humans, "horizon", at_rest, branch_at):
            if result is None:
                errors.append(f"inflation {inflation:.2f} m: {why}")
                continue
            # The way round must be predicted faster than keeping the old path. People walk on: without
            # this a stopped robot next to a moving person re-planned every few ticks, each plan blocked
            # again, and a moving one took long detours round a person who had gone by the time it got there
            predicted = self._worth_it(result, old, s_now, humans, baseline, gain=0.0, waited=waited)
            if predicted is None:
                errors.append(f"inflation {inflation:.2f} m: {'from rest ' if at_rest else ''}not faster than the "
                              f"old {baseline:.2f} s")
                continue
            how = "from rest" if result.from_rest else f"merged at s={result.junction:.2f}"
            return ReplanResult(result.trajectory, result.junction, result.reason, time.perf_counter() - started,
                                result.inflation, f"path blocked at s={blocked:.2f}, {how}, kept "
                                f"{result.inflation:.2f} m extra, predicted {predicted:.2f} s instead of "
                                f"{baseline:.2f} s", result.from_rest)
        raise ReplanFailed(f"path blocked at s={blocked:.2f}; " + "; ".join(errors))

    def _ladder(self, old: Trajectory, s_now: float, q_goal: np.ndarray, humans: HumanCapsules | None,
                reason: str, at_rest: bool, branch_at):
        """The inflation ladder of a replan (the separation at which a person standing still allows full
        speed, half of it, the bare margin): per rung (inflation, the new trajectory or None, why none).
        At rest a plan from rest where the robot stands; moving, a merge branching at branch_at(inflation)."""
        full = self.full_speed_inflation()
        for inflation in (full, full / 2, 0.0):
            try:
                if at_rest:
                    result = self._rest_plan(old, s_now, q_goal, humans, inflation, reason)
                else:
                    result = self.replan(old, s_now, q_goal, humans, reason, inflation=inflation,
                                         s_branch=branch_at(inflation))
            except (ReplanFailed, PlanningError, TimingError) as exc:
                yield inflation, None, str(exc)
                continue
            yield inflation, result, ""

    def _rest_plan(self, old: Trajectory, s_now: float, q_goal: np.ndarray, humans: HumanCapsules | None,
                   inflation: float, reason: str) -> ReplanResult:
        """A trajectory from rest where the robot stands (old at s_now) to the goal, keeping `inflation`
        extra clearance where it can (raises PlanningError or TimingError)."""
        q_now = old.sample(float(s_now))[0]
        kept = self._capped(inflation, np.vstack([q_now, q_goal]), humans)
        traj = self._from_rest(self._tail(q_now, q_goal, humans, inflation, kept), humans, min(kept, 0.0),
                               old.version + 1)
        return ReplanResult(traj, s_now, reason, 0.0, kept, from_rest=True)

    # ------------------------------------------------------------------------------------ beta replans
    def full_speed_inflation(self, robot_speed: float = 1.0) -> float:
        """Extra clearance (m) beyond the planner's own margin at which a human standing still allows a
        link moving at robot_speed: S_p(robot_speed, 0) - d_min - human margin."""
        sp = float(protective_separation_distance(robot_speed, 0.0, self.ssm))
        return max(0.0, sp - self.collision.min_separation - self.collision.margins.human)

    def predicted_time(self, trajectory: Trajectory, s_from: float, humans: HumanCapsules | None,
                       waited: float = 0.0) -> float:
        """Nominal remaining time stretched by the SSM: sum over samples of ds / alpha(s), alpha the
        safe bound with the humans where they will be when the robot gets there: moved on at their tracked
        velocities for up to options.extrapolation seconds, then standing (unknown velocities: standing
        from now). Floored at alpha_floor. The stretch (the delay over the nominal time) is capped at
        options.patience + waited: people in the way do not stay there for ever (uncapped, a path a person
        stands on now is predicted blocked for good, and any detour wins however long it is), while a robot
        held for `waited` seconds already expects to wait longer (so a person who stays is gone round)."""
        step = self.options.prediction_step
        samples = np.arange(s_from, trajectory.duration, step)
        if humans is None or samples.size == 0:
            return max(0.0, trajectory.duration - s_from)
        q, dq, _ = trajectory.sample(samples)
        total = 0.0
        moving = bool(humans.velocity_known.any()) and self.options.extrapolation > 0
        for qk, dqk in zip(q, dq):
            there = humans.extrapolated(min(total, self.options.extrapolation)) if moving else humans
            alpha = ssm_alpha_bound(self.collision.robot, qk, dqk, there, self.ssm)
            total += step / max(alpha, self.options.alpha_floor)
        nominal = step * samples.size
        return nominal + min(total - nominal, self.options.patience + waited)

    def _worth_it(self, result: ReplanResult, old: Trajectory, s_now: float, humans: HumanCapsules | None,
                  baseline: float, gain: float | None = None, waited: float = 0.0) -> float | None:
        """The new trajectory's predicted time to the goal when it beats baseline (the old one's) by
        gain (default min_gain), else None."""
        gain = self.options.min_gain if gain is None else gain
        if result.from_rest:
            predicted = self.predicted_time(result.trajectory, 0.0, humans, waited)
        else:
            predicted = (self.predicted_time(result.trajectory, result.junction, humans, waited)
                         + (result.junction - s_now))
        return predicted if predicted <= (1.0 - gain) * baseline else None

    def on_beta(self, old: Trajectory, s_now: float, q_goal: np.ndarray, humans: HumanCapsules | None,
                speed_now: float | None = None, waited: float = 0.0) -> ReplanResult:
        """A replan that is worth it, or ReplanFailed saying why the old trajectory stays.

        speed_now: the robot's actual joint speed (rad/s, max over joints; None: moving at the nominal
        speed). At rest (below rest_speed) the new trajectory starts at rest from where the robot is:
        continuous in the actual velocity, and free to leave in any direction. Moving, the merge must be
        continuous in nominal time, so the new part starts with the old nominal velocity: the branch point
        is then put one nominal stopping time ahead, so the old path gives room to come to rest before the
        new path leaves it. waited (s): how long the scaling layer has been asking (see predicted_time)."""
        started = time.perf_counter()
        v_now = old.sample(float(s_now))[1]
        baseline = self.predicted_time(old, s_now, humans, waited)
        at_rest = speed_now is not None and speed_now < self.options.rest_speed
        stopping = float(np.max(np.abs(v_now) / (self.limits.acceleration * 0.9)))
        s_branch = min(old.duration, s_now + self.options.lead + stopping)
        tried = []
        for inflation, result, why in self._ladder(old, s_now, q_goal, humans, "beta", at_rest, lambda _: s_branch):
            if result is None:
                tried.append(f"inflation {inflation:.2f} m: {why}")
                continue
            predicted = self._worth_it(result, old, s_now, humans, baseline, waited=waited)
            if predicted is not None:
                return ReplanResult(result.trajectory, result.junction, "beta", time.perf_counter() - started,
                                    result.inflation, f"predicted {predicted:.2f} s instead of {baseline:.2f} s",
                                    result.from_rest)
            tried.append(f"inflation {inflation:.2f} m: not {100 * self.options.min_gain:.0f} % faster than the old "
                         f"{baseline:.2f} s")
        raise ReplanFailed("kept the old trajectory; " + "; ".join(tried))
