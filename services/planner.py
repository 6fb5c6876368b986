"""planner: the planning layer as a service (a thin shell around shared.planning.loop.PlanningLoop).

Inputs (the latest of each is kept): goals, human states, joint states, scaler status (the last three
kept by Zenoh in rings of one and taken each turn: no Python runs per message). A worker thread (OMPL holds
the GIL: planning never runs in a latency-critical process) takes a turn every 20 ms while someone is within
reach of a path or a replan is asked, up to 0.2 s apart while nobody could come within reach sooner
(``shared.planning.loop.idle_time``), and at once on a new goal: one turn of the planning loop, the same loop
the simulation runs (a new goal first, then a replan request, then the horizon check on a new human
sample, then, where the goal names the goals after it, the next leg's plan prepared before the robot
arrives; see shared.planning.loop), telling it how long the scaler has been asking for a replan (HoldClock)
and how fast the robot moves. Every published trajectory and
every refusal is reported as an event on <prefix>/safety/events (source planner, severity info): why, and
how long it took. The service bounds every path search by the wall clock (CELL_BUDGET), and every planning
action as a whole (ACTION_BUDGET: the searches stop in time for the rest of the action; anytime: the best path
found by then is used).

    python -m services.planner --connect tcp/127.0.0.1:7447 [--scene deploy/scene.yaml] [--seed 1]
"""

from __future__ import annotations

import dataclasses
import sys
import threading
import time
from pathlib import Path

import numpy as np

from services.common import ServiceShell, open_service, serve, service_parser, setup_logging
from shared.core.errors import HrcError
from shared.core.trajectory import Trajectory
from shared.planning.collision import CollisionModel
from shared.planning.decision import HoldClock
from shared.planning.horizon import reach_gap
from shared.planning.inputs import goal_dropped, planning_inputs
from shared.planning.loop import PlanningLoop, idle_time, warm_up
from shared.planning.ompl_planner import JointPlanner, PlannerOptions
from shared.planning.path_search import ACTION_BUDGET, CELL_BUDGET, SearchOptions
from shared.planning.replanner import Replanner, ReplanOptions
from shared.planning.scene import DEFAULT_SCENE, load_scene
from shared.robot.model import default_robot
from shared.tracking.tracker import mean_age
from shared.transport.zenoh_session import warm_up_transport
from shared.wire.convert import capture_delay, humans_from_msg, report_from_status, trajectory_to_msg
from shared.wire.messages import Goal, HumanState, JointState, SafetyEvent, ScalerStatus, encode

TAKE_WAIT = 1.0      # s: a trajectory the scaler has not reported on by then was lost on the way (or the scaler restarted)
POLL = 0.02          # s: the worker's cadence (the planning loop's horizon period); a goal wakes it at once


def unique_version(traj: Trajectory, newest: Trajectory | None, highest_seen: int) -> Trajectory:
    """`traj`, renumbered above `newest` (the last one published; None: none yet) and `highest_seen` (the highest
    version the scaler reported) where it is not already: every trajectory the scaler is handed has a number of its
    own.

    Why: a replan is numbered the followed trajectory's version + 1. Where the scaler refused one (its start a
    millimetre off where the robot stands, under load) and the planner answered the next request on the same
    followed trajectory, the next was numbered the same: the scaler's ``received`` said the new one decided on
    before it arrived, so the planner planned on again while it was on its way, and where the scaler took one of
    two equal numbers and ignored the other (not above the followed), the planner took the other for the followed:
    its next merge, built on a path the robot was not on, passed the scaler's check of the base version (the paper's
    demo on the processes, loaded: four plans numbered 7 in 1.5 s, docs/measurements.md, session 87)."""
    floor = max(highest_seen, -1 if newest is None else newest.version)
    return traj if traj.version > floor else dataclasses.replace(traj, version=floor + 1)


