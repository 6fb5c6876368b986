"""The independent safety monitor's check (pure): ISO/TS 15066 SSM on a measured robot state.

Independent of the scaling layer on purpose: distances and witness points come from coal (not the
project's compiled kernels), point velocities from pinocchio (frame Jacobians; frame velocities in the
batch), not the compiled chain, and the robot's approach speed is taken at its actual closest point to
each human capsule, as the standard states it (the scaling layer bounds it by the worst end point of the
link, a stronger condition). Only the ISO formula itself (shared.safety.ssm.velocity_limit) is common: it
is the standard.

For every robot link i and human capsule j: separation d_ij (coal), unit direction n_ij from the robot's
closest point to the human's, the robot point's velocity v_r = J_i(q, p) qd, the human point's velocity
interpolated between the capsule's end points, human approach speed max(0, -n . v_h) (or the ISO 13855
speed when untracked). An exceedance: n . v_r > max(v_r_max(d, v_h), 0) + tolerance, or d < d_min while
the robot's point still approaches (n . v_r > tolerance; a person who walks into a robot that has
stopped, or that is moving away, is not the robot's approach: SSM governs the robot's motion). ``ReactionWindow`` then counts
a speed exceedance as a violation only when the robot does not react and brake as the formula assumes
(within T_r, then to a stop within T_s). Where the capsules overlap, coal's witness points lie inside the
other shape, so the direction between them is flipped back to point from the robot towards the human;
only where the two points coincide (no direction at all) does any motion of the robot's point count as
approaching.

``SafetyMonitor.check_batch`` is the same rule for many states at once, as the monitor service runs it so
that it never falls behind: pinocchio for each state's link frames and their velocities, then one compiled
closest-point computation over every (state, link, human capsule) (Ericson's segment-segment closest
points, the monitor's own, not the scaling layer's kernel). ``check`` (coal, one state) is the reference it
is tested against.
"""

from __future__ import annotations

from bisect import bisect_right
from collections import deque
from dataclasses import dataclass, field
from typing import NamedTuple

import coal
import numba
import numpy as np
import pinocchio as pin

from shared.core.humans import HumanCapsules
from shared.robot.model import RobotModel
from shared.safety.parameters import SsmParameters
from shared.safety.ssm import default_human_speed, velocity_limit
from shared.tracking.tracker import OLDEST_SAMPLE


def _capsule_placement(a: np.ndarray, b: np.ndarray) -> tuple[pin.SE3, float]:
    """The frame of a coal capsule (centre, z along the axis) for segment a-b, and its length."""
    axis = b - a
    length = float(np.linalg.norm(axis))
    z = axis / length if length > 1e-12 else np.array([0.0, 0.0, 1.0])
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return pin.SE3(np.column_stack([x, np.cross(z, x), z]), (a + b) / 2), length


@dataclass
class Violation:
    link: str
    capsule: int
    kind: str                 # 'speed' or 'separation'
    separation: float
    approach_speed: float
    limit: float


@dataclass
class MonitorResult:
    min_separation: float = np.inf
    min_margin: float = np.inf          # min over pairs of max(limit, 0) - approach speed (m/s)
    approach_speed: float = 0.0         # the robot's approach speed (m/s) at the pair of min_margin ...
    limit: float = np.inf               # ... and its ISO/TS 15066 limit there (m/s)
    violations: list[Violation] = field(default_factory=list)
    stop: float = np.nan                # the state's T_s (s), at which its limits were taken (NaN: not checked)


