"""The planning loop (the cadence both the planner service and the simulation run), and the planner
service in-process on a fake shell: the same loop behind Zenoh."""

from __future__ import annotations

import dataclasses
import time
from types import SimpleNamespace

import numpy as np
import pytest

from evidence.scenarios import Q_GOAL, Q_START, body_segments
from services.planner import POLL, TAKE_WAIT, PlannerService, unique_version
from shared.core.humans import HumanCapsules
from shared.core.trajectory import straight_line_trajectory
from shared.planning.collision import CollisionModel
from shared.planning.decision import ReplanFailed, ReplanResult, keep_or_replace, required_gain
from shared.planning.forecast import ConstantVelocity
from shared.planning.horizon import reach_gap
from shared.planning.inputs import AT_GOAL_WITHIN, goal_dropped, planning_inputs
from shared.planning.loop import APPROACH_SPEED, IDLE_LONGEST, PlanningInputs, PlanningLoop, idle_time, warm_up
from shared.planning.ompl_planner import JointPlanner, PlannerOptions, PlanningError
from shared.planning.path_search import SearchOptions
from shared.planning.presence import DWELL_RADIUS, StillClock
from shared.planning.replanner import PreparedPlan, Replanner, ReplanOptions
from shared.planning.scene import DEFAULT_SCENE, load_scene
from shared.robot.model import default_robot
from shared.safety.parameters import SsmParameters
from shared.scaling.report import ScalerReport
from shared.wire.convert import humans_to_msg
from shared.wire.messages import Goal, JointState, SafetyEvent, ScalerStatus, TrajectoryMsg
from tests.fake_shell import FakeShell

# The paper's formula (the measured human speed held): these tests hold the layers' logic on the paper's
# numbers; the shipped human model's own figures are tests/safety/test_ssm.py's and the cell's.
PAPER_SSM = SsmParameters().paper_formula()

ROBOT = default_robot()
LIM = ROBOT.limits
OLD = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration, version=3)
COLLISION = CollisionModel(ROBOT, load_scene(DEFAULT_SCENE))


class RecordingReplanner:
    """Answers every call at once and records it: the loop's cadence is what is under test here."""

    def __init__(self, horizon=None, beta_fails: bool = False, horizon_fails: bool = False, slow=None,
                 slow_fails: bool = False, defers: bool = False, folds: bool = False) -> None:
        """defers: a goal's search is left for the way (``Replanner.search_deferred``) where plan_goal is told the
        robot is leaving. folds: a goal's leg is the folded one (``Replanner.took_fold``)."""
        self.calls: list[str] = []
        self.defers, self.search_deferred, self.folds = defers, False, folds
        self.leaving: list[bool] = []        # plan_goal's leaving argument, call by call
        self.options = ReplanOptions()
        # whose record the loop keeps (ForecastTrust), and whose SSM the loop asks whether a goal is blocked
        self.cost = SimpleNamespace(forecaster=ConstantVelocity(), ssm=PAPER_SSM)
        self.searches = 0
        self.forgotten = 0
        self.horizon, self.beta_fails, self.horizon_fails = horizon, beta_fails, horizon_fails
        self.slow, self.slow_fails = slow, slow_fails
        self.collision, self.ssm = COLLISION, PAPER_SSM      # what the loop asks whether a goal is blocked
        self.open_actions = self.actions = 0
        self.remembered: list = []

        self.delays: list[float] = []        # take_delay's, turn by turn

    def take_delay(self, delay: float) -> None:
        self.delays.append(delay)

    def begin(self) -> None:
        self.open_actions += 1
        self.actions += 1

    def end(self) -> None:
        self.open_actions -= 1

    def widen(self, seconds: float) -> None:
        pass

    def forget(self, leg_start=None) -> None:
        self.forgotten += 1
        self.leg_start = leg_start

    def _result(self, reason: str) -> ReplanResult:
        self.searches += 1
        return ReplanResult(OLD, 0.5, reason, 0.0)

    def plan_goal(self, q, goal, humans, version, waited, prepared=None, leaving=False, trusted=False):
        self.calls.append(f"plan_goal v{version}")
        self.humans = humans
        self.leaving.append(leaving)
        self.trusted = trusted
        self.took_prepared = prepared is not None
        if np.allclose(goal, 99.0):
            raise PlanningError("the goal is out of reach")
        self.search_deferred, self.goal_searched, self.took_fold = self.defers and leaving, False, self.folds
        self.searches += not self.search_deferred
        return dataclasses.replace(OLD, version=version)

    def replan(self, old, s, goal, humans, reason, waited=0.0):
        self.calls.append("replan")
        return self._result(reason)

    def on_beta(self, old, s, goal, humans, speed, waited, held, reason="beta", why="replan request", stop_at=None):
        self.calls.append("beta" if reason == "beta" else f"beta as {reason}")
        self.waited, self.held, self.stop_at = waited, held, stop_at
        if self.beta_fails:
            raise ReplanFailed("not 10 % faster")
        return self._result(reason)

    def on_search(self, old, s, goal, humans, speed, waited, held):
        self.calls.append("search")
        self.waited, self.held = waited, held
        return self._result("search")

    def on_horizon(self, old, s, goal, humans, speed, waited, held):
        self.calls.append("horizon")
        self.held = held
        if self.horizon_fails:
            raise ReplanFailed("blocked, no way round")
        return self._result("horizon") if self.horizon else None

    def on_slow(self, old, s, goal, humans, speed, waited, held):
        self.calls.append("slow")
        if self.slow_fails:
            raise ReplanFailed("path predicted slow, kept the old trajectory")
        return self._result("slow") if self.slow else None


def inputs(**changes) -> PlanningInputs:
    base = dict(goal=Q_GOAL, new_goal=False, q=Q_START, humans=HumanCapsules.empty(), human_sample=0, following=(OLD, 0.2),
                speed=1.0, beta=False, waited=0.0, version=4)
    base.update(changes)
    return PlanningInputs(**base)


def test_nothing_is_planned_without_a_goal_or_a_known_position():
    loop = PlanningLoop(RecordingReplanner(horizon=True))
    assert loop.step(0.0, inputs(goal=None, new_goal=True)) is None
    assert loop.step(0.0, inputs(q=None, new_goal=True)) is None
    assert loop.replanner.calls == []


def test_nothing_is_planned_for_people_not_known_and_a_new_goal_waits_for_them():
    """No valid human state yet (the cell's first ms), or the track lost: the scaling layer moves nobody, so a plan
    made now would be the empty cell's shape for nothing. A goal waits, and the first state is planned for; a
    replan request in a dropout is not answered with a path for nobody."""
    loop = PlanningLoop(RecordingReplanner(horizon=True, slow=True))
    assert not PlanningLoop.ready(inputs(new_goal=True, following=None, humans=None))
    assert loop.step(0.0, inputs(new_goal=True, following=None, humans=None)) is None
    assert loop.replanner.calls == []
    seen = reaching_over_the_shuttle()
    goal = loop.step(0.02, inputs(new_goal=True, following=None, humans=seen, human_sample=1))
    assert goal.action == "goal" and loop.replanner.calls == ["plan_goal v4"] and loop.replanner.humans is seen
    assert loop.step(1.0, inputs(beta=True, humans=None, human_sample=2)) is None     # the track lost
    assert loop.replanner.calls == ["plan_goal v4"]
    assert loop.step(1.1, inputs(beta=True, humans=seen, human_sample=3)).action == "beta"       # back: answered


