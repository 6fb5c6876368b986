"""The scaling layer's cycle: missing and stale data stop the robot, beta has hysteresis, s advances as in
the paper, the path end is reached, and every command it sends meets the SSM limit."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from evidence.scenarios import Q_GOAL, Q_START, body_segments
from shared.core.humans import HumanCapsules
from shared.core.trajectory import Trajectory, straight_line_trajectory
from shared.robot.model import default_robot
from shared.safety.parameters import SsmParameters
from shared.safety.ssm import pair_ssm
from shared.scaling.layer import ScalingInputs, ScalingLayer, StepStatus
from shared.scaling.parameters import ScalingParameters

# The paper's formula (the measured human speed held): these tests hold the layers' logic on the paper's
# numbers; the shipped human model's own figures are tests/safety/test_ssm.py's and the cell's.
# the cases here were laid out with T_r 0.1 s (shipped until session 81, when T_r came to cover the cell's own
# chain alone: 0.05 s); the mechanisms they test do not depend on its value
LAID_OUT = SsmParameters(reaction_time=0.1)
PAPER_SSM = LAID_OUT.paper_formula()

ROBOT = default_robot()
NOBODY = HumanCapsules.empty()


def layer(**params):
    lay = ScalingLayer(ROBOT, PAPER_SSM, ScalingParameters(**params))
    lay.set_trajectory(straight_line_trajectory(Q_START, Q_GOAL, ROBOT.limits.velocity, ROBOT.limits.acceleration))
    return lay


def test_no_human_data_stops_the_robot_as_fast_as_the_drives_brake_along_the_path():
    """Stale or missing data: the path speed falls as fast as the drives' deceleration allows (not faster:
    no command the drives cannot follow), the robot stays on its path and comes to rest, then stays."""
    lay = layer()
    for _ in range(50):
        lay.step(ScalingInputs(humans=NOBODY))
    assert lay.sdot > 0.9
    qd = [lay.trajectory.sample(lay.s)[1] * lay.sdot]
    for k in range(60):
        step = lay.step(ScalingInputs(humans=None, human_age=math.inf))
        assert step.status is StepStatus.NO_HUMAN_DATA and not step.beta
        assert np.allclose(step.q_command, lay.trajectory.sample(step.s)[0])          # on the path
        qd.append(step.qd_command)
    joint_acc = np.abs(np.diff(np.array(qd), axis=0)) / 0.01
    assert joint_acc.max() <= 6.0 + 1e-6                          # what the drives can do, no more
    assert joint_acc.max() >= 0.9 * 6.0                           # and all of it: the fastest stop
    at_rest = step.s
    assert step.alpha == 0.0 and np.all(step.qd_command == 0)
    assert lay.step(ScalingInputs(humans=None, human_age=math.inf)).s == at_rest                  # stays there


@pytest.mark.parametrize("age", [0.051, 1.0, math.inf, math.nan])
def test_stale_human_data_stops_the_robot(age):
    lay = layer(human_timeout=0.05)
    lay.step(ScalingInputs(humans=NOBODY))
    step = lay.step(ScalingInputs(humans=NOBODY, human_age=age))
    assert step.status is StepStatus.STALE_HUMAN_DATA and step.alpha == 0.0 and step.sdot == 0.0


@pytest.mark.parametrize("age", [0.201, 1.0, math.inf, math.nan])
def test_a_robot_not_heard_from_is_stopped_along_its_path_and_goes_on_once_it_is(age):
    """No joint state within robot_timeout (or an age that is not a number): the layer no longer knows where
    the robot is, so it brakes along the path as for stale human data, and runs again once a state comes."""
    lay = layer(robot_timeout=0.2)
    for _ in range(50):
        lay.step(ScalingInputs(humans=NOBODY, robot_age=0.01))
    speeds = [lay.sdot]
    assert lay.step(ScalingInputs(humans=NOBODY, robot_age=0.2)).status is StepStatus.RUNNING
    for _ in range(60):
        step = lay.step(ScalingInputs(humans=NOBODY, robot_age=age))
        assert step.status is StepStatus.STALE_JOINT_STATE and not step.beta
        assert np.allclose(step.q_command, lay.trajectory.sample(step.s)[0])          # on the path
        speeds.append(step.sdot)
    assert speeds[1] > 0.0 and np.all(np.diff(speeds) <= 0.0) and speeds[-1] == 0.0   # braked, not jumped
    assert lay.step(ScalingInputs(humans=NOBODY, robot_age=0.0)).status is StepStatus.RUNNING


def test_path_parameter_advances_by_alpha_times_the_period_and_the_goal_is_reached():
    lay = layer()
    step = lay.step(ScalingInputs(humans=NOBODY))
    assert step.s == pytest.approx(step.alpha * 0.01)
    for _ in range(1000):
        step = lay.step(ScalingInputs(humans=NOBODY))
        if step.status is StepStatus.FINISHED:
            break
    assert step.status is StepStatus.FINISHED
    assert np.allclose(step.q_command, Q_GOAL) and np.all(step.qd_command == 0)


def test_nominal_duration_is_kept_when_nobody_is_there():
    lay = layer()
    n = 0
    while lay.step(ScalingInputs(humans=NOBODY)).status is not StepStatus.FINISHED:
        n += 1
    assert n * 0.01 == pytest.approx(lay.trajectory.duration, abs=0.02)


def _human_at(x):
    seg, radii = body_segments(x, 0.0, 1.0, np.array([-0.45, 0.0, 0.5]))
    return HumanCapsules.from_arrays(seg, radii, np.zeros_like(seg), np.ones(len(radii), bool))


def test_beta_rises_at_alpha_min_and_falls_only_above_alpha_release():
    lay = layer(alpha_min=0.2, alpha_release=0.3)
    lay.s = 1.0
    lay.sdot = 1.0
    history = []
    for x in list(np.linspace(-2.5, -0.7, 60)) + list(np.linspace(-0.7, -2.5, 60)):
        lay.s = 1.0                       # keep the robot at the same point of its path
        step = lay.step(ScalingInputs(humans=_human_at(x)))
        history.append((step.safe_alpha, step.beta))
    beta = False
    for safe, got in history:
        beta = True if safe <= 0.2 else (False if safe >= 0.3 else beta)
        assert got == beta
    assert any(b for _, b in history) and not history[-1][1]
    assert any(0.2 < s < 0.3 and b for s, b in history) or not any(0.2 < s < 0.3 for s, _ in history)


def test_a_new_trajectory_keeps_the_path_speed_and_clears_beta():
    lay = layer()
    for _ in range(100):
        lay.step(ScalingInputs(humans=NOBODY))
    lay.beta = True
    sdot = lay.sdot
    lay.set_trajectory(lay.trajectory.with_version(7), s=lay.s)
    assert lay.sdot == sdot and not lay.beta
    assert lay.step(ScalingInputs(humans=NOBODY)).trajectory_version == 7


@given(st.integers(0, 2 ** 31 - 1), st.floats(0.0, 2.4))
def test_every_command_meets_the_ssm_limit(seed, s):
    rng = np.random.default_rng(seed)
    lay = layer()
    lay.s, lay.sdot = s, float(rng.uniform(0, 1))
    m = int(rng.integers(1, 5))
    humans = HumanCapsules.from_arrays(rng.uniform([-1.0, -1.0, 0.2], [0.2, 1.0, 1.2], (m, 1, 3))
                                       + rng.normal(scale=0.15, size=(m, 2, 3)), rng.uniform(0.03, 0.15, m),
                                       rng.normal(scale=0.8, size=(m, 2, 3)), rng.random(m) < 0.8)
    floor = lay.braking_floor(*lay.trajectory.sample(lay.s)[1:])
    step = lay.step(ScalingInputs(humans=humans))
    points, jac = ROBOT.capsule_kinematics(step.q_command)
    check = pair_ssm(points, ROBOT.radii, jac @ step.qd_command, humans, PAPER_SSM)
    if step.method.endswith("+braking"):          # the drives cannot slow down faster: braking at their limit
        assert step.alpha == floor
    else:
        assert np.all(check.margin >= -1e-9)
    assert 0.0 <= step.alpha <= 1.0


def test_no_trajectory_commands_nothing():
    lay = ScalingLayer(ROBOT)
    step = lay.step(ScalingInputs(humans=NOBODY, q_measured=Q_START))
    assert step.status is StepStatus.NO_TRAJECTORY and np.allclose(step.q_command, Q_START)


def test_one_rule_takes_a_new_trajectory_without_a_jump():
    from shared.core.trajectory import straight_line_trajectory

    robot = default_robot()
    lim = robot.limits
    a, b = np.zeros(6), np.full(6, 0.5)
    layer = ScalingLayer(robot, PAPER_SSM, ScalingParameters())
    old = straight_line_trajectory(a, b, lim.velocity, lim.acceleration, version=1)
    layer.set_trajectory(old)
    layer.s, layer.sdot = 0.3, 0.8
    merged = straight_line_trajectory(a, b, lim.velocity, lim.acceleration, version=2)
    assert layer.take(merged, False, junction=0.5, q_here=None, start_tolerance=0.02) is None
    assert layer.trajectory is merged and (layer.s, layer.sdot) == (0.3, 0.8)      # same s, same speed
    assert "already passed" in layer.take(old, False, junction=0.1, q_here=None, start_tolerance=0.02)
    elsewhere = straight_line_trajectory(np.array([0.3, 0, 0, 0, 0, 0]), a, lim.velocity, lim.acceleration, version=3)
    assert "not at its start" in layer.take(elsewhere, True, 0.0, q_here=a, start_tolerance=0.02)
    assert layer.trajectory is merged and layer.step(ScalingInputs(humans=NOBODY)).pending is None
    fresh = straight_line_trajectory(b, a, lim.velocity, lim.acceleration, version=3)
    layer.set_trajectory(old, old.duration)
    layer.sdot = 0.0                                                              # at rest at b
    assert layer.take(fresh, True, 0.0, q_here=b + 0.01, start_tolerance=0.02) is None
    assert layer.trajectory is fresh and (layer.s, layer.sdot) == (0.0, 0.0)      # from rest, at its start


def test_a_plan_from_rest_is_taken_at_once_where_the_joints_stand_whatever_the_path_speed():
    """The one knot a cell holds before its first plan, and the end of a rest-to-rest leg, move nothing however
    fast they are followed: a plan from rest there is taken in the same call and the next step moves on it (it
    used to be stopped for one period first, which stopped nothing). A robot moving along its path is still
    brought to rest at the plan's start first."""
    lim = ROBOT.limits
    standing = straight_line_trajectory(Q_START, Q_START, lim.velocity, lim.acceleration, version=0)
    lay = ScalingLayer(ROBOT, PAPER_SSM, ScalingParameters())
    lay.set_trajectory(standing)
    lay.step(ScalingInputs(humans=NOBODY))
    assert lay.sdot > 0.0                                    # "followed" at full path speed, the joints at rest
    plan = straight_line_trajectory(Q_START, Q_GOAL, lim.velocity, lim.acceleration, version=1)
    assert lay.take(plan, True, 0.0, q_here=Q_START, start_tolerance=1e-3) is None
    assert lay.trajectory is plan and (lay.s, lay.sdot) == (0.0, 0.0)
    step = lay.step(ScalingInputs(humans=NOBODY))
    assert step.trajectory_version == 1 and step.s > 0.0 and step.pending is None
    leg = straight_line_trajectory(Q_START, Q_GOAL, lim.velocity, lim.acceleration, version=2)
    lay.set_trajectory(leg, leg.duration)                  # at the end of its leg, the path speed left at 1
    lay.sdot = 1.0
    back = straight_line_trajectory(Q_GOAL, Q_START, lim.velocity, lim.acceleration, version=3)
    assert lay.take(back, True, 0.0, q_here=Q_GOAL, start_tolerance=1e-3) is None and lay.trajectory is back
    lay.set_trajectory(leg, 0.5 * leg.duration)            # moving in the middle of it: stopped there first
    lay.sdot = 1.0
    ahead = straight_line_trajectory(leg.sample(0.5 * leg.duration + 0.3)[0], Q_START, lim.velocity,
                                     lim.acceleration, version=4)
    assert lay.take(ahead, True, 0.0, q_here=leg.sample(0.5 * leg.duration)[0], start_tolerance=1e-3) is None
    assert lay.trajectory is leg and lay.step(ScalingInputs(humans=NOBODY)).pending == 4


