"""The emulated drive as pure code: interpolated position motion (one period behind followable setpoints,
saturating beyond the limits), the following error window, protections, fault reset."""

import math

import numpy as np
import pytest

from hwsim.drive import Drive, DriveLimits
from shared.drives.cia402 import State
from shared.drives.prbt import (
    COUNTS_PER_RAD,
    EMCY_FOLLOWING,
    EMCY_LIMIT,
    EMCY_RESET,
    EMCY_RPDO_TIMEOUT,
    EMCY_SYNC_TIMEOUT,
    FOLLOWING_TIMEOUT,
    FOLLOWING_WINDOW,
    to_counts,
    to_rad,
)

T = 0.01


def enabled_drive(position=0.0):
    d = Drive(DriveLimits(lower=-2.96706, upper=2.96706))
    d.boot(position)
    d.mode = 7
    for cw in (0x0106, 0x0107, 0x010F, 0x001F):
        d.on_controlword(cw)
    assert d.state is State.OPERATION_ENABLED and d.interpolating
    return d


def run(d, setpoints, t0=0.0):
    """Feed one setpoint per SYNC; returns (positions at each SYNC, following errors, EMCY codes)."""
    pos, err, codes = [], [], []
    for k, sp in enumerate(setpoints):
        d.on_setpoint(to_counts(sp))
        codes += d.on_sync(t0 + k * T)
        pos.append(d.position)
        err.append(d.following_error)
    return np.array(pos), np.array(err), codes


def trapezoid(distance, v, a, n):
    """Setpoints at t = T, 2T, ... nT of a trapezoidal move from 0 over `distance` rad (peak v rad/s,
    a rad/s^2), the time law sampled exactly."""
    v = min(v, math.sqrt(distance * a))                   # a triangle when too short to reach v
    t_acc, d_acc = v / a, v * v / (2 * a)
    t_end = 2 * t_acc + (distance - 2 * d_acc) / v
    t = np.minimum(T * np.arange(1, n + 1), t_end)
    rise = 0.5 * a * np.minimum(t, t_acc) ** 2 + v * np.clip(t - t_acc, 0.0, None)
    fall = 0.5 * a * np.clip(t - (t_end - t_acc), 0.0, None) ** 2
    return np.minimum(rise - fall, distance)


def test_units_are_millidegrees():
    assert to_counts(math.radians(170.0)) == 170000 and to_rad(90000) == pytest.approx(math.pi / 2)


def test_constant_speed_is_followed_one_period_behind():
    d = enabled_drive()
    v = 0.95 * 1.57
    sp = trapezoid(10.0, v, 6.0, 100)                    # up to speed at the drive's own acceleration
    pos, err, codes = run(d, sp)
    assert codes == [] and not d.saturated
    steady = slice(40, None)                             # at speed
    lag = (sp[steady] - pos[steady]) / v                 # the setpoint sent at k is reached at k+1
    assert np.all(np.abs(lag - T) < 1e-4)
    assert np.max(np.abs(err[steady])) < 2 / 57295.8     # 0x60F4: within quantisation
    assert d.velocity_actual == pytest.approx(v, abs=1e-3)


def test_acceleration_ramps_within_the_limits_are_followed_within_two_periods():
    d = enabled_drive()
    sp = trapezoid(1.2, 1.49, 3.0, 150)                   # the trapezoid: 1.49 rad/s, 3 rad/s^2
    pos, err, codes = run(d, sp)
    assert codes == [] and not d.saturated
    # each measured position is a setpoint of at most two periods before
    for k in range(2, len(sp)):
        assert sp[k - 2] - 1e-4 <= pos[k] <= sp[k] + 1e-4
    assert np.max(np.abs(err)) < 1e-3
    assert pos[-1] == pytest.approx(1.2, abs=1e-4)


