"""The PRBT model: forward kinematics against the facts sheet, Jacobians against finite differences."""

import math

import numpy as np
import pinocchio as pin
import pytest
import yaml

from shared.core.errors import ConfigError
from shared.robot.model import CAPSULES_PATH, RobotModel, load_capsules

PI2 = math.pi / 2
# (q, flange position, flange quaternion xyzw) from ../shared/prbt/FACTS.md section 1.4
FK_VECTORS = [
    ([0, 0, 0, 0, 0, 0], (0, 0, 1.0014), (0, 0, 0, 1)),
    ([0, PI2, 0, 0, 0, 0], (0.741, 0, 0.2604), (0, 0.70711, 0, 0.70711)),
    ([0, 0, PI2, 0, 0, 0], (-0.391, 0, 0.6104), (0, 0.70711, 0, -0.70711)),
    ([PI2, 0, 0, 0, 0, 0], (0, 0, 1.0014), (0, 0, 0.70711, 0.70711)),
    ([0, 0, 0, 0, PI2, 0], (-0.084, 0, 0.9174), (0, 0.70711, 0, -0.70711)),
    ([0.3, -0.5, 1.2, 0.4, -0.8, 1.0], (-0.52036, -0.13640, 0.57550), (-0.32328, -0.33580, 0.58395, 0.66463)),
]


@pytest.mark.parametrize("q, pos, quat", FK_VECTORS)
def test_flange_pose_matches_the_facts_sheet(robot, q, pos, quat):
    pose = robot.flange_pose(np.array(q, dtype=float))
    assert np.allclose(pose.translation, pos, atol=1e-5)
    got = pin.Quaternion(pose.rotation).coeffs()           # x, y, z, w
    assert min(np.abs(got - quat).max(), np.abs(got + np.array(quat)).max()) < 1e-5


def test_straight_up_pose_by_hand(robot):
    # At q = 0 the arm stands straight up: the flange is L0 + L1 + L2 + L3 above the base.
    assert robot.frame_position(np.zeros(6), "prbt_flange") == pytest.approx([0, 0, 0.2604 + 0.35 + 0.307 + 0.084])
    # Joint 2 at +90 deg lays the arm along +x at the height of joint 2: reach 0.35 + 0.307 + 0.084.
    flange = robot.frame_position(np.array([0, PI2, 0, 0, 0, 0.0]), "prbt_flange")
    assert flange == pytest.approx([0.741, 0, 0.2604], abs=1e-9)


def test_capsules_in_base_frame_at_zero_match_the_facts_sheet(robot):
    # FACTS.md section 2.4, last column (a, b in the base frame at q = 0)
    expected = {
        "prbt_base_link": [(0, 0, 0.033), (0, 0, 0.056)],
        "prbt_link_1": [(0, 0, 0.204), (0, 0.021, 0.260)],
        "prbt_link_2": [(0, 0.118, 0.260), (0, 0.134, 0.610)],
        "prbt_link_3": [(0, 0.024, 0.610), (0, 0, 0.664)],
        "prbt_link_4": [(0, 0, 0.723), (0, 0.130, 0.914)],
        "prbt_link_5": [(0, 0.046, 0.917), (0, 0, 0.927)],
        "prbt_flange": [(0, 0, 1.0), (0, 0, 1.0)],
    }
    seg = robot.capsule_segments(np.zeros(6))
    for i, link in enumerate(robot.link_names):
        assert np.allclose(seg[i], expected[link], atol=1.5e-3), link