class SafetyMonitor:
    def __init__(self, robot: RobotModel, ssm: SsmParameters, tolerance: float = 1e-3) -> None:
        self.robot, self.ssm, self.tolerance = robot, ssm, tolerance
        self.model = robot.model
        self.data = self.model.createData()
        self._links = []
        for cap in robot.capsules:
            placement, length = _capsule_placement(cap.a, cap.b)
            self._links.append((cap.link, self.model.getFrameId(cap.link), placement,
                                coal.Capsule(cap.radius, length)))
        self._request = coal.DistanceRequest()
        self._request.enable_signed_distance = True
        self._segments = [(self.model.getFrameId(cap.link), np.asarray(cap.a, float), np.asarray(cap.b, float))
                          for cap in robot.capsules]
        self._radii = np.array([cap.radius for cap in robot.capsules], dtype=float)

    def stopping_times(self, qds: np.ndarray) -> np.ndarray:
        """T_s (s) of each measured joint velocity ((N, 6), or one (6,)): stopping_time x the fastest joint's share of its
        velocity limit, at least min_stopping_time (``SsmParameters.stop_at``); the limit of a state is the
        formula at its own T_s."""
        return self.ssm.stop_of(qds, self.robot.limits.velocity)

    def check_batch(self, qs: np.ndarray, qds: np.ndarray,
                    humans: list[HumanCapsules | None]) -> list[MonitorResult]:
        """check() for many measured states (N, 6), each against its own human state, vectorised: states
        whose human states have the same number of capsules are checked together (each against its own
        people: joint states at 100 Hz and tracker samples at 120 Hz seldom share a sample, so grouping by
        sample would check one state at a time, each paying the whole numpy overhead). The same results
        as check(), to rounding (tested)."""
        qs = np.asarray(qs, dtype=float).reshape(-1, self.model.nq)
        qds = np.asarray(qds, dtype=float).reshape(-1, self.model.nq)
        results: list[MonitorResult | None] = [None] * qs.shape[0]
        groups: dict[int, list[int]] = {}
        for k, h in enumerate(humans):
            if h is None or h.count == 0:
                results[k] = MonitorResult()
            else:
                groups.setdefault(h.count, []).append(k)
        for members in groups.values():
            for k, r in zip(members, _batch(self, qs[members], qds[members], [humans[k] for k in members])):
                results[k] = r
        return results

    def check(self, q: np.ndarray, qd: np.ndarray, humans: HumanCapsules | None) -> MonitorResult:
        result = MonitorResult()
        if humans is None or humans.count == 0:
            return result
        q, qd = np.asarray(q, dtype=float), np.asarray(qd, dtype=float)
        stop = result.stop = float(self.stopping_times(qd))
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        human_shapes = []
        for j in range(humans.count):
            placement, length = _capsule_placement(humans.segments[j, 0], humans.segments[j, 1])
            human_shapes.append((coal.Capsule(float(humans.radii[j]), length),
                                 coal.Transform3s(placement.rotation, placement.translation)))
        for link, fid, local, shape in self._links:
            frame = self.data.oMf[fid]
            world = frame * local
            tf = coal.Transform3s(world.rotation, world.translation)
            jac = pin.getFrameJacobian(self.model, self.data, fid, pin.LOCAL_WORLD_ALIGNED)
            twist = jac @ qd                                         # (v at the frame origin, omega)
            for j, (hshape, htf) in enumerate(human_shapes):
                res = coal.DistanceResult()
                d = coal.distance(shape, tf, hshape, htf, self._request, res)
                p_robot, p_human = res.getNearestPoint1(), res.getNearestPoint2()
                diff = p_human - p_robot
                norm = np.linalg.norm(diff)
                # the direction from the robot towards the human. In penetration (d < 0) coal's witness
                # points lie inside the other shape, so p_human - p_robot points the other way: flipped
                # back (else a link moving out of a person who walked into it reads as approaching)
                n = (diff / norm if d >= 0 else -diff / norm) if norm > 1e-9 else np.zeros(3)
                v_robot = twist[:3] + np.cross(twist[3:], p_robot - frame.translation)
                approach = float(n @ v_robot) if norm > 1e-9 else float(np.linalg.norm(v_robot))
                a, b = humans.segments[j]
                u = float(np.clip((p_human - a) @ (b - a) / max((b - a) @ (b - a), 1e-12), 0.0, 1.0))
                v_h_point = (1 - u) * humans.velocities[j, 0] + u * humans.velocities[j, 1]
                if humans.velocity_known[j]:
                    v_h = max(0.0, float(-(n @ v_h_point))) if norm > 1e-9 else float(np.linalg.norm(v_h_point))
                else:
                    v_h = float(default_human_speed(d, self.ssm))
                limit = float(velocity_limit(d, v_h, self.ssm, stop))
                margin = max(limit, 0.0) - approach
                result.min_separation = min(result.min_separation, float(d))
                if margin < result.min_margin:
                    result.min_margin, result.approach_speed, result.limit = margin, approach, limit
                if margin < -self.tolerance:
                    result.violations.append(Violation(link, j, "speed", float(d), approach, limit))
                if d < self.ssm.min_separation - self.tolerance and approach > self.tolerance:
                    result.violations.append(Violation(link, j, "separation", float(d), approach, limit))
        return result


