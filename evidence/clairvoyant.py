"""A clairvoyant bound that runs the real scaling layer, and rises with its own search (issue 38, item 7).

The oracle (``evidence.foresight``) is the planning layer told the people's future, and it ranks its
candidates by a prediction: `bench/bound_search.py` shows it falling as its search grows, so it is no bound.
This one ranks by what happens. Its policies are sequences of fixed leg shapes, one shape per leg of the
shuttle (``SHAPES``: the straight line, the fold of ``shared.planning.postures`` and variations of it, other
joints offset, the arm raised towards upright, a hold at the leg's start). Each sequence is judged by running
the whole scenario with it: the product's own scaling layer, with the same people and the same judge
(``evidence.sim.run_shuttle``). The scripted people are deterministic, so every run knows their future exactly.

The search (``best_sequence``, pure):
1. Every sequence of one shape throughout. So the bound is never below the straight shuttle (scale_only) or
   the fixed fold (fixed_path) on the same scenario.
2. Then each leg in turn: each other shape for that leg, the rest unchanged, kept where the run makes more
   shuttles (coordinate ascent).
3. A larger search starts from the smaller one's best and holds a superset of its shapes. It keeps a
   change only where a change does better, so it can never end lower. The bound rises with its search by
   construction, at 2, 4, 8, 16 and 20 shapes (``SEARCHES``; the last four the arm raised towards upright, the
   path search's raises, added when the planning layer got them).

What it is: the most a planner that picks one of these shapes per leg reaches with perfect knowledge of the
people, found by search (a lower estimate of that optimum, not an upper bound on every planner). A planner
that also bends mid-leg can do more. What it answers is whether the shapes the planning layer can choose
from hold the room the issue's goals ask for, and how much of that room the planning layer uses
(``bench/compare.py --clairvoyant``, ``bench/bound_search.py --bound clairvoyant``).

It costs about a hundred runs per scenario at 16 shapes, so it is a benchmark's column, not a strategy a
sweep of a thousand scenarios runs by default.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from shared.core.trajectory import Trajectory, straight_line_trajectory
from shared.planning.collision import CollisionModel
from shared.planning.postures import ELBOW, FOLD, FOLD_SPAN, FoldedLegs
from shared.planning.timing import TimingError

SHOULDER, BASE = 1, 0       # joint indices (0-based): the PRBT's shoulder and base
RAISED = (0.3, -1.2)        # rad, shoulder and elbow: the arm near upright (the path search's raises, its largest)
LEGS = 24                   # legs a sequence names (12 s make at most about 8); later legs repeat the last


@dataclass(frozen=True)
class LegShape:
    """One way to drive a leg: the straight line with `joint` (or a tuple of joints) offset by `offset` (rad; a
    tuple, one per joint) between the fractions `span` of the way (``folded_waypoints``; offset 0: the straight
    line, the exact trapezoid), after holding `wait` seconds at the start."""

    name: str
    offset: float | tuple[float, ...] = 0.0
    joint: int | tuple[int, ...] = ELBOW
    span: tuple[float, float] = FOLD_SPAN
    wait: float = 0.0


# In the order the search takes them: a search of n shapes uses the first n, so each holds the smaller ones.
SHAPES: tuple[LegShape, ...] = (
    LegShape("straight"),
    LegShape("fold", FOLD),
    LegShape("elbow +0.5", 0.5),
    LegShape("fold 25-75 %", FOLD, span=(0.25, 0.75)),
    LegShape("shoulder -0.3", -0.3, SHOULDER),
    LegShape("shoulder +0.3", 0.3, SHOULDER),
    LegShape("fold early", FOLD, span=(0.15, 0.45)),
    LegShape("fold late", FOLD, span=(0.55, 0.85)),
    LegShape("straight, hold 0.25 s", wait=0.25),
    LegShape("fold, hold 0.25 s", FOLD, wait=0.25),
    LegShape("straight, hold 0.5 s", wait=0.5),
    LegShape("fold, hold 0.5 s", FOLD, wait=0.5),
    LegShape("elbow +0.65", 0.65),
    LegShape("elbow -0.4", -0.4),
    LegShape("base +0.3", 0.3, BASE),
    LegShape("base -0.3", -0.3, BASE),
    LegShape("raised", RAISED, (SHOULDER, ELBOW)),
    LegShape("raised 25-75 %", RAISED, (SHOULDER, ELBOW), span=(0.25, 0.75)),
    LegShape("half raised", (0.3, -0.6), (SHOULDER, ELBOW)),
    LegShape("raised 20-80 %", RAISED, (SHOULDER, ELBOW), span=(0.2, 0.8)),
)
SEARCHES = (2, 4, 8, 16, 20)    # the nested searches (numbers of shapes) a benchmark runs
BETTER = 1e-6               # shuttles: a change must gain more than this to be kept


def held(trajectory: Trajectory, wait: float) -> Trajectory:
    """The trajectory after holding its (rest) start for `wait` seconds: one more knot at 0, the same start
    at rest, so the Hermite spline stands still until `wait`."""
    if wait <= 0.0:
        return trajectory
    return Trajectory(np.concatenate([[0.0], trajectory.times + wait]),
                      np.vstack([trajectory.positions[:1], trajectory.positions]),
                      np.vstack([np.zeros_like(trajectory.velocities[:1]), trajectory.velocities]),
                      trajectory.version)


class ShapedLegs:
    """The legs of each shape between two ends: a folded shape's timed once by the planning layer's own
    ``FoldedLegs`` (TOPP-RA through its waypoints, checked free of the static scene), the straight line the exact
    trapezoid, either after its hold (``held``)."""

    def __init__(self, collision: CollisionModel, shapes: Sequence[LegShape] = SHAPES) -> None:
        self.collision, self.shapes = collision, tuple(shapes)
        self._folds = {k: FoldedLegs(collision, shape.offset, shape.span, shape.joint)
                       for k, shape in enumerate(self.shapes) if np.any(np.asarray(shape.offset) != 0.0)}

    def leg(self, shape: int, start: np.ndarray, goal: np.ndarray, version: int) -> Trajectory:
        """Shape number `shape`'s leg from start to goal, numbered `version` (TimingError where it cannot be
        timed)."""
        if shape in self._folds:
            leg = self._folds[shape].leg(start, goal, version)
        else:
            limits = self.collision.robot.limits
            leg = straight_line_trajectory(start, goal, limits.velocity, limits.acceleration, version=version)
        return held(leg, self.shapes[shape].wait)

    def usable(self, shape: int, ends: Sequence[np.ndarray]) -> bool:
        """Whether the shape's legs can be timed both ways between the two ends."""
        try:
            self.leg(shape, ends[0], ends[1], 0)
            self.leg(shape, ends[1], ends[0], 0)
        except TimingError:
            return False
        return True


