"""The replanner's options (``shared.planning.replanner``, ``shared.planning.candidates``): one record, so the parts
of the planning layer that build and judge candidates read the same numbers. Those a cell configures (the
``planning`` section) take their defaults from ``shared.planning.parameters.PlanningParameters``."""

from __future__ import annotations

from dataclasses import dataclass

from shared.planning.parameters import JUDGES, PlanningParameters
from shared.planning.path_search import SearchOptions
from shared.planning.time_cost import TimeCostOptions
from shared.scaling.stopping import REST_SPEED


@dataclass(frozen=True)
class ReplanOptions:
    """lookback: nominal seconds of old path kept ahead of the branch point as room to slow down (and
    tried further back when a turn is too sharp); lead: nominal seconds ahead of the current s that the
    junction must stay (the follower moves on while we plan); min_gain: the fraction of predicted time a
    beta replan must save (a blocked horizon needs only to be faster), or min_saving (s) where that is
    less (``required_gain``); rest_speed (rad/s): below it the
    robot counts as at rest for a replan; crawl: below this fraction of its nominal speed a moving robot
    gets a plan from rest a little ahead, where the scaler stops it (``Candidates.stop_plan``), instead of a merge;
    stop_lead (s): the time that stop allows the plan to be delivered in (the robot crawls on meanwhile:
    in hrc demo a plan from rest came 90-180 ms after its request, the worker's 20 ms turn included;
    against 0.15 s, with the crawl predicted by the time cost, 0.2 s kept the paper's 24 s progress, see
    ``Candidates.stop_plan``);
    patience (s): how long people in the way are expected to stay
    before the robot has waited at all; a prediction assumes they stay patience + the time already held
    (0 is pure ski rental: never worse than twice the better choice, however long the person stays; a
    cell where people are known to stay at a station may set more); rrt_budget (s): RRT-Connect's time
    when it has to seed the search; worth_searching (s): a new goal's direct line is taken without a
    search unless the people are predicted to slow it by more than this; worth_waiting (s, None: never): where
    the planning loop leaves at once (``Replanner.plan_goal``, leaving), the robot still waits at the goal for
    its search where the direct line is predicted slower than nominal by more than this, and leaves at once
    below it, the search then run on the way (``Replanner.on_search``); slow_excess (s): the planning layer
    asks itself for a replan (``on_slow``) where the rest of the path followed at speed is predicted to lose more than this
    to the SSM; action_budget (s): wall clock for a whole planning
    action, searches and the rest (None: none; the simulation bounds by counts), see ``shared.planning.budget``; seed: the
    search's seed (each goal gets its own stream, derived from the seed and the goal, so the same query
    gives the same path in any order, see ``Replanner._rng``); search, cost:
    the search's bounds and the time cost's sampling; posture_gap (m): while someone is nearer than this to the
    robot's reach, a new goal's default leg is the folded one (``shared.planning.postures``; None: never; the
    shipped 2.5 m and why: ``PlanningParameters``); still_gap (m): unless everyone stands still farther than this
    from the reach (``PlanningParameters``); trust_tolerance (m), trust_span (s): where the forecast has held that
    well over that long (``shared.planning.trust``), the straight line takes the fold's place where predicted faster
    (0: never); goal_stay (s): a new goal's search, and whether its leg beats the line or the fold, assume the
    people stay at least this long (``Replanner.goal_waited``; 0: patience plus the time held, as every other
    decision);
    judge: what a decision's trajectories are predicted by, "cost" (the time cost's model,
    ``shared.planning.time_cost``) or "scaling" (a forward run of the scaling layer itself against the same
    forecast, ``shared.planning.executed``: slower, for a bound or a cell with the budget for it)."""

    lookback: tuple[float, ...] = (0.3, 0.6, 1.0)
    lead: float = 0.1
    min_gain: float = PlanningParameters.min_gain
    min_saving: float = PlanningParameters.min_saving
    rest_speed: float = REST_SPEED
    crawl: float = 0.25
    stop_lead: float = 0.2
    patience: float = PlanningParameters.patience
    rrt_budget: float = 0.2
    worth_searching: float = 0.25
    worth_waiting: float | None = PlanningParameters.worth_waiting
    trust_tolerance: float = PlanningParameters.trust_tolerance
    trust_span: float = PlanningParameters.trust_span
    goal_stay: float = PlanningParameters.goal_stay
    slow_excess: float = PlanningParameters.slow_excess
    action_budget: float | None = None
    posture_gap: float | None = PlanningParameters.posture_gap
    still_gap: float = PlanningParameters.still_gap
    seed: int = 0
    judge: str = PlanningParameters.judge
    search: SearchOptions = SearchOptions()
    cost: TimeCostOptions = TimeCostOptions()

    def __post_init__(self) -> None:
        if self.judge not in JUDGES:
            raise ValueError(f"ReplanOptions.judge: one of {JUDGES}, not {self.judge!r}")
