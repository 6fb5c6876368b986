"""The fastest path speed along a geometric path under joint velocity and acceleration limits: TOPP-RA
(Pham & Pham, "A New Approach to Time-Optimal Path Parameterization Based on Reachability Analysis",
IEEE T-RO 2018), compiled for exactly the constraints this project has.

Why not toppra's own: toppra solves the same problem with a Python loop over its grid points, a linear
program per point and pass; a planning action that takes a plan times up to nine laws (three smoothings,
each up to three acceleration headrooms), and those laws were most of what a replan did besides its searches
(docs/measurements.md). This kernel is the same algorithm over the same discretisation (toppra's
"interpolation" scheme, its forward-pass tolerances), compiled; tests hold it against toppra on random paths
and start speeds. The path itself (a cubic spline) is
still toppra's SplineInterpolator.

The problem, per grid point s_i (i = 0..N), in the squared path speed x = s'^2 and the path acceleration
u = s'' (constant between grid points, so x_{i+1} = x_i + 2 (s_{i+1} - s_i) u_i):
- velocity: |q'_j(s_i)| sqrt(x_i) <= v_j, i.e. 0 <= x_i <= min_j (v_j / |q'_j(s_i)|)^2;
- acceleration: |q'_j(s) u + q''_j(s) x| <= a_j, at s_i and, with u_i and x_{i+1} written in u_i and x_i,
  at s_{i+1} ("interpolation": the constraint holds at both ends of each interval).
The backward pass finds the controllable sets K_i (the x_i from which the end speed is reachable); the
forward pass takes, from the start speed, the largest u_i that stays inside K_{i+1}.
"""

from __future__ import annotations

import numba
import numpy as np

TINY = 1e-8          # toppra's: x_{i+1} is taken this much below the forward step's optimum (rounding)
SMALL = 1e-5         # toppra's: a start x this far outside K_0 still counts as inside it
RETRIES = 10         # toppra's: a forward step that fails by rounding is retried from 0.1 % slower, this often
FEASIBLE = 1e-9      # slack of a stage's rows in the kernel's own comparisons (u in path units / s^2)


@numba.njit(cache=True)
def _stage_rows(i, dq, ddq, delta, acceleration, k_lo, k_hi, x_hi, rows):
    """The rows alpha u + beta x <= gamma of stage i (< N) into rows (R, 3); returns their number R."""
    d = delta[i]
    r = 0
    for j in range(dq.shape[1]):
        for side in (1.0, -1.0):
            rows[r, 0], rows[r, 1], rows[r, 2] = side * dq[i, j], side * ddq[i, j], acceleration[j]
            rows[r + 1, 0] = side * (dq[i + 1, j] + 2.0 * d * ddq[i + 1, j])    # at s_{i+1}, in u_i and x_i
            rows[r + 1, 1], rows[r + 1, 2] = side * ddq[i + 1, j], acceleration[j]
            r += 2
    rows[r, 0], rows[r, 1], rows[r, 2] = 2.0 * d, 1.0, k_hi                 # x + 2 delta u within K_{i+1}
    rows[r + 1, 0], rows[r + 1, 1], rows[r + 1, 2] = -2.0 * d, -1.0, -k_lo
    rows[r + 2, 0], rows[r + 2, 1], rows[r + 2, 2] = 0.0, 1.0, x_hi          # the velocity limits
    rows[r + 3, 0], rows[r + 3, 1], rows[r + 3, 2] = 0.0, -1.0, 0.0
    return r + 4


@numba.njit(cache=True)
def _u_range(rows, count, x):
    """The interval of u that rows allow at x: (lowest, highest); lowest > highest where none does."""
    lo, hi = -np.inf, np.inf
    for r in range(count):
        a, b, g = rows[r, 0], rows[r, 1], rows[r, 2]
        rest = g - b * x
        if a > FEASIBLE:
            hi = min(hi, rest / a)
        elif a < -FEASIBLE:
            lo = max(lo, rest / a)
        elif rest < -FEASIBLE:
            return np.inf, -np.inf
    return lo, hi


@numba.njit(cache=True)
def _x_extremes(rows, count):
    """The least and the largest x for which some u satisfies all rows (a two-variable linear program:
    the optimum is where the u-interval closes, the meeting of a lower and an upper row, or an x bound).
    (nan, nan) where no x does."""
    x_lo, x_hi = -np.inf, np.inf
    for r in range(count):
        if abs(rows[r, 0]) <= FEASIBLE and abs(rows[r, 1]) > 0.0:
            bound = rows[r, 2] / rows[r, 1]
            if rows[r, 1] > 0.0:
                x_hi = min(x_hi, bound)
            else:
                x_lo = max(x_lo, bound)
    best_lo, best_hi = np.inf, -np.inf
    for x in (x_lo, x_hi):
        lo, hi = _u_range(rows, count, x)
        if lo <= hi + FEASIBLE:
            best_lo, best_hi = min(best_lo, x), max(best_hi, x)
    for p in range(count):                       # where a lower row meets an upper one
        ap, bp, gp = rows[p, 0], rows[p, 1], rows[p, 2]
        if ap >= -FEASIBLE:
            continue
        for q in range(count):
            aq, bq, gq = rows[q, 0], rows[q, 1], rows[q, 2]
            if aq <= FEASIBLE:
                continue
            # (gp - bp x) / ap = (gq - bq x) / aq
            den = bp * aq - bq * ap
            if abs(den) < 1e-15:
                continue
            x = (gp * aq - gq * ap) / den
            if x < x_lo - FEASIBLE or x > x_hi + FEASIBLE or (best_lo <= x <= best_hi):
                continue
            lo, hi = _u_range(rows, count, x)
            if lo <= hi + FEASIBLE:
                best_lo, best_hi = min(best_lo, x), max(best_hi, x)
    if best_lo > best_hi:
        return np.nan, np.nan
    return max(best_lo, x_lo), min(best_hi, x_hi)


