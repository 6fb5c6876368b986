"""The SSM-aware time cost: how long a path takes when the scaling layer holds it to the ISO/TS 15066 limit.

One cost for the whole planning layer: planning and shortening a path, choosing between keeping the old
trajectory and taking a new one, and the simulation's planner all call ``SsmTimeCost``; so does the stop
plan for a crawling robot, for where the crawl gets before its plan can come (``SsmTimeCost.reached``).

A path is walked sample by sample at its nominal joint velocity (the velocity the time law asks for at
full speed). At every sample the scaling layer's own SSM bound gives the largest alpha the people allow
(``shared.scaling.problem.ssm_alpha_bound``: every robot link against every human capsule, the limit of ISO/TS
15066 less the tracking margin), and the sample takes dt / alpha. This is the cost of Tonola et al. 2025
(an edge's length divided by the scaling factor expected along it), here as time, with the people moving:

* the people are where a forecast (``shared.planning.forecast``) has them by the time the robot has been
  predicted to travel, up to ``extrapolation`` seconds, then stay there. The default forecast moves people
  with a tracked velocity on along it (a body part slower than ``drift_speed`` stays where it is: a person
  shifting their stance does not walk on); people without one stay where they are and approach at the
  ISO 13855 speed inside the limit (``shared.safety.ssm``), as the standard treats them;
* people are assumed to stay in the cell for ``stay`` seconds of the prediction and to be gone after it.
  Both candidates of a keep-or-replace decision get the same ``stay``: a person who stays long makes the
  blocked old path slow and is gone round; a person who passes (tracked velocity) clears the old path in
  the prediction and is waited for;
* alpha is floored at ``alpha_floor``: a path through a person's slowdown is very slow, not infinitely;
  but where the bound is zero (a link inside a person's no-approach distance, approaching them) the robot
  does not pass at all while they stay, and the sample is waited at until they move or the stay ends.
  Floored there too, such a sample cost 50 times its nominal time and no more, so a plan that could not
  start while a person stood beside it was predicted as fast as one that could, however long they stayed.

The kernel runs compiled over all samples of a path (kinematics, the pairwise SSM and the bound in one
loop; a few microseconds per sample). Pure: no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from shared.core.humans import STANDING_SPEED, HumanCapsules
from shared.core.trajectory import Trajectory
from shared.planning.forecast import ConstantVelocity, Forecaster, PeopleForecast
from shared.planning.parameters import PlanningParameters
from shared.robot.model import RobotModel, chain_points_and_velocities
from shared.safety.parameters import SsmParameters
from shared.safety.ssm import _pair_ssm_kernel, speed_alpha_bound
from shared.scaling.problem import speed_fraction


@dataclass(frozen=True)
class TimeCostOptions:
    """spacing (rad): the largest joint step between the samples along a path's straight segments;
    trajectory_step (s): nominal time between the samples of a trajectory; alpha_floor: the least alpha a
    sample is charged with; extrapolation (s): how far people are moved on along their tracked velocities
    (``planning.forecast_horizon``; 2 s: a person crossing the cell at walking speed is predicted to leave
    the robot's reach, and is waited for rather than gone round. Against 1 s, full / scale_only on 48 seeded
    scenarios per kind: crossing 0.998x -> 1.000x, random walk 0.987x -> 0.991x, two people 1.0018x -> 1.0015x, the paper
    unchanged; on 16 others: crossing 0.995x -> 0.999x, random walk 0.975x -> 0.996x, standing 3.154x ->
    3.160x); wait_step (s): how long the prediction waits at a slow sample before it looks again at the
    people moved on; drift_speed (m/s): in the default forecast (``ConstantVelocity``), a capsule whose ends
    both move slower than this is not moved on (``shared.core.humans.STANDING_SPEED``)."""

    spacing: float = 0.05
    trajectory_step: float = 0.05
    alpha_floor: float = 0.02
    extrapolation: float = PlanningParameters.forecast_horizon
    wait_step: float = 0.1
    drift_speed: float = STANDING_SPEED


@numba.njit(cache=True)
def _stretched_time(qs, dqs, dts, velocity_limit, placement, parent, local, joint, ancestry, radii, frames, frame_vel,
                    frame_step, human_rad, human_known, horizon, fixed, near_d, v_near, v_far, a_h, lead, stop_full,
                    stop_min, reaction, a_stop, static, margin, extrapolation, stay, floor, wait_step, ends):
    """Sum of dts[k] / alpha_k along the samples, the people where the forecast has them by the time
    already predicted (frames (F, M, 2, 3) every frame_step s, linear in between, the last held; and, in
    ends[k], the sum up to the end of sample k: when the robot is predicted to get there); from `stay` on
    (within a sample too) at full speed. A sample that would take longer than wait_step is waited at in
    steps of wait_step, each with the people as forecast by then (up to extrapolation, the forecast's
    horizon): someone walking away clears the robot's way after a moment, not after the whole stretch
    their position of now would give (a sample at the alpha floor stands for 50 times its nominal time). Where the
    forecast does not move anyone (every frame and its velocities the first one's: people standing, or held), a
    look again would see the same people: a sample's bound is taken once and waited out in one step."""
    n_links = radii.shape[0]
    n_f, n_h = frames.shape[0], frames.shape[1]
    moved = np.empty_like(frames[0])
    still = _unmoving(frames, frame_vel)
    total = 0.0
    for k in range(qs.shape[0]):
        if n_h == 0 or total >= stay:
            total += dts[k]
            ends[k] = total
            continue
        points, vel = chain_points_and_velocities(qs[k], dqs[k], placement, parent, local, joint, ancestry)
        fraction = speed_fraction(dqs[k], velocity_limit)
        left = 1.0                 # the fraction of this sample still to travel
        while left > 0.0:
            if total >= stay:      # the people have left: the rest at full speed
                total += left * dts[k]
                break
            shift = min(total, extrapolation)
            at = shift / frame_step
            i = min(int(at), n_f - 1)
            nxt = min(i + 1, n_f - 1)
            frac = at - i if nxt > i else 0.0
            for j in range(n_h):
                for e in range(2):
                    for c in range(3):
                        moved[j, e, c] = frames[i, j, e, c] + frac * (frames[nxt, j, e, c] - frames[i, j, e, c])
            dist, robot_speed, human_speed, limit = _pair_ssm_kernel(
                points.reshape(n_links, 2, 3), radii, vel.reshape(n_links, 2, 3), moved, human_rad, frame_vel[i],
                human_known, horizon, fixed, near_d, v_near, v_far, a_h, lead)
            alpha = speed_alpha_bound(dist, robot_speed, human_speed, limit, fraction, stop_full, stop_min, reaction,
                                      a_stop, static, near_d, v_near, v_far, a_h, lead, margin)
            if alpha <= 0.0 and stay < np.inf:
                # inside a person's no-approach distance, approaching: the robot does not pass here while
                # they stay (the floor would charge 50 samples' time for a wait that has no end)
                alpha, need = 0.0, np.inf
            else:
                alpha = max(alpha, floor)
                need = left * dts[k] / alpha
            step = min(need, stay - total)
            if shift < extrapolation and not still:    # the people still move in the prediction: look again soon
                step = min(step, wait_step)
            total += step
            left = 0.0 if step >= need else left - step * alpha / dts[k]
        ends[k] = total
    return total


@numba.njit(cache=True)
def _unmoving(frames, frame_vel):
    """Whether every frame of a forecast, and its velocities, are the first one's (the people do not move in it)."""
    for f in range(1, frames.shape[0]):
        for j in range(frames.shape[1]):
            for e in range(2):
                for c in range(3):
                    if frames[f, j, e, c] != frames[0, j, e, c] or frame_vel[f, j, e, c] != frame_vel[0, j, e, c]:
                        return False
    return True


@numba.njit(cache=True)
def _path_samples(w, velocity, acceleration, spacing, from_rest):
    """SsmTimeCost.path_samples, compiled (it is called for every candidate of a search, and numpy's
    per-call overhead made it cost more than the SSM kernel itself): (q, dq, dt, overhead), overhead 0: what the
    time law adds (the start from rest, each corner, the stop at the end) is in the samples themselves, as a
    sample at rest where it happens, so that every later sample is predicted when the robot gets there."""
    n_j = w.shape[1]
    durations = np.zeros(max(w.shape[0] - 1, 0))
    counts = np.zeros(durations.size, dtype=np.int64)
    for k in range(durations.size):
        longest = 0.0
        for j in range(n_j):
            step = abs(w[k + 1, j] - w[k, j])
            durations[k] = max(durations[k], step / velocity[j])
            longest = max(longest, step)
        if durations[k] > 0.0:
            counts[k] = max(1, int(np.ceil(longest / spacing)))
    total = counts.sum() + durations.size + 1    # room for a sample at rest before each segment and at the end
    q, dq, dt = np.empty((total, n_j)), np.empty((total, n_j)), np.empty(total)
    last = np.zeros(n_j)                        # the previous moving segment's velocity
    m, seen = 0, False
    for k in range(durations.size):
        if counts[k] == 0:
            continue
        v = (w[k + 1] - w[k]) / durations[k]
        turn = 0.0                              # at rest before the first one (counted only from rest)
        for j in range(n_j):
            turn = max(turn, abs(v[j] - last[j]) / (2.0 * acceleration[j]))
        if (seen or from_rest) and turn > 0.0:  # the ramp or the corner, where it is: the robot does not move on
            q[m] = w[k]
            dq[m] = 0.0
            dt[m] = turn
            m += 1
        for i in range(counts[k]):             # from the segment's start: see path_samples
            q[m] = w[k] + (i / counts[k]) * (w[k + 1] - w[k])
            dq[m] = v
            dt[m] = durations[k] / counts[k]
            m += 1
        last, seen = v, True
    if seen:                                    # to rest at the end
        end = 0.0
        for j in range(n_j):
            end = max(end, abs(last[j]) / (2.0 * acceleration[j]))
        q[m] = w[w.shape[0] - 1]
        dq[m] = 0.0
        dt[m] = end
        m += 1
    return q[:m].copy(), dq[:m].copy(), dt[:m].copy(), 0.0


@dataclass(frozen=True)
class PathSamples:
    """A path walked at its nominal speed: configurations (N, 6), joint velocities (N, 6) and the nominal
    time each sample stands for (N,); plus the time the time law adds to it (rests and corners, s)."""

    q: np.ndarray
    dq: np.ndarray
    dt: np.ndarray
    overhead: float = 0.0

    @property
    def nominal(self) -> float:
        return float(self.dt.sum()) + self.overhead


class SsmTimeCost:
    """Expected traversal times of paths and trajectories under the SSM (see the module docstring)."""

    def __init__(self, robot: RobotModel, ssm: SsmParameters, options: TimeCostOptions = TimeCostOptions(),
                 forecaster: Forecaster | None = None) -> None:
        self.robot = robot
        self.ssm = ssm
        self.options = options
        self.forecaster = forecaster or ConstantVelocity(options.drift_speed)
        self.limits = robot.limits
        self.evaluations = 0
        self._forecasts: tuple[HumanCapsules, float, PeopleForecast] | None = None    # the latest, see forecast
        self._hypotheses: tuple[HumanCapsules, list[tuple[float, PeopleForecast]]] | None = None

    # ------------------------------------------------------------------------------------ sampling
    def segment_time(self, q0: np.ndarray, q1: np.ndarray) -> float:
        """Nominal time (s) of the straight joint motion q0 -> q1 at full joint speed."""
        return float(np.max(np.abs(np.asarray(q1) - np.asarray(q0)) / self.limits.velocity))

    def path_samples(self, waypoints: np.ndarray, from_rest: bool = True) -> PathSamples:
        """Samples of a waypoint path at full joint speed along each straight segment, each segment's first
        at its start: a robot that stands (or turns a corner) inside a person's no-approach distance and
        would approach them by moving on cannot start while they stay, and a sample half a step further on
        would miss exactly that (the timed trajectory's own samples see it, so the two disagreed by
        seconds on such a path). What a time law adds is on the timeline, where it happens, as a sample at rest
        there: v/(2a) to start from rest (from_rest) and again to come to rest (a trapezoid's L/v + v/a), and at
        each corner the time to change the joint velocities, |dv| / (2 a) for the slowest joint. Added as one lump
        at the end instead, every sample was predicted v/(2a) (0.2 s) before the robot got there: 0.36 m against
        a person walking at 1.6 m/s, and the search ranked paths by where people would not be."""
        w = np.ascontiguousarray(waypoints, dtype=float)
        return PathSamples(*_path_samples(w, self.limits.velocity, self.limits.acceleration, self.options.spacing,
                                          from_rest))

    def trajectory_samples(self, trajectory: Trajectory, s_from: float) -> PathSamples:
        """Samples of a timed trajectory from s_from to its end, at its own (nominal) velocities."""
        step = self.options.trajectory_step
        s = np.arange(s_from, trajectory.duration, step)
        if s.size == 0:
            return PathSamples(np.zeros((0, 6)), np.zeros((0, 6)), np.zeros(0))
        q, dq, _ = trajectory.sample(s)
        dt = np.diff(np.append(s, trajectory.duration))
        return PathSamples(q, dq, dt)

    # ------------------------------------------------------------------------------------ the cost
    def stretched(self, samples: PathSamples, humans: HumanCapsules | None, stay: float = np.inf,
                  moving: bool = True) -> float:
        """Predicted time (s) of the samples under the SSM, people staying `stay` seconds (moving=False:
        held where they are now, for a cost that does not depend on when the robot gets there)."""
        self.evaluations += 1
        if humans is None or humans.count == 0 or samples.q.shape[0] == 0:
            return samples.nominal
        if moving and callable(getattr(self.forecaster, "hypotheses", None)):     # the expected time over them
            return sum(weight * float(self._walk(samples, humans, stay, moving, ahead)[-1])
                       for weight, ahead in self.hypotheses(humans)) + samples.overhead
        return float(self._walk(samples, humans, stay, moving)[-1]) + samples.overhead

    def hypotheses(self, humans: HumanCapsules) -> list[tuple[float, PeopleForecast]]:
        """(weight, forecast) of each thing the people may do, from a forecaster with ``hypotheses(humans,
        horizon)`` (weights summing to 1; kept for the same HumanCapsules object, as ``forecast``)."""
        kept = self._hypotheses
        if kept is not None and kept[0] is humans:
            return kept[1]
        made = list(self.forecaster.hypotheses(humans, self.options.extrapolation))
        total = sum(w for w, _ in made)
        if not made or not all(w >= 0.0 for w, _ in made) or abs(total - 1.0) > 1e-6:
            raise ValueError(f"forecast hypotheses need weights >= 0 summing to 1, got {[w for w, _ in made]}")
        if any(f.frames.shape[1] != humans.count for _, f in made):
            raise ValueError(f"a forecast hypothesis does not have the tracked people's {humans.count} capsules")
        self._hypotheses = (humans, made)
        return made

    def forget_forecast(self) -> None:
        """Drop the kept forecast and hypotheses: for a forecaster whose answer for the same people changes (the
        evidence's forecast told per decision, ``bench/forecast_value.py``)."""
        self._forecasts = self._hypotheses = None

    def forecast(self, humans: HumanCapsules, moving: bool = True) -> PeopleForecast:
        """The forecaster's frames of these people over the options' extrapolation (moving=False: held where
        they are). A search costs hundreds of candidates against the same tracked people: the latest forecast
        is kept for the same HumanCapsules object (frozen; a new snapshot is a new object)."""
        horizon = self.options.extrapolation if moving else 0.0
        kept = self._forecasts
        if kept is not None and kept[0] is humans and kept[1] == horizon:
            return kept[2]
        made = self.forecaster.forecast(humans, horizon) if horizon > 0.0 else PeopleForecast.still(humans)
        if made.frames.shape[1] != humans.count:
            raise ValueError(f"the forecast has {made.frames.shape[1]} capsules, the tracked people {humans.count}")
        self._forecasts = (humans, horizon, made)
        return made

    def _walk(self, samples: PathSamples, humans: HumanCapsules, stay: float, moving: bool,
              ahead: PeopleForecast | None = None) -> np.ndarray:
        """When the robot is predicted to reach the end of each sample (s from the first one's start), the
        people as `ahead` has them (None: the forecaster's forecast)."""
        r = self.robot
        placement, parent, local, joint = r.chain
        ssm, o = self.ssm, self.options
        ahead = self.forecast(humans, moving) if ahead is None else ahead
        ends = np.empty(samples.q.shape[0])
        _stretched_time(np.ascontiguousarray(samples.q), np.ascontiguousarray(samples.dq), samples.dt,
                        r.limits.velocity, placement, parent, local, joint, r.ancestry, r.radii, ahead.frames,
                        ahead.velocities, ahead.step, humans.radii, humans.velocity_known, *ssm.kernel_constants,
                        *ssm.stop_constants, ssm.tracking_margin, ahead.horizon, float(stay), o.alpha_floor,
                        o.wait_step, ends)
        return ends

    def reached(self, trajectory: Trajectory, s_from: float, humans: HumanCapsules | None, seconds: float,
                stay: float = np.inf, samples: int = 20) -> float:
        """The path parameter the robot is predicted to have reached `seconds` from now, going on from s_from
        at the SSM's bound (the one the scaling layer holds it to; people moved on as in the cost). A robot
        crawling towards a person slows down further as they close in: at its present rate it would be
        predicted further on than it gets. The stretch ahead (at most `seconds` of nominal time) is walked
        in `samples` steps, then again over the part the robot gets through: each step takes the bound at
        its start, and a crawl gets through a few of the first walk's steps."""
        end = min(trajectory.duration, s_from + seconds)
        if humans is None or humans.count == 0 or end <= s_from:
            return end
        got = self._reach(trajectory, s_from, end, humans, seconds, stay, samples)
        closer = s_from + 1.5 * (got - s_from) + 1e-4
        if closer < end:
            again = self._reach(trajectory, s_from, closer, humans, seconds, stay, samples)
            if again < closer:
                return again
        return got

    def _reach(self, trajectory: Trajectory, s_from: float, s_to: float, humans: HumanCapsules, seconds: float,
               stay: float, samples: int) -> float:
        """reached() over [s_from, s_to] in `samples` steps (s_to when the time does not run out there)."""
        s = np.linspace(s_from, s_to, samples + 1)
        q, dq, _ = trajectory.sample(s[:-1])
        ends = self._walk(PathSamples(q, dq, np.diff(s)), humans, stay, True)
        k = int(np.searchsorted(ends, seconds))
        if k >= ends.size:
            return s_to
        began = ends[k - 1] if k > 0 else 0.0
        return float(s[k] + (s[k + 1] - s[k]) * (seconds - began) / max(ends[k] - began, 1e-12))

    def path_time(self, waypoints: np.ndarray, humans: HumanCapsules | None, stay: float = np.inf,
                  moving: bool = True, from_rest: bool = True) -> float:
        """Predicted time (s) of a waypoint path, rest to rest, under the SSM."""
        return self.stretched(self.path_samples(waypoints, from_rest), humans, stay, moving)

    def trajectory_time(self, trajectory: Trajectory, s_from: float, humans: HumanCapsules | None,
                        stay: float = np.inf) -> float:
        """Predicted time (s) from s_from to the end of a timed trajectory under the SSM."""
        return self.stretched(self.trajectory_samples(trajectory, s_from), humans, stay)
