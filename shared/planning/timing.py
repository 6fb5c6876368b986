"""Time parameterisation at the robot's own limits: the nominal, fastest trajectory along a path.

The waypoints of a planned path are joined by a cubic spline over chord length (toppra's
SplineInterpolator, i.e. scipy's CubicSpline); TOPP-RA (``shared.planning.topp``, compiled: toppra's
algorithm and discretisation, 20 times faster) finds the fastest path speed under the joint velocity and
acceleration limits; the result is sampled every knot_period into the project's
Trajectory (knots of position and velocity in nominal time).

Continuing a motion: with start_velocity v0 the spline's first derivative is clamped to v0's direction
and the law starts at path speed |v0| (a hair less where v0 is on a joint's limit: START_WITHIN), so the
trajectory begins with the velocity v0 (a merged trajectory continues without a jump).

How tightly the spline follows the polyline: the polyline is densified first (segments of at most
max_segment rad), and the denser, the tighter its corners and the slower the law through them. A corner
turned within a quarter radian is turned at a crawl: on the detours the planner chose in two-person
scenarios the law took 7 % longer than the polyline's own estimate (straight segments at full speed, a
joint's velocity change at each corner), up to 21 %. So the smoothings of ``SMOOTHINGS`` are tried in
order, the loosest first (the waypoints alone), and the first law that stays inside the joint position
limits (checked at its 10 ms knots; a spline can overshoot a waypoint), within
the acceleration tolerance and, when a collision model is given, free of the scene and the people
(the sampled trajectory's knots checked as one path with the guaranteed motion check) is the result: on
the same detours 2.6 % *shorter* than that estimate (the spline cuts the corners).
"""

from __future__ import annotations

import numpy as np
import toppra

from shared.core.errors import HrcError
from shared.core.humans import HumanCapsules
from shared.core.trajectory import Trajectory
from shared.planning.collision import CollisionModel
from shared.planning.topp import fastest_law
from shared.robot.model import JointLimits

# TOPP-RA enforces the limits at its grid points only; between them, where the path bends, the joint
# acceleration of its piecewise-constant-acceleration law can exceed the limit by a few percent (not monotone
# in the grid size; docs/measurements.md). 10 % of the acceleration limit
# is kept in hand, so the nominal trajectory stays within the limit to a few percent (the tests allow 10 %;
# the PRBT's controller tolerates 6.0 rad/s^2 against the 3.49 planned). Velocity is exact: a merged
# trajectory may have to start at the full 1.57 rad/s.
VELOCITY_HEADROOM = 1.0
VELOCITY_TOLERANCE = 1.01     # the same grid effect on velocity; the scaling layer's hard joint-velocity
ACCELERATION_HEADROOM = 0.9   # rows keep the *commanded* velocity within the limit in any case
# Rarely the effect is larger (1.42 x the limit once in 150 RRT-Connect detours): the sampled trajectory
# is checked against this tolerance and re-timed with proportionally more headroom when it exceeds it.
ACCELERATION_TOLERANCE = 1.10
# A law that continues a motion starts at the path speed of the given velocity, but at most at this fraction
# of what the joint velocity limits allow there: the old trajectory's own velocity is on the limit at its
# peaks (and up to VELOCITY_TOLERANCE over it), where TOPP-RA's first velocity row has no room left and, by
# rounding, no law exists. Merges through such junctions failed at every smoothing: 6 of the 8 failed
# merge laws (continuous or the stop of a stop-and-go) in 4 seeded scenarios, starting at 1.000000-1.000010 x the limit.
START_WITHIN = 1.0 - 1e-5
# max_segment (rad) of the smoothings tried in turn, loosest first (see the module docstring)
SMOOTHINGS = (np.inf, 0.5, 0.25)


class TimingError(HrcError):
    """No feasible time parameterisation (e.g. the start velocity cannot be followed along the path)."""


def densify(waypoints: np.ndarray, max_segment: float) -> np.ndarray:
    """Insert points so that no straight segment is longer than max_segment (inf-norm, rad)."""
    out = [waypoints[0]]
    for a, b in zip(waypoints[:-1], waypoints[1:]):
        n = max(1, int(np.ceil(np.max(np.abs(b - a)) / max_segment)))
        out.extend(a + (b - a) * (k / n) for k in range(1, n + 1))
    return np.array(out)


def parameterize(waypoints: np.ndarray, limits: JointLimits, start_velocity: np.ndarray | None = None,
                 knot_period: float = 0.01, max_segment: float | None = None, grid: int = 200,
                 collision: CollisionModel | None = None, humans: HumanCapsules | None = None,
                 inflation: float = 0.0, version: int = 0) -> Trajectory:
    """The fastest trajectory through waypoints (K, 6) that starts with start_velocity (rest if None)
    and ends at rest, within the position, velocity and acceleration limits: the smoothings of SMOOTHINGS
    in turn (max_segment: that one only), the first that is feasible and, with a collision model, free.
    Raises TimingError, with every smoothing's reason, if none is (or the inputs are not finite)."""
    if not np.all(np.isfinite(waypoints)):
        raise TimingError("the waypoints are not all finite")
    if start_velocity is not None and not np.all(np.isfinite(start_velocity)):
        raise TimingError("the start velocity is not finite")
    errors = []
    for segment in SMOOTHINGS if max_segment is None else (max_segment,):
        try:
            return _smoothed(waypoints, limits, start_velocity, knot_period, segment, grid, collision, humans,
                             inflation, version)
        except TimingError as exc:
            errors.append(f"max_segment {segment}: {exc}")
    if len(errors) == 1:
        raise TimingError(errors[0].split(": ", 1)[1])
    raise TimingError("; ".join(errors))


