"""Paired bootstrap intervals of the side-by-side comparison (evidence.stats)."""

import numpy as np
import pytest

from evidence.stats import paired_ratio


def test_identical_strategies_give_one_with_no_spread_and_every_scenario_a_tie():
    shuttles = np.random.default_rng(1).uniform(1.0, 5.0, 50)
    r = paired_ratio(shuttles, shuttles, np.random.default_rng(0))
    assert (r.ratio, r.low, r.high) == (1.0, 1.0, 1.0)
    assert (r.better, r.worse, r.same) == (0, 0, 50)


def test_a_consistent_gain_is_inside_its_interval_and_one_is_outside():
    rng = np.random.default_rng(2)
    base = rng.uniform(1.0, 5.0, 200)                     # scenarios differ a lot ...
    better = base * 1.1 + rng.normal(0.0, 0.05, 200)      # ... the strategy adds 10 % to each
    r = paired_ratio(better, base, np.random.default_rng(0))
    assert r.low < 1.1 < r.high
    assert r.low > 1.05                                    # pairing: the scenarios' spread cancels
    assert r.better > 190


def test_noise_alone_leaves_one_inside_the_interval():
    rng = np.random.default_rng(3)
    base = rng.uniform(1.0, 5.0, 200)
    r = paired_ratio(base + rng.normal(0.0, 0.3, 200), base, np.random.default_rng(0))
    assert r.low < 1.0 < r.high


def test_unpaired_resampling_would_be_wider():
    """The interval is the paired one: resampling the two strategies' scenarios independently gives a far
    wider spread for the same data."""
    rng = np.random.default_rng(4)
    base = rng.uniform(1.0, 5.0, 200)
    other = base * 1.02
    paired = paired_ratio(other, base, np.random.default_rng(0))
    picks_a, picks_b = rng.integers(0, 200, (2, 4000, 200))
    unpaired = other[picks_a].sum(axis=1) / base[picks_b].sum(axis=1)
    assert paired.high - paired.low < 0.1 * (np.percentile(unpaired, 97.5) - np.percentile(unpaired, 2.5))


def test_the_same_seed_gives_the_same_interval():
    rng = np.random.default_rng(5)
    a, b = rng.uniform(1, 5, 40), rng.uniform(1, 5, 40)
    assert paired_ratio(a, b, np.random.default_rng(7)) == paired_ratio(a, b, np.random.default_rng(7))


@pytest.mark.parametrize("a, b, match", [
    ([], [], "non-empty"),
    ([1.0, 2.0], [1.0], "equally long"),
    ([1.0, np.nan], [1.0, 1.0], "finite"),
    ([1.0, -1.0], [1.0, 1.0], "non-negative"),
    ([1.0, 2.0], [0.0, 0.0], "did nothing"),
])
def test_bad_inputs_are_refused_with_a_reason(a, b, match):
    with pytest.raises(ValueError, match=match):
        paired_ratio(a, b, np.random.default_rng(0))
