"""ISO/TS 15066 speed and separation monitoring (SSM), as the safety-aware kinodynamic paper writes it.

Protective separation distance for a robot approaching at v_r and a human approaching at v_h:

    S_p(v_r, v_h) = v_h (T_s + T_r) + v_r (T_s + T_r) + a_max T_s^2 / 2 + C + Z_d + Z_r

and its inverse, the largest robot approach speed allowed at the current separation S:

    v_r_max(S, v_h) = (S - v_h (T_s + T_r) - C - Z_d - Z_r) / (T_s + T_r) - a_max T_s^2 / (2 (T_s + T_r))

(the paper's form; its a_max term lowers the limit, which is conservative compared to the constant
deceleration derivation). A negative limit means the robot may not approach at all; moving away stays
allowed.

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


@numba.njit(cache=True)
def _travel_each(speed, cap, acceleration, horizon):
    out = np.empty(speed.shape[0])
    for k in range(speed.shape[0]):
        out[k] = human_travel(speed[k], cap[k], acceleration, horizon)
    return out


def human_distance(human_speed: np.ndarray, params: SsmParameters, separation: np.ndarray | None = None) -> np.ndarray:
    """The human's part of S_p (m): how far a person now approaching at human_speed (m/s) may come within
    T_r + T_s under the cell's human model (``human_travel``, capped at the ISO 13855 speed for that
    separation; without a separation at the near speed, the larger). Element by element, compiled."""
    cap = params.human_speed_near if separation is None else default_human_speed(separation, params)
    speed, cap = np.broadcast_arrays(np.asarray(human_speed, dtype=float), np.asarray(cap, dtype=float))
    out = _travel_each(np.ascontiguousarray(speed).ravel(), np.ascontiguousarray(cap).ravel(),
                       float(params.human_acceleration), float(params.horizon))
    return out.reshape(speed.shape) if speed.shape else float(out[0])


def default_human_speed(separation: np.ndarray, params: SsmParameters) -> np.ndarray:
    """ISO 13855 approach speed for an untracked human: 2.0 m/s within 0.5 m, 1.6 m/s beyond."""
    return np.where(np.asarray(separation) <= params.human_near_distance,
                    params.human_speed_near, params.human_speed_far)


def protective_separation_distance(robot_speed: np.ndarray, human_speed: np.ndarray,
                                   params: SsmParameters) -> np.ndarray:
    """S_p (m) for a robot approaching at robot_speed and a human at human_speed (m/s, >= 0), the human's
    part under the cell's human model (``human_distance``, capped at the near ISO 13855 speed)."""
    return human_distance(human_speed, params) + np.asarray(robot_speed) * params.horizon + params.fixed_distance


def velocity_limit(separation: np.ndarray, human_speed: np.ndarray, params: SsmParameters) -> np.ndarray:
    """v_r_max (m/s): the largest robot approach speed at this separation; negative means 'do not approach'.
    The human's part is ``human_distance`` (the paper's v_h (T_r + T_s) where human_acceleration is 0)."""
    separation = np.asarray(separation)
    return (separation - human_distance(human_speed, params, separation) - params.fixed_distance) / params.horizon


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
def _pair_ssm_kernel(robot_seg, robot_rad, robot_vel, human_seg, human_rad, human_vel, human_known,
                     horizon, fixed, near_d, v_near, v_far, a_h):
    n_l, n_m = robot_seg.shape[0], human_seg.shape[0]
    dist, robot_speed = np.empty((n_l, n_m)), np.empty((n_l, n_m))
    human_speed, limit = np.empty((n_l, n_m)), np.empty((n_l, n_m))
    for i in range(n_l):
        p1, q1 = robot_seg[i, 0], robot_seg[i, 1]
        # fastest end-point speed of link i (for pairs with no defined direction)
        link_speed = 0.0
        for e in range(2):
            v = np.sqrt(robot_vel[i, e, 0] ** 2 + robot_vel[i, e, 1] ** 2 + robot_vel[i, e, 2] ** 2)
            link_speed = max(link_speed, v)
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
                hs = 0.0
                for e in range(2):
                    hs = max(hs, np.sqrt(human_vel[j, e, 0] ** 2 + human_vel[j, e, 1] ** 2 + human_vel[j, e, 2] ** 2))
            else:
                nx, ny, nz = nx / centre, ny / centre, nz / centre
                rs = -np.inf
                hs = 0.0
                for e in range(2):
                    rs = max(rs, nx * robot_vel[i, e, 0] + ny * robot_vel[i, e, 1] + nz * robot_vel[i, e, 2])
                    hs = max(hs, -(nx * human_vel[j, e, 0] + ny * human_vel[j, e, 1] + nz * human_vel[j, e, 2]))
                robot_speed[i, j] = rs
            cap = v_near if d <= near_d else v_far
            if not human_known[j]:
                hs = cap
            human_speed[i, j] = hs
            limit[i, j] = (d - human_travel(hs, cap, a_h, horizon) - fixed) / horizon
    return dist, robot_speed, human_speed, limit


def pair_ssm(robot_segments: np.ndarray, robot_radii: np.ndarray, robot_velocities: np.ndarray,
             humans: HumanCapsules, params: SsmParameters) -> PairSsm:
    """Separation, approach speeds and the SSM limit for every (robot link, human capsule) pair.

    robot_segments (L, 2, 3) and robot_velocities (L, 2, 3): capsule end points and their velocities.
    The robot's approach speed of a pair is the largest projection of its two end-point velocities on the
    robot -> human direction (a rigid segment's point velocities are affine along it, so the ends bound
    every point); the human's is the largest projection of its end-point velocities on the opposite
    direction, never below zero, or the ISO 13855 speed where the tracker has no velocity. Where the two
    axes touch, no direction exists and full speeds count as approach. The scaling layer (velocities along
    the planned path), the planning layer's time cost, the simulation's conservative bound and the 3D
    view use this one computation; the independent monitor deliberately does not (shared.safety.monitor: coal
    distances, the actual closest points).
    """
    out = _pair_ssm_kernel(robot_segments, robot_radii, np.ascontiguousarray(robot_velocities), humans.segments,
                           humans.radii, humans.velocities, humans.velocity_known, *params.kernel_constants)
    return PairSsm(*out)
