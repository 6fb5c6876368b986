"""The emulated drive as pure code: motion within the limits, protections, fault reset."""

import math

import pytest

from hwsim.drive import (EMCY_FOLLOWING, EMCY_LIMIT, EMCY_RESET, EMCY_RPDO_TIMEOUT, EMCY_SYNC_TIMEOUT, Drive,
                         DriveLimits, to_counts, to_rad)
from shared.cia402 import State

T = 0.01


def enabled_drive(position=0.0):
    d = Drive(DriveLimits(lower=-2.96706, upper=2.96706))
    d.boot(position)
    d.mode = 7
    for cw in (0x0106, 0x0107, 0x010F, 0x001F):
        d.on_controlword(cw)
    assert d.state is State.OPERATION_ENABLED and d.interpolating
    return d


def test_units_are_millidegrees():
    assert to_counts(math.radians(170.0)) == 170000 and to_rad(90000) == pytest.approx(math.pi / 2)


def test_follows_a_ramp_within_velocity_and_acceleration_limits():
    d = enabled_drive()
    t, pos, vel = 0.0, [], []
    target = speed = 0.0
    for k in range(200):
        speed = min(1.4, speed + 3.0 * T)                   # accelerate at 3 rad/s^2 to 1.4 rad/s ...
        target = min(1.0, target + speed * T)                # ... towards 1 rad
        d.on_setpoint(to_counts(target))
        assert d.on_sync(t) == []
        pos.append(d.position)
        vel.append(d.velocity)
        t += T
    assert pos[-1] == pytest.approx(1.0, abs=1e-3)
    assert max(abs(v) for v in vel) <= 1.57 + 1e-9
    acc = [abs(b - a) / T for a, b in zip(vel, vel[1:])]
    assert max(acc) <= 6.0 + 1e-9


def test_stopping_setpoints_make_the_drive_brake_not_teleport():
    d = enabled_drive()
    for k in range(60):                                      # cruise at 1.5 rad/s
        d.on_setpoint(to_counts(1.5 * T * k))
        d.on_sync(k * T)
    last = to_counts(1.5 * T * 59)
    v_before = d.velocity
    d.on_setpoint(last)
    d.on_sync(0.6)
    assert abs(d.velocity) > v_before - 6.0 * T - 1e-9       # it cannot stop in one period


def test_setpoint_beyond_the_limit_faults_with_emcy():
    d = enabled_drive(2.9)
    d.on_setpoint(to_counts(2.99))
    assert d.on_sync(0.0) == [EMCY_LIMIT]
    assert d.state is State.FAULT                            # at rest: the fault reaction is over at once


def test_unfollowable_jump_faults():
    d = enabled_drive()
    d.on_setpoint(to_counts(0.5))
    assert d.on_sync(0.0) == [EMCY_FOLLOWING]


def test_missing_sync_and_missing_setpoints_fault():
    d = enabled_drive()
    d.on_setpoint(0)
    d.on_sync(0.0)
    assert d.watchdog(0.05) == [] and d.watchdog(0.07) == [EMCY_SYNC_TIMEOUT]
    d2 = enabled_drive()
    d2.on_setpoint(0)
    codes = []
    for k in range(10):
        codes += d2.on_sync(k * T)
    assert codes == [EMCY_RPDO_TIMEOUT]


def test_fault_reaction_brakes_then_fault_then_reset():
    d = enabled_drive()
    for k in range(50):
        d.on_setpoint(to_counts(1.2 * T * k))
        d.on_sync(k * T)
    d.raise_fault(0x5000)
    for k in range(60):
        d.on_sync(0.5 + k * T)
    assert d.state is State.FAULT and d.velocity == 0.0
    d.on_controlword(0x0000)
    assert d.on_controlword(0x0080) == [EMCY_RESET] and d.state is State.SWITCH_ON_DISABLED


def test_disabled_drive_does_not_move():
    d = Drive(DriveLimits(lower=-1, upper=1))
    d.boot(0.3)
    d.on_setpoint(to_counts(0.5))
    d.on_sync(0.0)
    assert d.position == 0.3 and d.velocity == 0.0


def test_without_sync_the_fault_reaction_brakes_on_the_drives_own_clock():
    d = enabled_drive()
    for k in range(40):                                   # moving at 1.2 rad/s
        d.on_setpoint(to_counts(1.2 * T * k))
        d.on_sync(k * T)
    t_last, v0, p0 = 39 * T, d.velocity, d.position
    assert v0 == pytest.approx(1.2, abs=0.05)
    assert d.watchdog(t_last + 0.07) == [EMCY_SYNC_TIMEOUT] and d.state is State.FAULT_REACTION_ACTIVE
    for k in range(1, 80):                                # the master is gone: no SYNC, only the drive's clock
        d.watchdog(t_last + 0.07 + k * 0.005)
    assert d.state is State.FAULT and d.velocity == 0.0
    # on at its speed until the watchdog fired, then braked at the acceleration limit
    assert d.position - p0 == pytest.approx(v0 * 0.07 + v0 ** 2 / (2 * d.limits.acceleration), rel=1e-6)
    d.on_sync(2.0)                                        # a new master: nothing left to move
    assert d.velocity == 0.0
