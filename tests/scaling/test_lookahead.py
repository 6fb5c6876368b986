"""The stop run ahead (shared.scaling.lookahead): a command is one the robot can still stop from without a link
approaching a person faster than the SSM allows on the way. The case it was made for, replayed: the folded leg of
a random walk (seed 4196) passing a walking person with the flange at full speed, the path turning towards them."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import shared.scaling.layer as layer_module
from evidence.scenarios import Q_GOAL, Q_START, make_scenario
from evidence.sim import CommandJudge, SimResult
from shared.config import CellConfig
from shared.core.humans import HumanCapsules
from shared.planning.collision import CollisionModel
from shared.planning.postures import FoldedLegs
from shared.planning.scene import DEFAULT_SCENE, load_scene
from shared.robot.model import default_robot
from shared.scaling.layer import ScalingInputs, ScalingLayer

# that run's folded leg Q_START -> Q_GOAL began at cycle 879 (8.79 s) and was followed to its end, unreplanned
LEG_FROM, LEG_TO = 879, 1190
# the configuration it was found with: T_r 0.1 s (shipped until session 81; now 0.05 s, the cell's own chain)
FOUND_WITH = CellConfig(ssm=replace(CellConfig().ssm, reaction_time=0.1))


def replay(robot, config):
    """The layer on that leg against the scripted person, from its start; (violations, methods)."""
    leg = FoldedLegs(CollisionModel(robot, load_scene(DEFAULT_SCENE), config.ssm.min_separation)).leg(Q_START, Q_GOAL, 4)
    layer = ScalingLayer(robot, config.ssm, config.scaling)
    layer.set_trajectory(leg)
    person, judge, result, methods = make_scenario("random_walk", 4196, 12.0), CommandJudge(robot, config), SimResult(), []
    for k in range(LEG_FROM, LEG_TO):
        t = k * config.scaling.period              # the simulation's clock, to the last bit (the judge's T_r edge)
        humans = person.at(t)
        step = layer.step(ScalingInputs(humans=humans))
        judge.judge(t, step, humans, result)
        methods.append(step.method)
    return result.violations, methods


@pytest.fixture(scope="module")
def robot():
    return default_robot()


def test_the_robot_slows_before_the_turn_and_the_monitor_counts_no_violation(robot):
    violations, methods = replay(robot, FOUND_WITH)
    assert violations == 0
    assert any("+lookahead" in m for m in methods)
    assert replay(robot, CellConfig())[0] == 0                  # and as shipped


def test_without_the_stop_run_ahead_the_same_pass_is_a_violation(robot, monkeypatch):
    """The case as it was found, with one T_s for every speed (``min_stopping_time = stopping_time``): with T_s
    following the robot's speed the layer takes this pass more slowly, and it is no violation without the stop run
    ahead either; the mechanism is what is tested here, on the model it was made for."""
    monkeypatch.setattr(layer_module, "LOOKAHEAD_LIMIT", -np.inf)
    fixed_stop = CellConfig(ssm=replace(FOUND_WITH.ssm, min_stopping_time=FOUND_WITH.ssm.stopping_time))
    violations, methods = replay(robot, fixed_stop)
    assert violations >= 1 and not any("+lookahead" in m for m in methods)
    monkeypatch.setattr(layer_module, "LOOKAHEAD_LIMIT", np.inf)
    assert replay(robot, fixed_stop)[0] == 0


def test_with_nobody_near_the_stop_lowers_nothing(robot):
    config = CellConfig()
    leg = FoldedLegs(CollisionModel(robot, load_scene(DEFAULT_SCENE), config.ssm.min_separation)).leg(Q_START, Q_GOAL, 0)
    layer = ScalingLayer(robot, config.ssm, config.scaling)
    layer.set_trajectory(leg, 1.3)
    layer.sdot = 1.0
    far = HumanCapsules(np.array([[[4.0, 4.0, 0.0], [4.0, 4.0, 1.7]]]), np.array([0.2]), np.zeros((1, 2, 3)),
                        np.array([True]))
    assert layer._stop_checked(leg, 1.0, far, np.zeros(6)) == (1.0, False)
    assert layer._stop_checked(leg, 0.0, far, np.zeros(6)) == (0.0, False)
