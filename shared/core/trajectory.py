"""Nominal trajectories: q(s) as a cubic Hermite spline over the path parameter s.

The path parameter s is the *nominal time*: the trajectory as planned at the robot's own limits reaches
q(s) at time s. So the nominal path speed is sdot_nominal = 1, the path tangent q'(s) is the nominal joint
velocity, and the scaling layer's alpha is the path speed sdot itself (the paper's time scaling tau).
Parameterising by nominal time instead of arc length keeps a trajectory that starts at rest
followable: with arc length, sdot_nominal(0) = 0 and s would never leave 0.

A trajectory is knots (s_k, q_k, q'_k); between knots the spline is the cubic Hermite interpolant, so
position and velocity are continuous and the samples are the representation: a trajectory message
carries exactly these arrays and decodes to the same q(s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np


@dataclass(frozen=True)
class Trajectory:
    """A versioned nominal trajectory. times (N,), positions (N, 6), velocities (N, 6); SI units."""

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    version: int = 0

    def __post_init__(self) -> None:
        t, q, v = self.times, self.positions, self.velocities
        if t.ndim != 1 or t.shape[0] < 2:
            raise ValueError("a trajectory needs at least two knots")
        if q.shape != (t.shape[0], q.shape[1]) or v.shape != q.shape:
            raise ValueError("positions and velocities must be (N, dof) with N = len(times)")
        if abs(t[0]) > 1e-12 or np.any(np.diff(t) <= 0):
            raise ValueError("knot times must start at 0 and increase strictly")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            raise ValueError("trajectory arrays must be finite")

    @property
    def duration(self) -> float:
        """Nominal duration (s): the end value of the path parameter."""
        return float(self.times[-1])

    @property
    def dof(self) -> int:
        return int(self.positions.shape[1])

    def sample(self, s: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q(s), q'(s), q''(s) at one s (each (dof,)) or at an array of s (each (K, dof)); s is clamped."""
        if isinstance(s, (float, int)):
            return _hermite_one(self.times, self.positions, self.velocities, float(s))
        scalar = np.ndim(s) == 0
        s_arr = np.atleast_1d(np.asarray(s, dtype=np.float64))
        out = np.empty((3, s_arr.size, self.positions.shape[1]))
        _hermite(self.times, self.positions, self.velocities, s_arr, out)
        if scalar:
            return out[0, 0], out[1, 0], out[2, 0]
        return out[0], out[1], out[2]

    def with_version(self, version: int) -> "Trajectory":
        return Trajectory(self.times, self.positions, self.velocities, version)


def trapezoid_profile(distance: float, v_max: float, a_max: float) -> tuple[float, float, float]:
    """Time-optimal rest-to-rest profile along a scalar distance: (duration, cruise speed, accel time)."""
    distance = abs(distance)
    if distance <= 0.0:
        return 0.0, 0.0, 0.0
    t_acc = v_max / a_max
    if a_max * t_acc * t_acc >= distance:           # never reaches v_max: triangle
        t_acc = float(np.sqrt(distance / a_max))
        return 2.0 * t_acc, a_max * t_acc, t_acc
    return distance / v_max + t_acc, v_max, t_acc