@numba.njit(cache=True)
def _monitor_pairs(a_w, b_w, origin, lin, ang, radii, segments, h_radii, h_vel):
    """For every state k, robot link i and human capsule j: separation, the robot's approach speed at its
    closest point and the human's there (as tracked), each (N, L, M). The monitor's own closest points (Ericson, Real-
    Time Collision Detection, 5.1.9; degenerate segments are points), compiled so that a pass costs its
    arithmetic and not a hundred numpy calls; not the scaling layer's kernel (shared.safety.ssm), on purpose.

    a_w, b_w, origin, lin, ang (N, L, 3): link segment ends, frame origin, and the frame's twist (linear
    velocity at the origin, angular velocity), world frame. segments (N, M, 2, 3), h_radii (N, M), h_vel
    (N, M, 2, 3): each state's people."""
    eps = 1e-12
    n, links, m = a_w.shape[0], a_w.shape[1], segments.shape[1]
    dist, approach, human = np.empty((n, links, m)), np.empty((n, links, m)), np.empty((n, links, m))
    for k in range(n):
        for i in range(links):
            ax, ay, az = a_w[k, i, 0], a_w[k, i, 1], a_w[k, i, 2]
            d1x, d1y, d1z = b_w[k, i, 0] - ax, b_w[k, i, 1] - ay, b_w[k, i, 2] - az
            aa = d1x * d1x + d1y * d1y + d1z * d1z
            for j in range(m):
                px, py, pz = segments[k, j, 0, 0], segments[k, j, 0, 1], segments[k, j, 0, 2]
                d2x, d2y, d2z = segments[k, j, 1, 0] - px, segments[k, j, 1, 1] - py, segments[k, j, 1, 2] - pz
                rx, ry, rz = ax - px, ay - py, az - pz
                e = d2x * d2x + d2y * d2y + d2z * d2z
                bb = d1x * d2x + d1y * d2y + d1z * d2z
                cc = d1x * rx + d1y * ry + d1z * rz
                f = d2x * rx + d2y * ry + d2z * rz
                a_ok, e_ok = aa > eps, e > eps
                safe_a, safe_e = aa if a_ok else 1.0, e if e_ok else 1.0
                denom = aa * e - bb * bb
                s = min(max((bb * f - cc * e) / denom, 0.0), 1.0) if denom > eps * max(aa * e, eps) else 0.0
                t = (bb * s + f) / safe_e
                if t < 0.0:
                    s = min(max(-cc / safe_a, 0.0), 1.0)
                elif t > 1.0:
                    s = min(max((bb - cc) / safe_a, 0.0), 1.0)
                t = min(max(t, 0.0), 1.0)
                if not a_ok:
                    s = 0.0
                elif not e_ok:
                    s = min(max(-cc / safe_a, 0.0), 1.0)
                if not e_ok:
                    t = 0.0
                elif not a_ok:
                    t = min(max(f / safe_e, 0.0), 1.0)
                # from the robot's closest point to the human's
                gx, gy, gz = px + t * d2x - ax - s * d1x, py + t * d2y - ay - s * d1y, pz + t * d2z - az - s * d1z
                centre = np.sqrt(gx * gx + gy * gy + gz * gz)
                dist[k, i, j] = centre - radii[i] - h_radii[k, j]
                defined = centre > 1e-9
                nx, ny, nz = (gx / centre, gy / centre, gz / centre) if defined else (0.0, 0.0, 0.0)
                # the robot's surface point, and its velocity: v_origin + omega x (p - origin)
                ox = ax + s * d1x + radii[i] * nx - origin[k, i, 0]
                oy = ay + s * d1y + radii[i] * ny - origin[k, i, 1]
                oz = az + s * d1z + radii[i] * nz - origin[k, i, 2]
                wx, wy, wz = ang[k, i, 0], ang[k, i, 1], ang[k, i, 2]
                vx = lin[k, i, 0] + wy * oz - wz * oy
                vy = lin[k, i, 1] + wz * ox - wx * oz
                vz = lin[k, i, 2] + wx * oy - wy * ox
                hx = (1.0 - t) * h_vel[k, j, 0, 0] + t * h_vel[k, j, 1, 0]
                hy = (1.0 - t) * h_vel[k, j, 0, 1] + t * h_vel[k, j, 1, 1]
                hz = (1.0 - t) * h_vel[k, j, 0, 2] + t * h_vel[k, j, 1, 2]
                if defined:
                    approach[k, i, j] = nx * vx + ny * vy + nz * vz
                    human[k, i, j] = max(0.0, -(nx * hx + ny * hy + nz * hz))
                else:
                    approach[k, i, j] = np.sqrt(vx * vx + vy * vy + vz * vz)
                    human[k, i, j] = np.sqrt(hx * hx + hy * hy + hz * hz)
    return dist, approach, human


