"""bench/real_people.py: every recording through hrc demo --human, as a table. Its command line, its errors, and
one short recording in the simulation end to end (the figures themselves are the benchmark's, not asserted)."""

import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from tests.util import load_bench

FIXTURE = Path(__file__).resolve().parents[1] / "data" / "human-assembly"


def test_bad_arguments_are_refused_with_the_reason(capsys, tmp_path):
    bench = load_bench("real_people")
    with pytest.raises(SystemExit) as exit_:
        bench.main(["--placements", "on_the_table"])
    assert exit_.value.code == 2 and "unknown placement 'on_the_table'" in capsys.readouterr().err
    for bad in ("-0.1:north", "x:30", "-0.1:nan"):
        with pytest.raises(SystemExit) as exit_:
            bench.main([f"--placements=table_edge,{bad}"])
        assert exit_.value.code == 2 and f"unknown placement '{bad}'" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        bench.main(["--recordings", str(tmp_path)])
    assert exit_.value.code == 2 and "no recordings" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        bench.main(["--every", "0"])
    assert exit_.value.code == 2 and "--every: expected a whole number >= 1" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        bench.main(["--recordings", str(FIXTURE), "--only", "nobody"])
    assert exit_.value.code == 2 and "named ['nobody']" in capsys.readouterr().err
    for bad, said in ((["--latency", "0.9"], "stale"), (["--latency", "-0.05", "--sim"], "expected 0 to 0.5 s")):
        with pytest.raises(SystemExit) as exit_:
            bench.main(bad)
        assert exit_.value.code == 2 and said in capsys.readouterr().err