def test_a_new_goal_comes_first_from_rest_or_merged_into_the_followed_trajectory():
    loop = PlanningLoop(RecordingReplanner(horizon=True))
    rest = loop.step(0.0, inputs(new_goal=True, following=None, beta=True))
    assert rest.action == "goal" and rest.result.from_rest and rest.result.junction == 0.0 and rest.searches == 1
    assert rest.result.detail == "the straight line"        # which leg, where it was not searched
    folded = PlanningLoop(RecordingReplanner(folds=True)).step(0.0, inputs(new_goal=True, following=None))
    assert folded.result.detail == "the folded leg"
    merged = loop.step(0.0, inputs(new_goal=True, beta=True))
    assert merged.action == "goal" and not merged.result.from_rest
    assert loop.replanner.calls == ["plan_goal v4", "replan"]
    assert loop.replanner.forgotten == 3        # a new loop and each new goal start with no remembered paths


def test_a_goal_from_rest_leaves_at_once_and_its_search_runs_on_the_way():
    """Nobody waits at a goal for its search: the leg is published without one, and once the robot has left on
    it (or the SSM holds it where it stands) the search runs, once, as a replan that must pay (reason 'search')."""
    loop = PlanningLoop(RecordingReplanner(defers=True), slow_period=None)
    goal = loop.step(0.0, inputs(new_goal=True, following=None))
    assert goal.action == "goal" and goal.searches == 0 and goal.result.detail == "left at once, searched on the way"
    assert loop.replanner.leaving == [True] and loop.search_due == 4
    leg = goal.result.trajectory
    assert loop.step(0.01, inputs(following=(leg, 0.0), speed=0.0)) is None          # not left yet: nothing
    assert loop.step(0.01, inputs(following=(leg, 0.0), speed=None)) is None         # speed unknown: nothing
    assert loop.step(0.01, inputs(following=(OLD, 0.05), speed=1.0)) is None         # another trajectory: nothing
    search = loop.step(0.02, inputs(following=(leg, 0.01), speed=0.05))
    assert search.action == "search" and search.result.reason == "search" and search.searches == 1
    assert loop.replanner.calls[-1] == "search" and loop.search_due is None
    assert loop.step(0.03, inputs(following=(leg, 0.02), speed=0.1)) is None         # once
    # held where it stands by the SSM: the search plans from rest there
    held = PlanningLoop(RecordingReplanner(defers=True), slow_period=None)
    leg = held.step(0.0, inputs(new_goal=True, following=None)).result.trajectory
    assert held.step(0.01, inputs(following=(leg, 0.0), speed=0.0, held=True)).action == "search"


def test_a_replan_request_or_a_new_goal_takes_the_place_of_the_search_left_for_the_way():
    loop = PlanningLoop(RecordingReplanner(defers=True), slow_period=None)
    leg = loop.step(0.0, inputs(new_goal=True, following=None)).result.trajectory
    beta = loop.step(0.01, inputs(following=(leg, 0.01), speed=0.05, beta=True))
    assert beta.action == "beta" and loop.search_due is None
    assert loop.step(0.02, inputs(following=(leg, 0.02), speed=0.1)) is None
    again = PlanningLoop(RecordingReplanner(defers=True), slow_period=None)
    again.step(0.0, inputs(new_goal=True, following=None))
    assert again.step(0.5, inputs(new_goal=True, following=(OLD, 0.2), goal=Q_START)).action == "goal"
    assert again.search_due is None               # a goal merged into the followed trajectory searches itself
    plain = PlanningLoop(RecordingReplanner(), slow_period=None)       # a goal whose line needs no search
    plain.step(0.0, inputs(new_goal=True, following=None))
    assert plain.search_due is None


def test_a_goal_that_cannot_be_planned_is_refused_with_the_reason():
    outcome = PlanningLoop(RecordingReplanner()).step(0.0, inputs(goal=np.full(6, 99.0), new_goal=True, following=None))
    assert outcome.action == "goal" and outcome.result is None
    assert outcome.refused == "PlanningError: the goal is out of reach"


def test_beta_is_answered_at_most_once_a_cooldown_and_before_the_horizon():
    loop = PlanningLoop(RecordingReplanner(horizon=True), beta_cooldown=0.5)
    assert loop.step(0.0, inputs(beta=True, human_sample=1)).action == "beta"
    assert loop.step(0.1, inputs(beta=True, human_sample=1)).action == "horizon"   # beta cools down
    assert loop.step(0.2, inputs(beta=True, human_sample=1)) is None     # same sample: the path ahead is not slow
    assert loop.step(0.5, inputs(beta=True, human_sample=1, held=True)).action == "beta"
    assert loop.replanner.calls == ["beta", "horizon", "slow", "beta"]


def test_the_replanner_is_told_whether_the_ssm_keeps_the_robot_slow_held_or_asking_for_a_replan():
    """The SSM keeps the robot's speed down where its speed is the SSM's bound (held) or the bound is below
    alpha_min (beta): beside a person the two chatter, and a robot at a few % of its nominal speed that is
    not held this cycle is no robot speeding back up (real_table_edge seed 6, 30 ms late). Neither: a ramp."""
    assert [inputs(held=h, beta=b).kept_slow for h, b in ((False, False), (True, False), (False, True))] == \
        [False, True, True]
    loop = PlanningLoop(RecordingReplanner(horizon=True), beta_cooldown=0.5, slow_period=None)
    assert loop.step(0.0, inputs(beta=True, human_sample=1)).action == "beta"
    assert loop.replanner.held is True          # asking, not held this cycle: kept slow all the same
    assert loop.step(1.0, inputs(human_sample=2)).action == "horizon"
    assert loop.replanner.held is False         # neither held nor asking: a ramp back to speed
    assert loop.step(2.0, inputs(human_sample=3, held=True)).action == "horizon"
    assert loop.replanner.held is True


def test_a_robot_stopped_to_await_its_plan_is_answered_at_once_and_once_for_each_wait():
    """The scaler brings a crawling robot to rest for the replan it asks for (stop_at): that request is answered
    in the next turn even within the cooldown of a refused one, with the stop handed to the replanner, and not
    again for the same wait."""
    loop = PlanningLoop(RecordingReplanner(beta_fails=True), beta_cooldown=0.5, slow_period=None)
    assert loop.step(0.0, inputs(beta=True)).action == "beta" and loop.replanner.stop_at is None
    assert loop.step(0.1, inputs(beta=True, stop_at=0.31)).action == "beta"        # a new wait: at once
    assert loop.replanner.stop_at == 0.31
    assert loop.step(0.2, inputs(beta=True, stop_at=0.31)) is None                   # the same wait: not again
    assert loop.step(0.3, inputs(beta=True, stop_at=0.35)).action == "beta" and loop.replanner.stop_at == 0.35
    assert loop.replanner.calls == ["beta", "beta", "horizon", "beta"]
    assert PlanningLoop(RecordingReplanner(), beta_replans=False).step(0.0, inputs(beta=True, stop_at=0.31)) is None


def test_every_action_is_one_budgeted_action_of_the_replanner_even_when_it_fails():
    loop = PlanningLoop(RecordingReplanner(beta_fails=True))
    assert loop.step(0.0, inputs(beta=True, human_sample=1)).refused == "not 10 % faster"
    assert loop.step(0.0, inputs(goal=np.full(6, 99.0), new_goal=True, following=None)).result is None
    assert loop.replanner.actions == 2 and loop.replanner.open_actions == 0      # begun and ended, each


def test_without_beta_replans_the_request_is_ignored():
    loop = PlanningLoop(RecordingReplanner(), beta_replans=False)
    assert loop.step(0.0, inputs(beta=True, human_sample=1)) is None      # the horizon is clear
    assert loop.replanner.calls == ["horizon"]


