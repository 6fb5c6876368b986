"""ISO/TS 15066 SSM: hand-computed numbers with the default parameters, validation, per-pair speeds.

The paper's formula (human_acceleration 0) unless said otherwise. The defaults with T_r = 0.1 (``BY_HAND``: the
shipped 0.05 covers the cell's own chain alone; the hand numbers are the formula's at any T_r), T_s = 0.3
(horizon 0.4 s), a_max = 5, C = 0, Z_d = 0.05, Z_r = 0.02, so the fixed distance is 0.5 * 5 * 0.3^2 + 0.07 =
0.295 m.
"""

import math
from dataclasses import replace

import numpy as np
import pytest

from shared.core.errors import ConfigError
from shared.core.humans import HumanCapsules
from shared.safety.parameters import SsmParameters
from shared.safety.ssm import (
    NEAR_RAMP,
    default_human_speed,
    human_distance,
    human_travel,
    pair_ssm,
    protective_separation_distance,
    velocity_limit,
)

BY_HAND = SsmParameters(reaction_time=0.1)   # the shipped model with T_r 0.1 s: a horizon of 0.4 s
P = BY_HAND.paper_formula()      # the paper's formula: the measured human speed held


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
    """ISO 13855's 2.0 m/s within 0.5 m and 1.6 m/s beyond, the step made a ramp over NEAR_RAMP that is never
    below the standard's speed and has no jump."""
    assert default_human_speed(np.array([0.2, 0.5, 0.5 + NEAR_RAMP, 3.0]), P).tolist() == pytest.approx([2.0, 2.0, 1.6, 1.6])
    d = np.linspace(0.0, 1.5, 1501)
    speed = default_human_speed(d, P)
    assert np.all(speed >= np.where(d <= 0.5, 2.0, 1.6)) and np.all(np.diff(speed) <= 0.0)
    assert np.abs(np.diff(speed)).max() < 0.01


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

    model = SsmParameters.from_mapping({"human_acceleration": 10.0, "reaction_time": 0.1})
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
    shipped = BY_HAND
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


def test_the_stopping_time_follows_the_robots_speed():
    """T_s of a state is stopping_time x the fastest joint's share of its velocity limit, at least
    min_stopping_time; the paper's formula has one T_s; a floor above T_s is refused."""
    shipped = BY_HAND
    limits = np.full(6, 1.57)
    assert shipped.stop_scales and not P.stop_scales and P.min_stopping_time == P.stopping_time
    assert shipped.stop_of(np.array([0.0, 1.57, 0, 0, 0, 0]), limits) == pytest.approx(0.30)
    assert shipped.stop_of(np.array([0.0, -0.785, 0.1, 0, 0, 0]), limits) == pytest.approx(0.15)
    assert shipped.stop_of(np.zeros(6), limits) == pytest.approx(shipped.min_stopping_time)
    assert P.stop_of(np.zeros(6), limits) == pytest.approx(0.30)
    # the formula at a state's own T_s: the limit of the full-speed T_s at 0.3 s, higher for a shorter stop
    for s in (0.3, 0.6, 1.0):
        assert velocity_limit(s, 0.0, shipped, 0.30) == pytest.approx(velocity_limit(s, 0.0, shipped))
        slower = [velocity_limit(s, 0.0, shipped, stop) for stop in (0.05, 0.15, 0.30)]
        assert slower[0] > slower[1] > slower[2]
    # by hand: T_s 0.05 s, a person standing 0.4 m away (2.0 m/s within 0.5 m, reached within 0.04 s)
    travel = 0.5 * 50.0 * 0.04 ** 2 + 2.0 * (0.15 - 0.04)
    assert velocity_limit(0.4, 0.0, shipped, 0.05) == pytest.approx((0.4 - travel - 2.5 * 0.05 ** 2 - 0.07) / 0.15)
    with pytest.raises(ConfigError, match="min_stopping_time"):
        SsmParameters.from_mapping({"min_stopping_time": 0.4})


