"""Sweeps without processes: one scenario as a pure function, records through Parquet, the grid, the plan
that keeps a folder to one sweep, progress lines, a chunk retried and then reported (tools.sweep with an
in-process stand-in for the pool is in tests/cell/test_sweep.py, with the real pool and Dask)."""

import csv
import io
import math
import re

import pytest

from evidence.summary import against_first, against_other, compared, per_point, wide_rows
from evidence.sweep import RECORD_FIELDS, ScenarioSpec, config_of, run_scenario
from shared.core.errors import ConfigError
from tools import grid as grids
from tools import sweep


def same(a: list[dict], b: list[dict]) -> bool:
    """Records equal field by field, but for the compute they cost (NaN equal to NaN)."""
    def key(r):
        return [(k, "nan" if isinstance(v, float) and math.isnan(v) else v) for k, v in r.items() if k != "wall_s"]
    return [key(r) for r in a] == [key(r) for r in b]


def test_a_scenario_is_a_pure_function_of_its_spec():
    spec = ScenarioSpec("standing", 3, 1.0, "scale_only", overrides=(("ssm.reaction_time", 0.15),))
    first, again = run_scenario(spec), run_scenario(spec)
    assert set(first) == set(RECORD_FIELDS) and same([first], [again])
    assert first["overrides"] == '{"ssm.reaction_time": 0.15}' and first["sim_s"] == pytest.approx(1.0, abs=0.02)
    other = run_scenario(ScenarioSpec("standing", 3, 1.0, "scale_only", overrides=(("ssm.reaction_time", 0.3),)))
    assert other["shuttles"] < first["shuttles"]        # a longer reaction time: larger distances, slower robot


def test_overrides_are_checked_as_a_configuration_file_is():
    assert config_of((("ssm.reaction_time", 0.2),)).ssm.reaction_time == 0.2
    with pytest.raises(ConfigError, match="nope"):
        config_of((("ssm.nope", 1.0),))
    with pytest.raises(ConfigError, match="section.key"):
        config_of((("reaction_time", 1.0),))


def records(n: int, strategies=("scale_only", "full")) -> list[dict]:
    base = {f: 0 for f in RECORD_FIELDS}
    return [base | {"kind": "standing", "seed": k, "duration": 2.0, "strategy": s, "overrides": "{}",
                    "forecaster": "", "shuttles": 1.0 + k + (s == "full"), "sim_s": 2.0, "stopped_fraction": 0.1,
                    "slowed_fraction": 0.2, "stopped_s": 0.2, "slowed_s": 0.4, "min_margin_m_s": float("nan"),
                    "wall_s": 0.5} for k in range(n) for s in strategies]


def test_records_survive_parquet_and_sum_up_as_the_comparison_does(tmp_path):
    rs = records(3)
    sweep.write_chunk(tmp_path, 1, rs[3:])
    sweep.write_chunk(tmp_path, 0, rs[:3])
    back = sweep.read_records(tmp_path)
    assert same(back, rs)                                              # chunk order, every field, NaN kept
    assert not list((tmp_path / "records").glob("*.tmp"))
    rows = wide_rows(back)
    assert len(rows) == 3 and rows[0]["full"]["min_margin_m_s"] is None
    (point,) = per_point(back, 0.4)
    assert point["scenarios"] == 3 and point["strategies"]["full"]["shuttles_per_min"] == pytest.approx(60 * 9 / 6)
    assert point["ratios"]["full/scale_only"].ratio == pytest.approx(9 / 6)