@numba.njit(cache=True)
def _speeds(dq, ddq, gridpoints, velocity, acceleration, x_start, x_end):
    """Squared path speeds x_i at the grid points of the fastest law from x_start to x_end; all nan where
    the start is not controllable or a pass fails."""
    n, dof = dq.shape[0] - 1, dq.shape[1]
    delta = gridpoints[1:] - gridpoints[:-1]
    x_max = np.empty(n + 1)
    for i in range(n + 1):
        m = np.inf
        for j in range(dof):
            if abs(dq[i, j]) > 1e-12:
                m = min(m, (velocity[j] / abs(dq[i, j])) ** 2)
        x_max[i] = m
    rows = np.empty((4 * dof + 4, 3))
    k = np.empty((n + 1, 2))
    xs = np.full(n + 1, np.nan)
    k[n, 0], k[n, 1] = x_end, x_end
    for i in range(n - 1, -1, -1):               # backward: the controllable sets
        count = _stage_rows(i, dq, ddq, delta, acceleration, k[i + 1, 0], k[i + 1, 1], x_max[i], rows)
        lo, hi = _x_extremes(rows, count)
        if np.isnan(lo):
            return xs
        k[i, 0], k[i, 1] = max(lo, 0.0), hi
    if x_start + SMALL < k[0, 0] or k[0, 1] + SMALL < x_start:
        return xs
    xs[0] = min(max(x_start, k[0, 0]), k[0, 1])
    tries = 0
    i = 0
    while i < n:                                  # forward: the fastest controllable step
        count = _stage_rows(i, dq, ddq, delta, acceleration, k[i + 1, 0], k[i + 1, 1], x_max[i], rows)
        lo, hi = _u_range(rows, count, xs[i])
        if lo > hi + FEASIBLE:
            if tries >= RETRIES:
                xs[:] = np.nan
                return xs
            xs[i] = max(xs[i] - TINY, 0.999 * xs[i])
            tries += 1
            continue
        tries = 0
        x_next = xs[i] + 2.0 * delta[i] * hi
        x_next = max(x_next - TINY, 0.9999 * x_next)
        xs[i + 1] = min(k[i + 1, 1], max(k[i + 1, 0], x_next))
        i += 1
    return xs


class TimeLaw:
    """s(t) of a law with constant path acceleration between grid points (toppra's ParametrizeConstAccel):
    the grid points' times, speeds and accelerations; sampled in s and s' at any times."""

    def __init__(self, gridpoints: np.ndarray, speeds: np.ndarray) -> None:
        self.s = np.asarray(gridpoints, dtype=float)
        self.speed = np.asarray(speeds, dtype=float)
        delta = np.diff(self.s)
        self.acceleration = 0.5 * np.diff(self.speed ** 2) / delta
        with np.errstate(divide="ignore"):            # at rest at two grid points in a row: never gets on
            self.times = np.concatenate([[0.0], np.cumsum(2.0 * delta / (self.speed[:-1] + self.speed[1:]))])

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Path position s (path units) and speed s' at times t (s); held at the ends outside [0, duration]."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        k = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.acceleration) - 1)
        dt = t - self.times[k]
        return (self.s[k] + dt * self.speed[k] + 0.5 * dt ** 2 * self.acceleration[k],
                self.speed[k] + dt * self.acceleration[k])


def fastest_law(path, gridpoints: np.ndarray, velocity: np.ndarray, acceleration: np.ndarray,
                start_speed: float, end_speed: float = 0.0) -> TimeLaw | None:
    """The time-optimal law along path (callable path(s, order) -> (M, dof), e.g. toppra's
    SplineInterpolator) at gridpoints, from path speed start_speed to end_speed, within |q'| <= velocity
    (rad/s) and |q''| <= acceleration (rad/s^2) per joint. None where no law reaches the end."""
    gridpoints = np.asarray(gridpoints, dtype=float)
    xs = _speeds(np.ascontiguousarray(path(gridpoints, 1)), np.ascontiguousarray(path(gridpoints, 2)), gridpoints,
                 np.asarray(velocity, dtype=float), np.asarray(acceleration, dtype=float),
                 float(start_speed) ** 2, float(end_speed) ** 2)
    if np.isnan(xs).any():
        return None
    law = TimeLaw(gridpoints, np.sqrt(np.maximum(xs, 0.0)))
    return law if np.isfinite(law.duration) else None          # two grid points at rest in a row: stuck


def toppra_law(path, gridpoints: np.ndarray, velocity: np.ndarray, acceleration: np.ndarray,
               start_speed: float, end_speed: float = 0.0):
    """toppra's own TOPP-RA on the same problem, the reference this kernel is held against (tests/planning/test_topp.py,
    bench/planning.py): toppra's trajectory (callable at times t, order 0 / 1; .duration), or None."""
    import toppra.algorithm
    import toppra.constraint
    velocity, acceleration = np.asarray(velocity, dtype=float), np.asarray(acceleration, dtype=float)
    constraints = [toppra.constraint.JointVelocityConstraint(np.stack([-velocity, velocity], axis=1)),
                   toppra.constraint.JointAccelerationConstraint(np.stack([-acceleration, acceleration], axis=1))]
    return toppra.algorithm.TOPPRA(constraints, path, gridpoints=np.asarray(gridpoints, dtype=float),
                                   parametrizer="ParametrizeConstAccel").compute_trajectory(start_speed, end_speed)
