"""When the person feed sends (tools.actors.FeedSchedule, HumanFeed): a recorded motion's frames each once at their
own times, regular or not; a late feed skips to the newest sample due instead of sending a burst; a finite feed
(`hrc human replay`, `hrc human inject --duration`) ends with its motion; --speed plays it faster."""

import time

import numpy as np
import pytest

from shared.core.humans import HumanCapsules
from shared.tracking.motion import RecordedMotion, parse_csv
from shared.wire.keys import KeySpace
from shared.wire.messages import decode
from tools.actors import LEAD_IN, FeedSchedule, HumanFeed, MovingCapsule, lead_in_time, schedule_of


class _Publisher:
    def __init__(self) -> None:
        self.sent: list[tuple[float, object]] = []

    def put(self, payload: bytes) -> None:
        self.sent.append((time.monotonic(), decode(payload)))


class _Session:
    def __init__(self) -> None:
        self.publisher = _Publisher()

    def declare_publisher(self, key):
        return self.publisher


def _motion(times: list[float], dropout_at: float | None = None) -> RecordedMotion:
    rows = ["t,person,capsule,ax,ay,az,bx,by,bz,radius"]
    for t in times:
        if t == dropout_at:
            rows.append(f"{t},,dropout,,,,,,,")
        else:
            rows.append(f"{t},p,torso,-1.5,{t:.3f},0.9,-1.5,{t:.3f},1.4,0.2")
    return RecordedMotion(parse_csv("\n".join(rows) + "\n"))


def test_a_recording_is_due_at_its_own_frame_times_then_on_at_its_rate():
    schedule = FeedSchedule(10.0, np.array([0.0, 0.1, 0.15, 0.4]))
    assert [schedule.offset(k) for k in range(6)] == pytest.approx([0.0, 0.1, 0.15, 0.4, 0.5, 0.6])
    assert schedule.newest(0.0) == 0 and schedule.newest(0.12) == 1 and schedule.newest(0.3) == 2
    assert schedule.newest(0.45) == 3 and schedule.newest(0.61) == 5
    assert schedule.count is None and not schedule.done(10 ** 6)


def test_a_finite_feed_ends_with_its_last_sample():
    schedule = FeedSchedule(10.0, np.array([0.0, 0.1, 0.15, 0.4]), until=0.4)
    assert schedule.count == 4 and schedule.done(4) and not schedule.done(3)
    assert schedule.newest(5.0) == 3                      # never past its end, however late
    script = FeedSchedule(100.0, until=0.25)               # a script from 0 at its rate: 0, 10, ..., 250 ms
    assert script.count == 26 and script.offset(25) == pytest.approx(0.25)
    assert FeedSchedule(100.0, until=0.0).count == 1       # `hrc human inject` without --duration: one pose


def test_the_schedule_of_a_recording_a_script_and_a_given_rate():
    motion = _motion([0.0, 0.05, 0.1])
    assert schedule_of(motion).times.tolist() == pytest.approx([0.0, 0.05, 0.1]) and schedule_of(motion).rate == 20.0
    fixed = schedule_of(motion, rate=240.0)
    assert fixed.rate == 240.0 and fixed.times.tolist() == [0.0]
    assert schedule_of(MovingCapsule([0, 0, 0], [0, 0, 1], 0.1, [0, 0, 0])).rate == 120.0
    with pytest.raises(ValueError):
        FeedSchedule(0.0)


def test_a_replay_sends_each_frame_once_at_its_time_and_nothing_in_a_dropout():
    motion = _motion([0.0, 0.05, 0.08, 0.2, 0.25], dropout_at=0.2)     # 30 ms apart at least: none skipped
    session = _Session()
    t0 = time.monotonic() + 0.02
    feed = HumanFeed(session, KeySpace("t/feed"), motion, t0, source="test", until=motion.duration)
    feed.run()
    assert feed.finished and feed.skipped == 0
    sent = session.publisher.sent
    assert [m.seq for _, m in sent] == [0, 1, 2, 4]            # the dropout frame (3) is silence
    assert [m.sample_time - t0 for _, m in sent] == pytest.approx([0.0, 0.05, 0.08, 0.25])
    assert [float(m.segments[0, 0, 1]) for _, m in sent] == pytest.approx([0.0, 0.05, 0.08, 0.25])
    for at, message in sent:                                  # each went out when it was due, not before
        assert at >= message.sample_time - 1e-6


