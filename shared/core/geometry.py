"""Capsule-to-capsule distances for every (robot link, human capsule) pair.

A capsule is a segment [a, b] and a radius. The distance of two capsules is the distance of their
segments minus both radii (negative when they overlap). The closest points of two segments follow
Ericson, *Real-Time Collision Detection* (2005), section 5.1.9, including its degenerate branches
(point-like segments, parallel segments). The loop over pairs is compiled with numba: in numpy some 40
whole-array operations on a few dozen pairs are almost all per-call overhead. ``coal`` computes the same
numbers pair by pair and ``tests/core/test_geometry.py`` cross-checks the two.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

EPS_POINT = 1e-12     # squared segment length (m^2) below which a segment is a point
EPS_NORMAL = 1e-9     # axis-to-axis distance (m) below which the robot -> human direction is undefined


@numba.njit(cache=True, inline="always")
def _clamp01(x: float) -> float:
    return 0.0 if x < 0.0 else (1.0 if x > 1.0 else x)


@numba.njit(cache=True)
def segment_closest_params(p1, q1, p2, q2):
    """Parameters (s, t) in [0, 1] of the closest points p1 + s (q1 - p1) and p2 + t (q2 - p2).

    Inputs are 3-vectors. For parallel segments one of the equally close pairs is returned.
    """
    d1x, d1y, d1z = q1[0] - p1[0], q1[1] - p1[1], q1[2] - p1[2]
    d2x, d2y, d2z = q2[0] - p2[0], q2[1] - p2[1], q2[2] - p2[2]
    rx, ry, rz = p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2]
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    if a <= EPS_POINT and e <= EPS_POINT:
        return 0.0, 0.0
    if a <= EPS_POINT:
        return 0.0, _clamp01(f / e)
    c = d1x * rx + d1y * ry + d1z * rz
    if e <= EPS_POINT:
        return _clamp01(-c / a), 0.0
    b = d1x * d2x + d1y * d2y + d1z * d2z
    denom = a * e - b * b
    s = _clamp01((b * f - c * e) / denom) if denom > EPS_POINT * a * e else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        return _clamp01(-c / a), 0.0
    if t > 1.0:
        return _clamp01((b - c) / a), 1.0
    return s, t


@numba.njit(cache=True)
def _pairs_kernel(robot_seg, robot_rad, human_seg, human_rad, dist, s_out, t_out, cr, ch, normal, degenerate):
    n_l, n_m = robot_seg.shape[0], human_seg.shape[0]
    for i in range(n_l):
        p1, q1 = robot_seg[i, 0], robot_seg[i, 1]
        for j in range(n_m):
            p2, q2 = human_seg[j, 0], human_seg[j, 1]
            s, t = segment_closest_params(p1, q1, p2, q2)
            norm2 = 0.0
            for k in range(3):
                a = p1[k] + s * (q1[k] - p1[k])
                b = p2[k] + t * (q2[k] - p2[k])
                cr[i, j, k] = a
                ch[i, j, k] = b
                normal[i, j, k] = b - a
                norm2 += (b - a) * (b - a)
            centre = np.sqrt(norm2)
            degenerate[i, j] = centre < EPS_NORMAL
            for k in range(3):
                normal[i, j, k] = 0.0 if centre < EPS_NORMAL else normal[i, j, k] / centre
            dist[i, j] = centre - robot_rad[i] - human_rad[j]
            s_out[i, j] = s
            t_out[i, j] = t


@dataclass(frozen=True)
class PairDistances:
    """Closest-approach data for robot capsule i and human capsule j (arrays shaped (L, M, ...)).

    distance: surface distance (m), negative when the capsules overlap.
    robot_param, human_param: where the closest points lie on each segment, in [0, 1].
    robot_point, human_point: the closest points of the two segment axes (m, base frame).
    normal: unit vector from the robot's closest point towards the human's; zero where undefined.
    degenerate: True where the axes touch so that no direction is defined (then every direction must
    count as "towards").
    """

    distance: np.ndarray
    robot_param: np.ndarray
    human_param: np.ndarray
    robot_point: np.ndarray
    human_point: np.ndarray
    normal: np.ndarray
    degenerate: np.ndarray


def capsule_pair_distances(robot_segments: np.ndarray, robot_radii: np.ndarray,
                           human_segments: np.ndarray, human_radii: np.ndarray) -> PairDistances:
    """Distances between every robot capsule (L, 2, 3)/(L,) and every human capsule (M, 2, 3)/(M,)."""
    rs = np.ascontiguousarray(robot_segments, dtype=np.float64)
    hs = np.ascontiguousarray(human_segments, dtype=np.float64)
    n_l, n_m = rs.shape[0], hs.shape[0]
    dist, s, t = np.empty((n_l, n_m)), np.empty((n_l, n_m)), np.empty((n_l, n_m))
    cr, ch, normal = np.empty((n_l, n_m, 3)), np.empty((n_l, n_m, 3)), np.empty((n_l, n_m, 3))
    degenerate = np.empty((n_l, n_m), dtype=np.bool_)
    _pairs_kernel(rs, np.ascontiguousarray(robot_radii, dtype=np.float64), hs,
                  np.ascontiguousarray(human_radii, dtype=np.float64), dist, s, t, cr, ch, normal, degenerate)
    return PairDistances(dist, s, t, cr, ch, normal, degenerate)


def capsule_frames(segments: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For capsules given by their axis end points (M, 2, 3): the start point (M, 3), the unit quaternion
    (x, y, z, w) that turns +z onto the axis (M, 4), and the axis length (M,): the pose of a capsule built
    along +z from the origin, as 3D viewers (rerun's Capsules3D) draw them. A point capsule (a sphere)
    gets the identity."""
    seg = np.asarray(segments, dtype=float).reshape(-1, 2, 3)
    axis = seg[:, 1] - seg[:, 0]
    length = np.linalg.norm(axis, axis=1)
    d = np.divide(axis, length[:, None], out=np.tile([0.0, 0.0, 1.0], (len(seg), 1)), where=length[:, None] > 0)
    # the rotation of +z onto d: axis z x d, angle acos(d_z); as a quaternion (z x d, 1 + d_z), normalised
    quat = np.column_stack([-d[:, 1], d[:, 0], np.zeros(len(seg)), 1.0 + d[:, 2]])
    flipped = quat[:, 3] < 1e-9                                  # d = -z: half a turn about x
    quat[flipped] = [1.0, 0.0, 0.0, 0.0]
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    return seg[:, 0].copy(), quat, length
