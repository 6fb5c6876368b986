"""The best one prediction of a spread of times: the most within a relative error, the least expected error;
each against a brute-force search over predictions."""

import numpy as np
import pytest

from evidence.prediction import best_within, least_relative_error


def test_the_prediction_with_the_most_times_within_a_tolerance_finds_the_cluster():
    times = [1.0, 1.1, 1.2, 2.0, 2.05, 2.1, 2.2]
    guess, share = best_within(times, 0.05)
    assert share == pytest.approx(4 / 7) and guess == pytest.approx(2.09)     # 2.0 ... 2.2 all within 5 % of it
    assert all(abs(guess / t - 1.0) <= 0.05 + 1e-12 for t in times[3:])
    assert best_within([3.0], 0.0) == (3.0, 1.0) and best_within([2.0, 2.0, 5.0], 0.0) == (2.0, pytest.approx(2 / 3))


@pytest.mark.parametrize("seed", range(5))
def test_no_prediction_has_more_times_within_the_tolerance_than_the_best(seed):
    rng = np.random.default_rng(seed)
    times = rng.lognormal(1.0, 0.3, size=int(rng.integers(2, 30)))
    for tolerance in (0.05, 0.15):
        guess, share = best_within(times, tolerance)
        assert share == pytest.approx(np.mean(np.abs(guess / times - 1.0) <= tolerance + 1e-12))
        grid = np.linspace(times.min() * 0.8, times.max() * 1.2, 20001)
        brute = (np.abs(grid[:, None] / times[None, :] - 1.0) <= tolerance).mean(axis=1).max()
        assert share >= brute - 1e-12


@pytest.mark.parametrize("seed", range(5))
def test_the_least_relative_error_prediction_beats_every_other(seed):
    rng = np.random.default_rng(seed)
    times = rng.lognormal(1.0, 0.4, size=int(rng.integers(1, 25)))
    best = least_relative_error(times)
    error = lambda p: float(np.mean(np.abs(p / times - 1.0)))
    grid = np.linspace(times.min() * 0.5, times.max() * 1.5, 20001)
    assert best in times and error(best) <= min(error(p) for p in grid) + 1e-12


@pytest.mark.parametrize("bad", [[], [1.0, 0.0], [1.0, -2.0], [float("nan")], [float("inf")]])
def test_times_that_are_no_times_are_refused(bad):
    with pytest.raises(ValueError, match="samples"):
        best_within(bad, 0.05)
    with pytest.raises(ValueError, match="samples"):
        least_relative_error(bad)


@pytest.mark.parametrize("tolerance", [-0.1, 1.0, float("nan")])
def test_a_tolerance_outside_0_1_is_refused(tolerance):
    with pytest.raises(ValueError, match="tolerance"):
        best_within([1.0, 2.0], tolerance)
