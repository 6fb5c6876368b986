"""The planning layer's paths: the seeded search fastest under the SSM (``shared.planning.path_search``), seeded
by the direct line and the winners it remembers to the current goal, and by RRT-Connect
(``shared.planning.ompl_planner``) where no simple detour is free. Each query's random stream comes from the seed
and the goal alone, so the same query gives the same path in any order."""

from __future__ import annotations

import time

import numpy as np

from shared.core.humans import HumanCapsules
from shared.planning.collision import CollisionModel
from shared.planning.ompl_planner import JointPlanner
from shared.planning.options import ReplanOptions
from shared.planning.path_search import PathSearch

REMEMBERED = 4          # searched paths to the current goal kept as seeds of the next searches


class SearchedPaths:
    """searches: path searches run (the simulation charges planning time by them); remembered: the latest
    searches' winners to the current goal (each (K, 6))."""

    def __init__(self, collision: CollisionModel, planner: JointPlanner, search: PathSearch,
                 options: ReplanOptions) -> None:
        self.collision, self.planner, self.search, self.options = collision, planner, search, options
        self.searches = 0
        self.remembered: list[np.ndarray] = []

    def forget(self) -> None:
        """Drop the remembered paths (a new goal, or a new run: the same inputs give the same plans)."""
        self.remembered = []

    def recalled(self, q_from: np.ndarray, q_goal: np.ndarray) -> list[np.ndarray]:
        """Seeds from the remembered paths to this goal: from q_from on to each of their later waypoints,
        then along them. A search has a small budget; one that starts from what the last ones found keeps
        improving while the situation stays, instead of drawing its luck anew at every replan."""
        out = []
        for w in self.remembered:
            if np.allclose(w[-1], q_goal, atol=1e-9):
                out += [np.vstack([q_from, w[i:]]) for i in range(1, len(w) - 1)]
        return out

    def remember(self, waypoints: np.ndarray) -> None:
        """Keep a search's winner (the newest REMEMBERED to its goal, each once)."""
        kept = [w for w in self.remembered if np.allclose(w[-1], waypoints[-1], atol=1e-9)
                and not (w.shape == waypoints.shape and np.array_equal(w, waypoints))]
        self.remembered = kept[-(REMEMBERED - 1):] + [waypoints]

    def rng(self, q_from: np.ndarray, q_goal: np.ndarray) -> np.random.Generator:
        """The search's random stream for a query: from the seed and the goal (to 1 mrad) only, so that
        nearby queries to the same goal get the same candidates, bent the same way from their own start.
        Seeded by both ends (before), a start a milliradian away drew a different set, and a different
        winner: whether the paper's phase 3 was gone round depended on when, to the millisecond, a leg
        ended (9 of 15 runs with the phase period 0.5 % longer or shorter and planning charged 0, 60,
        70, 80 or 90 ms; 15 of 15 now, the 24 s runs' progress 8.18 +- 0.37 shuttles -> 8.57 +- 0.15).
        The same query still gives the same path in any order."""
        goal = np.round(np.asarray(q_goal) * 1000.0).astype(np.int64) + 100_000
        return np.random.default_rng([self.options.seed, *goal.tolist()])

    def path(self, q_from: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None, stay: float,
             from_rest: bool = True) -> np.ndarray:
        """Waypoints (K, 6) of the path the search finds fastest (``paths``' first)."""
        return self.paths(q_from, q_goal, humans, stay, from_rest)[0]

    def paths(self, q_from: np.ndarray, q_goal: np.ndarray, humans: HumanCapsules | None, stay: float,
              from_rest: bool = True, alternatives: int = 0) -> list[np.ndarray]:
        """The waypoints (each (K, 6)) of the path the search finds fastest under the SSM, every segment free of
        the scene and the people (never closer to them than the ends already are), then up to `alternatives`
        runners-up (``PathSearch.search``); RRT-Connect seeds a second search where no simple detour is free
        (raises PlanningError when nothing is found). stay (s): how long the people are assumed to stay."""
        q_from, q_goal = np.asarray(q_from, dtype=float), np.asarray(q_goal, dtype=float)
        direct = np.vstack([q_from, q_goal])
        inflation = self.collision.capped_inflation(0.0, direct, humans)      # < 0 where a person has come closer already
        self.planner.check_ends(q_from, q_goal, humans, inflation)
        rng = self.rng(q_from, q_goal)
        self.searches += 1
        found = self.search.search(q_from, q_goal, humans, rng, stay, (direct, *self.recalled(q_from, q_goal)),
                                   from_rest, inflation, alternatives)
        if found is None:
            budget = self.options.rrt_budget
            if self.search.deadline is not None:           # within the action's budget, but never nothing
                budget = min(budget, max(0.02, self.search.deadline - time.perf_counter()))
            rrt = self.planner.plan(q_from, q_goal, humans, inflation, time_budget=budget)
            self.searches += 1
            found = self.search.search(q_from, q_goal, humans, rng, stay, (rrt,), from_rest, inflation, alternatives)
            if found is None:                               # out of time before reaching it: it is free
                return [rrt]
        if len(found.waypoints) > 2:
            self.remember(found.waypoints)
        return [found.waypoints, *found.others]
