"""Capsule distances: hand-computed cases, degenerate cases, and a cross-check against coal."""

import coal
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from shared.core.geometry import capsule_pair_distances, segment_closest_params


def pair(a0, a1, ra, b0, b1, rb):
    return capsule_pair_distances(np.array([[a0, a1]], float), np.array([ra]), np.array([[b0, b1]], float),
                                  np.array([rb]))


def test_crossing_segments_at_right_angles():
    d = pair((-1, 0, 0), (1, 0, 0), 0.1, (0, -1, 0.5), (0, 1, 0.5), 0.2)
    assert d.distance[0, 0] == pytest.approx(0.5 - 0.3)
    assert d.robot_point[0, 0] == pytest.approx([0, 0, 0])
    assert d.human_point[0, 0] == pytest.approx([0, 0, 0.5])
    assert d.normal[0, 0] == pytest.approx([0, 0, 1])
    assert d.robot_param[0, 0] == pytest.approx(0.5) and d.human_param[0, 0] == pytest.approx(0.5)


def test_parallel_segments_overlapping_and_offset():
    d = pair((0, 0, 0), (1, 0, 0), 0.0, (0.5, 0.3, 0), (2, 0.3, 0), 0.0)
    assert d.distance[0, 0] == pytest.approx(0.3)
    assert d.normal[0, 0] == pytest.approx([0, 1, 0])
    # parallel, not overlapping along the axis: end to end
    d = pair((0, 0, 0), (1, 0, 0), 0.0, (2, 0, 0), (3, 0, 0), 0.0)
    assert d.distance[0, 0] == pytest.approx(1.0)
    assert d.robot_point[0, 0] == pytest.approx([1, 0, 0]) and d.human_point[0, 0] == pytest.approx([2, 0, 0])


def test_zero_length_segments_are_spheres():
    d = pair((0, 0, 0), (0, 0, 0), 0.1, (3, 4, 0), (3, 4, 0), 0.4)
    assert d.distance[0, 0] == pytest.approx(5 - 0.5)
    assert d.normal[0, 0] == pytest.approx([0.6, 0.8, 0])
    d = pair((0, 0, 0), (0, 0, 0), 0.0, (-1, 1, 0), (1, 1, 0), 0.0)      # point vs segment
    assert d.distance[0, 0] == pytest.approx(1.0) and d.human_point[0, 0] == pytest.approx([0, 1, 0])
    d = pair((-1, 1, 0), (1, 1, 0), 0.0, (0, 0, 0), (0, 0, 0), 0.0)      # segment vs point
    assert d.distance[0, 0] == pytest.approx(1.0) and d.robot_point[0, 0] == pytest.approx([0, 1, 0])


def test_overlapping_capsules_give_negative_distance_and_touching_axes_no_direction():
    d = pair((0, 0, 0), (1, 0, 0), 0.2, (0.5, 0.1, 0), (0.5, 1, 0), 0.2)
    assert d.distance[0, 0] == pytest.approx(0.1 - 0.4)
    d = pair((-1, 0, 0), (1, 0, 0), 0.1, (0, -1, 0), (0, 1, 0), 0.1)     # axes intersect
    assert d.distance[0, 0] == pytest.approx(-0.2)
    assert d.degenerate[0, 0] and np.all(d.normal[0, 0] == 0)


def test_all_pairs_shapes(rng):
    d = capsule_pair_distances(rng.normal(size=(7, 2, 3)), np.full(7, 0.05), rng.normal(size=(4, 2, 3)),
                               np.full(4, 0.1))
    assert d.distance.shape == (7, 4) and d.normal.shape == (7, 4, 3)
    empty = capsule_pair_distances(rng.normal(size=(7, 2, 3)), np.full(7, 0.05), np.zeros((0, 2, 3)), np.zeros(0))
    assert empty.distance.shape == (7, 0)


def _coal_capsule(a, b, r):
    axis = b - a
    length = float(np.linalg.norm(axis))
    z = axis / length if length > 0 else np.array([0.0, 0.0, 1.0])
    helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    rot = np.column_stack([x, np.cross(z, x), z])
    return coal.Capsule(r, length), coal.Transform3s(rot, (a + b) / 2)


coords = st.floats(-1.0, 1.0, allow_nan=False)
point = st.tuples(coords, coords, coords)


@given(a0=point, a1=point, b0=point, b1=point, ra=st.floats(0.01, 0.2), rb=st.floats(0.01, 0.2),
       collapse=st.sampled_from(["none", "robot", "human"]))
def test_distances_agree_with_coal(a0, a1, b0, b1, ra, rb, collapse):
    a0, a1, b0, b1 = map(np.array, (a0, a1, b0, b1))
    if collapse == "robot":
        a1 = a0.copy()
    elif collapse == "human":
        b1 = b0.copy()
    d = pair(a0, a1, ra, b0, b1, rb)
    ga, ta = _coal_capsule(a0, a1, ra)
    gb, tb = _coal_capsule(b0, b1, rb)
    res = coal.DistanceResult()
    expected = coal.distance(ga, ta, gb, tb, coal.DistanceRequest(), res)
    assert d.distance[0, 0] == pytest.approx(expected, abs=1e-6)
    # witness points lie on the segments and realise the axis distance
    gap = np.linalg.norm(d.human_point[0, 0] - d.robot_point[0, 0])
    assert gap == pytest.approx(d.distance[0, 0] + ra + rb, abs=1e-9)
    if not d.degenerate[0, 0]:
        assert np.linalg.norm(d.normal[0, 0]) == pytest.approx(1.0)


@given(a0=point, a1=point, b0=point, b1=point)
def test_closest_params_are_a_minimum(a0, a1, b0, b1):
    a0, a1, b0, b1 = map(np.array, (a0, a1, b0, b1))
    s, t = segment_closest_params(a0, a1, b0, b1)
    assert 0 <= s <= 1 and 0 <= t <= 1
    best = np.linalg.norm((a0 + s * (a1 - a0)) - (b0 + t * (b1 - b0)))
    grid = np.linspace(0, 1, 41)
    pa = a0 + grid[:, None] * (a1 - a0)
    pb = b0 + grid[:, None] * (b1 - b0)
    brute = np.linalg.norm(pa[:, None, :] - pb[None, :, :], axis=2).min()
    assert best <= brute + 1e-9