class PlannerService:
    """The shell around the planning loop: inputs from Zenoh kept under a lock, a worker thread that takes
    the loop's turns, trajectories and events out."""

    def __init__(self, shell: ServiceShell, loop: PlanningLoop) -> None:
        self.shell, self.loop = shell, loop
        self.lock = threading.Lock()
        self.wake = threading.Event()
        self.goal: Goal | None = None
        self.new_goal = False
        self.humans = None
        self.human_seq = -1
        self.human_delay = 0.0             # s: the newest people's age as the scaler counts it on average (mean_age)
        self.q = None
        self.enabled = False               # the driver follows commands (the newest joint state says so)
        self.status: ScalerStatus | None = None
        self.highest_seen = 0              # the highest trajectory version the scaler reported following
        self.held = HoldClock()            # how long the scaler has been asking for a replan (s)
        self.trajectory: Trajectory | None = None       # the newest published
        self.published: dict[int, Trajectory] = {}      # the last few, by version: the scaler may still follow one
        self.published_at = -float("inf")
        self.planned_goal: int | None = None             # the goal the newest published trajectory was for
        self.resumed_at = -float("inf")
        self.goal_id = 0
        self.seq = 0
        self.traj_pub = shell.session.declare_publisher(shell.keys.trajectory)
        self.event_pub = shell.session.declare_publisher(shell.keys.safety_events)
        shell.subscribe(shell.keys.goal, Goal, self.on_goal)
        # the 100 Hz inputs are read at the loop's own cadence (POLL): only the newest of each matters, and a
        # callback for each of 300 messages a second kept an idle planner at 12 % of a core
        self.humans_in = shell.latest(shell.keys.human_state, HumanState)
        self.joints_in = shell.latest(shell.keys.joint_state, JointState)
        self.status_in = shell.latest(shell.keys.scaler_status, ScalerStatus)

    # ------------------------------------------------------------------------------------- inputs
    def on_goal(self, msg: Goal) -> None:
        with self.lock:
            self.goal, self.new_goal = msg, True
        self.wake.set()

    def poll(self, now: float) -> None:
        """Take the newest people, joints and scaler status (the worker's thread, each turn)."""
        humans, joints, status = self.humans_in.take(), self.joints_in.take(), self.status_in.take()
        with self.lock:
            if humans is not None:   # counted here: the horizon check must not depend on the sender's numbering
                self.humans, self.human_seq = humans_from_msg(humans), self.human_seq + 1
                self.human_delay = mean_age(capture_delay(humans), humans.sample_interval)
            if joints is not None:
                self.q, self.enabled = np.asarray(joints.q), joints.enabled
            if status is not None:
                self.status = status
                self.held.update(now, status.beta)
                self.highest_seen = max(self.highest_seen, status.trajectory_version)

    # ------------------------------------------------------------------------------------- outputs
    def _event(self, event: str, text: str, ms: float | None = None) -> None:
        """An event on <prefix>/safety/events; value: the planning time in ms, where there was one."""
        self.seq += 1
        self.event_pub.put(encode(SafetyEvent(source="planner", event=event, severity="info", text=text, value=ms,
                                              seq=self.seq, stamp=time.monotonic())))
        self.shell.log.info("%s: %s", event, text)

    def _publish(self, now: float, traj: Trajectory, reason: str, junction: float, base_version: int, ms: float,
                 detail: str = "") -> None:
        """Publish a trajectory, numbered above every one published before and every one the scaler reported
        (``unique_version``)."""
        traj = unique_version(traj, self.trajectory, self.highest_seen)
        self.trajectory, self.planned_goal = traj, self.goal_id
        self.published = {v: t for v, t in self.published.items() if v >= traj.version - 8}
        self.published[traj.version], self.published_at = traj, now
        self.seq += 1
        self.traj_pub.put(encode(trajectory_to_msg(traj, self.goal_id, reason, junction, base_version,
                                                   seq=self.seq, stamp=time.monotonic())))
        self._event(f"trajectory_{reason}", f"version {traj.version} in {ms:.0f} ms, junction s={junction:.2f}; {detail}",
                    ms)

    # ------------------------------------------------------------------------------------- work
    def _in_flight(self, now: float) -> bool:
        """The newest published trajectory is on its way: the scaler's status has not yet reported deciding on it
        (``ScalerStatus.received``), for at most TAKE_WAIT (a message lost, or a scaler restarted, is not waited
        for forever)."""
        st = self.status
        return (self.trajectory is not None and (st is None or st.received < self.trajectory.version)
                and now < self.published_at + TAKE_WAIT)

    def _dropped(self, now: float) -> bool:
        """The goal's plan was dropped while the robot was stopped and it runs again short of the goal
        (``goal_dropped``); at most once per TAKE_WAIT, so a plan dropped again is not asked for at every turn."""
        goal = self.goal
        return (goal is not None and not self.new_goal and now >= self.resumed_at + TAKE_WAIT
                and goal_dropped(goal=goal.q, q=self.q, enabled=self.enabled,
                                 followed_version=None if self.status is None else self.status.trajectory_version,
                                 planned=self.planned_goal == goal.goal_id, in_flight=self._in_flight(now)))

    def work_once(self, now: float) -> None:
        """One turn of the planning loop on the latest inputs; its outcome published (a trajectory, or an
        event saying why there is none)."""
        self.poll(now)
        with self.lock:
            if self._dropped(now):
                self.new_goal, self.resumed_at = True, now
                self._event("goal_resumed", f"goal {self.goal.goal_id} planned again from where the robot stands: "
                                            "its plan was dropped while the robot was stopped")
            goal, new_goal, humans, q, status = self.goal, self.new_goal, self.humans, self.q, self.status
            if goal is None:
                return
            report = None if status is None else report_from_status(status)
            # above every version the scaler has reported: a restarted planner must not publish an old number
            newest = max(self.trajectory.version if self.trajectory is not None else 0, self.highest_seen)
            inputs = planning_inputs(goal=goal.q, new_goal=new_goal, q=q, humans=humans, human_sample=self.human_seq,
                                     report=report, followed=None if report is None else self.published.get(report.version),
                                     in_flight=self._in_flight(now), waited=self.held.waited(now),
                                     newest_version=newest, then=goal.then[0] if len(goal.then) else None,
                                     human_delay=self.human_delay)
            if not self.loop.ready(inputs):      # a goal is kept until the robot's position and the people are known
                return
            self.new_goal = False
        if new_goal:
            self.goal_id = goal.goal_id
        started = time.perf_counter()
        outcome = self.loop.step(now, inputs)
        if outcome is None:
            return
        ms = (time.perf_counter() - started) * 1e3
        if outcome.action == "prepare":        # the next leg's plan, kept by the loop until its goal comes
            if outcome.prepared is not None:
                self._event("next_goal_prepared", f"for goal {goal.goal_id}: {outcome.prepared.duration:.2f} s "
                                                  f"nominal, kept for the goal after it", ms)
            else:
                self._event("prepare_refused", f"for goal {goal.goal_id}: {outcome.refused}"[:500], ms)
            return
        if outcome.result is None:
            what = f"goal {goal.goal_id}" if outcome.action == "goal" else outcome.action
            self._event("plan_refused" if outcome.action == "goal" else "replan_refused",
                        f"{what}: {outcome.refused}"[:500], ms)
            return
        result = outcome.result
        if result.from_rest:
            self._publish(now, result.trajectory, result.reason, 0.0, -1, ms, result.detail)
        else:
            self._publish(now, result.trajectory, result.reason, result.junction, inputs.following[0].version, ms,
                          result.detail)

    def pause(self) -> float:
        """How long the worker may wait for its next turn (``idle_time``): a turn every POLL while someone is
        within reach of any path, a replan is asked, a goal's search is left for the way, or a goal waits for the
        robot's position or the people; up to IDLE_LONGEST while the nearest person could not come within reach
        before then."""
        with self.lock:
            humans, status, new_goal = self.humans, self.status, self.new_goal
            waiting = self.goal is not None and (self.q is None or humans is None)
        if waiting or new_goal or (status is not None and status.beta) or self.loop.search_due is not None:
            return POLL
        return idle_time(reach_gap(self.loop.replanner.collision, humans), POLL)

    def run(self, stop: threading.Event) -> None:
        while not stop.is_set():
            self.wake.wait(self.pause())
            self.wake.clear()
            self.work_once(time.monotonic())


