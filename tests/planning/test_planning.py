"""The planning layer: RRT-Connect around a human arm in the paper's experiment, typed errors, time
parameterisation, horizon check, continuous merge, beta replans, and the trajectory message."""

import contextlib
import re

import numpy as np
import pytest

from evidence.scenarios import Q_GOAL, Q_START, body_segments, paper_phases
from shared.core.humans import HumanCapsules
from shared.core.trajectory import straight_line_trajectory
from shared.planning.collision import CollisionModel
from shared.planning.decision import HoldClock, ReplanFailed
from shared.planning.forecast import ConstantVelocity, PeopleForecast
from shared.planning.horizon import HorizonOptions, horizon_check, out_of_reach, people_passing
from shared.planning.ompl_planner import (
    GoalInCollision,
    JointPlanner,
    NoPathFound,
    OutOfLimits,
    PlannerOptions,
    StartInCollision,
)
from shared.planning.path_search import ACTION_BUDGET
from shared.planning.replanner import Replanner, ReplanOptions
from shared.planning.scene import DEFAULT_SCENE, load_scene
from shared.planning.timing import TimingError, parameterize
from shared.robot.model import default_robot
from shared.safety.parameters import SsmParameters
from shared.scaling.problem import ssm_alpha_bound
from shared.wire.convert import trajectory_from_msg, trajectory_to_msg
from shared.wire.messages import TrajectoryMsg, decode, encode

# The paper's formula (the measured human speed held): these tests hold the layers' logic on the paper's
# numbers; the shipped human model's own figures are tests/safety/test_ssm.py's and the cell's.
PAPER_SSM = SsmParameters().paper_formula()

ROBOT = default_robot()
LIM = ROBOT.limits
CM = CollisionModel(ROBOT, load_scene(DEFAULT_SCENE))
PLANNER = JointPlanner(CM, PlannerOptions(seed=7))
OLD = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration)


def known(segments, radii):
    segments = np.asarray(segments, dtype=float)
    return HumanCapsules.from_arrays(segments, radii, np.zeros_like(segments), np.ones(len(radii), bool))


# a forearm held across the middle of the shuttle, the body behind it
ARM_ACROSS = known([[[-0.75, -0.15, 0.55], [-0.35, 0.15, 0.55]], [[-1.0, -0.2, 0.9], [-1.0, -0.2, 1.45]]],
                   [0.05, 0.17])
ASIDE = known([[[-2.5, 1.5, 0.9], [-2.5, 1.5, 1.45]]], [0.17])


def assert_trajectory_feasible(traj, humans, s_from=0.0):
    q, _, _ = traj.sample(traj.times[traj.times >= s_from])
    for a, b in zip(q[:-1], q[1:]):
        assert CM.motion_free(a, b, humans)[0]


def test_the_straight_shuttle_is_blocked_and_the_plan_goes_around_the_arm():
    assert not CM.motion_free(Q_START, Q_GOAL, ARM_ACROSS)[0]
    waypoints = PLANNER.plan(Q_START, Q_GOAL, ARM_ACROSS)
    assert np.allclose(waypoints[0], Q_START) and np.allclose(waypoints[-1], Q_GOAL)
    assert all(CM.feasible(q, ARM_ACROSS) for q in waypoints)
    assert all(CM.motion_free(a, b, ARM_ACROSS)[0] for a, b in zip(waypoints[:-1], waypoints[1:]))
    traj = parameterize(waypoints, LIM, collision=CM, humans=ARM_ACROSS)
    assert_trajectory_feasible(traj, ARM_ACROSS)
    s = np.linspace(0, traj.duration, 4000)
    _, dq, ddq = traj.sample(s)
    assert np.all(np.abs(dq) <= LIM.velocity * 1.01)             # TOPP-RA's grid; see shared/planning/timing.py
    assert np.all(np.abs(ddq) <= LIM.acceleration * 1.10)       # TOPP-RA's grid; see shared/planning/timing.py


def test_a_free_straight_motion_needs_no_search():
    assert len(PLANNER.plan(Q_START, Q_GOAL, ASIDE)) == 2 and PLANNER.last_stats["planner"] == "direct"


def test_bad_goals_give_typed_errors():
    with pytest.raises(OutOfLimits, match="prbt_joint_1"):
        PLANNER.plan(Q_START, np.array([3.0, 0, 0, 0, 0, 0]))
    with pytest.raises(OutOfLimits):
        PLANNER.plan(Q_START, np.array([0.0, np.nan, 0, 0, 0, 0]))
    flange_goal = ROBOT.capsule_segments(Q_GOAL)[-1, 0]
    on_goal = known([[flange_goal, flange_goal + [0, 0, 0.01]]], [0.05])
    with pytest.raises(GoalInCollision, match="human"):
        PLANNER.plan(Q_START, Q_GOAL, on_goal)
    with pytest.raises(StartInCollision, match="human"):
        PLANNER.plan(Q_GOAL, Q_START, on_goal)
    with pytest.raises(NoPathFound):
        PLANNER.plan(Q_START, Q_GOAL, ARM_ACROSS, time_budget=1e-6)


