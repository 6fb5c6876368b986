"""Other futures of a wandering scenario: the same people up to the end of the wanderer's present stop, then
stops drawn as the scenario draws its own; repeatable by their random stream."""

import numpy as np
import pytest

from evidence.scenarios import WANDERING_KINDS, make_scenario, other_futures

TIMES = np.arange(0.0, 20.0, 0.02)


def first_difference(a, b) -> float | None:
    """s: the first of TIMES at which two scripted crowds' capsules differ (None: never)."""
    for t in TIMES:
        if np.abs(a.at(t).segments - b.at(t).segments).max() > 1e-9:
            return float(t)
    return None


@pytest.mark.parametrize("kind", WANDERING_KINDS)
@pytest.mark.parametrize("t0", [0.0, 4.0, 9.0])
def test_a_future_keeps_the_past_and_the_present_stop_and_draws_the_rest(kind, t0):
    own = make_scenario(kind, 11, 20.0)
    futures = other_futures(kind, 11, 20.0, t0, np.random.default_rng(3), 3)
    assert len(futures) == 3
    parted = [first_difference(own, future) for future in futures]
    assert all(p is not None and t0 < p < t0 + 6.0 for p in parted), parted     # the same until after t0, then not
    assert len(set(parted)) == 1                               # all part where the present stop is left
    assert first_difference(futures[0], futures[1]) is not None                # each future its own
    again = other_futures(kind, 11, 20.0, t0, np.random.default_rng(3), 3)
    assert all(first_difference(a, b) is None for a, b in zip(futures, again))  # the same stream, the same futures


def test_the_crosser_of_two_people_walks_as_in_the_scenario():
    own = make_scenario("two_humans", 4, 20.0)
    future = other_futures("two_humans", 4, 20.0, 2.0, np.random.default_rng(0), 1)[0]
    assert first_difference(own.humans[0], future.humans[0]) is None
    assert first_difference(own.humans[1], future.humans[1]) is not None


@pytest.mark.parametrize("kind", ["crossing", "standing", "paper"])
def test_a_kind_whose_future_is_fixed_by_its_start_has_no_other(kind):
    with pytest.raises(ValueError, match="wandering kinds"):
        other_futures(kind, 0, 12.0, 1.0, np.random.default_rng(0), 2)