def test_the_horizon_is_checked_once_a_sample_at_most_every_period_and_backs_off_after_a_refusal():
    loop = PlanningLoop(RecordingReplanner(horizon=True), horizon_period=0.02, beta_cooldown=0.5, slow_period=None)
    assert loop.step(0.00, inputs(human_sample=1)).action == "horizon"
    assert loop.step(0.01, inputs(human_sample=2)) is None                 # within the period
    assert loop.step(0.02, inputs(human_sample=2)).action == "horizon"
    loop.replanner.horizon_fails = True
    refused = loop.step(0.04, inputs(human_sample=3))
    assert refused.result is None and refused.refused == "blocked, no way round"
    assert loop.step(0.06, inputs(human_sample=4)) is None                 # backing off half a cooldown
    assert loop.step(0.29, inputs(human_sample=5)).action == "horizon"
    assert loop.replanner.calls == ["horizon"] * 4


def test_a_path_ahead_is_checked_for_a_slow_prediction_every_period_after_the_others_and_backs_off_after_a_refusal():
    loop = PlanningLoop(RecordingReplanner(), horizon_period=0.02, beta_cooldown=0.5, slow_period=0.25)
    assert loop.step(0.00, inputs(human_sample=1)) is None          # the horizon is clear, the path ahead not slow
    assert loop.step(0.10, inputs(human_sample=1)) is None          # within the period: not asked again
    loop.replanner.slow = True
    taken = loop.step(0.25, inputs(human_sample=1))
    assert taken.action == "slow" and taken.result.reason == "slow" and taken.searches == 1
    loop.replanner.slow_fails = True
    refused = loop.step(0.50, inputs(human_sample=1))
    assert refused.action == "slow" and refused.result is None and "kept the old trajectory" in refused.refused
    assert loop.step(0.80, inputs(human_sample=1)) is None          # backing off a beta cooldown after a refusal
    assert loop.step(1.00, inputs(human_sample=1)).action == "slow"
    assert loop.replanner.calls == ["horizon", "slow", "slow", "slow", "slow"]
    # beta and a new horizon sample come first; the paper's ablation (no replan requests) asks for none
    assert loop.step(1.60, inputs(beta=True, human_sample=2)).action == "beta"
    loop.replanner.horizon = True
    assert loop.step(1.70, inputs(human_sample=3)).action == "horizon"
    ablation = PlanningLoop(RecordingReplanner(slow=True), beta_replans=False)
    assert ablation.step(0.0, inputs(human_sample=1)) is None and ablation.replanner.calls == ["horizon"]


def test_a_finished_trajectory_is_not_replanned():
    loop = PlanningLoop(RecordingReplanner(horizon=True))
    assert loop.step(0.0, inputs(following=None, beta=True, human_sample=1)) is None
    assert loop.replanner.calls == []


def test_an_action_budget_stops_the_searches_in_time_for_the_rest_of_the_action():
    """The planner service's budget for a whole action: its searches stop at the deadline that leaves the
    rest of the action its recent time (anytime: still a free path), and the replanner learns that time.
    Without a budget (the simulation) the searches run their counts, whatever the clock."""
    segments, radii = body_segments(-1.0, 0.0, 1.0, np.array([-0.4, 0.0, 0.8]))   # reaching over the shuttle
    someone = HumanCapsules.from_arrays(segments, radii, np.zeros(segments.shape), np.ones(len(radii), bool))
    direct = np.vstack([Q_START, Q_GOAL])

    def search_in_an_action(budget):
        replanner = Replanner(COLLISION, JointPlanner(COLLISION, PlannerOptions(seed=5)), PAPER_SSM,
                              options=ReplanOptions(seed=5, action_budget=budget))
        began = time.perf_counter()
        replanner.begin()
        deadline = replanner.search.deadline
        found = replanner.search.search(Q_START, Q_GOAL, someone, np.random.default_rng(1), stay=5.0, seeds=(direct,))
        assert replanner.search.spent > 0.0
        replanner.end()
        assert replanner.search.deadline is None                   # no deadline outlives its action
        return replanner, None if deadline is None else deadline - began, found

    unbounded, deadline, counted = search_in_an_action(None)
    assert deadline is None and counted.costed >= SearchOptions().candidates and unbounded.finishing == 0.02
    # 5 ms for the whole action, less than the first guess of the rest (20 ms): the deadline has passed
    budgeted, deadline, cut = search_in_an_action(0.005)
    assert deadline < 0.0
    assert cut.costed < SearchOptions().candidates and budgeted.search.free(cut.waypoints, someone)
    assert 0.0 <= budgeted.finishing < 0.02        # learnt from what the rest took (at most the budget)


def test_a_widened_action_searches_until_its_own_deadline_past_the_search_budget_and_only_that_action():
    """The next leg's plan, prepared while the robot is on its way (nothing waits on it), may take PREPARE_BUDGET:
    its search runs past the cell's per-search bound to the widened deadline, costing the candidates the
    simulation's counted search costs; the next action has the budget again. No-op without a budget."""
    segments, radii = body_segments(-1.0, 0.0, 1.0, np.array([-0.4, 0.0, 0.8]))   # reaching over the shuttle
    someone = HumanCapsules.from_arrays(segments, radii, np.zeros(segments.shape), np.ones(len(radii), bool))
    direct = np.vstack([Q_START, Q_GOAL])
    replanner = Replanner(COLLISION, JointPlanner(COLLISION, PlannerOptions(seed=5)), PAPER_SSM,
                          options=ReplanOptions(seed=5, search=SearchOptions(time_budget=0.001), action_budget=0.002))

    def costed(widen: float | None) -> int:
        replanner.begin()
        if widen is not None:
            replanner.widen(widen)
        found = replanner.search.search(Q_START, Q_GOAL, someone, np.random.default_rng(1), stay=5.0, seeds=(direct,))
        out_of_time = replanner.budget.out_of_time()
        replanner.end()
        assert not replanner.search.widened and replanner.search.deadline is None    # nothing outlives its action
        return found.costed, out_of_time

    cut, _ = costed(None)
    whole, spent = costed(60.0)                    # a minute: the counts end the search, not the clock
    assert cut < SearchOptions().candidates <= whole and not spent
    again, _ = costed(None)
    assert again < SearchOptions().candidates     # the next action is bounded again
    unbudgeted = Replanner(COLLISION, JointPlanner(COLLISION, PlannerOptions(seed=5)), PAPER_SSM,
                           options=ReplanOptions(seed=5))
    unbudgeted.begin()
    unbudgeted.widen(0.25)
    assert unbudgeted.search.deadline is None and not unbudgeted.search.widened
    unbudgeted.end()


def test_the_loop_widens_the_budget_of_its_prepare_action_only(monkeypatch):
    """The loop widens the action that prepares the next leg to PREPARE_BUDGET, and no other."""
    import shared.planning.loop as module
    someone = reaching_over_the_shuttle()
    loop = PlanningLoop(fresh_replanner(), slow_period=None)
    widened = []
    monkeypatch.setattr(loop.replanner, "widen", lambda seconds: widened.append(seconds))
    leg = dict(humans=someone, then=Q_START)
    loop.step(0.0, inputs(**leg, following=(OLD, 0.3)))
    assert widened == []                                          # a horizon check: not widened
    prepared = loop.step(0.1, inputs(**leg, following=(OLD, OLD.duration - 0.3), human_sample=1))
    assert prepared.action == "prepare" and widened == [module.PREPARE_BUDGET]