def test_time_laws_never_leave_the_acceleration_tolerance():
    """TOPP-RA bounds acceleration at its grid points only; between them a sharp detour once reached 1.42
    x the limit. Whatever path RRT-Connect returns, the law parameterize gives stays within the tolerance
    (re-timed with more headroom), or it is refused."""
    from shared.planning.timing import ACCELERATION_TOLERANCE
    for _ in range(30):
        try:
            traj = parameterize(PLANNER.plan(Q_START, Q_GOAL, ARM_ACROSS), LIM, collision=CM, humans=ARM_ACROSS)
        except TimingError:
            continue
        ends = np.concatenate([traj.times[:-1] + 1e-9, traj.times[1:] - 1e-9])
        assert np.max(np.abs(traj.sample(ends)[2]) / LIM.acceleration) <= ACCELERATION_TOLERANCE + 1e-9


def test_a_detour_is_timed_through_its_corners_at_speed_and_inside_the_joint_limits():
    """A lifted detour (the shoulder and elbow offset over the middle of the shuttle): the loosest smoothing
    that is feasible turns its corners at speed, near the polyline's own estimate (straight segments at full
    speed plus each corner's velocity change), where a spline held a quarter radian to the polyline crawls
    round them; and a corner on a joint's limit, where the loosest spline would overshoot the limit, is
    timed with a tighter one that stays inside."""
    from shared.planning.time_cost import SsmTimeCost
    lift = np.zeros(6)
    lift[1], lift[2] = -0.3, 0.4
    detour = np.vstack([Q_START, Q_START + 0.25 * (Q_GOAL - Q_START) + lift, Q_START + 0.75 * (Q_GOAL - Q_START) + lift,
                        Q_GOAL])
    estimate = SsmTimeCost(ROBOT, PAPER_SSM).path_samples(detour).nominal
    loose, tight = parameterize(detour, LIM, collision=CM), parameterize(detour, LIM, max_segment=0.25, collision=CM)
    assert loose.duration < 1.03 * estimate and loose.duration < tight.duration - 0.05, (loose.duration, tight.duration,
                                                                                          estimate)
    near_limit = Q_START.copy()
    near_limit[2] = LIM.upper[2] - 0.1                           # the elbow 0.1 rad short of its limit
    corner = np.vstack([Q_START, near_limit, Q_GOAL])
    with pytest.raises(TimingError, match="joint position limits"):
        parameterize(corner, LIM, max_segment=np.inf)
    traj = parameterize(corner, LIM)
    assert np.all(traj.positions <= LIM.upper) and np.all(traj.positions >= LIM.lower)
    near_limit[2] = LIM.upper[2]                                 # on it: every spline overshoots; refused
    with pytest.raises(TimingError, match="max_segment 0.25: the smoothed path leaves the joint position limits"):
        parameterize(np.vstack([Q_START, near_limit, Q_GOAL]), LIM)


def test_time_parameterisation_starts_with_the_given_velocity():
    v0 = OLD.sample(0.5)[1]
    lead = OLD.sample(np.linspace(0.5, 1.0, 11))[0]
    traj = parameterize(np.vstack([lead, Q_GOAL]), LIM, start_velocity=v0)
    assert np.allclose(traj.sample(0.0)[1], v0) and np.allclose(traj.velocities[-1], 0.0)
    with pytest.raises(TimingError):
        parameterize(lead[:1], LIM, start_velocity=v0)        # cannot stop in zero distance


def test_a_law_continues_a_motion_on_a_joint_velocity_limit():
    """A junction where the old trajectory runs on a joint's velocity limit, or a grid effect over it (its
    knots are allowed VELOCITY_TOLERANCE): the new law still starts there, with that velocity. Without
    room at TOPP-RA's first velocity row no law existed, and such merges failed at every smoothing."""
    q0 = np.array([0.8, -0.4, 1.17, 0.0, 1.57, 0.0])
    bend = q0 + np.array([[0.0] * 6, [-0.6, 0, 0, 0, 0, 0], [-1.6, 0.2, -0.1, 0, 0, 0], [-2.0, 0.2, -0.1, 0, 0, 0]])
    for over in (1.0, 1.00001, 1.005):
        v0 = np.array([-LIM.velocity[0] * over, 0, 0, 0, 0, 0])
        traj = parameterize(bend, LIM, start_velocity=v0)
        assert np.allclose(traj.sample(0.0)[1], v0)
        assert np.all(np.abs(traj.velocities[1:]) <= LIM.velocity * 1.01)
    with pytest.raises(TimingError, match="not finite"):
        parameterize(bend, LIM, start_velocity=np.full(6, np.nan))
    with pytest.raises(TimingError, match="waypoints are not all finite"):
        parameterize(np.vstack([bend[:2], np.full(6, np.inf), bend[2:]]), LIM)
    with pytest.raises(TimingError, match="start velocity is 1.050 x a joint velocity limit"):
        parameterize(bend, LIM, start_velocity=np.array([-LIM.velocity[0] * 1.05, 0, 0, 0, 0, 0]))


def test_horizon_check_finds_a_human_in_the_path_and_ignores_one_beside_it():
    hit = horizon_check(OLD, 0.0, CM, ARM_ACROSS, HorizonOptions(samples=40, spacing=0.05))
    assert hit.first_infeasible is not None and hit.first_infeasible > 0
    assert np.all(hit.clearance[:hit.first_infeasible] > CM.margins.tolerance)
    assert horizon_check(OLD, 0.0, CM, ASIDE, HorizonOptions(samples=40, spacing=0.05)).first_infeasible is None
    # a human who steps in only later than the horizon reaches is not reported yet
    assert horizon_check(OLD, 0.0, CM, ARM_ACROSS, HorizonOptions(samples=3, spacing=0.05)).first_infeasible is None


