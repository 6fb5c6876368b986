"""ISO/TS 15066 speed and separation monitoring (SSM), as the safety-aware kinodynamic paper writes it.

Protective separation distance for a robot approaching at v_r and a human approaching at v_h:

    S_p(v_r, v_h) = v_h (T_s + T_r) + v_r (T_s + T_r) + a_max T_s^2 / 2 + C + Z_d + Z_r

and its inverse, the largest robot approach speed allowed at the current separation S:

    v_r_max(S, v_h) = (S - v_h (T_s + T_r) - C - Z_d - Z_r) / (T_s + T_r) - a_max T_s^2 / (2 (T_s + T_r))

(the paper's form; its a_max term lowers the limit, which is conservative compared to the constant
deceleration derivation). A negative limit means the robot may not approach at all; moving away stays
allowed.

T_s is the stopping time of the robot's state, not one number for every speed (``SsmParameters.stop_at``: T_s x
the fastest joint's fraction of its velocity limit, at least ``min_stopping_time``): the limit of a state is the
formula at its own T_s (``limit_at``), and the largest path speed a state allows is found where its limit, at the
stopping time of that speed, still holds (``speed_alpha_bound``: the limit falls as the speed rises, so the
speeds allowed are an interval from 0). With min_stopping_time = stopping_time it is the paper's single T_s.

Every function here is pure and vectorised over numpy arrays. Units: m, s, m/s, m/s^2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from shared.core.geometry import EPS_NORMAL, segment_closest_params
from shared.core.humans import HumanCapsules
from shared.safety.parameters import SsmParameters


@numba.njit(cache=True)
def human_travel(speed: float, cap: float, acceleration: float, horizon: float) -> float:
    """How far (m) a person approaching at `speed` (m/s) may come within `horizon` (T_r + T_s) when their
    speed may grow at `acceleration` (m/s^2) up to the ISO 13855 speed `cap` (m/s): the integral of
    min(speed + acceleration t, cap) over the horizon; a measured speed above the cap is held. acceleration
    0: speed x horizon, the paper's formula (the measured speed held)."""
    if acceleration <= 0.0 or speed >= cap:
        return speed * horizon
    rise = (cap - speed) / acceleration
    if rise >= horizon:
        return speed * horizon + 0.5 * acceleration * horizon * horizon
    return speed * rise + 0.5 * acceleration * rise * rise + cap * (horizon - rise)


def human_distance(human_speed: np.ndarray, params: SsmParameters, separation: np.ndarray | None = None,
                   stop: float | None = None) -> np.ndarray:
    """The human's part of S_p (m): how far a person now approaching at human_speed (m/s) may come within
    T_r + T_s under the cell's human model (``human_travel``, capped at the ISO 13855 speed for that
    separation; without a separation at the near speed, the larger), from human_lead s before where the data is
    that late (``aged_travel``); stop: the state's T_s (s; default the full-speed stopping_time). Element by
    element, compiled."""
    where = -np.inf if separation is None else separation      # nearer than any: the near speed
    speed, d = np.broadcast_arrays(np.asarray(human_speed, dtype=float), np.asarray(where, dtype=float))
    horizon = params.horizon if stop is None else params.reaction_time + float(stop)
    out = _aged_each(np.ascontiguousarray(d).ravel(), np.ascontiguousarray(speed).ravel(),
                     *params.kernel_constants[2:], float(horizon))
    return out.reshape(speed.shape) if speed.shape else float(out[0])


NEAR_RAMP = 0.3    # m above human_near_distance over which the ISO 13855 speed falls from the near to the far one


@numba.njit(cache=True)
def iso_speed(d, near_d, v_near, v_far):
    """The ISO 13855 approach speed (m/s) at separation d (m): v_near within near_d, then falling linearly to
    v_far over NEAR_RAMP, v_far beyond. ISO 13855 steps from 2.0 to 1.6 m/s at 0.5 m; the ramp is never below it
    (so never less safe), and it keeps the SSM limit continuous: at the step the limit of a robot that creeps
    near a person fell by 0.3 m/s within one control period, which no braking follows (a command above the
    limit for two periods in the paper's phases)."""
    if d <= near_d:
        return v_near
    if d >= near_d + NEAR_RAMP:
        return v_far
    return v_near + (v_far - v_near) * (d - near_d) / NEAR_RAMP


