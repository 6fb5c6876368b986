"""The scaler, tracker_ingest and the safety monitor as service classes, in-process on a fake shell (the real
ServiceShell over an in-memory session): their handling of every input, the messages they publish, and
bad input dropped with the service going on. The multi-process tests (test_system, test_demo_processes)
run the same classes over Zenoh."""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import replace

import numpy as np
import pytest

from evidence.scenarios import Q_GOAL, Q_START
from services.safety_monitor import MonitorService
from services.scaler import Scaler
from services.tracker_ingest import INVALID_PERIOD, TrackerIngest, next_check
from shared.config import CellConfig
from shared.core.humans import HumanCapsules
from shared.core.trajectory import straight_line_trajectory
from shared.robot.model import default_robot
from shared.safety.monitor import SafetyMonitor
from shared.safety.parameters import SsmParameters
from shared.scaling.layer import ScalingLayer
from shared.scaling.parameters import ScalingParameters
from shared.scheduling import WAKE_LATE as LATE
from shared.tracking.tracker import HumanTracker, TrackerParameters
from shared.wire.convert import humans_to_msg, trajectory_to_msg
from shared.wire.messages import (
    DriveLagReport,
    HumanRaw,
    HumanState,
    JointCommand,
    JointState,
    MonitorReport,
    SafetyEvent,
    ScalerStatus,
)
from tests.fake_shell import FakeShell

ROBOT = default_robot()
# The paper's formula (the measured human speed held): these tests hold the layers' logic on the paper's
# numbers; the shipped human model's own figures are tests/safety/test_ssm.py's and the cell's.
CONFIG = CellConfig(ssm=SsmParameters().paper_formula())
LIM = ROBOT.limits
FAR = HumanCapsules.from_arrays([[[-3.0, 0.0, 0.9], [-3.0, 0.0, 1.5]]], [0.2], np.zeros((1, 2, 3)), [True])


def joint_state(q, enabled: bool = True, stamp: float | None = None) -> JointState:
    """A driver's joint state, published at `stamp` (s, monotonic; default now)."""
    return JointState(q=np.asarray(q, float), qd=np.zeros(6), drive_state="running:operation_enabled",
                      enabled=enabled, fault=False, stamp=time.monotonic() if stamp is None else stamp)


# ---------------------------------------------------------------------------------------------- scaler
class TickClock:
    """The clock a test's scaler takes joint states' arrival from: the time of the test's next tick."""

    def __init__(self) -> None:
        self.now = time.monotonic()

    def __call__(self) -> float:
        return self.now


def robot_follows(shell: FakeShell, scaler: Scaler, at: float) -> None:
    """The driver's part before the tick at `at` (s): a joint state where the last command put the robot (q_s
    before the first), as the driver publishes one a SYNC. Without it the scaler stops the robot after
    robot_timeout."""
    commands = shell.published(shell.keys.command, JointCommand)
    scaler.arrival_clock.now = at
    shell.deliver(shell.keys.joint_state, joint_state(commands[-1].q if commands else Q_START, stamp=at))


def scaler_at_start(scaling: ScalingParameters = CONFIG.scaling) -> tuple[FakeShell, Scaler, object]:
    """A scaler on a fake shell, told that the robot stands at q_s and follows commands (the state's arrival
    on a TickClock: ``robot_follows``)."""
    shell = FakeShell("scaler")
    scaler = Scaler(shell, ScalingLayer(ROBOT, CONFIG.ssm, scaling), arrival_clock=TickClock())
    shell.deliver(shell.keys.joint_state, joint_state(Q_START))
    return shell, scaler, shell.keys


def test_the_scaler_follows_a_fresh_trajectory_and_publishes_a_command_and_a_status_each_tick():
    shell, scaler, keys = scaler_at_start()
    traj = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration, version=1)
    shell.deliver(keys.trajectory, trajectory_to_msg(traj, 1, "goal", 0.0, -1))
    now = time.monotonic()
    for k in range(30):
        robot_follows(shell, scaler, now + k * 0.01)
        shell.deliver(keys.human_state, humans_to_msg(FAR, True, now + k * 0.01))
        scaler.tick(now + k * 0.01)
    commands = shell.published(keys.command, JointCommand)
    statuses = shell.published(keys.scaler_status, ScalerStatus)
    assert len(commands) == len(statuses) == 30
    assert scaler.version == 1 and statuses[-1].trajectory_version == 1
    assert statuses[-1].s > 0.0 and statuses[-1].alpha > 0.9            # nobody near: full speed
    assert not np.allclose(commands[-1].q, Q_START)                       # moving along the shuttle