def test_people_out_of_the_robots_reach_need_no_horizon_check():
    # the reach sphere holds every capsule in every configuration (sampled), and is not loose
    rng = np.random.default_rng(4)
    farthest = max(float((np.linalg.norm(ROBOT.capsule_segments(q) - ROBOT.reach_centre, axis=-1).max(axis=1)
                          + ROBOT.radii).max()) for q in rng.uniform(LIM.lower, LIM.upper, (3000, 6)))
    assert farthest <= ROBOT.reach_radius < farthest + 0.05
    assert out_of_reach(CM, ASIDE) and out_of_reach(CM, None) and not out_of_reach(CM, ARM_ACROSS)
    # where the bound says out of reach, no configuration is blocked; just inside it, the check runs
    required = CM.min_separation + CM.margins.human + CM.margins.tolerance
    for gap in (required + 0.01, required - 0.01):
        centre = ROBOT.reach_centre + np.array([-(ROBOT.reach_radius + 0.17 + gap), 0.0, 0.0])
        person = known([[centre, centre + np.array([0.0, 0.0, 0.5])]], [0.17])
        qs = rng.uniform(LIM.lower, LIM.upper, (2000, 6))
        assert out_of_reach(CM, person) == (gap > required)
        if out_of_reach(CM, person):           # the person changes no configuration's clearance
            assert np.array_equal(CM.clearances(qs, person), CM.clearances(qs, None))
    replanner = Replanner(CM, JointPlanner(CM, PlannerOptions(seed=7)), PAPER_SSM)
    before = CM.checks
    assert replanner.on_horizon(OLD, 0.5, Q_GOAL, ASIDE) is None and CM.checks == before     # not even checked
    with contextlib.suppress(ReplanFailed):              # (whatever it decides; it has to look first)
        replanner.on_horizon(OLD, 0.5, Q_GOAL, known([[[-0.7, 0.0, 0.3], [-0.7, 0.0, 1.45]]], [0.17]))
    assert CM.checks > before


def merged_round(s_now: float, humans: HumanCapsules):
    """Alg. 2 itself (no decision whether it pays): branch at the last feasible horizon sample, with a
    planner seeded afresh (the same random sampling in every test)."""
    replanner = Replanner(CM, JointPlanner(CM, PlannerOptions(seed=7)), PAPER_SSM)
    check = horizon_check(OLD, s_now, CM, humans, replanner.horizon)
    return replanner.replan(OLD, s_now, Q_GOAL, humans, "horizon", s_branch=check.last_feasible_s)


def test_replan_and_merge_is_continuous_and_feasible():
    result = merged_round(0.0, ARM_ACROSS)
    new, s_j = result.trajectory, result.junction
    assert new.version == OLD.version + 1 and result.reason == "horizon"
    # identical before the junction, continuous in position and velocity at it
    s_before = np.linspace(0, s_j, 50)
    assert np.allclose(new.sample(s_before)[0], OLD.sample(s_before)[0], atol=1e-9)
    for k in range(2):
        assert np.allclose(new.sample(s_j - 1e-6)[k], new.sample(s_j + 1e-6)[k], atol=1e-4)
    # no acceleration spike at the junction
    assert np.abs(new.sample(np.linspace(s_j - 0.05, s_j + 0.05, 101))[2]).max() < 4.0
    assert_trajectory_feasible(new, ARM_ACROSS, s_j)
    assert np.allclose(new.positions[-1], Q_GOAL)


def test_replan_fails_cleanly_when_the_robot_cannot_turn_in_time():
    with pytest.raises(ReplanFailed, match="no junction allows a continuous merge"):
        merged_round(0.6, ARM_ACROSS)


def _mean_safe_alpha(traj, s_from, humans):
    """Mean over the rest of the trajectory (by nominal time) of the largest alpha the SSM allows: the
    clearance that matters for speed (distance and direction of motion together)."""
    q, dq, _ = traj.sample(np.linspace(s_from, traj.duration, 300))
    return float(np.mean([ssm_alpha_bound(ROBOT, qk, dqk, humans, PAPER_SSM) for qk, dqk in zip(q, dq)]))


STANDING = known(*body_segments(-1.0, 0.0, 1.0, np.array([-0.4, 0.0, 0.8])))   # reaching over the path


