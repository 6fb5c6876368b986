"""In-process simulation of both layers on a simulated clock: deterministic, no I/O.

The robot shuttles between two configurations; a scripted human (or a recorded motion, whose dropout
frames, None, stop the robot as missing data does in the cell) moves through the cell. Every control
period the scaling layer runs exactly as in the scaler service, and the planning layer, when given, takes
a turn of the planner service's own loop (shared.planning.loop: a new shuttle planned around the humans,
beta replans, the horizon check and merge) on what the scaler last reported; a new trajectory is taken by
the scaler's own rule (ScalingLayer.take). Every command is judged (CommandJudge) at the state it commands
by the independent monitor's rule, as the monitor service runs it (shared.safety.monitor's compiled
check_batch, tested against its coal reference: the ISO limit at the actual closest points, the
react-within-T_r-then-brake allowance), counting violations; `command_exceedances` counts,
stricter, every command the scaling layer chose (not one where it was braking at the drives' limit,
`braking_cycles`) whose conservative end-point bound exceeds the limit at all. The robot is taken to follow
its command exactly: the commands are followable by construction (the scaling layer slows down no faster
than the drives can brake), and the drive model itself comes with the CAN emulator. With charge_planning,
the planner's compute time (measured, or a fixed time per path search, which keeps runs repeatable) passes
on the simulated clock before its result is used (the robot keeps executing the old trajectory meanwhile,
and a new shuttle waits for its plan); without it, results are used in the cycle that asked for them.

The layers are given the people as the cell gives them (``sensed``): a recorded motion's newest frame, aged from
its capture, stale past the bound of the source's rate as the scaler service finds it, and with a `latency` (a
camera pipeline's, ``hrc demo --sim --latency``) each sample that much later; the judge checks every command
against the people of its moment, as the monitor pairs each joint state with the person captured then.

The speed policy is a parameter: the scaling layer (default), or any ScalingLayer subclass such as the
zone-based baseline (evidence.zones). Same core code as the services: ScalingLayer, PlanningLoop.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from evidence.scenarios import ScriptedHuman
from shared.config import CellConfig
from shared.core.trajectory import Trajectory, straight_line_trajectory
from shared.planning.decision import HoldClock
from shared.planning.inputs import planning_inputs
from shared.planning.loop import PlanningLoop, PlanningOutcome
from shared.planning.replanner import Replanner
from shared.robot.model import RobotModel
from shared.robot.poses import leg_fraction
from shared.safety.monitor import MonitorResult, ReactionWindow, SafetyMonitor
from shared.safety.ssm import pair_ssm
from shared.scaling.layer import ScalingInputs, ScalingLayer, ScalingStep, StepStatus
from shared.scaling.report import ScalerReport
from shared.tracking.tracker import mean_age, stale_bound

START_TOLERANCE = 1e-3   # rad: the simulated robot is exactly on its path (the scaler allows 0.02 for the drives)


@dataclass(frozen=True)
class Sensed:
    """The people as the layers are given them at a moment: humans (None: no sample yet, or the tracker's
    dropout), their age from the capture of the newest sample (s), the source's sample interval (s; 0: a
    scripted person, a state at every moment) and the samples' way from capture to the cell (s, the latency)."""

    humans: object
    age: float
    interval: float
    delay: float = 0.0

    @property
    def planned_age(self) -> float:
        """The age the planning layer counts (s): the scaler's on average, ``mean_age``."""
        return mean_age(self.delay, self.interval)


def sensed(human, t: float, latency: float = 0.0) -> Sensed:
    """What the layers have of `human` at t (s) when each sample reaches the cell `latency` s after its capture
    (``HumanFeed(latency=)`` on the processes): the state of t - latency, aged from its capture. A recorded
    motion (``TrackedMotion``) gives its newest frame, so its age grows between frames as the scaler finds it; a
    scripted person is captured at every moment. Before the first sample has come: nobody, infinitely old. A
    window into a longer recording (``RecordingWindow``) has the samples from before its start, as a cell's feed
    has been running before a run starts (else, 30 ms late, each window began unseen, and its first goal, planned
    once the people came, was merged into the stand-in the robot stood on: 19 % of the table's edge lost, not to
    the latency; ``run_shuttle``'s ``standing``)."""
    then = t - latency
    captured = getattr(human, "captured", None)
    taken, interval = captured(then) if captured is not None else (then, 0.0)
    if then < 0.0 and (captured is None or taken == -math.inf):     # before the run's, or a recording's, first sample
        return Sensed(None, float("inf"), 0.0, latency)
    return Sensed(human.at(then), t - taken, interval, latency)