def test_a_plan_from_rest_ahead_of_a_crawling_robot_is_taken_where_the_robot_stops():
    """A plan for a crawling robot starts a few millimetres ahead on its path (shared.planning.replanner's
    stop plan): the layer brings the robot to rest exactly there, never braking harder than the joints'
    planning deceleration in a period (nor the drives' 6 rad/s^2), not even in the step to rest, then
    follows the plan from rest; a robot too fast to stop there keeps its path and the plan is dropped,
    saying why."""
    from shared.core.trajectory import straight_line_trajectory

    lim = ROBOT.limits
    old = straight_line_trajectory(Q_START, Q_GOAL, lim.velocity, lim.acceleration, version=1)
    lay = ScalingLayer(ROBOT, PAPER_SSM, ScalingParameters())
    lay.set_trajectory(old)
    lay.s, lay.sdot = 1.0, 0.2                               # crawling in the middle of the shuttle
    stop_at = 1.04
    back = straight_line_trajectory(old.sample(stop_at)[0], Q_START, lim.velocity, lim.acceleration, version=2)
    assert lay.take(back, True, 0.0, q_here=old.sample(1.0)[0], start_tolerance=1e-3) is None
    assert lay.trajectory is old
    velocity = old.sample(lay.s)[1] * lay.sdot
    methods = []
    one_period = lim.acceleration.max() * 0.01               # rad/s: the most a period's braking takes off
    for _ in range(100):
        step = lay.step(ScalingInputs(humans=NOBODY))
        assert np.abs(step.qd_command - velocity).max() <= one_period + 1e-9     # the plan's first step too
        velocity = step.qd_command
        if step.trajectory_version == 2:
            break
        assert step.pending == 2                             # the step says which plan it stops for
        methods.append(step.method)
        assert step.s <= stop_at + 1e-9
        arrived = step
    assert methods[-1].endswith("+stopping")                # nobody near: only the stop slows it
    # it arrives at the plan's start at a crawl that one period brings to rest, and the plan takes it on
    assert np.abs(arrived.q_command - old.sample(stop_at)[0]).max() < 1e-9
    assert 0.0 < np.abs(arrived.qd_command).max() <= one_period + 1e-9
    assert step.trajectory_version == 2 and (lay.s, lay.sdot) == (0.0, 0.0) and not step.qd_command.any()
    later = [lay.step(ScalingInputs(humans=NOBODY)) for _ in range(20)]
    assert later[-1].trajectory_version == 2 and lay.s > 0.0           # on its way back, from rest
    # a start ahead but within the tolerance of where the robot is: still reached by stopping, not jumped to
    lay.set_trajectory(old)
    lay.s, lay.sdot = 1.0, 0.2
    near = straight_line_trajectory(old.sample(1.005)[0], Q_START, lim.velocity, lim.acceleration, version=3)
    assert lay.take(near, True, 0.0, q_here=old.sample(1.0)[0], start_tolerance=0.02) is None
    assert lay.trajectory is old and lay.step(ScalingInputs(humans=NOBODY)).pending == near.version

    lay.set_trajectory(old)
    lay.s, lay.sdot = 1.02, 1.0                              # at full speed: it cannot stop in 0.02 s of path
    assert lay.take(back, True, 0.0, q_here=old.sample(1.02)[0], start_tolerance=1e-3) is None
    steps = [lay.step(ScalingInputs(humans=NOBODY)) for _ in range(3)]
    assert all(st.trajectory_version == 1 for st in steps) and steps[-1].pending is None
    assert "could not stop" in next(st.dropped for st in steps if st.dropped is not None)