def test_the_scaler_takes_the_newest_human_state_at_its_tick_and_reports_its_latency_once():
    """Human states are queued by Zenoh and taken at the tick: of two that came between ticks both are checked
    (HumanCapsules.union), the newer dates them, and the first command computed from it carries its sample
    time and how long it waited since tracker_ingest published it; the commands after it carry neither."""
    shell, scaler, keys = scaler_at_start()
    traj = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration, version=1)
    shell.deliver(keys.trajectory, trajectory_to_msg(traj, 1, "goal", 0.0, -1))
    now = time.monotonic()
    older = humans_to_msg(FAR, True, now - 0.010, stamp=now - 0.009)
    newer = humans_to_msg(FAR, True, now - 0.006, stamp=now - 0.004)
    shell.deliver(keys.human_state, older)
    shell.deliver(keys.human_state, newer)
    scaler.tick(now)
    scaler.tick(now + 0.01)
    first, second = shell.published(keys.command, JointCommand)
    assert first.human_sample_stamp == pytest.approx(now - 0.006)
    assert first.human_wait == pytest.approx(0.004)
    assert second.human_sample_stamp is None and second.human_wait is None


def test_the_scaler_keeps_its_margin_over_the_drive_lag_the_driver_measures():
    """A drive lag report of 22 ms (a slow phase of the machine) raises the tracking margin from 12 ms x 4.4
    m/s^2 to 22 ms x 4.4 m/s^2; a report within the configured lag brings it back; the configuration's own
    value is never undercut."""
    shell, scaler, keys = scaler_at_start()

    def report(lag):
        return DriveLagReport(source="robot_driver", lag=np.array([0.010, lag, 0.0, 0.0, 0.0, 0.0]),
                              samples=np.full(6, 100.0), following_error=np.zeros(6), bound=0.012, stopped_by="")

    now = time.monotonic()
    shell.deliver(keys.drive_lag, report(0.022))
    scaler.tick(now)
    assert scaler.layer.ssm.drive_lag == pytest.approx(0.022)
    assert scaler.layer.ssm.tracking_margin == pytest.approx(0.022 * 4.4)
    shell.deliver(keys.drive_lag, report(0.004))
    scaler.tick(now + 0.01)
    assert scaler.layer.ssm is scaler.configured_ssm and scaler.layer.ssm.drive_lag == CONFIG.ssm.drive_lag


def test_the_scaler_widens_its_margin_on_the_next_tick_after_a_joint_state_says_so():
    """A joint state whose drive_lag is 32 ms (a drive losing frames) raises the tracking margin at the next
    tick, without waiting for a report; the larger of the state's lag and the newest report's is covered;
    a state back at the configured lag, with no report above it, brings the margin back."""
    shell, scaler, keys = scaler_at_start()

    def state(lag):
        return JointState(q=Q_START, qd=np.zeros(6), drive_state="running:operation_enabled", enabled=True,
                          fault=False, drive_lag=lag)

    now = time.monotonic()
    shell.deliver(keys.joint_state, state(0.032))
    scaler.tick(now)
    assert scaler.layer.ssm.drive_lag == pytest.approx(0.032)
    shell.deliver(keys.drive_lag, DriveLagReport(source="robot_driver", lag=np.full(6, 0.040), samples=np.full(6, 100.0),
                                                 following_error=np.zeros(6), bound=0.012, stopped_by=""))
    scaler.tick(now + 0.01)
    assert scaler.layer.ssm.drive_lag == pytest.approx(0.040)
    shell.deliver(keys.drive_lag, DriveLagReport(source="robot_driver", lag=np.full(6, 0.010), samples=np.full(6, 100.0),
                                                 following_error=np.zeros(6), bound=0.012, stopped_by=""))
    shell.deliver(keys.joint_state, state(CONFIG.ssm.drive_lag))
    scaler.tick(now + 0.02)
    assert scaler.layer.ssm is scaler.configured_ssm