def test_beyond_the_acceleration_limit_it_saturates_and_lands_without_overshoot():
    d = enabled_drive()
    v = 0.6
    sp = trapezoid(10.0, v, 3.0, 60)
    run(d, sp)
    stop_at = sp[-1]
    pos, err, codes = run(d, [stop_at] * 80, t0=0.6)   # the setpoints stop at once: 60 rad/s^2 implied
    assert codes == []                                   # 0.03 rad of braking: within the window
    assert np.max(np.abs(err)) > 0.02                    # it really fell behind (saturated)
    vel = np.diff(pos) / T
    assert np.max(np.abs(np.diff(vel))) <= 6.0 * T + 2 / COUNTS_PER_RAD / T + 1e-9   # its acceleration (+ 2 counts)
    assert np.max(pos) <= stop_at + v * v / (2 * 6.0) + 1e-3          # it braked, it did not bounce
    assert pos[-1] == pytest.approx(stop_at, abs=1e-4) and abs(d.velocity) < 1e-6


def test_following_error_beyond_the_window_for_the_time_out_faults_with_emcy():
    d = enabled_drive()
    pos, err, codes = run(d, np.full(20, 0.5))          # a jump of 0.5 rad: saturated at once
    assert codes == [EMCY_FOLLOWING]
    assert d.state in (State.FAULT_REACTION_ACTIVE, State.FAULT)
    d2 = enabled_drive()                                 # setpoints that stop dead from 1.5 rad/s: 0.19 rad
    run(d2, trapezoid(10.0, 1.5, 3.0, 60))              # of braking, beyond the window for longer than
    _, _, codes = run(d2, np.full(30, trapezoid(10.0, 1.5, 3.0, 60)[-1]), t0=0.6)   # the time-out
    assert codes == [EMCY_FOLLOWING]


def test_the_window_and_time_out_decide_when_it_trips():
    for window, timeout, trips in ((0.05, 0.05, True), (0.6, 0.05, False), (0.05, 1.0, False)):
        d = Drive(DriveLimits(lower=-3, upper=3, following_window=window, following_timeout=timeout))
        d.boot(0.0)
        d.mode = 7
        for cw in (0x0106, 0x0107, 0x010F, 0x001F):
            d.on_controlword(cw)
        _, err, codes = run(d, np.full(40, 0.5))
        assert (codes == [EMCY_FOLLOWING]) is trips, (window, timeout)


def test_time_to_trip_is_the_time_out_after_leaving_the_window():
    d = enabled_drive()
    times = []
    for k in range(20):
        d.on_setpoint(to_counts(0.5))
        c = d.on_sync(k * T)
        if abs(d.following_error) > FOLLOWING_WINDOW:
            times.append(k * T)
        if c:
            assert c == [EMCY_FOLLOWING]
            assert k * T - times[0] == pytest.approx(FOLLOWING_TIMEOUT, abs=1e-9)
            return
    pytest.fail("no following error fault")


def test_setpoint_beyond_the_limit_faults_with_emcy():
    d = enabled_drive(2.9)
    d.on_setpoint(to_counts(2.99))
    assert d.on_sync(0.0) == [EMCY_LIMIT]
    assert d.state is State.FAULT                            # at rest: the fault reaction is over at once


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


def test_the_watchdog_is_due_at_the_sync_time_out_and_at_each_braking_step_without_sync():
    from hwsim.emulator import WATCHDOG_STEP, next_watchdog
    from shared.scheduling import WAKE_LATE as LATE

    d = enabled_drive()
    assert d.watchdog_due(WATCHDOG_STEP) is None                # no SYNC yet: nothing to watch
    idle = Drive(DriveLimits(lower=-1, upper=1))
    assert next_watchdog([idle], 0.0) == pytest.approx(0.5 * 6 * T)      # half a time-out
    run(d, trapezoid(10.0, 1.2, 6.0, 40))                       # moving at 1.2 rad/s
    t_last = 39 * T
    assert d.watchdog_due(WATCHDOG_STEP) == pytest.approx(t_last + 6 * T)
    # a thread woken when the time-out is due finds the fault exactly then, not a poll later
    assert next_watchdog([d], t_last + T) == pytest.approx(5 * T + LATE)
    assert d.watchdog(t_last + 6 * T - 1e-6) == [] and d.watchdog(t_last + 6 * T + LATE) == [EMCY_SYNC_TIMEOUT]
    moved = t_last + 6 * T + LATE
    assert d.state is State.FAULT_REACTION_ACTIVE
    assert d.watchdog_due(WATCHDOG_STEP) == pytest.approx(moved + WATCHDOG_STEP)   # braking on its own clock
    now = moved
    while d.state is State.FAULT_REACTION_ACTIVE:
        now += next_watchdog([d], now)
        d.watchdog(now)
    assert d.velocity == 0.0 and d.state is State.FAULT
    assert d.watchdog_due(WATCHDOG_STEP) is None               # at rest in fault: nothing more until SYNC
    d.on_sync(now + 1.0)                                        # a master is back
    assert d.watchdog_due(WATCHDOG_STEP) is None and d.state is State.FAULT


