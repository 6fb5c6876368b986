"""Feasibility of robot configurations and motions: the planning layer's collision model.

A configuration q is feasible when it is inside the joint limits and every robot capsule keeps
* at least d_min + human_margin (+ an optional extra inflation) from every human capsule,
* at least static_margin from the floor, every box and every capsule of the static scene (the base
  capsule, bolted to the floor, is exempt),
* at least self_margin from the links the SRDF leaves enabled for self-collision.
``clearance(q)`` is the smallest of those surplus distances (m): feasible means clearance > tolerance.

Motions are checked by *conservative advancement*: along the straight joint-space segment, link i moves
at most D_i dt with D_i = sum_k |dq_k| reach_ik (reach_ik bounds the lever arm of joint k on link i in
every configuration), and the links of a self pair move relative to each other only through the joints
that move exactly one of them; so from a point whose link clearances are c_i (and pair clearances c_p)
the next min(c_i / D_i, c_p / D_p) of the segment cannot close any gap, and is skipped. Guarantee: a motion reported
free keeps
every clearance above zero at every point of the segment, whatever the size of the obstacle (nothing
thin can be stepped over); a motion is reported blocked when the clearance falls to the tolerance.
All kernels are compiled: OMPL calls them thousands of times per plan.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from shared.core.errors import ConfigError
from shared.core.geometry import segment_closest_params
from shared.core.humans import HumanCapsules
from shared.core.sections import check_numbers
from shared.planning.scene import Scene
from shared.robot.model import RobotModel, chain_world, place_points

# what limits a clearance: codes returned by the kernel
FREE, LIMITS, SELF, FLOOR, BOX, STATIC_CAPSULE, HUMAN = range(7)
KIND_NAMES = ("free", "joint limits", "self-collision", "floor", "box", "static capsule", "human")


@dataclass(frozen=True)
class CollisionMargins:
    """human (m): kept beyond d_min from every human capsule; static (m): from the cell; self_ (m):
    between links; tolerance (m): a clearance at or below this counts as a collision (it also bounds
    the number of steps of the motion check)."""

    human: float = 0.05
    static: float = 0.02
    self_: float = 0.0
    tolerance: float = 1e-3

    def __post_init__(self) -> None:
        check_numbers(self, "collision", non_negative=True)
        if self.tolerance <= 0:
            raise ConfigError("collision.tolerance: must be positive")


@dataclass(frozen=True)
class Contact:
    """The limiting constraint of a configuration: clearance (m), what it is, and which (name or index)."""

    clearance: float
    kind: str
    which: str

    @property
    def feasible(self) -> bool:
        return self.kind == "free"


@numba.njit(cache=True, inline="always")
def _segment_segment(p1, q1, p2, q2):
    s, t = segment_closest_params(p1, q1, p2, q2)
    d = 0.0
    for k in range(3):
        x = p2[k] + t * (q2[k] - p2[k]) - p1[k] - s * (q1[k] - p1[k])
        d += x * x
    return np.sqrt(d)


@numba.njit(cache=True, inline="always")
def _box_sdf(px, py, pz, c, h):
    """Signed distance from a point to an axis-aligned box (negative inside)."""
    dx, dy, dz = abs(px - c[0]) - h[0], abs(py - c[1]) - h[1], abs(pz - c[2]) - h[2]
    outside = np.sqrt(max(dx, 0.0) ** 2 + max(dy, 0.0) ** 2 + max(dz, 0.0) ** 2)
    return outside + min(max(dx, max(dy, dz)), 0.0)


@numba.njit(cache=True)
def _segment_box(a, b, c, h):
    """Signed distance from a segment to a box: the SDF of a convex set is convex, so along the segment
    it is a convex function of the parameter; golden-section search finds its minimum (to 1e-9)."""
    lo, hi = 0.0, 1.0
    g = 0.6180339887498949
    x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
    f1 = _box_sdf(a[0] + x1 * (b[0] - a[0]), a[1] + x1 * (b[1] - a[1]), a[2] + x1 * (b[2] - a[2]), c, h)
    f2 = _box_sdf(a[0] + x2 * (b[0] - a[0]), a[1] + x2 * (b[1] - a[1]), a[2] + x2 * (b[2] - a[2]), c, h)
    for _ in range(45):
        if f1 <= f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - g * (hi - lo)
            f1 = _box_sdf(a[0] + x1 * (b[0] - a[0]), a[1] + x1 * (b[1] - a[1]), a[2] + x1 * (b[2] - a[2]), c, h)
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + g * (hi - lo)
            f2 = _box_sdf(a[0] + x2 * (b[0] - a[0]), a[1] + x2 * (b[1] - a[1]), a[2] + x2 * (b[2] - a[2]), c, h)
    end_a = _box_sdf(a[0], a[1], a[2], c, h)
    end_b = _box_sdf(b[0], b[1], b[2], c, h)
    return min(min(f1, f2), min(end_a, end_b))


@numba.njit(cache=True)
def _evaluate(q, placement, parent, local, joint, radii, static_link, self_pairs, lower, upper,
              floor_z, box_c, box_h, cap_seg, cap_rad, human_seg, human_rad, human_req, static_req, self_req,
              link_clear, pair_clear):
    """Clearance of q: returns (smallest, kind, index) and writes every link's clearance to the cell and
    the humans into link_clear (L,) and every self pair's into pair_clear (P,)."""
    best, kind, index = np.inf, FREE, -1
    for k in range(q.shape[0]):
        out = max(lower[k] - q[k], q[k] - upper[k])
        if out > 0.0 and -out < best:
            best, kind, index = -out, LIMITS, k
    world = chain_world(q, placement, parent)
    pts = place_points(world, local, joint)
    for p in range(self_pairs.shape[0]):
        i, j = self_pairs[p, 0], self_pairs[p, 1]
        d = _segment_segment(pts[2 * i], pts[2 * i + 1], pts[2 * j], pts[2 * j + 1]) - radii[i] - radii[j] - self_req
        pair_clear[p] = d
        if d < best:
            best, kind, index = d, SELF, p
    for i in range(radii.shape[0]):
        a, b, r = pts[2 * i], pts[2 * i + 1], radii[i]
        link_best = np.inf
        if not static_link[i]:
            d = min(a[2], b[2]) - r - floor_z - static_req
            link_best = min(link_best, d)
            if d < best:
                best, kind, index = d, FLOOR, 0
            for o in range(box_c.shape[0]):
                d = _segment_box(a, b, box_c[o], box_h[o]) - r - static_req
                link_best = min(link_best, d)
                if d < best:
                    best, kind, index = d, BOX, o
            for o in range(cap_rad.shape[0]):
                d = _segment_segment(a, b, cap_seg[o, 0], cap_seg[o, 1]) - r - cap_rad[o] - static_req
                link_best = min(link_best, d)
                if d < best:
                    best, kind, index = d, STATIC_CAPSULE, o
        for o in range(human_rad.shape[0]):
            d = _segment_segment(a, b, human_seg[o, 0], human_seg[o, 1]) - r - human_rad[o] - human_req
            link_best = min(link_best, d)
            if d < best:
                best, kind, index = d, HUMAN, o
        link_clear[i] = link_best
    return best, kind, index


