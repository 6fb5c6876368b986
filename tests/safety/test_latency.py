"""The latency meter: what the driver reports, and the warning when the measured p99 exceeds T_r."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.safety.latency import DelayHistogram, LatencyMeter


def test_reports_what_was_added_since_the_last_drain():
    meter = LatencyMeter(0.1)
    for k in range(5):
        meter.add(0.010 + k * 1e-3, 0.001, 0.004)
    s2f, proc, tick = meter.drain()
    assert np.allclose(s2f, [0.010, 0.011, 0.012, 0.013, 0.014]) and np.allclose(proc, 0.001)
    assert np.allclose(tick, 0.004)
    assert meter.drain()[0].size == 0


def test_bad_measurements_are_not_data():
    meter = LatencyMeter(0.1, min_samples=1)
    meter.add(float("nan"), 0.0, 0.001)
    meter.add(-0.01, 0.0, 0.001)
    meter.add(0.01, 0.0, float("nan"))
    meter.add(0.01, 0.0, -0.001)
    assert meter.p99() is None and meter.drain()[0].size == 0


def test_warns_once_when_p99_exceeds_reaction_time_and_says_when_it_is_back():
    meter = LatencyMeter(0.02, window=200, min_samples=100)
    for _ in range(99):
        meter.add(0.08, 0.001, 0.05)
    assert meter.check() is None                      # too few chains to judge
    meter.add(0.08, 0.001, 0.05)
    warning = meter.check()
    assert warning.event == "reaction_time_exceeded" and warning.severity == "warning"
    assert "50.0 ms" in warning.text and "20 ms" in warning.text
    assert meter.check() is None                      # once per episode
    for _ in range(200):
        meter.add(0.08, 0.001, 0.012)
    back = meter.check()
    assert back.event == "reaction_time_ok" and back.value == pytest.approx(0.012)


def test_within_reaction_time_never_warns():
    meter = LatencyMeter(0.1, min_samples=10)
    for x in np.linspace(0.002, 0.013, 500):
        meter.add(float(x), 0.001, float(x))
        assert meter.check() is None


def test_a_cameras_latency_is_the_datas_age_not_the_reaction():
    """A 15 Hz camera 60 ms behind: from the capture to the frame 140 ms, but from the tick that took the sample to
    the frame 12 ms: the scaling layer counts the person's travel over the age (shared.safety.ssm.aged_travel), so
    T_r 50 ms covers the rest with a drive lag of 20 ms; a slow tick -> frame does not."""
    meter = LatencyMeter(0.05, window=100, min_samples=10)
    for _ in range(20):
        meter.add(0.14, 0.004, 0.012)
    assert meter.check(motion_lag=0.020) is None
    for _ in range(100):
        meter.add(0.14, 0.004, 0.035)
    warning = meter.check(motion_lag=0.020)
    assert warning.event == "reaction_time_exceeded" and warning.value == pytest.approx(0.055)
    assert "tick -> frame p99 35.0 ms" in warning.text


def test_reaction_time_must_be_positive():
    with pytest.raises(ValueError):
        LatencyMeter(0.0)


def test_the_whole_chain_counts_the_drive_lag():
    meter = LatencyMeter(0.1, min_samples=10)
    for _ in range(20):
        meter.add(0.15, 0.002, 0.085)
    assert meter.check(motion_lag=0.0) is None                      # 85 ms alone is within T_r
    verdict = meter.check(motion_lag=0.02)                         # 85 + 20 ms is not
    assert verdict.event == "reaction_time_exceeded" and "drive lag 20.0 ms" in verdict.text


def test_drive_lag_meter_measures_the_lag_of_moving_joints_only():
    import numpy as np

    from shared.safety.latency import DriveLagMeter
    meter = DriveLagMeter(0.012, min_samples=5)
    v = np.array([1.5, 0.05, -1.0, 0.0, 0.0, 0.0])
    for k in range(10):
        setpoint = v * 0.01 * (k + 1)
        measured = v * 0.01 * k                                    # one 10 ms period behind
        meter.add(setpoint, v, measured, np.array([1e-5, 0, -2e-5, 0, 0, 0]))
    p99 = meter.p99()
    assert p99[0] == np.float64(p99[0]) and abs(p99[0] - 0.01) < 1e-9 and abs(p99[2] - 0.01) < 1e-9
    assert np.isnan(p99[1]) and np.isnan(p99[3])                  # too slow to say
    assert meter.check() is None                                   # 10 ms is within 12 ms
    lag, samples, error, missed = meter.report()
    assert missed == 0
    assert samples.tolist() == [10, 0, 10, 0, 0, 0] and abs(lag[0] - 0.01) < 1e-9 and lag[1] == 0.0
    assert error[2] == 2e-5
    for k in range(10):                                            # now 30 ms behind
        meter.add(v * 0.03, v, np.zeros(6))
    verdict = meter.check()
    assert verdict.event == "drive_lag_exceeded" and verdict.severity == "warning"
    assert meter.report()[2].max() == 0.0                          # the report drained


def test_the_lag_to_cover_rises_with_one_sync_and_is_held():
    """covering: the configured bound while the joints follow; the worst joint's |lag| of a single SYNC at
    once, ahead of the setpoint as well as behind it; held for `hold` SYNCs; a SYNC not answered a period
    more than the lag before it."""
    import numpy as np

    from shared.safety.latency import DriveLagMeter
    meter = DriveLagMeter(0.012, hold=5)
    v = np.array([1.0, 0.05, 0.0, 0.0, 0.0, 0.0])
    assert meter.covering() == 0.012                                 # nothing measured yet
    meter.add(v * 0.01, v, np.zeros(6))                               # 10 ms behind: within the bound
    assert meter.covering() == 0.012
    meter.add(v * 0.01, v, v * 0.035)                                 # 25 ms ahead (an overshoot)
    assert abs(meter.covering() - 0.025) < 1e-9
    meter.add(np.array([0.0, 1.0, 0, 0, 0, 0]), v, np.zeros(6))       # joint 2 too slow to give a lag
    for _ in range(3):
        meter.add(v * 0.01, v, np.zeros(6))
    assert abs(meter.covering() - 0.025) < 1e-9                       # still within the hold
    meter.add(v * 0.01, v, np.zeros(6))
    assert meter.covering() == 0.012                                  # the hold has passed
    meter.missed(0.01)
    assert abs(meter.covering() - 0.022) < 1e-9                       # bound + a period
    meter.missed(0.01)
    assert abs(meter.covering() - 0.032) < 1e-9                       # two in a row: two periods
    assert meter.report()[3] == 2 and meter.report()[3] == 0          # counted in the report, once


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 2.0), min_size=1, max_size=400), st.sampled_from([50.0, 90.0, 99.0, 100.0]))
def test_the_delay_histogram_gives_the_percentile_to_one_bin(delays, q):
    hist = DelayHistogram(resolution=0.001, limit=10.0)
    for d in delays:
        hist.add(d)
    exact = float(np.percentile(delays, q, method="inverted_cdf"))
    assert exact - 1e-12 <= hist.percentile(q) <= exact + 0.001 + 1e-12
    assert hist.largest == max(delays) and hist.total == len(delays)


def test_the_delay_histogram_keeps_a_delay_beyond_its_range_and_is_zero_when_empty():
    hist = DelayHistogram(resolution=0.001, limit=1.0)
    assert hist.percentile(99) == 0.0
    hist.add(0.002)
    hist.add(30.0)                          # a monitor 30 s behind: counted, reported as the largest
    assert hist.percentile(100) == 30.0 and hist.largest == 30.0
    assert hist.percentile(50) == pytest.approx(0.003)


def test_two_delay_histograms_merged_are_one_histogram_of_both_and_other_bins_are_refused():
    first, second, both = (DelayHistogram(resolution=0.001, limit=1.0) for _ in range(3))
    for d in (0.002, 0.010, 0.5):
        first.add(d)
        both.add(d)
    for d in (0.004, 3.0):
        second.add(d)
        both.add(d)
    first.absorb(second)
    assert np.array_equal(first.counts, both.counts) and first.total == 5 and first.largest == 3.0
    assert first.percentile(50) == both.percentile(50)
    with pytest.raises(ValueError, match="other bins"):
        first.absorb(DelayHistogram(resolution=0.002, limit=1.0))


