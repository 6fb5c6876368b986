"""A robot held beside a person under the shipped model (a person at rest may start to move): every link inside
their protective distance, where the SSM lets nothing approach them. The state is ``hrc demo --human
docs/motions/two_people.json`` on the processes (session 72): the robot stopped on the folded leg beside Bob, and
before the staged candidates every plan from rest was predicted as slow as the old trajectory for the rest of the
run."""

import numpy as np

from evidence.scenarios import Q_GOAL
from shared.core.humans import HumanCapsules
from shared.core.trajectory import polyline_trajectory
from shared.planning.collision import CollisionModel
from shared.planning.executed import ExecutedTime
from shared.planning.ompl_planner import JointPlanner, PlannerOptions
from shared.planning.path_search import PathSearch, SearchOptions
from shared.planning.replanner import Replanner
from shared.planning.scene import DEFAULT_SCENE, load_scene
from shared.planning.time_cost import SsmTimeCost
from shared.robot.model import default_robot
from shared.scaling.parameters import ScalingParameters
from shared.scaling.problem import ssm_alpha_bound
from tests.util import LAID_OUT_SSM

ROBOT = default_robot()
LIM = ROBOT.limits
CM = CollisionModel(ROBOT, load_scene(DEFAULT_SCENE))
SHIPPED = LAID_OUT_SSM


# a person standing beside the start of the sweep, leaning in, a hand reaching half-way into it (capsule ends, m,
# and radii: docs/motions/two_people.json's Bob from 6 s on), and the arm held beside them on the folded leg
BESIDE = HumanCapsules.from_arrays(
    np.array([[[-0.9, -0.5, 0.95], [-0.74, -0.41, 1.3]], [[-0.74, -0.41, 1.57], [-0.74, -0.41, 1.57]],
              [[-0.84, -0.24, 1.3], [-0.86, -0.19, 1.0]], [[-0.86, -0.19, 1.0], [-0.82, -0.17, 0.73]],
              [[-0.82, -0.17, 0.73], [-0.82, -0.17, 0.73]], [[-0.65, -0.59, 1.3], [-0.61, -0.47, 1.03]],
              [[-0.61, -0.47, 1.03], [-0.56, -0.34, 0.71]], [[-0.56, -0.34, 0.71], [-0.56, -0.34, 0.71]]]),
    np.array([0.217, 0.217, 0.1, 0.066, 0.103, 0.1, 0.066, 0.103]), np.zeros((8, 2, 3)), np.ones(8, bool))
HELD = np.array([1.542, -0.4, 1.191, 0.0, 1.57, 0.0])


def test_a_robot_held_beside_a_person_folds_first_and_passes_them_without_waiting_for_them_to_leave():
    """Every link is inside the person's protective distance: the SSM lets the arm fold its elbow away from them,
    but not raise its shoulder or turn its base, and the lifts' change of posture (both joints at once) cannot
    start. Without staging, the best lift or raise waits for them to leave (the whole stay); staged (the elbow, then
    the shoulder, then the turn with the arm folded) the path's cost does not grow with the stay, and a forward run
    of the scaling layer itself takes the arm to the goal with the person still there."""
    cost = SsmTimeCost(ROBOT, SHIPPED)
    fold_and_raise = np.array([0.0, 0.3, 1.2, 0.0, 0.0, 0.0])          # rad/s: shoulder raised, elbow folded
    elbow = np.array([0.0, 0.0, 1.2, 0.0, 0.0, 0.0])
    assert ssm_alpha_bound(ROBOT, HELD, fold_and_raise, BESIDE, SHIPPED) == 0.0
    assert ssm_alpha_bound(ROBOT, HELD, elbow, BESIDE, SHIPPED) > 0.5
    options = SearchOptions(candidates=0, refinements=0, escape_directions=0)
    direct = np.vstack([HELD, Q_GOAL])
    unstaged, staged = PathSearch(CM, cost, options), PathSearch(CM, cost, options)
    unstaged._staged = lambda *args: []
    long_stay = 30.0
    waits = unstaged.search(HELD, Q_GOAL, BESIDE, np.random.default_rng(0), stay=long_stay, seeds=(direct,))
    passes = staged.search(HELD, Q_GOAL, BESIDE, np.random.default_rng(0), stay=long_stay, seeds=(direct,))
    assert waits.predicted > long_stay
    assert passes.origin == "staged" and passes.predicted < long_stay / 2 and staged.free(passes.waypoints, BESIDE)
    first = passes.waypoints[1] - HELD
    assert first[2] > 1.0 and np.abs(np.delete(first, 2)).max() < 1e-9          # the elbow alone first
    # timed with a stop at each corner (the planning layer's timing where the smoothed path would touch the elbow's
    # limit, as here), the person staying throughout: the staged path gets there, the unstaged one never starts
    executed = ExecutedTime(ROBOT, SHIPPED, ScalingParameters(), longest=long_stay)
    assert executed.time(polyline_trajectory(passes.waypoints, LIM.velocity, LIM.acceleration), 0.0, BESIDE) < 15.0
    assert executed.time(polyline_trajectory(waits.waypoints, LIM.velocity, LIM.acceleration), 0.0, BESIDE) == long_stay


def test_a_staged_path_from_rest_keeps_its_corners_where_smoothing_them_would_wait_for_the_person():
    """The planning layer's path from where the robot is held (its search, refined) starts with the elbow alone.
    Timed by TOPP-RA it never rests between its ends: it turns and raises while it still folds, which may not
    start beside the person. With the time held given, the plan from rest stops at its corners instead, predicted
    faster by more than a replan must save; without it (None), the smoothed timing as before."""
    planner = Replanner(CM, JointPlanner(CM, PlannerOptions(seed=1)), SHIPPED)
    waited = 2.0
    waypoints = planner.path(HELD, Q_GOAL, BESIDE, waited)
    others = [0, 1, 3, 4, 5]                                                        # every joint but the elbow
    assert waypoints[1][2] > HELD[2] + 1.0 and np.allclose(waypoints[1][others], HELD[others])   # staged
    smooth = planner.candidates.from_rest(waypoints, BESIDE, 1)
    corners = planner.candidates.from_rest(waypoints, BESIDE, 1, waited)
    inner = smooth.sample(np.linspace(0.05, 0.95, 200) * smooth.duration)[1]
    assert np.linalg.norm(inner, axis=1).min() > 1e-3         # the smoothing never rests: it turns while it folds
    at_corner = np.flatnonzero(np.all(np.isclose(corners.positions, waypoints[1]), axis=1))
    assert at_corner.size and np.allclose(corners.velocities[at_corner], 0.0)      # at rest after the fold
    assert planner.predicted_time(corners, 0.0, BESIDE, waited) < 0.9 * planner.predicted_time(smooth, 0.0, BESIDE,
                                                                                                 waited)
