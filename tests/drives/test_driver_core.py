"""The robot driver's decisions as pure code, against emulated drives (hwsim.drive) in lockstep."""

import math

import numpy as np
import pytest

from hwsim.drive import Drive, DriveLimits
from shared.drives.driver_core import CLAMP_TOLERANCE, EXACT, START_WAIT, DriverCore, Feedback, Mode, follow_step
from shared.drives.prbt import to_counts, to_rad
from shared.robot.model import default_robot

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
            # the figure the text gives, for the report to pair with the commands sent meanwhile
            assert out.events[0].value > 0.05 and f"no command for {out.events[0].value * 1e3:.0f} ms" == out.events[0].text
    assert stopped_at is not None and stopped_at * T <= 0.05 + 2 * T
    assert all(d.state.value == "quick_stop_active" for d in cell.drives)
    assert max(abs(d.velocity) for d in cell.drives) == 0.0


def test_jumps_and_limits_are_clamped_with_one_event():
    cell = Cell()
    enable(cell)
    before = cell.core.cycle(cell.t, cell.feedback()).setpoints[0]
    out = cell.step(Q0 + np.array([0.5, 0, 0, 0, 0, 0]))
    assert [e.event for e in out.events] == ["command_clamped"]
    assert out.setpoints[0] - before == pytest.approx(6.0 * T * T)   # from rest: one period at the drive's a
    out = cell.step(Q0 + np.array([0.5, 0, 0, 0, 0, 0]))
    assert out.events == []                                    # one event per episode
    for _ in range(100):
        out = cell.step(Q0 + np.array([0.5, 0, 0, 0, 0, 0]))
    assert all(d.state.value == "operation_enabled" for d in cell.drives)   # the drives never saw a jump
    assert out.setpoints[0] == pytest.approx(Q0[0] + 0.5) and cell.q[0] == pytest.approx(Q0[0] + 0.5, abs=1e-4)


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