def test_keep_or_replace_compares_both_trajectories_under_the_same_stay():
    """Like with like: the old trajectory and the new one are predicted by the same cost from the same
    moment, the person assumed to stay patience + waited. With no patience (pure ski rental) and not held
    yet, the person is expected to move on and the old path is kept; held for two seconds, the way round
    pays and is taken, faster under the SSM than the old path (its mean safe alpha higher). Both times
    are in the reason either way. As shipped (patience 1.5 s) it is taken at once."""
    replanner = Replanner(CM, PLANNER, PAPER_SSM, options=ReplanOptions(patience=0.0))
    with pytest.raises(ReplanFailed, match=r"predicted \d+\.\d\d s, not 10 % faster than the old \d+\.\d\d s"):
        replanner.on_beta(OLD, 0.3, Q_GOAL, STANDING, waited=0.0)
    result = replanner.on_beta(OLD, 0.3, Q_GOAL, STANDING, waited=2.0)
    assert result.reason == "beta"
    assert f"predicted {result.predicted:.2f} s instead of {result.baseline:.2f} s" in result.detail
    assert result.predicted == pytest.approx(replanner.predicted_time(result.trajectory, 0.3, STANDING, 2.0))
    assert result.baseline == pytest.approx(replanner.predicted_time(OLD, 0.3, STANDING, 2.0))
    assert result.predicted <= 0.9 * result.baseline
    assert _mean_safe_alpha(result.trajectory, result.junction, STANDING) > _mean_safe_alpha(OLD, result.junction, STANDING)
    assert_trajectory_feasible(result.trajectory, STANDING, result.junction)
    assert replanner.stay(1.0) == pytest.approx(1.0)
    shipped = Replanner(CM, PLANNER, PAPER_SSM)
    assert shipped.stay(0.0) == pytest.approx(1.5)
    assert "instead of" in shipped.on_beta(OLD, 0.3, Q_GOAL, STANDING, waited=0.0).detail


def test_a_crawling_robot_held_by_the_ssm_is_stopped_a_little_ahead_and_planned_for_from_rest():
    """A robot the SSM holds to a crawl (a tenth of its nominal speed here) can stop within millimetres: its
    plan starts from rest just ahead on its path, where the scaling layer brings it to rest, and may leave
    in any direction; a merge would have to leave at the old nominal speed. A robot merely speeding up
    again (not held) is merged into as before."""
    from shared.scaling.layer import ScalingInputs, ScalingLayer

    replanner = Replanner(CM, PLANNER, PAPER_SSM)
    crawl = 0.1 * float(np.abs(OLD.sample(0.3)[1]).max())
    stop = replanner.on_beta(OLD, 0.3, Q_GOAL, STANDING, speed_now=crawl, waited=2.0, held=True)
    assert stop.from_rest and 0.3 < stop.junction < 0.35 and "from rest" in stop.detail
    assert np.allclose(stop.trajectory.positions[0], OLD.sample(stop.junction)[0])
    assert not stop.trajectory.velocities[0].any()
    assert stop.predicted < stop.baseline
    merged = replanner.on_beta(OLD, 0.3, Q_GOAL, STANDING, speed_now=crawl, waited=2.0, held=False)
    assert not merged.from_rest and merged.junction >= 0.3 + replanner.options.lead
    # the scaling layer takes it where the robot comes to rest, without a jump
    layer = ScalingLayer(ROBOT, PAPER_SSM)
    layer.set_trajectory(OLD)
    layer.s, layer.sdot = 0.3, 0.1
    assert layer.take(stop.trajectory, True, 0.0, OLD.sample(0.3)[0], 1e-3) is None
    for _ in range(200):
        step = layer.step(ScalingInputs(humans=STANDING))
        if layer.trajectory is stop.trajectory:
            break
    assert layer.trajectory is stop.trajectory and np.allclose(step.q_command, OLD.sample(stop.junction)[0])


def test_a_robot_brought_to_rest_to_await_its_plan_is_planned_for_from_rest_where_it_stops():
    """The scaler stops a crawling robot that asked for a replan and awaits the plan (stop_at,
    ScalingStep.awaiting): the plan starts from rest exactly there, and the old trajectory is predicted from
    rest there too (it has to get back up to speed), whatever the robot's speed when the planner looked."""
    replanner = Replanner(CM, PLANNER, PAPER_SSM)
    crawl = 0.1 * float(np.abs(OLD.sample(0.3)[1]).max())
    plan = replanner.on_beta(OLD, 0.3, Q_GOAL, STANDING, speed_now=crawl, waited=2.0, held=True, stop_at=0.304)
    assert plan.from_rest and plan.junction == 0.304 and plan.reason == "beta"
    assert np.allclose(plan.trajectory.positions[0], OLD.sample(0.304)[0]) and not plan.trajectory.velocities[0].any()
    assert plan.baseline > replanner.predicted_time(OLD, 0.304, STANDING, 2.0)     # the old one from rest
    assert plan.predicted < plan.baseline


def test_trajectory_message_roundtrip_gives_the_same_law():
    result = merged_round(0.0, ARM_ACROSS)
    msg = decode(encode(trajectory_to_msg(result.trajectory, goal_id=4, reason="horizon", junction=result.junction,
                                          base_version=OLD.version)), TrajectoryMsg)
    back = trajectory_from_msg(msg)
    s = np.linspace(0, back.duration, 777)
    for k in range(3):
        assert np.array_equal(back.sample(s)[k], result.trajectory.sample(s)[k])
    assert back.version == result.trajectory.version and msg.junction == result.junction


def test_a_free_shuttle_is_planned_as_the_exact_trapezoid():
    replanner = Replanner(CM, PLANNER, PAPER_SSM)
    traj = replanner.plan_fresh(Q_START, Q_GOAL, ASIDE, 3)
    assert traj.duration == pytest.approx(OLD.duration, abs=1e-9) and traj.version == 3
    q = traj.sample(np.linspace(0, traj.duration, 50))[0]
    assert np.allclose(q, OLD.sample(np.linspace(0, OLD.duration, 50))[0], atol=1e-9)


