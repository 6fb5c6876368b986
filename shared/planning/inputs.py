"""What the planning layer knows at one moment (``PlanningInputs``), and the one rule that builds it from what the
scaling layer last reported (``planning_inputs``): the planner service (from the scaler's status over Zenoh) and
the simulation (from the step in its own process) call the same function, so the evidence measures the planning
layer on the cell's own inputs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from shared.core.humans import HumanCapsules
from shared.core.trajectory import Trajectory
from shared.scaling.report import ScalerReport

FINISHED_WITHIN = 1e-6     # s of path parameter: a trajectory followed to within this of its end is finished
AT_GOAL_WITHIN = 0.01      # rad, every joint: a robot this near its goal has arrived (nothing is left to plan for)


@dataclass(frozen=True, kw_only=True)
class PlanningInputs:
    """What the planning layer knows at one moment.

    goal: the goal configuration (rad; None: none yet). new_goal: it has not been planned for yet.
    q: where the robot is (rad; None: not known yet). humans: the latest human state (None: none).
    human_sample: a counter of human samples (a new value is a new sample). following: the trajectory the
    scaler follows and its path parameter s, None when it follows none of ours or has finished it.
    speed: the robot's joint speed (rad/s, max over joints; None: unknown). beta: the scaler asks for a
    replan. waited: how long it has been asking (s, HoldClock). version: the number a new trajectory from
    rest gets (above every version the scaler has followed). held: the robot's speed is the SSM's bound
    (``shared.scaling.layer.held_by_ssm``). stop_at: the s of the followed trajectory where the scaler has brought
    (or brings) the robot to rest to await the plan it asked for (``ScalingStep.awaiting``; None: it does not
    wait). then: the goal that follows this one (rad; None: not known), whose plan the loop prepares before the
    robot arrives. human_delay: the people's data's age as the scaler counts it on average (s; ``mean_age``,
    ``Replanner.take_delay``)."""

    goal: np.ndarray | None
    new_goal: bool
    q: np.ndarray | None
    humans: HumanCapsules | None
    human_sample: int
    following: tuple[Trajectory, float] | None
    speed: float | None
    beta: bool
    waited: float
    version: int
    held: bool = False
    stop_at: float | None = None
    then: np.ndarray | None = None
    human_delay: float = 0.0

    @property
    def kept_slow(self) -> bool:
        """The SSM keeps the robot's speed down: its speed is the SSM's bound (held), or the bound is below
        alpha_min (beta, the replan request, until it is back above alpha_release). Not a ramp back to speed:
        beside a person the bound and the robot's speed chatter with the data's age (the bound 0 at a frame's
        end, where the robot brakes and is held; about 0.2 on a fresh frame, where it speeds up and is not), and
        ``held`` alone, true one cycle in three, took a robot at 3 % of its nominal speed for one moving near it
        (real_table_edge seed 6, 30 ms late: merges offered for 8 s, never a plan from rest)."""
        return self.held or self.beta


def planning_inputs(*, goal: np.ndarray | None, new_goal: bool, q: np.ndarray | None, humans: HumanCapsules | None,
                    human_sample: int, report: ScalerReport | None, followed: Trajectory | None, in_flight: bool,
                    waited: float, newest_version: int, then: np.ndarray | None = None,
                    human_delay: float = 0.0) -> PlanningInputs:
    """PlanningInputs from the scaling layer's last report. followed: the trajectory of the report's version (None:
    not one of the planner's); in_flight: a trajectory handed to the scaling layer has not been reported on yet
    (nothing is followed meanwhile: the planner would plan on a path about to be replaced); newest_version: the
    highest version handed to the scaling layer (a new one is numbered above it and above the followed one).

    Nothing is followed while none is reported, a handed one is in flight, the scaler is bringing the robot to rest
    for a plan (``ScalerReport.pending``), or the followed trajectory is finished."""
    following = None
    if report is not None and followed is not None and not in_flight and report.pending is None \
            and report.s < followed.duration - FINISHED_WITHIN:
        following = (followed, report.s)
    return PlanningInputs(goal=goal, new_goal=new_goal, q=q, humans=humans, human_sample=human_sample,
                          following=following, speed=None if report is None else report.speed,
                          beta=report is not None and report.beta, waited=waited,
                          version=max(newest_version, -1 if report is None else report.version) + 1,
                          held=report is not None and report.held,
                          stop_at=None if report is None else report.awaiting, then=then, human_delay=human_delay)


def goal_dropped(*, goal: np.ndarray | None, q: np.ndarray | None, enabled: bool, followed_version: int | None,
                 planned: bool, in_flight: bool) -> bool:
    """Whether the goal's plan was dropped and the robot, able to move again, stands short of the goal: then the
    goal is planned anew from where the robot stands, as a new goal is.

    The scaling layer drops the trajectory it follows when the driver stops the robot (a drive fault, a stale
    command, the drives' SYNC watchdog) and holds where the robot stands, following none of the planner's
    (version -1). Nothing else plans again (the loop acts on a new goal or along a followed trajectory), so a goal
    sent to a stopped robot, or the rest of a leg a stop cut short, was lost: after `hrc recover` the robot stood.

    goal, q: the goal and the measured position (rad; None: not known); enabled: the driver follows commands (the
    newest joint state); followed_version: the version the scaler reports following (-1: none of the planner's;
    None: no report yet); planned: a trajectory was published for this goal; in_flight: the newest one published
    has not been decided on by the scaler yet (it may still be taken)."""
    if goal is None or q is None or not enabled or not planned or in_flight or followed_version != -1:
        return False
    return float(np.max(np.abs(np.asarray(q, dtype=float) - np.asarray(goal, dtype=float)))) > AT_GOAL_WITHIN