@numba.njit(cache=True)
def _clearance(q, placement, parent, local, joint, radii, static_link, self_pairs, lower, upper,
               floor_z, box_c, box_h, cap_seg, cap_rad, human_seg, human_rad, human_req, static_req, self_req):
    """(clearance, kind, index) of configuration q; see the module docstring."""
    return _evaluate(q, placement, parent, local, joint, radii, static_link, self_pairs, lower, upper,
                     floor_z, box_c, box_h, cap_seg, cap_rad, human_seg, human_rad, human_req, static_req,
                     self_req, np.empty(radii.shape[0]), np.empty(self_pairs.shape[0]))


@numba.njit(cache=True)
def _clearances(qs, placement, parent, local, joint, radii, static_link, self_pairs, lower, upper,
                floor_z, box_c, box_h, cap_seg, cap_rad, human_seg, human_rad, human_req, static_req, self_req):
    out = np.empty(qs.shape[0])
    link_clear, pair_clear = np.empty(radii.shape[0]), np.empty(self_pairs.shape[0])
    for k in range(qs.shape[0]):
        out[k] = _evaluate(qs[k], placement, parent, local, joint, radii, static_link, self_pairs, lower, upper,
                           floor_z, box_c, box_h, cap_seg, cap_rad, human_seg, human_rad,
                           human_req, static_req, self_req, link_clear, pair_clear)[0]
    return out


