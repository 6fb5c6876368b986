"""What a run's report says of the people's data's age (tools.report): each state's way from its sample's capture
to the tracker's publication, the share of control cycles the scaler found it stale, and the line `hrc demo` says
when that share is not small."""

import dataclasses

import numpy as np
import pytest

from shared.core.humans import HumanCapsules
from shared.wire.convert import humans_to_msg
from shared.wire.messages import ScalerStatus
from tools.report import Recording, reaction_said, stale_said, tracker_summary

PERSON = HumanCapsules.from_arrays([[[-1.5, 0.0, 0.9], [-1.5, 0.0, 1.4]]], [0.2], np.zeros((1, 2, 3)), [True])


def status(t: float, stale: bool) -> ScalerStatus:
    return ScalerStatus(s=0.0, alpha=0.0, safe_alpha=0.0, beta=False, q_command=np.zeros(6), trajectory_version=1,
                        status="stale_human_data" if stale else "running", method="none", min_separation=None,
                        min_margin=None, compute_us=0.0, speed=0.0,
                        held=False, pending=-1, received=1, stamp=t)


def test_a_cameras_latency_and_the_stale_cycles_it_makes_are_reported_and_said():
    rec = Recording(t0=100.0)
    rec.human_states = [humans_to_msg(PERSON, True, 100.0 + k / 30, stamp=100.0 + k / 30 + 0.06)
                        for k in range(30)]                             # 30 Hz, each 60 ms after its capture
    rec.statuses = [status(100.0 + k * 0.01, stale=k % 5 < 2) for k in range(100)]     # 40 % of the cycles
    tracker = tracker_summary(rec)
    assert tracker["capture_to_state_ms"] == {"p50": pytest.approx(60.0), "p99": pytest.approx(60.0)}
    assert tracker["stale_share"] == 0.4
    line = stale_said(tracker)
    assert "stale in 40 % of the control cycles" in line and "p99 60 ms" in line and "scaling.human_timeout" in line


def test_nothing_is_said_of_fresh_data_nor_of_a_run_without_figures():
    rec = Recording(t0=100.0)
    rec.statuses = [status(100.0 + k * 0.01, stale=k == 0) for k in range(200)]          # 0.5 %: a moment
    tracker = tracker_summary(rec)
    assert tracker["stale_share"] == 0.005 and tracker["capture_to_state_ms"] == {"p50": None, "p99": None}
    assert stale_said(tracker) is None and stale_said({}) is None
    assert tracker_summary(Recording(t0=0.0))["stale_share"] is None


def test_a_reaction_chain_longer_than_t_r_is_said_with_its_parts():
    """The parts T_r covers: the tick -> frame p99, the wait for the SYNC, the drive lag; a camera's latency (the
    capture -> frame p99's rest) is the data's age, not said."""
    summary = {"reaction_time_covers_p99": False, "reaction_time_s": 0.03,
               "latency": {"sample_to_frame_ms": {"p50": 68.4, "p99": 92.5}, "tick_to_frame_ms": {"p50": 3.1, "p99": 12.4},
                           "sync_wait_ms": 10.0},
               "tracker": {"sample_interval_ms": 33.33}, "drives": {"lag_p99_ms": [10.03, 10.04, 9.8]}}
    line = reaction_said(summary)
    assert "p99 12 ms" in line and "SYNC (10 ms)" in line and "10 ms behind that" in line and "92" not in line
    assert "T_r (30 ms)" in line
    assert reaction_said({**summary, "reaction_time_covers_p99": True}) is None
    assert reaction_said({"reaction_time_covers_p99": None}) is None            # not measured: nothing said


def test_the_reaction_chain_counts_the_drivers_own_sync_period_not_the_configurations():
    """The robot driver runs at its --period: the frame's wait for the SYNC is the period it reports, which a
    driver at 50 ms (the configuration's 10 ms) makes longer than T_r's 50 ms; without a report, the configuration's."""
    from evidence.scenarios import Q_START
    from shared.config import CellConfig
    from shared.robot.model import default_robot
    from shared.wire.messages import LatencyReport
    from tools.report import analyse

    def chain(sync_wait: float | None) -> dict:
        rec = Recording(t0=100.0)
        rec.statuses = [dataclasses.replace(status(100.0 + k * 0.01, stale=False), q_command=Q_START, alpha=1.0)
                        for k in range(50)]
        if sync_wait is not None:
            rec.latency = [LatencyReport(source="robot_driver", sample_to_frame=np.full(20, 0.03),
                                         processing=np.full(20, 0.001), tick_to_frame=np.full(20, 0.002),
                                         sync_wait=sync_wait, stamp=100.2)]
        summary, _ = analyse(default_robot(), CellConfig(), rec)
        return summary

    at_10, at_50 = chain(0.01), chain(0.05)
    assert at_10["latency"]["sync_wait_ms"] == 10.0 and at_10["reaction_time_covers_p99"] is True
    assert at_50["latency"]["sync_wait_ms"] == 50.0 and at_50["reaction_time_covers_p99"] is False     # 2 + 50 ms
    assert chain(None)["latency"]["sync_wait_ms"] == 10.0


def test_hrc_status_says_the_peoples_track_rate_and_way_from_capture():
    from tools.cli import people_said

    state = humans_to_msg(PERSON, True, 100.0, stamp=100.045, sample_interval=1 / 15)
    assert people_said(state) == "1 capsule(s), 15.0 Hz, 45 ms from capture to the tracker"
    assert "rate not yet measured" in people_said(humans_to_msg(PERSON, True, 100.0, stamp=100.0))
    assert "not valid" in people_said(humans_to_msg(HumanCapsules.empty(), False, 100.0, stamp=100.0))
    assert people_said(None) == "no human state"


def test_the_summary_writes_numpy_numbers_as_plain_ones_and_still_refuses_anything_else():
    """A count that became numpy's int once failed the report's JSON and lost the run's summary.json."""
    import json

    import numpy as np
    import pytest

    from tools.report import plain_json
    text = json.dumps({"count": np.int64(3), "flag": np.bool_(True), "lag": np.float64(0.5), "p": np.arange(2)},
                      default=plain_json)
    assert json.loads(text) == {"count": 3, "flag": True, "lag": 0.5, "p": [0, 1]}
    with pytest.raises(TypeError, match="object is not JSON serializable"):
        json.dumps({"what": object()}, default=plain_json)
