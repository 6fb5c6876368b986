"""Keep or replace: what a replan produces, why it may be refused, and how long the robot has been held.

Both the old trajectory and the new one are predicted by the same SSM-aware time cost, from the same
moment, with the same people assumed to stay for ``patience`` plus the time the robot has already been
held (``HoldClock``; ski rental: once waiting has cost what the way round costs extra, go round). The new
one is kept only when predicted faster (a beta replan by ``min_gain``); the reason, with both predicted
times, travels as the result's detail or as ``ReplanFailed``'s message (the planner's event). The rule
itself is ``keep_or_replace``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from shared.core.errors import HrcError
from shared.core.trajectory import Trajectory


@dataclass(frozen=True)
class ReplanResult:
    trajectory: Trajectory
    junction: float       # s where the new trajectory starts to differ from the old one
    reason: str           # 'horizon', 'beta', 'slow', 'search' (a goal's search on the way) or 'goal'
    plan_s: float         # wall time spent (s)
    predicted: float = float("nan")   # its predicted time to the goal under the SSM (s)
    baseline: float = float("nan")    # the old trajectory's, predicted the same way (s)
    detail: str = ""
    from_rest: bool = False   # True: a new trajectory from the robot's configuration at rest (junction =
    # the s it was planned at); take it only while the robot is still there, with path speed 0


class ReplanFailed(HrcError):
    """No acceptable new trajectory; the old one stays (and the scaling layer keeps the robot safe)."""


class HoldClock:
    """How long the scaling layer has been asking for a replan (beta raised without a break), in s: the
    `waited` of a prediction (Replanner.predicted_time). Pure; fed the beta flag of each status."""

    def __init__(self) -> None:
        self.since: float | None = None

    def update(self, now: float, beta: bool) -> None:
        if not beta:
            self.since = None
        elif self.since is None:
            self.since = now

    def waited(self, now: float) -> float:
        return 0.0 if self.since is None else max(0.0, now - self.since)


def required_gain(baseline: float, min_gain: float, min_saving: float) -> float:
    """The fraction of the old trajectory's predicted time (baseline, s) a new one must save to be kept:
    min_gain, or less where min_saving seconds are a smaller fraction. As a hold grows, both predictions
    grow with it, and a fixed saving becomes an ever smaller fraction of them: 0.27 s saved on a 3.37 s
    wait is worth a replan although it is only 8 %."""
    return min(min_gain, min_saving / max(baseline, 1e-9))


def keep_or_replace(result: ReplanResult, baseline: float, gain: float, started: float, what: str) -> ReplanResult:
    """Keep the new trajectory when its prediction beats the old one's (baseline, s) by the fraction
    `gain`, else ReplanFailed; either way the reason carries both predicted times. started: the
    perf_counter time the replan began (the result's plan_s)."""
    how = "from rest" if result.from_rest else f"merged at s={result.junction:.2f}"
    how += f", {result.detail}" if result.detail else ""
    if result.predicted <= (1.0 - gain) * baseline:
        return ReplanResult(result.trajectory, result.junction, result.reason, time.perf_counter() - started,
                            result.predicted, baseline, f"{what}, {how}: predicted {result.predicted:.2f} s "
                            f"instead of {baseline:.2f} s", result.from_rest)
    need = f"{100 * gain:.0f} % faster than" if gain > 0 else "faster than"
    raise ReplanFailed(f"{what}, kept the old trajectory: the new one ({how}) predicted "
                       f"{result.predicted:.2f} s, not {need} the old {baseline:.2f} s")