def test_the_grid_is_every_combination_and_bad_grids_are_refused():
    grid = grids.Grid({"ssm.reaction_time": [0.1, 0.2], "scaling.alpha_min": [0.1, 0.15, 0.2]}, ["scale_only"],
                      ["standing", "crossing"], 3, 2.0)
    assert len(grid.points()) == 6 and len(grid.specs()) == 18
    assert [s.kind for s in grid.specs()[:3]] == ["standing", "crossing", "standing"]
    assert {s.latency for s in grid.specs()} == {0.0}
    assert {s.latency for s in grids.Grid(**{**grid.__dict__, "latency": 0.03}).specs()} == {0.03}
    grids.check_grid(grid)
    for bad, what in ((dict(strategies=["fastest"]), "strategies"), (dict(kinds=["moon"]), "kinds"),
                      (dict(values={"ssm.reaction_time": [-1.0]}), "reaction_time"), (dict(scenarios=0), "scenarios")):
        with pytest.raises(grids.GridError, match=what):
            grids.check_grid(grids.Grid(**{**grid.__dict__, **bad}))
    assert grids.parse_values("ssm.reaction_time=0.1,0.15") == ("ssm.reaction_time", [0.1, 0.15])
    assert grids.parse_values("planning.judge=cost, scaling") == ("planning.judge", ["cost", "scaling"])
    for text in ("ssm.reaction_time", "=1", "ssm.reaction_time=0.1,"):
        with pytest.raises(grids.GridError):
            grids.parse_values(text)
    # a choice is swept by its words; a number's key refuses a word, a choice an unknown word, and a key
    # refuses numbers and words mixed
    grids.check_grid(grids.Grid(**{**grid.__dict__, "values": {"planning.judge": ["cost", "scaling"]}}))
    for values, what in (({"ssm.reaction_time": ["fast"]}, "reaction_time"), ({"planning.judge": ["oracle"]}, "judge"),
                         ({"ssm.reaction_time": [0.1, "fast"]}, "all numbers or all words")):
        with pytest.raises(grids.GridError, match=what):
            grids.check_grid(grids.Grid(**{**grid.__dict__, "values": values}))


def test_a_grid_file_is_read_and_a_broken_one_refused(tmp_path):
    good = tmp_path / "g.yaml"
    good.write_text("set:\n  ssm.reaction_time: [0.1, 0.2]\nscenarios: 4\n")
    assert grids.load_grid(good)["set"] == {"ssm.reaction_time": [0.1, 0.2]}
    for text in ("set: 3\n", "sett: {}\n", "set: {ssm.reaction_time: []}\n", "\x00\xff[", "- 1\n"):
        bad = tmp_path / "b.yaml"
        bad.write_bytes(text.encode("latin-1"))
        with pytest.raises(grids.GridError):
            grids.load_grid(bad)


def test_a_folder_holds_one_sweep(tmp_path):
    specs = [ScenarioSpec("standing", k, 1.0, "scale_only") for k in range(3)]
    sweep.write_plan(tmp_path, specs, 2, {"code": "abc"})
    sweep.write_plan(tmp_path, specs, 2, {"code": "abc"})                # the same sweep: resumed
    for other in ((specs[:2], 2, {"code": "abc"}), (specs, 3, {"code": "abc"}), (specs, 2, {"code": "def"})):
        with pytest.raises(sweep.SweepMismatch, match="another sweep"):
            sweep.write_plan(tmp_path, *other)


def test_a_latency_is_part_of_the_spec_its_record_and_its_plan_and_a_bad_one_is_refused(tmp_path):
    now = ScenarioSpec("standing", 3, 1.0, "scale_only")
    late = ScenarioSpec("standing", 3, 1.0, "scale_only", latency=0.03)
    assert run_scenario(now)["latency"] == 0.0
    record = run_scenario(late)
    assert record["latency"] == 0.03 and set(record) == set(RECORD_FIELDS)
    assert sweep.plan_id([now]) != sweep.plan_id([late])
    assert sweep.plan_of([now], 2, {})["specs"] == [["standing", 3, 1.0, "scale_only", [], None]]   # as before
    for bad in (-0.01, float("nan"), 0.6):
        with pytest.raises(ConfigError, match="latency"):
            ScenarioSpec("standing", 3, 1.0, "scale_only", latency=bad)
    older = {f: 0 for f in RECORD_FIELDS if f != "latency"}         # a sweep written before the latency was kept
    sweep.chunk_path(tmp_path, 0).parent.mkdir(parents=True)
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.Table.from_pylist([older]), sweep.chunk_path(tmp_path, 0))
    assert sweep.read_sweep(tmp_path)[0]["latency"] == 0.0