def test_the_scaler_is_woken_once_per_sync_of_the_drives():
    """A joint state for a SYNC the path has already stepped for (after a fallback tick stood in for it, or
    a second answer) wakes no tick; the next SYNC's does. Its position is still taken."""
    shell, scaler, keys = scaler_at_start()

    def state(sync, q=Q_START):
        return JointState(q=q, qd=np.zeros(6), drive_state="running:operation_enabled", enabled=True, fault=False,
                          drive_lag=0.012, sync=sync)

    now = time.monotonic()
    scaler.joint_state_arrived.clear()
    shell.deliver(keys.joint_state, state(7))
    assert scaler.joint_state_arrived.is_set()
    scaler.joint_state_arrived.clear()
    scaler.tick(now)                                     # steps for SYNC 7
    scaler.tick(now + 0.015)                             # the fallback: stands in for SYNC 8
    shell.deliver(keys.joint_state, state(8, Q_START + 0.001))        # SYNC 8's state, late
    assert not scaler.joint_state_arrived.is_set()
    assert np.allclose(scaler.joint_q, Q_START + 0.001)
    shell.deliver(keys.joint_state, state(9))
    assert scaler.joint_state_arrived.is_set()


def test_the_scaler_logs_a_sync_it_let_pass_without_a_command_with_what_woke_it(caplog):
    """A tick more than 2.5 periods after the last one: the log says how long, how long the last tick took, and
    how long the first joint state since the last tick had waited in this process (tools.silences has only the
    stamps)."""
    shell, scaler, keys = scaler_at_start()
    traj = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration, version=1)
    shell.deliver(keys.trajectory, trajectory_to_msg(traj, 1, "goal", 0.0, -1))
    def state(sync: int) -> JointState:
        return JointState(q=Q_START, qd=np.zeros(6), drive_state="running:operation_enabled", enabled=True,
                          fault=False, stamp=time.monotonic() - 0.003, sync=sync)

    with caplog.at_level(logging.WARNING, logger="scaler"):
        now = time.monotonic()
        for k in range(3):
            scaler.tick(now + 0.01 * k)                  # on time: nothing said
        scaler.tick(now + 0.02 + 0.024)                  # the fallback, 24 ms after the last: 2.4 periods, no silence
        assert not [r for r in caplog.records if "no tick" in r.getMessage()]
        shell.deliver(keys.joint_state, state(5))
        came = scaler.woken_by[0]                        # when this process had it: the first state since the tick
        shell.deliver(keys.joint_state, state(6))
        assert scaler.woken_by[0] == came
        scaler.tick(now + 0.044 + 0.061)                 # 61 ms after the last tick
        scaler.tick(now + 0.105 + 0.049)                 # a fallback 49 ms later, with no new state
    said = [r.getMessage() for r in caplog.records if "no tick" in r.getMessage()]
    assert len(said) == 2
    waited = (now + 0.105 - came) * 1e3
    assert said[0].startswith("no tick for 61.0 ms (the last took ")
    assert f"with a joint state that had waited {waited:.1f} ms for it" in said[0]
    assert "after the driver published it" in said[0]
    assert "with no new joint state (the fallback)" in said[1] and said[1].startswith("no tick for 49.0 ms")


def test_a_camera_rate_source_is_stale_after_its_own_bound():
    """A 30 Hz source (HumanState.sample_interval 1/30): 70 ms without a sample is one lost frame, not stale
    data; 90 ms is (2.5 intervals, 83 ms)."""
    shell, scaler, keys = scaler_at_start()
    traj = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration, version=1)
    shell.deliver(keys.trajectory, trajectory_to_msg(traj, 1, "goal", 0.0, -1))
    now = time.monotonic()
    shell.deliver(keys.human_state, humans_to_msg(FAR, True, now, sample_interval=1 / 30))
    scaler.tick(now + 0.07)
    assert shell.published(keys.scaler_status, ScalerStatus)[-1].status == "running"
    scaler.tick(now + 0.09)
    assert shell.published(keys.scaler_status, ScalerStatus)[-1].status == "stale_human_data"


