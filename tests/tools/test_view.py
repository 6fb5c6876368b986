"""The 3D view: capsule poses, the closest pair, and a recording written and read back."""

import numpy as np
import pytest
from rerun.chunk import RrdReader

from evidence.scenarios import Q_GOAL, Q_START
from shared.core.geometry import capsule_frames
from shared.core.humans import HumanCapsules
from shared.core.trajectory import straight_line_trajectory
from shared.robot.model import default_robot
from shared.safety.parameters import SsmParameters
from shared.safety.ssm import pair_ssm
from shared.wire.convert import trajectory_to_msg
from shared.wire.messages import HumanState, JointCommand, JointState, ScalerStatus
from tools.view import closest_pair, write_recording

ROBOT = default_robot()
SSM = SsmParameters()


def rotate(quat: np.ndarray, v: np.ndarray) -> np.ndarray:
    x, y, z, w = quat
    u = np.array([x, y, z])
    return 2 * u.dot(v) * u + (w * w - u.dot(u)) * v + 2 * w * np.cross(u, v)


def test_capsule_frames_turn_plus_z_onto_each_axis():
    seg = np.array([[[0, 0, 0], [0, 0, 2.0]], [[1, 1, 1], [1, 1, -1.0]], [[0, 0, 0], [3.0, 4.0, 0]],
                    [[5, 5, 5], [5, 5, 5.0]]])
    start, quat, length = capsule_frames(seg)
    assert np.allclose(start, seg[:, 0]) and np.allclose(length, [2.0, 2.0, 5.0, 0.0])
    assert np.allclose(np.linalg.norm(quat, axis=1), 1.0)
    for k in range(3):
        axis = (seg[k, 1] - seg[k, 0]) / length[k]
        assert np.allclose(rotate(quat[k], np.array([0.0, 0.0, 1.0])), axis)
    assert np.allclose(quat[3], [0, 0, 0, 1])                 # a sphere: no rotation


def test_the_closest_pair_is_the_one_nearest_its_limit():
    flange = ROBOT.capsule_segments(Q_START)[-1, 1]
    seg = np.array([[flange + [0.5, 0, 0], flange + [0.5, 0, 0.3]], [[-3.0, 0, 0.9], [-3.0, 0, 1.5]]])
    radii, vel, known = np.array([0.05, 0.17]), np.zeros((2, 2, 3)), np.ones(2, bool)
    qd = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    pair = closest_pair(ROBOT, Q_START, qd, seg, radii, vel, known, SSM)
    points, jac = ROBOT.capsule_kinematics(Q_START)
    full = pair_ssm(points, ROBOT.radii, jac @ qd, HumanCapsules(seg, radii, vel, known), SSM,
                    SSM.stop_of(qd, ROBOT.limits.velocity))
    margin = np.maximum(full.limit, 0.0) - full.robot_speed
    i, j = np.unravel_index(np.argmin(margin), margin.shape)
    assert j == 0 and pair.separation == pytest.approx(full.distance[i, j])
    assert pair.approach == pytest.approx(full.robot_speed[i, j]) and pair.limit == pytest.approx(full.limit[i, j])
    gap = np.linalg.norm(pair.human_point - pair.robot_point) - ROBOT.radii[i] - radii[0]
    assert gap == pytest.approx(pair.separation, abs=1e-9)
    assert closest_pair(ROBOT, Q_START, qd, np.zeros((0, 2, 3)), np.zeros(0), np.zeros((0, 2, 3)),
                        np.zeros(0, bool), SSM) is None


def test_a_recording_holds_every_kind_of_message_and_reads_back(tmp_path):
    traj = straight_line_trajectory(Q_START, Q_GOAL, ROBOT.limits.velocity, ROBOT.limits.acceleration, version=3)
    human = HumanState(segments=np.array([[[-1.0, 0, 0.9], [-1.0, 0, 1.5]]]), radii=np.array([0.17]),
                       velocities=np.zeros((1, 2, 3)), velocity_known=np.ones(1, bool), valid=True, sample_stamp=0.0,
                       stamp=99.99)
    messages = [human, trajectory_to_msg(traj, 1, "horizon", 0.2, 2, stamp=100.05)]
    for k in range(10):
        t = 100.0 + 0.01 * k
        q, qd, _ = traj.sample(0.01 * k)
        messages += [JointState(q=q, qd=qd, drive_state="enabled", enabled=True, fault=False, stamp=t),
                     JointCommand(q=q, qd=qd, trajectory_version=3, s=0.01 * k, stamp=t),
                     ScalerStatus(s=0.01 * k, alpha=1.0, safe_alpha=1.0, beta=False, q_command=q, trajectory_version=3,
                                  status="running", method="piqp", min_separation=0.5, min_margin=1.0, compute_us=50.0,
                                  stamp=t)]
    path = tmp_path / "recording.rrd"
    assert write_recording(path, ROBOT, SSM, messages[::-1], t0=100.0) == len(messages)   # any order in
    rows: dict[str, int] = {}
    for chunk in RrdReader(path).stream():
        rows[chunk.entity_path] = rows.get(chunk.entity_path, 0) + chunk.num_rows
    assert rows["/world/robot/measured"] == 10 and rows["/world/robot/commanded"] == 10
    assert rows["/world/humans"] == 1 and rows["/world/planner/merged"] == 1
    assert rows["/scaling/alpha"] == 10 and rows["/scaling/beta"] == 10
    assert rows["/world/ssm/closest"] == 10 and rows["/ssm/approach"] == 10 and rows["/ssm/limit"] == 10
    assert rows["/world/planner/current"] == 1                  # the followed trajectory's path, once


