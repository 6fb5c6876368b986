"""`hrc demo` on the real processes (emulator on udp_multicast in a private namespace, five services over
Zenoh), the paper's 24 s: it ends with zero violations counted by the monitor, the planner goes round the
arm in the path and, after the replan request, past the person very close, and its report folder holds what
docs/report-format.md promises."""

import csv
import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

from evidence.scenarios import Q_GOAL, Q_START
from shared.config import CellConfig
from tests.util import ROOT, require_namespace


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    require_namespace("the same experiment runs in-process in tests/tools/test_cli_and_demo.py")
    out = tmp_path_factory.mktemp("demo")
    # the paper's experiment as the paper had it (its formula: the measured human speed held); the shipped
    # human model's cost on it is measured in docs/real-people.md, not asserted here
    run = subprocess.run([sys.executable, "-m", "tools.cli", "demo", "--paper-formula", "--out", str(out)], cwd=ROOT,
                         capture_output=True, text=True, timeout=300,
                         env=dict(os.environ, PYTHONPATH=str(ROOT)))
    print(run.stdout[-3000:], run.stderr[-3000:])
    return run, out


def test_runs_to_the_end_with_zero_violations(report):
    run, out = report
    assert run.returncode == 0, run.stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["violations"] == 0, summary["violation_events"]
    assert summary["mode"] == "processes" and all(summary["services_alive_at_end"].values())
    feed = summary["human_feed"]                   # the person came from a process of its own, at 120 Hz
    assert feed["rate_hz"] == 120.0 and feed["sent"] > 2000 and summary["exit_codes"]["human_feed"] == 0, feed
    # standing at the start, the person was shown to the tracker before it (the feed's lead-in): tracked from
    # before 0 s, so the first goal is planned for a person of known velocity, as the simulation plans it
    with (out / "events.csv").open() as f:
        tracked = [float(e["t"]) for e in csv.DictReader(f) if e["event"] == "tracker_ok"]
    assert tracked and tracked[0] < 0.0, tracked
    machine = summary["machine"]                   # the machine's own stalls, witnessed at FIFO 99 beside the cell
    assert machine["wakeups"] > 3000 and summary["exit_codes"]["stall_witness"] == 0, machine
    assert set(machine["after_stall"]) <= set(summary["events"]) and machine["stalls"] >= len(machine["longest"])
    assert summary["cycles_completed"] > 2000 and abs(summary["mean_cycle_s"] - 0.01) < 0.002
    assert summary["shuttles_completed"] >= 5                                # goal after goal reached
    # the part of the last leg counts as the simulation counts it: at least the goals reached, less than one more
    assert summary["shuttles_completed"] <= summary["shuttle_progress"] < summary["shuttles_completed"] + 1
    assert summary["min_margin_m"] is not None and summary["min_separation_m"] > 0.05
    assert summary["latency"]["chains"] > 300 and summary["latency"]["sample_to_frame_ms"]["p99"] > 0
    cycle = summary["scaling_cycle"]                     # the scaler's own compute, every cycle accounted for
    assert cycle["cycles"] > 1000 and sum(cycle["methods"].values()) == cycle["cycles"]
    assert cycle["compute_us"]["p50"] > 0 and cycle["methods"].get("presolved", 0) > 0
    # the printed last line counts the replans taken and refused apart (one count of both read as taken)
    printed = json.loads(run.stdout.strip().splitlines()[-2])
    taken = sum(e["ok"] for e in summary["replans"])
    assert (printed["replans_accepted"], printed["replans_refused"]) == (taken, len(summary["replans"]) - taken)
    # and the replans' compute median and p95 (from the planner's events), as the issue measures them
    computes = [e["compute_ms"] for e in summary["replans"]]
    assert printed["replan_compute_ms"] == summary["replan_compute_ms"]
    assert summary["replan_compute_ms"]["p50"] == (round(float(np.percentile(computes, 50)), 3) if computes else None)
    # the shuttle names the way back with each goal, so the planner prepares the next leg on the way: with the
    # person standing (phases 3 and 4) a goal comes prepared and is published without a search
    goals = summary["goal_plans"]
    assert goals["count"] >= summary["shuttles_completed"] and 1 <= goals["prepared"] <= goals["count"], goals
    assert printed["goal_plans"] == goals
    # every refusal says why, with the old and the new trajectory's predicted times (or the planning error,
    # or the blocked goal)
    for entry in summary["replans"]:
        assert entry["reason"] in ("horizon", "beta", "slow", "search") and entry["compute_ms"] is not None
        assert entry["ok"] or re.search(r"predicted \d+\.\d\d s, not (\d+ % )?faster than the old \d+\.\d\d s",
                                        entry["detail"]) \
            or "Error" in entry["detail"] or "merge" in entry["detail"] \
            or "not searched: the goal is blocked while the person stays: there" in entry["detail"], entry
    # the paper's story. Phase 3 (the arm in the path from 13.8 s): the planner goes round it and the robot
    # completes a shuttle while the arm stays. Phase 4 (the person closer from 19.2 s until 22.8 s): the robot
    # is not held beside them until they leave: after the scaling layer's replan request a new plan takes it
    # on, or (when its path gets through before a faster one is found) it reaches its goal. That the replan
    # takes it to the goal before the person leaves is asserted on the simulated clock
    # (tests/tools/test_cli_and_demo.py): on the processes the moment of the replan varies with load.
    with (out / "trace.csv").open() as f:
        rows = [r for r in csv.DictReader(f) if r["q_meas_1"]]
    arrivals, was_there = [], True
    for r in rows:
        there = min(max(abs(float(r[f"q_meas_{k + 1}"]) - end[k]) for k in range(6)) for end in (Q_START, Q_GOAL)) < 0.02
        if there and not was_there:
            arrivals.append(float(r["t"]))
        was_there = there
    taken = [e for e in summary["replans"] if e["ok"]]
    phase3 = [e["t"] for e in taken if 13.8 <= e["t"] < 18.0]
    if phase3:      # held beside the arm: a replan takes the robot round it, and it arrives while the arm stays
        assert any(phase3[0] < t < 18.0 for t in arrivals), (summary["replans"], arrivals)
    else:           # or the leg the robot follows as the arm comes in already goes round it (the goal's own plan,
        # or its search merged on the way): it arrives while the arm stays, on a trajectory that leaves the straight
        # shuttle, and is never held there for longer than a replan request's cooldown with no request answered
        # (that would be a stall the paper does not have). A request answered by a refusal says the way found
        # is not faster than the one followed by what a replan must save (both predicted times, asserted above):
        # in 5 of 12 runs on 2026-12-05 the robot crawled past the arm at alpha 0.16-0.2 for 0.56 s after one,
        # and arrived as early as in the runs that took the replan (16.10 s against 16.11 s)
        assert any(13.8 <= t < 18.0 for t in arrivals), (summary["replans"], arrivals)
        followed = next(int(r["trajectory_version"]) for r in rows if float(r["t"]) >= 13.8)
        leg = [tr for tr in json.loads((out / "trajectories.json").read_text()) if tr["version"] == followed]
        assert leg and leg[-1]["reason"] in ("goal", "search") and off_the_line(leg[-1]["positions"]) > 0.1, \
            (followed, [(tr["t"], tr["reason"]) for tr in leg])
        alpha_min = CellConfig().scaling.alpha_min
        held = sum(1 for r in rows if 13.8 <= float(r["t"]) < 18.0 and float(r["alpha"]) < alpha_min)
        answered = [e for e in summary["replans"] if e["reason"] == "beta" and 13.8 <= e["t"] < 18.0]
        assert held <= 50 or answered, (summary["replans"], arrivals, held)      # 0.5 s at 100 Hz
    phase4 = [e for e in taken if 18.0 <= e["t"] < 22.8 and e["reason"] in ("beta", "slow")]   # (or the planner's
    # own request, for the path ahead predicted slow: before the scaling layer had to ask)
    # The answer is the first of them the scaler followed: a merge it refused (its junction passed while it was
    # planned: version 11 at 19.4 s, 141 ms, on 2026-12-08, idle) took the robot nowhere, and the next replan
    # (version 12, from rest, at 20.55 s at alpha 1.0) took it on
    followed_versions = {int(r["trajectory_version"]) for r in rows}
    answers = [(e, int(re.search(r"version (\d+)", e["detail"]).group(1))) for e in phase4]
    answers = [(e, version) for e, version in answers if version in followed_versions]
    moved_on = False
    if answers:
        (first, version) = answers[0]
        moved_on = sum(1 for r in rows if first["t"] < float(r["t"]) < 22.8 and int(r["trajectory_version"]) == version
                       and float(r["alpha"]) >= 0.5) >= 20              # 0.2 s at 100 Hz
    assert moved_on or any(19.2 < t < 22.8 for t in arrivals), (summary["replans"], arrivals)
    assert "t=" in run.stdout and "alpha=" in run.stdout                     # progress while it ran


