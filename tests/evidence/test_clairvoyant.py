"""The clairvoyant bound (evidence.clairvoyant): its search keeps only what does better, so it never ends below
a constant shape or a smaller search; its held legs stand still; on a real scenario it runs the scaling layer
safely, is at least scale_only and fixed_path, and replays to what it reports."""

from __future__ import annotations

import numpy as np
import pytest

from evidence.clairvoyant import (
    SHAPES,
    Choice,
    EpisodeRuns,
    LegSequence,
    best_sequence,
    greedy_sequence,
    held,
    nested_searches,
)
from evidence.scenarios import make_scenario
from evidence.strategies import Strategies
from shared.config import CellConfig
from shared.core.trajectory import straight_line_trajectory

LEGS = 6


def separable(values: np.ndarray):
    """An evaluate whose shuttles are each leg's value for its shape, summed: the best sequence is known."""
    def evaluate(shapes: tuple[int, ...]) -> tuple[float, int]:
        return float(sum(values[leg, shape] for leg, shape in enumerate(shapes[:LEGS]))), LEGS
    return evaluate


def entangled(seed: int):
    """An evaluate where every sequence's worth is arbitrary (a hash of it): no structure the search could lean on."""
    def evaluate(shapes: tuple[int, ...]) -> tuple[float, int]:
        rng = np.random.default_rng([seed, *shapes[:LEGS]])
        return float(rng.uniform(0.0, 3.0)), LEGS
    return evaluate


def test_on_separable_legs_the_search_finds_each_legs_best_shape():
    values = np.random.default_rng(0).uniform(0.0, 1.0, size=(LEGS, 5))
    best = best_sequence(separable(values), range(5), legs=LEGS)
    assert best.shapes == tuple(int(k) for k in values.argmax(axis=1))
    assert best.shuttles == pytest.approx(values.max(axis=1).sum())


@pytest.mark.parametrize("seed", range(6))
def test_a_larger_search_never_ends_lower_and_never_below_a_constant_shape(seed):
    evaluate = entangled(seed)
    found = nested_searches(evaluate, range(8), sizes=(2, 4, 8), legs=LEGS)
    assert found[2].shuttles <= found[4].shuttles <= found[8].shuttles
    for size, choice in found.items():
        constants = max(evaluate((k,) * LEGS)[0] for k in range(size))
        assert choice.shuttles >= constants
        assert evaluate(choice.shapes)[0] == choice.shuttles      # what it reports is what its sequence does


def test_a_search_started_from_a_better_choice_keeps_it():
    evaluate = entangled(1)
    start = Choice((0,) * LEGS, 10.0, LEGS)        # better than anything the evaluate gives
    assert best_sequence(evaluate, range(4), start, legs=LEGS) == start
    with pytest.raises(ValueError):
        best_sequence(evaluate, [], legs=LEGS)


def test_a_held_leg_stands_at_its_start_and_then_drives_the_same_leg():
    from shared.robot.model import default_robot

    limits = default_robot().limits
    leg = straight_line_trajectory(np.zeros(6), np.full(6, 0.5), limits.velocity, limits.acceleration)
    hold = held(leg, 0.25)
    assert hold.duration == pytest.approx(leg.duration + 0.25)
    q, dq, _ = hold.sample(np.linspace(0.0, 0.25, 11))
    assert np.allclose(q, leg.positions[0]) and np.allclose(dq, 0.0)
    s = np.linspace(0.0, leg.duration, 37)
    assert np.allclose(hold.sample(s + 0.25)[0], leg.sample(s)[0])
    assert held(leg, 0.0) is leg


@pytest.fixture(scope="module")
def strategies():
    return Strategies(CellConfig())


def test_on_two_people_the_bound_runs_safe_beats_both_fixed_paths_and_replays(strategies):
    kind, seed, duration = "two_humans", 301, 8.0
    choices, runs = strategies.clairvoyant(kind, seed, duration, sizes=(2, 4))
    straight = strategies.run("scale_only", kind, seed, duration).progress
    folded = strategies.run("fixed_path", kind, seed, duration).progress
    assert choices[2].shuttles >= max(straight, folded) - 1e-9      # both are constant sequences of the first two
    assert choices[4].shuttles >= choices[2].shuttles
    assert runs >= 4
    replay = strategies.shaped_run(make_scenario(kind, seed, duration), duration,
                                    LegSequence(strategies.shaped, choices[4].shapes))
    assert replay.progress == pytest.approx(choices[4].shuttles)
    assert replay.violations == 0
    assert all(0 <= k < len(SHAPES) for k in choices[4].shapes)