def pending_plan_beside_a_person() -> tuple[ScalingLayer, Trajectory, Trajectory, HumanCapsules]:
    """A robot crawling (path speed 0.2) along the shuttle's line towards a person 0.4 m ahead of its flange, with a
    plan from rest (version 2) that starts ahead of it at s = 1.04 pending: (the layer, the line, the plan, the
    person)."""
    lim = ROBOT.limits
    old = straight_line_trajectory(Q_START, Q_GOAL, lim.velocity, lim.acceleration, version=1)
    q, dq, _ = old.sample(1.0)
    points, velocities = ROBOT.capsule_motion(q, dq)
    ahead = points[-1, 1] + 0.4 * velocities[-1, 1] / np.linalg.norm(velocities[-1, 1])   # in the flange's way
    person = HumanCapsules(np.array([[ahead, ahead]]), np.array([0.1]), np.zeros((1, 2, 3)), np.array([True]))
    lay = ScalingLayer(ROBOT, PAPER_SSM, ScalingParameters())
    lay.set_trajectory(old)
    lay.s, lay.sdot = 1.0, 0.2
    back = straight_line_trajectory(old.sample(1.04)[0], Q_START, lim.velocity, lim.acceleration, version=2)
    assert lay.take(back, True, 0.0, q_here=q, start_tolerance=1e-3) is None
    return lay, old, back, person