def test_report_folder_holds_the_trace_and_the_figures(report):
    _, out = report
    summary = json.loads((out / "summary.json").read_text())
    for name in ("joints.png", "human.png", "scaling.png", "ssm.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with (out / "trace.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == summary["cycles_completed"]
    assert {"t", "alpha", "beta", "trajectory_version", "q_cmd_1", "q_meas_6", "qd_meas_1", "phase"} <= rows[0].keys()
    times = [float(r["t"]) for r in rows]
    assert times == sorted(times)
    with (out / "humans.csv").open() as f:
        humans = list(csv.DictReader(f))
    assert humans and {"t", "capsule", "ax", "radius", "vbz", "valid"} <= humans[0].keys()
    trajectories = json.loads((out / "trajectories.json").read_text())
    assert trajectories and all(len(t["times"]) == len(t["positions"]) for t in trajectories)
    # the 3D recording of the run: robot, people, the closest pair, alpha, the planner's paths
    from rerun.chunk import RrdReader
    assert summary["recording"] == "recording.rrd"
    rows: dict[str, int] = {}
    for chunk in RrdReader(out / "recording.rrd").stream():
        rows[chunk.entity_path] = rows.get(chunk.entity_path, 0) + chunk.num_rows
    assert rows["/world/robot/measured"] > 2000 and rows["/world/humans"] > 1000, rows
    assert rows["/scaling/alpha"] == summary["cycles_completed"] and rows["/world/planner/current"] >= 5, rows
    # every service's log ends clean: what a service built is freed at its exit (the heap frozen for the run's
    # collections left the planner's OMPL objects to outlive the interpreter, and OMPL's bindings listed them as
    # leaked, a hundred lines a run), and no error at a clean stop (the driver published a drive's late answer
    # into its closed session: canopen's 'ERROR session closed' in most robot_driver.logs)
    for log in (out / "logs").glob("*.log"):
        text = log.read_text()
        assert "leaked" not in text and " ERROR " not in text, (log.name, text[-2000:])


def off_the_line(positions) -> float:
    """How far (rad, largest joint) a trajectory's knots leave the straight joint-space line between its ends."""
    p = np.asarray(positions, dtype=float)
    line = p[-1] - p[0]
    u = np.clip((p - p[0]) @ line / max(float(line @ line), 1e-12), 0.0, 1.0)
    return float(np.abs(p - p[0] - u[:, None] * line).max())