class LegSequence:
    """``run_shuttle``'s ``leg_path`` for one sequence: leg n gets shape ``shapes[n]`` (the last one beyond
    the sequence); ``begun`` counts the legs handed out."""

    def __init__(self, legs: ShapedLegs, shapes: Sequence[int]) -> None:
        self.legs, self.shapes, self.begun = legs, tuple(shapes), 0

    def __call__(self, start: np.ndarray, goal: np.ndarray, version: int) -> Trajectory:
        shape = self.shapes[min(self.begun, len(self.shapes) - 1)]
        self.begun += 1
        return self.legs.leg(shape, start, goal, version)


@dataclass(frozen=True)
class Choice:
    """The best sequence a search found: a shape per leg, the shuttles its run made, and the legs that run
    began (only those matter)."""

    shapes: tuple[int, ...]
    shuttles: float
    legs: int


def best_sequence(evaluate: Callable[[tuple[int, ...]], tuple[float, int]], candidates: Sequence[int],
                  start: Choice | None = None, legs: int = LEGS) -> Choice:
    """The best sequence of leg shapes from `candidates` found by the module's search. evaluate(shapes) ->
    (shuttles, legs begun) runs a sequence (``legs`` long). start: a smaller search's result to start from;
    the result is never below it, nor below any constant sequence of the candidates. Pure given evaluate."""
    if not candidates:
        raise ValueError("no candidate shapes")
    best = start
    for shape in candidates:                        # one shape throughout
        shapes = (shape,) * legs
        if start is not None and shapes == start.shapes:
            continue
        shuttles, begun = evaluate(shapes)
        if best is None or shuttles > best.shuttles + BETTER:
            best = Choice(shapes, shuttles, begun)
    assert best is not None
    leg = 0
    while leg < min(best.legs, legs):               # the legs the best run begins (it may begin more as it gets faster)
        for shape in candidates:
            if shape == best.shapes[leg]:
                continue
            shapes = best.shapes[:leg] + (shape,) + best.shapes[leg + 1:]
            shuttles, begun = evaluate(shapes)
            if shuttles > best.shuttles + BETTER:
                best = Choice(shapes, shuttles, begun)
        leg += 1
    return best


