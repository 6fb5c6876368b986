"""The path that is fastest under the SSM: a seeded, bounded search on the SSM-aware time cost.

RRT-Connect (shared.planning.ompl_planner) finds a collision-free path; it does not care whether that path runs
through a person's slowdown, where the scaling layer makes the robot crawl. ``PathSearch`` looks for
the path that *takes the least time* under the scaling layer's bound (``shared.planning.time_cost``):

1. candidates: the seeds it is given (the direct line, an RRT-Connect path); lifts, the shoulder and elbow
   offset over a stretch of the line (over, under or folded past a person's arm); raises, the arm raised
   towards upright over a stretch of it (every link near the base's axis, past a person in the sweep); both
   staged one joint at a time where the SSM forbids their change of posture where the robot stands as one
   motion; escapes, which first move in the joint directions the SSM lets the robot take fastest from where it is
   (away from every person close by), then go on; and random detours, each a few waypoints: the straight line bent by a
   joint offset at one point of it, held over a stretch of it (a plateau: lift, go across, lower), or
   taken at once (move away first, then go). Offsets are drawn with growing radii, so small detours are
   as likely as large ones;
2. every candidate is costed (microseconds per sample, compiled); only candidates that beat the best so
   far are checked for collisions (the collision model's guaranteed motion check against the static
   scene and the people), in order of cost: the cheapest collision-free one wins;
3. the winner is refined: its interior waypoints are perturbed with shrinking steps, and waypoints
   whose removal does not cost time are dropped (shortening by the same cost, not by length).

The result keeps out of a person's slowdown when going round is quicker than crawling past, and goes
close when the way round is longer. The search is bounded by iteration counts (repeatable for a seed:
the simulation's evidence) and, optionally, by a wall-clock budget (the planner service): when time is
up, the best path found so far is returned. Pure apart from the clock.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from shared.core.humans import HumanCapsules
from shared.planning.collision import CollisionModel
from shared.planning.time_cost import SsmTimeCost
from shared.scaling.problem import ssm_alpha_bound

CELL_BUDGET = 0.08   # s of wall clock per search in the planner service (the simulation charges it per search)
ACTION_BUDGET = 0.1  # s of wall clock for a whole planning action in the planner service (searches + the rest)
BENT_WITHIN = 1.5    # a straight winner: the best free bent candidate within this factor of its time is refined
# rad: how far inside the joint ranges a candidate's waypoints stay. A waypoint clipped onto a limit made the
# trajectory touch it, and the driver clamped the commands there (it keeps every setpoint able to stop
# before a limit, and a command on the limit is a hair beyond it in floating point)
LIMIT_MARGIN = 0.01


@dataclass(frozen=True)
class SearchOptions:
    """candidates: random detours costed per search; refinements: perturbations of the winner;
    radii (rad): the scales of the detours' joint offsets; escape_directions: random joint directions
    weighed for leaving the people's slowdown first, escape_best of them tried (``_escapes``); lift_joints,
    lift_offsets, lift_spans: the lifts (``_lifts``); raises: (shoulder, elbow) offsets (rad) that raise the arm
    towards upright (``_raises``); time_budget (s): wall-clock bound (None: bounded by the counts only, the same
    result for the same seed)."""

    candidates: int = 72
    refinements: int = 60
    radii: tuple[float, ...] = (0.25, 0.5, 1.0, 1.5)
    escape_directions: int = 64
    escape_best: int = 4
    lift_joints: tuple[int, int] = (1, 2)
    lift_offsets: tuple[tuple[float, ...], tuple[float, ...]] = ((-0.6, -0.3, 0.3, 0.6), (0.0, 0.4, 0.8, 1.2))
    lift_spans: tuple[tuple[float, float], ...] = ((0.0, 0.5), (0.25, 0.75), (0.5, 1.0))
    raises: tuple[tuple[float, float], ...] = tuple((a, b) for a in (0.0, 0.3, 0.6, 0.9) for b in (-0.6, -0.9, -1.2))
    time_budget: float | None = None


@dataclass(frozen=True)
class SearchResult:
    waypoints: np.ndarray        # (K, 6), q_from first, q_goal last, every segment collision-free
    predicted: float             # its SSM-aware time (s), as SsmTimeCost.path_time
    origin: str                  # its family: 'seed k', 'lift', 'raise', 'staged', 'escape' or 'detour'
    costed: int                  # candidates and refinements costed
    checked: int                 # of them, checked for collisions
    others: tuple[np.ndarray, ...] = ()   # runners-up asked for (``search``'s alternatives): free, bent, by cost


class PathSearch:
    """Seeded search for the fastest collision-free path under the SSM (see the module docstring)."""

    def __init__(self, collision: CollisionModel, cost: SsmTimeCost, options: SearchOptions = SearchOptions()) -> None:
        self.collision = collision
        self.cost = cost
        self.options = options
        self.limits = collision.robot.limits
        self.lower = self.limits.lower + LIMIT_MARGIN      # where candidates' waypoints are clipped to
        self.upper = self.limits.upper - LIMIT_MARGIN
        # perf_counter time by which the current planning action must have its path (None: no action budget);
        # a search stops at the earlier of this and its own time_budget (set by Replanner.begin)
        self.deadline: float | None = None
        self.spent = 0.0                 # s of wall clock searched since the action began
        self.widened = False             # the action's deadline alone bounds a search (``ActionBudget.widen``)

    def free(self, waypoints: np.ndarray, humans: HumanCapsules | None, inflation: float = 0.0) -> bool:
        """Every segment collision-free (static scene and the people, the planner's margin + inflation)."""
        return self.collision.path_free(waypoints, humans, inflation)

    def _detours(self, q_from: np.ndarray, q_goal: np.ndarray, rng: np.random.Generator, count: int) -> list[np.ndarray]:
        """`count` random detours: the straight line with a joint offset (radius cycling through
        options.radii) at one point, over a stretch (a plateau), or taken at once; within the limits."""
        radii = np.asarray(self.options.radii)
        lower, upper = self.lower, self.upper
        out = []
        for k in range(count):
            offset = rng.normal(0.0, 1.0, q_from.size) * radii[k % radii.size] / np.sqrt(q_from.size)
            shape = k % 3
            if shape == 0:                                       # bent at one point
                f = rng.uniform(0.15, 0.85)
                via = [q_from + f * (q_goal - q_from) + offset]
            elif shape == 1:                                     # a plateau over a stretch
                f1, f2 = np.sort(rng.uniform(0.05, 0.95, 2))
                via = [q_from + f * (q_goal - q_from) + offset for f in (f1, f2)]
            else:                                                # away first, then on
                f = rng.uniform(0.0, 0.3)
                via = [q_from + f * (q_goal - q_from) + offset]
            out.append(np.vstack([q_from, np.clip(via, lower, upper), q_goal]))
        return out

    def _lifts(self, q_from: np.ndarray, q_goal: np.ndarray) -> list[np.ndarray]:
        """Detours over or under a person: the straight line with the shoulder and elbow (``lift_joints``)
        offset by every pair of ``lift_offsets`` over a stretch of it (``lift_spans``, fractions of the
        line), which raises, lowers, folds or stretches the arm there. Random 6-joint offsets seldom hit
        these: a person's arm across a sweep is passed over by a few tenths of a radian of exactly these
        two joints, with the wrist left as it is."""
        return self._held_offsets(q_from, q_goal, self._lift_pairs())

    def _lift_pairs(self) -> list[tuple[float, float]]:
        """Every (shoulder, elbow) pair of ``lift_offsets`` (rad)."""
        offsets = self.options.lift_offsets
        return [(a, b) for a in offsets[0] for b in offsets[1]]

    def _raises(self, q_from: np.ndarray, q_goal: np.ndarray) -> list[np.ndarray]:
        """The arm raised towards upright over a stretch of the straight line: the shoulder raised and the elbow
        opened by each pair of ``raises`` (the shuttle's arm, shoulder -0.4 and elbow 1.17 rad, is upright at
        +0.4 and -1.17; the largest pairs take the shoulder up to 0.5 rad past it). Upright, every link is within
        0.13 m of the base's axis, where the shuttle's arm reaches 0.46 m out: a turn of the base hardly moves
        them, and people at the table are 0.3 m farther from them, so the SSM lets the base turn fast where the
        folded arm crawls past a person standing in the sweep. Opening the elbow and raising the shoulder costs
        time with nobody there (the elbow travels as far as the base), so it is a candidate, not a posture taken
        by default."""
        return self._held_offsets(q_from, q_goal, self.options.raises)

    def _held_offsets(self, q_from: np.ndarray, q_goal: np.ndarray,
                      pairs: list[tuple[float, float]] | tuple[tuple[float, float], ...]) -> list[np.ndarray]:
        """The straight line with the shoulder and elbow (``lift_joints``) offset by each (a, b) of `pairs`
        between the fractions of each of ``lift_spans``, within the joint ranges."""
        out = []
        for a, b in pairs:
            offset = self._offset(a, b, q_from.size)
            for span in self.options.lift_spans:
                out.append(np.vstack([q_from, self._held_via(q_from, q_goal, offset, span), q_goal]))
        return out

    def _offset(self, a: float, b: float, size: int) -> np.ndarray:
        """The joint offset (rad) of shoulder a and elbow b (``lift_joints``)."""
        offset = np.zeros(size)
        offset[list(self.options.lift_joints)] = a, b
        return offset

    def _held_via(self, q_from: np.ndarray, q_goal: np.ndarray, offset: np.ndarray,
                  span: tuple[float, float]) -> np.ndarray:
        """The two waypoints (2, 6) of the straight line offset by `offset` at the fractions `span`, within the
        joint ranges."""
        return np.clip([q_from + f * (q_goal - q_from) + offset for f in span], self.lower, self.upper)

    def _staged(self, q_from: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None) -> list[np.ndarray]:
        """The lifts and raises that change posture where the robot stands (their stretch begins at the line's start),
        where the SSM lets no part of that change start as one motion, with the change staged: one joint first (each
        of ``lift_joints`` whose own motion may start), then the other, then on as the lift or raise goes. Why: a
        robot held beside a person (every link inside their protective distance, where the shipped model lets
        nothing approach them) may fold its elbow away from them but not raise its shoulder; folding and raising
        together approaches them, and every candidate that starts with it waits for them to leave, as the old
        trajectory does (``hrc demo --human docs/motions/two_people.json`` on the processes: held for 19 s, every
        plan from rest predicted as slow as the one it would replace), while the fold first, the shoulder next,
        then the turn with the arm folded passes them slowly without waiting."""
        if humans is None or humans.count == 0:
            return []
        speed = self.limits.velocity

        def may_start(change: np.ndarray) -> bool:
            """Whether the SSM lets the straight joint motion along `change` start (at the joints' speed)."""
            moved = change != 0.0
            scale = float(np.min(speed[moved] / np.abs(change[moved])))
            return ssm_alpha_bound(self.collision.robot, q_from, change * scale, humans, self.cost.ssm) > 0.0

        out = []
        for a, b in self._lift_pairs() + list(self.options.raises):
            offset = self._offset(a, b, q_from.size)
            if a == 0.0 or b == 0.0 or may_start(offset):
                continue
            stages = [np.clip(q_from + part, self.lower, self.upper)
                      for part in (self._offset(a, 0.0, q_from.size), self._offset(0.0, b, q_from.size))
                      if may_start(part)]
            for span in self.options.lift_spans:
                if span[0] == 0.0:
                    via = self._held_via(q_from, q_goal, offset, span)
                    out += [np.vstack([q_from, stage, via, q_goal]) for stage in stages]
        return out

    def _escapes(self, q_from: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None,
                 rng: np.random.Generator) -> list[np.ndarray]:
        """Detours that first leave the people's slowdown: of `escape_directions` random joint directions,
        the ones the SSM lets the robot take fastest from q_from (moving away from every person close
        by), each followed for a few step lengths, then on to the goal directly or over a plateau."""
        if humans is None or humans.count == 0 or self.options.escape_directions == 0:
            return []
        directions = rng.normal(0.0, 1.0, (self.options.escape_directions, q_from.size))
        directions /= np.abs(directions).max(axis=1, keepdims=True)
        alpha = np.array([ssm_alpha_bound(self.collision.robot, q_from, d * self.limits.velocity, humans,
                                          self.cost.ssm) for d in directions])
        out = []
        lower, upper = self.lower, self.upper
        for d in directions[np.argsort(-alpha, kind="stable")[:self.options.escape_best]]:
            for step in (0.2, 0.5, 1.0):
                away = np.clip(q_from + step * d, lower, upper)
                out.append(np.vstack([q_from, away, q_goal]))
                out.append(np.vstack([q_from, away, np.clip(q_goal + step * d, lower, upper), q_goal]))
        return out

    def search(self, q_from: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None, rng: np.random.Generator,
               stay: float = np.inf, seeds: tuple[np.ndarray, ...] = (), from_rest: bool = True,
               inflation: float = 0.0, alternatives: int = 0) -> SearchResult | None:
        """The fastest collision-free path found from q_from to q_goal, or None when no candidate is free.
        Seeds are candidates like the others (checked for collisions too). inflation (m, may be negative):
        added to the people's margin (negative for a robot a person has already come closer to). alternatives:
        up to this many runners-up as well (``SearchResult.others``: the next free bent candidates by cost, within
        BENT_WITHIN of the winner), for a caller that times each as it will be driven: the cost walks the
        waypoints with a stop at each corner, and a timing law that smooths them can be slower or faster by
        up to a tenth (docs/measurements.md, session 73)."""
        q_from, q_goal = np.asarray(q_from, dtype=float), np.asarray(q_goal, dtype=float)
        started = time.perf_counter()
        budget = None if self.widened else self.options.time_budget
        stop_at = min(started + budget if budget is not None else np.inf,
                      self.deadline if self.deadline is not None else np.inf)
        try:
            return self._search(q_from, q_goal, humans, rng, stay, seeds, from_rest, inflation, stop_at, alternatives)
        finally:
            self.spent += time.perf_counter() - started

    def _search(self, q_from: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None, rng: np.random.Generator,
                stay: float, seeds: tuple[np.ndarray, ...], from_rest: bool, inflation: float,
                stop_at: float, alternatives: int = 0) -> SearchResult | None:
        """search, stopping at the perf_counter time stop_at (inf: bounded by the counts only)."""
        def out_of_time() -> bool:
            return time.perf_counter() > stop_at

        def cost(w: np.ndarray) -> float:
            return self.cost.path_time(w, humans, stay, from_rest=from_rest)

        # the lifts right after the seeds: where a busy machine's budget stops the costing early, the family
        # that finds the way over a person's arm has been costed
        labelled = [(f"seed {k}", np.asarray(w, dtype=float)) for k, w in enumerate(seeds)]
        labelled += [("lift", w) for w in self._lifts(q_from, q_goal)]
        labelled += [("raise", w) for w in self._raises(q_from, q_goal)]
        labelled += [("staged", w) for w in self._staged(q_from, q_goal, humans)]
        labelled += [("escape", w) for w in self._escapes(q_from, q_goal, humans, rng)]
        labelled += [("detour", w) for w in self._detours(q_from, q_goal, rng, self.options.candidates)]
        costs = []
        for _, w in labelled:
            if costs and out_of_time() and len(costs) > len(seeds):
                break
            costs.append(cost(w))
        checked = 0
        best = bent = None
        order = np.argsort(costs, kind="stable")
        tried: set[int] = set()                 # the candidates checked for collisions here
        for k in order:
            if best is not None and (labelled[k][1].shape[0] <= 2 or costs[k] > BENT_WITHIN * best[1]):
                continue
            checked += 1
            tried.add(int(k))
            if self.free(labelled[k][1], humans, inflation):
                if best is None:
                    best = (labelled[k][1], costs[k], labelled[k][0])
                    if best[0].shape[0] > 2:
                        break
                else:
                    bent = (labelled[k][1], costs[k], labelled[k][0])
                    break
            if out_of_time() and checked > 4:
                break
        if best is None:
            return None
        costed = len(costs)
        waypoints, predicted, origin = best
        if waypoints.shape[0] <= 2 and bent is not None:      # a straight winner has nothing to refine: the
            waypoints, predicted, origin = bent                # best bent candidate is refined instead, and
        waypoints, predicted, refined, refined_checked = self._refine(      # wins if it ends up faster
            waypoints, predicted, q_from, humans, rng, inflation, cost, out_of_time)
        costed, checked = costed + refined, checked + refined_checked
        if predicted >= best[1]:
            waypoints, predicted, origin = best
        others: list[np.ndarray] = []
        if alternatives > 0 and waypoints.shape[0] > 2:
            taken = (best[0], waypoints) if bent is None else (best[0], bent[0], waypoints)
            for k in order:             # the next ones not checked yet, none equal to a winner
                if len(others) >= alternatives or out_of_time() or costs[k] > BENT_WITHIN * predicted:
                    break
                w = labelled[k][1]
                if w.shape[0] <= 2 or int(k) in tried or any(w.shape == t.shape and np.array_equal(w, t) for t in taken):
                    continue
                checked += 1
                if self.free(w, humans, inflation):
                    others.append(w)
        return SearchResult(waypoints, predicted, origin, costed, checked, tuple(others))

    def _refine(self, waypoints: np.ndarray, predicted: float, q_from: np.ndarray, humans: HumanCapsules | None,
                rng: np.random.Generator, inflation: float, cost, out_of_time) -> tuple[np.ndarray, float, int, int]:
        """The waypoints perturbed with shrinking steps, and dropped where that costs no time, as long as
        each change is faster and free: (waypoints, predicted, costed, checked)."""
        costed = checked = 0
        step = max(self.options.radii) / 4
        for k in range(self.options.refinements):
            if out_of_time():
                break
            inner = waypoints.shape[0] - 2
            if inner <= 0:
                break
            trial = waypoints.copy()
            if k % 4 == 3:                                       # drop a waypoint
                trial = np.delete(trial, 1 + int(rng.integers(inner)), axis=0)
            else:
                i = 1 + int(rng.integers(inner))
                trial[i] = np.clip(trial[i] + rng.normal(0.0, step, q_from.size), self.lower, self.upper)
            value = cost(trial)
            costed += 1
            if value < predicted:
                checked += 1
                if self.free(trial, humans, inflation):
                    waypoints, predicted = trial, value
                    continue
            step = max(step * 0.93, 0.02)
        return waypoints, predicted, costed, checked