@dataclass
class SimRecord:
    """One control cycle as it happened."""

    t: float
    phase: str
    step: ScalingStep
    shuttles: int
    approach_margin: float       # min over pairs of max(limit, 0) - approach speed at the commanded motion (m/s)


@dataclass
class ReplanEvent:
    t: float
    reason: str                  # the loop's action: 'horizon', 'beta', 'slow', 'search' or 'goal'
    ok: bool
    compute_ms: float
    detail: str = ""


@dataclass
class SimResult:
    records: list[SimRecord] = field(default_factory=list)
    replans: list[ReplanEvent] = field(default_factory=list)
    goals: list[ReplanEvent] = field(default_factory=list)   # each new goal's plan, taken (reason 'goal', its detail)
    shuttles: int = 0
    violations: int = 0
    command_exceedances: int = 0
    braking_cycles: int = 0
    beta_requests: int = 0
    progress: float = 0.0        # shuttles completed plus the fraction of the current leg covered
    stale_cycles: int = 0        # cycles the scaling layer found the people's data stale (older than its bound)
    latency: float = 0.0         # s: from each sample's capture to the cell (run_shuttle's latency)
    sample_interval: float = 0.0  # s: the source's sample interval as last measured (0: a scripted person)
    reaction_time: float = 0.0   # s: the configured T_r
    period: float = 0.0          # s: the control period

    def leg_ends(self) -> list[float]:
        """When (s) each leg of the shuttle ended: the first record that counts it."""
        ends, done = [], 0
        for record in self.records:
            if record.shuttles > done:
                ends += [record.t] * (record.shuttles - done)
                done = record.shuttles
        return ends

    def summary(self) -> dict:
        steps = [r.step for r in self.records]
        compute = np.array([s.compute_us for s in steps]) if steps else np.zeros(1)
        alpha = np.array([s.alpha for s in steps]) if steps else np.zeros(1)
        margins = [r.approach_margin for r in self.records if np.isfinite(r.approach_margin)]
        seps = [s.min_separation for s in steps if np.isfinite(s.min_separation)]
        duration = self.records[-1].t if self.records else 0.0
        done = [e for e in self.replans if e.ok]
        return {
            "duration_s": round(duration, 3),
            "cycles": len(steps),
            "shuttles_completed": self.shuttles,
            "shuttles_per_min": round(60.0 * self.shuttles / duration, 2) if duration else 0.0,
            "shuttle_progress": round(self.progress, 4),
            "mean_alpha": round(float(alpha.mean()), 4),
            "stopped_fraction": round(float(np.mean(alpha < 1e-6)), 4),
            # the share of cycles the robot moved below full speed (the SSM, a ramp or braking), not stopped
            "slowed_fraction": round(float(np.mean((alpha >= 1e-6) & (alpha < 1.0 - 1e-6))), 4),
            "beta_requests": self.beta_requests,
            "replans": [{"t": round(e.t, 2), "reason": e.reason, "compute_ms": round(e.compute_ms, 1),
                         "detail": e.detail} for e in done],
            "replans_failed": len(self.replans) - len(done),
            "min_separation_m": round(min(seps), 4) if seps else None,
            "min_margin_m_s": round(min(margins), 4) if margins else None,
            "violations": self.violations,
            "command_exceedances": self.command_exceedances,
            "braking_cycles": self.braking_cycles,
            "compute_us": {"p50": round(float(np.percentile(compute, 50)), 1),
                           "p99": round(float(np.percentile(compute, 99)), 1)},
            **self.reaction_figures(),
        }

    def reaction_figures(self) -> dict:
        """The people's data as the processes' report gives it (docs/report-format.md): the share of cycles it was
        stale, a sample's way from its capture to the tracker's state (the latency) and to the command made on it
        (that and at most a control period: the simulated drives follow each command at once, no drive lag), the
        source's interval, the part T_r covers (from the tick to the command's taking effect: a control period) and
        whether T_r covers it: the same test as ``reaction_time_covers_p99``."""
        cycles = len(self.records)
        chain = 1e3 * (self.latency + self.period)
        own = round(1e3 * self.period, 1)
        return {"tracker": {"stale_share": round(self.stale_cycles / cycles, 4) if cycles else None,
                            "capture_to_state_ms": {"p50": round(1e3 * self.latency, 1),
                                                    "p99": round(1e3 * self.latency, 1)},
                            "sample_interval_ms": round(1e3 * self.sample_interval, 2)},
                "latency": {"sample_to_frame_ms": {"p50": round(chain, 1), "p99": round(chain, 1)},
                            "tick_to_frame_ms": {"p50": own, "p99": own}},
                "reaction_time_s": self.reaction_time,
                "reaction_time_covers_p99": self.period <= self.reaction_time + 1e-9}