@numba.njit(cache=True)
def aged_travel(d, hs, near_d, v_near, v_far, a_h, lead, horizon):
    """How far (m) a person seen at separation d (m), approaching at hs (m/s), may have come by the end of
    `horizon` (T_r + T_s, s) from now when they were seen as they were `lead` s ago (``SsmParameters.human_lead``:
    the data's whole age, from its capture to this cycle): their travel under the human model over lead +
    horizon from the capture (``human_travel``: a start or a speed-up within the lead counted as one within the
    horizon), capped at the ISO 13855 speed of the separation they may have reached by now. lead 0: the
    formula's own human term at d.

    ISO/TS 15066's T_r runs from the person's detection to the robot's reaction. The robot's part of a delay is
    known: the scaling layer takes the robot where it is now, and only the person's way since their capture is
    unknown. So that way is counted here, on the person's side, once, and T_r covers only the cell's own chain
    from this cycle to the drives moving (the robot driver's ``reaction_time_exceeded``, the report's
    ``reaction_time_covers_p99``). A camera's latency and the wait for its next frame are both in the age:
    counted in T_r as well, they were counted twice, on the robot's side too (docs/measurements.md, session 81).
    """
    ahead = human_travel(hs, iso_speed(d, near_d, v_near, v_far), a_h, lead)
    cap = iso_speed(d - ahead, near_d, v_near, v_far)
    return human_travel(hs, cap, a_h, lead + horizon)


@numba.njit(cache=True)
def _aged_each(d, speed, near_d, v_near, v_far, a_h, lead, horizon):
    out = np.empty(speed.shape[0])
    for k in range(speed.shape[0]):
        out[k] = aged_travel(d[k], speed[k], near_d, v_near, v_far, a_h, lead, horizon)
    return out


@numba.njit(cache=True)
def _iso_each(d, near_d, v_near, v_far):
    out = np.empty(d.shape[0])
    for k in range(d.shape[0]):
        out[k] = iso_speed(d[k], near_d, v_near, v_far)
    return out


def default_human_speed(separation: np.ndarray, params: SsmParameters) -> np.ndarray:
    """ISO 13855 approach speed for an untracked human: 2.0 m/s within 0.5 m, 1.6 m/s beyond (``iso_speed``:
    a ramp between the two over NEAR_RAMP above 0.5 m)."""
    d = np.asarray(separation, dtype=float)
    out = _iso_each(np.ascontiguousarray(d).ravel(), float(params.human_near_distance),
                    float(params.human_speed_near), float(params.human_speed_far))
    return out.reshape(d.shape) if d.shape else float(out[0])


def protective_separation_distance(robot_speed: np.ndarray, human_speed: np.ndarray,
                                   params: SsmParameters, stop: float | None = None) -> np.ndarray:
    """S_p (m) for a robot approaching at robot_speed and a human at human_speed (m/s, >= 0), the human's
    part under the cell's human model (``human_distance``, capped at the near ISO 13855 speed); stop: the
    robot's T_s (s; default the full-speed stopping_time)."""
    stop = params.stopping_time if stop is None else float(stop)
    return human_distance(human_speed, params, stop=stop) + np.asarray(robot_speed) * (params.reaction_time + stop) \
        + params.fixed_distance_at(stop)


def velocity_limit(separation: np.ndarray, human_speed: np.ndarray, params: SsmParameters,
                   stop: float | np.ndarray | None = None) -> np.ndarray:
    """v_r_max (m/s): the largest robot approach speed at this separation; negative means 'do not approach'.
    The human's part is ``human_distance`` (the paper's v_h (T_r + T_s) where human_acceleration is 0); stop:
    the state's T_s (s, ``SsmParameters.stop_at``; default the full-speed stopping_time), a number or one per
    element."""
    stop = params.stopping_time if stop is None else stop
    d, hs, st = np.broadcast_arrays(np.asarray(separation, dtype=float), np.asarray(human_speed, dtype=float),
                                    np.asarray(stop, dtype=float))
    out = _limits_each(np.ascontiguousarray(d).ravel(), np.ascontiguousarray(hs).ravel(),
                       np.ascontiguousarray(st).ravel(), *params.stop_constants[2:], *params.kernel_constants[2:])
    return out.reshape(d.shape) if d.shape else float(out[0])


@numba.njit(cache=True)
def limit_at(d, hs, stop, reaction, a_stop, static, near_d, v_near, v_far, a_h, lead):
    """v_r_max (m/s) at separation d (m) for a person approaching at hs (m/s; the ISO 13855 speed where
    untracked) and a robot whose stopping time is `stop` (s): the formula with T_s = stop, the person's travel
    counted from `lead` s before (``SsmParameters.human_lead``: the data's delay; ``aged_travel``)."""
    horizon = reaction + stop
    return (d - aged_travel(d, hs, near_d, v_near, v_far, a_h, lead, horizon) - 0.5 * a_stop * stop * stop
            - static) / horizon