@pytest.mark.parametrize("seed", range(6))
def test_the_path_speed_bound_is_where_the_limit_at_its_own_stop_holds(seed):
    """speed_alpha_bound: at the bound every approaching pair is within its limit at the bound's T_s, a little
    faster some pair is not (unless the bound is 1), every alpha below is allowed, and it is never below the
    bound of the full-speed T_s; with one T_s it is that bound exactly."""
    from shared.safety.ssm import _pair_ssm_kernel, fixed_stop_alpha_bound, speed_alpha_bound

    rng = np.random.default_rng(seed)
    shipped = BY_HAND
    robot = rng.uniform(-0.3, 0.3, (4, 2, 3))
    robot_vel = rng.normal(scale=0.8, size=(4, 2, 3))
    humans = HumanCapsules.from_arrays(rng.uniform(0.2, 0.9, (3, 2, 3)), rng.uniform(0.05, 0.12, 3),
                                       rng.normal(scale=0.5, size=(3, 2, 3)), [True, False, True])
    margin, fraction = shipped.tracking_margin, float(rng.uniform(0.3, 1.0))

    def allowed(alpha, ssm):
        stop = ssm.stop_at(alpha * fraction)
        pairs = pair_ssm(robot, np.full(4, 0.05), robot_vel, humans, ssm, stop)
        moving = pairs.robot_speed > 1e-12
        return bool(np.all(alpha * pairs.robot_speed[moving] <= np.maximum(pairs.limit[moving] - margin, 0.0) + 1e-12))

    for ssm in (shipped, shipped.paper_formula()):
        k = _pair_ssm_kernel(robot, np.full(4, 0.05), robot_vel, humans.segments, humans.radii, humans.velocities,
                             humans.velocity_known, *ssm.kernel_constants)
        bound = speed_alpha_bound(*k, fraction, *ssm.stop_constants, *ssm.kernel_constants[2:], margin)
        one_stop = fixed_stop_alpha_bound(k[1], k[3] - margin)
        assert bound >= one_stop - 1e-12 and allowed(bound, ssm)
        assert all(allowed(a, ssm) for a in np.linspace(0.0, bound, 9))
        if bound < 1.0:
            assert not allowed(bound + 2e-4, ssm) or bound == pytest.approx(one_stop)
        if not ssm.stop_scales:
            assert bound == one_stop


def _every_pair_bisection(dist, robot_speed, human_speed, limit, fraction, stop_full, stop_min, reaction, a_stop, static,
                          near_d, v_near, v_far, a_h, lead, margin):
    """speed_alpha_bound as it was written before session 85: every approaching pair asked at 1, then at each of
    the 14 halvings of [the one-T_s bound, 1]."""
    from shared.safety.ssm import BISECTIONS, fixed_stop_alpha_bound, limit_at, stop_of_speed

    def allowed(alpha):
        stop = stop_of_speed(alpha, fraction, stop_full, stop_min)
        moving = np.argwhere(robot_speed > 1e-12)
        return all(alpha * robot_speed[i, k] <= max(limit_at(dist[i, k], human_speed[i, k], stop, reaction, a_stop,
                                                              static, near_d, v_near, v_far, a_h, lead) - margin, 0.0)
                   for i, k in moving)

    low = fixed_stop_alpha_bound(robot_speed, limit - margin)
    if stop_min >= stop_full or low >= 1.0:
        return low
    if fraction > 1.0:
        low = min(low, 1.0 / fraction)
    if allowed(1.0):
        return 1.0
    high = 1.0
    for _ in range(BISECTIONS):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if allowed(middle) else (low, middle)
    return low


@pytest.mark.parametrize("seed", range(4))
def test_the_path_speed_bound_asks_pair_by_pair_for_the_point_every_pair_bisection_finds(seed):
    """speed_alpha_bound asks the pairs in turn, bisecting only one that refuses the highest point found so far: the
    same float, to the last bit, as asking every pair at every halving, for robots and people drawn at random near
    each other (a bound of 0, of 1 and in between among them), with and without T_s following the speed."""
    from shared.safety.ssm import _pair_ssm_kernel, speed_alpha_bound

    rng = np.random.default_rng(100 + seed)
    seen = set()
    for _ in range(150):
        robot = rng.uniform(-0.4, 0.4, (5, 2, 3))
        robot_vel = rng.normal(scale=1.0, size=(5, 2, 3))
        known = rng.uniform(size=4) < 0.8
        humans = HumanCapsules.from_arrays(rng.uniform(0.0, 1.2, (4, 2, 3)), rng.uniform(0.04, 0.12, 4),
                                           rng.normal(scale=0.6, size=(4, 2, 3)), known)
        fraction = float(rng.uniform(0.1, 1.2))
        for ssm in (BY_HAND, BY_HAND.paper_formula()):
            k = _pair_ssm_kernel(robot, np.full(5, 0.05), robot_vel, humans.segments, humans.radii,
                                 humans.velocities, humans.velocity_known, *ssm.kernel_constants)
            args = (*k, fraction, *ssm.stop_constants, *ssm.kernel_constants[2:], ssm.tracking_margin)
            bound = speed_alpha_bound(*args)
            assert bound == _every_pair_bisection(*args)
            seen.add(0.0 if bound == 0.0 else 1.0 if bound == 1.0 else 0.5)
    assert seen == {0.0, 0.5, 1.0}


