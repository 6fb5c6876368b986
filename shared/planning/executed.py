"""A candidate judged by the scaling layer itself: the time the product's own ``ScalingLayer`` takes along a
timed trajectory when the people move as a forecast has them (issue 38, item 3), instead of the time cost's
model of it (``shared.planning.time_cost``: the SSM bound at nominal speed, sample by sample).

The forward run is the scaling layer's own ``step``, cycle by cycle, so it has what the cost's model leaves out:
alpha changing at the acceleration the layer allows, braking at the drives' deceleration, the check of where
each command leads, the robot never speeding up towards a person of unknown velocity. It follows the
trajectory alone: no planner answers its replan requests (``await_plan`` 0), as the trajectory would be
followed if it were kept. The people are the forecast's frames (positions linear between frames, velocities
those of the frame the moment falls in) for ``stay`` seconds, then gone, as the cost has them; a run not
finished within ``longest`` seconds counts that long. It runs at ``period`` (default the cell's; a coarser one
is the same layer at a coarser clock, for a budget).

Cost: one step of the layer (tens of microseconds) per period of the trajectory: 300 steps for a 3 s leg at
100 Hz. For choosing between a few timed trajectories (a decision's baseline and its candidates), not for a
path search's thousands of candidate paths. Pure: no I/O.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from shared.core.humans import HumanCapsules
from shared.core.trajectory import Trajectory
from shared.planning.forecast import ConstantVelocity, Forecaster
from shared.robot.model import RobotModel
from shared.safety.parameters import SsmParameters
from shared.scaling.layer import ScalingInputs, ScalingLayer, StepStatus
from shared.scaling.parameters import ScalingParameters

LONGEST = 15.0       # s: a forward run not done by then counts this long (a person who never leaves)


class ExecutedTime:
    """time(trajectory, s_from, humans, stay, forecaster) -> s: the forward run of the scaling layer along
    `trajectory` from s_from (at rest at the start of a plan from rest, else at full path speed, as the cost
    assumes), against the forecaster's frames of `humans` (the default: ``ConstantVelocity``)."""

    def __init__(self, robot: RobotModel, ssm: SsmParameters, scaling: ScalingParameters,
                 period: float | None = None, longest: float = LONGEST) -> None:
        self.robot, self.ssm = robot, ssm
        self.params = replace(scaling, await_plan=0.0, period=period or scaling.period)
        self.longest = longest
        self.layer = ScalingLayer(robot, ssm, self.params)
        self.runs = 0                 # forward runs made (what a benchmark charges them by)
        self.delay = 0.0              # s: the people's data's age, which the layer counts (mean_age)

    @staticmethod
    def people(humans: HumanCapsules | None, horizon: float, forecaster: Forecaster):
        """t -> HumanCapsules: the forecast of `humans` t seconds from now (None: nobody in view)."""
        if humans is None or humans.count == 0:
            nobody = HumanCapsules.empty()
            return lambda t: nobody
        forecast = forecaster.forecast(humans, horizon)

        def at(t: float) -> HumanCapsules:
            frame = min(int(max(t, 0.0) / forecast.step), forecast.frames.shape[0] - 1)
            return HumanCapsules(forecast.at(t), humans.radii, forecast.velocities[frame], humans.velocity_known)
        return at

    def time(self, trajectory: Trajectory, s_from: float, humans: HumanCapsules | None, stay: float = np.inf,
             forecaster: Forecaster | None = None) -> float:
        """Seconds from s_from to the end of `trajectory` as the scaling layer follows it (``longest`` if later)."""
        self.runs += 1
        layer = self.layer
        layer.set_trajectory(trajectory, s_from)
        layer.sdot = 1.0 if s_from > 0.0 else 0.0
        period = self.params.period
        people = self.people(humans, min(stay, self.longest), forecaster or ConstantVelocity())
        gone = HumanCapsules.empty()
        for k in range(int(np.ceil(self.longest / period))):
            t = k * period
            step = layer.step(ScalingInputs(humans=people(t) if t < stay else gone, human_age=self.delay,
                                            stale_after=math.inf))     # a forecast: as old as the data, never stale
            if step.status is StepStatus.FINISHED:
                return t
        return self.longest