def test_progress_prints_done_total_rate_and_time_left_as_plain_lines_off_a_terminal():
    out = io.StringIO()
    progress = sweep.Progress(10, stream=out, every=0.0)
    progress.advance(4)
    progress.advance(6)
    lines = out.getvalue().splitlines()
    assert len(lines) == 2 and lines[0].startswith("4/10 scenarios, ") and "s left" in lines[0]
    assert lines[1].startswith("10/10 scenarios") and "\r" not in out.getvalue()


def test_a_failing_chunk_is_tried_again_then_reported_never_dropped_silently():
    tries, pending, result = {5: 0}, [], sweep.SweepResult(chunks=6)
    sweep._retry(5, tries, 1, pending, result, "boom")
    assert pending == [5] and not result.failed
    sweep._retry(5, tries, 1, pending, result, "boom")
    assert result.failed == [5]


def test_hrc_sweep_refuses_bad_grids_with_a_message_and_exit_2(tmp_path):
    from tests.util import run_hrc

    grid, late = tmp_path / "g.yaml", tmp_path / "late.yaml"
    cases = [(("--set", "ssm.nope=1"), "nope"), (("--set", "ssm.reaction_time"), "KEY=V1"),
             (("--set", "ssm.reaction_time=0.1", "--strategies", "fastest"), "strategies"),
             (("--set", "ssm.reaction_time=0.1", "--kinds", "moon"), "kinds"),
             (("--set", "ssm.reaction_time=0.1", "--workers", "0"), "--workers"),
             (("--grid", str(grid)), "scenarios: expected a number"),
             (("--against", str(tmp_path / "nowhere")), "no such folder"),
             (("--forecaster", "nope:Nope"), "cannot import 'nope'"),
             (("--against", str(tmp_path)), "no sweep records"),
             (("--latency", "0.9"), "--latency"), (("--grid", str(late)), "latency: from 0 to")]
    grid.write_text("set:\n  ssm.reaction_time: [0.1]\nscenarios: many\n")
    late.write_text("set:\n  ssm.reaction_time: [0.1]\nlatency: 0.9\n")
    for args, says in cases:
        done = run_hrc("sweep", "--out", str(tmp_path / "out"), *args)
        assert done.returncode == 2 and says in done.stderr, (args, done.stderr)
    assert not (tmp_path / "out" / "records").exists()                     # nothing ran


