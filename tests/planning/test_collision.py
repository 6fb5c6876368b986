"""The planning layer's collision model: known answers, the scene file, and the motion-check guarantee."""

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.scenarios import Q_GOAL, Q_START
from shared.core.errors import ConfigError
from shared.core.humans import HumanCapsules
from shared.planning.collision import CollisionMargins, CollisionModel, _segment_box
from shared.planning.scene import DEFAULT_SCENE, Scene, load_scene, scene_from_mapping
from shared.robot.model import CAPSULES_PATH, RobotModel, default_robot

ROBOT = default_robot()
UP = np.zeros(6)                       # straight up: flange sphere (r 0.033) centred at z = 1.0004


def sphere(centre, radius):
    c = np.asarray(centre, dtype=float)
    return HumanCapsules.from_arrays([[c, c]], [radius], np.zeros((1, 2, 3)), [True])


def test_human_clearance_by_hand():
    cm = CollisionModel(ROBOT, Scene(), min_separation=0.05)
    # a sphere 0.12 m above the flange sphere's centre: 0.12 - 0.033 - 0.05 = 0.037 m apart,
    # minus d_min 0.05 and the human margin 0.05: -0.063
    contact = cm.contact(UP, sphere([0, 0, 1.0004 + 0.12], 0.05))
    assert contact.kind == "human" and contact.clearance == pytest.approx(0.12 - 0.083 - 0.1, abs=1e-9)
    assert cm.clearance(UP, sphere([0, 0, 3.0], 0.05)) > 0.03           # far: the self pairs limit


def test_table_floor_limits_and_self_collision_are_named():
    scene = scene_from_mapping({"floor": {"z": 0.0}, "boxes": [{"name": "table", "center": [0.5, 0, 0.2],
                                                               "size": [0.4, 0.4, 0.4]}]})
    cm = CollisionModel(ROBOT, scene)
    down = np.array([0, 2.0, 0.3, 0, 0, 0])           # arm laid down towards +x, into the table
    assert cm.contact(down).kind == "box" and cm.contact(down).which == "table"
    cm_floor = CollisionModel(ROBOT, scene_from_mapping({"floor": {"z": 0.0}}))
    assert cm_floor.contact(np.array([0, 2.5, 0.0, 0, 0, 0])).kind == "floor"
    assert cm.contact(np.array([3.0, 0, 0, 0, 0, 0])).kind == "joint limits"


def test_self_pairs_are_checked(tmp_path):
    # with these capsules and the joint limits the enabled pairs never touch (as the facts sheet found);
    # a fatter forearm must make the link_2 / link_4 pair collide at q = 0
    doc = yaml.safe_load(CAPSULES_PATH.read_text())
    doc["capsules"]["prbt_link_4"]["radius"] = 0.12
    path = tmp_path / "caps.yaml"
    path.write_text(yaml.safe_dump(doc))
    contact = CollisionModel(RobotModel(capsules_path=path)).contact(UP)
    assert contact.kind == "self-collision" and contact.which == "prbt_link_2 / prbt_link_4"
    assert CollisionModel(ROBOT).contact(UP).kind == "free"


def test_paper_shuttle_ends_are_feasible_in_the_shipped_scene():
    cm = CollisionModel(ROBOT, load_scene(DEFAULT_SCENE))
    assert cm.feasible(Q_START) and cm.feasible(Q_GOAL)
    assert cm.motion_free(Q_START, Q_GOAL) == (True, 1.0)