def test_people_are_forecast_at_their_known_velocities_only():
    seg = np.array([[[0.0, 0, 0], [0, 0, 1.0]], [[1.0, 0, 0], [1.0, 0, 1.0]]])
    people = HumanCapsules(seg, np.array([0.1, 0.1]), np.full((2, 2, 3), 0.5), np.array([True, False]))
    later = ConstantVelocity().forecast(people, 2.0).at(2.0)
    assert np.allclose(later[0], seg[0] + 1.0) and np.allclose(later[1], seg[1])


def test_a_person_crossing_out_of_the_path_is_waited_for_and_one_standing_in_it_is_not():
    replanner = Replanner(CM, PLANNER, PAPER_SSM)
    seg = np.asarray(ARM_ACROSS.segments)
    leaving = HumanCapsules(seg, ARM_ACROSS.radii, np.tile([0.0, -2.0, 0.0], (2, 2, 1)), np.ones(2, bool))
    check = horizon_check(OLD, 0.0, CM, leaving, replanner.horizon)
    assert check.first_infeasible is not None                  # blocked now ...
    forecast = replanner.cost.forecast
    assert people_passing(OLD, 0.0, check, leaving, CM, forecast(leaving))   # ... but gone when the robot is there
    assert replanner.on_horizon(OLD, 0.0, Q_GOAL, leaving) is None
    assert not people_passing(OLD, 0.0, check, ARM_ACROSS, CM, forecast(ARM_ACROSS))
    # the planning layer's forecast decides: one that holds them where they are does not let them pass
    held = PeopleForecast.still(leaving)
    assert not people_passing(OLD, 0.0, check, leaving, CM, held)


def test_nearby_starts_to_one_goal_are_planned_alike():
    """The search draws its candidates by the seed and the goal alone: from starts a few milliradians apart
    (a leg that ended a moment earlier) the searched paths bend the same way. Seeded by the start too,
    they differed by up to a radian (another draw, another winner), and the plans after a small change
    of timing had nothing in common with those before it."""
    replanner = Replanner(CM, PLANNER, PAPER_SSM)
    for humans in (STANDING, ARM_ACROSS):
        paths = []
        for offset in (0.0, 0.002, 0.005, 0.01):
            replanner.forget()
            paths.append(replanner.path(Q_START + offset, Q_GOAL, humans))
        for path in paths[1:]:       # the same bend; the refinement's last steps may differ by a tenth of a radian
            assert path.shape == paths[0].shape and np.abs(path[1:-1] - paths[0][1:-1]).max() < 0.15, (path, paths[0])
    rng = replanner.paths.rng
    assert not np.array_equal(rng(Q_START, Q_GOAL).random(4), rng(Q_START, Q_START).random(4))


def test_the_hold_clock_counts_only_while_the_scaler_keeps_asking():
    clock = HoldClock()
    clock.update(10.0, True)
    clock.update(12.0, True)
    assert clock.waited(14.0) == pytest.approx(4.0)
    clock.update(14.5, False)                                 # the scaler stopped asking: the wait starts again
    assert clock.waited(15.0) == 0.0


def test_a_person_blocking_every_way_is_waited_for_and_a_robot_in_reach_is_not_replanned():
    """The arm across the shuttle next to the robot's base: every way to the goal passes inside its
    slowdown, so a new path only adds length; the old one is kept (held or not, moving or at rest), and
    the reason says so with both times. A person already within the margin of the robot's own
    configuration: no branch ahead can help."""
    replanner = Replanner(CM, PLANNER, PAPER_SSM)
    for waited in (0.0, 4.0):
        with pytest.raises(ReplanFailed, match="kept the old trajectory: the new one .* not faster than the old"):
            replanner.on_horizon(OLD, 0.0, Q_GOAL, ARM_ACROSS, waited=waited)
        with pytest.raises(ReplanFailed, match=r"from rest\) predicted"):
            replanner.on_horizon(OLD, 0.0, Q_GOAL, ARM_ACROSS, speed_now=0.0, waited=waited)
    # the old path, held at the arm, is predicted at its nominal time plus at most the stay: every second
    # already waited adds a second (the person is expected to stay that much longer)
    held = replanner.predicted_time(OLD, 0.0, ARM_ACROSS, 4.0)
    assert OLD.duration + replanner.stay(4.0) - 0.5 < held <= OLD.duration + replanner.stay(4.0)
    assert held - replanner.predicted_time(OLD, 0.0, ARM_ACROSS, 0.0) == pytest.approx(4.0, abs=0.1)  # creeping at the floor
    flange = ROBOT.capsule_segments(Q_START)[-1][1]
    touching = known([[flange, flange + [0, 0, 0.2]]], [0.1])
    assert replanner.on_horizon(OLD, 0.0, Q_GOAL, touching, speed_now=0.0) is None