def test_a_plan_ahead_whose_start_the_ssm_keeps_the_robot_from_is_dropped_once_it_is_held_at_rest():
    """A person who came closer after the stop plan was made holds the robot short of its start: it would
    wait there for as long as they stay, so the plan is dropped, saying why, and a plan from rest where the
    robot stands is taken instead (the paper's phase 4, where the robot used to stand still beside the arm)."""
    lay, old, back, person = pending_plan_beside_a_person()
    lim = ROBOT.limits
    steps = [lay.step(ScalingInputs(humans=person))]
    while steps[-1].pending is not None and len(steps) < 100:
        steps.append(lay.step(ScalingInputs(humans=person)))
    assert all(st.pending == 2 and st.dropped is None for st in steps[:-1]) and len(steps) > 1
    assert steps[-1].dropped.startswith("held by the SSM") and "plan 2" in steps[-1].dropped
    assert all(st.trajectory_version == 1 and st.s < 1.04 for st in steps)
    assert np.abs(old.sample(lay.s)[1] * lay.sdot).max() < 0.02            # at rest, short of the start
    here = old.sample(lay.s)[0]
    fresh = straight_line_trajectory(here, Q_START, lim.velocity, lim.acceleration, version=3)
    for _ in range(5):                                    # the braking floor has brought it to rest exactly
        lay.step(ScalingInputs(humans=person))
    assert lay.take(fresh, True, 0.0, q_here=old.sample(lay.s)[0], start_tolerance=0.02) is None
    assert lay.trajectory is fresh