def nested_searches(evaluate: Callable[[tuple[int, ...]], tuple[float, int]], usable: Sequence[int],
                    sizes: Sequence[int] = SEARCHES, legs: int = LEGS) -> dict[int, Choice]:
    """The search at each size (the first `size` shapes that are usable), each starting from the one before:
    {size: Choice}, non-decreasing in shuttles by construction."""
    out: dict[int, Choice] = {}
    previous: Choice | None = None
    for size in sorted(sizes):
        candidates = [s for s in usable if s < size]
        previous = best_sequence(evaluate, candidates, previous, legs)
        out[size] = previous
    return out


class EpisodeRuns:
    """``best_sequence``'s evaluate for one scenario: run(leg_path) -> SimResult runs the whole scenario with a
    ``LegSequence`` as its legs; each sequence is run once (``runs`` counts the runs made)."""

    def __init__(self, run: Callable[[LegSequence], object], legs: ShapedLegs) -> None:
        self.run, self.legs = run, legs
        self.runs = 0
        self._seen: dict[tuple[int, ...], tuple[float, int]] = {}

    def __call__(self, shapes: tuple[int, ...]) -> tuple[float, int]:
        return self._run(shapes)[:2]

    def ends(self, shapes: tuple[int, ...]) -> list[float]:
        """When (s) each leg of the sequence's run ended (``SimResult.leg_ends``)."""
        return self._run(shapes)[2]

    def _run(self, shapes: tuple[int, ...]) -> tuple[float, int, list[float]]:
        if shapes not in self._seen:
            sequence = LegSequence(self.legs, shapes)
            result = self.run(sequence)
            self.runs += 1
            self._seen[shapes] = (float(result.progress), sequence.begun, result.leg_ends())
        return self._seen[shapes]


def greedy_sequence(runs: EpisodeRuns, candidates: Sequence[int], legs: int = LEGS) -> Choice:
    """The clairvoyant chooser that looks one leg ahead: leg by leg, the shape of `candidates` whose leg ends first
    in the run (the people's future known; ties: the more shuttles), the later legs the first candidate, never
    revised. runs(shapes) -> (shuttles, legs begun) and runs.ends(shapes) -> each leg's end (s): an
    ``EpisodeRuns``, or anything with those two calls. What it answers beside the bound's search of whole
    sequences: whether the bound's room needs looking further than the leg being driven (bench/bound_search.py
    --greedy). Pure given runs."""
    if not candidates:
        raise ValueError("no candidate shapes")
    chosen: list[int] = []
    for leg in range(legs):
        best = None
        for shape in candidates:
            shapes = tuple(chosen) + (shape,) + (candidates[0],) * (legs - leg - 1)
            ends = runs.ends(shapes)
            key = (ends[leg] if len(ends) > leg else np.inf, -runs(shapes)[0])
            if best is None or key < best[0]:
                best = (key, shape)
        chosen.append(best[1])
        if not np.isfinite(best[0][0]):          # this leg does not end within the run: the rest does not matter
            break
    shapes = tuple(chosen) + (candidates[0],) * (legs - len(chosen))
    shuttles, begun = runs(shapes)
    return Choice(shapes, shuttles, begun)
