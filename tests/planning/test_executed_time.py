"""A candidate judged by the scaling layer itself (shared.planning.executed): the forward run of the product's own
ScalingLayer along a trajectory, against a forecast of the people, and the replanner's decisions predicted by it
where ReplanOptions.judge says so."""

import numpy as np
import pytest

from evidence.scenarios import Q_GOAL, Q_START, body_segments
from shared.core.humans import HumanCapsules
from shared.core.trajectory import straight_line_trajectory
from shared.planning.collision import CollisionModel
from shared.planning.executed import ExecutedTime
from shared.planning.ompl_planner import JointPlanner, PlannerOptions
from shared.planning.options import ReplanOptions
from shared.planning.replanner import Replanner
from shared.planning.scene import DEFAULT_SCENE, load_scene
from shared.robot.model import default_robot
from shared.safety.parameters import SsmParameters
from shared.scaling.layer import ScalingInputs, ScalingLayer, StepStatus
from shared.scaling.parameters import ScalingParameters
from tests.util import LAID_OUT_SSM

ROBOT = default_robot()
SSM = SsmParameters().paper_formula()          # the paper's formula: a person beside the path slows, not stops
LEG = straight_line_trajectory(Q_START, Q_GOAL, ROBOT.limits.velocity, ROBOT.limits.acceleration)
PERIOD = ScalingParameters().period


def person(x: float, velocity=(0.0, 0.0, 0.0)) -> HumanCapsules:
    seg, radii = body_segments(x, 0.0, 1.0, np.array([-0.4, 0.0, 0.8]))
    vel = np.broadcast_to(np.asarray(velocity, dtype=float), seg.shape).copy()
    return HumanCapsules.from_arrays(seg, radii, vel, np.ones(len(radii), bool))


def test_with_nobody_the_forward_run_takes_the_time_law():
    judge = ExecutedTime(ROBOT, SSM, ScalingParameters())
    assert judge.time(LEG, 0.0, None) == pytest.approx(LEG.duration, abs=2 * PERIOD)
    assert judge.time(LEG, 0.0, HumanCapsules.empty()) == pytest.approx(LEG.duration, abs=2 * PERIOD)
    half = LEG.duration / 2                                        # from the middle, at speed
    assert judge.time(LEG, half, None) == pytest.approx(LEG.duration - half, abs=2 * PERIOD)


def test_the_forward_run_is_the_scaling_layers_own_steps_against_the_forecast():
    """A person who stays: the judge's time is the cycle at which the product's layer, stepped by hand with
    that person, finishes the leg."""
    near = person(-1.08)                                              # slows the sweep, does not hold it
    layer = ScalingLayer(ROBOT, SSM, ScalingParameters(await_plan=0.0))
    layer.set_trajectory(LEG)
    by_hand = next(k * PERIOD for k in range(3000)
                   if layer.step(ScalingInputs(humans=near)).status is StepStatus.FINISHED)
    judged = ExecutedTime(ROBOT, SSM, ScalingParameters()).time(LEG, 0.0, near)
    assert judged == pytest.approx(by_hand, abs=1e-9) and judged > LEG.duration + 0.2     # the person slows it


def test_people_who_leave_or_walk_away_cost_less_and_one_who_never_leaves_costs_the_longest():
    judge = ExecutedTime(ROBOT, LAID_OUT_SSM, ScalingParameters(), longest=6.0)   # the shipped model
    blocking = person(-1.0)                     # near enough that even a creeping robot may not pass them
    stays = judge.time(LEG, 0.0, blocking)
    assert stays == 6.0                                               # held for as long as it looks
    leaves = judge.time(LEG, 0.0, blocking, stay=1.0)
    assert 1.0 < leaves < stays and leaves == pytest.approx(1.0 + LEG.duration, abs=0.6)
    walking_away = judge.time(LEG, 0.0, person(-1.0, velocity=(-1.5, 0.0, 0.0)))
    assert walking_away < stays


def test_the_replanner_predicts_by_the_forward_run_when_asked():
    collision = CollisionModel(ROBOT, load_scene(DEFAULT_SCENE), SSM.min_separation)
    planner = JointPlanner(collision, PlannerOptions(seed=1))
    by_cost = Replanner(collision, planner, SSM)
    by_run = Replanner(collision, planner, SSM, options=ReplanOptions(judge="scaling"))
    near = person(-1.08)
    assert by_cost.executed is None
    run = by_run.predicted_time(LEG, 0.0, near)
    assert run == ExecutedTime(ROBOT, SSM, ScalingParameters()).time(LEG, 0.0, near, by_run.stay(0.0))
    assert run != by_cost.predicted_time(LEG, 0.0, near) and by_run.executed.runs == 1
    with pytest.raises(ValueError, match="judge"):
        ReplanOptions(judge="guess")