def test_episode_runs_run_each_sequence_once():
    made = []

    class Result:
        progress = 1.5

        def leg_ends(self):
            return [2.0]

    def run(legs):
        made.append(legs.shapes)
        legs.begun = 3
        return Result()

    runs = EpisodeRuns(run, legs=None)
    assert runs((0, 1)) == (1.5, 3) and runs((0, 1)) == (1.5, 3) and runs.ends((0, 1)) == [2.0]
    assert runs.runs == 1 and made == [(0, 1)]


class TimedLegs:
    """``EpisodeRuns`` for a run of `duration` s whose leg n takes durations[n, shape] s, whatever came before:
    a known best per leg."""

    def __init__(self, durations: np.ndarray, duration: float) -> None:
        self.durations, self.duration = durations, duration

    def ends(self, shapes: tuple[int, ...]) -> list[float]:
        ends = np.cumsum([self.durations[n, k] for n, k in enumerate(shapes[:len(self.durations)])])
        return [float(t) for t in ends if t <= self.duration]

    def __call__(self, shapes: tuple[int, ...]) -> tuple[float, int]:
        ends = self.ends(shapes)
        begun = min(len(ends) + 1, len(self.durations))
        part = (self.duration - (ends[-1] if ends else 0.0)) / self.durations[len(ends), shapes[len(ends)]] \
            if len(ends) < len(self.durations) else 0.0
        return len(ends) + part, begun


def test_the_greedy_chooser_takes_each_legs_quickest_shape_and_stops_at_the_leg_the_run_does_not_end():
    durations = np.random.default_rng(2).uniform(1.0, 3.0, size=(LEGS, 4))
    legs = TimedLegs(durations, duration=7.0)
    chosen = greedy_sequence(legs, range(4), legs=LEGS)
    quickest = durations.argmin(axis=1)
    ended = len(legs.ends(chosen.shapes))
    assert ended >= 1 and chosen.shapes[:ended] == tuple(int(k) for k in quickest[:ended])
    assert chosen.shuttles == pytest.approx(legs(chosen.shapes)[0])
    assert chosen.shuttles >= max(legs((k,) * LEGS)[0] for k in range(4)) - 1e-9     # never below a constant shape


def test_on_two_people_the_greedy_chooser_runs_safe_and_replays(strategies):
    kind, seed, duration = "two_humans", 301, 8.0
    human = make_scenario(kind, seed, duration)
    runs = EpisodeRuns(lambda legs: strategies.shaped_run(human, duration, legs), strategies.shaped)
    chosen = greedy_sequence(runs, [0, 1])
    replay = strategies.shaped_run(human, duration, LegSequence(strategies.shaped, chosen.shapes))
    assert replay.progress == pytest.approx(chosen.shuttles) and replay.violations == 0
    ends = replay.leg_ends()
    assert len(ends) == replay.shuttles and ends == sorted(ends) and ends[-1] <= duration
    for leg, end in enumerate(ends):            # each leg's shape was the one of the two that ended it first
        other = chosen.shapes[:leg] + (1 - chosen.shapes[leg],) + (0,) * (len(chosen.shapes) - leg - 1)
        theirs = runs.ends(other)
        assert len(theirs) <= leg or theirs[leg] >= end - 1e-9


def test_a_raised_shape_offsets_the_shoulder_and_the_elbow_together_and_is_timed_both_ways():
    """A shape of several joints (the arm raised towards upright): the leg passes, at both ends of its span, the
    straight line with the shoulder and the elbow offset by the shape's two offsets, within the joint ranges, and
    the bound can use it (timed both ways between the shuttle's ends)."""
    from evidence.clairvoyant import RAISED, ShapedLegs
    from evidence.scenarios import Q_GOAL, Q_START
    from shared.planning.collision import CollisionModel
    from shared.planning.postures import folded_waypoints
    from shared.planning.scene import Scene
    from shared.robot.model import default_robot

    robot = default_robot()
    legs = ShapedLegs(CollisionModel(robot, Scene(floor_z=0.0), 0.05))
    raised = next(k for k, shape in enumerate(SHAPES) if shape.name == "raised")
    assert SHAPES[raised].joint == (1, 2) and SHAPES[raised].offset == RAISED
    assert legs.usable(raised, (Q_START, Q_GOAL))
    waypoints = folded_waypoints(Q_START, Q_GOAL, robot.limits, RAISED, SHAPES[raised].span, (1, 2))
    for via, f in zip(waypoints[1:3], SHAPES[raised].span):
        line = Q_START + f * (Q_GOAL - Q_START)
        assert np.allclose(via - line, [0.0, RAISED[0], RAISED[1], 0.0, 0.0, 0.0])
    leg = legs.leg(raised, Q_START, Q_GOAL, 3)
    assert leg.version == 3 and np.allclose(leg.positions[[0, -1]], [Q_START, Q_GOAL])
    assert leg.positions[:, 2].min() < Q_START[2] + RAISED[1] + 0.05        # the elbow opened on the way
