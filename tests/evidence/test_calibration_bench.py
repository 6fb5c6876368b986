"""bench/calibration.py's command line, and what its --truth means: with the people's own future, the scaling
layer's forward run predicts what the scaling layer then does (the other figures are the benchmark's)."""

import json
import sys

import pytest

from tests.util import load_bench


def run(monkeypatch, capsys, *args: str) -> tuple[int, str]:
    bench = load_bench("calibration")
    monkeypatch.setattr(sys, "argv", ["calibration.py", *args])
    code = bench.main()
    return code, capsys.readouterr().out


def test_with_the_future_known_the_forward_run_predicts_the_execution(monkeypatch, capsys):
    code, out = run(monkeypatch, capsys, "--seeds", "1", "--seed", "1", "--kinds", "crossing", "--moments", "1",
                    "--truth", "--judge", "scaling", "--worst", "2")
    assert code == 0
    figures = json.loads(out.strip().splitlines()[-1])
    crossing = figures["kinds"]["crossing"]
    assert figures["truth"] and figures["judge"] == "scaling" and crossing["finished"] == 6, figures
    assert crossing["abs_error_p95"] < 0.02 and crossing["ranked_right"] == 1.0, crossing
    assert list(crossing["by_moment"]) == ["0"] and crossing["by_moment"]["0"] == [crossing["abs_error_median"],
                                                                                   crossing["abs_error_p95"]]
    assert sum(line.startswith("  worst: seed 1 from 0.0 s") for line in out.splitlines()) == 2, out


def test_other_futures_say_what_no_forecast_can_predict_in_the_wandering_kinds_only(monkeypatch, capsys):
    code, out = run(monkeypatch, capsys, "--seeds", "1", "--seed", "1000", "--kinds", "random_walk,crossing",
                    "--moments", "1", "--futures", "3")
    assert code == 0
    figures = json.loads(out.strip().splitlines()[-1])
    walk, crossing = figures["kinds"]["random_walk"], figures["kinds"]["crossing"]
    assert figures["futures"] == 3 and "unforeseeable" not in crossing, figures
    floor = walk["unforeseeable"]
    assert floor["legs"] == walk["finished"] > 0, floor
    for tolerance in ("within_5pc", "within_15pc"):
        held_out, in_sample = floor[tolerance]
        assert 0.0 <= held_out <= 1.0 and 0.25 <= in_sample <= 1.0, floor     # one of four is always within
    assert floor["within_5pc"][1] <= floor["within_15pc"][1], floor
    assert 0.0 <= floor["ranked_right"] <= 1.0 and floor["loss_s"] >= 0.0, floor
    assert "other futures of its people" in out


def test_a_leg_is_judged_against_its_own_future_which_the_prediction_never_saw():
    bench = load_bench("calibration")
    same = bench.unforeseeable([10.0, 10.0, 10.0], 10.0)
    assert same["least_error"] == 0.0 and same[0.05] == (True, 1.0) and same[0.15] == (True, 1.0)
    apart = bench.unforeseeable([10.0, 10.0, 10.0], 20.0)           # the own future slower than every other
    assert apart["least_error"] == pytest.approx(-0.5) and apart[0.15] == (False, 0.75)
    summary = bench.floor_summary([same, apart])
    assert summary["within_5pc"] == [0.5, 0.875] and summary["legs"] == 2


@pytest.mark.parametrize("args", [("--worst", "-1"), ("--truth", "--stay", "2"), ("--kinds", "moon"),
                                  ("--judge", "oracle"), ("--futures", "-2")])
def test_bad_arguments_are_refused_with_exit_2(monkeypatch, capsys, args):
    with pytest.raises(SystemExit) as stop:
        run(monkeypatch, capsys, *args)
    assert stop.value.code == 2


def test_the_people_stay_as_long_as_the_planning_layers_presence_clocks_say_by_each_moment():
    """The default prediction has the people stay as the planning loop has them stay: patience plus how long its
    presence clocks have counted by then, the scenario replayed from its start (a person who has stood beside the
    path for seconds is expected to stay that much longer; a walker is not)."""
    from evidence.scenarios import make_scenario

    bench = load_bench("calibration")
    standing = make_scenario("standing", 3, 12.0)              # walks up, then stands reaching in for good
    arrived = standing.keyframes[1].t
    at_start, waited = bench.presence_waited(standing, [0.0, 8.0], 0.01)
    assert 8.0 - arrived - 0.5 < waited <= 8.0 - arrived + 0.01, (arrived, waited)
    assert at_start == 0.0 and bench.presence_waited(standing, [8.0], 0.01) == [waited]    # one replay, the same
    crossing = make_scenario("crossing", 3, 12.0)              # walking at 1.6 m/s the whole time
    assert bench.presence_waited(crossing, [8.0], 0.01)[0] < 0.2