def test_point_jacobians_match_finite_differences(robot, rng):
    for _ in range(20):
        q = rng.uniform(robot.limits.lower, robot.limits.upper)
        qd = rng.normal(size=6)
        points, jac = robot.capsule_kinematics(q)
        h = 1e-6
        numeric = (robot.capsule_segments(q + h * qd) - robot.capsule_segments(q - h * qd)) / (2 * h)
        assert np.allclose(np.einsum("lpij,j->lpi", jac, qd), numeric, atol=1e-7)
        moved, velocities = robot.capsule_motion(q, qd)          # the Jacobians applied, never formed
        assert np.array_equal(moved, points)
        assert np.allclose(velocities, np.einsum("lpij,j->lpi", jac, qd), atol=1e-12)
        assert np.allclose(velocities, numeric, atol=1e-7)


def test_compiled_chain_matches_pinocchio(robot, rng):
    for _ in range(20):
        q = rng.uniform(robot.limits.lower, robot.limits.upper)
        pin.computeJointJacobians(robot.model, robot.data, q)
        pin.updateFramePlacements(robot.model, robot.data)
        seg = robot.capsule_segments(q)
        for i, cap in enumerate(robot.capsules):
            placement = robot.data.oMf[robot.model.getFrameId(cap.link)]
            assert np.allclose(seg[i], [placement.act(cap.a), placement.act(cap.b)], atol=1e-12)
        # the flange origin's Jacobian equals pinocchio's linear frame Jacobian
        j_pin = pin.getFrameJacobian(robot.model, robot.data, robot.flange_frame, pin.LOCAL_WORLD_ALIGNED)[:3]
        assert np.allclose(robot.point_jacobian(q, "prbt_flange", np.zeros(3)), j_pin, atol=1e-12)


def test_point_jacobian_of_any_point_on_a_link(robot, rng):
    q = rng.uniform(robot.limits.lower, robot.limits.upper)
    local = np.array([0.05, -0.02, 0.1])
    jac = robot.point_jacobian(q, "prbt_link_4", local)

    def place(qq):
        pin.framesForwardKinematics(robot.model, robot.data, qq)
        return robot.data.oMf[robot.model.getFrameId("prbt_link_4")].act(local)

    for k in range(6):
        e = np.zeros(6)
        e[k] = 1e-6
        assert np.allclose((place(q + e) - place(q - e)) / 2e-6, jac[:, k], atol=1e-7)
    assert np.all(jac[:, 4:] == 0.0)          # joints 5 and 6 do not move link 4


def test_base_capsule_never_moves(robot, rng):
    _, jac = robot.capsule_kinematics(rng.uniform(-1, 1, 6))
    assert np.all(jac[0] == 0.0)
    assert not robot.moving_links[0] and robot.moving_links[1:].all()


def test_limits_are_arrays_from_the_urdf_and_limit_file(robot):
    lim = robot.limits
    assert lim.upper == pytest.approx([2.96706, 2.53073, 2.35620, 2.96706, 2.96706, 3.12414])
    assert np.array_equal(lim.lower, -lim.upper)
    assert lim.velocity == pytest.approx([1.57] * 6)
    assert lim.acceleration == pytest.approx([3.49] * 6)
    assert lim.within(np.zeros(6)) and not lim.within(np.array([3.0, 0, 0, 0, 0, 0]))


def test_capsule_file_errors_name_the_field(tmp_path):
    doc = yaml.safe_load(CAPSULES_PATH.read_text())
    doc["capsules"]["prbt_link_2"]["radius"] = -0.1
    bad = tmp_path / "caps.yaml"
    bad.write_text(yaml.safe_dump(doc))
    with pytest.raises(ConfigError, match=r"prbt_link_2\.radius"):
        load_capsules(bad)
    doc["capsules"]["prbt_link_2"] = {"a": [0, 0], "b": [0, 0, 1], "radius": 0.1}
    bad.write_text(yaml.safe_dump(doc))
    with pytest.raises(ConfigError, match=r"prbt_link_2\.a"):
        load_capsules(bad)
    bad.write_text("capsules: [")
    with pytest.raises(ConfigError, match="cannot read"):
        load_capsules(bad)
    with pytest.raises(ConfigError):
        RobotModel(capsules_path=tmp_path / "missing.yaml")
