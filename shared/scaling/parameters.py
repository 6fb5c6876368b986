"""The scaling layer's parameters (the ``scaling`` section of a cell's configuration): control period, the
beta hysteresis, the human data timeout, the acceleration slack's price and the solver. Their own module,
free of compiled code, so reading a configuration loads nothing heavy.
"""

from __future__ import annotations

from dataclasses import dataclass

from shared.core.errors import ConfigError
from shared.core.sections import check_numbers, from_mapping

SOLVERS = ("piqp", "closed_form")


@dataclass(frozen=True)
class ScalingParameters:
    """period (s): control period. alpha_min / alpha_release: beta hysteresis thresholds on the safe bound.
    human_timeout (s): human data older than this stops the robot (5 periods at 100 Hz). robot_timeout (s): no
    joint state from the driver for this long stops the robot along its path: the layer no longer knows where the
    robot is, nor that it follows (a driver whose SYNC cycle had died once left the scaler running a whole path
    open loop to "finished" while the robot stood; the fault campaign then waited for an arrival that never
    came). 20 periods: beyond the longest delivery hold seen under load (85 ms), above the driver's own 50 ms
    command time-out and the drives' 60 ms SYNC watchdog, which stop the robot first where the driver is gone.
    acceleration_weight: price of one unit of acceleration slack (in units of the limit) against alpha.
    solver: 'piqp' (closed form as fallback) or 'closed_form'. await_plan (s): how long a robot that asked for a
    replan while crawling stands, at rest where it stopped, for the plan from there (``ScalingLayer._await``).
    0, shipped: it never stands to wait, and crawls on to where the planner's stop plan starts
    (``Candidates.stop_plan``). The stand shortened an accepted replan's stall in hrc demo (100-190 ms against
    300-350), but it is decided before the planner has weighed the request: the crawl is lost where the request
    is refused, the robot may stand just short of where a crawl would have cleared the person, and the old
    trajectory is then judged from rest too, which tips the decision to a detour (docs/measurements.md,
    2026-12-04, session 58: 0 s against 0.3 s, the paper's kind 1.9-2.1 % more shuttles, worse in none of 100)."""

    period: float = 0.01
    alpha_min: float = 0.2
    alpha_release: float = 0.3
    human_timeout: float = 0.05
    robot_timeout: float = 0.2
    acceleration_weight: float = 100.0
    solver: str = "piqp"
    await_plan: float = 0.0

    def __post_init__(self) -> None:
        check_numbers(self, "scaling", skip=("solver",))
        if not 0.0 < self.period <= 1.0:
            raise ConfigError(f"scaling.period: must be in (0, 1] s, got {self.period}")
        if not 0.0 <= self.alpha_min < self.alpha_release <= 1.0:
            raise ConfigError("scaling: need 0 <= alpha_min < alpha_release <= 1, got "
                              f"{self.alpha_min} and {self.alpha_release}")
        if self.human_timeout <= 0.0:
            raise ConfigError(f"scaling.human_timeout: must be positive, got {self.human_timeout}")
        if self.robot_timeout <= 0.0:
            raise ConfigError(f"scaling.robot_timeout: must be positive, got {self.robot_timeout}")
        if self.acceleration_weight <= 0.0:
            raise ConfigError(f"scaling.acceleration_weight: must be positive, got {self.acceleration_weight}")
        if self.await_plan < 0.0:
            raise ConfigError(f"scaling.await_plan: must be >= 0 s, got {self.await_plan}")
        if self.solver not in SOLVERS:
            raise ConfigError(f"scaling.solver: expected one of {SOLVERS}, got {self.solver!r}")

    @classmethod
    def from_mapping(cls, raw: object) -> "ScalingParameters":
        """Build from a config mapping; unknown keys and bad values raise ConfigError naming the key."""
        return from_mapping(cls, raw, "scaling")
