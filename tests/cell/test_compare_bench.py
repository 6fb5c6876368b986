"""bench/compare.py's command line and its ratios (the figures themselves are the benchmark's, not asserted): the
tests that start a process or a network namespace (the rest, in-process, are in
tests/evidence/test_compare_bench.py)."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.util import ROOT, load_bench


def run(*args: str, tmp_path: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(ROOT / "bench" / "compare.py"), "--out", str(tmp_path), *args],
                          capture_output=True, text=True, timeout=300, cwd=ROOT)


def test_unknown_kinds_are_refused_naming_the_known_ones(tmp_path):
    done = run("--kinds", "standing,nope", tmp_path=tmp_path)
    assert done.returncode == 2 and "--kinds: unknown or none ['nope']" in done.stderr and "two_humans" in done.stderr


def test_one_kind_runs_and_its_ratios_come_with_intervals(tmp_path):
    done = run("--scenarios", "2", "--kinds", "standing", "--duration", "0.5", "--workers", "1", tmp_path=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert set(result["kinds"]) == {"standing"} and set(result["ratios"]) == {"standing", "overall"}
    low_mid_high = result["ratios"]["overall"]["full/scale_only"]
    assert low_mid_high[1] <= low_mid_high[0] <= low_mid_high[2]
    # nobody in the cell: the robot shuttles at full speed, never slower than any strategy with a person in it
    assert result["empty_cell"] >= max(result["kinds"]["standing"].values())
    assert set(result["won_back"]) == {"standing", "overall"}
    assert (tmp_path / "compare.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(json.loads((tmp_path / "scenarios.json").read_text())) == 2


@pytest.mark.parametrize("bound, other", [("foresight", "oracle"), ("oracle", "foresight")])
def test_a_bound_adds_its_column_with_its_ratios_and_only_it(tmp_path, bound, other):
    done = run("--scenarios", "1", "--kinds", "paper", "--duration", "1.0", "--workers", "1", f"--{bound}",
               tmp_path=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert set(result["kinds"]["paper"]) == {"zones", "scale_only", "full", bound}
    assert {f"{bound}/scale_only", f"full/{bound}"} <= set(result["ratios"]["overall"])
    assert f"{other}/scale_only" not in result["ratios"]["overall"] and f"won_back_{other}" not in result
    assert set(result[f"won_back_{bound}"]) == {"paper", "overall"}
    assert bound in json.loads((tmp_path / "scenarios.json").read_text())[0]
    assert (tmp_path / "compare.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # without it, neither the column nor its ratios
    plain = {"kind": "standing", "zones": {"shuttles": 1.0}, "scale_only": {"shuttles": 1.0}, "full": {"shuttles": 2.0}}
    assert load_bench("compare").ratios([plain]).keys() == {"full/scale_only", "full/zones"}


def test_the_paper_formula_runs_beside_the_shipped_model_on_the_same_scenarios(tmp_path):
    """--paper: scale_only and full under the paper's formula, their ratios to the shipped model's; judged by
    the shipped model's monitor like every column."""
    done = run("--scenarios", "1", "--kinds", "paper", "--duration", "2.0", "--workers", "1", "--paper",
               tmp_path=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert set(result["kinds"]["paper"]) == {"zones", "scale_only", "full", "scale_only_paper", "full_paper"}
    assert {"scale_only/scale_only_paper", "full/full_paper", "full_paper/zones"} <= set(result["ratios"]["overall"])
    assert "won_back_scale_only_paper" not in result and "won_back_full_paper" not in result
    assert "full_paper/scale_only_paper" in result["ratios"]["overall"]
    assert "full_paper/fixed_path_paper" not in result["ratios"]["overall"]          # not without --fixed-path
    assert result["strategies"]["full_paper"]["violations"] >= 0


def test_the_fixed_path_baseline_runs_beside_the_strategies_with_its_ratios(tmp_path):
    """--fixed-path: the scaling layer on one fixed folded path, its column, full/fixed_path and its won-back
    share, on the same scenarios; with --paper too, the same under the paper's formula (fixed_path_paper) and the
    planning layer's ratios to it under that formula."""
    done = run("--scenarios", "2", "--kinds", "two_humans", "--duration", "2.0", "--workers", "1", "--fixed-path",
               "--paper", tmp_path=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert set(result["kinds"]["two_humans"]) == {"zones", "scale_only", "full", "fixed_path", "scale_only_paper",
                                                  "full_paper", "fixed_path_paper"}
    assert {"fixed_path/scale_only", "full/fixed_path", "full_paper/fixed_path_paper",
            "fixed_path_paper/scale_only_paper", "full_paper/scale_only_paper"} <= set(result["ratios"]["overall"])
    assert set(result["won_back_fixed_path"]) == {"two_humans", "overall"}
    assert result["strategies"]["fixed_path"]["violations"] == 0


def test_a_latency_runs_every_strategy_that_late_and_a_bad_one_is_refused(tmp_path):
    """--latency: each strategy given the people 30 ms after their capture (its records say so), zones sized for
    it; a latency beyond the oldest sample the cell takes is refused with a message, nothing run."""
    done = run("--scenarios", "1", "--kinds", "crossing", "--duration", "1.0", "--workers", "1", "--latency", "0.03",
               tmp_path=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["latency_s"] == 0.03 and set(result["kinds"]["crossing"]) == {"zones", "scale_only", "full"}
    import pyarrow.parquet as pq

    records = [r for p in tmp_path.glob("run-*/records/*.parquet") for r in pq.read_table(p).to_pylist()]
    assert len(records) == 3 and {r["latency"] for r in records} == {0.03}
    for bad in ("-0.01", "0.8", "soon"):
        refused = run("--latency", bad, tmp_path=tmp_path)
        assert refused.returncode == 2 and "--latency" in refused.stderr, bad