def test_thin_obstacle_is_never_stepped_over():
    # Arm stretched out horizontally, joint 1 sweeping 2 rad: the flange (0.74 m out) moves 10.6 cm per
    # 0.143 rad, OMPL's default checking resolution for this space. A 2 mm wire placed between two of
    # those samples is missed by the sampled check and found by conservative advancement.
    a, b = np.array([1.0, 1.5708, 0, 0, 0, 0]), np.array([-1.0, 1.5708, 0, 0, 0, 0])
    n = int(np.ceil(np.abs(b - a).max() / 0.143))
    u_wire = (n // 2 + 0.5) / n
    flange = ROBOT.capsule_segments(a + u_wire * (b - a))[-1, 0]
    wire = {"capsules": [{"name": "wire", "a": list(flange + [0, 0, -0.3]), "b": list(flange + [0, 0, 0.3]),
                          "radius": 0.001}]}
    cm = CollisionModel(ROBOT, scene_from_mapping(wire), margins=CollisionMargins(static=0.0))
    sampled = [cm.feasible(a + u * (b - a)) for u in np.linspace(0, 1, n + 1)]
    assert all(sampled)                              # the resolution-based check steps over the wire
    free, t = cm.motion_free(a, b)
    assert not free and t < u_wire                   # ours stops before it
    assert cm.motion_free(a, a + 0.9 * u_wire * (b - a))[0]     # and the part before it is free


@settings(max_examples=40)
@given(st.integers(0, 2 ** 31 - 1))
def test_a_path_reported_free_is_free_everywhere_with_fewer_checks_than_segment_by_segment(seed):
    """path_free follows a whole path (a time law's knots, a search's candidates) by conservative
    advancement across its segments: free means every point keeps a clearance above zero, blocked means it
    really came close, and it never needs more configuration checks than motion_free segment by segment
    (which says the same wherever no knot sits within the tolerance of a collision)."""
    rng = np.random.default_rng(seed)
    lim = ROBOT.limits
    path = np.clip(rng.uniform(lim.lower * 0.6, lim.upper * 0.6) + np.cumsum(rng.uniform(-0.5, 0.5, (5, 6)), axis=0),
                   lim.lower, lim.upper)
    centre = rng.uniform([-0.8, -0.8, 0.1], [0.8, 0.8, 1.2], size=(2, 1, 3))
    humans = HumanCapsules.from_arrays(centre + rng.normal(scale=0.15, size=(2, 2, 3)), rng.uniform(0.005, 0.1, 2))
    one, each = CollisionModel(ROBOT, Scene(floor_z=0.0)), CollisionModel(ROBOT, Scene(floor_z=0.0))
    segment_by_segment = all(each.motion_free(a, b, humans)[0] for a, b in zip(path[:-1], path[1:]))
    free = one.path_free(path, humans)
    if free == segment_by_segment:
        assert one.checks <= each.checks + 1
    dense = one.clearances(np.concatenate([a + np.linspace(0, 1, 1001)[:, None] * (b - a)
                                           for a, b in zip(path[:-1], path[1:])]), humans)
    if free:
        assert dense.min() > 0.0
    else:
        assert dense.min() <= 0.05             # blocked means it really came close (within the step's slack)
    if free != segment_by_segment:             # only where a knot is within the tolerance of a collision
        assert one.clearances(path, humans).min() <= one.margins.tolerance


def test_a_time_laws_knots_are_checked_as_one_path_not_knot_by_knot():
    """A time law's knots are 10 ms apart: followed through, one check covers many of them."""
    cm = CollisionModel(ROBOT, Scene(floor_z=0.0))
    knots = Q_START + np.linspace(0.0, 1.0, 251)[:, None] * (Q_GOAL - Q_START)
    assert cm.path_free(knots) and cm.checks < 250 / 4


@settings(max_examples=60)
@given(st.integers(0, 2 ** 31 - 1))
def test_a_motion_reported_free_is_free_everywhere(seed):
    rng = np.random.default_rng(seed)
    lim = ROBOT.limits
    q0 = rng.uniform(lim.lower * 0.6, lim.upper * 0.6)
    q1 = q0 + rng.uniform(-1.0, 1.0, 6)
    q1 = np.clip(q1, lim.lower, lim.upper)
    centre = rng.uniform([-0.8, -0.8, 0.1], [0.8, 0.8, 1.2], size=(2, 1, 3))
    humans = HumanCapsules.from_arrays(centre + rng.normal(scale=0.15, size=(2, 2, 3)), rng.uniform(0.005, 0.1, 2))
    cm = CollisionModel(ROBOT, Scene(floor_z=0.0))
    if not (cm.feasible(q0, humans)):
        return
    free, _ = cm.motion_free(q0, q1, humans)
    dense = cm.clearances(q0 + np.linspace(0, 1, 3001)[:, None] * (q1 - q0), humans)
    if free:
        assert dense.min() > 0.0
    else:
        assert dense.min() <= 0.0 + 0.05       # blocked means it really came close (within the step's slack)


@given(st.lists(st.floats(-1, 1), min_size=6, max_size=6), st.lists(st.floats(0.05, 0.5), min_size=3, max_size=3))
def test_segment_box_distance_matches_brute_force(ends, half):
    a, b = np.array(ends[:3]), np.array(ends[3:])
    c, h = np.array([0.1, -0.2, 0.3]), np.array(half)
    got = _segment_box(a, b, c, h)
    ts = np.linspace(0, 1, 4001)
    pts = a + ts[:, None] * (b - a)
    d = np.abs(pts - c) - h
    sdf = np.linalg.norm(np.maximum(d, 0), axis=1) + np.minimum(d.max(axis=1), 0)
    assert got == pytest.approx(sdf.min(), abs=2e-3)        # the grid itself is 0.6 mm coarse
    assert got <= sdf.min() + 1e-9


@pytest.mark.parametrize("doc, field", [
    ({"boxes": [{"name": "t", "center": [0, 0], "size": [1, 1, 1]}]}, r"boxes\[0\]\.center"),
    ({"boxes": [{"name": "t", "center": [0, 0, 0], "size": [1, -1, 1]}]}, r"boxes\[0\]\.size"),
    ({"capsules": [{"a": [0, 0, 0], "b": [0, 0, 1]}]}, r"capsules\[0\].*missing \['radius'\]"),
    ({"floor": {"z": float("nan")}}, r"floor\.z"),
    ({"walls": []}, "unknown key"),
    ({"schema": "other/9"}, "schema"),
])
def test_bad_scene_files_name_the_field(doc, field):
    with pytest.raises(ConfigError, match=field):
        scene_from_mapping(doc)


def test_unreadable_scene_file(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        load_scene(tmp_path / "missing.yaml")
    (tmp_path / "bad.yaml").write_text("boxes: [")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_scene(tmp_path / "bad.yaml")