def test_a_plan_ahead_is_not_dropped_for_a_hold_shorter_than_held_short_for():
    """Beside a person the SSM's bound chatters with the data's age (0 at a frame's end, up on a fresh frame) and the
    robot creeps on between: a hold of a few cycles short of a pending plan's start does not drop the plan, which is
    taken at its start once the robot gets there (dropped at the first such cycle, every stop plan was lost:
    real_table_edge seed 6, 30 ms late). A hold of HELD_SHORT_FOR drops it (the test above)."""
    from shared.scaling.layer import HELD_SHORT_FOR

    lay, old, back, person = pending_plan_beside_a_person()
    steps = [lay.step(ScalingInputs(humans=person))]
    while steps[-1].pending is not None and steps[-1].speed >= 0.02 and len(steps) < 100:   # brought to rest short
        steps.append(lay.step(ScalingInputs(humans=person)))
    held = int(round(0.5 * HELD_SHORT_FOR / lay.params.period))
    steps += [lay.step(ScalingInputs(humans=person)) for _ in range(held)]          # held short, half the grace
    assert all(st.dropped is None and st.pending == 2 for st in steps)
    nobody = HumanCapsules.empty()
    for _ in range(300):                                  # the person steps back: the robot goes on to the start
        steps.append(lay.step(ScalingInputs(humans=nobody)))
        if lay.trajectory is back:
            break
    assert lay.trajectory is back and all(st.dropped is None for st in steps)


