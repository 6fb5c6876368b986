"""The planning layer's parameters a cell configures (the ``planning`` section of its configuration): the
numbers of its decisions that an integrator tunes for a cell and a researcher sweeps (``hrc sweep --set
planning.patience=0.5,1.5,3``). Their own module, free of compiled code, so reading a configuration loads
nothing heavy; ``shared.planning.options.ReplanOptions`` takes its defaults from here, so each number is
written once.

patience (s): how long people in the way are expected to stay before the robot has waited at all (a
prediction assumes patience + the time already held). min_gain: the fraction of predicted time a replan must
save, or min_saving (s) where that is less. slow_excess (s): the planning layer asks itself for a replan where
the rest of the path is predicted to lose more than this to the SSM. posture_gap (m): while someone is
nearer than this to the robot's reach, a new goal's default leg is the folded one (``shared.planning.postures``;
None or negative: never). Shipped at 2.5 m (anyone who could reach the robot within a leg): side by side on the
same scenarios it is above the straight line in every walking kind and on the paper's own phases under the
paper's formula, where the folded leg already clears the reaching arm and the paper's phase-3 replan is not
needed (docs/measurements.md). The paper's planner had no posture: ``deploy/cell-paper.yaml`` sets null.
still_gap (m): people who all stand still (every body part slower than ``STANDING_SPEED``) and are farther than
this from the robot's reach make no folded leg: only someone walking comes near within a leg. Shipped at 1.0 m:
on 60 seeds a kind it gained in the paper (a person waiting 2.8 m off in its first phase) and lost nowhere
(docs/measurements.md, 2026-12-03, session 55); at or above posture_gap, standing people fold as walkers do.
judge: what a decision's trajectories are predicted by, "cost" (the time cost's model) or "scaling" (a
forward run of the scaling layer itself, ``shared.planning.executed``). forecast_horizon (s): how far ahead the
planning layer's forecast moves the tracked people on along their velocities, then holds them (the time cost's
``extrapolation``; 0: held where they are now). 2 s shipped: swept from 1 to 6 s, with the patience, it trades
the two-person scenarios against the random walk by about 1 % either way (docs/measurements.md, 2026-12-03).
worth_waiting (s, or null): a new goal's robot waits at the goal for its search only where the people slow the
direct line by more than this; below it, it leaves at once and the search runs on the way (``shared.planning.loop``,
``Replanner.on_search``). null shipped, never waits: since the search on the way is decided as the goal's own
(searched from rest where the leg began), waiting for it gained nothing anywhere; leaving at once gained 0.1-0.8 %
in five kinds of seven on two sets of 48 seeds a kind and changed the standing person's kind by -0.8 % and
+0.4 % (docs/measurements.md, session 63). Before that, 0.5 s: never waiting had lost the paper's phase 4 at 3 s
phases.
trust_tolerance (m), trust_span (s): where the planning layer's forecast has held over the last trust_span
(every snapshot of the people moved on by the forecast lands within trust_tolerance of where they are:
``shared.planning.trust``), a new goal's leg is the straight line instead of the fold where the cost predicts it
faster; elsewhere the fold, which pays wherever people turn out to be. 0: never trusted.
goal_stay (s): at a new goal, the search and whether its leg (or the one prepared on the way) beats the line or
the fold (``Replanner.plan_goal``) assume the people present stay at least this long, not only patience + the
time held (the line against the fold keeps the patience, and so does the goal's search run on the way,
``Replanner.on_search``: with the goal's stay there too the standing person's kind lost 1.8 %): a robot leaving a
goal commits to a whole leg, and someone standing by its way now is there for most of it (every keep-or-replace
on the way keeps the patience: waiting there is ski rental). 6 s shipped: side by
side on two sets of 48 seeds a kind, the paper's kind gained 2.9 % and 3.3 % (30 and 38 better, none worse), the
other kinds within 0.4 %; 3 s gave half that, 10 s and for good the same as 6 (docs/measurements.md, session 74).
0: patience + held only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from shared.core.errors import ConfigError
from shared.core.sections import check_numbers

JUDGES = ("cost", "scaling")


@dataclass(frozen=True)
class PlanningParameters:
    patience: float = 1.5
    min_gain: float = 0.10
    min_saving: float = 0.25
    slow_excess: float = 1.0
    posture_gap: float | None = 2.5
    still_gap: float = 1.0
    judge: str = "cost"
    forecast_horizon: float = 2.0
    worth_waiting: float | None = None
    trust_tolerance: float = 0.08
    trust_span: float = 1.0
    goal_stay: float = 6.0

    def __post_init__(self) -> None:
        check_numbers(self, "planning", skip=("posture_gap", "judge", "worth_waiting"), non_negative=True)
        for key in ("posture_gap", "worth_waiting"):
            value = getattr(self, key)
            if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))
                                      or not math.isfinite(value)):
                raise ConfigError(f"planning.{key}: expected a finite number or null, got {value!r}")
        if self.worth_waiting is not None and self.worth_waiting < 0:
            raise ConfigError(f"planning.worth_waiting: expected a number of seconds >= 0 or null, got "
                              f"{self.worth_waiting!r}")
        if self.judge not in JUDGES:
            raise ConfigError(f"planning.judge: expected one of {JUDGES}, got {self.judge!r}")
        if not self.trust_span > 0:
            raise ConfigError(f"planning.trust_span: expected a positive number of seconds, got {self.trust_span!r}")

    @property
    def folds(self) -> float | None:
        """The posture gap (m) the replanner uses, None for never (a negative gap, as a sweep gives it)."""
        return None if self.posture_gap is None or self.posture_gap < 0 else float(self.posture_gap)

    def replan_fields(self) -> dict:
        """These values as ``ReplanOptions`` fields (``ReplanOptions(**fields)``). The forecast's horizon comes as
        ``cost``, the time cost's default options with that extrapolation, so ``dataclasses.replace`` onto options
        whose cost differs otherwise resets the rest of it (imported here: reading a configuration loads nothing
        compiled)."""
        from shared.planning.time_cost import TimeCostOptions

        return {"patience": float(self.patience), "min_gain": float(self.min_gain),
                "min_saving": float(self.min_saving), "slow_excess": float(self.slow_excess),
                "posture_gap": self.folds, "still_gap": float(self.still_gap), "judge": self.judge,
                "worth_waiting": None if self.worth_waiting is None else float(self.worth_waiting),
                "trust_tolerance": float(self.trust_tolerance),
                "trust_span": float(self.trust_span), "goal_stay": float(self.goal_stay),
                "cost": TimeCostOptions(extrapolation=float(self.forecast_horizon))}