def test_the_scaler_gives_the_layer_the_peoples_age_from_their_capture():
    """A state captured 40 ms before the tick (a camera's latency, the state's way, its wait for the tick): the
    scaling layer is given that whole age, whenever the tracker published it (it counts the person's travel over
    it); the command made on it carries the capture's stamp and its own, the tick's, so that the driver measures
    the part T_r covers (from the tick to the frame) apart from the age."""
    shell, scaler, keys = scaler_at_start()
    traj = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration, version=1)
    shell.deliver(keys.trajectory, trajectory_to_msg(traj, 1, "goal", 0.0, -1))
    given = []
    step = scaler.layer.step
    scaler.layer.step = lambda inputs: (given.append(inputs), step(inputs))[1]
    now = time.monotonic()
    for k, published in enumerate((now - 0.01, 0.0, now - 0.05)):
        shell.deliver(keys.human_state, humans_to_msg(FAR, True, now - 0.04 + k * 1e-3, stamp=published))
        scaler.tick(now)
        assert given[-1].human_age == pytest.approx(0.04 - k * 1e-3)
        command = shell.published(keys.command, JointCommand)[-1]
        assert command.stamp == now and command.human_sample_stamp == pytest.approx(now - 0.04 + k * 1e-3)


def test_the_scaler_stops_the_robot_on_stale_human_data():
    shell, scaler, keys = scaler_at_start()
    traj = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration, version=1)
    shell.deliver(keys.trajectory, trajectory_to_msg(traj, 1, "goal", 0.0, -1))
    now = time.monotonic()
    shell.deliver(keys.human_state, humans_to_msg(FAR, True, now))
    for k in range(60):                     # no new human sample for 0.6 s (the timeout is 0.05 s)
        scaler.tick(now + k * 0.01)
    last = shell.published(keys.scaler_status, ScalerStatus)[-1]
    assert last.alpha == 0.0 and last.status == "stale_human_data"


def under_way(shell: FakeShell, scaler: Scaler, ticks: int = 60) -> tuple[object, float]:
    """A straight leg q_s -> q_g (version 1) followed for `ticks` SYNCs with the person far: the leg and the time
    (s) of the next tick."""
    traj = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration, version=1)
    shell.deliver(shell.keys.trajectory, trajectory_to_msg(traj, 1, "goal", 0.0, -1))
    now = time.monotonic()
    for k in range(ticks):                            # a state each SYNC
        robot_follows(shell, scaler, now)
        shell.deliver(shell.keys.human_state, humans_to_msg(FAR, True, now))
        scaler.tick(now)
        now += 0.01
    return traj, now


def test_the_scaler_stops_the_robot_along_its_path_when_the_driver_falls_silent():
    """No joint state for scaling.robot_timeout (by when they reach the scaler): the path is braked to rest,
    not run open loop to 'finished' (a driver whose SYNC cycle had died once left the robot standing mid-path
    while the scaler reported the goal reached); the next state from a following robot sets it going again."""
    shell, scaler, keys = scaler_at_start()
    traj, now = under_way(shell, scaler)
    silent_from = scaler.joint_arrived
    for k in range(100):                              # then nothing from the driver for a second
        shell.deliver(keys.human_state, humans_to_msg(FAR, True, now))
        scaler.tick(now)
        now += 0.01
    silent = [st for st in shell.published(keys.scaler_status, ScalerStatus)[60:]]
    stale = [st.stamp - silent_from > CONFIG.scaling.robot_timeout for st in silent]
    assert [st.status == "stale_joint_state" for st in silent] == stale and any(stale) and not all(stale)
    speeds = [st.speed for st in silent if st.status == "stale_joint_state"]
    assert speeds[0] > 0.5 and np.all(np.diff(speeds) <= 1e-12) and speeds[-1] == 0.0
    assert silent[-1].s < traj.duration                # stopped on the path, short of its end
    robot_follows(shell, scaler, now)
    shell.deliver(keys.human_state, humans_to_msg(FAR, True, now))
    scaler.tick(now)
    assert shell.published(keys.scaler_status, ScalerStatus)[-1].status == "running"