def straight_line_trajectory(q_start: np.ndarray, q_goal: np.ndarray, v_max: np.ndarray, a_max: np.ndarray,
                             knot_period: float = 0.01, version: int = 0) -> Trajectory:
    """The fastest rest-to-rest straight joint-space motion with every joint synchronised.

    The path q_start + r (q_goal - q_start), r in [0, 1], gets a trapezoidal speed law in r whose limits
    are the tightest joint's: rdot <= min_j v_max_j / |dq_j|, rddot <= min_j a_max_j / |dq_j|. Knots every
    knot_period seconds and at the two switch times carry the exact position and velocity of that law.
    """
    q_start = np.asarray(q_start, dtype=float)
    delta = np.asarray(q_goal, dtype=float) - q_start
    span = np.abs(delta)
    if not np.any(span > 0):
        return Trajectory(np.array([0.0, knot_period]), np.vstack([q_start, q_start]),
                          np.zeros((2, q_start.size)), version)
    moving = span > 0
    r_vmax = float(np.min(np.asarray(v_max)[moving] / span[moving]))
    r_amax = float(np.min(np.asarray(a_max)[moving] / span[moving]))
    duration, r_cruise, t_acc = trapezoid_profile(1.0, r_vmax, r_amax)
    n = max(2, int(np.ceil(duration / knot_period)) + 1)
    t_dec = duration - t_acc
    # knots at the switches too: between knots the law is then a polynomial of degree <= 2, which the
    # cubic Hermite interpolant reproduces exactly (no acceleration overshoot at the switches)
    t = np.unique(np.concatenate([np.linspace(0.0, duration, n), [t_acc, t_dec]]))
    t = t[np.concatenate([[True], np.diff(t) > 1e-9])]
    r = np.where(t < t_acc, 0.5 * r_amax * t ** 2,
                 np.where(t <= t_dec, 0.5 * r_amax * t_acc ** 2 + r_cruise * (t - t_acc),
                          1.0 - 0.5 * r_amax * (duration - t) ** 2))
    rdot = np.where(t < t_acc, r_amax * t, np.where(t <= t_dec, r_cruise, r_amax * (duration - t)))
    return Trajectory(t, q_start + r[:, None] * delta, rdot[:, None] * delta, version)


def polyline_trajectory(waypoints: np.ndarray, v_max: np.ndarray, a_max: np.ndarray, knot_period: float = 0.01,
                        version: int = 0) -> Trajectory:
    """Rest to rest along every straight segment of a waypoint path in turn: the exact polyline (no
    smoothing leaves it, so a path whose segments were checked free stays free), slower than a smoothed
    path by a stop at every corner."""
    w = np.asarray(waypoints, dtype=float)
    times, positions, velocities = [np.zeros(1)], [w[:1]], [np.zeros((1, w.shape[1]))]
    offset = 0.0
    for a, b in zip(w[:-1], w[1:]):
        if not np.any(np.abs(b - a) > 0):
            continue
        leg = straight_line_trajectory(a, b, v_max, a_max, knot_period)
        times.append(offset + leg.times[1:])
        positions.append(leg.positions[1:])
        velocities.append(leg.velocities[1:])
        offset += leg.duration
    if offset == 0.0:
        return straight_line_trajectory(w[0], w[0], v_max, a_max, knot_period, version)
    return Trajectory(np.concatenate(times), np.vstack(positions), np.vstack(velocities), version)


@numba.njit(cache=True)
def _hermite(times, positions, velocities, s_values, out):
    """Cubic Hermite value, first and second derivative at each s (clamped to the knot range)."""
    n = times.shape[0]
    for i in range(s_values.shape[0]):
        s = min(max(s_values[i], times[0]), times[n - 1])
        k = min(max(np.searchsorted(times, s, side="right") - 1, 0), n - 2)
        h = times[k + 1] - times[k]
        u = (s - times[k]) / h
        u2 = u * u
        u3 = u2 * u
        for j in range(positions.shape[1]):
            q0, q1 = positions[k, j], positions[k + 1, j]
            m0, m1 = velocities[k, j] * h, velocities[k + 1, j] * h
            out[0, i, j] = (2 * u3 - 3 * u2 + 1) * q0 + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * q1 + (u3 - u2) * m1
            out[1, i, j] = ((6 * u2 - 6 * u) * q0 + (3 * u2 - 4 * u + 1) * m0 + (-6 * u2 + 6 * u) * q1
                            + (3 * u2 - 2 * u) * m1) / h
            out[2, i, j] = ((12 * u - 6) * q0 + (6 * u - 4) * m0 + (-12 * u + 6) * q1 + (6 * u - 2) * m1) / (h * h)


@numba.njit(cache=True)
def _hermite_one(times, positions, velocities, s):
    """The same as _hermite at a single s: (q, q', q'') as three (dof,) arrays."""
    out = np.empty((3, 1, positions.shape[1]))
    _hermite(times, positions, velocities, np.array([s]), out)
    return out[0, 0], out[1, 0], out[2, 0]