def _smoothed(waypoints: np.ndarray, limits: JointLimits, start_velocity: np.ndarray | None, knot_period: float,
              max_segment: float, grid: int, collision: CollisionModel | None, humans: HumanCapsules | None,
              inflation: float, version: int) -> Trajectory:
    """parameterize with one smoothing (the polyline densified to max_segment rad)."""
    pts, chord = chord_points(waypoints, max_segment)
    v0 = np.zeros(pts.shape[1]) if start_velocity is None else np.asarray(start_velocity, dtype=float)
    speed0 = float(np.linalg.norm(v0))
    if len(pts) < 2:
        if speed0 > 1e-9:
            raise TimingError("a moving start cannot stop in zero distance")
        return Trajectory(np.array([0.0, knot_period]), np.vstack([pts[0], pts[0]]), np.zeros((2, pts.shape[1])),
                          version)
    d_start = v0 / speed0 if speed0 > 1e-9 else (pts[1] - pts[0]) / chord[1]
    over = float(np.max(np.abs(v0) / limits.velocity))
    if over > VELOCITY_TOLERANCE:
        raise TimingError(f"the start velocity is {over:.3f} x a joint velocity limit")
    speed0 *= min(1.0, START_WITHIN / over) if over > 0.0 else 1.0
    path = chord_spline(pts, chord, d_start)
    # the spline's geometry is the law's: where it leaves the joint ranges no law can help (checked here,
    # before the law, at a fraction of a law's cost; the law's own knots are checked again below)
    if not _within(path(np.linspace(0.0, chord[-1], grid + 1)), limits):
        raise TimingError("the smoothed path leaves the joint position limits")
    headroom = ACCELERATION_HEADROOM
    for _ in range(3):
        traj = _timed(path, chord, pts, v0, speed0, limits, headroom, knot_period, grid, version)
        peak = _peak_acceleration(traj, limits)
        if peak <= ACCELERATION_TOLERANCE:
            break
        headroom *= 0.95 * ACCELERATION_TOLERANCE / peak
    else:
        raise TimingError(f"the law exceeds the joint acceleration limit {peak:.2f}-fold")
    if not _within(traj.positions, limits):
        raise TimingError("the smoothed path leaves the joint position limits")
    if collision is not None and not collision.path_free(traj.positions, humans, inflation):
        raise TimingError("the smoothed path is not collision-free")
    return traj


def chord_points(waypoints: np.ndarray, max_segment: float) -> tuple[np.ndarray, np.ndarray]:
    """The waypoints (K, 6) densified to max_segment rad, repeated points dropped, and their chord length
    (the path parameter, rad): (points (M, 6), chord (M,))."""
    pts = densify(np.asarray(waypoints, dtype=float), max_segment)
    chord = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    keep = np.concatenate([[True], np.diff(chord) > 1e-9])
    return pts[keep], chord[keep]


def chord_spline(pts: np.ndarray, chord: np.ndarray, d_start: np.ndarray) -> toppra.SplineInterpolator:
    """The cubic spline through pts (M >= 2) over chord length: its first derivative d_start (unit) at the
    start, the last segment's direction at the end; callable as path(s, order) (toppra's interpolator)."""
    d_end = (pts[-1] - pts[-2]) / (chord[-1] - chord[-2])
    return toppra.SplineInterpolator(chord, pts, bc_type=((1, d_start), (1, d_end)))


def _within(positions: np.ndarray, limits: JointLimits) -> bool:
    """Every configuration (N, 6) inside the joint position limits (to 1e-6 rad)."""
    return bool(np.all(positions >= limits.lower - 1e-6) and np.all(positions <= limits.upper + 1e-6))


def _peak_acceleration(traj: Trajectory, limits: JointLimits) -> float:
    """The largest |q''| / a_max of the trajectory: q'' of a cubic Hermite interval is linear, so its
    extremes are at the two ends of every interval."""
    inside = 1e-9
    s = np.concatenate([traj.times[:-1] + inside, traj.times[1:] - inside])
    return float(np.max(np.abs(traj.sample(s)[2]) / limits.acceleration))


def _timed(path, chord: np.ndarray, pts: np.ndarray, v0: np.ndarray, speed0: float, limits: JointLimits,
           headroom: float, knot_period: float, grid: int, version: int) -> Trajectory:
    """TOPP-RA's fastest law along the spline with the acceleration limits times headroom, sampled."""
    law = fastest_law(path, np.linspace(0.0, chord[-1], grid + 1), limits.velocity * VELOCITY_HEADROOM,
                      limits.acceleration * headroom, speed0)
    if law is None:
        raise TimingError(f"no time law reaches the end from path speed {speed0:.3f}")
    n = max(2, int(np.ceil(law.duration / knot_period)) + 1)
    t = np.linspace(0.0, law.duration, n)
    s, speed = law.at(t)
    q, qd = path(s), path(s, 1) * speed[:, None]
    q[0], q[-1] = pts[0], pts[-1]
    qd[0], qd[-1] = v0, 0.0
    if np.any(np.abs(qd) > limits.velocity * VELOCITY_TOLERANCE):
        raise TimingError("the sampled trajectory exceeds a joint velocity limit")
    return Trajectory(t, q, qd, version)
