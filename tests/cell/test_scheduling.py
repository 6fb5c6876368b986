"""Scheduling and naming of the cell's threads (shared.scheduling), and the per-thread CPU the CPU bench reads: the
tests that start a process or a network namespace (the rest, in-process, are in
tests/tools/test_scheduling.py)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time

from tests.util import ROOT
from tools.launch import CellProcesses


def test_realtime_says_what_it_applied_and_leaves_other_services_in_the_normal_class():
    code = textwrap.dedent("""
        import os
        from shared.scheduling import realtime
        print(realtime("planner"), os.sched_getscheduler(0) == os.SCHED_OTHER)
        said = realtime("scaler")
        print(said, os.sched_getscheduler(0) == (os.SCHED_FIFO if said.startswith("SCHED_FIFO") else os.SCHED_OTHER))
    """)                                              # in a child: never this test process's own scheduling
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=ROOT).stdout.splitlines()
    assert out[0].startswith("normal scheduling, ") and out[0].endswith("True")
    assert out[1].endswith("True") and "SCHED_FIFO 50" in out[1]          # applied, or refused and said so


def test_realtime_reaches_the_threads_the_process_started_before_it():
    code = textwrap.dedent("""
        import os, threading
        from shared.scheduling import realtime
        gate = threading.Event()
        thread = threading.Thread(target=gate.wait)       # like Zenoh's threads, started before the warm-up
        thread.start()
        said = realtime("scaler")
        fifo = said.startswith("SCHED_FIFO")
        print(said, os.sched_getscheduler(thread.native_id) == (os.SCHED_FIFO if fifo else os.SCHED_OTHER), fifo)
        gate.set()
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=ROOT).stdout.split()
    if out[-1] == "False":
        print("SCHED_FIFO refused here: the thread is checked to stay in the normal class instead")
    assert out[-2] == "True"


def test_a_service_warms_up_in_the_normal_class_and_takes_its_scheduling_when_it_serves():
    # a compile in SCHED_FIFO on a cold cache used up the real-time budget and faulted every drive (0x8100)
    code = textwrap.dedent("""
        import argparse, os
        import services.common as common

        class Shell:
            def __init__(self, name, args):
                self.name = name
            def announce(self):
                pass
            def close(self):
                pass

        common.ServiceShell = Shell
        _, shell = common.open_service("scaler", argparse.Namespace(config=None))
        print(os.sched_getscheduler(0) == os.SCHED_OTHER)
        seen = []
        common.serve(shell, "ready", lambda stop: seen.append(os.sched_getscheduler(0)))
        print(seen[0] == os.SCHED_FIFO)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=ROOT).stdout.splitlines()
    assert out[0] == "True"                                      # open_service: still the normal class
    assert out[1].startswith("ready, SCHED_FIFO 50") or out[1].startswith("ready, normal scheduling (SCHED_FIFO 50 refused")
    assert out[2] == str(out[1].startswith("ready, SCHED_FIFO"))  # the loop runs in what serve took


def test_realtime_pins_the_driver_only_when_asked_to():
    code = "import os; from shared.scheduling import realtime; print(realtime('robot_driver')); " \
           "print(sorted(os.sched_getaffinity(0)))"
    root = ROOT
    cpus = sorted(os.sched_getaffinity(0))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=root,
                         env=dict(os.environ, HRC_PIN_CPUS="1")).stdout.splitlines()
    if len(cpus) >= 2:
        assert out[0].endswith(f"CPU {cpus[-1]}") and out[1] == str([cpus[-1]])
    else:
        assert out[0].endswith("any CPU (one available)") and out[1] == str(cpus)
    env = {k: v for k, v in os.environ.items() if k != "HRC_PIN_CPUS"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=root,
                         env=env).stdout.splitlines()
    assert out[0].endswith("any CPU") and out[1] == str(cpus)                 # the default: free


def test_the_cpu_of_each_thread_of_a_child_is_read_by_its_os_name(tmp_path):
    code = textwrap.dedent("""
        import threading, time
        from shared.scheduling import name_os_thread
        def spin():
            name_os_thread("busy-worker")
            end = time.monotonic() + 4.0
            while time.monotonic() < end:
                pass
        threading.Thread(target=spin, name="busy").start()
        time.sleep(5)
    """)
    cell = CellProcesses(tmp_path, "test/threads", "virtual")
    cell.procs["child"] = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT)
    try:
        deadline = time.monotonic() + 10.0
        threads: dict[str, float] = {}
        while time.monotonic() < deadline:               # until the worker has spun a while (it spins 4 s)
            threads = cell.thread_cpu_seconds().get("child", {})
            if threads.get("busy-worker", 0.0) >= 0.2:
                break
            time.sleep(0.1)
        assert threads.get("busy-worker", 0.0) >= 0.2
        assert threads["busy-worker"] > threads.get("python", 0.0)
    finally:
        cell.procs["child"].kill()
        cell.procs["child"].wait()
    assert cell.thread_cpu_seconds() == {}               # a child that has gone has no threads to read
