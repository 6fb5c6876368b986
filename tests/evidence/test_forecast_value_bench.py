"""bench/forecast_value.py: the future told to one kind of decision at a time. Its two ends are the strategies they
stand for (told everything: the foresight strategy to the digit), and its command line refuses what it cannot run."""

import sys

import pytest

from evidence.strategies import Strategies
from tests.util import load_bench


def test_told_every_decision_it_is_the_foresight_strategy_and_told_none_the_forecast_costs_shuttles():
    bench = load_bench("forecast_value")
    foresight = Strategies().run("foresight", "random_walk", 12105, 6.0)
    kind, seed, row, told_all, violations = bench.one(("random_walk", 12105, 6.0, "everything", None))
    assert (kind, seed, row, violations) == ("random_walk", 12105, "everything", 0)
    assert told_all == pytest.approx(foresight.progress, abs=1e-12)
    told_none = bench.one(("random_walk", 12105, 6.0, "nothing", None))[3]
    assert told_none < told_all - 0.1           # the forecast matters here: 1.74 against 2.06 shuttles


@pytest.mark.parametrize("name, args", [("forecast_value", ("--kinds", "moon")), ("forecast_value", ("--seeds", "0")),
                                        ("forecast_value", ("--forecaster", "nowhere:thing")),
                                        ("bound_search", ("--kinds", "moon")), ("bound_search", ("--duration", "0"))])
def test_bad_arguments_are_refused_with_exit_2(monkeypatch, name, args):
    """The scenario options both benchmarks share (evidence.scenarios.scenario_arguments), and the forecaster."""
    bench = load_bench(name)
    monkeypatch.setattr(sys, "argv", [f"{name}.py", *args])
    with pytest.raises(SystemExit) as stop:
        bench.main()
    assert stop.value.code == 2
