"""A recorded motion through the product's tracker (shared.tracking.tracked), as `hrc demo --sim --human` runs it:
what tracker_ingest passes on to the layers on the processes, frame by frame at the motion's own times."""

import numpy as np
import pytest

from shared.tracking.motion import RecordedMotion, ReplayFrame
from shared.tracking.tracked import TrackedMotion
from shared.tracking.tracker import TrackerParameters

RATE = 30.0           # Hz, a camera's skeleton tracker
SPEED = 0.6           # m/s along x


def walker(frames: int, gap: tuple[int, int] | None = None) -> RecordedMotion:
    """One capsule walking along x at SPEED, a frame every 1 / RATE s; frames in [gap) are dropouts."""
    out = []
    for k in range(frames):
        t = k / RATE
        seg = np.array([[[SPEED * t, 0.0, 1.0], [SPEED * t, 0.0, 1.5]]])
        dropped = gap is not None and gap[0] <= k < gap[1]
        out.append(ReplayFrame(t, seg, np.array([0.1]), ("a",), ("torso",), dropout=dropped))
    return RecordedMotion(out)


def test_velocities_are_the_trackers_fit_known_once_its_window_holds_enough_frames():
    motion = walker(30)
    tracked = TrackedMotion(motion)
    first = tracked.at(0.0)
    assert first is not None and not first.velocity_known.any()        # one frame: no velocity yet
    assert motion.at(1.5 / RATE).velocity_known.all()                  # the file's own: known from the 2nd frame
    assert not tracked.at(1.5 / RATE).velocity_known.any()             # the tracker's: not with two frames
    later = tracked.at(10.2 / RATE)
    assert later.velocity_known.all()
    assert np.allclose(later.velocities[..., 0], SPEED, atol=1e-6) and np.allclose(later.velocities[..., 1:], 0.0)
    assert np.allclose(later.segments[0, :, 0], SPEED * 10 / RATE, atol=1e-6)     # the newest frame's place


def test_a_dropout_longer_than_the_trackers_bound_is_nobody_then_the_track_starts_again():
    params = TrackerParameters()
    tracked = TrackedMotion(walker(40, gap=(10, 20)), params)
    assert tracked.at(9.5 / RATE) is not None
    assert tracked.at(11.0 / RATE) is not None            # one missing frame is within the bound (3 intervals)
    assert tracked.at(19.5 / RATE) is None                # ten frames without a sample: the dropout
    back = tracked.at(20.2 / RATE)
    assert back is not None and not back.velocity_known.any()          # a new track: no velocity yet
    assert tracked.at(30.2 / RATE).velocity_known.all()


def test_any_order_of_times_gives_the_same_answers_as_a_clock_that_runs_on():
    motion = walker(20)
    times = np.arange(0.0, 19.0 / RATE, 0.01)
    forward = [TrackedMotion(motion).at(t) for t in times]
    tracked = TrackedMotion(motion)
    for k in np.random.default_rng(3).permutation(times.size):        # a forecast told the future reads ahead
        x, y = tracked.at(times[k]), forward[k]
        assert np.array_equal(x.segments, y.segments) and np.array_equal(x.velocity_known, y.velocity_known)
    assert tracked.at(-0.1) is None                                      # before the first frame
    assert np.array_equal(tracked.at(60.0).segments, tracked.at(19.0 / RATE).segments)   # past the end: the last
    assert tracked.phase(0.2) == motion.phase(0.2) and tracked.duration == pytest.approx(19.0 / RATE)


def test_the_data_of_a_moment_is_aged_from_the_capture_of_the_newest_frame_the_tracker_had():
    """captured(t): the newest frame's capture time and the interval the tracker had measured, so that a frame
    held between two of a 30 Hz camera ages as the scaler finds it; none before the first frame; past the
    motion's end its last frame holds as fresh as it was then (as at(t) holds it)."""
    tracked = TrackedMotion(walker(30, gap=(10, 12)))
    assert tracked.captured(-0.01) == (-np.inf, 0.0)
    taken, interval = tracked.captured(5.5 / RATE)
    assert taken == pytest.approx(5 / RATE) and interval == pytest.approx(1 / RATE)
    assert tracked.captured(11.5 / RATE)[0] == pytest.approx(9 / RATE)          # two frames lost: 2.5 frames old
    end = 29 / RATE                                                             # the last frame
    assert tracked.captured(end + 0.5)[0] == pytest.approx(end + 0.5)         # held as fresh as it came