def test_a_person_standing_at_the_start_is_shown_for_the_lead_in_before_it_and_a_walker_or_a_recording_is_not():
    """The lead-in (hrc demo's feed): where the people stand at t0, their first moment LEAD_IN intervals before it,
    stamped then, so the tracker knows their velocity at t0 (with a latency, that many captured before t0 minus it);
    a walker at t0, or a recording's first frame (whose velocity nothing gives), gets none: the track starts at t0,
    as the simulation of a recording starts it."""
    rate = 20.0                            # 50 ms apart: on time on a loaded machine too
    standing = MovingCapsule([-1.5, 0.0, 0.9], [-1.5, 0.0, 1.4], 0.2, [0.0, 0.0, 0.0])
    session = _Session()
    t0 = time.monotonic() + lead_in_time(rate) + 0.02
    feed = HumanFeed(session, KeySpace("t/feed"), standing, t0, rate=rate, until=0.1, lead_in=LEAD_IN)
    feed.run()
    sent = [m for _, m in session.publisher.sent]
    lead = [m for m in sent if m.sample_time < t0]
    assert [round((m.sample_time - t0) * rate) for m in lead] == list(range(-LEAD_IN, 0))      # none skipped here
    assert all((m.segments == standing.at(0.0).segments).all() for m in lead)
    assert [m.seq for m in sent] == list(range(len(sent))) and sent[len(lead)].sample_time == t0
    # 60 ms late, as a camera pipeline: the cell has at t0 what was captured by t0 - 60 ms, so the lead-in starts
    # that much earlier too (LEAD_IN samples captured before then)
    session = _Session()
    t0 = time.monotonic() + lead_in_time(rate, 0.06) + 0.02
    HumanFeed(session, KeySpace("t/feed"), standing, t0, rate=rate, until=0.1, lead_in=LEAD_IN, latency=0.06).run()
    lead = [m for _, m in session.publisher.sent if m.sample_time < t0]
    assert [round((m.sample_time - t0) * rate) for m in lead] == list(range(-LEAD_IN - 2, 0))
    assert sum(m.sample_time <= t0 - 0.06 for m in lead) >= LEAD_IN
    walker = MovingCapsule([-1.5, 0.0, 0.9], [-1.5, 0.0, 1.4], 0.2, [0.5, 0.0, 0.0])
    for person in (walker, _motion([0.0, 0.05, 0.1])):
        session = _Session()
        t0 = time.monotonic() + lead_in_time(rate) + 0.02
        HumanFeed(session, KeySpace("t/feed"), person, t0, rate=rate, until=0.1, lead_in=LEAD_IN).run()
        assert min(m.sample_time for _, m in session.publisher.sent) == t0


def test_a_late_feed_skips_to_the_newest_sample_instead_of_a_burst():
    motion = _motion([round(0.01 * k, 2) for k in range(11)])
    session = _Session()
    t0 = time.monotonic() - 0.055                             # started 55 ms ago: samples 0-4 are gone
    feed = HumanFeed(session, KeySpace("t/feed"), motion, t0, until=motion.duration)
    feed.run()
    seqs = [m.seq for _, m in session.publisher.sent]
    # the first sample sent is the newest due (5, or later on a loaded machine), then on in order to the last one
    assert seqs[0] >= 5 and seqs == sorted(set(seqs)) and seqs[-1] == 10 and feed.skipped == 11 - len(seqs)
    assert feed.lateness.largest >= 0.05 and feed.figures()["late_max_at_s"] == 0.0   # the first sample, due at t0


def test_speed_plays_the_motion_faster_and_inject_moves_its_capsule():
    motion = _motion([0.0, 0.1, 0.2])
    session = _Session()
    t0 = time.monotonic()
    feed = HumanFeed(session, KeySpace("t/feed"), motion, t0, until=motion.duration, speed=2.0)
    feed.run()
    assert feed.rate == pytest.approx(20.0)
    assert [m.sample_time - t0 for _, m in session.publisher.sent] == pytest.approx([0.0, 0.05, 0.1])
    person = MovingCapsule([-2.0, 0.0, 0.9], [-2.0, 0.0, 1.4], 0.17, [0.5, 0.0, 0.0])
    caps = person.at(2.0)
    assert isinstance(caps, HumanCapsules) and caps.segments[0, :, 0].tolist() == pytest.approx([-1.0, -1.0])
    assert caps.velocity_known.all() and caps.radii.tolist() == [0.17]


def test_a_stopped_feed_says_it_did_not_finish():
    session = _Session()
    feed = HumanFeed(session, KeySpace("t/feed"), _motion([0.0, 5.0]), time.monotonic(), until=5.0)
    feed.running = False
    feed.run()
    assert not feed.finished and feed.sent == 0


def test_hrc_demo_declares_a_recorded_motions_rate_to_the_tracker():
    """`hrc demo --human FILE` sends the file at its own rate and tells tracker_ingest that rate (its second frame
    is then no lost person); the scripted person (None) and a rate the service refuses declare nothing."""
    from tools.demo import NO_BETA_ARGS, service_args

    assert service_args(False, 15.0) == {"tracker_ingest": ["--source-rate", "15.0"]}
    assert service_args(False, None) == {} and service_args(False, 0.5) == {} and service_args(False, 2000.0) == {}
    both = service_args(True, 30.0)
    assert both == {**NO_BETA_ARGS, "tracker_ingest": ["--source-rate", "30.0"]}
    both["planner"].append("--x")                              # a copy: the shared table stays as it is
    assert NO_BETA_ARGS["planner"] == ["--no-beta"]


def test_a_feed_with_latency_sends_each_sample_that_long_after_its_capture_stamped_with_the_capture():
    motion = _motion([0.0, 0.05, 0.1, 0.15])
    session = _Session()
    t0 = time.monotonic() + 0.02
    feed = HumanFeed(session, KeySpace("t/feed"), motion, t0, until=motion.duration, latency=0.08)
    feed.run()
    sent = session.publisher.sent
    assert feed.finished and feed.skipped == 0 and feed.figures()["latency_ms"] == 80.0
    assert [m.sample_time - t0 for _, m in sent] == pytest.approx([0.0, 0.05, 0.1, 0.15])   # stamped at capture
    assert [float(m.segments[0, 0, 1]) for _, m in sent] == pytest.approx([0.0, 0.05, 0.1, 0.15])  # the person then
    assert all(at >= m.sample_time + 0.08 - 1e-6 for at, m in sent)                         # sent 80 ms after it
    for bad in (-0.01, 0.6, float("nan")):
        with pytest.raises(ValueError, match="latency"):
            HumanFeed(session, KeySpace("t/feed"), motion, t0, latency=bad)