def test_a_new_goal_is_chosen_with_the_people_staying_for_the_leg():
    """A person reaching over the path, at rest: with a patience of 1 s alone they are predicted gone early in
    the leg and the direct line is kept; a new goal's decision has them stay goal_stay (6 s shipped) however
    short the robot has been held, and goes round them. Later decisions keep the patience."""
    only_patience = Replanner(CM, PLANNER, PAPER_SSM, options=ReplanOptions(posture_gap=None, patience=1.0,
                                                                            goal_stay=0.0))
    direct = only_patience.plan_goal(Q_START, Q_GOAL, STANDING, 3)
    assert not only_patience.goal_searched and np.allclose(direct.sample(1.0)[0], OLD.sample(1.0)[0])
    for_the_leg = Replanner(CM, PLANNER, PAPER_SSM, options=ReplanOptions(posture_gap=None, patience=1.0))
    assert for_the_leg.stay(for_the_leg.goal_waited(0.0)) == pytest.approx(6.0)
    assert for_the_leg.stay(for_the_leg.goal_waited(7.0)) == pytest.approx(8.0)     # held longer: longer still
    chosen = for_the_leg.plan_goal(Q_START, Q_GOAL, STANDING, 4)
    assert for_the_leg.goal_searched and not np.allclose(chosen.sample(1.0)[0], OLD.sample(1.0)[0])
    assert for_the_leg.predicted_time(chosen, 0.0, STANDING, 5.0) < for_the_leg.predicted_time(OLD, 0.0, STANDING, 5.0)
    assert_trajectory_feasible(chosen, STANDING)


def test_a_new_goal_takes_the_direct_line_unless_the_searched_path_is_predicted_faster():
    """The paper's planner (no posture; the shipped folded leg in the direct line's place: below)."""
    replanner = Replanner(CM, PLANNER, PAPER_SSM, options=ReplanOptions(posture_gap=None))
    # nobody near: the exact trapezoid, no search
    assert replanner.plan_goal(Q_START, Q_GOAL, ASIDE, 7).duration == pytest.approx(OLD.duration, abs=1e-9)
    # an arm that blocks every way: the direct line (the scaling layer holds the robot until it moves)
    direct = replanner.plan_goal(Q_START, Q_GOAL, ARM_ACROSS, 5)
    assert direct.version == 5 and np.allclose(direct.sample(1.0)[0], OLD.sample(1.0)[0])
    # a person reaching over the path who stays: the searched way round, predicted faster
    stays = Replanner(CM, PLANNER, PAPER_SSM, options=ReplanOptions(patience=5.0, posture_gap=None))
    chosen = stays.plan_goal(Q_START, Q_GOAL, STANDING, 6)
    assert not np.allclose(chosen.sample(1.0)[0], OLD.sample(1.0)[0])
    assert stays.predicted_time(chosen, 0.0, STANDING) < stays.predicted_time(OLD, 0.0, STANDING)
    assert_trajectory_feasible(chosen, STANDING)
    # leaving (the planning loop leaves at once and searches on the way) where the direct line is predicted no more
    # than worth_waiting slower than nominal: the direct line, no search, and it says the search was left
    excess = stays.predicted_time(OLD, 0.0, STANDING, stays.goal_waited(0.0)) - OLD.duration
    leaves = Replanner(CM, PLANNER, PAPER_SSM, options=ReplanOptions(patience=5.0, posture_gap=None,
                                                                     worth_waiting=excess + 0.1))
    at_once = leaves.plan_goal(Q_START, Q_GOAL, STANDING, 8, leaving=True)
    assert leaves.search_deferred and leaves.searches == 0 and at_once.version == 8
    assert np.allclose(at_once.sample(1.0)[0], OLD.sample(1.0)[0])
    leaves.plan_goal(Q_START, Q_GOAL, ASIDE, 9, leaving=True)           # no search would decide: nothing left
    assert not leaves.search_deferred
    # slower than that: the robot waits for the search at the goal, as without leaving
    waits = Replanner(CM, PLANNER, PAPER_SSM, options=ReplanOptions(patience=5.0, posture_gap=None,
                                                                    worth_waiting=excess - 0.1))
    searched = waits.plan_goal(Q_START, Q_GOAL, STANDING, 10, leaving=True)
    assert not waits.search_deferred and waits.searches == 1 and np.allclose(searched.positions, chosen.positions)
    assert waits.goal_searched and not leaves.goal_searched


def test_a_goal_left_at_once_takes_on_the_way_the_leg_its_search_from_rest_would_have_given():
    """The search the goal would have waited for, run once the robot has left (on_search): searched from rest where
    the leg began, taken by the goal's own rule (predicted faster than the leg from there by required_gain), then
    merged a moment ahead of the robot and kept while still predicted faster than the leg from where it is."""
    stays = Replanner(CM, PLANNER, PAPER_SSM, options=ReplanOptions(patience=5.0, posture_gap=None))
    leg = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration, version=8)
    searched_from = []
    search = stays.path
    stays.path = lambda q_from, *args, **kw: (searched_from.append(np.array(q_from)), search(q_from, *args, **kw))[1]
    result = stays.on_search(leg, 0.02, Q_GOAL, STANDING)
    assert len(searched_from) == 1 and np.allclose(searched_from[0], Q_START)      # one search, from the leg's start
    assert result.reason == "search" and not result.from_rest and 0.02 < result.junction < 0.5
    assert result.trajectory.version == 9 and result.predicted < stays.predicted_time(leg, 0.02, STANDING)
    assert not np.allclose(result.trajectory.sample(1.5)[0], leg.sample(1.5)[0], atol=0.05)        # gone round
    assert_trajectory_feasible(result.trajectory, STANDING, result.junction)
    # an arm across every way: the search from the leg's start finds nothing the goal would have taken; the leg stays
    refused = r"the new one \(searched from the leg's start\) predicted \d\.\d\d s, not \d+ % faster than the old"
    with pytest.raises(ReplanFailed, match=refused):
        stays.on_search(leg, 0.02, Q_GOAL, ARM_ACROSS)