Veto = Callable[[int, ReplanEvent], bool]     # run_shuttle's veto: (the n-th replan meant, its event) -> drop it
# run_shuttle's goal_leg: (the n-th new goal's leg from rest, its event, the planner's leg) -> another leg, or None
GoalLeg = Callable[[int, ReplanEvent, Trajectory], "Trajectory | None"]


class CommandJudge:
    """The judging half of a run: every commanded state against the ISO limit. The conservative end-point
    bound first (fast); where it comes near, the independent monitor's rule (shared.safety.monitor's
    check_batch, the monitor service's own check: 4 times faster here than its coal reference ``check``,
    which it is tested against; with its ReactionWindow seeing every cycle) counts violations; a command
    beyond the bound that the scaling layer chose (not braking at the drives' limit) counts as a command
    exceedance."""

    def __init__(self, robot: RobotModel, config: CellConfig, monitor: SafetyMonitor | None = None) -> None:
        self.robot, self.ssm = robot, config.ssm
        self.monitor = monitor or SafetyMonitor(robot, config.ssm)
        self.window = ReactionWindow(config.ssm.reaction_time, config.ssm.stopping_time)

    def judge(self, t: float, step: ScalingStep, humans, result: SimResult) -> float:
        """Count this cycle's command into result; returns its smallest approach margin (m/s; inf when there
        is nobody to judge against, a tracker dropout in a recorded motion)."""
        margin = float("inf")
        if humans is not None:
            points, velocities = self.robot.capsule_motion(step.q_command, step.qd_command)
            check = pair_ssm(points, self.robot.radii, velocities, humans, self.ssm,
                             self.ssm.stop_of(step.qd_command, self.robot.limits.velocity))
            margin = float(check.margin.min()) if check.margin.size else margin
        braking = step.method.endswith("+braking")
        result.braking_cycles += braking
        if margin < -1e-9 and not braking:
            result.command_exceedances += 1
        judged = self.monitor.check_batch(step.q_command[None], step.qd_command[None], [humans])[0] \
            if margin < 0.02 else MonitorResult()
        result.violations += len(self.window.update(t, judged))
        return margin


