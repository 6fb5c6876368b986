"""bench/forecast_value.py: the future told to one kind of decision at a time. Its two ends are the strategies they
stand for (told everything: the foresight strategy to the digit), and its command line refuses what it cannot run."""

import sys

import pytest

from evidence.strategies import Strategies
from tests.util import load_bench


def test_told_every_decision_it_is_the_foresight_strategy_and_told_none_the_forecast_costs_shuttles():
    bench = load_bench("forecast_value")
    foresight = Strategies().run("foresight", "random_walk", 12112, 6.0)
    kind, seed, row, told_all, violations = bench.one(("random_walk", 12112, 6.0, "everything", None))
    assert (kind, seed, row, violations) == ("random_walk", 12112, "everything", 0)
    assert told_all == pytest.approx(foresight.progress, abs=1e-12)
    told_none = bench.one(("random_walk", 12112, 6.0, "nothing", None))[3]
    assert told_none < told_all - 0.1           # the forecast matters here: 1.73 against 2.14 shuttles


@pytest.mark.parametrize("args", [("--kinds", "moon"), ("--seeds", "0"), ("--forecaster", "nowhere:thing")])
def test_bad_arguments_are_refused_with_exit_2(monkeypatch, args):
    bench = load_bench("forecast_value")
    monkeypatch.setattr(sys, "argv", ["forecast_value.py", *args])
    with pytest.raises(SystemExit) as stop:
        bench.main()
    assert stop.value.code == 2
