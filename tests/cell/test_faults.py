"""Faults across the real processes: the whole cell under supervisord (hrc up, udp_multicast in a private
namespace), the fault campaign (hrc faults) injecting each fault while the robot shuttles next to a person:
kill -9 of every service, SIGSTOP of the scaler and of the driver, lost CAN frames, a stopped heartbeat, a
silent tracker, NaN poses, a person who jumps, glitches. For each: the robot stops within its stated bound
(or, for faults outside the stopping chain, goes on safely), neither the monitor nor the re-check against
the true person finds a violation, the service is back under the supervisor, and the next shuttle completes.
The judging itself (tools.faultcheck) is tested directly below, without processes."""

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from shared.config import load_config
from shared.core.humans import HumanCapsules
from shared.safety.monitor import SafetyMonitor
from tests.util import ROOT, free_port, require_namespace
from tools.cell import cell_pid, run_dir
from tools.faultcheck import FaultVerdict, moving_at, standstill_after, stop_timeline, truth_violations
from tools.faults import FAULT_NAMES, INJECTIONS, fault_service, inject_again


def hrc(*args, timeout=60):
    return subprocess.run([sys.executable, "-m", "tools.cli", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout, env=dict(os.environ, PYTHONPATH=str(ROOT)))


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    require_namespace("the stop decisions are covered by tests/drives/test_driver_core.py, "
                      "tests/scaling/test_scaling_layer.py and the judging below")
    prefix = f"test/faults{os.getpid()}"
    out = hrc("up", "--prefix", prefix, "--port", str(min(free_port(), 60000)))
    assert out.returncode == 0, out.stderr
    pid = cell_pid(prefix)
    report = tmp_path_factory.mktemp("faults")
    try:
        run = hrc("faults", "--prefix", prefix, "--timeout", "60", "--out", str(report), timeout=900)
        print(run.stdout[-4000:], run.stderr[-2000:])
        verdicts = {v["name"]: v for v in json.loads((report / "faults.json").read_text())} \
            if (report / "faults.json").exists() else {}
        yield verdicts, run
    finally:
        hrc("down", "--prefix", prefix)
        assert cell_pid(prefix) is None
        with pytest.raises(OSError):
            os.kill(pid, 0)
        shutil.rmtree(run_dir(prefix), ignore_errors=True)


@pytest.mark.parametrize("name", FAULT_NAMES)
def test_fault(campaign, name):
    verdicts, run = campaign
    assert name in verdicts, f"the campaign did not judge {name}:\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}"
    v = verdicts[name]
    print(json.dumps(v))
    assert v["moving_at_injection"], v
    if v["expect"] == "stop":
        assert v["stop_s"] is not None and v["stop_s"] <= v["bound_s"], v
    if v["expect"] == "slow":
        assert v["detected_s"] is not None and v["detected_s"] <= v["bound_s"], v
    assert v["monitor_violations"] == 0 and v["truth_violations"] == 0, v
    assert v["back"] and v["resumed_s"] is not None, v
    assert v["ok"]


def test_the_campaign_exits_zero_and_prints_the_table(campaign):
    verdicts, run = campaign
    assert run.returncode == 0, run.stdout[-3000:]
    assert "| fault | expected | bound |" in run.stdout and len(verdicts) == len(FAULT_NAMES)


def test_unknown_fault_and_no_cell_are_clear_errors():
    out = hrc("faults", "--only", "unplug_everything", "--prefix", "test/nocell")
    assert out.returncode == 2 and "unknown fault" in out.stderr and "kill_scaler" in out.stderr
    out = hrc("faults", "--prefix", "test/nocell")
    assert out.returncode == 2 and "no cell test/nocell is up" in out.stderr


# ----------------------------------------------------------------------------------- the judging, pure
def test_standstill_is_the_first_still_sample_after_the_injection():
    times = np.arange(0.0, 1.0, 0.01)
    speeds = np.where(times < 0.42, 1.0, 0.0)
    assert standstill_after(times, speeds, 0.2) == pytest.approx(0.22)
    assert standstill_after(times, np.ones_like(times), 0.2) is None
    assert moving_at(times, speeds, 0.3) and not moving_at(times, speeds, 0.5) and not moving_at(times, speeds, -1)


def test_each_kill_and_freeze_names_the_service_it_acts_on():
    assert fault_service("kill_tracker_ingest") == "tracker_ingest"
    assert fault_service("freeze_robot_driver") == "robot_driver"
    assert fault_service("freeze_scaler_recover") == "scaler" and fault_service("can_drop") is None
    assert all(fault_service(n) is not None for n in FAULT_NAMES if n.startswith(("kill_", "freeze_")))


def test_only_a_fault_that_leaves_nothing_behind_is_injected_again_into_a_robot_that_stood():
    stood, moved = (lambda: False), (lambda: True)
    assert inject_again("human_jump", 0, True, stood) and inject_again("tracker_nan", 0, True, stood)
    assert not inject_again("human_jump", 0, True, moved)                  # it moved: judged as injected
    assert not inject_again("human_jump", INJECTIONS - 1, True, stood)     # the last try is judged as it is
    assert not inject_again("human_jump", 0, False, stood)                 # never seen moving: nothing to wait for
    asked = []
    assert not inject_again("kill_scaler", 0, True, lambda: asked.append(1) or False) and not asked   # no undo


def test_a_late_stop_comes_with_what_the_scaler_did_and_how_fast_the_robot_went():
    times = np.arange(10.0, 11.0, 0.01)
    speeds = np.where(times < 10.5, 1.2, 0.0)
    statuses = [(10.02, "running", "piqp", 7, 1.0), (10.03, "running", "piqp", 7, 0.9),        # no change: one line
                (10.06, "stale_human_data", "none+braking", 7, 0.8), (10.3, "running", "piqp", 8, 0.1),
                (11.5, "running", "piqp", 9, 1.0)]                                           # after `until`
    lines = stop_timeline(10.0, statuses, times, speeds, until=10.6)
    assert lines[:3] == ["t+20ms scaler running piqp v7 alpha 1.00",
                         "t+60ms scaler stale_human_data none+braking v7 alpha 0.80",
                         "t+300ms scaler running piqp v8 alpha 0.10"]
    assert lines[3].startswith("largest joint speed (ms: rad/s) 0:1.20 50:1.20")
    assert lines[3].endswith("450:1.20 500:0.00 550:0.00 600:0.00")
    assert len(lines) == 4


def test_truth_check_finds_a_robot_that_does_not_slow_for_the_true_person(robot):
    monitor = SafetyMonitor(robot, load_config(None).ssm)
    q = np.array([0.0, -0.4, 1.17, 0.0, 1.57, 0.0])
    flange = robot.capsule_segments(q)[-1][1]
    person = HumanCapsules(np.array([[flange + [0.25, 0, 0], flange + [0.25, 0, 0.3]]]), np.array([0.1]),
                           np.zeros((1, 2, 3)), np.array([True]))
    fast = np.array([0.0, 1.2, -1.2, 0.0, 0.0, 0.0])
    times = np.arange(0.0, 0.8, 0.01)
    samples_fast = [(t, q, fast) for t in times]
    samples_still = [(t, q, np.zeros(6)) for t in times]
    assert truth_violations(monitor, samples_fast, lambda t: person)
    assert truth_violations(monitor, samples_still, lambda t: person) == []
    far = HumanCapsules(person.segments + [3.0, 0, 0], person.radii, person.velocities, person.velocity_known)
    assert truth_violations(monitor, samples_fast, lambda t: far) == []


def test_a_verdict_is_ok_only_when_every_part_holds():
    good = FaultVerdict("kill_scaler", "stop", 0.32, "", moving_at_injection=True, stop_s=0.1, back=True,
                        resumed_s=3.0)
    assert good.ok and good.as_dict()["ok"]
    for change in ({"stop_s": 0.4}, {"stop_s": None}, {"back": False}, {"resumed_s": None},
                   {"truth_violations": 1}, {"monitor_violations": 2}, {"moving_at_injection": False}):
        assert not FaultVerdict(**{**good.__dict__, **change}).ok, change
    assert FaultVerdict("kill_planner", "any", None, "", moving_at_injection=True, back=True, resumed_s=5.0).ok