@numba.njit(cache=True, inline="always")
def _motion_bounds(q0, q1, link_reach, pair_moves, self_pairs, d_link, d_pair):
    """Into d_link (L,) and d_pair (P,): how far (m) each link, and each self pair's links relative to each
    other, can move per unit of t along q0 -> q1 (see _motion_free)."""
    d_link[:] = 0.0
    d_pair[:] = 0.0
    for k in range(q0.shape[0]):
        dq = abs(q1[k] - q0[k])
        for i in range(d_link.shape[0]):
            d_link[i] += dq * link_reach[i, k]
        for p in range(d_pair.shape[0]):
            if pair_moves[p, k]:
                d_pair[p] += dq * max(link_reach[self_pairs[p, 0], k], link_reach[self_pairs[p, 1], k])


@numba.njit(cache=True, inline="always")
def _safe_step(link_left, pair_left, d_link, d_pair):
    """How much of t no link and no self pair can use up what it may still move (m): inf if none moves."""
    step = np.inf
    for i in range(d_link.shape[0]):
        if d_link[i] > 0.0:
            step = min(step, link_left[i] / d_link[i])
    for p in range(d_pair.shape[0]):
        if d_pair[p] > 0.0:
            step = min(step, pair_left[p] / d_pair[p])
    return step


@numba.njit(cache=True)
def _motion_free(q0, q1, link_reach, pair_moves, tolerance, placement, parent, local, joint, radii, static_link,
                 self_pairs, lower, upper, floor_z, box_c, box_h, cap_seg, cap_rad, human_seg, human_rad,
                 human_req, static_req, self_req):
    """(free, t, evaluations): conservative advancement along q0 -> q1; t is where it stopped (1.0 when
    free); evaluations counts the configurations checked.

    Per unit of t, link i moves at most D_i = sum_k |dq_k| link_reach[i, k] (m), and the two links of
    self pair p move relative to each other at most D_p = the same sum over the joints that move exactly
    one of them (the others move both rigidly). From a point with clearances c, the next
    min(c_i / D_i, c_p / D_p) of t cannot close any gap."""
    n_links, n_pairs, n = radii.shape[0], self_pairs.shape[0], q0.shape[0]
    d_link, d_pair = np.empty(n_links), np.empty(n_pairs)
    _motion_bounds(q0, q1, link_reach, pair_moves, self_pairs, d_link, d_pair)
    link_clear, pair_clear = np.empty(n_links), np.empty(n_pairs)
    q = q0.copy()
    t = 0.0
    evaluations = 0
    while True:
        evaluations += 1
        for k in range(n):
            q[k] = q0[k] + t * (q1[k] - q0[k])
        best = _evaluate(q, placement, parent, local, joint, radii, static_link, self_pairs, lower, upper,
                         floor_z, box_c, box_h, cap_seg, cap_rad, human_seg, human_rad, human_req, static_req,
                         self_req, link_clear, pair_clear)[0]
        if best <= tolerance:
            return False, t, evaluations
        if t >= 1.0:
            return True, 1.0, evaluations
        t = min(1.0, t + _safe_step(link_clear, pair_clear, d_link, d_pair))