def test_a_robot_that_creeps_may_pass_a_person_where_one_at_full_speed_may_not():
    """A link 0.6 m from a person standing, approaching at 1 m/s at full path speed: with one T_s the link may
    not approach at all (0.6 m is inside the 0.91 m no-approach distance); with T_s following the speed it may,
    slowly, and not at full speed."""
    from shared.safety.ssm import _pair_ssm_kernel, speed_alpha_bound

    shipped = BY_HAND
    robot, robot_vel = np.array([[[0.0, 0, 0], [0.0, 0, 0]]]), np.array([[[1.0, 0, 0], [1.0, 0, 0]]])
    humans = HumanCapsules.from_arrays([[[0.8, 0, 0], [0.8, 0, 0]]], [0.1], np.zeros((1, 2, 3)), [True])
    bounds = {}
    for name, ssm in (("scaling", shipped), ("one", replace(shipped, min_stopping_time=shipped.stopping_time))):
        k = _pair_ssm_kernel(robot, np.array([0.1]), robot_vel, humans.segments, humans.radii, humans.velocities,
                             humans.velocity_known, *ssm.kernel_constants)
        bounds[name] = speed_alpha_bound(*k, 1.0, *ssm.stop_constants, *ssm.kernel_constants[2:], ssm.tracking_margin)
    assert bounds["one"] == 0.0 and 0.2 < bounds["scaling"] < 0.8


def test_data_that_took_a_while_to_come_counts_the_persons_travel_since_its_capture():
    """A person seen as they were 30 ms ago (the data's age: a camera's latency, the wait for its next frame): the
    human's part of S_p is their travel under the human model over those 30 ms and T_r + T_s, from the capture,
    at the ISO speed of the nearer separation they may have reached by then. The paper's formula by hand: 0.5 m/s
    over 0.43 s; the shipped model: the capped acceleration over 0.43 s (a start within the 30 ms counted, as one
    within T_r: T_r covers only the cell's chain from the tick). Every kernel that takes the constants agrees
    (the pair kernel, the per-state limit, the human's distance)."""
    late = P.aged(0.03)
    assert late.human_lead == pytest.approx(0.03) and P.human_lead == 0.0
    r = pair_ssm(np.array([[[0.0, 0, 0], [0.0, 0, 0]]]), np.array([0.1]), np.array([[[1.0, 0, 0], [1.0, 0, 0]]]),
                 HumanCapsules.from_arrays([[[1.0, 0, 0], [1.0, 0, 0]]], [0.1], [[[-0.5, 0, 0], [-0.5, 0, 0]]], [True]),
                 late)
    assert r.limit[0, 0] == pytest.approx((0.8 - 0.5 * 0.43 - 0.295) / 0.4)
    assert velocity_limit(0.8, 0.5, late) == pytest.approx(r.limit[0, 0])
    shipped = BY_HAND
    a_h = shipped.human_acceleration
    ahead = human_travel(0.5, float(default_human_speed(0.9, shipped)), a_h, 0.03)
    cap = default_human_speed(0.9 - ahead, shipped)               # where they may be by now: a higher ISO speed
    travel = human_travel(0.5, float(cap), a_h, 0.43)              # a start within the 30 ms counted once
    assert travel > 0.5 * 0.03 + human_travel(0.5, float(cap), a_h, 0.4)
    assert velocity_limit(0.9, 0.5, shipped.aged(0.03)) == pytest.approx((0.9 - travel - shipped.fixed_distance) / 0.4)
    assert velocity_limit(0.9, 0.5, shipped.aged(0.03)) < velocity_limit(0.9, 0.5, shipped)
    assert human_distance(0.5, shipped.aged(0.03), 0.9) == pytest.approx(travel)
    unknown = HumanCapsules.from_arrays([[[1.3, 0, 0], [1.3, 0, 0]]], [0.1], np.zeros((1, 2, 3)), [False])
    far = pair_ssm(np.array([[[0.0, 0, 0], [0.0, 0, 0]]]), np.array([0.1]), np.zeros((1, 2, 3)), unknown,
                   shipped.aged(0.05))
    assert far.human_speed[0, 0] == pytest.approx(float(default_human_speed(1.1 - 0.1, shipped)))