def test_hrc_sweep_sweeps_a_choice_by_its_words(tmp_path):
    """A word-valued key (the planning layer's judge) runs, is printed and written as its word, and plotted."""
    from tests.util import run_hrc

    assert grids.point_label([("planning.judge", "scaling"), ("ssm.reaction_time", 0.1)]) == \
        "planning.judge=scaling, ssm.reaction_time=0.1"
    out = tmp_path / "out"
    done = run_hrc("sweep", "--set", "planning.judge=cost,scaling", "--strategies", "scale_only", "--kinds", "standing",
                   "--scenarios", "1", "--duration", "0.5", "--workers", "1", "--out", str(out))
    assert done.returncode == 0, done.stderr[-2000:]
    assert "planning.judge=cost:" in done.stdout and "planning.judge=scaling:" in done.stdout, done.stdout
    with open(out / "sweep.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["planning.judge"] for r in rows] == ["cost", "scaling"]
    assert (out / "sweep-planning.judge.png").stat().st_size > 0


def kind_records(point: str, shift: float = 0.0) -> list[dict]:
    """Two kinds, three seeds each, scale_only and full: full gains 1 shuttle a scenario standing, loses 0.5 crossing;
    `shift` added to full's standing shuttles in seeds 0 and 2 (another point, or another version of the code)."""
    base = {f: 0 for f in RECORD_FIELDS}
    out = []
    for k in range(6):
        kind = ("standing", "crossing")[k % 2]
        for strategy in ("scale_only", "full"):
            shuttles = 2.0 + (strategy == "full") * (1.0 if kind == "standing" else -0.5)
            if strategy == "full" and kind == "standing" and k < 3:
                shuttles += shift
            out.append(base | {"kind": kind, "seed": k, "duration": 12.0, "strategy": strategy, "overrides": point,
                               "shuttles": shuttles, "sim_s": 12.0, "stopped_fraction": 0.0, "slowed_fraction": 0.0,
                               "min_margin_m_s": float("nan"), "wall_s": 0.1})
    return out


def test_a_point_is_read_kind_by_kind_and_against_the_first_point_scenario_by_scenario():
    """Overall, full gains on these records; per kind it gains standing and loses crossing, which the overall
    figure sums away. The second point against the first: only full's standing scenarios changed, seeds 0 and 2
    better, seed 4 the same."""
    first, second = '{"planning.patience": 1.5}', '{"planning.patience": 0.5}'
    records = kind_records(first) + kind_records(second, shift=0.5)
    (one, two) = per_point(records, 0.4)
    assert one["ratios"]["full/scale_only"].ratio == pytest.approx(13.5 / 12)
    assert set(one["kinds"]) == {"standing", "crossing"} and one["kinds"]["crossing"]["scenarios"] == 3
    assert one["kinds"]["standing"]["ratios"]["full/scale_only"].ratio == pytest.approx(9 / 6)
    crossing = one["kinds"]["crossing"]["ratios"]["full/scale_only"]
    assert crossing.ratio == pytest.approx(4.5 / 6) and (crossing.better, crossing.worse) == (0, 3)
    assert two["kinds"]["standing"]["strategies"]["full"]["shuttles_per_min"] == pytest.approx(60 * 10 / 36, abs=1e-3)
    (against,) = against_first(records)
    assert against["point"] == {"planning.patience": 0.5} and against["of"] == {"planning.patience": 1.5}
    ratios = {(c["strategy"], c["kind"]): c for c in against["compared"]}
    standing = ratios[("full", "standing")]["ratio"]              # seeds 0, 2, 4: 0 and 2 gained 0.5 each, of 9
    assert standing.ratio == pytest.approx(10 / 9) and (standing.better, standing.worse, standing.same) == (2, 0, 1)
    assert ratios[("full", "crossing")]["ratio"].ratio == pytest.approx(1.0)
    # the scenarios to take apart first: where a pair lost most, where a point gained and lost most
    assert one["kinds"]["crossing"]["most_lost"]["full/scale_only"] == [["crossing", k, 1.5, 2.0] for k in (1, 3, 5)]
    assert one["kinds"]["standing"]["most_lost"]["full/scale_only"] == []
    assert ratios[("full", "standing")]["most_gained"] == [["standing", 0, 3.5, 3.0], ["standing", 2, 3.5, 3.0]]
    assert ratios[("full", "standing")]["most_lost"] == [] and ratios[("full", "crossing")]["most_gained"] == []
    assert ratios[("full", "overall")]["scenarios"] == 6 and ratios[("scale_only", "overall")]["ratio"].ratio == 1.0
    assert against_first(kind_records(first)) == []                # one point: nothing to compare
    # printed kind by kind, and each point against the first by the values that differ
    two_keys = lambda patience, shift: kind_records(f'{{"planning.patience": {patience}, "ssm.reaction_time": 0.1}}',
                                                    shift)
    both = two_keys(1.5, 0.0) + two_keys(0.5, 0.5)
    lines = grids.figure_lines(per_point(both, 0.4), ["scale_only", "full"], against_first(both), None)
    assert "  crossing (3): scale_only 10.00/min  full 7.50/min  full/scale_only 0.750 [0.750, 0.750] " \
           "(better in 0, worse in 3, same in 0)" in lines, lines
    assert "planning.patience=0.5 against planning.patience=1.5:" in lines, lines
    assert "    full/scale_only most lost: seed 1 1.50 against 2.00, seed 3 1.50 against 2.00, seed 5 1.50 against " \
           "2.00" in lines and "    most gained: seed 0 3.50 against 3.00, seed 2 3.50 against 3.00" in lines, lines


def test_scenarios_are_compared_only_with_themselves():
    """Another sweep's records pair by kind, seed and duration: a seed the other did not run, or ran for
    another duration, is left out, never paired with a different scenario; the points pair by their values."""
    point = '{"planning.patience": 1.5}'
    mine, theirs = kind_records(point, shift=1.0), kind_records(point)
    theirs = [r for r in theirs if r["seed"] != 0] + [r | {"duration": 6.0} for r in theirs if r["seed"] == 0]
    full = {c["kind"]: c for c in compared(mine, theirs) if c["strategy"] == "full"}
    assert full["standing"]["scenarios"] == 2 and full["standing"]["ratio"].ratio == pytest.approx(7 / 6)
    assert full["overall"]["scenarios"] == 5
    (other,) = against_other(mine, theirs)
    assert other["point"] == {"planning.patience": 1.5} and len(other["compared"]) == 6
    assert against_other(mine, kind_records('{"planning.patience": 3.0}')) == []
    assert compared(mine, []) == []


def test_hrc_sweep_against_another_sweep_and_kind_by_kind(tmp_path):
    """The same sweep twice (the same code): every ratio against the first is 1 with every scenario the same,
    printed kind by kind and written to summary.json and sweep-kinds.csv; without --set, one point as shipped.
    A folder of records that cannot be read is refused before anything runs."""
    import json

    from tests.util import run_hrc

    common = ("--strategies", "scale_only", "--kinds", "standing,crossing", "--scenarios", "2", "--duration", "0.5",
              "--workers", "1")
    assert run_hrc("sweep", *common, "--out", str(tmp_path / "a")).returncode == 0
    done = run_hrc("sweep", *common, "--out", str(tmp_path / "b"), "--against", str(tmp_path / "a"))
    assert done.returncode == 0, done.stderr[-2000:]
    assert "as shipped: scale_only" in done.stdout and "  standing (1): scale_only" in done.stdout, done.stdout
    assert f"as shipped against the same point in {tmp_path / 'a'}:" in done.stdout
    assert "  scale_only overall (2): 1.000 [1.000, 1.000] (better in 0, worse in 0, same in 2)" in done.stdout, \
        done.stdout
    summary = json.loads((tmp_path / "b" / "summary.json").read_text())
    (point,) = summary["against"]["points"]
    assert [(c["kind"], c["ratio"]["same"]) for c in point["compared"]] == [("crossing", 1), ("standing", 1),
                                                                           ("overall", 2)]
    assert set(summary["points"][0]["kinds"]) == {"standing", "crossing"} and summary["against_first"] == []
    with open(tmp_path / "b" / "sweep-kinds.csv") as f:
        assert [(r["kind"], r["strategy"]) for r in csv.DictReader(f)] == [("crossing", "scale_only"),
                                                                           ("standing", "scale_only")]
    # a researcher's forecaster for full, named in the records (a folder of one forecaster: the plan holds it)
    named = run_hrc("sweep", "--strategies", "full", "--kinds", "standing", "--scenarios", "1", "--duration", "0.5",
                    "--workers", "1", "--forecaster", "shared.planning.forecast:DampedVelocity", "--out",
                    str(tmp_path / "f"))
    assert named.returncode == 0 and "(full's forecaster shared.planning.forecast:DampedVelocity)" in named.stdout
    assert {r["forecaster"] for r in sweep.read_records(tmp_path / "f")} == {"shared.planning.forecast:DampedVelocity"}
    broken = tmp_path / "broken"
    (broken / "records").mkdir(parents=True)
    (broken / "records" / "chunk-00000.parquet").write_bytes(b"PAR1 not really")
    done = run_hrc("sweep", *common, "--out", str(tmp_path / "c"), "--against", str(broken))
    assert done.returncode == 2 and "chunk-00000.parquet: cannot read these records" in done.stderr, done.stderr
    assert not (tmp_path / "c" / "records").exists()


def test_a_scenario_taken_apart_holds_and_arrivals():
    """held_spans joins the cycles below alpha_min into spans (a gap under GAP is one span); arrivals are the
    moments the shuttle count rose."""
    from types import SimpleNamespace

    from tools.scenario import arrivals, held_spans

    alphas = [1.0, 0.1, 0.1, 1.0, 0.1, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0]
    records = [SimpleNamespace(t=0.01 * k, step=SimpleNamespace(alpha=a), shuttles=int(k >= 6) + int(k >= 10))
               for k, a in enumerate(alphas)]
    result = SimpleNamespace(records=records)
    assert held_spans(result, 0.2) == [(0.01, pytest.approx(0.05)), (0.11, pytest.approx(0.12))]
    assert arrivals(result) == [0.06, 0.1]


def test_hrc_scenario_tells_what_each_strategy_did_with_the_sweeps_figures(tmp_path):
    """The seed a sweep names, taken apart: each strategy's shuttles as the sweep's record has them, its arrivals
    and holds, every goal's leg named; a bad kind, key or a grid of values is refused (exit 2)."""
    from tests.util import run_hrc

    done = run_hrc("scenario", "standing", "3", "--strategies", "scale_only,full", "--duration", "4")
    assert done.returncode == 0, done.stderr[-2000:]
    record = run_scenario(ScenarioSpec("standing", 3, 4.0, "full"))
    assert f"full: {record['shuttles']:.2f} shuttles ({record['completed']} completed)" in done.stdout, done.stdout
    assert "hrc scenario: standing seed 3, 4 s, as shipped" in done.stdout and "scale_only: " in done.stdout
    # scale_only held beside the person to the end; full gone round them, arrived
    scale_only, full = done.stdout.split("\nfull: ")
    assert "  no arrival" in scale_only and re.search(r"held below alpha_min 0.2: \d+\.\d\d-4\.00 s", scale_only)
    assert re.search(r"  arrivals at \d+\.\d\d s", full) and "  held below alpha_min 0.2: " in full, full
    goals = [line for line in done.stdout.splitlines() if " goal " in line]
    assert goals and all(line.split("taken", 1)[1].strip() in ("the straight line", "the folded leg",
                                                               "left at once, searched on the way",
                                                               "searched from rest", "prepared on the way here")
                         for line in goals), goals
    for args, says in ((("moon", "1"), "kinds"), (("standing", "1", "--set", "ssm.nope=1"), "nope"),
                       (("standing", "1", "--set", "ssm.reaction_time=0.1,0.2"), "one value a key"),
                       (("standing", "1", "--forecaster", "shared.planning.forecast:Nope"), "has no 'Nope'"),
                       (("standing", "1", "--latency", "-0.03"), "--latency")):
        refused = run_hrc("scenario", *args)
        assert refused.returncode == 2 and says in refused.stderr, (args, refused.stderr)
    late = run_hrc("scenario", "standing", "3", "--strategies", "full", "--duration", "4", "--latency", "0.03")
    record = run_scenario(ScenarioSpec("standing", 3, 4.0, "full", latency=0.03))
    assert late.returncode == 0 and "as shipped, the people 30 ms late" in late.stdout, late.stderr[-2000:]
    assert f"full: {record['shuttles']:.2f} shuttles" in late.stdout, late.stdout