def test_the_learnt_finishing_time_rises_at_once_and_falls_slowly(monkeypatch):
    """A refused replan's rest is a millisecond, a taken one's the time laws of its trajectory (20-45 ms):
    an average of both let the next taken plan's searches run into its time (hrc demo: replans 107-118 ms
    against a 100 ms budget). The learnt time goes up at once to a longer rest, down a tenth of the gap."""
    import shared.planning.budget as module
    clock = [100.0]
    monkeypatch.setattr(module, "time", type("Clock", (), {"perf_counter": staticmethod(lambda: clock[0])}))
    replanner = Replanner(COLLISION, JointPlanner(COLLISION, PlannerOptions(seed=5)), PAPER_SSM,
                          options=ReplanOptions(action_budget=0.1))

    def action(search: float, rest: float) -> float:
        replanner.begin()
        replanner.search.spent = search
        clock[0] += search + rest
        replanner.end()
        return replanner.finishing

    assert action(0.06, 0.045) == pytest.approx(0.045)                          # up at once
    assert action(0.02, 0.001) == pytest.approx(0.045 + 0.1 * (0.001 - 0.045))  # down a tenth of the gap
    assert action(0.0, 0.5) == pytest.approx(0.0406)                  # an action that did not search: unlearnt
    assert action(0.01, 0.5) == pytest.approx(0.05)     # at most half the budget: the searches keep the rest


def test_a_merge_tries_further_junctions_only_within_the_action_budget(monkeypatch):
    """Every junction a merge tries times a whole law; in the cell a merge that failed at two junctions took
    685 ms. With an action budget, a try after the budget is spent is not made: the replan is refused
    saying what was tried. Without one (the simulation) every junction and stop-and-go are tried."""
    import shared.planning.candidates as candidates_module
    from shared.planning.timing import TimingError

    tried = []

    def failing(waypoints, *args, **kwargs):
        tried.append(len(waypoints))
        raise TimingError("the smoothed path leaves the joint position limits")

    monkeypatch.setattr(candidates_module, "parameterize", failing)

    def merge_with(budget):
        tried.clear()
        replanner = Replanner(COLLISION, JointPlanner(COLLISION, PlannerOptions(seed=5)), PAPER_SSM,
                              options=ReplanOptions(seed=5, action_budget=budget))
        replanner.begin()
        try:
            with pytest.raises(ReplanFailed) as refused:
                replanner.replan(OLD, 0.5, Q_GOAL, None, "horizon", s_branch=1.5)
        finally:
            replanner.end()
        return str(refused.value), len(tried)

    unbounded, tries = merge_with(None)
    assert tries == len(ReplanOptions().lookback) + 1 and unbounded.startswith("no junction allows")
    spent, tries = merge_with(1e-6)                       # spent before the first try ends
    assert tries == 1 and spent.startswith("no merge within the action's time: through at s=1.20")


def test_the_warm_up_runs_every_kind_of_action_and_leaves_no_trace():
    """The planner service warms up with one action of each kind (a goal, the horizon, beta moving, crawling
    and at rest) so that no kernel is loaded inside a real one; afterwards the replanner plans exactly as a
    fresh one: nothing remembered, the learnt finishing time as it was."""
    segments, radii = body_segments(-1.0, 0.0, 1.0, np.array([-0.4, 0.0, 0.8]))   # reaching over the shuttle
    someone = HumanCapsules.from_arrays(segments, radii, np.zeros(segments.shape), np.ones(len(radii), bool))

    def fresh() -> Replanner:
        return Replanner(COLLISION, JointPlanner(COLLISION, PlannerOptions(seed=5)), PAPER_SSM,
                         options=ReplanOptions(seed=5))

    warmed = fresh()
    warmed.finishing = 0.037
    assert warm_up(warmed) >= 4 and warmed.searches >= 3        # a goal and the replan requests searched
    assert warmed.remembered == [] and warmed.finishing == 0.037
    first, second = (r.plan_goal(Q_START, Q_GOAL, someone, 1) for r in (warmed, fresh()))
    assert np.array_equal(first.positions, second.positions) and first.duration == second.duration


def reaching_over_the_shuttle() -> HumanCapsules:
    """A person standing beside the shuttle's middle, reaching over it: the direct line is predicted slow."""
    segments, radii = body_segments(-1.0, 0.0, 1.0, np.array([-0.4, 0.0, 0.8]))
    return HumanCapsules.from_arrays(segments, radii, np.zeros(segments.shape), np.ones(len(radii), bool))


def fresh_replanner() -> Replanner:
    """The paper's planner (no posture): a way round the person is searched, so there is a search to prepare (the
    shipped folded leg in the direct line's place clears this person without one)."""
    return Replanner(COLLISION, JointPlanner(COLLISION, PlannerOptions(seed=5)), PAPER_SSM,
                     options=ReplanOptions(seed=5, posture_gap=None))


def test_the_next_leg_is_prepared_on_the_way_and_taken_at_the_goal_without_a_search():
    """Within prepare_ahead of the goal, the loop plans the leg after it (the goal the inputs say comes
    then), once for the trajectory followed; when that goal comes, the plan is published at once: no search,
    the same path, the version the goal gets."""
    someone = reaching_over_the_shuttle()
    loop = PlanningLoop(fresh_replanner(), slow_period=None)
    leg = dict(humans=someone, then=Q_START)
    loop.step(0.0, inputs(**leg, following=(OLD, 0.3)))
    assert loop.prepared is None                                  # far from the goal: nothing prepared
    before = OLD.duration - 0.3                                   # within PREPARE_AHEAD
    prepared = loop.step(0.1, inputs(**leg, following=(OLD, before), human_sample=1))
    assert prepared.action == "prepare" and prepared.result is None and prepared.searches >= 1
    assert prepared.prepared is loop.prepared.trajectory and np.allclose(prepared.prepared.positions[0], Q_GOAL)
    assert np.allclose(prepared.prepared.positions[-1], Q_START)
    assert prepared.prepared.positions.shape[0] > 4           # a way round the person, not the direct line
    assert loop.replanner.remembered == []                    # the current goal's memory is left as it was
    again = loop.step(0.12, inputs(**leg, following=(OLD, before + 0.02), human_sample=2))
    assert again is None or again.action != "prepare"         # once for the trajectory followed
    goal = loop.step(0.3, inputs(humans=someone, goal=Q_START, then=Q_GOAL, new_goal=True, q=Q_GOAL,
                                 following=None, version=9, human_sample=3))
    assert goal.action == "goal" and goal.searches == 0 and goal.result.detail == "prepared on the way here"
    assert np.array_equal(goal.result.trajectory.positions, prepared.prepared.positions)
    assert goal.result.trajectory.version == 9 and loop.prepared is None


def test_a_prepared_plan_is_taken_only_while_still_good():
    """A prepared plan is taken only from where it starts, while the people are where it was planned for
    them (none moved more than PREPARED_DRIFT) and while it is collision-free against them; otherwise the
    goal gets a search of its own, as without preparation."""
    someone = reaching_over_the_shuttle()
    replanner = fresh_replanner()
    plan = replanner.plan_goal(Q_GOAL, Q_START, someone, 0)
    assert plan.positions.shape[0] > 4                                  # a way round the person
    prepared = PreparedPlan(plan, someone)
    taken = replanner.plan_goal(Q_GOAL, Q_START, someone, 4, prepared=prepared)
    assert replanner.took_prepared and taken.version == 4 and np.array_equal(taken.positions, plan.positions)

    def not_taken(q_start, humans, prepared_plan) -> np.ndarray:
        before = replanner.searches
        anew = replanner.plan_goal(q_start, Q_START, humans, 4, prepared=prepared_plan)
        assert not replanner.took_prepared and replanner.searches > before       # searched anew
        return anew.positions

    assert not np.allclose(not_taken(Q_GOAL + 0.05, someone, prepared)[0], plan.positions[0])   # from elsewhere
    moved = dataclasses.replace(someone, segments=someone.segments + [0.0, 0.15, 0.0])        # stepped aside
    not_taken(Q_GOAL, moved, prepared)
    wrist = ROBOT.capsule_segments(plan.sample(0.5 * plan.duration)[0])[-1, 1]
    stepped_in = HumanCapsules.from_arrays(np.vstack([someone.segments, [[wrist, wrist + [0.0, 0.0, 0.3]]]]),
                                           np.append(someone.radii, 0.1), np.zeros((len(someone.radii) + 1, 2, 3)),
                                           np.ones(len(someone.radii) + 1, bool))
    # (as if planned for them: only the collision check stands between it and the robot)
    anew = not_taken(Q_GOAL, stepped_in, PreparedPlan(plan, stepped_in))
    assert not np.array_equal(anew, plan.positions)