def run_shuttle(robot: RobotModel, config: CellConfig, human: ScriptedHuman, q_a: np.ndarray, q_b: np.ndarray,
                duration: float, on_record=None, replanner: Replanner | None = None, beta_replans: bool = True,
                beta_cooldown: float = 0.5, on_replan=None, layer: ScalingLayer | None = None,
                charge_planning: bool | float = False, monitor: SafetyMonitor | None = None,
                leg_path=None, veto: Veto | None = None, goal_leg: GoalLeg | None = None,
                latency: float = 0.0) -> SimResult:
    """Shuttle between q_a and q_b for `duration` simulated seconds next to a scripted human.

    replanner: the planning layer (None: scaling only, straight shuttles), run by the planner service's
    own loop (shared.planning.loop.PlanningLoop) once a cycle, before the scaling step, on what the
    scaler last reported. beta_replans: answer the scaling layer's replan requests (the paper's ablation
    switches this off). on_record / on_replan: called with each SimRecord / ReplanEvent as it happens.
    layer: the speed policy (default: a new ScalingLayer). charge_planning: planning takes time on the
    simulated clock: True its measured wall time, a number that many seconds per path search (repeatable
    whatever the machine's load). monitor: the judge's monitor (default: a SafetyMonitor of this robot;
    pass one to reuse it across runs). leg_path(start, goal, version) -> Trajectory: the fixed path of each leg where
    no planning layer plans it (default: the straight line, rest to rest). veto(n, event) -> bool: the planning
    layer's n-th replan it means to take (1, 2, ...: every action but a goal's plan, in the order they come; event:
    when, which action as its reason, its detail) is dropped where it says True, logged as refused ("vetoed:
    ..."), and the robot keeps what it follows: the run without that one decision (``bench/decision_value.py``;
    the simulation is deterministic, so the runs agree until then). goal_leg(n, event, leg) -> Trajectory | None:
    the n-th new goal's leg from rest the planning layer chose (1, 2, ...) is replaced by the trajectory it
    returns (the same version, from the same start to the same goal: the fold, the line), the goal's detail
    prefixed "replaced: "; everything after it is decided again, the goal's search on the way among it.
    latency (s): each people sample reaches both layers that long after its capture (``sensed``); the judge
    checks against the people of each moment."""
    layer = layer or ScalingLayer(robot, config.ssm, config.scaling)
    if replanner is None or not beta_replans:
        layer.params = replace(layer.params, await_plan=0.0)   # nobody answers a replan request: never await one
    judge = CommandJudge(robot, config, monitor)
    loop = PlanningLoop(replanner, beta_cooldown=beta_cooldown, beta_replans=beta_replans) \
        if replanner is not None else None
    period = config.scaling.period
    lim = robot.limits
    ends = [np.asarray(q_a, dtype=float), np.asarray(q_b, dtype=float)]
    result = SimResult(latency=latency, reaction_time=config.ssm.reaction_time, period=period)
    leg = 0
    if leg_path is None:
        def leg_path(start, goal, version):
            return straight_line_trajectory(start, goal, lim.velocity, lim.acceleration, version=version)
    # with a planning layer the first leg is its plan too, as in the cell (until it comes, the robot stands at
    # its start: a trajectory of one knot period that stays there; a plan made with no search charged, the
    # goal's default shape, is ready at t = 0, as the fixed path is); without one, the fixed path's
    first = leg_path(ends[0], ends[1], 0) if loop is None else \
        straight_line_trajectory(ends[0], ends[0], lim.velocity, lim.acceleration)
    layer.set_trajectory(first)
    handed = {first.version: first}   # the trajectories handed to the scaling layer, by version (the service's too)
    # the stand-in before the first plan is none of the planner's (the scaler service holds the measured position,
    # version -1, until one comes): a first goal planned after it (the people late at the start) is planned from
    # rest, as on the processes, not merged into it (which took the line without the fold or the search)
    standing = first.version if loop is not None else None
    in_flight = False                 # one was handed since the last step: not reported on yet
    report: ScalerReport | None = None   # what the planning layer reads of the last step (the service: its status)
    q_now = ends[0]                   # where the robot is: the last command (the simulated drives follow exactly)
    held = HoldClock()                # how long the scaling layer has been asking for a replan
    pending_leg = loop is not None    # a shuttle ended (or the run began): the next one waits for its plan
    busy_until = -1.0                 # charge_planning: the planner is computing until then
    waiting: tuple | None = None      # (ready at, PlanningOutcome, compute ms)
    replans_meant = 0                 # the replans the planning layer meant to take so far (veto's count)
    goals_meant = 0                   # the new goals' legs from rest it chose so far (goal_leg's count)

    def log_replan(event: ReplanEvent) -> None:
        result.replans.append(event)
        if on_replan is not None:
            on_replan(event)

    def take(t: float, outcome: PlanningOutcome, elapsed: float) -> None:
        nonlocal pending_leg, in_flight
        res = outcome.result
        handed[res.trajectory.version], in_flight = res.trajectory, True
        for old in [v for v in handed if v < res.trajectory.version - 8]:
            del handed[old]
        why = layer.take(res.trajectory, res.from_rest, res.junction, q_now, START_TOLERANCE)
        if why is not None:           # the scaler service logs it too ("trajectory N not taken: ...")
            log_replan(ReplanEvent(t, outcome.action, False, elapsed, f"not taken by the scaling layer: {why}"))
        elif outcome.action == "goal":
            pending_leg = False
            result.goals.append(ReplanEvent(t, "goal", True, elapsed, res.detail))
        else:
            log_replan(ReplanEvent(t, outcome.action, True, elapsed, res.detail))

    def planning_turn(t: float, k: int, humans, delay: float = 0.0) -> None:
        """One turn of the planner's loop on what the scaler last reported; its result is taken at once, or
        when its charged time has passed."""
        nonlocal busy_until, waiting, replans_meant, goals_meant
        inputs = planning_inputs(goal=ends[(leg + 1) % 2], new_goal=pending_leg, q=q_now, humans=humans,
                                 human_sample=k, report=report,
                                 followed=None if report is None or report.version == standing
                                 else handed.get(report.version),
                                 in_flight=in_flight, waited=held.waited(t), newest_version=max(handed),
                                 then=ends[leg % 2], human_delay=delay)   # then: the shuttle's next goal, back
        started = time.perf_counter()
        outcome = loop.step(t, inputs)
        elapsed = time.perf_counter() - started
        if outcome is None:
            return
        if charge_planning:
            busy_until = t + (elapsed if charge_planning is True else outcome.searches * float(charge_planning))
        if outcome.action == "prepare":           # the next leg's plan, kept by the loop: nothing to take now
            return
        if outcome.result is not None and outcome.action != "goal" and veto is not None:
            replans_meant += 1
            if veto(replans_meant, ReplanEvent(t, outcome.action, True, elapsed * 1e3, outcome.result.detail)):
                log_replan(ReplanEvent(t, outcome.action, False, elapsed * 1e3, f"vetoed: {outcome.result.detail}"))
                return
        if outcome.result is not None and outcome.action == "goal" and outcome.result.from_rest \
                and goal_leg is not None:
            goals_meant += 1
            chosen = outcome.result
            other = goal_leg(goals_meant, ReplanEvent(t, "goal", True, elapsed * 1e3, chosen.detail), chosen.trajectory)
            if other is not None:
                outcome = replace(outcome, result=replace(chosen, trajectory=other, detail=f"replaced: {chosen.detail}"))
        if outcome.result is None:
            log_replan(ReplanEvent(t, outcome.action, False, elapsed * 1e3, outcome.refused or ""))
        elif charge_planning:
            waiting = (busy_until, outcome, elapsed * 1e3)
        else:
            take(t, outcome, elapsed * 1e3)

    def take_ready(t: float) -> None:
        """A charged result whose time has passed, taken now."""
        nonlocal waiting
        if waiting is not None and t >= waiting[0]:
            _, outcome, elapsed = waiting
            waiting = None
            take(t, outcome, elapsed)

    if loop is not None:      # the first leg planned before the clock starts, as the fixed path's is made
        first = sensed(human, 0.0, latency)
        planning_turn(0.0, 0, first.humans, first.planned_age)
        take_ready(0.0)       # planned with no search charged: ready at the start
    for k in range(int(round(duration / period))):
        t = k * period
        given = sensed(human, t, latency)          # the layers' people
        humans = human.at(t) if latency else given.humans      # the people of this moment, the judge's
        stale_after = stale_bound(layer.params.human_timeout, given.interval)
        result.sample_interval = given.interval or result.sample_interval
        take_ready(t)
        if loop is not None and t >= busy_until:
            planning_turn(t, k, given.humans, given.planned_age)
        step = layer.step(ScalingInputs(humans=given.humans, human_age=given.age, stale_after=stale_after))
        result.stale_cycles += step.status is StepStatus.STALE_HUMAN_DATA     # as the report counts the scaler's
        if step.beta and not (report is not None and report.beta):
            result.beta_requests += 1
        report, in_flight, q_now = ScalerReport.of_step(step), False, step.q_command
        held.update(t, step.beta)
        margin = judge.judge(t, step, humans, result)
        if step.status is StepStatus.FINISHED and not pending_leg:
            result.shuttles += 1
            leg += 1
            start, goal = ends[leg % 2], ends[(leg + 1) % 2]
            if loop is None:
                layer.set_trajectory(leg_path(start, goal, step.trajectory_version + 1))
            else:
                pending_leg = True          # a new goal: the planner takes a turn on it at once (when free)
                if t >= busy_until:
                    planning_turn(t, k, given.humans, given.planned_age)
        result.progress = result.shuttles + leg_fraction(step.q_command, ends[leg % 2], ends[(leg + 1) % 2])
        record = SimRecord(t, human.phase(t), step, result.shuttles, margin)
        result.records.append(record)
        if on_record is not None:
            on_record(record)
    return result