def test_joint_states_that_waited_in_a_queue_are_as_old_as_their_stamps():
    """The scaler held up for 1.5 s (SIGSTOP; the fault campaign's freeze_scaler): Zenoh then delivers the joint
    states of that time at once, the oldest first, those from before the driver stopped the robot saying it
    follows. Judged fresh by their arrival, they set the old path going again towards a robot its driver had
    stopped, and the driver, recovering, could take a command that moves. By their stamps they are stale: the path
    only brakes, and the state that says the robot is stopped brings the hold where it stands."""
    shell, scaler, keys = scaler_at_start()
    traj, now = under_way(shell, scaler)
    frozen_at, now = now, now + 1.5                   # held up for 1.5 s
    last = shell.published(keys.command, JointCommand)[-1]
    shell.deliver(keys.human_state, humans_to_msg(FAR, True, now))
    statuses = []
    for k in range(5):                                # the queue: states from the first 50 ms of the hold, "following"
        scaler.arrival_clock.now = now
        shell.deliver(keys.joint_state, joint_state(last.q, enabled=True, stamp=frozen_at + 0.01 * k))
        scaler.tick(now)
        statuses.append(shell.published(keys.scaler_status, ScalerStatus)[-1])
        now += 0.002
    assert [st.status for st in statuses] == ["stale_joint_state"] * 5
    speeds = [st.speed for st in statuses]
    assert np.all(np.diff(speeds) <= 1e-12)          # braking, never speeding up again
    scaler.arrival_clock.now = now                   # the driver's newest: stopped, the robot stands further on
    stood = last.q + 0.05 * np.sign(Q_GOAL - Q_START)
    shell.deliver(keys.joint_state, joint_state(stood, enabled=False, stamp=now - 0.003))
    scaler.tick(now)
    command = shell.published(keys.command, JointCommand)[-1]
    assert np.allclose(command.q, stood) and np.all(command.qd == 0.0)


def test_the_scaler_refuses_a_merge_into_a_trajectory_it_does_not_follow_and_drops_garbage():
    shell, scaler, keys = scaler_at_start()
    traj = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration, version=5)
    shell.deliver(keys.trajectory, trajectory_to_msg(traj, 1, "beta", 0.4, base_version=3))
    shell.deliver(keys.trajectory, b"\xc1 not msgpack")
    shell.deliver(keys.human_state, b"")
    scaler.tick(time.monotonic())
    assert scaler.version == -1 and shell.bad_messages == 2
    assert shell.published(keys.scaler_status, ScalerStatus)[-1].trajectory_version == -1    # holding


def test_after_the_layer_drops_a_plan_the_scaler_takes_the_next_plan_numbered_like_it():
    """The planner numbers a replan from the trajectory the scaler follows, so the plan after a dropped one
    carries the dropped one's number; the scaler must not take it for an old message (in the demo's phase 4
    every replan for 4 s was ignored so, and the robot stood beside the arm until the person left)."""
    shell, scaler, keys = scaler_at_start()
    old = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration, version=1)
    shell.deliver(keys.trajectory, trajectory_to_msg(old, 1, "goal", 0.0, -1))
    now = time.monotonic()
    def ticks(n: int) -> None:
        nonlocal now
        for _ in range(n):
            now += 0.01
            shell.deliver(keys.human_state, humans_to_msg(FAR, True, now))
            scaler.tick(now)
    ticks(60)                                      # at full speed
    ahead = straight_line_trajectory(old.sample(scaler.layer.s + 0.02)[0], Q_START, LIM.velocity, LIM.acceleration,
                                     version=2)    # a plan from rest just ahead: too close to stop for
    shell.deliver(keys.trajectory, trajectory_to_msg(ahead, 1, "beta", 0.0, -1))
    ticks(5)
    assert scaler.layer.trajectory.version == 1 and scaler.version == 1
    last = shell.published(keys.scaler_status, ScalerStatus)[-1]
    assert last.pending == -1 and last.received == 2           # decided on (dropped: it could not stop there)
    merged = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration, version=2)
    shell.deliver(keys.trajectory, trajectory_to_msg(merged, 1, "beta", scaler.layer.s + 0.3, base_version=1))
    ticks(1)
    assert scaler.version == 2 and scaler.layer.trajectory is not None and scaler.layer.trajectory.version == 2
    assert shell.published(keys.scaler_status, ScalerStatus)[-1].trajectory_version == 2


