"""The SSM parameters of a cell (the ``ssm`` section of its configuration): ISO/TS 15066's reaction and stopping
allowances, the uncertainties, the human speeds of ISO 13855, and the drive lag the scaling layer keeps a
margin for. Their own module, free of compiled code, so reading a configuration loads nothing heavy.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace

import numpy as np

from shared.core.errors import ConfigError
from shared.core.sections import check_numbers, from_mapping

AGE_STEP = 0.001   # s: the data's delay is rounded up to this (SsmParameters.aged)
PAPER_REACTION_TIME = 0.10   # s: T_r of the paper's formula as this project reproduces it (``paper_formula``): the whole
                             # chain from the person's detection, counted on the robot's side too (shipped until
                             # session 81, when the data's age came to be counted on the person's side instead)


@dataclass(frozen=True)
class SsmParameters:
    """The SSM parameter set. Defaults and where they come from:

    reaction_time T_r = 0.05 s: the cell's own reaction, from the control cycle that takes a person's sample to
      the joints moving: the tick's command to its frame on CAN (a few ms), the frame's wait for the SYNC the
      drives take it at (one 10 ms period at most) and the drives' lag behind that SYNC (one period, 10-12 ms; up
      to 24 ms measured here in a slow phase of the machine), with margin. The way from the person's capture to
      that cycle (a camera's latency, the tracker's hop, the wait for the next frame) is the data's age, counted on
      the person's side each cycle (human_lead): the robot's part of it is known, since the scaling layer takes the
      robot where it is now. Must stay >= the measured p99 of that chain; the robot driver warns
      (``reaction_time_exceeded``) and the report checks it (``reaction_time_covers_p99``).
    stopping_time T_s = 0.30 s: Pilz publishes no stopping data. A Cartesian stop from the PRBT's 1 m/s
      speed limit at its 5 m/s^2 deceleration limit takes 0.20 s (also the controller's Stop-1 trajectory
      duration, stop_trajectory_duration = 0.2 s); a joint stop from 1.57 rad/s at the 6 rad/s^2 the
      controller tolerates takes 0.26 s. The larger, rounded up, so the drives can really stop within it.
    min_stopping_time = 0.05 s: the stopping time of a robot that barely moves. ISO/TS 15066's T_s is the
      robot's stopping time, which depends on its speed (ISO 10218-1 Annex B: stopping time and distance at
      33, 66 and 100 % of speed): the scaling layer brakes at the drives' limit along the path (6 rad/s^2 on
      the leading joint, ``ScalingLayer.braking_floor``), so a stop takes the fastest joint's speed over
      6 rad/s^2. T_s of a state is therefore stopping_time x the fastest joint's fraction of its velocity
      limit (0.30 s at 1.57 rad/s holds the 0.26 s with the same 15 % on top), never below this floor (five
      control periods: the stop's discretisation to whole periods and the command's way to the drives,
      which T_r also covers). ``stop_at``; the SSM limit of a state is the formula at its own T_s, and the
      human's part is their travel over T_r + that T_s: a person may stand closer to a robot that creeps
      than to one at full speed. Set it to stopping_time for the fixed T_s of the paper (``paper_formula``).
    stopping_deceleration a_max = 5.0 m/s^2: the PRBT's Cartesian deceleration limit (cartesian_limits.yaml).
    intrusion_distance C = 0.0 m: the human is modelled by capsules that enclose the tracked segments,
      hands included, so nothing reaches past the modelled body (ISO 13855's C is for presence sensors
      that see only part of the body; set it per ISO 13855 when the body model is partial).
    human_uncertainty Z_d = 0.05 m: motion-capture position error (millimetres) plus marker/skin and
      capsule-fitting error, the value used in the SSM literature for marker-based tracking.
    robot_uncertainty Z_r = 0.02 m: encoder error is negligible (0.001 deg per count); this covers the drive
      following error over one 10 ms interpolation period at the PRBT's link speeds.
    min_separation d_min = 0.05 m: the separation the independent monitor and the planner require at all
      times, also when the robot stands still.
    human_speed_near = 2.0 m/s within human_near_distance = 0.5 m, human_speed_far = 1.6 m/s beyond: the
      approach speeds of ISO 13855, used where the tracker gives no velocity.
    drive_lag = 0.012 s: how far the measured joints run behind the driver's setpoints. An interpolated
      position drive whose setpoints are followable (the driver sends no others) reaches each one at the
      next SYNC, one 10 ms period behind; 20 % on top covers the count quantisation of the measurement.
      The robot driver measures the real lag and warns when its p99 exceeds this value.
    link_acceleration = 4.4 m/s^2: how fast a link point's speed can change, the drives' 6 rad/s^2 at the
      arm's 0.741 m reach.
    human_acceleration a_h = 50 m/s^2: how fast a tracked person's approach speed may grow within T_r + T_s,
      beyond the velocity the tracker measures now, up to the ISO 13855 speed of the separation (2.0 m/s
      within 0.5 m, 1.6 m/s beyond; a measured speed above it is held): the human's part of S_p is the
      integral of min(v_h + a_h t, v_ISO) over the horizon (shared.safety.ssm.human_travel). Source: the
      largest joint acceleration of the human reachability model of SaRA (Thumm and Althoff, provably safe
      human-robot interaction; its human_reach configuration: 50 m/s^2 for shoulders, elbows, wrists and
      hands, 20-30 m/s^2 for the lower body). The arms are what comes near the robot, so one value, theirs,
      for every capsule. At 50 m/s^2 a person measured standing reaches the ISO speed within 0.04 s: their
      distance over the full-speed horizon (0.4 s) is 0.76 m within 0.5 m (0.80 m untracked), 0.61 m beyond
      (0.64 m); over that of a robot that creeps (T_r + min_stopping_time, 0.15 s) 0.26 m within 0.5 m. 0 is
      the paper's formula (the measured speed held over the horizon: ``paper_formula``, ``hrc demo --paper-formula``), which
      lets a link pass a standing person at its stopping distance and does not cover their starting to move
      (docs/measurements.md: its cost and the violations it lets through, side by side).
    human_lead (s, not a setting) = 0: the people's data's age, from its capture to the control cycle (a camera
      pipeline's latency, the tracker's hop, the state's wait for the tick, the wait for a source's next sample).
      The independent monitor checks each measured state against the person captured at its moment, which it
      waits for; the scaling layer has that person only human_lead later. A robot whose speed follows where a
      person was human_lead ago rides the limit of then, above the limit of now by their travel since (46
      violations in ``hrc demo --latency 0.03`` before this was counted; docs/real-people.md). So the human's part
      of S_p is their travel under the human model over human_lead + T_r + T_s from the capture
      (``shared.safety.ssm.aged_travel``): a start or a turn towards the robot within those ms counts, and T_r
      covers only the cell's own chain from the cycle on. The scaling layer sets it each cycle to the age
      (``aged``); the planning layer to the age it counts on average (``shared.tracking.tracker.mean_age``).
    tracking_margin (derived, m/s) = drive_lag x link_acceleration = 0.053 m/s: while the joints run
      drive_lag behind, the measured speed differs from the commanded one by at most this much. The
      scaling layer keeps the commanded approach speed this far below the limit, so the *measured* robot
      meets it too (the independent monitor checks measured states).
    """

    reaction_time: float = 0.05
    stopping_time: float = 0.30
    min_stopping_time: float = 0.05
    stopping_deceleration: float = 5.0
    intrusion_distance: float = 0.0
    human_uncertainty: float = 0.05
    robot_uncertainty: float = 0.02
    min_separation: float = 0.05
    human_speed_near: float = 2.0
    human_speed_far: float = 1.6
    human_near_distance: float = 0.5
    drive_lag: float = 0.012
    link_acceleration: float = 4.4
    human_acceleration: float = 50.0
    human_lead: float = field(default=0.0, metadata={"setting": False})

    def __post_init__(self) -> None:
        check_numbers(self, "ssm", non_negative=True)
        if self.reaction_time + self.stopping_time <= 0:
            raise ConfigError("ssm: reaction_time + stopping_time must be positive")
        if self.min_stopping_time > self.stopping_time:
            raise ConfigError(f"ssm.min_stopping_time: at most stopping_time ({self.stopping_time!r} s), "
                              f"got {self.min_stopping_time!r}")
        if self.drive_lag <= 0:
            raise ConfigError(f"ssm.drive_lag: must be positive (the drives cannot follow without lag), "
                              f"got {self.drive_lag!r}")

    def covering_lag(self, measured: float) -> "SsmParameters":
        """The same parameters with drive_lag raised to a measured lag (s) where that is longer, never lowered:
        the tracking margin (drive_lag x link_acceleration) then covers the drives as they run now (the
        scaler takes the robot driver's reports; a slow phase of the machine put the joints 21-22 ms behind
        their setpoints against the 12 ms configured)."""
        if not measured > self.drive_lag:          # NaN or no longer: as configured
            return self
        return replace(self, drive_lag=float(measured))

    def aged(self, delay: float) -> "SsmParameters":
        """The same parameters for people data that took `delay` s from capture to the cell (``human_lead``,
        rounded up to the next AGE_STEP: a cycle's parameters are one of a few, kept). A NaN or infinite delay is
        a stale-data stop, not a limit: refused."""
        if not (math.isfinite(delay) and delay >= 0.0):
            raise ValueError(f"delay: a finite number of seconds >= 0, got {delay!r}")
        lead = math.ceil(delay / AGE_STEP - 1e-9) * AGE_STEP
        return self if lead == self.human_lead else _with_lead(self, lead)

    def paper_formula(self) -> "SsmParameters":
        """The same parameters with the paper's formula: the measured speed held over T_r + T_s
        (human_acceleration 0), one T_s whatever the robot's speed (min_stopping_time = stopping_time) and T_r for
        the whole chain from the detection (``PAPER_REACTION_TIME``), for reproducing the paper; not safe for a
        person who starts to move."""
        return replace(self, human_acceleration=0.0, min_stopping_time=self.stopping_time,
                       reaction_time=PAPER_REACTION_TIME)

    @property
    def stop_scales(self) -> bool:
        """Whether T_s follows the robot's speed (min_stopping_time below stopping_time)."""
        return self.min_stopping_time < self.stopping_time

    def stop_at(self, fraction):
        """T_s (s) of a robot whose fastest joint moves at `fraction` of its velocity limit (a number, or an array
        of them): stopping_time x fraction, at least min_stopping_time (see the class)."""
        return np.maximum(self.min_stopping_time, self.stopping_time * np.asarray(fraction, dtype=float))

    def stop_of(self, joint_velocity, velocity_limit):
        """T_s (s) of a robot moving at joint_velocity (rad/s; (6,), or (N, 6) for one per state) under the joints'
        velocity_limit (rad/s): ``stop_at`` of the fastest joint's share of its limit."""
        return self.stop_at(np.max(np.abs(np.asarray(joint_velocity, dtype=float))
                                   / np.asarray(velocity_limit, dtype=float), axis=-1))

    def constants_at(self, stop: float) -> tuple[float, float, float, float, float, float, float]:
        """``kernel_constants`` at the stopping time `stop` (s) in place of T_s: the limits of one state."""
        return (self.reaction_time + stop, self.fixed_distance_at(stop), self.human_near_distance,
                self.human_speed_near, self.human_speed_far, self.human_acceleration, self.human_lead)

    def fixed_distance_at(self, stop: float) -> float:
        """``fixed_distance`` with the stopping time `stop` (s) in place of T_s."""
        return 0.5 * self.stopping_deceleration * stop ** 2 + self.static_distance

    @property
    def static_distance(self) -> float:
        """C + Z_d + Z_r (m): the distance terms that depend on neither speed nor stopping time."""
        return self.intrusion_distance + self.human_uncertainty + self.robot_uncertainty

    @property
    def stop_constants(self) -> tuple[float, float, float, float, float]:
        """What the compiled bound of a state's path speed takes (``shared.safety.ssm.speed_alpha_bound``), in
        its order: T_s at full speed, its floor, T_r, a_max, C + Z_d + Z_r."""
        return (self.stopping_time, self.min_stopping_time, self.reaction_time, self.stopping_deceleration,
                self.static_distance)

    @classmethod
    def from_mapping(cls, raw: object) -> "SsmParameters":
        """Build from a config mapping; unknown keys and bad values raise ConfigError naming the key."""
        return from_mapping(cls, raw, "ssm")

    @property
    def tracking_margin(self) -> float:
        """m/s kept between the commanded approach speed and the limit: drive_lag x link_acceleration."""
        return self.drive_lag * self.link_acceleration

    @property
    def horizon(self) -> float:
        """T_s + T_r (s): how long the human keeps approaching before the robot has stopped."""
        return self.reaction_time + self.stopping_time

    @property
    def kernel_constants(self) -> tuple[float, float, float, float, float, float, float]:
        """What the compiled SSM kernel takes, in its order: horizon, fixed distance, the ISO 13855 near
        distance and its two approach speeds (near, far), the human's acceleration, the data's delay (human_lead)."""
        return self.constants_at(self.stopping_time)

    @property
    def fixed_distance(self) -> float:
        """The distance terms that do not depend on speed: a_max T_s^2 / 2 + C + Z_d + Z_r (m)."""
        return self.fixed_distance_at(self.stopping_time)


@functools.lru_cache(maxsize=256)
def _with_lead(params: SsmParameters, lead: float) -> SsmParameters:
    """``SsmParameters.aged``'s parameters, kept (equal parameters give equal ones): a control cycle asks for one of a
    few delays, 100 times a second."""
    return replace(params, human_lead=lead)