@numba.njit(cache=True)
def _limits_each(d, hs, stop, reaction, a_stop, static, near_d, v_near, v_far, a_h, lead):
    out = np.empty(d.shape[0])
    for k in range(d.shape[0]):
        out[k] = limit_at(d[k], hs[k], stop[k], reaction, a_stop, static, near_d, v_near, v_far, a_h, lead)
    return out


NEGLIGIBLE_SPEED = 1e-12   # m/s: an approach speed below this counts as none (no overflow in b / c)
BISECTIONS = 14            # of the path speed where T_s follows it: 1/16384 of full speed


@numba.njit(cache=True)
def fixed_stop_alpha_bound(robot_speed, limit):
    """min(1, max(limit, 0) / robot speed) over the pairs that approach (robot_speed, limit: per pair, m/s, at
    alpha = 1; the limit already less any margin): the largest alpha every pair allows with one T_s."""
    upper = 1.0
    for i in range(robot_speed.shape[0]):
        for k in range(robot_speed.shape[1]):
            if robot_speed[i, k] > NEGLIGIBLE_SPEED:
                upper = min(upper, max(limit[i, k], 0.0) / robot_speed[i, k])
    return upper


@numba.njit(cache=True)
def stop_of_speed(alpha, fraction, stop_full, stop_min):
    """T_s (s) at path speed alpha where the fastest joint moves at `fraction` of its limit at alpha = 1: the
    compiled ``SsmParameters.stop_at`` (stop_full = stopping_time, stop_min = min_stopping_time)."""
    return max(stop_min, stop_full * alpha * fraction)


@numba.njit(cache=True)
def _pair_allows(alpha, i, k, dist, robot_speed, human_speed, fraction, stop_full, stop_min, reaction, a_stop, static,
                 near_d, v_near, v_far, a_h, lead, margin):
    """Whether pair (i, k), approaching, keeps path speed alpha within its limit at that speed's T_s, less margin."""
    stop = stop_of_speed(alpha, fraction, stop_full, stop_min)
    lim = limit_at(dist[i, k], human_speed[i, k], stop, reaction, a_stop, static, near_d, v_near, v_far, a_h, lead)
    return alpha * robot_speed[i, k] <= max(lim - margin, 0.0)


@numba.njit(cache=True)
def speed_alpha_bound(dist, robot_speed, human_speed, limit, fraction, stop_full, stop_min, reaction, a_stop,
                      static, near_d, v_near, v_far, a_h, lead, margin):
    """The largest alpha in [0, 1] at which every pair that approaches keeps alpha robot_speed within its limit
    less `margin`, the limit taken at the stopping time of that alpha: max(stop_min, stop_full alpha fraction),
    fraction the fastest joint's share of its velocity limit at alpha = 1 (pairs: dist, robot_speed, human_speed
    from ``_pair_ssm_kernel`` at alpha = 1, limit its limit at stop_full). The limit falls as alpha rises, so the
    alphas allowed are [0, bound]: the one-T_s bound at the longest stopping time those alphas can have is
    allowed, then bisection up to 1 (the allowed end returned). With stop_min = stop_full, the one-T_s bound.

    The bisection's points are the 2^BISECTIONS steps from that one-T_s bound to 1, each the float that halving
    [low, 1] again and again computes, and the bound is the highest of them every pair allows. Each pair allows the
    points up to its own highest, so the pairs are asked in turn, the ones with the lowest one-T_s bound first (they
    most often decide): a pair that allows the highest point found so far is passed after one question; one that does
    not is bisected alone, with the points above that one taken as refused. The same point, to the last bit, as a
    bisection that asks every pair at each of its 14 steps; that took as long as the pairs' kinematics beside a
    person (2-5 us of a sample's 4-7 us in the planning layer's time cost at a table's edge, docs/measurements.md,
    session 85)."""
    low = fixed_stop_alpha_bound(robot_speed, limit - margin)
    if stop_min >= stop_full or low >= 1.0:
        return low
    if fraction > 1.0:                     # beyond the velocity limit T_s grows past stop_full: not below it
        low = min(low, 1.0 / fraction)
    cols = robot_speed.shape[1]
    order = np.empty(robot_speed.size, dtype=np.int64)
    keys = np.empty(robot_speed.size)
    n = 0
    for i in range(robot_speed.shape[0]):
        for k in range(cols):
            if robot_speed[i, k] > NEGLIGIBLE_SPEED:
                order[n], keys[n] = i * cols + k, (limit[i, k] - margin) / robot_speed[i, k]
                n += 1
    order = order[:n][np.argsort(keys[:n])]
    top = 1 << BISECTIONS
    best, best_alpha = top, 1.0            # the highest point every pair asked so far allows: its index, its alpha
    for m in range(n):
        if best == 0:                      # low: every pair allows it
            break
        i, k = order[m] // cols, order[m] % cols
        if _pair_allows(best_alpha, i, k, dist, robot_speed, human_speed, fraction, stop_full, stop_min, reaction,
                        a_stop, static, near_d, v_near, v_far, a_h, lead, margin):
            continue
        below, below_alpha, above_alpha, step = 0, low, 1.0, top     # down the halving's tree from [low, 1]
        while step > 1:
            step //= 2
            middle, middle_alpha = below + step, 0.5 * (below_alpha + above_alpha)
            if middle < best and _pair_allows(middle_alpha, i, k, dist, robot_speed, human_speed, fraction, stop_full,
                                              stop_min, reaction, a_stop, static, near_d, v_near, v_far, a_h, lead,
                                              margin):
                below, below_alpha = middle, middle_alpha
            else:
                above_alpha = middle_alpha
        best, best_alpha = below, below_alpha
    return best_alpha