def test_a_recording_goes_through_the_simulation_and_its_row_comes_from_the_runs_summary(capsys, tmp_path):
    bench = load_bench("real_people")
    assert bench.main(["--sim", "--recordings", str(FIXTURE), "--placements", "step_back", "--out", str(tmp_path)]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    (row,) = result["rows"]
    summary = json.loads((tmp_path / "task1_human1_trial1_first300-step_back" / "summary.json").read_text())
    assert row["shuttles_per_min"] == summary["shuttles_per_min"] > 0.0
    assert row["violations"] == [summary["violations"], None, None] and row["error"] is None
    assert result["means"]["step_back"]["shuttles_per_min"] == summary["shuttles_per_min"]
    # the last leg's part counted, from the same summary: at least the whole shuttles' rate, less than one more
    whole = summary["shuttles_completed"]
    assert row["progress_per_min"] == result["means"]["step_back"]["progress_per_min"] \
        == round(60.0 * summary["shuttle_progress"] / summary["duration_s"], 2)
    assert whole <= summary["shuttle_progress"] < whole + 1
    assert result["means"]["step_back"]["violations"] == [summary["violations"], None, None]
    motion = json.loads((tmp_path / "task1_human1_trial1_first300-step_back.json").read_text())
    assert motion                                   # the product's own reader wrote the placed motion


def test_a_placement_anywhere_is_the_one_the_simulation_kinds_use(capsys, tmp_path):
    """X:YAW places the file where ``evidence.recorded.Placement`` does (the real_around kind's people), so a
    scenario found in a sweep runs on the processes as it ran in the simulation."""
    from evidence.recorded import Placement, placed_motion
    from shared.tracking.motion import RecordedMotion

    bench = load_bench("real_people")
    assert bench.main(["--sim", "--recordings", str(FIXTURE), "--placements=-0.3:40", "--out", str(tmp_path)]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert result["rows"][0]["placement"] == "-0.3:40" and result["rows"][0]["error"] is None
    written = RecordedMotion.load(tmp_path / "task1_human1_trial1_first300--0.3_40.json")
    placed = placed_motion(FIXTURE / "task1_human1_trial1_first300.txt", Placement(-0.3, math.radians(40.0)))
    for t in (0.0, 3.3):
        assert np.allclose(written.at(t).segments, placed.at(t).segments, atol=2e-5)


def test_every_other_frame_is_a_15_hz_camera_of_the_same_person(tmp_path):
    """--every 2: the product's reader keeps every second frame, each at its own time (hrc human from-keypoints
    --every), into a file of its own beside the full-rate one."""
    from shared.tracking.motion import RecordedMotion

    bench = load_bench("real_people")
    recording = FIXTURE / "task1_human1_trial1_first300.txt"
    full, half = bench.convert(recording, "step_back", tmp_path), bench.convert(recording, "step_back", tmp_path, 2)
    assert half.name == "task1_human1_trial1_first300-step_back-every2.json" and full != half
    a, b = RecordedMotion.load(full), RecordedMotion.load(half)
    assert len(b.frames) == 150 and b.rate == pytest.approx(15.0) and b.duration == pytest.approx(298 / 30)
    assert np.allclose(b.frames[5].segments, a.frames[10].segments)


def test_a_run_without_a_summary_is_a_row_with_its_error_and_the_table_goes_on():
    bench = load_bench("real_people")
    row = bench.row("r", "step_back", {"error": "exit 2: bad file"})
    assert row["error"] == "exit 2: bad file" and row["shuttles_per_min"] is None
    means = bench.means([row, bench.row("s", "step_back", {"shuttles_per_min": 10.0, "violations": 0})])
    assert means["step_back"]["runs"] == 1 and means["step_back"]["failed"] == 1
    assert means["step_back"]["shuttles_per_min"] == 10.0 and means["step_back"]["violations"] == [0, None, None]
    assert row["progress_per_min"] is None and means["step_back"]["progress_per_min"] is None    # none measured
    assert means["step_back"]["speedups"] == [None, None, None]                                  # nor these


def test_the_speed_ups_are_summed_per_placement_by_each_count():
    """The judge's speed-ups (all, towards an unknown velocity, of those a command's) summed over a placement's runs;
    a count no run measured stays None (unchecked), never 0."""
    bench = load_bench("real_people")
    check = {"monitor_check": {"independent": {"speedups": 3, "speedups_unknown": 3, "speedups_unknown_commanded": 0}}}
    older = {"monitor_check": {"independent": {"speedups": 2, "speedups_unknown": 1}}}        # before the commands
    rows = [bench.row("a", "table_edge", {"shuttles_per_min": 8.0, **check}),
            bench.row("b", "table_edge", {"shuttles_per_min": 9.0, **older})]
    assert rows[0]["speedups"] == [3, 3, 0] and rows[1]["speedups"] == [2, 1, None]
    assert bench.means(rows)["table_edge"]["speedups"] == [5, 4, 0]
    assert bench.means(rows[1:])["table_edge"]["speedups"] == [2, 1, None]


def test_a_row_says_the_machines_stalls_and_the_events_after_them():
    bench = load_bench("real_people")
    summary = {"shuttles_per_min": 12.0, "events": ["robot_driver:frames_lost", "safety_monitor:monitor_behind"],
               "machine": {"stalls": 2, "late_ms_max": 100.2, "after_stall": ["robot_driver:frames_lost"]}}
    row = bench.row("r", "step_back", summary)
    assert row["machine"] == [2, 100.2] and row["after_stall"] == ["robot_driver:frames_lost"]
    assert bench.row("r", "step_back", {"shuttles_per_min": 1.0})["machine"] == [None, None]   # --sim: no witness


def test_a_row_says_the_scalers_silences():
    bench = load_bench("real_people")
    summary = {"shuttles_per_min": 12.0, "scaler_silences": {"count": 2, "longest": [[3.447, 41.4, 0.25, 3, 23.3],
                                                                                    [9.1, 26.0, 0.2, 0, 26.0]]}}
    assert bench.row("r", "table_edge", summary)["scaler_silences"] == [2, 41.4, 3]
    quiet = {"shuttles_per_min": 12.0, "scaler_silences": {"count": 0, "longest": []}}
    assert bench.row("r", "table_edge", quiet)["scaler_silences"] == [0, None, None]
    assert bench.row("r", "table_edge", {"shuttles_per_min": 1.0})["scaler_silences"] == [None, None, None]  # --sim


def test_a_stale_command_says_how_many_commands_were_sent_meanwhile():
    bench = load_bench("real_people")
    summary = {"shuttles_per_min": 5.0, "events": ["robot_driver:stale_command"],
               "scaler_silences": {"count": 0, "longest": [], "stale_stops": [[9.855, 56.0, 3, 39.8]]},
               "machine": {"stalls": 0, "late_ms_max": 9.0, "after_stall": []}}
    row = bench.row("r", "table_edge", summary)
    assert row["stale_stops"] == [[9.855, 56.0, 3, 39.8]]
    assert bench.event_cell(row) == "robot_driver:stale_command (3 commands sent meanwhile)"
    summary["machine"]["after_stall"] = ["robot_driver:stale_command"]
    summary["scaler_silences"]["stale_stops"] = [[9.855, 56.0, 0, None]]
    assert bench.event_cell(bench.row("r", "table_edge", summary)) == \
        "robot_driver:stale_command (machine, 0 commands sent meanwhile)"
    assert bench.event_cell(bench.row("r", "table_edge", {"shuttles_per_min": 1.0})) == "-"


def test_a_latency_goes_to_the_demo_of_each_run(monkeypatch, tmp_path):
    bench = load_bench("real_people")
    calls = []
    monkeypatch.setattr(bench.subprocess, "run", lambda cmd, **_: calls.append(cmd) or SimpleNamespace(
        returncode=1, stderr="no cell here", stdout=""))
    said = bench.run(tmp_path / "motion.json", tmp_path / "report", False, False, None, 0.08)
    assert said == {"error": "exit 1: no cell here"}
    assert calls[0][calls[0].index("--latency") + 1] == "0.08" and "--sim" not in calls[0]
    bench.run(tmp_path / "motion.json", tmp_path / "report", False, False)
    assert "--latency" not in calls[1]
    bench.run(tmp_path / "motion.json", tmp_path / "report", True, False, None, 0.03)       # the simulation's too
    assert calls[2][calls[2].index("--latency") + 1] == "0.03" and "--sim" in calls[2]