# -------------------------------------------------------------------------------------- tracker_ingest
def test_tracker_ingest_publishes_each_sample_with_velocities_and_announces_a_dropout():
    shell = FakeShell("tracker_ingest")
    service = TrackerIngest(shell, HumanTracker(TrackerParameters(window=0.04, dropout=0.05)))
    keys = shell.keys
    HumanTracker.warm_up()                  # as the service does before its first sample: a compile at the first
    t0 = time.monotonic()                   # (numba's cache cold) took 0.5 s, and the samples after it were stale
    for k in range(10):                     # one capsule walking at 1 m/s along x
        x = -2.0 + 0.01 * k
        shell.deliver(keys.human_raw, HumanRaw(source="test", sample_time=t0 + 0.01 * k,
                                               segments=np.array([[[x, 0.0, 0.9], [x, 0.0, 1.5]]]),
                                               radii=np.array([0.2])))
    states = shell.published(keys.human_state, HumanState)
    assert len(states) == 10 and all(s.valid for s in states)
    assert np.allclose(states[-1].velocities[0, :, 0], 1.0, atol=0.05) and states[-1].velocity_known[0]
    service.check(time.monotonic())         # its 100 Hz check: tracking
    assert [e.event for e in shell.published(keys.safety_events, SafetyEvent)] == ["tracker_ok"]
    service.check(time.monotonic() + 1.0)   # nothing for a second
    assert not shell.published(keys.human_state, HumanState)[-1].valid
    event = shell.published(keys.safety_events, SafetyEvent)[-1]
    assert event.event == "tracker_dropout" and event.severity == "stop"
    shell.deliver(keys.human_raw, b"\x80")  # an empty map: not a message
    assert shell.bad_messages == 1


def test_a_state_is_stamped_with_its_capture_so_a_cameras_latency_counts_in_the_datas_age(caplog):
    """A sample captured 60 ms before it reached tracker_ingest (a camera pipeline's latency) is stamped with its
    capture: at the scaler's next tick its age is past the 50 ms bound and the robot stops, where by its arrival
    it would be 10 ms old and the robot would go on towards a person 60 ms further on than it knows. A stamp ahead
    of the arrival (another clock) counts as captured on arrival; one 0.6 s old is dropped as stale and said."""
    ingest_shell = FakeShell("tracker_ingest")
    ingest = TrackerIngest(ingest_shell, HumanTracker(TrackerParameters()))
    seg = np.array([[[-2.0, 0.0, 0.9], [-2.0, 0.0, 1.5]]])
    HumanTracker.warm_up()
    arrived = time.monotonic()
    ingest_shell.deliver(ingest_shell.keys.human_raw, HumanRaw(source="camera", sample_time=arrived - 0.06,
                                                               segments=seg, radii=np.array([0.2])))
    after = time.monotonic()
    (state,) = ingest_shell.published(ingest_shell.keys.human_state, HumanState)
    assert state.sample_stamp == pytest.approx(arrived - 0.06, abs=1e-9)
    shell, scaler, keys = scaler_at_start()
    traj = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration, version=1)
    shell.deliver(keys.trajectory, trajectory_to_msg(traj, 1, "goal", 0.0, -1))
    shell.deliver(keys.human_state, state)
    scaler.tick(after + 0.01)
    assert shell.published(keys.scaler_status, ScalerStatus)[-1].status == "stale_human_data"
    ahead = time.monotonic() + 5.0
    ingest_shell.deliver(ingest_shell.keys.human_raw, HumanRaw(source="camera", sample_time=ahead, segments=seg,
                                                               radii=np.array([0.2])))
    newest = ingest_shell.published(ingest_shell.keys.human_state, HumanState)[-1]
    assert after <= newest.sample_stamp <= time.monotonic()
    late_shell = FakeShell("tracker_ingest")
    late = TrackerIngest(late_shell, HumanTracker(TrackerParameters()))
    with caplog.at_level(logging.WARNING):
        for _ in range(2):
            late_shell.deliver(late_shell.keys.human_raw, HumanRaw(source="late", sample_time=time.monotonic() - 0.6,
                                                                   segments=seg, radii=np.array([0.2])))
    assert not late_shell.published(late_shell.keys.human_state, HumanState)                # dropped, both
    assert caplog.text.count("dropped as stale") == 1 and "1 human sample(s) from 'late'" in caplog.text
    assert late.stale == 1 and ingest.stale == 0                # the second one waits for the next second's word


