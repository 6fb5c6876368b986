"""The people's forecast as a function of time (PeopleForecast.at) and bench/forecast.py's command line and
errors (the figures themselves are the benchmark's, not asserted)."""


import numpy as np
import pytest

from evidence.scenarios import make_scenario
from shared.core.humans import HumanCapsules
from shared.planning.forecast import ConstantVelocity, DampedVelocity, PeopleForecast, forecaster_problem, load_forecaster
from tests.util import load_bench


def test_a_forecast_is_linear_between_frames_and_holds_after_the_last():
    frames = np.zeros((3, 1, 2, 3))
    frames[1, :, :, 0], frames[2, :, :, 0] = 1.0, 1.5          # x: 0 -> 1 -> 1.5 m at 0, 0.5, 1 s
    ahead = PeopleForecast(frames, np.zeros_like(frames), 0.5)
    assert ahead.horizon == pytest.approx(1.0)
    for shift, x in ((0.0, 0.0), (0.25, 0.5), (0.5, 1.0), (0.75, 1.25), (1.0, 1.5), (3.0, 1.5), (-1.0, 0.0)):
        np.testing.assert_allclose(ahead.at(shift)[..., 0], x)
    still = PeopleForecast.still(HumanCapsules.from_arrays(frames[0], [0.1]))
    np.testing.assert_array_equal(still.at(2.0), frames[0])


def test_the_errors_are_zero_for_a_forecast_that_knows_and_grow_for_one_that_does_not():
    bench = load_bench("forecast")
    script = make_scenario("crossing", 1, 6.0)

    class Knows:       # the script's own future: no error at all
        def forecast(self, humans, horizon):
            return PeopleForecast(np.stack([humans.segments, script.at(self.now + horizon).segments]),
                                  np.stack([humans.velocities] * 2), horizon)

    class Clocked:     # the people, telling Knows the moment
        def at(self, t):
            knows.now = t
            return script.at(t)

    knows = Knows()
    assert bench.capsule_errors(Clocked(), 6.0, 1.0, knows).max() < 1e-9
    # someone crossing at 1.6 m/s: holding them where they are is off by about 1.6 m a second later
    still = bench.capsule_errors(script, 6.0, 1.0, bench.Still())
    assert still.size > 0 and 1.0 < np.median(still) <= 1.6 + 1e-9
    assert np.median(bench.capsule_errors(script, 6.0, 1.0, ConstantVelocity())) < np.median(still)
    assert bench.summarise(np.zeros(0)) is None


def make_still():
    """A factory: load_forecaster calls it."""
    return load_bench("forecast").Still()


def test_forecasters_are_loaded_by_name_or_refused_saying_why():
    assert isinstance(load_forecaster("shared.planning.forecast:ConstantVelocity"), ConstantVelocity)   # a class
    assert isinstance(load_forecaster("tests.evidence.test_forecast_bench:make_still").forecast(
        make_scenario("crossing", 0, 2.0).at(0.5), 1.0), PeopleForecast)                                  # a factory
    for spec, why in (("ConstantVelocity", "module:attribute"), ("no.such.module:X", "cannot import"),
                      ("shared.planning.forecast:Nope", "has no 'Nope'"), ("numpy:pi", "no forecast")):
        with pytest.raises(ValueError, match=why):
            load_forecaster(spec)
        assert why in forecaster_problem(spec)                     # what the entry points print before they run
    assert forecaster_problem("shared.planning.forecast:ConstantVelocity") is None


def test_a_damped_forecast_slows_the_people_down():
    walking = make_scenario("crossing", 1, 6.0).at(1.0)
    damped, constant = DampedVelocity(time_constant=1.0).forecast(walking, 2.0), ConstantVelocity().forecast(walking, 2.0)
    moved = np.linalg.norm(damped.at(2.0) - walking.segments, axis=2).max()
    assert moved == pytest.approx((1.0 - np.exp(-2.0)) / 2.0 * np.linalg.norm(constant.at(2.0) - walking.segments,
                                                                               axis=2).max())
    assert np.abs(damped.velocities[-1]).max() == pytest.approx(np.exp(-2.0) * np.abs(walking.velocities).max())


