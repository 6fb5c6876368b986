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

import math
from dataclasses import dataclass, fields

import numba
import numpy as np

from shared.core.errors import ConfigError
from shared.core.geometry import EPS_NORMAL, segment_closest_params
from shared.core.humans import HumanCapsules


@dataclass(frozen=True)
class SsmParameters:
    """The SSM parameter set. Defaults and where they come from:

    reaction_time T_r = 0.10 s: the system's reaction latency bound: tracker latency and velocity filter
      (a few 240 Hz samples), one control period (10 ms), one drive interpolation period (10 ms), the CAN
      and Zenoh hops (sub-millisecond, measured by bench/), with margin. Must stay >= the measured p99 of
      human-sample-to-target-frame latency; the end-to-end benchmark checks this.
    stopping_time T_s = 0.30 s: Pilz publishes no stopping data. A Cartesian stop from the PRBT's 1 m/s
      speed limit at its 5 m/s^2 deceleration limit takes 0.20 s (also the controller's Stop-1 trajectory
      duration, stop_trajectory_duration = 0.2 s); a joint stop from 1.57 rad/s at the 6 rad/s^2 the
      controller tolerates takes 0.26 s. The larger, rounded up, so the drives can really stop within it.
    stopping_deceleration a_max = 5.0 m/s^2: the PRBT's Cartesian deceleration limit (cartesian_limits.yaml).
    intrusion_distance C = 0.0 m: the human is modelled by capsules that enclose the tracked segments,
      hands included, so nothing reaches past the modelled body (ISO 13855's C is for presence sensors
      that see only part of the body; set it per ISO 13855 when the body model is partial).
    human_uncertainty Z_d = 0.05 m: motion-capture position error (millimetres) plus marker/skin and
      capsule-fitting error, the value used in the SSM literature for marker-based tracking.
    robot_uncertainty Z_r = 0.02 m: encoder error is negligible (0.001 deg per count); this covers the drive
      following error over one 10 ms interpolation period at the PRBT's link speeds.
    min_separation d_min = 0.05 m: the separation the independent monitor and the planner require at all
      times, also when the robot stands still.
    human_speed_near = 2.0 m/s within human_near_distance = 0.5 m, human_speed_far = 1.6 m/s beyond: the
      approach speeds of ISO 13855, used where the tracker gives no velocity.
    drive_lag = 0.012 s: how far the measured joints run behind the driver's setpoints. An interpolated
      position drive whose setpoints are followable (the driver sends no others) reaches each one at the
      next SYNC, one 10 ms period behind; 20 % on top covers the count quantisation of the measurement.
      The robot driver measures the real lag and warns when its p99 exceeds this value.
    link_acceleration = 4.4 m/s^2: how fast a link point's speed can change, the drives' 6 rad/s^2 at the
      arm's 0.741 m reach.
    tracking_margin (derived, m/s) = drive_lag x link_acceleration = 0.053 m/s: while the joints run
      drive_lag behind, the measured speed differs from the commanded one by at most this much. The
      scaling layer keeps the commanded approach speed this far below the limit, so the *measured* robot
      meets it too (the independent monitor checks measured states).
    """

    reaction_time: float = 0.10
    stopping_time: float = 0.30
    stopping_deceleration: float = 5.0
    intrusion_distance: float = 0.0
    human_uncertainty: float = 0.05
    robot_uncertainty: float = 0.02
    min_separation: float = 0.05
    human_speed_near: float = 2.0
    human_speed_far: float = 1.6
    human_near_distance: float = 0.5
    drive_lag: float = 0.012
    link_acceleration: float = 4.4

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ConfigError(f"ssm.{f.name}: expected a finite number, got {value!r}")
            if value < 0:
                raise ConfigError(f"ssm.{f.name}: must not be negative, got {value!r}")
        if self.reaction_time + self.stopping_time <= 0:
            raise ConfigError("ssm: reaction_time + stopping_time must be positive")
        if self.drive_lag <= 0:
            raise ConfigError(f"ssm.drive_lag: must be positive (the drives cannot follow without lag), "
                              f"got {self.drive_lag!r}")

    @classmethod
    def from_mapping(cls, raw: object) -> "SsmParameters":
        """Build from a config mapping; unknown keys and bad values raise ConfigError naming the key."""
        if raw is None:
            return cls()
        if not isinstance(raw, dict):
            raise ConfigError(f"ssm: expected a mapping, got {type(raw).__name__}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(map(str, raw)) - known)
        if unknown:
            raise ConfigError(f"ssm: unknown key(s) {unknown}; known: {sorted(known)}")
        return cls(**raw)

    @property
    def tracking_margin(self) -> float:
        """m/s kept between the commanded approach speed and the limit: drive_lag x link_acceleration."""
        return self.drive_lag * self.link_acceleration

    @property
    def horizon(self) -> float:
        """T_s + T_r (s): how long the human keeps approaching before the robot has stopped."""
        return self.reaction_time + self.stopping_time

    @property
    def fixed_distance(self) -> float:
        """The distance terms that do not depend on speed: a_max T_s^2 / 2 + C + Z_d + Z_r (m)."""
        return (0.5 * self.stopping_deceleration * self.stopping_time ** 2 + self.intrusion_distance
                + self.human_uncertainty + self.robot_uncertainty)


def default_human_speed(separation: np.ndarray, params: SsmParameters) -> np.ndarray:
    """ISO 13855 approach speed for an untracked human: 2.0 m/s within 0.5 m, 1.6 m/s beyond."""
    return np.where(np.asarray(separation) <= params.human_near_distance,
                    params.human_speed_near, params.human_speed_far)


def protective_separation_distance(robot_speed: np.ndarray, human_speed: np.ndarray,
                                   params: SsmParameters) -> np.ndarray:
    """S_p (m) for a robot approaching at robot_speed and a human at human_speed (m/s, >= 0)."""
    return (np.asarray(human_speed) + np.asarray(robot_speed)) * params.horizon + params.fixed_distance


def velocity_limit(separation: np.ndarray, human_speed: np.ndarray, params: SsmParameters) -> np.ndarray:
    """v_r_max (m/s): the largest robot approach speed at this separation; negative means 'do not approach'."""
    return (np.asarray(separation) - np.asarray(human_speed) * params.horizon - params.fixed_distance) / params.horizon


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
                     horizon, fixed, near_d, v_near, v_far):
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
            if not human_known[j]:
                hs = v_near if d <= near_d else v_far
            human_speed[i, j] = hs
            limit[i, j] = (d - hs * horizon - fixed) / horizon
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
                           humans.radii, humans.velocities, humans.velocity_known, params.horizon,
                           params.fixed_distance, params.human_near_distance, params.human_speed_near,
                           params.human_speed_far)
    return PairSsm(*out)
