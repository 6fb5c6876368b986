"""Whether the forecast of the people has held (shared.planning.trust), and the choice it gates: a new goal's straight
line instead of the folded leg (Replanner.plan_goal, PlanningLoop)."""

from __future__ import annotations

import numpy as np
import pytest

from evidence.scenarios import Q_GOAL, Q_START
from shared.core.humans import HumanCapsules
from shared.planning.collision import CollisionModel
from shared.planning.forecast import ConstantVelocity
from shared.planning.horizon import reach_gap
from shared.planning.loop import PlanningLoop
from shared.planning.ompl_planner import JointPlanner, PlannerOptions
from shared.planning.postures import ELBOW
from shared.planning.replanner import Replanner, ReplanOptions
from shared.planning.scene import DEFAULT_SCENE, load_scene
from shared.planning.trust import ForecastTrust
from shared.robot.model import default_robot
from shared.safety.parameters import SsmParameters

CM = CollisionModel(default_robot(), load_scene(DEFAULT_SCENE))


def person(x: float, y: float, velocity=(0.0, 0.0, 0.0), known: bool = True) -> HumanCapsules:
    """A standing body (one capsule, feet to head) at (x, y), moving at `velocity` (m/s)."""
    return HumanCapsules.from_arrays([[[x, y, 0.0], [x, y, 1.7]]], [0.2], np.tile(velocity, (1, 2, 1)), [known])


def walk(trust: ForecastTrust, t0: float, t1: float, start, velocity, rate: float = 30.0) -> tuple[float, float]:
    """Feed a steady walk from `start` (x, y at t0) at `velocity` (m/s) from t0 to t1 at `rate` Hz; returns where
    the walker is at t1."""
    x, y = start
    for t in np.arange(t0, t1 + 1e-9, 1.0 / rate):
        x, y = start[0] + velocity[0] * (t - t0), start[1] + velocity[1] * (t - t0)
        trust.update(float(t), person(x, y, (velocity[0], velocity[1], 0.0)))
    return x, y


def test_a_steady_walk_is_trusted_from_its_first_sample_and_a_turn_within_the_first_span_ends_that():
    trust = ForecastTrust(ConstantVelocity(), span=1.0, tolerance=0.15)
    assert not trust.trusted(0.0)                                  # nobody yet
    trust.update(0.0, person(-2.0, -2.0, (0.0, 1.6, 0.0)))
    assert trust.error(0.0) == np.inf and trust.trusted(0.0)       # a walker's course is in their velocity
    walk(trust, 0.0, 0.5, (-2.0, -2.0), (0.0, 1.6))
    assert trust.trusted(0.5)                                      # half a span, and it has held so far
    walk(trust, 0.5, 1.5, (-2.0, -1.2), (0.0, 1.6))
    assert trust.error(1.5) < 0.01 and trust.trusted(1.5)
    turning = ForecastTrust(ConstantVelocity(), span=1.0, tolerance=0.15)
    x, y = walk(turning, 0.0, 0.4, (-2.0, -2.0), (0.0, 1.6))
    walk(turning, 0.4 + 1 / 30, 0.7, (x, y), (0.0, -1.6))        # turned back after 0.4 s
    assert turning.error(0.7, partial=True) > 0.5 and not turning.trusted(0.7)


def test_someone_at_rest_when_first_seen_is_trusted_only_once_the_span_has_held():
    """A person standing, or one whose body is partly at rest (a hand still, the torso walking), gives no sign of
    where they go next: the fold is made until the forecast has held for the span."""
    trust = ForecastTrust(ConstantVelocity(), span=1.0, tolerance=0.15)
    for t in np.arange(0.0, 0.9 + 1e-9, 1 / 30):
        trust.update(float(t), person(-1.5, 0.5))
        assert not trust.trusted(float(t))
    for t in np.arange(0.9 + 1 / 30, 1.2 + 1e-9, 1 / 30):
        trust.update(float(t), person(-1.5, 0.5))
    assert trust.trusted(1.2)
    half = ForecastTrust(ConstantVelocity(), span=1.0, tolerance=0.15)
    half.update(0.0, HumanCapsules.from_arrays([[[-2.0, 1.0, 0.0], [-2.0, 1.0, 1.7]], [[-2.0, 1.2, 1.0], [-1.6, 1.2, 1.2]]],
                                               [0.2, 0.05], [[[0.0, 1.6, 0.0]] * 2, [[0.0, 0.0, 0.0]] * 2], [True, True]))
    assert not half.trusted(0.0)


