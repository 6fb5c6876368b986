"""The latency meter: what the driver reports, and the warning when the measured p99 exceeds T_r."""

import numpy as np
import pytest

from shared.latency import LatencyMeter


def test_reports_what_was_added_since_the_last_drain():
    meter = LatencyMeter(0.1)
    for k in range(5):
        meter.add(0.010 + k * 1e-3, 0.001)
    s2f, proc = meter.drain()
    assert np.allclose(s2f, [0.010, 0.011, 0.012, 0.013, 0.014]) and np.allclose(proc, 0.001)
    assert meter.drain()[0].size == 0


def test_bad_measurements_are_not_data():
    meter = LatencyMeter(0.1, min_samples=1)
    meter.add(float("nan"), 0.0)
    meter.add(-0.01, 0.0)
    assert meter.p99() is None and meter.drain()[0].size == 0


def test_warns_once_when_p99_exceeds_reaction_time_and_says_when_it_is_back():
    meter = LatencyMeter(0.02, window=200, min_samples=100)
    for _ in range(99):
        meter.add(0.05, 0.001)
    assert meter.check() is None                      # too few chains to judge
    meter.add(0.05, 0.001)
    warning = meter.check()
    assert warning.event == "reaction_time_exceeded" and warning.severity == "warning"
    assert "50.0 ms" in warning.text and "20 ms" in warning.text
    assert meter.check() is None                      # once per episode
    for _ in range(200):
        meter.add(0.012, 0.001)
    back = meter.check()
    assert back.event == "reaction_time_ok" and back.p99 == pytest.approx(0.012)


def test_within_reaction_time_never_warns():
    meter = LatencyMeter(0.1, min_samples=10)
    for x in np.linspace(0.002, 0.013, 500):
        meter.add(float(x), 0.001)
        assert meter.check() is None


def test_reaction_time_must_be_positive():
    with pytest.raises(ValueError):
        LatencyMeter(0.0)
