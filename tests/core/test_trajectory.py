"""Nominal trajectories: Hermite knots, derivatives, and the straight-line law within the limits."""

import numpy as np
import pytest

from shared.core.trajectory import Trajectory, straight_line_trajectory, trapezoid_profile

QS = np.array([1.57, -0.4, 1.17, 0, 1.57, 0])
QG = np.array([-1.57, -0.4, 1.17, 0, 1.57, 0])


def test_knots_are_reproduced_and_derivatives_are_consistent(robot):
    traj = straight_line_trajectory(QS, QG, robot.limits.velocity, robot.limits.acceleration)
    q, dq, _ = traj.sample(traj.times)
    assert np.allclose(q, traj.positions) and np.allclose(dq, traj.velocities)
    s = np.linspace(0.01, traj.duration - 0.01, 200)
    h = 1e-6
    numeric = (traj.sample(s + h)[0] - traj.sample(s - h)[0]) / (2 * h)
    assert np.allclose(traj.sample(s)[1], numeric, atol=1e-5)


def test_straight_line_respects_the_limits_and_starts_and_ends_at_rest(robot):
    lim = robot.limits
    traj = straight_line_trajectory(QS, QG, lim.velocity, lim.acceleration)
    s = np.linspace(0, traj.duration, 2000)
    q, dq, ddq = traj.sample(s)
    assert np.all(np.abs(dq) <= lim.velocity + 1e-9)
    assert np.all(np.abs(ddq) <= lim.acceleration * 1.01)
    assert np.allclose(q[0], QS) and np.allclose(q[-1], QG)
    assert np.allclose(dq[0], 0) and np.allclose(dq[-1], 0)
    # joint 1 moves 3.14 rad at 1.57 rad/s and 3.49 rad/s^2: trapezoid of 2.0 + 0.45 s
    assert traj.duration == pytest.approx(3.14 / 1.57 + 1.57 / 3.49, rel=1e-9)


def test_trapezoid_triangle_case():
    duration, peak, t_acc = trapezoid_profile(0.1, 1.57, 3.49)
    assert peak < 1.57 and duration == pytest.approx(2 * np.sqrt(0.1 / 3.49))


def test_sample_clamps_outside_the_range(robot):
    traj = straight_line_trajectory(QS, QG, robot.limits.velocity, robot.limits.acceleration)
    assert np.allclose(traj.sample(-1.0)[0], QS) and np.allclose(traj.sample(99.0)[0], QG)


@pytest.mark.parametrize("times", [[0.0], [0.1, 0.2], [0.0, 0.0, 1.0], [0.0, np.nan]])
def test_bad_knots_are_rejected(times):
    n = len(times)
    with pytest.raises(ValueError):
        Trajectory(np.array(times), np.zeros((n, 6)), np.zeros((n, 6)))