@dataclass(slots=True)
class PairSsm:
    """SSM quantities for every robot capsule i and human capsule j, each shaped (L, M).

    distance: surface separation (m). robot_speed: the fastest approach of link i towards capsule j (m/s;
    negative when it moves away). human_speed: the approach speed of capsule j towards link i (m/s, >= 0).
    limit: v_r_max at that separation and human speed (m/s).
    """

    distance: np.ndarray
    robot_speed: np.ndarray
    human_speed: np.ndarray
    limit: np.ndarray

    @property
    def margin(self) -> np.ndarray:
        """How far below its limit each pair is (m/s): max(limit, 0) - robot_speed; negative = violation."""
        return self.margin_at(1.0)

    def margin_at(self, alpha: float) -> np.ndarray:
        """The margin when the robot velocities behind robot_speed are scaled by alpha."""
        return np.maximum(self.limit, 0.0) - alpha * self.robot_speed

    def closest(self, alpha: float) -> tuple[float, float]:
        """(smallest separation, smallest margin at alpha) over all pairs; (inf, inf) with no pairs."""
        return _closest(self.distance, self.limit, self.robot_speed, float(alpha))


@numba.njit(cache=True)
def _closest(distance, limit, robot_speed, alpha):
    sep, margin = np.inf, np.inf
    for i in range(distance.shape[0]):
        for j in range(distance.shape[1]):
            sep = min(sep, distance[i, j])
            margin = min(margin, max(limit[i, j], 0.0) - alpha * robot_speed[i, j])
    return sep, margin


@numba.njit(cache=True)
def approach_within(along, speed, sin_doubt):
    """The largest projection (m/s) of a velocity of magnitude `speed` whose projection on the direction n is
    `along`, on any direction within an angle of n whose sine is `sin_doubt`: how fast a point may approach a person
    whose direction is known only to within that angle. sin_doubt 0: `along` itself.

    A person seen ``human_lead`` s ago has moved since; where they are within the no-approach distance, a robot
    point moving along the old direction's normal (approach 0 to where they were) approached where they are: a
    walker 60 ms late, passing a link the robot moved tangentially, 8.5 mm/s of approach for 0.45 s, 27 violations
    of the monitor's rule (random walk seed 237, T_r 0.11 s; docs/measurements.md, session 79)."""
    if sin_doubt <= 0.0:
        return along
    cos_doubt = np.sqrt(1.0 - sin_doubt * sin_doubt)
    if along >= speed * cos_doubt:              # the velocity itself is within the angle
        return speed
    return along * cos_doubt + np.sqrt(max(0.0, speed * speed - along * along)) * sin_doubt


