"""ISO/TS 15066 SSM: hand-computed numbers with the default parameters, validation, per-pair speeds.

The paper's formula (human_acceleration 0) unless said otherwise. Defaults: T_r = 0.1, T_s = 0.3 (horizon
0.4 s), a_max = 5, C = 0, Z_d = 0.05, Z_r = 0.02, so the fixed
distance is 0.5 * 5 * 0.3^2 + 0.07 = 0.295 m.
"""

import math

import numpy as np
import pytest

from shared.core.errors import ConfigError
from shared.core.humans import HumanCapsules
from shared.safety.parameters import SsmParameters
from shared.safety.ssm import default_human_speed, pair_ssm, protective_separation_distance, velocity_limit

P = SsmParameters().paper_formula()      # the paper's formula: the measured human speed held


def test_fixed_terms_by_hand():
    assert P.horizon == pytest.approx(0.4)
    assert P.fixed_distance == pytest.approx(0.295)


def test_velocity_limit_is_the_papers_formula_by_hand():
    # (1.0 - 1.6*0.4 - 0.07)/0.4 - 5*0.09/(2*0.4) = 0.725 - 0.5625
    assert velocity_limit(1.0, 1.6, P) == pytest.approx(0.1625)
    assert velocity_limit(1.0, 0.0, P) == pytest.approx(1.7625)
    assert velocity_limit(0.3, 1.6, P) < 0           # too close: may not approach at all


def test_protective_distance_inverts_the_limit():
    assert protective_separation_distance(0.5, 1.6, P) == pytest.approx(2.1 * 0.4 + 0.295)
    for s in (0.4, 1.0, 2.5):
        for vh in (0.0, 1.6, 2.0):
            assert protective_separation_distance(velocity_limit(s, vh, P), vh, P) == pytest.approx(s)


def test_iso_13855_default_speeds():
    assert default_human_speed(np.array([0.2, 0.5, 0.51, 3.0]), P).tolist() == [2.0, 2.0, 1.6, 1.6]


@pytest.mark.parametrize("bad", [{"reaction_time": -0.1}, {"stopping_time": float("nan")},
                                 {"human_uncertainty": float("inf")}, {"reaction_time": "fast"},
                                 {"reaction_time": True}, {"unknown_key": 1}])
def test_bad_parameters_raise_a_clear_error(bad):
    with pytest.raises(ConfigError, match=r"ssm"):
        SsmParameters.from_mapping(bad)


def test_a_person_who_may_speed_up_comes_as_far_as_the_capped_acceleration_takes_them():
    """The shipped model: a person's approach speed may grow at a_h up to the ISO 13855 speed of the
    separation (2.0 m/s within 0.5 m, 1.6 m/s beyond) over T_r + T_s = 0.4 s. By hand, at a_h = 10 m/s^2: from
    rest at 0.4 m, 2.0 m/s is reached after 0.2 s: 0.2 m rising plus 0.4 m at 2.0 m/s = 0.6 m; at 1.0 m (cap
    1.6) after 0.16 s: 0.128 + 0.384 = 0.512 m. A person already at the cap (or untracked) keeps it: the
    ISO speeds' distance. a_h 0 is the paper's formula; a negative a_h is refused."""
    from shared.safety.ssm import human_distance, human_travel

    model = SsmParameters.from_mapping({"human_acceleration": 10.0})
    assert human_travel(0.0, 2.0, 10.0, 0.4) == pytest.approx(0.6)
    assert human_travel(0.0, 1.6, 10.0, 0.4) == pytest.approx(0.512)
    assert human_travel(0.5, 2.0, 1.0, 0.4) == pytest.approx(0.5 * 0.4 + 0.08)       # never reaches the cap
    assert human_travel(2.5, 2.0, 10.0, 0.4) == pytest.approx(1.0)                   # above the cap: held
    assert human_travel(0.7, 2.0, 0.0, 0.4) == pytest.approx(0.28)                   # the paper's formula
    assert velocity_limit(0.4, 0.0, model) == pytest.approx((0.4 - 0.6 - 0.295) / 0.4)
    assert velocity_limit(1.0, 0.0, model) == pytest.approx((1.0 - 0.512 - 0.295) / 0.4)
    for s in (0.3, 1.0, 2.5):
        assert velocity_limit(s, 2.0, model) == pytest.approx(velocity_limit(s, 2.0, P))
        assert velocity_limit(s, 0.3, P) > velocity_limit(s, 0.3, model) >= velocity_limit(s, 2.0, model)
    assert human_distance(np.array([0.0, 2.0]), model, np.array([0.4, 0.4])) == pytest.approx([0.6, 0.8])
    # the compiled kernel of the scaling layer and the planner says the same
    r = pair_ssm(np.array([[[0.0, 0, 0], [0.0, 0, 0]]]), np.array([0.1]), np.zeros((1, 2, 3)),
                 HumanCapsules.from_arrays([[[1.2, 0, 0], [1.2, 0, 0]]], [0.1], np.zeros((1, 2, 3)), [True]), model)
    assert r.limit[0, 0] == pytest.approx(velocity_limit(1.0, 0.0, model))
    with pytest.raises(ConfigError, match="human_acceleration"):
        SsmParameters.from_mapping({"human_acceleration": -1.0})