def _batch(monitor: "SafetyMonitor", qs: np.ndarray, qds: np.ndarray,
           people: list[HumanCapsules]) -> list[MonitorResult]:
    """check() for states (N, 6), each against its own human state (N of them, the same number of capsules
    M): pinocchio for each state's link frames and their spatial velocities, then every (state, link, capsule)
    pair compiled, then the ISO formula (an untracked capsule at the ISO 13855 speed)."""
    n, links = qs.shape[0], len(monitor._links)
    a_w, b_w = np.empty((n, links, 3)), np.empty((n, links, 3))
    origin, lin, ang = np.empty((n, links, 3)), np.empty((n, links, 3)), np.empty((n, links, 3))
    model, data = monitor.model, monitor.data
    for k in range(n):
        pin.forwardKinematics(model, data, qs[k], qds[k])
        pin.updateFramePlacements(model, data)
        for i, (fid, a_local, b_local) in enumerate(monitor._segments):
            frame = data.oMf[fid]
            rot, pos = frame.rotation, frame.translation
            a_w[k, i], b_w[k, i], origin[k, i] = rot @ a_local + pos, rot @ b_local + pos, pos
            twist = pin.getFrameVelocity(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
            lin[k, i], ang[k, i] = twist.linear, twist.angular
    d, approach, tracked = _monitor_pairs(a_w, b_w, origin, lin, ang, monitor._radii,
                                          np.stack([h.segments for h in people]), np.stack([h.radii for h in people]),
                                          np.stack([h.velocities for h in people]))
    known = np.stack([h.velocity_known for h in people])[:, None, :]
    stops = monitor.stopping_times(qds)
    stop = np.broadcast_to(stops[:, None, None], d.shape)
    limit = velocity_limit(d, np.where(known, tracked, default_human_speed(d, monitor.ssm)), monitor.ssm, stop)
    margin = np.maximum(limit, 0.0) - approach
    speeding = margin < -monitor.tolerance
    too_close = (d < monitor.ssm.min_separation - monitor.tolerance) & (approach > monitor.tolerance)
    results = []
    flat = margin.reshape(n, -1)
    worst = np.argmin(flat, axis=1)
    for k in range(n):
        i, j = np.unravel_index(worst[k], margin.shape[1:])
        r = MonitorResult(float(d[k].min()), float(margin[k, i, j]), float(approach[k, i, j]), float(limit[k, i, j]),
                          stop=float(stops[k]))
        for i, j in zip(*np.nonzero(speeding[k] | too_close[k])):
            name = monitor._links[i][0]
            if speeding[k, i, j]:
                r.violations.append(Violation(name, int(j), "speed", float(d[k, i, j]), float(approach[k, i, j]),
                                              float(limit[k, i, j])))
            if too_close[k, i, j]:
                r.violations.append(Violation(name, int(j), "separation", float(d[k, i, j]),
                                              float(approach[k, i, j]), float(limit[k, i, j])))
        results.append(r)
    return results


class ReactionWindow:
    """Turns instantaneous speed exceedances into violations the way the standard's formula allows them.

    ISO/TS 15066's S_p = v_h (T_r + T_s) + v_r T_r + B + C + Z_d + Z_r assumes that, once the separation
    reaches S_p, the robot reacts within T_r and then brakes to a stop within T_s. So when the limit falls
    below a pair's approach speed (a person appears, their velocity turns unknown, or they come faster than
    the robot can be slowed by one command), the robot is allowed, for that (link, capsule) pair:
    * up to T_r at the speed it had (v_ref: the highest approach speed seen in the first T_r), then
    * a braking envelope down to zero over T_s: v_ref (1 - (t - T_r) / T_s), T_s that of the episode's first
      state (``MonitorResult.stop``: a robot that creeps has to be stopped sooner; the full-speed stopping_time
      where a result does not say).
    An exceedance that rises above the envelope (it did not brake), or outlasts T_r + T_s (it did not stop),
    is a violation; an episode ends at the pair's first compliant state. A separation below d_min is a
    violation at once. tolerance (m/s): measurement noise allowed on top.

    A stricter reading (within T_r no faster than at the episode's first state: the v_r T_r term at the
    speed of then) was tried and is not this rule: a robot braking at its full deceleration along a curved
    path turns towards a person, its approach rising from a near-tangent 3 mm/s to 25 mm/s (random walk,
    seed 2, 5.89 s), which no command can avoid; the formula's braking term covers that travel. The scaling
    layer does not speed up towards a capsule of unknown velocity (shared.scaling.layer.unknown_within_reach).
    """

    def __init__(self, reaction_time: float, stopping_time: float, tolerance: float = 0.01) -> None:
        self.reaction_time, self.stopping_time, self.tolerance = reaction_time, stopping_time, tolerance
        self._episodes: dict[tuple[str, int], tuple[float, float, float]] = {}    # pair -> (start, v_ref, T_s)

    def allowed(self, elapsed: float, v_ref: float, stop: float | None = None) -> float:
        """The approach speed (m/s) the formula still allows `elapsed` seconds into an exceedance whose first
        state's T_s is `stop` (s; default the full-speed stopping_time)."""
        if elapsed <= self.reaction_time:
            return np.inf
        stop = self.stopping_time if stop is None else stop
        return v_ref * max(0.0, 1.0 - (elapsed - self.reaction_time) / stop) + self.tolerance

    def update(self, now: float, result: MonitorResult) -> list[Violation]:
        speeding = {(v.link, v.capsule): v for v in result.violations if v.kind == "speed"}
        episodes, late = {}, []
        first_stop = result.stop if result.stop > 0.0 else self.stopping_time      # NaN: not said
        for pair, v in speeding.items():
            start, v_ref, stop = self._episodes.get(pair, (now, v.approach_speed, first_stop))
            elapsed = now - start
            if elapsed <= self.reaction_time:
                v_ref = max(v_ref, v.approach_speed)
            episodes[pair] = (start, v_ref, stop)
            if elapsed > self.reaction_time + stop or v.approach_speed > self.allowed(elapsed, v_ref, stop):
                late.append(v)
        self._episodes = episodes
        return late + [v for v in result.violations if v.kind == "separation"]


class HumanHistory:
    """The human states of the last `span` seconds, by the time their sample was taken, so that each joint
    state is checked against the person *as they were when it was measured*.

    A monitor that falls behind (it is niced below the control loop, and a check costs a few ms) works
    through a backlog of joint states while new human states keep arriving; checking an old joint state
    against the newest person pairs a robot at speed with a person who has since turned away (a false
    exceedance) or with one who has since come nearer (a false alarm the other way). With the history the
    pairing is the one the scaling layer faced: the newest sample taken at or before the joint state.
    """

    def __init__(self, span: float = 2.0) -> None:
        self.span = span
        self._stamps: deque[float] = deque()
        self._states: deque[HumanCapsules | None] = deque()

    def add(self, sample_stamp: float, humans: HumanCapsules | None) -> None:
        """Keep a human state (None: the track is not valid) taken at sample_stamp (monotonic s). Samples
        out of order are placed in order; those replaced more than the span ago are forgotten."""
        if self._stamps and sample_stamp < self._stamps[-1]:
            stamps, states = list(self._stamps), list(self._states)
            k = bisect_right(stamps, sample_stamp)
            stamps.insert(k, sample_stamp)
            states.insert(k, humans)
            self._stamps, self._states = deque(stamps), deque(states)
        else:
            self._stamps.append(sample_stamp)
            self._states.append(humans)
        while len(self._stamps) > 1 and self._stamps[1] <= self._stamps[-1] - self.span:   # keep the one in force
            self._stamps.popleft()
            self._states.popleft()

    @property
    def newest(self) -> float | None:
        """The sample time of the newest kept human state, None when none is kept."""
        return self._stamps[-1] if self._stamps else None

    def pair(self, stamp: float) -> tuple[float, HumanCapsules | None] | None:
        """(sample time, state) of the newest sample taken at or before `stamp`; None when every kept sample
        is newer (the person of that moment is not known: no guess)."""
        k = bisect_right(self._stamps, stamp)
        return (self._stamps[k - 1], self._states[k - 1]) if k else None

    def pair_since(self, stamp: float, after: float) -> tuple[float, HumanCapsules | None] | None:
        """Like ``pair``, for a joint state at `stamp` whose predecessor was measured at `after`: the people of
        every sample in force during (after, stamp] (the one in force at `after` and every one taken since) as
        one state (``HumanCapsules.union``, newest first), so that a state that held for less than a joint
        state's period is checked too; the newest sample's time, and None when that newest sample is an
        invalid track. Only one sample in force: ``pair(stamp)``."""
        lo, hi = max(bisect_right(self._stamps, after) - 1, 0), bisect_right(self._stamps, stamp)
        if hi - lo <= 1:
            return self.pair(stamp)
        newest = self._states[hi - 1]
        if newest is None:
            return self._stamps[hi - 1], None
        valid = [self._states[k] for k in range(hi - 1, lo - 1, -1) if self._states[k] is not None]
        return self._stamps[hi - 1], HumanCapsules.union(valid)

    def at(self, stamp: float) -> HumanCapsules | None:
        """The person at `stamp`: the newest sample taken at or before it. A joint state older than every
        kept sample gets the oldest kept (the nearest in time there is); none kept: None."""
        if not self._stamps:
            return None
        paired = self.pair(stamp)
        return self._states[0] if paired is None else paired[1]


class Unchecked(NamedTuple):
    """A joint state the monitor could not check: when it was measured, the kind of reason ('late',
    'before any human state', 'tracker silent', 'invalid track') and the reason in words."""

    stamp: float
    kind: str
    reason: str


AT_REST = 1e-4     # rad/s: every joint slower than this is at rest (0.1 mm/s at a metre: below the tolerance)
DELAYS_KEPT = 64   # people samples whose way from capture to the tracker's publication the monitor's wait follows


@dataclass
class Backlog:
    """The joint states waiting for the monitor, and the rule for when each can be checked (pure).

    A state is checked against the person of its own moment: the newest human sample taken at or before
    it, and every other sample taken since the state before it (``HumanHistory.pair_since``: a person state
    shorter than the joint states' period counts too). That pairing is final once a sample newer than the
    state has arrived; until then the state waits, at most ``pair_wait`` seconds. A robot at rest (every
    joint slower than AT_REST) needs no person and no wait: the rule counts nothing where no link
    approaches, so such a state passes
    whoever is there (checked against the person of its moment when that one is already known, for the
    figures). A state is *unchecked* (counted and reported, never a violation and never a pass) when no
    human state of its moment is known: none taken at or before it, the one before it older than
    ``pair_age`` (the tracker was silent: the scaler had stopped the robot, and what the person did then is
    not known), or an invalid track; and when the monitor reaches it more than ``deadline`` seconds after
    it was measured (a monitor that fell that far behind skips ahead instead of reporting the past as if it
    were now). The people's samples are stamped with their capture and reach the monitor ``delay`` later at
    the most (a camera's latency, the tracker's hop: ``note_delay``), so the wait and the deadline are that
    much longer: a state is never paired before the person of its moment can have come.
    """

    pair_wait: float = 0.1
    pair_age: float = 0.1
    deadline: float = 0.5
    _pending: list = field(default_factory=list)
    _previous: float = -np.inf           # when the last state taken (checked or not) was measured
    _delays: deque = field(default_factory=lambda: deque(maxlen=DELAYS_KEPT))

    def note_delay(self, delay: float) -> None:
        """A people sample's way from its capture to its publication by the tracker (s)."""
        if np.isfinite(delay):
            self._delays.append(min(max(float(delay), 0.0), OLDEST_SAMPLE))

    @property
    def delay(self) -> float:
        """s: the longest of the last DELAYS_KEPT samples' ways from capture to publication (0 before any)."""
        return max(self._delays, default=0.0)

    def add(self, stamp: float, q: np.ndarray, qd: np.ndarray) -> None:
        self._pending.append((stamp, q, qd))

    def __len__(self) -> int:
        return len(self._pending)

    def take(self, now: float, history: HumanHistory) -> tuple[list[tuple[float, np.ndarray, np.ndarray, HumanCapsules]],
                                                            list[Unchecked]]:
        """(states to check now with their person, states that cannot be checked with the reason); the
        rest stay for a later pass. Both lists in measurement order."""
        ready, unchecked, keep = [], [], []
        newest, delay = history.newest, self.delay
        for stamp, q, qd in sorted(self._pending, key=lambda item: item[0]):
            age = now - stamp
            if age > self.deadline + delay:
                unchecked.append(Unchecked(stamp, "late", f"reached {age * 1e3:.0f} ms after it was measured"))
                continue
            at_rest = np.abs(qd).max() <= AT_REST
            if not at_rest and (newest is None or newest <= stamp) and age < self.pair_wait + delay:
                keep.append((stamp, q, qd))                   # the person of its moment may still arrive
                continue
            paired = history.pair_since(stamp, self._previous)
            self._previous = max(self._previous, stamp)
            known = paired is not None and paired[1] is not None and stamp - paired[0] <= self.pair_age
            if known:
                ready.append((stamp, q, qd, paired[1]))
            elif at_rest:                                     # nothing approaches: a pass whoever is there
                ready.append((stamp, q, qd, HumanCapsules.empty()))
            elif paired is None:
                unchecked.append(Unchecked(stamp, "before any human state", "no human state taken at or before it"))
            elif stamp - paired[0] > self.pair_age:
                unchecked.append(Unchecked(stamp, "tracker silent", f"the human state of its moment is "
                                                                    f"{(stamp - paired[0]) * 1e3:.0f} ms old"))
            else:
                unchecked.append(Unchecked(stamp, "invalid track", "the tracker had no valid track"))
        self._pending = keep
        return ready, unchecked