@numba.njit(cache=True)
def _pair_ssm_kernel(robot_seg, robot_rad, robot_vel, human_seg, human_rad, human_vel, human_known,
                     horizon, fixed, near_d, v_near, v_far, a_h, lead):
    n_l, n_m = robot_seg.shape[0], human_seg.shape[0]
    dist, robot_speed = np.empty((n_l, n_m)), np.empty((n_l, n_m))
    human_speed, limit = np.empty((n_l, n_m)), np.empty((n_l, n_m))
    # each capsule's fastest end-point speed (m/s): a person's where their direction is not defined or has turned
    capsule_speed = np.zeros(n_m)
    for j in range(n_m):
        for e in range(2):
            capsule_speed[j] = max(capsule_speed[j], np.sqrt(human_vel[j, e, 0] ** 2 + human_vel[j, e, 1] ** 2
                                                             + human_vel[j, e, 2] ** 2))
    end_speed = np.empty(2)
    for i in range(n_l):
        p1, q1 = robot_seg[i, 0], robot_seg[i, 1]
        for e in range(2):              # link i's end-point speeds; the fastest for pairs with no defined direction
            end_speed[e] = np.sqrt(robot_vel[i, e, 0] ** 2 + robot_vel[i, e, 1] ** 2 + robot_vel[i, e, 2] ** 2)
        link_speed = max(end_speed[0], end_speed[1])
        for j in range(n_m):
            p2, q2 = human_seg[j, 0], human_seg[j, 1]
            s, t = segment_closest_params(p1, q1, p2, q2)
            nx = p2[0] + t * (q2[0] - p2[0]) - p1[0] - s * (q1[0] - p1[0])
            ny = p2[1] + t * (q2[1] - p2[1]) - p1[1] - s * (q1[1] - p1[1])
            nz = p2[2] + t * (q2[2] - p2[2]) - p1[2] - s * (q1[2] - p1[2])
            centre = np.sqrt(nx * nx + ny * ny + nz * nz)
            d = centre - robot_rad[i] - human_rad[j]
            dist[i, j] = d
            if centre < EPS_NORMAL:
                # axes touch: every direction is "towards" -- take full speeds
                robot_speed[i, j] = link_speed
                hs = capsule_speed[j]
            else:
                nx, ny, nz = nx / centre, ny / centre, nz / centre
                rs = -np.inf
                hs = 0.0
                for e in range(2):
                    hs = max(hs, -(nx * human_vel[j, e, 0] + ny * human_vel[j, e, 1] + nz * human_vel[j, e, 2]))
                # the person seen lead s ago has moved since (at their measured speed, the ISO 13855 speed where
                # unknown): the direction to them now is within an angle of n whose sine is that way / centre
                sin_t = 0.0
                if lead > 0.0:
                    moved = capsule_speed[j] if human_known[j] else v_near
                    sin_t = min(1.0, moved * lead / centre)
                for e in range(2):
                    p = nx * robot_vel[i, e, 0] + ny * robot_vel[i, e, 1] + nz * robot_vel[i, e, 2]
                    rs = max(rs, approach_within(p, end_speed[e], sin_t))
                robot_speed[i, j] = rs
            if not human_known[j]:                 # the ISO speed of the nearest they may be by now
                hs = iso_speed(d - v_near * lead, near_d, v_near, v_far)
            human_speed[i, j] = hs
            limit[i, j] = (d - aged_travel(d, hs, near_d, v_near, v_far, a_h, lead, horizon) - fixed) / horizon
    return dist, robot_speed, human_speed, limit


def pair_ssm(robot_segments: np.ndarray, robot_radii: np.ndarray, robot_velocities: np.ndarray,
             humans: HumanCapsules, params: SsmParameters, stop: float | None = None) -> PairSsm:
    """Separation, approach speeds and the SSM limit for every (robot link, human capsule) pair.

    robot_segments (L, 2, 3) and robot_velocities (L, 2, 3): capsule end points and their velocities.
    The robot's approach speed of a pair is the largest projection of its two end-point velocities on the
    robot -> human direction (a rigid segment's point velocities are affine along it, so the ends bound
    every point), on any direction the person may be in by now where the data is ``human_lead`` s late (their
    way since, at their measured speed, turns the direction by up to asin(way / centre distance):
    ``approach_within``); the human's is the largest projection of its end-point velocities on the opposite
    direction, never below zero, or the ISO 13855 speed where the tracker has no velocity. Where the two
    axes touch, no direction exists and full speeds count as approach. The scaling layer (velocities along
    the planned path), the planning layer's time cost, the simulation's conservative bound and the 3D
    view use this one computation; the independent monitor deliberately does not (shared.safety.monitor: coal
    distances, the actual closest points). stop: the state's T_s (s, ``SsmParameters.stop_of``); default the
    full-speed stopping_time.
    """
    constants = params.kernel_constants if stop is None else params.constants_at(float(stop))
    out = _pair_ssm_kernel(robot_segments, robot_radii, np.ascontiguousarray(robot_velocities), humans.segments,
                           humans.radii, humans.velocities, humans.velocity_known, *constants)
    return PairSsm(*out)
