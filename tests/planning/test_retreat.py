"""A robot its replans led into a person's slowdown, where every path on to the goal waits for them: a plan from
rest may go back to where the leg began and take the leg again from there (``Candidates.retreat``).

The state is a real run's (``bench/real_people.py``, task1_human2_trial1 at the table's edge, on the processes,
loaded; 2026-12-04): the robot stood from 6 s to the end of the 47 s recording, its arm leant back towards the
person's body, and every plan searched from there was predicted to wait for them as the old one did."""

import numpy as np
import pytest

from shared.core.humans import HumanCapsules
from shared.core.trajectory import straight_line_trajectory
from shared.planning.collision import CollisionModel
from shared.planning.decision import ReplanFailed
from shared.planning.ompl_planner import JointPlanner, PlannerOptions
from shared.planning.replanner import Replanner
from shared.planning.scene import DEFAULT_SCENE, load_scene
from shared.robot.model import default_robot
from tests.util import LAID_OUT_SSM

ROBOT = default_robot()
LIM = ROBOT.limits
CM = CollisionModel(ROBOT, load_scene(DEFAULT_SCENE))
SHIPPED = LAID_OUT_SSM
LEG_START = np.array([1.57, -0.4, 1.17, 0.0, 1.57, 0.0])        # where the leg began, at rest
GOAL = np.array([-1.57, -0.4, 1.17, 0.0, 1.57, 0.0])
HELD_AT = np.array([0.620081, -1.199181, 1.343502, -0.174341, 1.737545, -0.470488])
# the tracked person 20 s into the run (tracker_ingest's state): body, then two arms of three capsules
PERSON = HumanCapsules(
    np.array([[[-0.846, 0.02841, 0.76182], [-0.846, 0.02841, 1.56182]],
              [[-0.845, 0.16087, 1.272], [-0.839049, 0.329486, 1.073441]],
              [[-0.839049, 0.329486, 1.073441], [-0.718963, 0.16983, 1.046184]],
              [[-0.718963, 0.16983, 1.046184], [-0.718963, 0.16983, 1.046184]],
              [[-0.847, -0.10404, 1.25163], [-0.80564, -0.244342, 1.036005]],
              [[-0.80564, -0.244342, 1.036005], [-0.695595, -0.07548, 1.0411]],
              [[-0.695595, -0.07548, 1.0411], [-0.695595, -0.07548, 1.0411]]]),
    np.array([0.217, 0.1, 0.066, 0.103, 0.1, 0.066, 0.103]),
    np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
              [[0.0, 0.0, 0.0], [-0.06063, 0.03522, 0.02727]],
              [[-0.06063, 0.03522, 0.02727], [-0.06756, 0.0375, -0.02172]],
              [[-0.06756, 0.0375, -0.02172], [-0.06756, 0.0375, -0.02172]],
              [[0.0, 0.0, 0.0], [0.01095, -0.00579, 0.00615]],
              [[0.01095, -0.00579, 0.00615], [-0.00345, 0.00465, -0.0141]],
              [[-0.00345, 0.00465, -0.0141], [-0.00345, 0.00465, -0.0141]]]),
    np.ones(7, dtype=bool))
HELD = straight_line_trajectory(HELD_AT, GOAL, LIM.velocity, LIM.acceleration, version=4)   # the way on, at rest


def replanner(leg_start):
    planner = Replanner(CM, JointPlanner(CM, PlannerOptions(seed=1)), SHIPPED)
    planner.forget(leg_start)
    return planner


def test_every_way_on_waits_for_the_person_as_the_old_one_does():
    """What the run did: held for 14 s, the plan searched from where the robot stands waits for the person as the
    old trajectory does (each predicted longer than the people are assumed to stay), so it saves a fraction of a
    second however long the wait, and the run stood to its end (the baseline of the next test: the way back is
    what changes it)."""
    without = replanner(None)
    stay = without.stay(14.0)
    assert without.predicted_time(HELD, 0.0, PERSON, 14.0) > stay          # the old way waits for them
    searched = without.candidates.rest_plan(HELD, 0.0, GOAL, PERSON, "beta", 14.0)
    assert "back by" not in searched.detail and searched.predicted > stay    # and so does the searched one
    assert searched.predicted > without.predicted_time(HELD, 0.0, PERSON, 14.0) - 1.0


def test_held_long_the_robot_goes_back_by_where_the_leg_began_clear_of_the_person():
    """With the leg's start known, the plan from rest goes back there on the straight line, comes to rest, and
    takes the leg from there (the fold: the person is near); predicted seconds faster than waiting, and free of
    the person's margin all along. Held only a moment, waiting is still predicted the better bet
    (ski rental: the way back costs a leg's length again), and the plan from rest is not the way back."""
    planner = replanner(LEG_START)
    result = planner.on_beta(HELD, 0.0, GOAL, PERSON, speed_now=0.0, waited=14.0, held=True)
    assert "back by where the leg began" in result.detail and result.from_rest
    assert result.predicted < result.baseline - 2.0
    traj = result.trajectory
    assert np.allclose(traj.positions[0], HELD_AT) and np.allclose(traj.positions[-1], GOAL)
    at_start = np.flatnonzero(np.all(np.isclose(traj.positions, LEG_START), axis=1))
    assert at_start.size and np.allclose(traj.velocities[at_start], 0.0)     # at rest where the leg began
    q = traj.sample(np.linspace(0.0, traj.duration, 400))[0]
    near = np.array([CM.clearances(qk[None], PERSON, inflation=0.0).min() for qk in q])
    assert near[0] > 0.0 and near.min() > 0.0          # free of the person's margin all along, as it starts
    back = planner.candidates.retreat(HELD_AT, GOAL, PERSON, 5)             # held a second: waiting is the bet
    assert planner.predicted_time(back, 0.0, PERSON, 1.0) > planner.predicted_time(HELD, 0.0, PERSON, 1.0) + 1.0
    assert "back by" not in planner.candidates.rest_plan(HELD, 0.0, GOAL, PERSON, "beta", 1.0).detail


def test_no_way_back_is_offered_from_where_the_leg_began_or_when_it_is_not_known():
    planner = replanner(LEG_START)
    assert planner.candidates.retreat(LEG_START + 0.01, GOAL, PERSON, 1) is None
    assert replanner(None).candidates.retreat(HELD_AT, GOAL, PERSON, 1) is None
    assert planner.candidates.retreat(HELD_AT, GOAL, PERSON, 1) is not None


def test_where_the_search_finds_nothing_the_way_back_is_still_a_plan_and_without_it_the_refusal_says_why():
    from shared.planning.ompl_planner import PlanningError

    def nothing(*args, **kwargs):
        raise PlanningError("no path found")

    planner = replanner(LEG_START)
    planner.candidates.path = planner.candidates.paths = nothing
    result = planner.candidates.rest_plan(HELD, 0.0, GOAL, PERSON, "beta", 14.0)
    assert result.detail == "back by where the leg began" and np.allclose(result.trajectory.positions[-1], GOAL)
    bare = replanner(None)
    bare.candidates.path = bare.candidates.paths = nothing
    with pytest.raises(ReplanFailed, match="from rest: PlanningError: no path found"):
        bare.candidates.rest_plan(HELD, 0.0, GOAL, PERSON, "beta", 14.0)
