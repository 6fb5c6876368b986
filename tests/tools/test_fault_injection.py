"""The fault campaign's CAN requests: retried, and a clear error (never a traceback) when unanswered."""

import canopen
import numpy as np
import pytest

from tools.faults import CanProbe, InjectionError


class FlakyEntry:
    def __init__(self, failures: int) -> None:
        self.failures, self.writes = failures, []

    @property
    def raw(self):
        return None

    @raw.setter
    def raw(self, value):
        if self.failures > 0:
            self.failures -= 1
            raise canopen.SdoCommunicationError("No SDO response received")
        self.writes.append(value)


def probe_with(entry: FlakyEntry) -> CanProbe:
    probe = CanProbe.__new__(CanProbe)                 # no bus: only the request logic is under test
    probe.nodes = {5: type("Node", (), {"sdo": {0x2F00: {2: entry}}})()}
    return probe


def test_an_unanswered_request_is_tried_again():
    entry = FlakyEntry(failures=2)
    probe_with(entry).inject(5, 2, 1)
    assert entry.writes == [1]


def test_a_request_never_answered_is_a_clear_error():
    with pytest.raises(InjectionError, match=r"node 5: SDO write 0x2F00:2 = 1 not answered after 3 tries"):
        probe_with(FlakyEntry(failures=10)).inject(5, 2, 1)


def test_the_campaign_estimates_the_time_left_from_the_faults_done():
    from tools.faults import time_left
    assert time_left(0, 12, 0.0) == ""
    assert time_left(3, 12, 60.0) == " (60 s so far, about 180 s left)"
    assert time_left(12, 12, 240.0).endswith("about 0 s left)")


def test_an_emcy_is_timed_when_it_reached_the_socket_not_when_a_busy_campaign_read_it():
    """The probe's receive thread may get to a frame late on a loaded machine: the EMCY is recorded at its
    receive time (taken back onto the monotonic clock), so the drives are not blamed for the observer's
    delay; no receive time, or one that makes no sense, counts no delay."""
    import threading
    import time

    probe = CanProbe.__new__(CanProbe)
    probe.lock, probe.emcy, probe.registers = threading.Lock(), [], []
    code = (0x8250).to_bytes(2, "little")
    before = time.monotonic()
    probe._on_emcy(3, code + b"\x81", time.time() - 0.4)     # read 0.4 s after it arrived
    probe._on_emcy(4, code, 0.0)                             # a bus without receive times
    probe._on_emcy(5, code, time.time() + 60.0)              # a clock that makes no sense
    after = time.monotonic()
    (t3, n3, c3), (t4, _, _), (t5, _, _) = probe.emcy
    assert (n3, c3) == (3, 0x8250)
    assert before - 0.45 < t3 < after - 0.35
    assert before <= t4 <= after and before <= t5 <= after
    assert probe.registers[:2] == [(0x8250, 0x81), (0x8250, None)]      # CiA 301's error register, if sent


def test_a_person_shown_nearer_is_seen_in_the_first_status_that_has_them_nearer():
    """The jump fault's judge (tools.faultcheck.nearer_seen): two thirds of the jump nearer than before; where
    the scaler had nobody in its problem before (no separation), the first separation at all."""
    from tools.faultcheck import nearer_seen
    walking = [(0.01, 0.95), (0.02, 0.94), (0.03, 0.93)]            # the person walking up: not the jump
    assert nearer_seen(1.0, walking, 0.3) is None
    assert nearer_seen(1.0, walking + [(0.04, 0.72)], 0.3) == 0.04
    assert nearer_seen(None, [(0.004, 0.81), (0.014, 0.80)], 0.3) == 0.004
    assert nearer_seen(None, [], 0.3) is None