@numba.njit(cache=True)
def _path_free(qs, link_reach, pair_moves, tolerance, placement, parent, local, joint, radii, static_link,
               self_pairs, lower, upper, floor_z, box_c, box_h, cap_seg, cap_rad, human_seg, human_rad,
               human_req, static_req, self_req):
    """(free, evaluations): conservative advancement along the whole path qs[0] -> qs[1] -> ... at once.
    From each configuration checked the path is followed, across segment ends, until some link (or self
    pair) may have moved by its clearance there (the bounds of _motion_free, per segment); there is the
    next check. The guarantee is motion_free's: every point of a path called free keeps every clearance
    above zero, and each check's step is at least the tolerance's worth of motion (a budget of clearance
    less tolerance would crawl, without bound, along a path that keeps just over the tolerance). Unlike
    checking segment by segment, the knots themselves are not each checked against the tolerance.
    A time law's knots are 10 ms apart and move a link a centimetre or two: checked a segment at a time,
    each cost two or three checks (250 knots, 6 ms of an 8 ms law); followed through, a check covers
    several segments."""
    n_links, n_pairs, n = radii.shape[0], self_pairs.shape[0], qs.shape[1]
    link_clear, pair_clear = np.empty(n_links), np.empty(n_pairs)
    d_link, d_pair = np.empty(n_links), np.empty(n_pairs)
    q = qs[0].copy()
    evaluations = 1
    if _evaluate(q, placement, parent, local, joint, radii, static_link, self_pairs, lower, upper, floor_z, box_c,
                 box_h, cap_seg, cap_rad, human_seg, human_rad, human_req, static_req, self_req, link_clear,
                 pair_clear)[0] <= tolerance:
        return False, evaluations
    link_left, pair_left = link_clear.copy(), pair_clear.copy()       # how far each may still move (m)
    for k in range(qs.shape[0] - 1):
        _motion_bounds(qs[k], qs[k + 1], link_reach, pair_moves, self_pairs, d_link, d_pair)
        t = 0.0
        while True:
            step = _safe_step(link_left, pair_left, d_link, d_pair)
            if t + step >= 1.0:                  # the rest of this segment is within every budget
                link_left -= (1.0 - t) * d_link
                pair_left -= (1.0 - t) * d_pair
                break
            t += step
            for j in range(n):
                q[j] = qs[k, j] + t * (qs[k + 1, j] - qs[k, j])
            evaluations += 1
            if _evaluate(q, placement, parent, local, joint, radii, static_link, self_pairs, lower, upper, floor_z,
                         box_c, box_h, cap_seg, cap_rad, human_seg, human_rad, human_req, static_req, self_req,
                         link_clear, pair_clear)[0] <= tolerance:
                return False, evaluations
            link_left[:] = link_clear
            pair_left[:] = pair_clear
    return True, evaluations