def main(argv: list[str] | None = None) -> int:
    parser = service_parser("planner", __doc__)
    parser.add_argument("--scene", type=Path, default=None, help="static cell (default deploy/scene.yaml)")
    parser.add_argument("--seed", type=int, default=None, help="seed of OMPL's sampling (default: random)")
    parser.add_argument("--no-beta", action="store_true",
                        help="ignore the scaling layer's replan requests (the paper's ablation)")
    args = parser.parse_args(argv)
    setup_logging(args.log_level)
    try:
        scene = load_scene(args.scene or DEFAULT_SCENE)      # a missing file is refused, saying which
    except HrcError as exc:
        print(f"planner: error: {exc}", file=sys.stderr)
        return 2
    opened = open_service("planner", args)
    if opened is None:
        return 2
    config, shell = opened
    collision = CollisionModel(default_robot(), scene, config.ssm.min_separation)
    # the wall clock bounds every search (anytime: the best path found by then is used); the simulation
    # bounds it by counts instead, for repeatable evidence
    options = ReplanOptions(seed=args.seed or 0, search=SearchOptions(time_budget=CELL_BUDGET),
                            action_budget=ACTION_BUDGET, **config.planning.replan_fields())
    replanner = Replanner(collision, JointPlanner(collision, PlannerOptions(seed=args.seed)), config.ssm,
                          options=options, scaling=config.scaling)
    warm_up(replanner)               # every kind of action once: no kernel is loaded when it counts
    warm_up_transport()              # Zenoh's one slow large message of a process: not the second trajectory's
    service = PlannerService(shell, PlanningLoop(replanner, beta_replans=not args.no_beta))
    return serve(shell, f"planner: SSM-aware path search, scene with {len(scene.names)} obstacles, "
                        f"keys {shell.keys.prefix}/",
                 service.run, on_stop=service.wake.set)

if __name__ == "__main__":
    sys.exit(main())