def test_a_campaign_with_a_failed_verdict_keeps_its_trace(monkeypatch, tmp_path):
    """run_campaign writes faults.json and faults.md; where a verdict failed, the whole campaign's messages too
    (trace/), so where its stop went can be judged afterwards; all verdicts good, no trace."""
    import threading

    import numpy as np

    import tools.faults as faults
    from shared.robot.model import default_robot
    from shared.wire.messages import JointState
    from tools.faultcheck import FaultVerdict
    from tools.report import Recording

    class FakeCampaign:
        def __init__(self, *args):
            self.rec = Recording(t0=0.0)
            self.rec.joint_states.append(JointState(q=np.zeros(6), qd=np.zeros(6), drive_state="running:x",
                                                    enabled=True, fault=False, seq=1, stamp=0.01))
            self.recorder = type("Recorder", (), {"lock": threading.Lock()})()

        def run(self, name):
            verdict = FaultVerdict(name, "any", None, "test")
            verdict.moving_at_injection, verdict.back, verdict.resumed_s = True, True, 1.0
            verdict.truth_violations = 3 if name == "can_drop" else 0        # the failed one
            return verdict

        def close(self):
            pass

    monkeypatch.setattr(faults, "Campaign", FakeCampaign)
    said = []
    faults.run_campaign("t/x", "tcp/127.0.0.1:9", "virtual", None, None, default_robot(), ["kill_planner"],
                        tmp_path / "good", say=said.append)
    assert (tmp_path / "good" / "faults.json").exists() and not (tmp_path / "good" / "trace").exists()
    faults.run_campaign("t/x", "tcp/127.0.0.1:9", "virtual", None, None, default_robot(), ["can_drop"],
                        tmp_path / "bad", say=said.append)
    assert (tmp_path / "bad" / "trace" / "trace.csv").exists() and "trace is in" in said[-1]


def test_a_human_data_faults_bound_is_the_cells_stale_bound_at_the_sources_measured_rate():
    """The scaler stops for stale human data at the cell's own rule (shared.tracking.tracker.stale_bound): 50 ms,
    or 2.5 of the source's measured sample interval where that is longer (a feed that skips samples under load,
    a camera), at most 100 ms. The campaign's bound for a human-data fault is stated from the same rule at the
    interval measured at the injection, not from 50 ms alone (a stop at 344 ms against a 342 ms bound, the
    scaler's stop 85 ms after the fault, where the tracker measured a longer interval)."""
    from shared.config import CellConfig
    from shared.robot.model import default_robot
    from tools.faults import braking_time, expectations, human_stop

    config, robot = CellConfig(), default_robot()
    rest = 0.03 + braking_time(robot)                     # tick, SYNC and report, and the braking
    assert expectations(config, robot)["tracker_silent"].bound_s == pytest.approx(0.05 + rest)
    assert human_stop(config, robot, 1 / 120).bound_s == pytest.approx(0.05 + rest)
    at_30_hz = human_stop(config, robot, 1 / 30)
    assert at_30_hz.bound_s == pytest.approx(2.5 / 30 + rest) and "measured interval 33.3 ms" in at_30_hz.why
    assert human_stop(config, robot, 0.2).bound_s == pytest.approx(0.1 + rest)      # never past the ceiling


def test_the_interval_judged_is_the_one_the_tracker_held_when_the_fault_came():
    """The tracker's interval is the median of its last ones and stays as it was once the samples stop, so the
    newest human state says it, however long before the injection the (loaded) campaign received it: a CI run
    with no state in the last 0.1 s judged the tracker's 94 ms dropout by 50 ms and failed a stop the cell made
    by its own rule. A state older than HELD_FOR says nothing (the configured bound alone)."""
    from shared.wire.messages import HumanState
    from tools.faults import HELD_FOR, held_interval

    def state(stamp: float, interval: float) -> HumanState:
        return HumanState(segments=np.zeros((0, 2, 3)), radii=np.zeros(0), velocities=np.zeros((0, 2, 3)),
                          velocity_known=np.zeros(0, dtype=bool), valid=True, sample_stamp=stamp,
                          sample_interval=interval, stamp=stamp)

    states = [state(10.0, 0.0083), state(10.05, 0.0375), state(10.03, 0.0083)]    # out of order on the wire
    assert held_interval(states, 10.3) == pytest.approx(0.0375)          # the newest, 250 ms before
    assert held_interval(states, 10.05 + HELD_FOR + 0.01) == 0.0          # too old to say anything
    assert held_interval([], 10.0) == 0.0
    assert held_interval([state(10.5, 0.02)], 10.3) == 0.0                # stamped after now: not yet held
