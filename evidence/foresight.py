"""The bound on prediction: the planning layer told the scripted people's own future.

The planning layer predicts people with a constant-velocity forecast (``shared.planning.forecast``): a
person walking up is predicted to walk on, one who stops to have stopped only once they have. How much
of what the people cost would a perfect prediction of human motion win back? ``Foresight`` answers it in
the simulation: a forecaster whose frames are the script's own future (what the people *will* do), for
the product's own planning layer, unchanged otherwise (the same search, cost, keep-or-replace rule,
planning loop and scaling layer). No tracker can know this; the gap between the full architecture and
the ``foresight`` strategy (``evidence.strategies``, ``bench/compare.py --foresight``) is the most any
better prediction could add, and what is left beyond it is the search's and the rules' (or physics').

``oracle_options`` goes one step further, to a bound on the planning layer itself (the ``oracle`` strategy,
``bench/compare.py --oracle``): foresight, a search ``ORACLE_SEARCH`` times as large, planning free of
time (its plans taken the cycle they are asked for), every predicted gain taken, and a replan of its own
wherever the path ahead is predicted to lose ``ORACLE_SLOW``. What the oracle does not win back, no
better forecast, faster computer or bigger search of this planning layer would: it is the people
simply in the way, under the SSM.
"""

from __future__ import annotations

from collections import deque
from dataclasses import replace

import numpy as np

from shared.core.humans import HumanCapsules
from shared.planning.forecast import PeopleForecast
from shared.planning.replanner import ReplanOptions

FORESIGHT_HORIZON = 6.0    # s: the future the forecast spans (longer than a shuttle leg under any slowdown)
FRAME_STEP = 0.1           # s: at most this between its frames (the scripts move linearly between keyframes)
# s: how long the foreseeing planner's predictions have the people stay. Its forecast already says when they
# leave, so nobody is assumed gone before it ends; after it they stay where it left them.
FORESIGHT_STAY = 1e9
# the oracle's search, this many times the planner's candidates and refinements. On 16 seeds (300-315, 12 s),
# 4x against 8x: two people 63.25 -> 63.41 shuttles, the paper's phases 71.05 -> 71.68: near its ceiling
ORACLE_SEARCH = 8
ORACLE_SLOW = 0.2          # s: the oracle asks itself for a replan where the path ahead loses this much


def foresight_options(options: ReplanOptions = ReplanOptions()) -> ReplanOptions:
    """The planning layer's options for a forecast that knows the future: predictions over its whole
    horizon, nobody assumed gone before the forecast says so."""
    return replace(options, patience=FORESIGHT_STAY, cost=replace(options.cost, extrapolation=FORESIGHT_HORIZON))


def oracle_options(options: ReplanOptions = ReplanOptions(), times: int = ORACLE_SEARCH,
                   judge: str = "cost") -> ReplanOptions:
    """foresight_options with the search `times` (ORACLE_SEARCH) times as large, every predicted gain taken
    (min_gain 0: its predictions are right) and its own replans from ORACLE_SLOW s of predicted loss on; its
    decisions predicted by `judge` ("scaling": the scaling layer's forward run against the known future).
    A bound must not fall as its search grows: bench/bound_search.py runs it at 1x, 2x, 4x, 8x."""
    fore = foresight_options(options)
    search = replace(fore.search, candidates=times * fore.search.candidates,
                     refinements=times * fore.search.refinements)
    return replace(fore, search=search, min_gain=0.0, min_saving=0.0, slow_excess=ORACLE_SLOW, judge=judge)


class Foresight:
    """The people of a script, and a forecaster that knows their future. The simulation reads the people
    through ``at(t)`` (which keeps the clock), the time cost asks ``forecast``: frames of the script from
    the moment of the people it is given. That is the latest ``at`` for the time cost's people, and an
    earlier one for a snapshot the planning layer kept (``shared.planning.trust`` moves each snapshot of the
    last second on to now, to see whether the forecast has held): the people states handed out over the last
    ``REMEMBERED`` seconds are kept with their moments, so such a snapshot's forecast is the script from then,
    and it holds, as a perfect forecast does. (Forecast from now instead, every snapshot would be off and the
    foreseeing planner would never trust its forecast: always the fold, never the line, where a person walks
    steadily; 1 % behind the full strategy in the crossing kind.)"""

    REMEMBERED = 3.0   # s: longer than the trust gate's span (``PlanningParameters.trust_span``)

    def __init__(self, script, step: float = FRAME_STEP) -> None:
        self.script = script
        self.step = step
        if hasattr(script, "captured"):     # a recorded motion's samples: the simulation ages them as the script's
            self.captured = script.captured
        self.now = 0.0
        self._handed: deque[tuple[float, HumanCapsules]] = deque()

    def at(self, t: float) -> HumanCapsules:
        self.now = t
        people = self.script.at(t)
        self._handed.append((t, people))
        while self._handed and self._handed[0][0] < t - self.REMEMBERED:
            self._handed.popleft()
        return people

    def phase(self, t: float) -> str:
        return self.script.phase(t)

    def moment(self, humans: HumanCapsules) -> float:
        """When (s) the script's people were `humans`: the moment ``at`` handed out that very object within the
        last REMEMBERED seconds; else the latest (people the script did not give, e.g. a tracker's)."""
        for t, people in reversed(self._handed):
            if people is humans:
                return t
        return self.now

    def forecast(self, humans: HumanCapsules, horizon: float) -> PeopleForecast:
        if horizon <= 0.0 or humans.count == 0:
            return PeopleForecast.still(humans)
        start = self.moment(humans)
        frames = int(np.ceil(horizon / self.step))        # (the time cost keeps one forecast per snapshot)
        step = horizon / frames
        future = []
        for k in range(frames + 1):
            then = self.script.at(start + horizon * k / frames)
            if then is None or then.count != humans.count:     # a dropout, someone seen or lost: known to there, held
                break
            future.append(then)
        if len(future) < 2:
            return PeopleForecast.still(humans)
        return PeopleForecast(np.stack([f.segments for f in future]), np.stack([f.velocities for f in future]), step)