def test_a_goal_after_that_cannot_be_planned_is_refused_saying_why_and_nothing_is_kept():
    loop = PlanningLoop(RecordingReplanner(), slow_period=None)
    outcome = loop.step(0.0, inputs(following=(OLD, OLD.duration - 0.1), then=np.full(6, 99.0)))
    assert outcome.action == "prepare" and outcome.prepared is None and loop.prepared is None
    assert outcome.refused == "PlanningError: the goal is out of reach"
    goal = loop.step(1.0, inputs(new_goal=True, following=None, goal=Q_START))     # the next goal: planned as ever
    assert goal.action == "goal" and goal.result is not None and loop.replanner.calls[-1] == "plan_goal v4"


def test_without_the_goal_after_nothing_is_prepared():
    loop = PlanningLoop(RecordingReplanner(), slow_period=None)
    assert loop.step(0.0, inputs(following=(OLD, OLD.duration - 0.1))) is None and loop.prepared is None
    assert loop.replanner.calls == ["horizon"]


def test_nothing_is_prepared_for_people_on_the_move_until_they_stand():
    """A plan prepared for walking people would be out of date when its goal comes (it is taken only where
    they have not moved on): the loop waits until they stand, and prepares then."""
    loop = PlanningLoop(RecordingReplanner(), slow_period=None)
    someone = reaching_over_the_shuttle()
    walking = dataclasses.replace(someone, velocities=np.full(someone.segments.shape, 0.0) + [0.0, 0.5, 0.0])
    end = OLD.duration - 0.2
    assert loop.step(0.0, inputs(following=(OLD, end), humans=walking, then=Q_START)) is None and loop.prepared is None
    assert "plan_goal v0" not in loop.replanner.calls
    prepared = loop.step(0.1, inputs(following=(OLD, end + 0.05), humans=someone, then=Q_START, human_sample=1))
    assert prepared.action == "prepare" and loop.replanner.calls[-1] == "plan_goal v0"


# ------------------------------------------------------------------------ the service, in-process
@pytest.fixture(scope="module")
def replanner() -> Replanner:
    collision = CollisionModel(ROBOT, load_scene(DEFAULT_SCENE))
    return Replanner(collision, JointPlanner(collision, PlannerOptions(seed=5)), PAPER_SSM,
                     options=ReplanOptions(seed=5))


def planner_given_a_goal(replanner, goal_id: int) -> tuple[FakeShell, PlannerService]:
    """A planner service in-process that knows where the robot is and has taken its turn on a goal (t = 1 s) once
    the tracker's first state came (nobody in view); until then the goal waits, kept, with nothing published."""
    shell = FakeShell("planner")
    service = PlannerService(shell, PlanningLoop(replanner))
    shell.deliver(shell.keys.joint_state, JointState(q=Q_START, qd=np.zeros(6), drive_state="running", enabled=True,
                                                     fault=False))
    shell.deliver(shell.keys.goal, Goal(goal_id=goal_id, name="q_g", q=Q_GOAL))
    service.work_once(0.9)
    assert shell.published(shell.keys.trajectory, TrajectoryMsg) == [] and service.new_goal
    assert service.pause() == POLL                 # the goal waits for the people: turns at the loop's cadence
    shell.deliver(shell.keys.human_state, humans_to_msg(HumanCapsules.empty(), True, 0.95))
    service.work_once(1.0)
    return shell, service


def test_the_planning_layer_counts_the_peoples_way_from_capture_as_the_scaler_does(replanner):
    """A people state published 30 ms after its capture: the planner service hands the loop that delay, the loop
    the replanner before it acts, and its time cost, path search and forward run of the scaling layer count the
    person's travel over it (a path it predicts passable on data of now, the scaler holds at rest)."""
    shell, service = planner_given_a_goal(replanner, 3)
    assert replanner.cost.ssm.human_lead == 0.0
    someone = HumanCapsules.from_arrays([[[-1.6, 0.0, 0.9], [-1.6, 0.0, 1.5]]], [0.2], np.zeros((1, 2, 3)), [True])
    shell.deliver(shell.keys.human_state, humans_to_msg(someone, True, 1.9, stamp=1.93))
    service.work_once(2.0)
    assert service.human_delay == pytest.approx(0.03)
    assert replanner.cost.ssm.human_lead == pytest.approx(0.03) and replanner.cost.ssm == PAPER_SSM.aged(0.03)
    shell.deliver(shell.keys.human_state, humans_to_msg(someone, True, 2.0))          # no publication stamp
    service.work_once(2.1)
    assert service.human_delay == 0.0 and replanner.cost.ssm.human_lead == 0.0
    loop = PlanningLoop(RecordingReplanner(horizon=True))
    loop.step(0.0, inputs(human_delay=0.045))
    assert loop.replanner.delays == [0.045]
    judged = fresh_replanner()
    judged.executed = SimpleNamespace(delay=0.0)
    judged.take_delay(float("nan"))
    assert judged.executed.delay == 0.0 and judged.cost.ssm.human_lead == 0.0
    judged.take_delay(0.02)
    assert judged.executed.delay == 0.02


def test_the_planner_service_plans_a_goal_and_answers_beta_through_the_loop(replanner):
    shell, service = planner_given_a_goal(replanner, 7)
    keys = shell.keys
    sent = shell.published(keys.trajectory, TrajectoryMsg)
    assert len(sent) == 1 and sent[0].goal_id == 7 and sent[0].base_version == -1 and sent[0].reason == "goal"
    assert np.allclose(sent[0].positions[0], Q_START) and np.allclose(sent[0].positions[-1], Q_GOAL)
    events = shell.published(keys.safety_events, SafetyEvent)
    assert events[-1].event == "trajectory_goal" and events[-1].source == "planner"
    # the scaler follows it and asks for a replan with a person's arm across the path (not so far in that
    # the goal itself is out of reach: shared.planning.blocked, tests/planning/test_blocked_goal.py)
    arm = HumanCapsules.from_arrays([[[-0.85, -0.05, 0.5], [-0.4, 0.0, 0.5]]], [0.05], np.zeros((1, 2, 3)), [True])
    shell.deliver(keys.human_state, humans_to_msg(arm, True, 1.5))
    shell.deliver(keys.scaler_status, ScalerStatus(s=0.3, alpha=0.0, safe_alpha=0.0, beta=True, q_command=Q_START,
                                                   trajectory_version=sent[0].version, status="running",
                                                   method="piqp", min_separation=None, min_margin=None,
                                                   compute_us=50.0, received=sent[0].version))
    service.work_once(2.0)
    events = shell.published(keys.safety_events, SafetyEvent)
    assert events[-1].event in ("trajectory_beta", "replan_refused")     # answered, one way or the other
    assert "predicted" in events[-1].text            # the decision says both predicted times


