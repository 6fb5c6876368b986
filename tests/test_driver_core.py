"""The robot driver's decisions as pure code, against emulated drives (hwsim.drive) in lockstep."""

import math

import numpy as np
import pytest

from hwsim.drive import Drive, DriveLimits, to_counts, to_rad
from services.driver_core import DriverCore, Feedback, Mode
from shared.robot_model import default_robot

LIM = default_robot().limits
T = 0.01
Q0 = np.array([1.57, -0.4, 1.17, 0.0, 1.57, 0.0])


class Cell:
    """Six pure drives and the core, one SYNC per step (what goes over the bus, without the bus)."""

    def __init__(self):
        self.drives = [Drive(DriveLimits(float(lo), float(hi), 1.57, 6.0, T)) for lo, hi in zip(LIM.lower, LIM.upper)]
        for d, q in zip(self.drives, Q0):
            d.boot(float(q))
            d.mode = 7
        self.core = DriverCore(LIM, T)
        self.t = 0.0
        self.heartbeat_age = [0.0] * 6
        self.emcy = [None] * 6

    def feedback(self):
        return [Feedback(d.statusword(), to_rad(to_counts(d.position)), d.velocity, self.heartbeat_age[k], self.emcy[k])
                for k, d in enumerate(self.drives)]

    def step(self, command=None):
        if command is not None:
            self.core.command(command, self.t)
        out = self.core.cycle(self.t, self.feedback())
        self.emcy = [None] * 6
        for d, cw, sp in zip(self.drives, out.controlwords, out.setpoints):
            d.on_controlword(cw)
            d.on_setpoint(to_counts(sp))
            codes = d.on_sync(self.t)
            if codes:
                self.emcy[self.drives.index(d)] = codes[0]
        self.t += T
        return out

    @property
    def q(self):
        return np.array([d.position for d in self.drives])


def enable(cell):
    for _ in range(20):
        out = cell.step(cell.q)
    assert out.mode is Mode.RUNNING
    return out


def test_enable_sequence_reaches_running_with_a_command_at_the_robot():
    cell = Cell()
    out = cell.step()
    assert out.mode is Mode.ENABLING and out.controlwords[0] == 0x0106
    enable(cell)
    assert all(d.interpolating for d in cell.drives)


def test_command_far_from_the_robot_is_not_started():
    cell = Cell()
    for _ in range(20):
        out = cell.step(Q0 + 0.3)
    assert out.mode is Mode.ENABLING and np.allclose(cell.q, Q0, atol=1e-4)


def test_follows_a_trajectory_and_stops_on_a_stale_command():
    cell = Cell()
    enable(cell)
    for k in range(100):
        target = Q0 + np.array([-0.5 * (1 - math.cos(math.pi * k / 100)), 0, 0, 0, 0, 0]) * 0.5
        cell.step(target)
    assert np.abs(cell.q - target).max() < 0.03
    stopped_at = None
    for k in range(20):
        out = cell.step()
        if out.mode is Mode.STOPPED and stopped_at is None:
            stopped_at = k
            assert out.events[0].event == "stale_command" and out.events[0].severity == "stop"
    assert stopped_at is not None and stopped_at * T <= 0.05 + 2 * T
    assert all(d.state.value == "quick_stop_active" for d in cell.drives)
    assert max(abs(d.velocity) for d in cell.drives) == 0.0


def test_jumps_and_limits_are_clamped_with_one_event():
    cell = Cell()
    enable(cell)
    before = cell.core.cycle(cell.t, cell.feedback()).setpoints[0]
    out = cell.step(Q0 + np.array([0.5, 0, 0, 0, 0, 0]))
    assert [e.event for e in out.events] == ["command_clamped"]
    assert out.setpoints[0] - before == pytest.approx(1.57 * T)
    out = cell.step(Q0 + np.array([0.5, 0, 0, 0, 0, 0]))
    assert out.events == []                                    # one event per episode
    assert all(d.state.value == "operation_enabled" for d in cell.drives)   # the drives never saw a jump


@pytest.mark.parametrize("fault", ["heartbeat", "drive_fault", "emcy"])
def test_faults_stop_all_drives(fault):
    cell = Cell()
    enable(cell)
    if fault == "heartbeat":
        cell.heartbeat_age[2] = 0.5
    elif fault == "drive_fault":
        cell.drives[4].raise_fault(0x5000)
    else:
        cell.emcy[1] = 0x8611
    out = cell.step(cell.q)
    assert out.mode is Mode.STOPPED and out.events[0].severity == "stop"
    for _ in range(3):
        cell.step(cell.q)
    assert all(d.state.value in ("quick_stop_active", "fault", "switch_on_disabled") for d in cell.drives)


def test_recovery_only_when_asked_and_safe():
    cell = Cell()
    enable(cell)
    cell.drives[3].raise_fault(0x5000)
    for _ in range(5):
        out = cell.step(cell.q)
    assert out.mode is Mode.STOPPED
    cell.heartbeat_age[0] = 1.0
    cell.core.request("recover")
    out = cell.step(cell.q)
    assert out.mode is Mode.STOPPED and any(e.event == "recover_refused" for e in out.events)
    cell.heartbeat_age[0] = 0.0
    cell.core.request("recover")
    for _ in range(30):
        out = cell.step(cell.q)
    assert out.mode is Mode.RUNNING and all(d.interpolating for d in cell.drives)


def test_an_early_command_gives_the_setpoint_the_next_cycle_will_send():
    cell = Cell()
    assert cell.core.command(Q0, cell.t) is None               # not running yet: nothing goes out early
    enable(cell)
    target = cell.q + np.array([0.001, 0, 0, 0, 0, -0.002])
    early = cell.core.command(target, cell.t)
    out = cell.step()
    assert np.array_equal(early, out.setpoints)
    far = cell.core.command(cell.q + 1.0, cell.t)               # rate-limited like the cycle
    assert np.abs(far - cell.core.cycle(cell.t, cell.feedback()).setpoints).max() < 1e-12
