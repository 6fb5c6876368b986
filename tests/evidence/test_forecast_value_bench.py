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


def test_the_clairvoyant_report_gives_each_strategy_and_the_bound_over_scale_only():
    """The issue's goals are ratios over scale_only: the report prints them beside the shares of the bound's room."""
    from argparse import Namespace

    from evidence.clairvoyant import SEARCHES
    bench = load_bench("bound_search")
    rows = [{"kind": "two_humans", "seed": s, "runs": 10,
             "beside": {"scale_only": 4.0, "fixed_path": 4.2, "full": 4.4, "foresight": 4.6},
             "bound": {size: (4.8 if size == max(SEARCHES) else 4.5, (0, 1)) for size in SEARCHES}} for s in (1, 2)]
    out = bench.clairvoyant_report(rows, ["two_humans"], Namespace(paper=False, seeds=2, duration=12.0, greedy=False))
    kind = out["kinds"]["two_humans"]
    assert kind["over_scale_only"] == {"fixed_path": 1.05, "full": 1.1, "foresight": 1.15, "bound": 1.2}
    assert kind["share_of_room"]["full"] == 0.5        # (8.8 - 8) / (9.6 - 8)
