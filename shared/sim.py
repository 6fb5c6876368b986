"""In-process simulation of both layers on a simulated clock: deterministic, no I/O.

The robot shuttles between two configurations; a scripted human moves through the cell. Every control
period the scaling layer runs exactly as in the scaler service. The planning layer, when given, runs the
horizon check on every human sample (Alg. 1), replans and merges when the path ahead is blocked (Alg. 2)
and when the scaling layer raises beta, and plans each new shuttle around the humans. Every command is
checked against the ISO/TS 15066 limit at the state it commands, counting violations. The robot is taken
to follow its command exactly (the drive model comes with the CAN emulator), and a new trajectory is
taken over in the same cycle (the planner's compute time is measured and reported, not yet charged to
the simulated clock).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from shared.config import CellConfig
from shared.planner import PlanningError
from shared.replanning import ReplanFailed, Replanner
from shared.timing import TimingError
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
class ReplanEvent:
    t: float
    reason: str                  # 'horizon', 'beta' or 'goal'
    ok: bool
    compute_ms: float
    detail: str = ""


@dataclass
class SimResult:
    records: list[SimRecord] = field(default_factory=list)
    replans: list[ReplanEvent] = field(default_factory=list)
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
        done = [e for e in self.replans if e.ok]
        return {
            "duration_s": round(duration, 3),
            "cycles": len(steps),
            "shuttles_completed": self.shuttles,
            "shuttles_per_min": round(60.0 * self.shuttles / duration, 2) if duration else 0.0,
            "mean_alpha": round(float(alpha.mean()), 4),
            "stopped_fraction": round(float(np.mean(alpha < 1e-6)), 4),
            "beta_requests": self.beta_requests,
            "replans": [{"t": round(e.t, 2), "reason": e.reason, "compute_ms": round(e.compute_ms, 1),
                         "detail": e.detail} for e in done],
            "replans_failed": len(self.replans) - len(done),
            "min_separation_m": round(min(seps), 4) if seps else None,
            "min_margin_m_s": round(min(margins), 4) if margins else None,
            "violations": self.violations,
            "compute_us": {"p50": round(float(np.percentile(compute, 50)), 1),
                           "p99": round(float(np.percentile(compute, 99)), 1)},
        }


def run_shuttle(robot: RobotModel, config: CellConfig, human: ScriptedHuman, q_a: np.ndarray, q_b: np.ndarray,
                duration: float, on_record=None, replanner: Replanner | None = None, beta_replans: bool = True,
                beta_cooldown: float = 0.5, on_replan=None) -> SimResult:
    """Shuttle between q_a and q_b for `duration` simulated seconds next to a scripted human.

    replanner: the planning layer (None: scaling only, straight shuttles). beta_replans: answer the
    scaling layer's replan requests (the paper's ablation switches this off). on_record / on_replan: called
    with each SimRecord / ReplanEvent as it happens."""
    layer = ScalingLayer(robot, config.ssm, config.scaling)
    period = config.scaling.period
    lim = robot.limits
    ends = [np.asarray(q_a, dtype=float), np.asarray(q_b, dtype=float)]
    result = SimResult()
    leg = 0
    layer.set_trajectory(straight_line_trajectory(ends[0], ends[1], lim.velocity, lim.acceleration))
    beta_before = False
    next_beta_try = next_horizon_try = 0.0
    pending_leg = False

    def log_replan(event: ReplanEvent) -> None:
        result.replans.append(event)
        if on_replan is not None:
            on_replan(event)

    def replan(t: float, reason: str, action, *args) -> None:
        started = time.perf_counter()
        try:
            res = action(*args)
        except ReplanFailed as exc:
            log_replan(ReplanEvent(t, reason, False, (time.perf_counter() - started) * 1e3, str(exc)))
            return
        if res is None:
            return
        elapsed = (time.perf_counter() - started) * 1e3
        if res.from_rest:
            here = layer.trajectory.sample(layer.s)[0]
            if np.abs(here - res.trajectory.positions[0]).max() > 1e-3:
                return                                    # the robot has moved on: not taken
            layer.set_trajectory(res.trajectory, s=0.0)
            layer.sdot = 0.0
        elif layer.s <= res.junction + 1e-9:
            sdot = layer.sdot
            layer.set_trajectory(res.trajectory, s=layer.s)
            layer.sdot = sdot
        else:
            return
        log_replan(ReplanEvent(t, reason, True, elapsed, res.detail))

    for k in range(int(round(duration / period))):
        t = k * period
        humans = human.at(t)
        goal = ends[(leg + 1) % 2]
        if pending_leg and replanner is not None:          # a new shuttle, planned around the humans
            try:
                traj = replanner.plan_fresh(layer.trajectory.positions[-1], goal, humans,
                                            layer.trajectory.version + 1)
                layer.set_trajectory(traj)
                pending_leg = False
            except (PlanningError, TimingError) as exc:   # goal blocked for now: hold and try again
                log_replan(ReplanEvent(t, "goal", False, 0.0, f"{type(exc).__name__}: {exc}"))
        elif replanner is not None and layer.s < layer.trajectory.duration and t >= next_horizon_try:
            failures = len(result.replans)
            replan(t, "horizon", replanner.on_horizon, layer.trajectory, layer.s, goal, humans)
            if len(result.replans) > failures and not result.replans[-1].ok:
                next_horizon_try = t + beta_cooldown / 2     # do not hammer a blocked horizon every cycle
        step = layer.step(humans, 0.0)
        if step.beta and not beta_before:
            result.beta_requests += 1
        beta_before = step.beta
        if step.beta and beta_replans and replanner is not None and t >= next_beta_try:
            next_beta_try = t + beta_cooldown
            speed = float(np.abs(step.qd_command).max())
            replan(t, "beta", replanner.on_beta, layer.trajectory, layer.s, goal, humans, speed)
        # independent check of the commanded motion: approach speed of every link against its limit
        points, jac = robot.capsule_kinematics(step.q_command)
        check = pair_ssm(points, robot.radii, jac @ step.qd_command, humans, config.ssm)
        margin = float(check.margin.min()) if check.margin.size else float("inf")
        if margin < -1e-9:
            result.violations += 1
        if step.status is StepStatus.FINISHED and not pending_leg:
            result.shuttles += 1
            leg += 1
            start, goal = ends[leg % 2], ends[(leg + 1) % 2]
            if replanner is None:
                layer.set_trajectory(straight_line_trajectory(start, goal, lim.velocity, lim.acceleration,
                                                              version=layer.trajectory.version + 1))
            else:
                pending_leg = True
        record = SimRecord(t, human.phase(t), step, result.shuttles, margin)
        result.records.append(record)
        if on_record is not None:
            on_record(record)
    return result