def test_a_plan_whose_start_a_crawl_has_passed_is_refused_with_the_services_tolerance_never_jumped_back_to():
    """The scaler service takes plans with a start tolerance of 0.02 rad, for the drives' following error. A plan from
    rest made where the robot stood is passed by the crawl before it comes (beside a person the bound chatters and
    the robot creeps on): its start is not on the path ahead within AT_START, so it is refused, not taken where the
    robot is with the command jumping back 15.7 mrad in one period. One that starts on the path ahead is stopped at."""
    from shared.scaling.layer import AT_START

    lim = ROBOT.limits
    old = straight_line_trajectory(Q_START, Q_GOAL, lim.velocity, lim.acceleration, version=1)
    lay = ScalingLayer(ROBOT, PAPER_SSM, ScalingParameters())
    lay.set_trajectory(old)
    lay.s, lay.sdot = 1.0, 0.05
    here = lay.step(ScalingInputs(humans=HumanCapsules.empty())).q_command
    passed = straight_line_trajectory(old.sample(lay.s - 0.01)[0], Q_START, lim.velocity, lim.acceleration, version=2)
    assert 10 * AT_START < np.abs(passed.positions[0] - here).max() < 0.02
    why = lay.take(passed, True, 0.0, q_here=here, start_tolerance=0.02)
    assert why is not None and "never jumped to" in why
    assert lay.trajectory is old
    ahead = straight_line_trajectory(old.sample(lay.s + 0.01)[0], Q_START, lim.velocity, lim.acceleration, version=3)
    assert lay.take(ahead, True, 0.0, q_here=here, start_tolerance=0.02) is None
    steps = [lay.step(ScalingInputs(humans=HumanCapsules.empty())) for _ in range(30)]
    assert lay.trajectory is ahead
    commands = np.array([here] + [st.q_command for st in steps])
    assert np.abs(np.diff(commands, axis=0)).max() < 0.01           # no jump on the way to its start


def test_a_plan_for_a_crawling_robot_that_comes_after_the_ssm_stopped_it_short_is_refused_not_jumped_to():
    """The SSM has stopped the robot (at rest, its joints where its command is) short of where a plan for a crawling
    robot starts, within the scaler's start tolerance: taking it would make the command jump ahead, towards the
    person who stopped it, and the drives would move there unchecked (seen on the processes: 13 mrad). It is
    refused, saying so, the command stays, and a plan from where the robot stands is taken."""
    from shared.scaling.layer import AT_START

    lim = ROBOT.limits
    old = straight_line_trajectory(Q_START, Q_GOAL, lim.velocity, lim.acceleration, version=1)
    lay = ScalingLayer(ROBOT, PAPER_SSM, ScalingParameters())
    lay.set_trajectory(old, 1.0)
    lay.sdot = 0.0                                           # stopped by the SSM at s = 1.0
    here = old.sample(1.0)[0]
    ahead = straight_line_trajectory(old.sample(1.01)[0], Q_START, lim.velocity, lim.acceleration, version=2)
    assert AT_START < np.abs(ahead.positions[0] - here).max() < 0.02        # within the drives' tolerance
    why = lay.take(ahead, True, 0.0, q_here=here, start_tolerance=0.02)
    assert why is not None and "never jumped to" in why
    step = lay.step(ScalingInputs(humans=NOBODY))
    assert step.trajectory_version == 1 and step.speed <= lim.acceleration.max() * 0.01 + 1e-9   # no jump: on from
    assert np.abs(step.q_command - here).max() <= step.speed * 0.01 + 1e-12                # rest, as the SSM allows
    fresh = straight_line_trajectory(here, Q_START, lim.velocity, lim.acceleration, version=3)
    lay.set_trajectory(old, 1.0)
    lay.sdot = 0.0
    assert lay.take(fresh, True, 0.0, q_here=here + 0.005, start_tolerance=0.02) is None   # the drives' lag: fine
    assert lay.trajectory is fresh


def _crawling_beside_a_person(await_plan: float = 0.3):
    """The shuttle at s = 1.0, crawling at the SSM's bound (0.17) towards a person 0.65 m ahead of the flange,
    where the bound is 0.18 and falling: a replan request is due."""
    lim = ROBOT.limits
    old = straight_line_trajectory(Q_START, Q_GOAL, lim.velocity, lim.acceleration, version=1)
    q, dq, _ = old.sample(1.0)
    points, velocities = ROBOT.capsule_motion(q, dq)
    ahead = points[-1, 1] + 0.65 * velocities[-1, 1] / np.linalg.norm(velocities[-1, 1])
    person = HumanCapsules(np.array([[ahead, ahead]]), np.array([0.1]), np.zeros((1, 2, 3)), np.array([True]))
    lay = ScalingLayer(ROBOT, PAPER_SSM, ScalingParameters(await_plan=await_plan))
    lay.set_trajectory(old)
    lay.s, lay.sdot = 1.0, 0.17
    return lay, old, person