def test_the_planner_service_prepares_the_goal_after_and_publishes_it_at_once_when_it_comes():
    """A goal that names the one after it (Goal.then): near its end the planner prepares the leg after
    (an event says so, not a trajectory), and when that goal comes it publishes the prepared plan."""
    shell = FakeShell("planner")
    keys = shell.keys
    service = PlannerService(shell, PlanningLoop(fresh_replanner()))
    someone = reaching_over_the_shuttle()
    shell.deliver(keys.joint_state, JointState(q=Q_START, qd=np.zeros(6), drive_state="running", enabled=True,
                                               fault=False))
    shell.deliver(keys.human_state, humans_to_msg(someone, True, 0.9))
    shell.deliver(keys.goal, Goal(goal_id=7, name="q_g", q=Q_GOAL, then=Q_START[None]))
    service.work_once(1.0)
    leg = shell.published(keys.trajectory, TrajectoryMsg)[-1]
    assert leg.goal_id == 7 and np.allclose(leg.positions[-1], Q_GOAL)
    end = float(leg.times[-1])
    shell.deliver(keys.scaler_status, ScalerStatus(s=end - 0.2, alpha=1.0, safe_alpha=1.0, beta=False,
                                                   q_command=leg.positions[-1], trajectory_version=leg.version,
                                                   status="running", method="piqp", min_separation=None,
                                                   min_margin=None, compute_us=50.0, received=leg.version))
    shell.deliver(keys.human_state, humans_to_msg(someone, True, 1.9))
    service.work_once(2.0)
    events = shell.published(keys.safety_events, SafetyEvent)
    assert events[-1].event == "next_goal_prepared" and "for goal 7" in events[-1].text, events[-1].text
    assert len(shell.published(keys.trajectory, TrajectoryMsg)) == 1           # kept, not published
    shell.deliver(keys.joint_state, JointState(q=Q_GOAL, qd=np.zeros(6), drive_state="running", enabled=True,
                                               fault=False))
    shell.deliver(keys.scaler_status, ScalerStatus(s=end, alpha=1.0, safe_alpha=1.0, beta=False,
                                                   q_command=leg.positions[-1], trajectory_version=leg.version,
                                                   status="finished", method="piqp", min_separation=None,
                                                   min_margin=None, compute_us=50.0, received=leg.version))
    shell.deliver(keys.goal, Goal(goal_id=8, name="q_s", q=Q_START, then=Q_GOAL[None]))
    service.work_once(3.0)
    back = shell.published(keys.trajectory, TrajectoryMsg)[-1]
    events = shell.published(keys.safety_events, SafetyEvent)
    assert back.goal_id == 8 and back.reason == "goal" and np.allclose(back.positions[-1], Q_START)
    assert events[-1].event == "trajectory_goal" and "prepared on the way here" in events[-1].text, events[-1].text


def test_the_planner_service_plans_from_where_the_scaler_awaits_its_plan(replanner):
    """The scaler's status says where it brings the crawling robot to rest to await its replan (stop_s): the
    answer is a plan from rest there, or a refusal that compares it from there; a new wait is answered at once,
    within the cooldown of the last answer."""
    shell, service = planner_given_a_goal(replanner, 7)
    keys = shell.keys
    goal = shell.published(keys.trajectory, TrajectoryMsg)[-1]
    arm = HumanCapsules.from_arrays([[[-0.85, -0.05, 0.5], [-0.4, 0.0, 0.5]]], [0.05], np.zeros((1, 2, 3)), [True])

    def awaiting(now: float, stop_s: float) -> SafetyEvent:
        shell.deliver(keys.human_state, humans_to_msg(arm, True, now))
        shell.deliver(keys.scaler_status, ScalerStatus(
            s=stop_s - 0.01, alpha=0.05, safe_alpha=0.05, beta=True, q_command=Q_START, trajectory_version=goal.version,
            status="running", method="piqp+stopping", min_separation=None, min_margin=None, compute_us=50.0,
            stop_s=stop_s, received=service.trajectory.version))
        service.work_once(now)
        return shell.published(keys.safety_events, SafetyEvent)[-1]

    first = awaiting(1.0, 0.32)
    assert first.event in ("trajectory_beta", "replan_refused") and "from rest" in first.text, first.text
    again = awaiting(1.1, 0.33)                 # a new wait: answered at once, within the cooldown
    assert again.seq > first.seq and "from rest" in again.text, again.text
    if again.event == "trajectory_beta":
        plan = shell.published(keys.trajectory, TrajectoryMsg)[-1]
        assert plan.base_version == -1 and np.allclose(plan.positions[0], service.published[goal.version].sample(0.33)[0])


def test_the_planner_service_drops_bad_bytes_and_goes_on(replanner):
    shell = FakeShell("planner")
    service = PlannerService(shell, PlanningLoop(replanner))
    shell.deliver(shell.keys.goal, b"\x93garbage")
    shell.deliver(shell.keys.goal, Goal(goal_id=1, name="bad", q=np.full(6, 0.0)).__class__.__name__.encode())
    assert shell.bad_messages == 2 and service.goal is None
    shell.deliver(shell.keys.human_state, b"\x81\xa4kind\xa5human")        # kept by the ring, judged when taken
    service.work_once(0.0)
    assert shell.bad_messages == 3 and service.humans is None
    assert shell.published(shell.keys.trajectory, TrajectoryMsg) == []


def test_the_planner_goes_on_with_the_version_the_scaler_follows_when_a_plan_was_not_taken(replanner):
    """A published plan is on its way until the scaler's status says it has decided on it (``received``):
    nothing is replanned meanwhile; once the scaler has refused it, the one it still follows is; a plan never
    reported on (lost, or a scaler restarted) is on its way for TAKE_WAIT at most."""
    shell, service = planner_given_a_goal(replanner, 1)
    keys = shell.keys
    first = shell.published(keys.trajectory, TrajectoryMsg)[-1]

    def status(version: int, received: int) -> ScalerStatus:
        return ScalerStatus(s=0.3, alpha=1.0, safe_alpha=1.0, beta=False, q_command=Q_START,
                            trajectory_version=version, status="running", method="piqp", min_separation=None,
                            min_margin=None, compute_us=50.0, received=received)

    assert service._in_flight(1.0)                           # published, no status yet
    shell.deliver(keys.scaler_status, status(first.version, first.version))
    service.poll(1.1)
    assert not service._in_flight(1.1)
    service.trajectory = dataclasses.replace(service.trajectory, version=first.version + 1)   # a newer plan, sent
    service.published[first.version + 1], service.published_at = service.trajectory, 1.2
    assert service._in_flight(1.5)                           # on its way: nothing to replan on yet
    assert not service._in_flight(1.2 + TAKE_WAIT)           # never reported on: not waited for forever
    shell.deliver(keys.scaler_status, status(first.version, first.version + 1))        # decided on: refused
    service.poll(1.6)
    assert not service._in_flight(1.6)


