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
    assert sum(line.startswith("  worst: seed 1 from 0.0 s") for line in out.splitlines()) == 2, out


@pytest.mark.parametrize("args", [("--worst", "-1"), ("--truth", "--stay", "2"), ("--kinds", "moon"),
                                  ("--judge", "oracle")])
def test_bad_arguments_are_refused_with_exit_2(monkeypatch, capsys, args):
    with pytest.raises(SystemExit) as stop:
        run(monkeypatch, capsys, *args)
    assert stop.value.code == 2
