"""The operator's shuttle (tools.actors.Shuttle) on fakes, no Zenoh: goals sent, sent again while the robot follows
none, the next one on arrival, and the shuttles counted with the last leg's part, as the simulation counts them."""

import threading
from types import SimpleNamespace

import numpy as np
import pytest

from evidence.scenarios import Q_GOAL, Q_START
from shared.wire.keys import KeySpace
from shared.wire.messages import Goal, JointState, ScalerStatus, decode, encode
from tools.actors import GOAL_RETRY, Shuttle
from tools.report import Recording


class Publisher:
    def __init__(self) -> None:
        self.sent: list[bytes] = []

    def put(self, payload: bytes) -> None:
        self.sent.append(payload)


class Session:
    def __init__(self) -> None:
        self.publishers: dict[str, Publisher] = {}

    def declare_publisher(self, key: str) -> Publisher:
        return self.publishers.setdefault(key, Publisher())


class Recorder:
    """The latest message of each kind, as tools.actors.Recorder keeps them."""

    def __init__(self) -> None:
        self.lock, self.latest = threading.Lock(), {}

    def get(self, kind):
        return self.latest.get(kind)


def joint_state(q) -> SimpleNamespace:
    return SimpleNamespace(q=np.asarray(q, dtype=float), drive_state="running:operation_enabled")


@pytest.fixture
def cell():
    session, recorder, rec, keys = Session(), Recorder(), Recording(t0=0.0), KeySpace("test/shuttle")
    shuttle = Shuttle(session, keys, recorder, rec)
    goals = session.publishers[keys.goal].sent
    return shuttle, recorder, rec, goals


def test_a_goal_nobody_follows_is_sent_again_while_the_robot_reports_its_state(cell):
    shuttle, recorder, rec, goals = cell
    shuttle.start(0.0)
    recorder.latest[JointState] = joint_state(Q_START)
    shuttle.step(0.5 * GOAL_RETRY)
    assert len(goals) == 1                                   # not yet
    shuttle.step(1.5 * GOAL_RETRY)
    assert len(goals) == 2 and decode(goals[-1]).goal_id == decode(goals[0]).goal_id == 1    # the same goal again
    assert rec.shuttles == 0 and rec.progress == 0.0


def test_on_arrival_the_next_goal_and_the_shuttles_count_with_the_last_legs_part(cell):
    shuttle, recorder, rec, goals = cell
    shuttle.start(0.0)
    rec.trajectories.append(SimpleNamespace(version=3, goal_id=1))          # the planner's answer to goal 1
    recorder.latest[ScalerStatus] = SimpleNamespace(status="running", trajectory_version=3)
    recorder.latest[JointState] = joint_state(0.5 * (Q_START + Q_GOAL))
    shuttle.step(0.2)
    assert rec.shuttles == 0 and rec.progress == pytest.approx(0.5) and len(goals) == 1
    recorder.latest[ScalerStatus] = SimpleNamespace(status="finished", trajectory_version=3)
    recorder.latest[JointState] = joint_state(Q_GOAL)
    shuttle.step(2.5)
    goal = decode(goals[-1])
    assert isinstance(goal, Goal) and goal.goal_id == 2 and np.allclose(goal.q, Q_START)   # back again
    assert rec.shuttles == 1 and rec.progress == pytest.approx(1.0)
    recorder.latest[JointState] = joint_state(0.75 * Q_START + 0.25 * Q_GOAL)                # most of the way back
    shuttle.step(2.6)
    assert rec.shuttles == 1 and rec.progress == pytest.approx(1.75)


def test_the_reports_rates_are_over_the_time_the_shuttle_was_directed_not_the_traces_tail():
    """hrc demo directs the shuttle for --duration, then records a moment longer (the monitor's last summary): the
    shuttles were counted over the first, and a rate over the trace's length understated the processes' runs against
    the simulation's by that tail (1.2 s of a 15 s recording: 8 %)."""
    from shared.config import CellConfig
    from shared.robot.model import default_robot
    from tools.report import analyse

    rec = Recording(t0=100.0, shuttles=3, progress=3.5)
    for k in range(1321):                      # the trace: 13.2 s
        rec.statuses.append(ScalerStatus(s=0.0, alpha=1.0, safe_alpha=1.0, beta=False, q_command=Q_START,
                                         trajectory_version=1, status="running", method="piqp", min_separation=None,
                                         min_margin=None, compute_us=80.0, stamp=100.0 + 0.01 * k))
    undirected, _ = analyse(default_robot(), CellConfig(), rec)
    assert undirected["duration_s"] == undirected["trace_s"] == pytest.approx(13.2)     # no directed time: the trace
    rec.directed_s = 12.0
    summary, _ = analyse(default_robot(), CellConfig(), rec)
    assert summary["duration_s"] == 12.0 and summary["trace_s"] == pytest.approx(13.2)
    assert summary["shuttles_per_min"] == 15.0 and summary["shuttle_progress"] == 3.5


class Sample:
    def __init__(self, payload: bytes) -> None:
        self.payload = SimpleNamespace(to_bytes=lambda: payload)