def test_frames_lost_stop_the_drives_and_a_late_answer_now_and_then_does_not():
    """Four SYNCs of every hundred not answered in time (a busy host): the drives go on. Five within a
    hundred: frames are being lost, a stop with its event; a recovery request enables them again."""
    from shared.drives.driver_core import MISSED_LIMIT, MISSED_WINDOW
    cell = Cell()
    enable(cell)
    for k in range(3 * MISSED_WINDOW):
        out = cell.core.cycle(cell.t, cell.feedback(), answered=k % (MISSED_WINDOW // (MISSED_LIMIT - 1) + 1) != 0)
        cell.core.command(cell.q, cell.t)
        cell.t += T
        assert out.mode is Mode.RUNNING, k
    events = []
    for k in range(MISSED_LIMIT):
        cell.core.command(cell.q, cell.t)
        out = cell.core.cycle(cell.t, cell.feedback(), answered=False)
        events += out.events
        cell.t += T
    assert out.mode is Mode.STOPPED and [e.event for e in events] == ["frames_lost"]
    assert events[0].severity == "stop" and f"{MISSED_LIMIT} of the last {MISSED_WINDOW}" in events[0].text
    cell.core.request("recover")
    for _ in range(30):
        out = cell.step(cell.q)
    assert out.mode is Mode.RUNNING


def test_a_command_that_moves_past_the_robot_is_not_started():
    """A path under way that passes where the robot stands (a scaler's old path, run on for a few ticks after it
    was held up) is not a start: the robot at rest would chase it at its limits. The same command at rest is."""
    cell = Cell()
    for k in range(-10, 11):              # 1 rad/s on joint 1, through Q0 at k = 0 (within start_tolerance at |k| <= 2)
        q = Q0 + np.array([0.01 * k, 0, 0, 0, 0, 0])
        cell.core.command(q, cell.t, qd=np.array([1.0, 0, 0, 0, 0, 0]))
        out = cell.step()
        assert out.mode is Mode.ENABLING
    assert np.allclose(cell.q, Q0, atol=1e-4)
    cell.core.command(Q0 + 0.005, cell.t, qd=np.zeros(6))
    out = cell.step()
    assert out.mode is Mode.RUNNING


@pytest.mark.parametrize("command, said", [(lambda t: (Q0 + 0.3, None), "mrad from the robot"),
                                           (lambda t: (Q0, np.full(6, 0.5)), "moves at 0.500 rad/s"),
                                           (None, "no command yet")])
def test_drives_enabled_without_a_command_to_start_on_say_why_once(command, said):
    cell = Cell()
    told = []
    for _ in range(int(2 * START_WAIT / T)):
        if command is not None:
            q, qd = command(cell.t)
            cell.core.command(q, cell.t, qd=qd)
        told += [e for e in cell.step().events if e.event == "not_started"]
    assert len(told) == 1 and said in told[0].text and told[0].severity == "warning"
    assert cell.core.mode is Mode.ENABLING


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


def test_why_the_drives_are_stopped_is_kept_until_they_run_again():
    cell = Cell()
    enable(cell)
    assert cell.core.stopped_by == ""
    cell.drives[2].raise_fault(0x8100)
    cell.emcy[2] = 0x8100                                     # its EMCY, as the CAN master hands it on
    out = cell.step(cell.q)
    assert out.mode is Mode.STOPPED
    assert cell.core.stopped_by == "joint 3: EMCY 0x8100 (no SYNC within the drive's time-out)"
    for _ in range(5):                                        # still stopped: still said, for `hrc status`
        cell.step(cell.q)
    assert cell.core.stopped_by.startswith("joint 3: EMCY 0x8100")
    cell.core.request("recover")
    for _ in range(30):
        out = cell.step(cell.q)
    assert out.mode is Mode.RUNNING and cell.core.stopped_by == ""


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


def test_abrupt_commands_never_trip_a_drive_and_it_stays_one_period_behind():
    """Random commands (jumps, full-speed runs, dead stops like the scaler's alpha = 0) through the core:
    every setpoint is followable, so the drives never fault, never saturate, and their following error
    stays at the count level while the measured joints are one period behind the setpoints."""
    rng = np.random.default_rng(4)
    cell = Cell()
    enable(cell)
    target, previous, velocities = cell.q.copy(), None, []
    for k in range(600):
        if k % 40 == 0:                                          # a new far command every 0.4 s
            target = np.clip(Q0 + rng.uniform(-1.0, 1.0, 6), LIM.lower, LIM.upper)
        command = target if rng.random() < 0.7 else cell.q + rng.normal(0.0, 0.2, 6)   # and noise
        out = cell.step(command)
        assert all(d.state.value == "operation_enabled" for d in cell.drives), k
        assert not any(d.saturated for d in cell.drives), k
        if previous is not None:
            assert np.abs(cell.q - previous).max() < 1e-4       # measured = the setpoint of one SYNC before
        previous = out.setpoints
        velocities.append(out.setpoint_velocity)
        assert max(abs(d.following_error) for d in cell.drives) < 1e-4
    v = np.array(velocities)
    assert np.abs(v).max() <= 1.57 + 1e-9 and np.abs(np.diff(v, axis=0)).max() <= 6.0 * T + 1e-9
    assert np.abs(v).max() > 1.0                                 # it did run fast


def test_a_stop_at_full_speed_is_the_drives_fastest_stop():
    cell = Cell()
    enable(cell)
    start = cell.q.copy()
    for k in range(60):                                          # joint 1 accelerates at 3 rad/s^2 to 1.5 rad/s
        t = (k + 1) * T
        v = min(3.0 * t, 1.5)
        x = 1.5 * t * t if t <= 0.5 else 0.375 + 1.5 * (t - 0.5)
        cell.core.command(start - np.array([x, 0, 0, 0, 0, 0]), cell.t, np.array([-v, 0, 0, 0, 0, 0]))
        cell.step()
    held = cell.core._command.copy()
    velocities, positions = [], []
    for _ in range(100):                                         # the scaler says: stop here (alpha = 0)
        cell.core.command(held, cell.t, np.zeros(6))
        out = cell.step()
        velocities.append(out.setpoint_velocity[0])
        positions.append(cell.q[0])
    assert held[0] - min(positions) <= 1.5 ** 2 / (2 * 6.0) + 0.01   # the braking distance, no more
    assert all(d.state.value == "operation_enabled" for d in cell.drives)
    dv = np.abs(np.diff(velocities)) / T
    assert dv.max() <= 6.0 + 1e-6                                # decelerating at the drive's limit, no faster
    assert np.abs(cell.q - held).max() < 1e-3                    # and back where the command stopped


def test_a_scaler_on_its_own_clock_is_followed_without_clamping():
    """The scaler ticks every 10 ms on its own clock, at a phase of its own and late now and then (a busy
    machine): some SYNCs find no new command (the last one is taken twice), the next finds two (one is
    never taken). The setpoints follow the motion the commands describe: no clamping, no drive behind."""
    from evidence.scenarios import Q_GOAL
    from shared.core.trajectory import straight_line_trajectory
    rng = np.random.default_rng(3)
    cell = Cell()
    enable(cell)
    traj = straight_line_trajectory(cell.q, Q_GOAL, LIM.velocity, LIM.acceleration)
    t0, events, late = cell.t, [], 0
    arrivals = []                                  # (arrival time, tick number)
    for k in range(int(traj.duration / T) + 30):
        delay = 0.004 + (0.008 if rng.random() < 0.15 else rng.uniform(0.0, 0.003))
        arrivals.append((t0 + k * T + delay, k))
    sent = 0
    while cell.t < t0 + traj.duration + 0.25:
        fresh = False
        while sent < len(arrivals) and arrivals[sent][0] <= cell.t:
            k = arrivals[sent][1]
            q, dq, _ = traj.sample(min((k + 1) * T, traj.duration))
            cell.core.command(q, arrivals[sent][0], dq if (k + 1) * T < traj.duration else np.zeros(6))
            sent, fresh = sent + 1, True
        late += not fresh
        out = cell.step()
        events += [e.event for e in out.events]
        assert not any(d.saturated for d in cell.drives)
    assert late > 5                                # the case did happen
    assert "command_clamped" not in events
    assert np.abs(cell.q - Q_GOAL).max() < 1e-3


def test_a_setpoint_left_behind_meets_a_braking_command_at_its_stop_without_overshooting():
    """Joint 1's setpoint 130 mrad behind a command at the velocity limit (a drive never makes that up while
    the command runs there): when the command brakes at the drives' deceleration to rest, the setpoint brakes
    later but no harder, and stops where the command stopped, never beyond it and back (before: 104 mrad
    past the stop, then back at 0.78 rad/s, towards the person the scaler had braked for)."""
    a, v_max = LIM.monitor_acceleration[0], LIM.velocity[0]
    q0 = (LIM.lower + LIM.upper) / 2
    command, w = q0.copy(), np.zeros(6)
    setpoint, velocity = q0.copy(), np.zeros(6)
    command[0], w[0] = q0[0] + 0.13, v_max
    setpoint[0], velocity[0] = q0[0], v_max
    path, speeds = [], []
    for k in range(200):
        if k > 0:                                             # the command: at v_max for 5 periods, then braking
            w[0] = v_max if k < 5 else max(w[0] - a * T, 0.0)
            command[0] += w[0] * T if k < 5 else (w[0] + min(w[0] + a * T, v_max)) / 2 * T
        setpoint, velocity, _ = follow_step(command, w, setpoint, velocity, LIM, T)
        path.append(setpoint[0])
        speeds.append(velocity[0])
    rest = command[0]
    assert w[0] == 0.0 and max(path) <= rest + 1e-3, (max(path) - rest)
    assert abs(path[-1] - rest) < 1e-6
    assert np.abs(np.diff(speeds)).max() <= a * T + 1e-9 and max(speeds) <= v_max + 1e-9


def follow_step_reference(command, command_velocity, setpoint, velocity, limits, period):
    """follow_step's definition in numpy, vectorised (what the compiled kernel must reproduce exactly)."""
    lower, upper = limits.lower, limits.upper
    v_max, a = limits.velocity, limits.monitor_acceleration
    with np.errstate(invalid="ignore"):
        target = np.clip(command, lower, upper)
        w = np.clip(np.nan_to_num(command_velocity), -v_max, v_max)
        rest = target - setpoint - w * period
        correction = np.sign(rest) * np.minimum(np.abs(rest) / period, np.sqrt(2.0 * a * np.abs(rest)))
        step = a * period
        ahead = target + w * np.abs(w) / (2.0 * a) + w * period - setpoint
        forward = np.sqrt(step * step + 2.0 * a * np.maximum(ahead + step * period, 0.0)) - step
        backward = np.sqrt(step * step + 2.0 * a * np.maximum(step * period - ahead, 0.0)) - step
        wanted = np.clip(w + correction, -backward, forward)
        new_v = np.clip(wanted, velocity - a * period, velocity + a * period)
        room_up = np.sqrt(2.0 * a * np.maximum(upper - setpoint, 0.0))
        room_down = np.sqrt(2.0 * a * np.maximum(setpoint - lower, 0.0))
        new_v = np.clip(new_v, -np.minimum(v_max, room_down), np.minimum(v_max, room_up))
        new_s = np.clip(setpoint + new_v * period, lower, upper)
        new_v = (new_s - setpoint) / period
        clamped = bool(np.any(np.abs(new_s - command) > CLAMP_TOLERANCE) or np.any(target != command))
        return np.where(np.abs(new_s - target) <= EXACT, target, new_s), new_v, clamped


def test_the_compiled_follow_step_is_its_numpy_definition_to_the_bit():
    """Random setpoints, velocities and commands (near and beyond the limits, abrupt, exactly followable,
    NaN and infinite ones): the same setpoint, velocity and clamp flag as the numpy definition, bit for bit."""
    rng = np.random.default_rng(7)
    specials = np.array([np.nan, np.inf, -np.inf, 0.0])
    for k in range(4000):
        setpoint = rng.uniform(LIM.lower - 0.05, LIM.upper + 0.05)
        velocity = rng.uniform(-1.2, 1.2, 6) * LIM.velocity
        command = setpoint + rng.choice([0.0, 1e-4, 0.01, 0.3, 5.0]) * rng.normal(size=6)
        command_velocity = rng.normal(size=6) * rng.choice([0.0, 0.5, 3.0])
        if k % 5 == 0:                                 # exactly followable: one period along its velocity
            command = setpoint + velocity * T
            command_velocity = velocity.copy()
        if k % 7 == 0:
            command_velocity[rng.integers(6)] = rng.choice(specials)
        if k % 11 == 0:
            command[rng.integers(6)] = rng.choice(specials)
        if k % 13 == 0:
            setpoint[rng.integers(6)] = np.nan
        got = follow_step(command, command_velocity, setpoint, velocity, LIM, T)
        want = follow_step_reference(command, command_velocity, setpoint, velocity, LIM, T)
        assert np.array_equal(got[0], want[0], equal_nan=True), (k, got[0], want[0])
        assert np.array_equal(got[1], want[1], equal_nan=True), (k, got[1], want[1])
        assert got[2] == want[2], k


def test_a_recovery_asked_while_a_quick_stop_still_brakes_waits_for_rest_and_faults_no_drive():
    """A stale_command stop at full speed, and the operator's recovery request 40 ms later, the robot still braking
    at 1.3 rad/s, the scaler holding where the robot is until the driver follows again, then that place (a loaded
    run, 2026-12-05: enabled at once, the drives overran that setpoint by 0.1 rad and raised EMCY 0x8611; this test
    raises it on the code before). The quick stop ends at rest first; then the drives run again, with no fault."""
    cell = Cell()
    enable(cell)
    q = cell.q.copy()
    for k in range(60):                                    # joint 1 up to 1.5 rad/s
        q[0] -= min(1.5, 6.0 * T * (k + 1)) * T
        cell.step(q)
    assert abs(cell.drives[0].velocity) > 1.4
    while cell.core.mode is not Mode.STOPPED:               # no command: the stale-command stop
        cell.step()
    for _ in range(4):
        cell.step()
    assert abs(cell.drives[0].velocity) > 1.0               # still braking
    cell.core.request("recover")
    events, held = [], cell.q.copy()
    for _ in range(60):
        if cell.core.mode is not Mode.RUNNING:     # the scaler holds where the robot is until the driver follows
            held = cell.q.copy()
        out = cell.step(held)
        events += [e.event for e in out.events]
        if out.mode is not Mode.STOPPED:
            assert max(abs(d.velocity) for d in cell.drives) < 0.05          # enabled only once at rest
    assert out.mode is Mode.RUNNING and "emcy" not in events and "drive_fault" not in events
    assert all(d.state.value == "operation_enabled" for d in cell.drives)
