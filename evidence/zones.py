"""Zone-based speed and separation monitoring as deployed in cells today (the baseline, pure).

A safety laser scanner or camera gives the separation between the robot and the nearest person; the
robot runs at full speed, at a reduced speed, or stops, by which zone that separation is in. No
direction or velocity awareness: the zones are sized once with the ISO/TS 15066 formula for the worst
case, a person approaching at the ISO 13855 speed (2.0 m/s) while the robot approaches at its speed in
that zone:

    S_stop = S_p(v_reduced, 2.0 m/s)        below it: protective stop (within T_s)
    S_full = S_p(v_robot_max, 2.0 m/s)      beyond it: full speed; between: reduced speed

each with the robot's stopping time from its zone's speed (the cell's model of T_s, ``SsmParameters.stop_at``;
the reduced zone's is shorter). Behind a sensor whose data is ``latency`` s late (a camera pipeline's), both zones
grow by the person's travel over it at that speed, as ISO 13855 counts a sensor's response time in T. The zones
count no age of their data, so their T_r is the whole chain from the sensor to the drives (``WHOLE_CHAIN``, the
SSM's own T_r until session 81): with the cell's T_r of 0.05 s, which covers only the chain from the control cycle
because the scaling layer counts the data's age, the zones let 11 violations through in 1000 scenarios
(``bench/compare.py --scenarios 1000``, random walk seeds 467 and 627), none with 0.1 s.

The reduced speed caps every point of every link at v_reduced (ISO 10218's 250 mm/s by default). The
stop is a category 2 stop: the path speed ramps down to zero within T_s, as S_p assumes; speeding up
again ramps over T_s too. It follows the same path as the scaling layer, so the comparison isolates the
speed policy.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from shared.core.geometry import capsule_pair_distances
from shared.robot.model import RobotModel
from shared.safety.parameters import PAPER_REACTION_TIME, SsmParameters
from shared.safety.ssm import protective_separation_distance
from shared.scaling.layer import ScalingInputs, ScalingLayer, ScalingStep, StepStatus, held_by_ssm
from shared.scaling.parameters import ScalingParameters

ISO_13855_SPEED = 2.0        # m/s, the approach speed the zones are sized for
REDUCED_SPEED = 0.25         # m/s, ISO 10218-1 reduced speed
WHOLE_CHAIN = PAPER_REACTION_TIME   # s: the zones' T_r at the least, from the sensor's detection to the drives


@dataclass(frozen=True)
class SpeedZones:
    """Zone boundaries (m) and the speed caps (m/s) they were sized with."""

    stop: float
    full: float
    reduced_speed: float

    @classmethod
    def sized(cls, ssm: SsmParameters, robot_speed: float, reduced_speed: float = REDUCED_SPEED,
              human_speed: float = ISO_13855_SPEED, latency: float = 0.0) -> "SpeedZones":
        """Zones from the ISO/TS 15066 formula for robot_speed (the fastest point of the robot at full speed,
        m/s), each with the robot's stopping time at its zone's speed (``SsmParameters.stop_at``, as the scaling
        layer has it: at reduced speed the joints move at about reduced_speed / robot_speed of full speed, and a
        robot stops sooner from there; an integrator sizes the stop zone with the stopping time of the reduced
        speed). latency (s): the sensor's data is that late (``SsmParameters.aged``: the person's travel over it at
        human_speed is added to both zones). T_r is at least ``WHOLE_CHAIN``: zones count no age of their data."""
        ssm = replace(ssm, reaction_time=max(ssm.reaction_time, WHOLE_CHAIN)).aged(latency)
        reduced_stop = ssm.stop_at(min(1.0, reduced_speed / robot_speed))
        return cls(float(protective_separation_distance(reduced_speed, human_speed, ssm, reduced_stop)),
                   float(protective_separation_distance(robot_speed, human_speed, ssm)), reduced_speed)


def fastest_point_speed(robot: RobotModel, q: np.ndarray, qd: np.ndarray) -> float:
    """The speed (m/s) of the fastest capsule end point of the robot moving at qd."""
    _, velocities = robot.capsule_motion(q, qd)
    return float(np.linalg.norm(velocities, axis=-1).max())


class ZoneScalingLayer(ScalingLayer):
    """Follows a trajectory like ScalingLayer, with the path speed chosen by separation zones."""

    def __init__(self, robot: RobotModel, zones: SpeedZones, ssm: SsmParameters | None = None,
                 params: ScalingParameters | None = None) -> None:
        super().__init__(robot, ssm, params)
        self.zones = zones

    def target_alpha(self, separation: float, q: np.ndarray, dq: np.ndarray) -> float:
        """The path speed the zone of `separation` allows at this point of the path (dq: nominal q')."""
        if separation >= self.zones.full:
            return 1.0
        if separation < self.zones.stop:
            return 0.0
        fastest = fastest_point_speed(self.robot, q, dq)
        return 1.0 if fastest <= self.zones.reduced_speed else self.zones.reduced_speed / fastest

    def step(self, inputs: ScalingInputs) -> ScalingStep:
        start = time.perf_counter()
        traj = self.trajectory
        if traj is None:
            return super().step(inputs)
        humans = inputs.humans
        q_nom, dq, _ = traj.sample(self.s)
        running = self.s < traj.duration
        separation, target = math.inf, 0.0
        status = self.input_status(humans, inputs.human_age, running, inputs.stale_after)   # the source's bound
        if status is StepStatus.RUNNING:
            if humans.count:
                pairs = capsule_pair_distances(self.robot.capsule_segments(q_nom), self.robot.radii,
                                               humans.segments, humans.radii)
                separation = float(pairs.distance.min())
            target = self.target_alpha(separation, q_nom, dq)
        ramp = self.params.period / self.ssm.stopping_time          # full speed <-> stop within T_s
        alpha = min(max(target, self.sdot - ramp), self.sdot + ramp) if running else 0.0
        if status in (StepStatus.NO_HUMAN_DATA, StepStatus.STALE_HUMAN_DATA):
            alpha = 0.0                                          # no data: stop at once, as the scaler does
        alpha = min(max(alpha, 0.0), 1.0)
        alpha = 0.0 if alpha < 1e-9 else alpha                   # the ramp's rounding is not motion
        self.sdot = alpha
        self.s = min(self.s + alpha * self.params.period, traj.duration)
        q_c, dq_c, _ = traj.sample(self.s)
        return ScalingStep(alpha=alpha, safe_alpha=target, beta=False, s=self.s, sdot=alpha, q_command=q_c,
                           qd_command=dq_c * alpha, status=status, method="zones", trajectory_version=traj.version,
                           min_separation=separation, min_margin=math.inf,
                           compute_us=(time.perf_counter() - start) * 1e6,
                           speed=float(np.abs(dq_c).max()) * alpha, held=held_by_ssm(alpha, target))
