"""The wall clock of one planning action (``PlanningLoop`` brackets each with ``begin`` / ``end``): its path
searches stop in time for the rest of the action (the timing, the merge, the predictions) to end within the
budget, the rest's duration learnt from the actions before. Anytime: when time is up the best path found so
far is used. None: no budget (the simulation bounds searches by counts, for repeatable evidence)."""

from __future__ import annotations

import time

from shared.planning.path_search import PathSearch

FINISHING_EASE = 0.1    # how far a planning action's learnt finishing time falls towards a shorter one (end)
# the most of an action's budget the learnt finishing time keeps from its searches: one rest stretched by a
# preemption on a busy machine would otherwise leave the next actions' searches no time at all
FINISHING_MOST = 0.5


class ActionBudget:
    """budget: seconds for a whole planning action (None: none); search: the path search whose deadline it sets.
    finishing: the recent wall time (s) of an action's work besides its searches."""

    def __init__(self, search: PathSearch, budget: float | None) -> None:
        self.search, self.budget = search, budget
        self.finishing = 0.02
        self._began: float | None = None
        self._allowed = budget             # s this action may take (``widen``: more than budget)

    def begin(self) -> None:
        """One planning action starts (the planning loop calls it): with an action_budget, its searches stop
        in time for the rest of the action (the timing, the merge, the predictions: ``finishing``, their
        recent wall time) to end within the budget. Anytime: when time is up the best path found so far is
        used. On a loaded machine the rest takes longer, and the searches get less of the budget: the plan
        still comes when the budget says, not a preemption later. No-op without an action_budget."""
        self.search.spent = 0.0
        self.search.widened = False
        self._allowed = self.budget
        if self.budget is None:
            self.search.deadline = self._began = None
            return
        self._began = time.perf_counter()
        self.search.deadline = self._began + self.budget - self.finishing

    def widen(self, seconds: float) -> None:
        """This action may take `seconds` from its start, its searches too, past their own time_budget: for an action
        nothing waits on, the next leg's plan prepared while the robot is still on its way (``PlanningLoop``). Within
        the cell's 80 ms a search of the people at a table's edge costed 146 of the 241 candidates it costs
        unbounded (125 ms on this 2-core VM, idle), and the prepared leg was more often the fold than the simulation's,
        which charges every search the cell's 80 ms whatever it costed. No-op without an action budget (the
        simulation's searches are bounded by their counts)."""
        if self._began is None:
            return
        self._allowed = max(seconds, self.budget)
        self.search.deadline = self._began + self._allowed - self.finishing
        self.search.widened = True

    def end(self) -> None:
        """The action is done: learn how long its work besides the searches took, over the actions that
        searched: up at once to a longer one, down by a tenth of the gap after a shorter one. The rest of
        a refused replan is short, of a taken one the new trajectory's time laws and collision checks; an
        average of both would let the searches of the next taken plan run into that time and past the
        budget (docs/measurements.md). At most FINISHING_MOST of the budget."""
        if self._began is not None and self.search.spent > 0.0:
            rest = min(max(0.0, time.perf_counter() - self._began - self.search.spent),
                       FINISHING_MOST * self.budget)
            self.finishing = rest if rest > self.finishing else self.finishing + FINISHING_EASE * (rest - self.finishing)
        self.search.deadline = self._began = None
        self.search.widened = False
        self._allowed = self.budget

    def out_of_time(self) -> bool:
        """The planning action's budget is spent (never without an action budget: the simulation)."""
        return self._began is not None and time.perf_counter() > self._began + self._allowed