def test_the_shipped_default_covers_a_person_who_starts_to_move():
    """The built-in parameters (= deploy/cell.yaml) hold a person measured standing to less than the
    paper's formula does, and never to more than an untracked person."""
    shipped = SsmParameters()
    assert shipped.human_acceleration > 0
    for s in (0.3, 0.6, 1.0, 2.0):
        assert velocity_limit(s, 0.0, shipped) < velocity_limit(s, 0.0, P)
        assert velocity_limit(s, 0.0, shipped) >= velocity_limit(s, 2.0, shipped)


def _one_pair(human_velocity, known=True, distance_centres=1.0):
    robot = np.array([[[0.0, 0, 0], [0.0, 0, 0]]])                  # a sphere of radius 0.1 at the origin
    robot_vel = np.array([[[1.0, 0, 0], [1.0, 0, 0]]])              # moving towards +x at 1 m/s
    humans = HumanCapsules.from_arrays([[[distance_centres, 0, 0], [distance_centres, 0, 0]]], [0.1],
                                       [[human_velocity, human_velocity]], [known])
    return pair_ssm(robot, np.array([0.1]), robot_vel, humans, P)


def test_pair_speeds_and_limit_by_hand():
    r = _one_pair([-0.5, 0, 0])                       # human walks towards the robot at 0.5 m/s
    assert r.distance[0, 0] == pytest.approx(0.8)
    assert r.robot_speed[0, 0] == pytest.approx(1.0)
    assert r.human_speed[0, 0] == pytest.approx(0.5)
    assert r.limit[0, 0] == pytest.approx((0.8 - 0.2 - 0.295) / 0.4)
    assert r.margin[0, 0] == pytest.approx(0.7625 - 1.0)


def test_human_walking_away_counts_as_zero_not_negative():
    r = _one_pair([0.5, 0, 0])
    assert r.human_speed[0, 0] == 0.0
    assert r.limit[0, 0] == pytest.approx((0.8 - 0.295) / 0.4)


def test_untracked_human_takes_the_iso_13855_speed():
    assert _one_pair([0, 0, 0], known=False).human_speed[0, 0] == pytest.approx(1.6)
    assert _one_pair([0, 0, 0], known=False, distance_centres=0.6).human_speed[0, 0] == pytest.approx(2.0)


def test_sideways_motion_is_not_approach():
    r = _one_pair([0, 3.0, 0])
    assert r.human_speed[0, 0] == pytest.approx(0.0)


def test_fastest_end_of_a_segment_counts():
    robot = np.array([[[0.0, 0, 0], [0.0, 0, 1.0]]])                 # vertical link, rotating about its base
    robot_vel = np.array([[[0.0, 0, 0], [2.0, 0, 0]]])               # top moves at 2 m/s towards +x
    humans = HumanCapsules.from_arrays([[[1.0, 0, 0.0], [1.0, 0, 0.0]]], [0.0], np.zeros((1, 2, 3)), [True])
    r = pair_ssm(robot, np.array([0.0]), robot_vel, humans, P)
    assert r.distance[0, 0] == pytest.approx(1.0)      # closest point is the (still) base ...
    assert r.robot_speed[0, 0] == pytest.approx(2.0)   # ... but the link's fastest point counts


def test_touching_axes_count_full_speed():
    robot = np.array([[[-1.0, 0, 0], [1.0, 0, 0]]])
    humans = HumanCapsules.from_arrays([[[0, -1.0, 0], [0, 1.0, 0]]], [0.05], [[[0, 0, 0.3], [0, 0, 0.3]]], [True])
    r = pair_ssm(robot, np.array([0.05]), np.array([[[0, 0.4, 0], [0, 0.4, 0]]]), humans, P)
    assert r.robot_speed[0, 0] == pytest.approx(0.4) and r.human_speed[0, 0] == pytest.approx(0.3)
    assert r.limit[0, 0] < 0 and math.isfinite(r.limit[0, 0])