def test_a_delay_is_rounded_up_to_the_millisecond_kept_and_never_a_setting():
    """aged: 12.2 ms counts as 13 ms (never less), the same delay gives the same parameters (a cycle does not
    build new ones), a NaN or negative delay is refused (it is a stale-data stop, not a limit), and a cell's
    configuration cannot set human_lead: the cell sets it as it runs."""
    shipped = BY_HAND
    assert shipped.aged(0.0122).human_lead == pytest.approx(0.013)
    assert shipped.aged(0.013).human_lead == pytest.approx(0.013)
    assert shipped.aged(0.0122) is shipped.aged(0.0125) and shipped.aged(0.0) is shipped
    for bad in (float("nan"), float("inf"), -0.01):
        with pytest.raises(ValueError, match="delay"):
            shipped.aged(bad)
    with pytest.raises(ConfigError, match="unknown key"):
        SsmParameters.from_mapping({"human_lead": 0.03})


def test_a_robot_point_may_approach_a_person_seen_late_in_any_direction_they_may_have_turned_to():
    """approach_within by hand: the largest projection of a velocity on a direction within an angle of n."""
    from shared.safety.ssm import approach_within

    assert approach_within(0.3, 1.0, 0.0) == 0.3                          # no doubt: the projection itself
    assert approach_within(0.0, 1.0, 0.1) == pytest.approx(0.1)           # sideways: speed x sin
    assert approach_within(1.0, 1.0, 0.1) == pytest.approx(1.0)           # straight at them: all of it
    assert approach_within(0.999, 1.0, 0.1) == pytest.approx(1.0)         # within the angle: all of it
    away = approach_within(-1.0, 1.0, 0.1)
    assert away == pytest.approx(-math.sqrt(1 - 0.01)) and away < 0.0     # away, still away
    assert approach_within(0.6, 1.0, 0.6) == pytest.approx(0.6 * 0.8 + 0.8 * 0.6)
    for along, speed, doubt in ((0.2, 0.5, 0.3), (-0.4, 0.5, 0.9), (0.0, 2.0, 1.0)):
        worst = max(speed * math.cos(max(0.0, math.acos(along / speed) - a)) for a in np.linspace(0, math.asin(doubt), 200))
        assert approach_within(along, speed, doubt) == pytest.approx(worst, abs=1e-3)


def test_a_link_moving_sideways_past_a_walker_seen_late_counts_the_turn_of_their_direction():
    """A person 1 m away walking sideways at 1 m/s, seen 60 ms ago: the direction to them may have turned by up to
    asin(0.06 / 1.0), so a robot point moving sideways at 1 m/s approaches at up to 0.06 m/s; with data of now, not
    at all. The person's own measured approach is none, as before; the limit is lower (a start towards the robot
    within the 60 ms counts)."""
    robot = np.array([[[0.0, 0, 0], [0.0, 0, 0]]])
    sideways = np.array([[[0.0, 1.0, 0], [0.0, 1.0, 0]]])
    humans = HumanCapsules.from_arrays([[[1.0, 0, 0], [1.0, 0, 0]]], [0.1], [[[0, 1.0, 0], [0, 1.0, 0]]], [True])
    now = pair_ssm(robot, np.array([0.1]), sideways, humans, BY_HAND)
    late = pair_ssm(robot, np.array([0.1]), sideways, humans, BY_HAND.aged(0.06))
    assert now.robot_speed[0, 0] == pytest.approx(0.0, abs=1e-12)
    assert late.robot_speed[0, 0] == pytest.approx(0.06)
    assert late.human_speed[0, 0] == now.human_speed[0, 0] == 0.0 and late.limit[0, 0] < now.limit[0, 0]
    unknown = HumanCapsules.from_arrays([[[1.0, 0, 0], [1.0, 0, 0]]], [0.1], [[[0, 0, 0], [0, 0, 0]]], [False])
    assert pair_ssm(robot, np.array([0.1]), sideways, unknown, BY_HAND.aged(0.06)).robot_speed[0, 0] == \
        pytest.approx(2.0 * 0.06)                                         # the ISO 13855 speed's way
