"""One emulated PRBT joint drive, as a pure core: CiA 402 state machine, interpolated position motion,
protections. The emulator process feeds it what arrives on the bus and the time; it answers with the
statusword, position and velocity in drive units and the EMCY codes to send.

Behaviour (PRBT facts sheet, sections 3 and 4; CiA 402 where the sheet is silent):
* mode 7 (interpolated position): in operation enabled with controlword bit 4 set, every SYNC takes the
  latest setpoint (0x60C1:1, 0.001 degree per count) as the target for the next period and moves towards
  it within the joint's velocity limit and the drive's acceleration limit (braking-aware: never faster
  than it can stop on the target), so the motion is that of a drive, not a teleport;
* quick stop and fault reaction brake at the acceleration limit; a fault reaction ends in FAULT;
* protections, each a fault with an EMCY code: a setpoint outside the software position limits
  (0x8612), a setpoint step the joint cannot follow in one period (0x8611), no SYNC for sync_timeout_factor
  periods while powered (0x8100), no new setpoint for that many SYNCs while interpolating (0x8250), an
  injected drive fault (0x5000). A fault reset sends the EMCY "error reset" (0x0000).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from shared.cia402 import CW_ENABLE_IP, DriveStateMachine, State, statusword

COUNTS_PER_RAD = 180.0 / math.pi * 1000.0       # 0.001 degree per count
EMCY_RESET, EMCY_FOLLOWING, EMCY_LIMIT = 0x0000, 0x8611, 0x8612
EMCY_SYNC_TIMEOUT, EMCY_RPDO_TIMEOUT, EMCY_DRIVE_FAULT = 0x8100, 0x8250, 0x5000
MODE_IP = 7


def to_counts(rad: float) -> int:
    return int(round(rad * COUNTS_PER_RAD))


def to_rad(counts: int) -> float:
    return counts / COUNTS_PER_RAD


@dataclass
class DriveLimits:
    """lower / upper (rad) software limits, velocity (rad/s), acceleration (rad/s^2; the drive's own, the
    PRBT controller's 6.0), period (s) the interpolation period, jump_tolerance: a setpoint step up to
    velocity * period * this factor is followable."""

    lower: float
    upper: float
    velocity: float = 1.57
    acceleration: float = 6.0
    period: float = 0.01
    sync_timeout_factor: int = 6
    jump_tolerance: float = 1.2


@dataclass
class Drive:
    limits: DriveLimits
    position: float = 0.0                      # rad
    velocity: float = 0.0                      # rad/s
    mode: int = 0
    controlword: int = 0
    sm: DriveStateMachine = field(default_factory=DriveStateMachine)
    setpoint: int | None = None                # counts, latest received
    _target: float | None = None               # rad, the target being interpolated to
    _fresh_setpoint: bool = False
    _syncs_without_setpoint: int = 0
    last_sync: float | None = None
    _moved_at: float | None = None             # the last braking step without SYNC (watchdog)
    fault_code: int = 0

    def boot(self, position: float) -> None:
        self.position, self.velocity = position, 0.0
        self.sm.boot()

    @property
    def state(self) -> State:
        return self.sm.state

    @property
    def interpolating(self) -> bool:
        return (self.state is State.OPERATION_ENABLED and self.mode == MODE_IP
                and bool(self.controlword & CW_ENABLE_IP))

    def statusword(self) -> int:
        return statusword(self.state, ip_active=self.interpolating,
                          target_reached=self._target is not None and abs(self._target - self.position) < 1e-4)

    def on_controlword(self, controlword: int) -> list[int]:
        """Apply a controlword; returns EMCY codes to send (the error reset after a fault reset)."""
        before = self.state
        self.controlword = controlword
        after = self.sm.on_controlword(controlword)
        if before is State.FAULT and after is not State.FAULT:
            self.fault_code = 0
            return [EMCY_RESET]
        if after is State.OPERATION_ENABLED and before is not State.OPERATION_ENABLED:
            self._target, self.setpoint, self._syncs_without_setpoint = None, None, 0
        return []

    def on_setpoint(self, counts: int) -> None:
        self.setpoint = int(counts)
        self._fresh_setpoint = True

    def raise_fault(self, code: int) -> list[int]:
        """Enter the fault reaction (controlled stop, then FAULT) and report code (once)."""
        if self.state in (State.FAULT, State.FAULT_REACTION_ACTIVE):
            return []
        self.sm.fault()
        self.fault_code = code
        return [code]

    def watchdog(self, now: float) -> list[int]:
        """Called between SYNCs: once SYNC has run, no SYNC for sync_timeout_factor periods while the drive is
        powered (ready, switched on, enabled, quick stop) is a fault. Without SYNC the drive keeps its own
        clock: the fault reaction then brakes in real time (a drive does not wait for a dead master to finish
        its stop), so the joint is at rest when a new master brings SYNC back."""
        powered = (State.READY_TO_SWITCH_ON, State.SWITCHED_ON, State.OPERATION_ENABLED, State.QUICK_STOP_ACTIVE)
        if self.last_sync is None or now - self.last_sync <= self.limits.sync_timeout_factor * self.limits.period:
            return []
        codes = self.raise_fault(EMCY_SYNC_TIMEOUT) if self.state in powered else []
        if self.state is State.FAULT_REACTION_ACTIVE:
            if self._moved_at is None:            # until the watchdog fired it went on at its speed
                self.position += self.velocity * (now - self.last_sync)
            else:
                self._brake_for(now - self._moved_at)
            self._moved_at = now
        return codes

    def _brake_for(self, dt: float) -> None:
        """dt seconds of braking at the acceleration limit (the fault reaction's own time law)."""
        v, a = self.velocity, self.limits.acceleration
        t = min(dt, abs(v) / a) if a > 0 else 0.0
        self.position += v * t - math.copysign(0.5 * a * t * t, v)
        self.velocity = 0.0 if t < dt or abs(v) <= a * t else v - math.copysign(a * t, v)
        if self.velocity == 0.0:
            self.sm.motion_stopped()

    def on_sync(self, now: float) -> list[int]:
        """One interpolation period: protections, then motion. Returns EMCY codes to send."""
        self.last_sync, self._moved_at = now, None
        lim = self.limits
        emcy: list[int] = []
        if self.interpolating:
            if self._fresh_setpoint and self.setpoint is not None:
                target = to_rad(self.setpoint)
                reference = self._target if self._target is not None else self.position
                if not lim.lower <= target <= lim.upper:
                    emcy += self.raise_fault(EMCY_LIMIT)
                elif abs(target - reference) > lim.velocity * lim.period * lim.jump_tolerance:
                    emcy += self.raise_fault(EMCY_FOLLOWING)
                else:
                    self._target = target
                self._syncs_without_setpoint = 0
            elif self._target is not None:
                self._syncs_without_setpoint += 1
                if self._syncs_without_setpoint > lim.sync_timeout_factor:
                    emcy += self.raise_fault(EMCY_RPDO_TIMEOUT)
        self._fresh_setpoint = False
        self._move()
        return emcy

    def _move(self) -> None:
        lim = self.limits
        dt, a = lim.period, lim.acceleration
        if self.interpolating and self._target is not None:
            err = self._target - self.position
            # the speed that lands on the target, no faster than a stop at the acceleration limit allows
            wanted = math.copysign(min(abs(err) / dt, math.sqrt(2.0 * a * abs(err))), err)
        elif self.state in (State.OPERATION_ENABLED, State.QUICK_STOP_ACTIVE, State.FAULT_REACTION_ACTIVE):
            wanted = 0.0                                   # hold, quick stop, fault reaction: brake
        else:
            self.velocity = 0.0                            # brakes closed
            return
        change = max(-a * dt, min(a * dt, wanted - self.velocity))
        self.velocity = max(-lim.velocity, min(lim.velocity, self.velocity + change))
        self.position += self.velocity * dt
        if self.state is State.FAULT_REACTION_ACTIVE and self.velocity == 0.0:
            self.sm.motion_stopped()