def test_a_crawling_robot_that_asks_for_a_replan_stops_and_awaits_the_plan_where_it_stands():
    """Beta rising while the robot crawls brings it to rest where the discrete stop from its speed ends
    (never braking harder than the joints' planning deceleration in a period), and it stands exactly there,
    saying where (``awaiting``), until its plan from rest there comes and is taken; with no plan, it goes on
    at the SSM's speed after await_plan, and does not stop again while the same request stands."""
    lay, old, person = _crawling_beside_a_person()
    lim = ROBOT.limits
    one_period = lim.acceleration.max() * 0.01
    velocity = old.sample(lay.s)[1] * lay.sdot
    first = lay.step(ScalingInputs(humans=person))
    assert first.beta and first.awaiting is not None and first.awaiting > first.s
    stop_at = first.awaiting
    steps = [first]
    for _ in range(15):
        steps.append(lay.step(ScalingInputs(humans=person)))
    for step in steps:
        assert np.abs(step.qd_command - velocity).max() <= one_period + 1e-9
        assert step.s <= stop_at + 1e-12 and step.trajectory_version == 1
        velocity = step.qd_command
    assert steps[-1].awaiting == stop_at and steps[-1].s == stop_at and not steps[-1].qd_command.any()
    assert "+stopping" in steps[2].method
    here = old.sample(stop_at)[0]
    assert np.abs(steps[-1].q_command - here).max() < 1e-12
    plan = straight_line_trajectory(here, Q_START, lim.velocity, lim.acceleration, version=2)
    assert lay.take(plan, True, 0.0, q_here=here, start_tolerance=1e-3) is None
    assert lay.trajectory is plan and lay.step(ScalingInputs(humans=person)).awaiting is None

    lay, old, person = _crawling_beside_a_person()          # no plan comes: it waits await_plan, then goes on
    steps = [lay.step(ScalingInputs(humans=person)) for _ in range(60)]
    waiting = [k for k, step in enumerate(steps) if lay.params.period * k <= 0.3 and step.sdot == 0.0]
    assert waiting and all(step.beta for step in steps)
    assert steps[-1].sdot > 0.0 and steps[-1].s > steps[waiting[-1]].s and steps[-1].awaiting is None

    lay, old, person = _crawling_beside_a_person(await_plan=0.0)  # nobody answers: it never stands to wait
    steps = [lay.step(ScalingInputs(humans=person)) for _ in range(20)]
    assert steps[0].beta and all(step.awaiting is None and step.sdot > 0.0 for step in steps)



def test_people_data_that_took_a_while_is_checked_with_the_persons_travel_since_its_capture():
    """Data 30 ms old (a camera's latency, the wait for its next frame): the cycle's SSM counts the person's travel
    over those 30 ms (``SsmParameters.aged`` of the age; what it prevents: tests/evidence/test_latency_sim.py), so a
    person walking towards the base allows a lower speed than the same data of now, the more so the older it is,
    under the paper's formula and under the shipped human model."""
    humans = HumanCapsules.from_arrays([[[-1.5, 0.3, 0.6], [-1.5, 0.3, 1.4]]], [0.12], [[[1.2, 0, 0], [1.2, 0, 0]]],
                                       [True])                         # walking towards the base at 1.2 m/s

    def step(ssm, age):
        lay = ScalingLayer(ROBOT, ssm, ScalingParameters())
        lay.set_trajectory(straight_line_trajectory(Q_START, Q_GOAL, ROBOT.limits.velocity, ROBOT.limits.acceleration))
        lay.s, lay.sdot = 1.0, 0.6
        return lay.step(ScalingInputs(humans=humans, human_age=age))

    for ssm in (PAPER_SSM, LAID_OUT):
        older, late, of_now = step(ssm, 0.045), step(ssm, 0.03), step(ssm, 0.0)
        assert 0.0 < older.safe_alpha < late.safe_alpha < of_now.safe_alpha < 1.0