def test_a_search_starts_from_the_paths_the_last_ones_found_to_the_same_goal():
    """The search's budget is small; the winners of the last searches to this goal are seeds of the next,
    so a replan keeps what was found while the situation stays. A search with no random candidates of its
    own finds the remembered way round the arm; after forget() it has only the direct line and RRT-Connect."""
    from shared.planning.path_search import SearchOptions
    options = ReplanOptions(seed=3)
    replanner = Replanner(CM, JointPlanner(CM, PlannerOptions(seed=7)), PAPER_SSM, options=options)
    first = replanner.path(Q_START, Q_GOAL, ARM_ACROSS)
    assert len(first) > 2 and len(replanner.remembered) == 1
    bare = Replanner(CM, JointPlanner(CM, PlannerOptions(seed=7)), PAPER_SSM,
                     options=ReplanOptions(seed=3, search=SearchOptions(candidates=0, refinements=0, escape_directions=0,
                                                                        lift_offsets=((), ()), raises=())))
    bare.remembered = list(replanner.remembered)
    recalled = bare.path(Q_START, Q_GOAL, ARM_ACROSS)
    assert np.allclose(recalled, first)                       # the remembered path, from the same start
    assert bare.searches == 1                                 # found without RRT-Connect
    bare.forget()
    assert bare.remembered == []
    bare.path(Q_START, Q_GOAL, ARM_ACROSS)
    assert bare.searches == 3                                 # nothing free among its seeds: RRT-Connect seeded it
    elsewhere = bare.paths.recalled(Q_START, Q_START)            # paths to another goal are no seeds
    assert elsewhere == []


def test_a_crawl_that_the_ssm_slows_further_is_stopped_where_it_gets_by_the_plans_arrival():
    """Towards the arm reaching over the path, the bound falls from 0.21 at s = 0.75 to 0 by s = 0.9: at its
    present rate the crawl would be predicted further on than it gets, and the robot would crawl on for
    the difference after its plan has come (about 150 ms of a 400 ms stall in hrc demo). The stop is where
    the time cost's bound takes it in stop_lead and half the stop."""
    replanner = Replanner(CM, PLANNER, PAPER_SSM)
    s_now = 0.75
    q, v, _ = OLD.sample(np.array([s_now]))
    rate = ssm_alpha_bound(ROBOT, q[0], v[0], STANDING, PAPER_SSM)
    stop = replanner.on_beta(OLD, s_now, Q_GOAL, STANDING, speed_now=rate * float(np.abs(v).max()), waited=2.0,
                             held=True)
    stopping = rate * float(np.max(np.abs(v[0]) / LIM.acceleration))   # the joints' planning deceleration
    lead = replanner.options.stop_lead + 0.5 * stopping
    assert stop.from_rest and s_now < stop.junction < s_now + rate * lead - 0.005
    assert stop.junction == pytest.approx(replanner.cost.reached(OLD, s_now, STANDING, lead, replanner.stay(2.0)))
    # where the bound is already zero in the plan's view (a person who came closer than the plan's state says, or
    # the bound chattering with the data's age while the robot creeps on between: the cost sees the crawl stand), the
    # stop is no nearer than where the present rate takes the robot while the plan is made (ACTION_BUDGET): a start
    # it passed before the plan came would be refused; one the SSM holds it short of is dropped after HELD_SHORT_FOR
    s_now, rate = 0.88, 0.1
    q, v, _ = OLD.sample(np.array([s_now]))
    assert ssm_alpha_bound(ROBOT, q[0], v[0], STANDING, PAPER_SSM) == 0.0
    stop = replanner.on_beta(OLD, s_now, Q_GOAL, STANDING, speed_now=rate * float(np.abs(v).max()), waited=2.0,
                             held=True)
    stopping = rate * float(np.max(np.abs(v[0]) / LIM.acceleration))   # the joints' planning deceleration
    assert replanner.cost.reached(OLD, s_now, STANDING, 0.2, replanner.stay(2.0)) < s_now + rate * ACTION_BUDGET
    assert stop.junction == pytest.approx(s_now + rate * ACTION_BUDGET)
    assert stop.junction > s_now + rate * 0.5 * stopping              # beyond where it could stop