def test_a_walker_who_has_just_stopped_is_not_trusted_until_the_stop_has_held():
    trust = ForecastTrust(ConstantVelocity(), span=1.0, tolerance=0.15)
    x, y = walk(trust, 0.0, 1.5, (-2.0, -2.0), (0.0, 1.6))
    assert trust.trusted(1.5)
    for t in np.arange(1.5 + 1 / 30, 1.8 + 1e-9, 1 / 30):          # stopped: standing where they got to
        trust.update(float(t), person(x, y))
    # the forecast of 1 s ago has them 0.3 s x 1.6 m/s further on
    assert trust.error(1.8) == pytest.approx(0.48, abs=0.06) and not trust.trusted(1.8)
    for t in np.arange(1.8 + 1 / 30, 3.0 + 1e-9, 1 / 30):
        trust.update(float(t), person(x, y))
    assert trust.trusted(3.0)                                      # standing for a span: the forecast holds again


def test_an_unknown_velocity_or_a_new_capsule_starts_the_record_again():
    trust = ForecastTrust(ConstantVelocity(), span=1.0, tolerance=0.15)
    x, y = walk(trust, 0.0, 1.5, (-2.0, -2.0), (0.0, 1.6))
    assert trust.trusted(1.5)
    trust.update(1.55, person(x, y + 0.08, known=False))           # the tracker lost the velocity
    assert not trust.trusted(1.55)
    walk(trust, 1.6, 2.0, (x, y + 0.16), (0.0, 1.6))
    assert trust.error(2.0) == np.inf and trust.trusted(2.0)       # less than a span since, a walk that has held
    walk(trust, 2.0, 2.7, (x, y + 0.8), (0.0, 1.6))
    assert trust.error(2.7) < 0.01 and trust.trusted(2.7)
    two = HumanCapsules.from_arrays([[[-2.0, 1.0, 0.0], [-2.0, 1.0, 1.7]], [[-3.0, 0.0, 0.0], [-3.0, 0.0, 1.7]]],
                                    [0.2, 0.2], np.zeros((2, 2, 3)), [True, True])
    trust.update(2.75, two)                                        # someone came in
    assert not trust.trusted(2.75)
    trust.update(2.8, None)                                        # nobody in view
    assert not trust.trusted(2.8)
    with pytest.raises(ValueError):
        ForecastTrust(ConstantVelocity(), span=0.0)


def test_a_new_goal_takes_the_line_instead_of_the_fold_only_where_the_forecast_has_held_and_says_so():
    """A person 2 m off the robot's reach, walking away: within the posture gap, so the fold by default; the line is
    predicted faster (nobody comes near it, and the fold is the longer path). Trusted, the line; not, the fold.
    Where the fold is predicted faster, it stays, trusted or not."""
    replanner = Replanner(CM, JointPlanner(CM, PlannerOptions(seed=7)), SsmParameters())
    away = person(-2.6, 0.0, (-1.2, 0.0, 0.0))
    assert 0.0 < reach_gap(CM, away) < replanner.options.posture_gap
    folded = replanner.plan_goal(Q_START, Q_GOAL, away, 3)
    assert folded.positions[:, ELBOW].max() > Q_START[ELBOW] + 0.5 and replanner.took_fold    # (the goal's detail)
    line = replanner.plan_goal(Q_START, Q_GOAL, away, 4, trusted=True)
    assert np.allclose(line.positions[:, ELBOW], Q_START[ELBOW]) and line.version == 4 and not replanner.took_fold
    assert replanner.predicted_time(line, 0.0, away) < replanner.predicted_time(folded, 0.0, away)
    # where the cost has the line slower (here made so), the fold stays, trusted or not
    replanner.predicted_time = lambda trajectory, *args, **kwargs: trajectory.duration * (
        2.0 if np.allclose(trajectory.positions[:, ELBOW], Q_START[ELBOW]) else 1.0)
    kept = replanner.plan_goal(Q_START, Q_GOAL, away, 5, trusted=True)
    assert kept.positions[:, ELBOW].max() > Q_START[ELBOW] + 0.5 and replanner.searches == 0
    off = Replanner(CM, replanner.planner, SsmParameters(), options=ReplanOptions(trust_tolerance=0.0))
    assert PlanningLoop(off).trust is None and PlanningLoop(replanner).trust is not None