def test_a_goal_whose_plan_was_dropped_while_the_robot_was_stopped_is_planned_again_once_it_runs(replanner):
    """A goal sent to a stopped robot (a stale command, a drive's watchdog): planned, dropped by the scaler, which
    holds and follows none of the planner's (version -1). Nothing is planned while the robot stays stopped; once
    the driver runs again (``hrc recover``) the goal is planned anew from where the robot stands, once, with an
    event saying so; a plan dropped again is not asked for at every turn."""
    shell, service = planner_given_a_goal(replanner, 5)
    keys = shell.keys
    first = shell.published(keys.trajectory, TrajectoryMsg)[-1]

    def scaler(version: int, received: int) -> ScalerStatus:
        return ScalerStatus(s=0.0, alpha=1.0, safe_alpha=1.0, beta=False, q_command=Q_START, trajectory_version=version,
                            status="finished", method="piqp", min_separation=None, min_margin=None, compute_us=50.0,
                            received=received)

    def robot(enabled: bool) -> JointState:
        return JointState(q=Q_START, qd=np.zeros(6), drive_state="running" if enabled else "stopped:fault",
                          enabled=enabled, fault=not enabled)

    shell.deliver(keys.human_state, humans_to_msg(HumanCapsules.empty(), True, 1.9))
    shell.deliver(keys.joint_state, robot(False))
    shell.deliver(keys.scaler_status, scaler(-1, first.version))          # decided on: dropped, holding
    for now in (2.0, 2.5, 4.0):
        service.work_once(now)
    assert len(shell.published(keys.trajectory, TrajectoryMsg)) == 1      # stopped: nothing to plan for
    shell.deliver(keys.joint_state, robot(True))                           # recovered
    service.work_once(4.1)
    again = shell.published(keys.trajectory, TrajectoryMsg)
    assert len(again) == 2 and again[-1].goal_id == 5 and again[-1].reason == "goal" and again[-1].base_version == -1
    assert again[-1].version > first.version and np.allclose(again[-1].positions[0], Q_START)
    assert np.allclose(again[-1].positions[-1], Q_GOAL)
    resumed = [e for e in shell.published(keys.safety_events, SafetyEvent) if e.event == "goal_resumed"]
    assert len(resumed) == 1 and "goal 5" in resumed[0].text
    shell.deliver(keys.scaler_status, scaler(-1, again[-1].version))      # dropped again at once
    service.work_once(4.2)
    assert len(shell.published(keys.trajectory, TrajectoryMsg)) == 2      # not within TAKE_WAIT of the last
    service.work_once(4.1 + TAKE_WAIT)
    assert len(shell.published(keys.trajectory, TrajectoryMsg)) == 3
    shell.deliver(keys.scaler_status, scaler(again[-1].version + 1, again[-1].version + 1))   # followed now
    shell.deliver(keys.joint_state, JointState(q=Q_GOAL, qd=np.zeros(6), drive_state="running", enabled=True,
                                               fault=False))
    service.work_once(9.0)
    assert len(shell.published(keys.trajectory, TrajectoryMsg)) == 3


def test_every_trajectory_the_planner_publishes_has_a_number_of_its_own(replanner):
    """Two replans on the same followed trajectory (the scaler refused the first) were both numbered its version + 1:
    the scaler's `received` then said the second decided on before it arrived, and where it took one of the two and
    ignored the other, the planner took the other for the one followed. Published, each is numbered above every one
    before it and every one the scaler reported; a number already above them is kept."""
    shell, service = planner_given_a_goal(replanner, 2)
    keys = shell.keys
    goal = shell.published(keys.trajectory, TrajectoryMsg)[-1]
    replan = dataclasses.replace(OLD, version=goal.version + 1)
    service._publish(2.0, replan, "beta", 0.0, -1, 100.0)
    service._publish(2.5, replan, "beta", 0.0, -1, 100.0)          # the same number again: renumbered
    sent = [m.version for m in shell.published(keys.trajectory, TrajectoryMsg)]
    assert sent == [goal.version, goal.version + 1, goal.version + 2]
    assert service.published[goal.version + 2].version == goal.version + 2 and service.trajectory.version == sent[-1]
    events = shell.published(keys.safety_events, SafetyEvent)
    assert f"version {goal.version + 2} " in events[-1].text           # the event names the number sent
    assert unique_version(replan, None, 40).version == 41            # above what the scaler reported
    assert unique_version(dataclasses.replace(OLD, version=50), replan, 40).version == 50     # already above: kept


def test_a_dropped_goal_is_planned_again_only_where_the_robot_runs_short_of_it_and_nothing_else_is_on_its_way():
    common = dict(goal=Q_GOAL, q=Q_START, enabled=True, followed_version=-1, planned=True, in_flight=False)
    assert goal_dropped(**common)
    assert not goal_dropped(**{**common, "enabled": False})               # stopped: wait for the recovery
    assert not goal_dropped(**{**common, "followed_version": 4})          # the scaler follows one of ours
    assert not goal_dropped(**{**common, "followed_version": None})       # no report yet
    assert not goal_dropped(**{**common, "planned": False})               # never planned: the loop's own goal
    assert not goal_dropped(**{**common, "in_flight": True})              # the newest may still be taken
    assert not goal_dropped(**{**common, "goal": None}) and not goal_dropped(**{**common, "q": None})
    assert not goal_dropped(**{**common, "q": Q_GOAL + AT_GOAL_WITHIN / 2})      # arrived: nothing left
    assert goal_dropped(**{**common, "q": Q_GOAL + 2 * AT_GOAL_WITHIN})


def test_the_planning_inputs_follow_what_the_scaler_reports_and_nothing_while_a_plan_is_on_its_way():
    """The one rule the planner service and the simulation share (``planning_inputs``): the followed
    trajectory where the scaler reports following it, not finished; nothing while a plan is in flight, while the
    scaler brings the robot to rest for a plan (pending) or at the trajectory's end; the robot's speed, beta,
    held and the wait from the report; a new version above every one handed and followed."""
    report = ScalerReport(version=OLD.version, s=0.5, speed=0.4, beta=True, held=True, awaiting=0.7)
    common = dict(goal=Q_GOAL, new_goal=False, q=Q_START, humans=None, human_sample=3, waited=0.2)
    got = planning_inputs(report=report, followed=OLD, in_flight=False, newest_version=OLD.version + 4, **common)
    assert got.following == (OLD, 0.5) and (got.speed, got.beta, got.held, got.stop_at) == (0.4, True, True, 0.7)
    assert got.version == OLD.version + 5 and got.waited == 0.2 and got.human_sample == 3
    assert planning_inputs(report=report, followed=OLD, in_flight=True, newest_version=0, **common).following is None
    assert planning_inputs(report=dataclasses.replace(report, pending=OLD.version + 1), followed=OLD,
                           in_flight=False, newest_version=0, **common).following is None
    assert planning_inputs(report=dataclasses.replace(report, s=OLD.duration), followed=OLD, in_flight=False,
                           newest_version=0, **common).following is None
    nothing = planning_inputs(report=None, followed=None, in_flight=False, newest_version=0, **common)
    assert nothing.following is None and nothing.speed is None and not nothing.beta and nothing.version == 1


# ------------------------------------------------------------------------------ the keep-or-replace rule
def _result(predicted: float) -> ReplanResult:
    return ReplanResult(OLD, 0.5, "beta", 0.0, predicted)


def test_a_replan_is_kept_only_when_predicted_faster_by_the_required_gain_and_says_both_times():
    kept = keep_or_replace(_result(3.0), 3.5, 0.10, 0.0, "replan request")
    assert kept.detail.endswith("predicted 3.00 s instead of 3.50 s") and kept.baseline == 3.5
    with pytest.raises(ReplanFailed, match=r"predicted 3.40 s, not 10 % faster than the old 3.50 s"):
        keep_or_replace(_result(3.4), 3.5, 0.10, 0.0, "replan request")


def test_a_fixed_saving_is_enough_once_the_predicted_wait_is_long():
    assert required_gain(2.0, 0.10, 0.25) == pytest.approx(0.10)            # short: 10 % (0.2 s) it is
    assert required_gain(5.0, 0.10, 0.25) == pytest.approx(0.05)            # long: 0.25 s is enough
    gain = required_gain(3.37, 0.10, 0.25)
    assert keep_or_replace(_result(3.10), 3.37, gain, 0.0, "replan request").predicted == 3.10
    with pytest.raises(ReplanFailed):
        keep_or_replace(_result(3.10), 3.37, 0.10, 0.0, "replan request")   # what min_gain alone refused


