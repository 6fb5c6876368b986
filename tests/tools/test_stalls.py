"""The machine's stall witness (tools.stalls): how late it woke, its stalls with the CPU they ended on, and which
of the cell's warnings came during or just after one, so that a report tells the machine's hiccups from the
cell's own."""

import json
import os
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from tests.util import ROOT, stopped
from tools.stalls import AFTER_STALL, READY, StallLog, in_run, said, steal_seconds, steal_ticks, witness


def test_a_stall_is_a_wake_up_later_than_the_threshold_and_the_longest_are_kept():
    log = StallLog(threshold=0.02, kept=2)
    assert not log.add(1.0, 1.0003)
    assert log.add(2.0, 2.1, cpu=1, steal_ms=100.0) and log.add(3.0, 3.03, cpu=0) and log.add(4.0, 4.05, cpu=0)
    figures = log.figures(t0=1.0)
    assert figures["wakeups"] == 4 and figures["stalls"] == 3
    assert figures["longest"] == [[1.0, 100.0, 1, 100.0], [3.0, 50.0, 0, -1.0]]   # the two longest, in time order
    assert figures["late_ms_max"] == pytest.approx(100.0) and figures["threshold_ms"] == 20.0
    assert StallLog().threshold == pytest.approx(0.01)      # one SYNC period: long enough to cost a drive answer
    assert StallLog().figures()["late_ms_p99"] is None


def test_the_logs_of_the_witnesses_on_each_cpu_are_merged_into_one():
    on_cpu0, on_cpu1 = StallLog(threshold=0.02, kept=2), StallLog(threshold=0.02, kept=2)
    on_cpu0.add(1.0, 1.0001)
    on_cpu0.add(2.0, 2.03, cpu=0)
    on_cpu1.add(1.5, 1.5002)
    on_cpu1.add(3.0, 3.08, cpu=1, steal_ms=70.0)          # only CPU 1 was taken away: only its witness saw it
    on_cpu0.absorb(on_cpu1)
    figures = on_cpu0.figures()
    assert figures["wakeups"] == 4 and figures["stalls"] == 2
    assert figures["late_ms_max"] == pytest.approx(80.0)
    assert figures["longest"] == [[2.0, pytest.approx(30.0), 0, -1.0], [3.0, pytest.approx(80.0), 1, 70.0]]


def test_the_cells_warnings_during_or_just_after_a_stall_are_named():
    figures = {"started": 100.5, "longest": [[110.0, 100.0, 1, 90.0]], "stalls": 1}
    event = lambda t, source, name, severity="warning": SimpleNamespace(stamp=t, source=source, event=name,
                                                                       severity=severity)
    events = [event(110.05, "robot_driver", "frames_lost", "stop"),            # during the stall
              event(110.1 + AFTER_STALL - 0.01, "robot_driver", "command_clamped"),   # just after it
              event(110.1 + AFTER_STALL + 0.1, "safety_monitor", "monitor_behind"),   # too late to be its
              event(110.02, "planner", "trajectory_goal", "info"),                  # not a warning
              event(105.0, "scaler", "stale_command")]                              # before it
    run = in_run(figures, 100.0, events)
    assert run["longest"] == [[10.0, 100.0, 1, 90.0]] and run["started"] == 0.5
    assert run["after_stall"] == ["robot_driver:command_clamped", "robot_driver:frames_lost"]
    assert in_run({"longest": []}, 100.0, events)["after_stall"] == []


def test_the_witness_wakes_on_its_grid_and_makes_up_no_missed_deadline():
    log = StallLog(threshold=0.05)
    start = time.monotonic() - 0.2                     # 200 ms of deadlines already gone: one late wake-up, no burst
    witness(log, 0.005, lambda: True, start=start, until=start + 0.3)
    # 61 deadlines in all, 40 of them gone: the first wake-up is the 200 ms stall, then at most the 20 left (fewer
    # on a loaded machine, which skips what it misses), never the 40 made up in a burst
    first = min(log.longest)
    assert first[1] >= 0.19 and 5 <= log.late.total <= 21, log.figures()
    assert steal_seconds(steal_ticks(), steal_ticks()).keys() == steal_ticks().keys()


def test_the_witness_process_writes_its_figures_when_ended(tmp_path):
    stats = tmp_path / "witness.json"
    proc = subprocess.Popen([sys.executable, "-m", "tools.stalls", "--stats", str(stats), "--period", "0.002"],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    with stopped(proc):
        said = proc.stdout.readline()
        assert said.startswith(READY) and ("SCHED_FIFO 99" in said or "normal class" in said), said
        time.sleep(0.5)
        proc.terminate()                                  # by its PID
        assert proc.wait(10) == 0, proc.stderr.read()
    figures = json.loads(stats.read_text())
    assert figures["wakeups"] > 100 and figures["scheduling"] in said and figures["period_ms"] == 2.0
    # one witness pinned to each CPU this process may use: a hypervisor that stops one CPU is seen there
    cpus = sorted(os.sched_getaffinity(0))
    assert sorted(figures["per_cpu"], key=int) == [str(cpu) for cpu in cpus] and "unwitnessed_cpus" not in figures
    assert f"one witness on each of CPUs {','.join(map(str, cpus))}" in said
    assert set(figures["steal_s"]) == set(steal_ticks())
    bad = subprocess.run([sys.executable, "-m", "tools.stalls", "--stats", str(stats), "--period", "0"], cwd=ROOT,
                         capture_output=True, text=True, timeout=30)
    assert bad.returncode == 2 and "positive" in bad.stderr and "Traceback" not in bad.stderr


def test_the_operator_is_told_of_the_machines_stalls_and_what_followed_them():
    assert said({"stalls": 0, "longest": []}) is None and said({"error": "no figures"}) is None
    line = said({"stalls": 2, "threshold_ms": 20.0, "longest": [[3.0, 24.0, 0, 0.0], [10.0, 101.0, 1, 90.0]],
                 "after_stall": ["robot_driver:frames_lost"]})
    assert line.startswith("the machine itself stalled 2 time(s) beyond 20 ms (the longest 101 ms at t=10.00 s, 90 ms")
    assert line.endswith("during or just after them: robot_driver:frames_lost")
    assert "no warning of the cell" in said({"stalls": 1, "longest": [[1.0, 30.0, 0, -1.0]], "after_stall": []})


def running(pid: int) -> bool:
    """Whether process `pid` exists and is not a zombie (its state, after the name, in /proc/PID/stat)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


def test_the_witnesses_on_each_cpu_end_with_their_parent_even_when_it_is_killed(tmp_path):
    proc = subprocess.Popen([sys.executable, "-m", "tools.stalls", "--stats", str(tmp_path / "w.json"), "--period",
                             "0.002"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    with stopped(proc):
        assert proc.stdout.readline().startswith(READY)
        children = [int(pid) for pid in Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()]
        assert len(children) == len(os.sched_getaffinity(0)) and all(map(running, children))
        proc.kill()                                       # no SIGTERM, no stop event: only the parent's absence
        proc.wait(10)
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline and any(map(running, children)):
        time.sleep(0.05)
    assert not any(map(running, children)), "a witness in SCHED_FIFO 99 outlived its parent"
