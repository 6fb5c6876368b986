"""The scaling problem: piqp and the closed form agree; alpha in [0, 1]; every SSM row holds; alpha never
rises when a human comes closer or faster; safety beats the acceleration limits."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from shared.core.humans import HumanCapsules
from shared.core.trajectory import straight_line_trajectory
from shared.robot.model import default_robot
from shared.safety.parameters import SsmParameters
from shared.scaling.problem import PiqpScalingSolver, build_rows, solve, solve_closed_form

ROBOT = default_robot()
SSM = SsmParameters()
WEIGHT = 100.0
PIQP = PiqpScalingSolver(WEIGHT)
QS = np.array([1.57, -0.4, 1.17, 0, 1.57, 0])
QG = np.array([-1.57, -0.4, 1.17, 0, 1.57, 0])
TRAJ = straight_line_trajectory(QS, QG, ROBOT.limits.velocity, ROBOT.limits.acceleration)


@st.composite
def cycles(draw):
    """A random cycle: a point on the paper's shuttle, a previous path speed, and 1-6 human capsules
    around the robot (some untracked, some overlapping it)."""
    s = draw(st.floats(0.0, TRAJ.duration))
    sdot_prev = draw(st.floats(0.0, 1.0))
    m = draw(st.integers(1, 6))
    seed = draw(st.integers(0, 2 ** 31 - 1))
    rng = np.random.default_rng(seed)
    centre = rng.uniform([-1.2, -1.2, 0.0], [1.2, 1.2, 1.6], size=(m, 1, 3))
    segments = centre + rng.normal(scale=0.2, size=(m, 2, 3))
    humans = HumanCapsules.from_arrays(segments, rng.uniform(0.03, 0.2, m), rng.normal(scale=1.0, size=(m, 2, 3)),
                                       rng.random(m) < 0.8)
    return s, sdot_prev, humans


def rows_for(s, sdot_prev, humans):
    q, dq, ddq = TRAJ.sample(s)
    return build_rows(ROBOT, q, dq, ddq, 1.0, sdot_prev, humans, SSM, 0.01)


@given(cycles())
def test_piqp_and_closed_form_agree_and_respect_every_hard_row(cycle):
    rows = rows_for(*cycle)
    a_cf = solve(rows, WEIGHT, None)
    a_qp = solve(rows, WEIGHT, PIQP)
    binding = not np.all(rows.soft_coef * rows.upper <= rows.soft_bound)     # an acceleration row binds at upper
    assert a_qp.method == ("piqp" if binding else "presolved") and a_cf.method in ("closed_form", "presolved")
    assert 0.0 <= a_cf.alpha <= 1.0 and 0.0 <= a_qp.alpha <= 1.0
    assert a_qp.alpha == pytest.approx(a_cf.alpha, abs=1e-6)
    # the presolve is exact: the solvers themselves agree with it
    assert PIQP.solve(rows) == pytest.approx(a_qp.alpha, abs=1e-6)
    assert solve_closed_form(rows, WEIGHT) == pytest.approx(a_cf.alpha, abs=1e-9)
    for alpha in (a_cf.alpha, a_qp.alpha):
        assert np.all(rows.hard_coef * alpha <= rows.hard_bound + 1e-12)
    # and the SSM rows themselves: approach speed at alpha within max(limit, 0), each limit at the T_s of upper
    assert np.all(rows.state.robot_speed * a_qp.alpha <= np.maximum(rows.state.limit, 0) + 1e-12)


@given(cycles(), st.floats(0.0, 0.3), st.floats(1.0, 3.0))
def test_alpha_never_rises_when_a_human_comes_closer_or_faster(cycle, grow, faster):
    s, sdot_prev, h = cycle
    base = solve_closed_form(rows_for(s, sdot_prev, h), WEIGHT)
    # closer: a larger radius brings every surface nearer without changing any direction
    closer = HumanCapsules(h.segments, h.radii + grow, h.velocities, h.velocity_known)
    assert solve_closed_form(rows_for(s, sdot_prev, closer), WEIGHT) <= base + 1e-12
    # faster: every tracked velocity scaled up
    quicker = HumanCapsules(h.segments, h.radii, h.velocities * faster, h.velocity_known)
    assert solve_closed_form(rows_for(s, sdot_prev, quicker), WEIGHT) <= base + 1e-12
    assert solve(rows_for(s, sdot_prev, quicker), WEIGHT, PIQP).alpha <= base + 1e-6


def test_no_human_gives_full_speed_in_cruise():
    rows = rows_for(1.2, 1.0, HumanCapsules.empty())
    assert rows.upper == 1.0 and solve(rows, WEIGHT, PIQP).alpha == pytest.approx(1.0, abs=1e-6)


def test_acceleration_limits_ramp_the_speed_up_after_a_stop():
    # cruising joint 1 at 1.57 rad/s from rest: one 10 ms cycle may add 3.49 * 0.01 / 1.57 of alpha
    rows = rows_for(1.2, 0.0, HumanCapsules.empty())
    assert solve(rows, WEIGHT, PIQP).alpha == pytest.approx(3.49 * 0.01 / 1.57, rel=1e-4)
    assert solve_closed_form(rows, WEIGHT) == pytest.approx(3.49 * 0.01 / 1.57, rel=1e-9)


def test_safety_beats_the_acceleration_limit():
    # at full speed, a human capsule right on the flange's path: alpha must drop to 0 at once,
    # although that is far beyond the deceleration limit (the slack pays for it)
    q, dq, _ = TRAJ.sample(1.2)
    points, jac = ROBOT.capsule_kinematics(q)
    flange, heading = points[-1, 0], jac[-1, 0] @ dq
    ahead = flange + 0.15 * heading / np.linalg.norm(heading)
    humans = HumanCapsules.from_arrays([[ahead, ahead + [0, 0, 0.01]]], [0.05], np.zeros((1, 2, 3)), [True])
    rows = rows_for(1.2, 1.0, humans)
    sol = solve(rows, WEIGHT, PIQP)
    assert rows.upper == 0.0 and sol.alpha == 0.0 and rows.slack(sol.alpha) > 10


def test_a_failing_piqp_falls_back_to_the_closed_form():
    class Broken(PiqpScalingSolver):
        def solve(self, rows):
            return None
    rows = rows_for(1.2, 0.0, HumanCapsules.empty())          # ramping up from rest: the acceleration binds
    sol = solve(rows, WEIGHT, Broken(WEIGHT))
    assert sol.method == "closed_form_fallback" and sol.alpha == pytest.approx(3.49 * 0.01 / 1.57, rel=1e-9)
    cruise = solve(rows_for(1.2, 1.0, HumanCapsules.empty()), WEIGHT, Broken(WEIGHT))
    assert cruise.method == "presolved" and cruise.alpha == 1.0          # nothing binds: no solver needed
