"""Human tracking: velocity from noisy samples, glitches, dropouts."""

import numpy as np
import pytest

from shared.tracking.tracker import OLDEST_SAMPLE, HumanTracker, TrackerParameters, capture_stamp

DT = 1 / 240


def feed(tracker, positions, radius=0.05, t0=0.0, noise=0.0, rng=None):
    out = None
    for k, p in enumerate(positions):
        seg = np.array([[p, p + [0, 0, 0.3]]])
        if noise:
            seg = seg + rng.normal(scale=noise, size=seg.shape)
        out = tracker.update(seg, [radius], t0 + k * DT, t0 + k * DT)
    return out


def test_constant_velocity_is_estimated_without_bias_through_noise():
    rng = np.random.default_rng(3)
    v = np.array([1.2, -0.4, 0.1])
    errs = []
    tracker = HumanTracker()
    for k in range(400):
        p = np.array([0.5, 0.2, 1.0]) + v * k * DT
        seg = np.array([[p, p + [0, 0, 0.3]]]) + rng.normal(scale=0.001, size=(1, 2, 3))
        h = tracker.update(seg, [0.05], k * DT, k * DT)
        if k > 20:
            errs.append(h.velocities[0, 0] - v)
    errs = np.array(errs)
    assert np.abs(errs.mean(axis=0)).max() < 0.01                  # unbiased
    assert errs.std(axis=0).max() < 0.06                           # noise about 0.03 m/s
    assert h.velocity_known.all()


def test_velocity_is_unknown_until_the_window_has_samples():
    tracker = HumanTracker()
    h = feed(tracker, [np.zeros(3)] * 2)
    assert not h.velocity_known.any()
    h = feed(tracker, [np.zeros(3)] * 10, t0=2 * DT)
    assert h.velocity_known.all() and np.allclose(h.velocities, 0)


def test_a_jump_faster_than_a_human_marks_the_velocity_unknown_and_takes_the_new_position():
    tracker = HumanTracker()
    feed(tracker, [np.zeros(3)] * 20)
    h = tracker.update(np.array([[[1.0, 0, 0], [1.0, 0, 0.3]]]), [0.05], 20 * DT, 20 * DT)
    assert not h.velocity_known.any() and h.segments[0, 0, 0] == pytest.approx(1.0)
    assert tracker.glitches == 1
    # where the person just was is reported too, until the filter trusts the new position
    assert h.count == 2 and h.segments[1, 0, 0] == pytest.approx(0.0)
    h = feed(tracker, [np.array([1.0, 0, 0])] * 12, t0=21 * DT)
    assert h.count == 1 and h.velocity_known.all()


def test_a_one_sample_glitch_away_never_hides_where_the_person_is():
    tracker = HumanTracker()
    near = np.array([0.4, 0.0, 0.0])
    feed(tracker, [near] * 20)
    far = tracker.update(np.array([[near + [2.0, 0, 0], near + [2.0, 0, 0.3]]]), [0.05], 20 * DT, 20 * DT)
    back = tracker.update(np.array([[near, near + [0, 0, 0.3]]]), [0.05], 21 * DT, 21 * DT)
    for h in (far, back):
        assert np.linalg.norm(h.segments[:, 0] - near, axis=1).min() < 1e-9     # the near person is in every state
        assert not h.velocity_known.any()


def test_dropout_invalidates_the_track():
    tracker = HumanTracker(TrackerParameters(dropout=0.05))
    feed(tracker, [np.zeros(3)] * 5)
    last = 4 * DT
    assert tracker.valid(last + 0.04) and not tracker.valid(last + 0.06)


def test_out_of_order_samples_are_dropped_and_capsule_count_changes_restart():
    tracker = HumanTracker()
    feed(tracker, [np.zeros(3)] * 10)
    assert tracker.update(np.zeros((1, 2, 3)), [0.05], 0.0, 1.0) is None
    h = tracker.update(np.zeros((2, 2, 3)), [0.05, 0.05], 11 * DT, 11 * DT)
    assert h.count == 2 and not h.velocity_known.any()


def test_a_window_longer_than_the_buffer_keeps_every_sample_and_fits_exactly():
    """A 0.5 s window at 240 Hz holds 121 samples, more than the tracker's arrays start with: they grow, and
    a constant velocity is still fitted exactly from all of them."""
    tracker = HumanTracker(TrackerParameters(window=0.5))
    v = np.array([0.7, -0.2, 0.05])
    h = feed(tracker, [np.array([0.3, 0.1, 1.0]) + v * k * DT for k in range(300)])
    assert tracker.samples == 121
    assert np.allclose(h.velocities[0], v, atol=1e-9)
    assert np.allclose(h.segments[0, 0], [0.3, 0.1, 1.0] + v * 299 * DT, atol=1e-9)


def test_a_sample_is_stamped_with_its_capture_on_the_cells_clock():
    """The data's age counts from the capture (a camera's latency is part of T_r): the sample's own time; the
    arrival where that is ahead of it (no capture after its arrival); stale (None) past OLDEST_SAMPLE, and NaN."""
    assert capture_stamp(9.94, 10.0) == 9.94
    assert capture_stamp(10.0, 10.0) == 10.0
    assert capture_stamp(12.0, 10.0) == 10.0                   # another clock, or one running ahead
    assert capture_stamp(10.0 - OLDEST_SAMPLE, 10.0) == 10.0 - OLDEST_SAMPLE
    assert capture_stamp(9.4, 10.0) is None and capture_stamp(float("nan"), 10.0) is None
    assert capture_stamp(9.8, 10.0, oldest=0.1) is None
