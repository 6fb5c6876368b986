"""In-process simulation of the scaling layer on a simulated clock: deterministic, no I/O.

The robot shuttles between two configurations along straight joint-space trajectories at its own limits;
a scripted human moves through the cell; every control period the scaling layer runs exactly as in the
scaler service, and the commanded motion is checked against the ISO/TS 15066 limit. The robot is taken
to follow its command exactly (the drive model comes with the CAN emulator).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from shared.config import CellConfig
from shared.robot_model import RobotModel
from shared.scaling_layer import ScalingLayer, ScalingStep, StepStatus
from shared.scenarios import ScriptedHuman
from shared.ssm import pair_ssm
from shared.trajectory import straight_line_trajectory


@dataclass
class SimRecord:
    """One control cycle as it happened."""

    t: float
    phase: str
    step: ScalingStep
    shuttles: int
    approach_margin: float       # min over pairs of max(limit, 0) - approach speed at the commanded motion (m/s)


@dataclass
class SimResult:
    records: list[SimRecord] = field(default_factory=list)
    shuttles: int = 0
    violations: int = 0
    beta_requests: int = 0

    def summary(self) -> dict:
        steps = [r.step for r in self.records]
        compute = np.array([s.compute_us for s in steps]) if steps else np.zeros(1)
        alpha = np.array([s.alpha for s in steps]) if steps else np.zeros(1)
        margins = [r.approach_margin for r in self.records if np.isfinite(r.approach_margin)]
        seps = [s.min_separation for s in steps if np.isfinite(s.min_separation)]
        duration = self.records[-1].t if self.records else 0.0
        return {
            "duration_s": round(duration, 3),
            "cycles": len(steps),
            "shuttles_completed": self.shuttles,
            "shuttles_per_min": round(60.0 * self.shuttles / duration, 2) if duration else 0.0,
            "mean_alpha": round(float(alpha.mean()), 4),
            "stopped_fraction": round(float(np.mean(alpha < 1e-6)), 4),
            "beta_requests": self.beta_requests,
            "min_separation_m": round(min(seps), 4) if seps else None,
            "min_margin_m_s": round(min(margins), 4) if margins else None,
            "violations": self.violations,
            "compute_us": {"p50": round(float(np.percentile(compute, 50)), 1),
                           "p99": round(float(np.percentile(compute, 99)), 1)},
        }


def run_shuttle(robot: RobotModel, config: CellConfig, human: ScriptedHuman, q_a: np.ndarray, q_b: np.ndarray,
                duration: float, on_record=None) -> SimResult:
    """Shuttle between q_a and q_b for `duration` seconds of simulated time next to a scripted human."""
    layer = ScalingLayer(robot, config.ssm, config.scaling)
    period = config.scaling.period
    lim = robot.limits
    ends = [np.asarray(q_a, dtype=float), np.asarray(q_b, dtype=float)]
    version = 0
    layer.set_trajectory(straight_line_trajectory(ends[0], ends[1], lim.velocity, lim.acceleration, version=version))
    result = SimResult()
    beta_before = False
    for k in range(int(round(duration / period))):
        t = k * period
        humans = human.at(t)
        step = layer.step(humans, 0.0)
        # independent check of the commanded motion: approach speed of every link against its limit
        points, jac = robot.capsule_kinematics(step.q_command)
        check = pair_ssm(points, robot.radii, jac @ step.qd_command, humans, config.ssm)
        margin = float(check.margin.min()) if check.margin.size else float("inf")
        if margin < -1e-9:
            result.violations += 1
        if step.beta and not beta_before:
            result.beta_requests += 1
        beta_before = step.beta
        if step.status is StepStatus.FINISHED:
            result.shuttles += 1
            version += 1
            start, goal = ends[version % 2], ends[(version + 1) % 2]
            layer.set_trajectory(straight_line_trajectory(start, goal, lim.velocity, lim.acceleration,
                                                          version=version))
        record = SimRecord(t, human.phase(t), step, result.shuttles, margin)
        result.records.append(record)
        if on_record is not None:
            on_record(record)
    return result