class SubscribingSession:
    """declare_subscriber keeps each key's callback, so a test can deliver samples to tools.actors.Recorder."""

    def __init__(self) -> None:
        self.callbacks: dict[str, object] = {}

    def declare_subscriber(self, key: str, callback):
        self.callbacks[key] = callback
        return SimpleNamespace(undeclare=lambda: None)


def test_the_operator_wakes_when_the_scaler_says_its_trajectory_is_finished():
    """The demo's operator waits for its next turn on the recorder (``wait_finished``): a scaler status saying
    the trajectory is finished ends the wait, so the next goal goes out at once instead of up to a poll later;
    a running status does not, and each wait takes the finish it was woken by (the next one waits again)."""
    from tools.actors import Recorder as KeepingRecorder

    session, keys = SubscribingSession(), KeySpace("test/shuttle")
    recorder = KeepingRecorder(session, keys, Recording(t0=0.0))

    def status(what: str) -> Sample:
        return Sample(encode(ScalerStatus(s=1.0, alpha=1.0, safe_alpha=1.0, beta=False, q_command=Q_GOAL,
                                          trajectory_version=3, status=what, method="piqp", min_separation=None,
                                          min_margin=None, compute_us=50.0, received=3, seq=1, stamp=0.0)))

    session.callbacks[keys.scaler_status](status("running"))
    assert not recorder.finished.is_set() and recorder.get(ScalerStatus).status == "running"
    session.callbacks[keys.scaler_status](status("finished"))
    assert recorder.finished.is_set()
    woke = threading.Event()
    waiter = threading.Thread(target=lambda: (recorder.wait_finished(60.0), woke.set()))
    waiter.start()
    waiter.join(30.0)
    assert woke.is_set() and not recorder.finished.is_set()       # woken by the finish, and it is taken
    session.callbacks[keys.scaler_status](Sample(b"\x00not a message"))
    assert recorder.bad == 1 and not recorder.finished.is_set()


def test_the_report_says_how_long_the_robot_stood_at_each_goal_before_the_next_leg_moved():
    """``goal_changeovers``: from a trajectory's first 'finished' status to the first status moving (alpha above
    0.01) on a newer one; the finish the run ends on counts for nothing. The summary gives the legs, p50, p95, max."""
    from shared.config import CellConfig
    from shared.robot.model import default_robot
    from tools.report import analyse, goal_changeovers

    def status(t: float, version: int, what: str, alpha: float) -> ScalerStatus:
        return ScalerStatus(s=0.0, alpha=alpha, safe_alpha=1.0, beta=False, q_command=Q_START,
                            trajectory_version=version, status=what, method="piqp", min_separation=None,
                            min_margin=None, compute_us=80.0, stamp=t)

    timeline = [(0.00, 1, "running", 1.0), (0.01, 1, "finished", 0.0), (0.02, 1, "finished", 0.0),
                (0.03, 2, "running", 0.0),                       # the next leg taken, not yet moving
                (0.04, 2, "running", 0.5), (0.05, 2, "finished", 0.0), (0.06, 2, "finished", 0.0),
                (0.07, 2, "finished", 0.0), (0.08, 3, "running", 0.2), (0.09, 3, "finished", 0.0)]
    statuses = [status(*row) for row in timeline]
    assert goal_changeovers(statuses) == pytest.approx([0.03, 0.03])
    assert goal_changeovers(statuses[:3]).size == 0              # a run that ends at its goal
    rec = Recording(t0=0.0, statuses=statuses)
    summary, _ = analyse(default_robot(), CellConfig(), rec)
    assert summary["goal_changeover_ms"] == {"legs": 2, "p50": pytest.approx(30.0), "p95": pytest.approx(30.0),
                                             "max": pytest.approx(30.0)}


class Clock:
    """A simulated clock: sleep moves it on, and after `running_at` s the fake driver reports running."""

    def __init__(self, recorder: Recorder, running_at: float | None, now: float = 0.0) -> None:
        self.now, self.recorder, self.running_at = now, recorder, running_at

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += seconds
        if self.running_at is not None and self.now >= self.running_at:
            self.recorder.latest[JointState] = joint_state(Q_START)


def test_drives_stopped_at_the_start_are_recovered_before_the_run_and_only_they(cell):
    from tools.actors import RECOVER_EVERY

    shuttle, recorder, rec, goals = cell
    requests = shuttle.req_pub.sent
    recorder.latest[JointState] = SimpleNamespace(q=Q_START, drive_state="stopped:fault")   # a fault at start-up
    clock = Clock(recorder, running_at=0.06)                 # the drives run once recovered
    assert shuttle.enable(5.0, clock, clock.sleep)
    assert len(requests) == 1 and decode(requests[0]).action == "recover" and clock.now < 0.1 and not goals
    recorder.latest[JointState] = SimpleNamespace(q=Q_START, drive_state="stopped:fault")   # never recovered:
    clock = Clock(recorder, running_at=None, now=clock.now + RECOVER_EVERY)   # asked every RECOVER_EVERY, given up
    assert not shuttle.enable(2.5 * RECOVER_EVERY, clock, clock.sleep)
    assert len(requests) == 1 + 3 and not goals
    recorder.latest[JointState] = joint_state(Q_START)       # running: nothing asked
    assert shuttle.enable(1.0, clock, clock.sleep) and len(requests) == 4
