"""One emulated PRBT joint drive, as a pure core: CiA 402 state machine, interpolated position motion,
protections. The emulator process feeds it what arrives on the bus and the time; it answers with the
statusword, position, velocity and following error in drive units and the EMCY codes to send.

Time: ``position`` is where the joint is at the last SYNC (or watchdog) instant; ``velocity`` is the speed
it moves at from then on, ``velocity_actual`` the speed of the period that just ended (what an encoder
difference reports). A SYNC first completes the period that ended, then takes the new setpoint. A SYNC the
drive does not receive (a lost frame) ends its period on the drive's own clock all the same, holding the
last setpoint (``on_missed_sync``); before, the joint stood still for that period and then went on, a stop
and a restart in an instant that no motor makes.

Interpolated position mode (7), as CiA 402 describes it: in operation enabled with controlword bit 4 set,
each SYNC takes the latest setpoint (0x60C1:1, 0.001 degree per count) and moves to it over the
interpolation period (0x60C2), with the velocity that consecutive setpoints imply as feed-forward and a
braking-aware correction of any following error left over. The position demand (0x6062) is the setpoint
being interpolated to. While the setpoints are followable (``shared.drives.prbt``) the joint reaches each
one at the next SYNC: one period behind them, following error (0x60F4 = demand - actual) zero. Beyond the
velocity or acceleration limit the drive saturates (statusword bit 11, internal limit) and the following
error grows; beyond the window 0x6065 for longer than 0x6066 that is a fault. With no new setpoint the
drive holds the last one.

Protections, each a fault with an EMCY (and the error register set): a following error beyond the window
for longer than the time-out (0x8611), a setpoint outside the software position limits (0x8612), no SYNC
for sync_timeout_factor periods while powered (0x8100), no new setpoint for that many SYNCs while
interpolating (0x8250), an injected drive fault (0x5000). Quick stop and the fault reaction brake at the
acceleration limit; a fault reaction ends in FAULT. A fault reset sends the EMCY "error reset" (0x0000).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from shared.drives.cia402 import CW_ENABLE_IP, DriveStateMachine, State, statusword
from shared.drives.prbt import (
    COUNTS_PER_RAD,
    EMCY_FOLLOWING,
    EMCY_LIMIT,
    EMCY_RESET,
    EMCY_RPDO_TIMEOUT,
    EMCY_SYNC_TIMEOUT,
    FOLLOWING_TIMEOUT,
    FOLLOWING_WINDOW,
    MODE_IP,
    PERIOD,
    to_rad,
)


@dataclass
class DriveLimits:
    """lower / upper (rad) software limits, velocity (rad/s), acceleration (rad/s^2; the drive's own, the
    PRBT controller's 6.0), period (s) the interpolation period, following_window (rad, 0x6065) and
    following_timeout (s, 0x6066)."""

    lower: float
    upper: float
    velocity: float = 1.57
    acceleration: float = 6.0
    period: float = PERIOD
    sync_timeout_factor: int = 6
    following_window: float = FOLLOWING_WINDOW
    following_timeout: float = FOLLOWING_TIMEOUT

    @property
    def sync_timeout(self) -> float:
        """s without SYNC after which a powered drive faults (sync_timeout_factor periods)."""
        return self.sync_timeout_factor * self.period


POWERED = (State.READY_TO_SWITCH_ON, State.SWITCHED_ON, State.OPERATION_ENABLED, State.QUICK_STOP_ACTIVE)


@dataclass
class Drive:
    limits: DriveLimits
    position: float = 0.0                      # rad, at the last SYNC / watchdog instant
    velocity: float = 0.0                      # rad/s, from that instant on
    velocity_actual: float = 0.0               # rad/s, over the period that ended at the last SYNC
    mode: int = 0
    controlword: int = 0
    sm: DriveStateMachine = field(default_factory=DriveStateMachine)
    setpoint: int | None = None                # counts, latest received
    demand: float | None = None                # rad, the setpoint being interpolated to (0x6062)
    saturated: bool = False                    # the last period's motion hit the velocity or acceleration limit
    following_error: float = 0.0               # rad, 0x60F4 at the last SYNC: demand - actual (0: not interpolating)
    position_demand: float = 0.0               # rad, 0x6062 at the last SYNC: where the joint should have been
    _fresh_setpoint: bool = False
    _syncs_without_setpoint: int = 0
    _outside_window_since: float | None = None
    last_sync: float | None = None
    _moved_at: float | None = None             # the last braking step without SYNC (watchdog)
    _missed: int = 0                           # periods run on the drive's own clock since the last SYNC received
    fault_code: int = 0

    def boot(self, position: float) -> None:
        self.position, self.velocity, self.velocity_actual = position, 0.0, 0.0
        self.demand, self._outside_window_since = None, None
        self.position_demand, self.following_error = position, 0.0
        self.sm.boot()

    @property
    def state(self) -> State:
        return self.sm.state

    @property
    def interpolating(self) -> bool:
        return (self.state is State.OPERATION_ENABLED and self.mode == MODE_IP
                and bool(self.controlword & CW_ENABLE_IP))

    def statusword(self) -> int:
        return statusword(self.state, ip_active=self.interpolating, internal_limit=self.saturated,
                          target_reached=self.demand is not None and abs(self.demand - self.position) < 1e-4)

    def on_controlword(self, controlword: int) -> list[int]:
        """Apply a controlword; returns EMCY codes to send (the error reset after a fault reset)."""
        before = self.state
        self.controlword = controlword
        after = self.sm.on_controlword(controlword)
        if before is State.FAULT and after is not State.FAULT:
            self.fault_code = 0
            return [EMCY_RESET]
        if after is State.OPERATION_ENABLED and before is not State.OPERATION_ENABLED:
            self.demand, self.setpoint, self._syncs_without_setpoint = None, None, 0
            self._outside_window_since = None
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

    def watchdog_due(self, step: float) -> float | None:
        """The monotonic time (s) at which ``watchdog`` has something to do: the SYNC time-out after the last
        SYNC while powered or in a fault reaction; the next braking step (step, s) while a fault reaction
        brakes on the drive's own clock; None when there is nothing to watch (no SYNC yet, or at rest in a
        state the time-out does not concern)."""
        if self.last_sync is None:
            return None
        timeout_at = self.last_sync + self.limits.sync_timeout
        if self.state is State.FAULT_REACTION_ACTIVE:
            return timeout_at if self._moved_at is None else self._moved_at + step
        return timeout_at if self.state in POWERED else None

    def watchdog(self, now: float) -> list[int]:
        """Called between SYNCs: once SYNC has run, no SYNC for sync_timeout_factor periods while the drive is
        powered (ready, switched on, enabled, quick stop) is a fault. Without SYNC the drive keeps its own
        clock: the fault reaction then brakes in real time (a drive does not wait for a dead master to finish
        its stop), so the joint is at rest when a new master brings SYNC back."""
        if self.last_sync is None or now - self.last_sync <= self.limits.sync_timeout:
            return []
        codes = self.raise_fault(EMCY_SYNC_TIMEOUT) if self.state in POWERED else []
        if self.state is State.FAULT_REACTION_ACTIVE:
            if self._moved_at is None:            # until the watchdog fired it went on at its speed
                self.position += self.velocity * (now - self.last_sync - self._missed * self.limits.period)
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
        """One SYNC: the period that ended is completed (the joint moved at `velocity`), the following error
        is checked, the newest setpoint taken, and the motion of the next period chosen. Returns EMCY codes."""
        watchdog_moved = self._moved_at is not None
        self.last_sync, self._moved_at, self._missed = now, None, 0
        lim = self.limits
        if not watchdog_moved:
            self.position += self.velocity * lim.period
        self.velocity_actual = self.velocity
        tracking = self.interpolating and self.demand is not None
        self.position_demand = self.demand if tracking else self.position
        self.following_error = self.position_demand - self.position
        emcy = self._check_following(now)
        if self.interpolating:
            if self.demand is None:
                self.demand = self.position
            if self._fresh_setpoint and self.setpoint is not None:
                target = to_rad(self.setpoint)
                if not lim.lower <= target <= lim.upper:
                    emcy += self.raise_fault(EMCY_LIMIT)
                else:
                    self._plan(target)
                self._syncs_without_setpoint = 0
            else:
                self._plan(self.demand)                   # hold the last setpoint
                self._syncs_without_setpoint += 1
                if self.setpoint is not None and self._syncs_without_setpoint > lim.sync_timeout_factor:
                    emcy += self.raise_fault(EMCY_RPDO_TIMEOUT)
        self._fresh_setpoint = False
        if not self.interpolating:
            self._brake()
        return emcy

    def on_missed_sync(self) -> None:
        """A SYNC that this drive did not receive (a lost frame): its own clock still ends the period (the
        joint moves on at its velocity: a motor does not stop and restart in an instant), and with no SYNC
        to take the newest setpoint it holds the last one, within its acceleration limit, as for a missing
        setpoint; the next SYNC takes the newest. Nothing is reported (the TPDOs answer SYNCs), and the
        watchdog still counts from the last SYNC received."""
        if self.last_sync is None or self._moved_at is not None:      # not started, or the watchdog's to move
            return
        self._missed += 1
        self.position += self.velocity * self.limits.period
        self.velocity_actual = self.velocity
        if self.interpolating and self.demand is not None:
            self._plan(self.demand)
        elif not self.interpolating:
            self._brake()

    def _check_following(self, now: float) -> list[int]:
        """A following error beyond the window for longer than the time-out is a fault (0x8611)."""
        lim = self.limits
        if abs(self.following_error) <= lim.following_window:
            self._outside_window_since = None
            return []
        if self._outside_window_since is None:
            self._outside_window_since = now
        if now - self._outside_window_since >= lim.following_timeout - 1e-9:
            return self.raise_fault(EMCY_FOLLOWING)
        return []

    def _plan(self, target: float) -> None:
        """The velocity of the next period: the setpoints' own velocity (feed-forward, (target - demand) / T)
        plus a correction of the following error left (braking-aware, so a saturated drive lands on a held
        setpoint instead of overshooting it), within the velocity and acceleration limits."""
        lim = self.limits
        dt, a = lim.period, lim.acceleration
        feed_forward = (target - self.demand) / dt
        error = self.demand - self.position
        correction = math.copysign(min(abs(error) / dt, math.sqrt(2.0 * a * abs(error))), error)
        wanted = feed_forward + correction
        # setpoints come in whole counts: a followable stream may imply up to 2 counts per period more
        resolution = 2.0 / COUNTS_PER_RAD / dt
        v_max, dv = lim.velocity + resolution, a * dt + resolution
        velocity = max(-v_max, min(v_max, max(self.velocity - dv, min(self.velocity + dv, wanted))))
        self.saturated = abs(velocity - wanted) > 1e-9
        self.velocity, self.demand = velocity, target

    def _brake(self) -> None:
        """Not interpolating: hold, quick stop and fault reaction brake at the acceleration limit; otherwise
        the brakes are closed."""
        self.saturated = False
        if self.state not in (State.OPERATION_ENABLED, State.QUICK_STOP_ACTIVE, State.FAULT_REACTION_ACTIVE):
            self.velocity = 0.0
            return
        step = self.limits.acceleration * self.limits.period
        self.velocity = 0.0 if abs(self.velocity) <= step else self.velocity - math.copysign(step, self.velocity)
        if self.state is State.FAULT_REACTION_ACTIVE and self.velocity == 0.0:
            self.sm.motion_stopped()
