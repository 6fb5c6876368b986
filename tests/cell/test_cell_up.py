"""The whole cell under supervisord, as a user runs it: hrc up (udp_multicast in a private namespace),
hrc status, hrc human inject, hrc goal, a service killed and restarted by the supervisor, a goal sent to the
stopped robot and reached once `hrc recover` has it running, hrc down."""

import os
import re
import shutil
import signal
import subprocess
import sys
import time
import warnings

import pytest

from tests.util import ROOT, free_port, require_namespace
from tools.cell import cell_pid, conf_path, run_dir


def hrc(*args, timeout=60):
    return subprocess.run([sys.executable, "-m", "tools.cli", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout, env=dict(os.environ, PYTHONPATH=str(ROOT)))


def status(prefix):
    return hrc("status", "--prefix", prefix, "--timeout", "3").stdout      # the monitor reports once a second


def wait_status(prefix, pattern, timeout):
    deadline = time.monotonic() + timeout
    text = ""
    while time.monotonic() < deadline:
        text = status(prefix)
        if re.search(pattern, text, re.S):
            return text
        time.sleep(0.5)
    raise AssertionError(f"status never matched {pattern!r}:\n{text}\n{log_tails(prefix)}")


def log_tails(prefix, lines=15):
    """The last lines of every log in the cell's run folder (supervisord's and each program's): the fixture
    removes the folder after the test, and a status that never came says nothing of why by itself."""
    tails = []
    for log in sorted(run_dir(prefix).glob("*.log")):
        try:
            tails.append(f"--- {log.name}:\n" + "".join(log.read_text(errors="replace").splitlines(True)[-lines:]))
        except OSError as exc:
            tails.append(f"--- {log.name}: {exc}")
    return "\n".join(tails)


REACHED_Q_G = r"q = \[-1\.5[67]"            # the status's robot line at q_g = [-1.57, ...]
REACHED_Q_S = r"q = \[1\.5[67]"             # and at q_s = [1.57, ...]
ROBOT_RUNS = r"robot:\s+running"
TIMING_STOP = re.compile(r"stopped:\s+(no command for \d+ ms|.*EMCY 0x8100|.*frames are being lost)")
RECOVERIES = 3                              # in one session, at most


def recover_a_timing_stop(prefix, text):
    """Do what the status tells a user when the robot stopped for the machine's timing: `hrc recover`, then wait
    until it runs; True if it did, False if `text` (a status) shows the robot not stopped.

    The driver stops the drives when no command came for 55 ms (standing still too) or when the drives' answers to
    10 SYNCs of 100 were late, and the drives stop themselves when no SYNC came within their watchdog (EMCY 0x8100).
    On this kind of machine a CPU is now and then taken away for 100 ms (the FIFO 99 stall witness sees 97-101 ms
    with as much steal when the machine is busy; the scaler's log "no tick for 109 ms", the tracker's sample late at
    the same time, the driver on the other CPU on time). CI once: 120 ms, 60 s into a fresh machine's start, before
    the first goal; here, with a CPU-bound process beside the cell, 3 sessions of 8 stopped once, at the start or in
    the motion, and a later one three times. The stop is the cell doing its job; the session goes on as a user's
    would, and the planner plans the goal again once the robot runs. `hrc demo` recovers a start-up stop the same
    way (``Shuttle.enable``). Any other cause fails the test, and each recovery is a warning in the test summary,
    so a cell that stops every time is seen (a session allows RECOVERIES)."""
    if not re.search(r"robot:\s+stopped", text):
        return False
    assert TIMING_STOP.search(text), f"stopped for another cause than the machine's timing:\n{text}"
    warnings.warn(f"the robot stopped on the machine's timing; `hrc recover` as its status says:\n{text}",
                  stacklevel=2)
    out = hrc("recover", "--prefix", prefix)
    assert out.returncode == 0, out.stderr
    wait_status(prefix, ROBOT_RUNS, timeout=30)
    return True


def reach(prefix, reached, recoveries, timeout=20):
    """Wait until the status matches `reached`, recovering a stop for the machine's timing on the way (the planner
    plans the goal again once the robot runs); the recoveries of the session so far, counted on."""
    while True:
        text = wait_status(prefix, rf"{reached}|robot:\s+stopped", timeout=timeout)
        if re.search(reached, text):
            return recoveries
        assert recoveries < RECOVERIES, f"stopped {recoveries + 1} times in one session:\n{text}"
        recoveries += recover_a_timing_stop(prefix, text)


@pytest.fixture
def cell():
    require_namespace("the services are covered one by one in tests/cell/test_system.py")
    prefix = f"test/up{os.getpid()}"
    out = hrc("up", "--prefix", prefix, "--port", str(min(free_port(), 60000)))     # six ports from there
    assert out.returncode == 0, out.stderr
    pid = cell_pid(prefix)
    yield prefix
    hrc("down", "--prefix", prefix)
    assert cell_pid(prefix) is None
    with pytest.raises(OSError):
        os.kill(pid, 0)                       # supervisord is gone, and with it every service
    shutil.rmtree(run_dir(prefix), ignore_errors=True)


def test_a_user_session(cell):
    prefix = cell
    # on a fresh machine every service compiles its kernels into numba's empty cache at its first start, six
    # processes on two cores: the whole cell was up after 51.5 s on a cold cache here (a few s on a warm one)
    wait_status(prefix, r"tracker_ingest up.*planner up.*scaler up.*robot_driver up.*safety_monitor up"
                r".*robot:\s+(running|stopped)", timeout=120)
    recoveries = reach(prefix, ROBOT_RUNS, 0)
    person = subprocess.Popen([sys.executable, "-m", "tools.cli", "human", "inject", "-2.5", "0", "0.9", "-2.5", "0",
                               "1.45", "--radius", "0.17", "--velocity", "0", "0", "0", "--duration", "90",
                               "--prefix", prefix], cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        out = hrc("goal", "q_g", "--prefix", prefix)
        assert out.returncode == 0, out.stderr
        recoveries = reach(prefix, REACHED_Q_G, recoveries)
        recoveries = reach(prefix, ROBOT_RUNS, recoveries)      # stopped at the goal: running again before the kill
        # kill -9 the scaler: the driver stops the drives (stale commands), supervisord restarts it
        env = dict(os.environ, HRC_RUN=str(run_dir(prefix)), HRC_PYTHON=sys.executable, HRC_CAN="udp_multicast",
                   HRC_PREFIX=prefix, **{f"HRC_PORT{k if k else ''}": "0" for k in range(6)})
        ctl = [sys.executable, "-c", "from supervisor.supervisorctl import main; main()", "-c", str(conf_path(prefix))]
        pid = int(subprocess.run(ctl + ["pid", "scaler"], capture_output=True, text=True, env=env).stdout.strip())
        os.kill(pid, signal.SIGKILL)
        text = wait_status(prefix, r"robot:\s+stopped", timeout=10)
        assert "monitor:" in text
        # and why, with what to do (the driver says it in its report, once a second, while it holds the stop)
        text = wait_status(prefix, r"stopped:\s+no command for \d+ ms; `hrc recover`", timeout=10)
        new_pid = None
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            out = subprocess.run(ctl + ["pid", "scaler"], capture_output=True, text=True, env=env).stdout.strip()
            if out.isdigit() and int(out) not in (0, pid):
                new_pid = int(out)
                break
            time.sleep(0.5)
        assert new_pid is not None, "supervisord did not restart the scaler"
        wait_status(prefix, r"scaler up", timeout=20)
        text = status(prefix)
        assert re.search(r"monitor:\s+\d+ checks, 0 violations", text), text
        # a goal sent to the stopped robot is planned, and dropped by the scaler; once `hrc recover` has the drives
        # running again the planner plans it anew from where the robot stands, and the robot goes there
        out = hrc("goal", "q_s", "--prefix", prefix)
        assert out.returncode == 0, out.stderr
        assert re.search(r"robot:\s+stopped", status(prefix))
        out = hrc("recover", "--prefix", prefix)
        assert out.returncode == 0, out.stderr
        wait_status(prefix, ROBOT_RUNS, timeout=30)
        reach(prefix, REACHED_Q_S, recoveries, timeout=30)
    finally:
        person.terminate()
        person.wait(10)