class CollisionModel:
    """The robot, the static scene and the margins; humans are passed per call (they move)."""

    def __init__(self, robot: RobotModel, scene: Scene | None = None, min_separation: float = 0.05,
                 margins: CollisionMargins | None = None) -> None:
        self.robot = robot
        self.scene = scene or Scene()
        self.margins = margins or CollisionMargins()
        self.min_separation = float(min_separation)
        index = {name: i for i, name in enumerate(robot.link_names)}
        self._self_pairs = np.array([[index[a], index[b]] for a, b in robot.self_collision_pairs], dtype=np.int64
                                    ).reshape(-1, 2)
        self._static_link = ~robot.moving_links
        anc = robot.link_reach > 0                                           # (L, 6): joint k moves link i
        self._pair_moves = np.array([anc[i] != anc[j] for i, j in self._self_pairs], dtype=np.bool_
                                    ).reshape(-1, robot.nq)
        s = self.scene
        self._static = (s.floor_z, s.box_centers, s.box_half_sizes, s.capsule_segments, s.capsule_radii)
        self._fixed = (*robot.chain, robot.radii, self._static_link, self._self_pairs, robot.limits.lower,
                       robot.limits.upper, *self._static)
        self.checks = 0          # configurations evaluated (motion checks count every step)

    def _human_args(self, humans: HumanCapsules | None, inflation: float):
        h = humans if humans is not None else HumanCapsules.empty()
        required = self.min_separation + self.margins.human + inflation
        return h.segments, h.radii, required, self.margins.static, self.margins.self_

    def clearance(self, q: np.ndarray, humans: HumanCapsules | None = None, inflation: float = 0.0) -> float:
        """Smallest surplus distance (m) of configuration q; feasible when > tolerance."""
        self.checks += 1
        return _clearance(np.asarray(q, dtype=np.float64), *self._fixed, *self._human_args(humans, inflation))[0]

    def feasible(self, q: np.ndarray, humans: HumanCapsules | None = None, inflation: float = 0.0) -> bool:
        return self.clearance(q, humans, inflation) > self.margins.tolerance

    def contact(self, q: np.ndarray, humans: HumanCapsules | None = None, inflation: float = 0.0) -> Contact:
        """The limiting constraint of q, named (for error messages)."""
        value, kind, index = _clearance(np.asarray(q, dtype=np.float64), *self._fixed,
                                        *self._human_args(humans, inflation))
        if value > self.margins.tolerance:
            return Contact(float(value), "free", "")
        if kind == LIMITS:
            which = self.robot.joint_names[index]
        elif kind == SELF:
            which = " / ".join(self.robot.self_collision_pairs[index])
        elif kind == BOX or kind == STATIC_CAPSULE:
            offset = 0 if kind == BOX else len(self.scene.box_centers)
            which = self.scene.names[offset + index]
        elif kind == HUMAN:
            which = f"human capsule {index}"
        else:
            which = KIND_NAMES[kind]
        return Contact(float(value), KIND_NAMES[kind], which)

    def clearances(self, qs: np.ndarray, humans: HumanCapsules | None = None, inflation: float = 0.0) -> np.ndarray:
        """Clearance of each row of qs (K, 6) at once."""
        qs = np.ascontiguousarray(qs, dtype=np.float64).reshape(-1, self.robot.nq)
        self.checks += qs.shape[0]
        return _clearances(qs, *self._fixed, *self._human_args(humans, inflation))

    def capped_inflation(self, inflation: float, configs: np.ndarray, humans: HumanCapsules | None) -> float:
        """The inflation (m), lowered to the clearance that the configurations a plan must start or end in
        (configs, (K, 6)) already have from the people (so it may turn negative: a robot a person has walked up
        to is not refused a way out). A plan's smoothed trajectory is then checked never to come closer to a
        human than that."""
        if humans is None or humans.count == 0:
            return max(0.0, inflation)
        have = float(self.clearances(configs, humans, inflation=0.0).min()) - 2 * self.margins.tolerance
        return min(inflation, have)

    def motion_free(self, q0: np.ndarray, q1: np.ndarray, humans: HumanCapsules | None = None,
                    inflation: float = 0.0) -> tuple[bool, float]:
        """(free, t): whether the straight joint-space motion q0 -> q1 keeps clearance > 0 throughout
        (guaranteed, see the module docstring); t is the fraction reached when it is not."""
        free, t, evaluations = _motion_free(np.asarray(q0, dtype=np.float64), np.asarray(q1, dtype=np.float64),
                               self.robot.link_reach, self._pair_moves, self.margins.tolerance, *self._fixed,
                               *self._human_args(humans, inflation))
        self.checks += evaluations
        return bool(free), float(t)

    def path_free(self, waypoints: np.ndarray, humans: HumanCapsules | None = None, inflation: float = 0.0) -> bool:
        """Every straight segment of the path (K, 6) free, by conservative advancement along the whole path
        in one compiled call (see _path_free): free means every clearance stays above zero all along it,
        motion_free's guarantee; only a knot within the tolerance of a collision is judged differently."""
        qs = np.ascontiguousarray(waypoints, dtype=np.float64).reshape(-1, self.robot.nq)
        free, evaluations = _path_free(qs, self.robot.link_reach, self._pair_moves, self.margins.tolerance,
                                       *self._fixed, *self._human_args(humans, inflation))
        self.checks += evaluations
        return bool(free)