def test_a_path_predicted_slow_ahead_of_a_robot_at_speed_is_replanned_by_the_planning_layer():
    """The paper's phase 4: a goal planned 40 ms before the person stops stepping in, and followed at speed
    while they stand in its way. The longer they stand, the longer the prediction has them stay; once the
    rest of the path is predicted more than slow_excess over its nominal time, the planning layer asks
    itself for a replan (on_slow) and takes the merge round them, which is faster against the person as
    they really stay, too. (The paper's planner, whose goal has the person stay only its patience: the shipped
    one's folded leg already clears this person, and its goal's stay, goal_stay, already goes round them.)"""
    phases = paper_phases(6.0)
    replanner = Replanner(CM, JointPlanner(CM, PlannerOptions(seed=1)), PAPER_SSM,
                          options=ReplanOptions(seed=2, posture_gap=None, goal_stay=0.0))
    plan = replanner.plan_goal(Q_GOAL, Q_START, phases.at(19.16), 9)
    standing = phases.at(19.3)
    round_them = Replanner(CM, JointPlanner(CM, PlannerOptions(seed=1)), PAPER_SSM,
                           options=ReplanOptions(seed=2, posture_gap=None))
    planned = round_them.plan_goal(Q_GOAL, Q_START, phases.at(19.16), 9)
    assert round_them.goal_searched       # goal_stay: however long they stand, not slower (patience only: it grows)
    assert round_them.predicted_time(planned, 0.0, standing, 10.0) == pytest.approx(
        round_them.predicted_time(planned, 0.0, standing, 0.0), abs=0.05)
    assert replanner.predicted_time(plan, 0.0, standing, 10.0) > replanner.predicted_time(plan, 0.0, standing, 0.0) + 5

    def speed(s):                 # the robot at its nominal speed there
        return float(np.abs(plan.sample(s)[1]).max())

    assert replanner.on_slow(plan, 0.3, Q_START, standing, speed(0.3), 0.2) is None      # not predicted slow yet
    taken = replanner.on_slow(plan, 0.9, Q_START, standing, speed(0.9), 0.8)
    assert taken.reason == "slow" and taken.detail.startswith("path predicted slow (")
    predicted, nominal = (float(x) for x in re.match(r"path predicted slow \((\S+) s for (\S+) s", taken.detail).groups())
    assert predicted - nominal > replanner.options.slow_excess
    assert taken.predicted < 0.9 * taken.baseline and not taken.from_rest
    stays = 22.8 - 19.9           # the person leaves at 22.8 s
    assert (replanner.cost.trajectory_time(taken.trajectory, 0.9, standing, stays)
            < replanner.cost.trajectory_time(plan, 0.9, standing, stays))
    # a robot the SSM has already slowed is the scaling layer's to ask for (beta); nobody near: nothing
    assert replanner.on_slow(plan, 0.9, Q_START, standing, 0.3 * speed(0.9), 0.8) is None
    assert replanner.on_slow(plan, 0.9, Q_START, ASIDE, speed(0.9), 0.8) is None


def test_a_new_goal_takes_the_folded_leg_by_default_while_someone_is_near():
    """ReplanOptions.posture_gap (2.5 m as shipped): a new goal's default leg is the folded one
    (shared.planning.postures) while someone is that near the robot's reach and it is free of them; nobody
    near, or the option off (the paper's planner), the straight line as before."""
    from shared.planning.horizon import reach_gap
    from shared.planning.postures import ELBOW

    near = Replanner(CM, PLANNER, PAPER_SSM)
    assert near.options.posture_gap == 2.5 and reach_gap(CM, STANDING) < 2.5
    leg = near._posture(Q_START, Q_GOAL, STANDING, 5)
    assert leg is not None and leg.version == 5 and np.allclose(leg.positions[[0, -1]], [Q_START, Q_GOAL])
    assert leg.positions[:, ELBOW].max() > Q_START[ELBOW] + 0.5                   # folded on the way
    assert CM.path_free(leg.positions, STANDING, CM.capped_inflation(0.0, leg.positions[[0, -1]], STANDING))
    far = HumanCapsules.from_arrays([[[-5.0, 0.0, 0.0], [-5.0, 0.0, 1.7]]], [0.2], np.zeros((1, 2, 3)), [True])
    assert reach_gap(CM, far) > 2.5
    assert near._posture(Q_START, Q_GOAL, far, 5) is None                          # nobody near: no posture
    paper = Replanner(CM, PLANNER, PAPER_SSM, options=ReplanOptions(posture_gap=None))
    assert paper._posture(Q_START, Q_GOAL, STANDING, 5) is None                    # the paper's planner: none


def test_people_standing_still_beyond_the_still_gap_make_no_folded_leg_but_walking_there_they_do():
    """ReplanOptions.still_gap (1.0 m as shipped): a person waiting well off (the paper's first phase, 2.8 m from
    the base) cannot come near within a leg; the straight line is faster then. The same person walking, or
    standing nearer than the still gap, still makes the fold."""
    from shared.planning.horizon import reach_gap

    replanner = Replanner(CM, PLANNER, PAPER_SSM)
    assert replanner.options.still_gap == 1.0

    def person(x: float, speed: float) -> HumanCapsules:
        return HumanCapsules.from_arrays([[[x, 0.0, 0.0], [x, 0.0, 1.7]]], [0.2],
                                         np.tile([speed, 0.0, 0.0], (1, 2, 1)), [True])

    waiting, walking = person(-2.8, 0.0), person(-2.8, 1.2)
    assert replanner.options.still_gap < reach_gap(CM, waiting) < replanner.options.posture_gap
    assert replanner._posture(Q_START, Q_GOAL, waiting, 1) is None                 # standing well off: the line
    assert replanner._posture(Q_START, Q_GOAL, walking, 1) is not None             # walking: the fold
    unknown = HumanCapsules(waiting.segments, waiting.radii, waiting.velocities, np.array([False]))
    assert replanner._posture(Q_START, Q_GOAL, unknown, 1) is not None             # not known to stand: the fold
    assert reach_gap(CM, STANDING) < replanner.options.still_gap
    assert replanner._posture(Q_START, Q_GOAL, STANDING, 1) is not None            # standing near: the fold
    everyone = Replanner(CM, PLANNER, PAPER_SSM, options=ReplanOptions(still_gap=2.5))
    assert everyone._posture(Q_START, Q_GOAL, waiting, 1) is not None              # at posture_gap: like walkers