def test_tracker_ingest_declares_its_sources_rate_until_it_measures_one(capsys):
    """--source-rate 15: the first state says 67 ms (the scaler's stale bound, 100 ms), and the track is not lost
    before the camera's second frame; a rate outside 1-1000 Hz is refused before anything starts."""
    from services.tracker_ingest import main

    shell = FakeShell("tracker_ingest")
    service = TrackerIngest(shell, HumanTracker(TrackerParameters(source_interval=1 / 15)))
    t0 = time.monotonic()
    shell.deliver(shell.keys.human_raw, HumanRaw(source="camera", sample_time=t0, radii=np.array([0.2]),
                                                 segments=np.array([[[-2.0, 0.0, 0.9], [-2.0, 0.0, 1.5]]])))
    (state,) = shell.published(shell.keys.human_state, HumanState)
    assert state.sample_interval == pytest.approx(1 / 15) and state.valid
    service.check(t0 + 0.067)                    # the second frame is due: still tracking
    assert [e.event for e in shell.published(shell.keys.safety_events, SafetyEvent)] == ["tracker_ok"]
    for bad in ("0", "-15", "nan", "5000"):
        assert main(["--source-rate", bad]) == 2
        assert "--source-rate must be within [1, 1000] Hz" in capsys.readouterr().err


def test_the_dropout_watch_sleeps_until_the_bound_would_pass_and_repeats_the_invalid_state_while_silent():
    assert next_check(10.0, 10.03) == pytest.approx(0.03 + LATE)    # valid: just after the bound would pass
    assert next_check(10.0, 9.99) == INVALID_PERIOD        # invalid: the invalid state again every period
    assert next_check(10.0, -np.inf) == INVALID_PERIOD     # no sample yet
    assert HumanTracker(TrackerParameters(dropout=0.05)).valid_until == -np.inf
    shell = FakeShell("tracker_ingest")
    service = TrackerIngest(shell, HumanTracker(TrackerParameters(window=0.04, dropout=0.05)))
    stop = threading.Event()
    watch = threading.Thread(target=service.watch, args=(stop,), daemon=True)
    watch.start()
    try:
        t0 = time.monotonic()
        while time.monotonic() < t0 + 0.3:                  # samples at 100 Hz: tracking
            shell.deliver(shell.keys.human_raw, HumanRaw(source="test", sample_time=time.monotonic(),
                                                         segments=np.array([[[-2.0, 0.0, 0.9], [-2.0, 0.0, 1.5]]]),
                                                         radii=np.array([0.2])))
            time.sleep(0.01)
        silent = time.monotonic()
        deadline = silent + 5.0                              # then silence: the watch must say so (waits on it)
        while time.monotonic() < deadline and "tracker_dropout" not in [
                e.event for e in shell.published(shell.keys.safety_events, SafetyEvent)]:
            time.sleep(0.01)
        events = [e.event for e in shell.published(shell.keys.safety_events, SafetyEvent)]
        assert events[-1] == "tracker_dropout" and "tracker_ok" in events
        assert not shell.published(shell.keys.human_state, HumanState)[-1].valid
    finally:
        stop.set()
        watch.join(2.0)
    assert not watch.is_alive()


# ------------------------------------------------------------------------------------------ the monitor
def test_the_monitor_checks_states_paired_with_people_and_counts_the_rest_unchecked():
    shell = FakeShell("safety_monitor")
    service = MonitorService(shell, SafetyMonitor(ROBOT, CONFIG.ssm))
    keys = shell.keys
    now = time.monotonic()
    shell.deliver(keys.joint_state, JointState(q=Q_START, qd=np.full(6, 0.2), drive_state="running", enabled=True,
                                               fault=False, stamp=now - 0.9))      # nobody known then
    for k in range(5):
        t = now - 0.05 + 0.01 * k
        shell.deliver(keys.human_state, humans_to_msg(FAR, True, t))
        shell.deliver(keys.joint_state, JointState(q=Q_START, qd=np.full(6, 0.2), drive_state="running",
                                                   enabled=True, fault=False, stamp=t))
    service.check_pass(now + 0.2)
    assert service.checks >= 4 and service.violations == 0 and service.unchecked >= 1
    service.summary()
    report = shell.published(keys.monitor, MonitorReport)[-1]
    assert report.checks == service.checks and report.unchecked == service.unchecked and report.violations == 0
    assert shell.published(keys.safety_events, SafetyEvent)[-1].event == "monitor_summary"