# ------------------------------------------------------------------------------ people standing still
def people(velocity: float, known: bool = True, count: int = 1) -> HumanCapsules:
    seg = np.tile([[[-0.8, 0.0, 0.9], [-0.8, 0.0, 1.5]]], (count, 1, 1))
    return HumanCapsules.from_arrays(seg, [0.2] * count, np.full((count, 2, 3), velocity / np.sqrt(3.0)),
                                     [known] * count)


def test_the_still_clock_counts_while_everyone_stands_and_starts_again_on_any_change():
    clock = StillClock(speed=0.1)
    for t in (0.0, 0.5, 1.0):
        clock.update(t, people(0.02))
    assert clock.waited(1.0) == pytest.approx(1.0 - 0.5)   # still from the second sample (the first sets the count)
    clock.update(1.5, people(0.5))                          # someone moves
    assert clock.waited(1.5) == 0.0
    for t, who in ((2.0, people(0.0)), (2.5, people(0.0)), (3.0, people(0.0, count=2))):
        clock.update(t, who)
    assert clock.waited(3.0) == 0.0                         # someone came in
    clock.update(3.5, people(0.0, count=2))
    clock.update(4.0, people(0.0, known=False, count=2))   # a velocity the tracker does not know
    assert clock.waited(4.0) == 0.0
    clock.update(4.5, None)
    assert clock.waited(4.5) == 0.0


def test_the_predictions_assume_standing_people_stay_at_least_as_long_as_they_have_stood():
    loop = PlanningLoop(RecordingReplanner(), still_speed=0.1)
    for k in range(30):                      # 3 s of a person standing in the cell
        loop.step(0.1 * k, inputs(humans=people(0.0), human_sample=k))
    loop.step(3.0, inputs(humans=people(0.0), human_sample=30, beta=True, waited=0.4))
    assert loop.replanner.waited == pytest.approx(2.9)      # stood 2.9 s, held only 0.4 s
    walker = PlanningLoop(RecordingReplanner(), still_speed=0.1)
    for k in range(30):
        walker.step(0.1 * k, inputs(humans=people(1.0), human_sample=k))
    walker.step(3.0, inputs(humans=people(1.0), human_sample=30, beta=True, waited=0.4))
    assert walker.replanner.waited == pytest.approx(0.4)


def test_the_predictions_assume_people_working_in_place_stay_at_least_as_long_as_they_have_been_there():
    """A person assembling at a table's edge moves their hands all the time: the still clock never counts, the
    dwell clock does (shared.planning.presence), so a way round them is taken sooner."""
    from tests.planning.test_presence import worker
    for dwell, expected in ((DWELL_RADIUS, 2.9), (None, 0.4)):
        loop = PlanningLoop(RecordingReplanner(), dwell_radius=dwell)
        for k in range(30):
            loop.step(0.1 * k, inputs(humans=worker(0.1 * k, shift=(-0.6, 0.0, 0.0)), human_sample=k))
        loop.step(3.0, inputs(humans=worker(3.0, shift=(-0.6, 0.0, 0.0)), human_sample=30, beta=True, waited=0.4))
        assert loop.replanner.calls[-1] == "beta"
        assert loop.replanner.waited == pytest.approx(expected)


def test_the_loop_idles_only_as_long_as_nobody_could_come_within_reach():
    assert idle_time(-0.1, 0.02) == 0.02 and idle_time(0.0, 0.02) == 0.02 and idle_time(float("nan"), 0.02) == 0.02
    assert idle_time(0.01, 0.02) == 0.02                              # never faster than the horizon period
    assert idle_time(0.2, 0.02) == pytest.approx(0.2 / APPROACH_SPEED)
    assert idle_time(5.0, 0.02) == IDLE_LONGEST and idle_time(float("inf"), 0.02) == IDLE_LONGEST


def test_the_planner_service_polls_every_period_only_while_someone_is_within_reach(replanner):
    shell, service = planner_given_a_goal(replanner, 3)
    keys = shell.keys
    far = HumanCapsules.from_arrays([[[-3.0, 0.0, 0.5], [-3.0, 0.0, 1.5]]], [0.2], np.zeros((1, 2, 3)), [True])
    near = HumanCapsules.from_arrays([[[-0.9, 0.0, 0.5], [-0.9, 0.0, 1.5]]], [0.2], np.zeros((1, 2, 3)), [True])
    assert reach_gap(replanner.collision, far) > 0 > reach_gap(replanner.collision, near)
    shell.deliver(keys.human_state, humans_to_msg(far, True, 1.5))
    service.work_once(1.5)
    assert service.pause() == IDLE_LONGEST                  # 3 m away: nobody within reach for a while
    shell.deliver(keys.human_state, humans_to_msg(near, True, 1.6))
    service.work_once(1.6)
    assert service.pause() == POLL                          # within reach: every horizon period
    shell.deliver(keys.human_state, humans_to_msg(far, True, 1.7))
    shell.deliver(keys.scaler_status, ScalerStatus(s=0.3, alpha=0.1, safe_alpha=0.1, beta=True, q_command=Q_START,
                                                   trajectory_version=3, status="running", method="piqp",
                                                   min_separation=None, min_margin=None, compute_us=50.0))
    service.work_once(1.7)
    assert service.pause() == POLL                          # a replan asked: every period whoever is where
    shell.deliver(keys.scaler_status, ScalerStatus(s=0.3, alpha=1.0, safe_alpha=1.0, beta=False, q_command=Q_START,
                                                   trajectory_version=3, status="running", method="presolved",
                                                   min_separation=None, min_margin=None, compute_us=50.0))
    service.work_once(1.8)
    assert service.pause() == IDLE_LONGEST
    service.loop.search_due = 3                             # a goal's search left for the way: due at the next turn
    assert service.pause() == POLL


def test_the_planner_refuses_a_missing_scene_file_saying_which(tmp_path, capsys):
    """No silent bare floor: a scene file that is not there stops the planner before it plans, naming it."""
    from services.planner import main

    missing = tmp_path / "no-such-scene.yaml"
    assert main(["--scene", str(missing), "--connect", "tcp/127.0.0.1:9"]) == 2
    err = capsys.readouterr().err
    assert str(missing) in err and "cannot read scene" in err


def test_a_new_goal_is_told_whether_the_forecast_of_the_people_has_held():
    """The loop keeps the forecast's record on every new human sample (ForecastTrust) and tells plan_goal: a steady
    walker seen for a span, trusted; the same walker just after stopping, not."""
    def walker(x: float, vx: float) -> HumanCapsules:
        return HumanCapsules.from_arrays([[[x, -2.0, 0.0], [x, -2.0, 1.7]]], [0.2], np.tile([vx, 0.0, 0.0], (1, 2, 1)),
                                         [True])

    replanner = RecordingReplanner()
    loop = PlanningLoop(replanner)
    k = 0
    for t in np.arange(0.0, 1.5, 1 / 30):
        k += 1
        loop.step(float(t), inputs(goal=None, human_sample=k, humans=walker(-3.0 + 1.2 * t, 1.2)))
    loop.step(1.5, inputs(new_goal=True, following=None, human_sample=k + 1, humans=walker(-3.0 + 1.8, 1.2)))
    assert replanner.trusted is True
    for t in np.arange(1.5 + 1 / 30, 1.8, 1 / 30):             # stopped where they got to
        k += 1
        loop.step(float(t), inputs(goal=None, human_sample=k, humans=walker(-1.2, 0.0)))
    loop.step(1.8, inputs(new_goal=True, following=None, human_sample=k + 1, humans=walker(-1.2, 0.0)))
    assert replanner.trusted is False