def test_a_held_setpoint_is_kept_until_the_rpdo_time_out():
    d = enabled_drive()
    pos, _, _ = run(d, [0.0005, 0.0015, 0.003])
    for k in range(6):                                   # no new setpoint for a few SYNCs: hold the last one
        assert d.on_sync(0.03 + k * T) == []
    assert d.position == pytest.approx(0.003, abs=2e-3) and d.state is State.OPERATION_ENABLED


def test_fault_reaction_brakes_then_fault_then_reset():
    d = enabled_drive()
    run(d, trapezoid(10.0, 1.2, 6.0, 50))
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
    d.on_sync(0.01)
    assert d.position == 0.3 and d.velocity == 0.0


def test_without_sync_the_fault_reaction_brakes_on_the_drives_own_clock():
    d = enabled_drive()
    run(d, trapezoid(10.0, 1.2, 6.0, 40))                 # moving at 1.2 rad/s
    t_last, v0, p0 = 39 * T, d.velocity, d.position
    assert v0 == pytest.approx(1.2, abs=0.05)
    assert d.watchdog(t_last + 0.07) == [EMCY_SYNC_TIMEOUT] and d.state is State.FAULT_REACTION_ACTIVE
    for k in range(1, 80):                                # the master is gone: no SYNC, only the drive's clock
        d.watchdog(t_last + 0.07 + k * 0.005)
    assert d.state is State.FAULT and d.velocity == 0.0
    # on at its speed until the watchdog fired, then braked at the acceleration limit
    assert d.position - p0 == pytest.approx(v0 * 0.07 + v0 ** 2 / (2 * d.limits.acceleration), rel=1e-6)
    p_rest = d.position
    d.on_sync(2.0)                                        # a new master: nothing left to move
    assert d.velocity == 0.0 and d.position == p_rest


def test_a_sync_the_drive_does_not_receive_is_a_period_on_its_own_clock_holding_the_last_setpoint():
    """At 1 rad/s, one SYNC lost: the joint moves on through that period (it does not stop and restart in an
    instant), then brakes at most a T towards the held setpoint; the next SYNC takes the newest setpoint and
    the drive is back on the setpoints within a few periods, its velocity never changing faster than its
    acceleration limit. Six lost in a row are the SYNC time-out, and the position is counted once."""
    d = enabled_drive()
    v, a = 1.0, d.limits.acceleration
    setpoints = trapezoid(2.0, v, 3.0, 60)                           # at 1 rad/s from 0.33 s on
    positions, velocities = [], []
    for k in range(1, 61):
        d.on_setpoint(to_counts(setpoints[k - 1]))
        if k == 45:
            before = d.position
            d.on_missed_sync()
            assert d.position == pytest.approx(before + d.velocity_actual * T)
            assert d.position > before + 0.9 * v * T                  # it went on through the lost period
        else:
            d.on_sync(k * T)
        positions.append(d.position)
        velocities.append(d.velocity_actual)
    assert np.abs(np.diff(velocities)).max() <= a * T + 2 * (2.0 / COUNTS_PER_RAD / T) + 1e-9
    assert positions[-1] == pytest.approx(setpoints[-2], abs=2e-5)    # one period behind again
    assert not d.fault_code
    d2 = enabled_drive()
    d2.on_setpoint(0)
    d2.on_sync(0.0)
    d2.velocity = 0.5
    for k in range(1, 7):
        d2.on_missed_sync()
    p6, v6 = d2.position, d2.velocity
    assert p6 > 0.0                                                    # it moved through the six periods
    assert d2.watchdog(0.065) == [EMCY_SYNC_TIMEOUT]
    assert d2.position == pytest.approx(p6 + v6 * 0.005)               # the last 5 ms only, not all 65 again
