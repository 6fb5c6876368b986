"""What the planning layer reads of the scaling layer's last step: one record, whether the step ran in this process
(``ScalingStep``, the simulation) or came over Zenoh (``ScalerStatus``, the planner service;
``shared.wire.convert.report_from_status``), so that both feed the planning layer the same inputs
(``shared.planning.inputs.planning_inputs``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from shared.scaling.layer import ScalingStep


@dataclass(frozen=True, slots=True, kw_only=True)
class ScalerReport:
    """version: the trajectory followed (-1: none of the planner's); s: where on it (its path parameter, s);
    speed: the commanded joint speed (rad/s, fastest joint); beta: the replan request; held: the speed is the SSM's
    bound, not a ramp below it; awaiting: the s where the robot is brought to rest to await its replan (None: it
    does not wait); pending: the version of a plan from rest the robot is being brought to rest for (None: none)."""

    version: int
    s: float
    speed: float
    beta: bool
    held: bool
    awaiting: float | None = None
    pending: int | None = None

    @classmethod
    def of_step(cls, step: ScalingStep) -> ScalerReport:
        return cls(version=step.trajectory_version, s=step.s, speed=step.speed, beta=step.beta, held=step.held,
                   awaiting=step.awaiting, pending=step.pending)
