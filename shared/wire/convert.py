"""Between the cores' types and the wire messages (shared.wire.messages)."""

from __future__ import annotations

import numpy as np

from shared.core.humans import HumanCapsules
from shared.core.trajectory import Trajectory
from shared.scaling.report import ScalerReport
from shared.wire.messages import HumanState, ScalerStatus, TrajectoryMsg


def trajectory_to_msg(trajectory: Trajectory, goal_id: int, reason: str, junction: float = 0.0,
                      base_version: int = -1, seq: int = 0, stamp: float = 0.0) -> TrajectoryMsg:
    return TrajectoryMsg(version=trajectory.version, goal_id=goal_id, base_version=base_version, reason=reason,
                         junction=float(junction), times=trajectory.times, positions=trajectory.positions,
                         velocities=trajectory.velocities, seq=seq, stamp=stamp)


def trajectory_from_msg(msg: TrajectoryMsg) -> Trajectory:
    """The same q(s), sdot(s): the knots are the representation."""
    return Trajectory(msg.times, msg.positions, msg.velocities, msg.version)


def humans_to_msg(humans: HumanCapsules, valid: bool, sample_stamp: float, seq: int = 0,
                  stamp: float = 0.0, sample_interval: float = 0.0) -> HumanState:
    return HumanState(segments=humans.segments, radii=humans.radii, velocities=humans.velocities,
                      velocity_known=humans.velocity_known, valid=valid, sample_stamp=sample_stamp,
                      sample_interval=sample_interval, seq=seq, stamp=stamp)


def humans_from_msg(msg: HumanState) -> HumanCapsules | None:
    """The capsules of a valid human state; None when the tracker says the track is not valid."""
    if not msg.valid:
        return None
    return HumanCapsules(np.asarray(msg.segments), np.asarray(msg.radii), np.asarray(msg.velocities),
                         np.asarray(msg.velocity_known))


def capture_delay(msg: HumanState) -> float:
    """s: a valid state's way from its sample's capture to the tracker's publication (a camera's latency, the
    tracker's hop), which the scaling and planning layers count the person's travel over and the monitor waits for;
    0 for an invalid state, one with no publication stamp or one stamped before its capture (another clock)."""
    delay = msg.stamp - msg.sample_stamp
    return float(delay) if msg.valid and np.isfinite(delay) and delay >= 0.0 else 0.0


def status_from_step(step, received: int = -1, seq: int = 0, stamp: float = 0.0) -> ScalerStatus:
    """The scaler's status message of one scaling step (``shared.scaling.layer.ScalingStep``): what the scaler
    service publishes each cycle, and what a recording of an in-process run holds (infinite separations and
    margins, where nobody is in view, as None)."""
    finite = lambda v: v if np.isfinite(v) else None  # noqa: E731
    return ScalerStatus(
        s=step.s, alpha=step.alpha, safe_alpha=step.safe_alpha, beta=step.beta, q_command=step.q_command,
        trajectory_version=step.trajectory_version, status=step.status.value, method=step.method,
        min_separation=finite(step.min_separation), min_margin=finite(step.min_margin),
        compute_us=step.compute_us, stop_s=step.awaiting, speed=step.speed, held=step.held,
        pending=-1 if step.pending is None else step.pending, received=received, seq=seq, stamp=stamp)


def report_from_status(msg: ScalerStatus) -> ScalerReport:
    """What the planning layer reads of the scaler's status (the same record a step in this process gives)."""
    return ScalerReport(version=msg.trajectory_version, s=msg.s, speed=msg.speed, beta=msg.beta, held=msg.held,
                        awaiting=msg.stop_s, pending=None if msg.pending < 0 else msg.pending)