def test_the_monitor_waits_for_the_people_as_long_as_their_samples_take_from_capture():
    """A camera 150 ms behind (the tracker publishes each state 0.15 s after its capture): the monitor's backlog
    waits that much longer for the person of a state's moment, and is not 'behind' for the camera's latency."""
    shell = FakeShell("safety_monitor")
    service = MonitorService(shell, SafetyMonitor(ROBOT, CONFIG.ssm))
    service.monitor.check_batch(Q_START[None], np.full((1, 6), 0.2), [FAR])    # compiled before the clock starts
    now = time.monotonic()
    shell.deliver(shell.keys.human_state, humans_to_msg(FAR, True, now - 0.2, stamp=now - 0.05))
    shell.deliver(shell.keys.joint_state, JointState(q=Q_START, qd=np.full(6, 0.2), drive_state="running",
                                                     enabled=True, fault=False, stamp=now - 0.13))
    service.check_pass(now)                          # 130 ms after the state: its person may still come
    assert service.backlog.delay == pytest.approx(0.15) and service.checks == 0 and len(service.backlog) == 1
    shell.deliver(shell.keys.human_state, humans_to_msg(FAR, True, now - 0.12, stamp=now + 0.03))
    service.check_pass(now + 0.04)
    assert service.checks == 1 and service.unchecked == 0 and not service.behind


def test_the_scaler_says_where_it_awaits_the_replan_it_asked_for_and_takes_the_plan_from_there():
    """With scaling.await_plan > 0 (0 shipped), a crawling robot that asks for a replan is stopped, and the status
    says where (stop_s): the planner's plan from rest there is taken at once. Before the request, and once the plan
    is taken, stop_s is None."""
    shell, scaler, keys = scaler_at_start(replace(CONFIG.scaling, await_plan=0.3))
    traj = straight_line_trajectory(Q_START, Q_GOAL, LIM.velocity, LIM.acceleration, version=1)
    shell.deliver(keys.trajectory, trajectory_to_msg(traj, 1, "goal", 0.0, -1))
    now = time.monotonic()
    shell.deliver(keys.human_state, humans_to_msg(FAR, True, now))
    scaler.tick(now)
    q, dq, _ = traj.sample(1.0)
    points, velocities = ROBOT.capsule_motion(q, dq)
    ahead = points[-1, 1] + 0.65 * velocities[-1, 1] / np.linalg.norm(velocities[-1, 1])
    person = HumanCapsules.from_arrays([[ahead, ahead]], [0.1], np.zeros((1, 2, 3)), [True])
    scaler.layer.s, scaler.layer.sdot = 1.0, 0.17                # crawling towards the person
    for _ in range(20):
        now += 0.01
        robot_follows(shell, scaler, now)
        shell.deliver(keys.human_state, humans_to_msg(person, True, now))
        scaler.tick(now)
    statuses = shell.published(keys.scaler_status, ScalerStatus)
    assert statuses[0].stop_s is None and statuses[-1].beta and statuses[-1].alpha == 0.0
    stop_s = statuses[-1].stop_s
    assert stop_s is not None and statuses[-1].s == stop_s and statuses[-1].pending == -1
    here = traj.sample(stop_s)[0]
    shell.deliver(keys.joint_state, joint_state(here))
    plan = straight_line_trajectory(here, Q_START, LIM.velocity, LIM.acceleration, version=2)
    shell.deliver(keys.trajectory, trajectory_to_msg(plan, 1, "beta", 0.0, -1))
    now += 0.01
    shell.deliver(keys.human_state, humans_to_msg(person, True, now))
    scaler.tick(now)
    last = shell.published(keys.scaler_status, ScalerStatus)[-1]
    assert scaler.version == 2 and last.trajectory_version == 2 and last.stop_s is None
