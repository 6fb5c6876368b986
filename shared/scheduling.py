"""Scheduling of the cell's processes: the safety chain first.

On a small machine (two cores here, seven Python processes) the threads that carry a human sample to the
drives must not wait behind a plan or the witness. Where the operating system allows it they run in
SCHED_FIFO, highest first: the driver's SYNC cycle, the emulated drives, the scaler, tracker_ingest. The
planner and the safety monitor stay in the normal class and are niced (planner +10, monitor +5: in
deploy/supervisord.conf and in hrc demo's launcher).

On a machine with two or more CPUs the two ends of the CAN bus (the driver and, in the emulated cell, the
drives) get the last CPU and the scaler and tracker_ingest the others (``cpus_for``); the planner and the
monitor, niced, stay free to take any idle CPU for their bursts (pinned too, a replan under load once took
1.1 s). Each chain process then wakes on a core whose caches still hold its code (a Python wake-up on a
cache another process has just evicted costs 4-8 times its warm time here), and the SYNC cycle never
queues behind a Zenoh service. Measured in hrc demo with a CPU-bound process beside it, two runs each:
processing p99 2.3 / 2.9 ms pinned against 2.8 / 3.3 ms free, the cell's CPU 20.8 / 20.4 s against
22.8 / 25.4 s. HRC_PIN_CPUS=0 in the environment leaves every process on every CPU.
"""

from __future__ import annotations

import ctypes
import os
import threading

# SCHED_FIFO priorities of the safety chain, highest first: the driver's SYNC cycle, the emulated drives,
# the scaler, tracker_ingest. The planner and the safety monitor stay in the normal class (and niced): a
# slow plan or a busy witness must never delay a command.
PRIORITY = {"robot_driver": 60, "hwsim": 55, "scaler": 50, "tracker_ingest": 45}


BUS_SIDE = ("robot_driver", "hwsim")      # the two ends of the CAN bus: the last CPU is theirs


def cpus_for(name: str, available: set[int]) -> set[int] | None:
    """The CPUs process `name` runs on (None: leave it where it is): with two CPUs or more, the last one
    for the bus side and the others for the rest of the safety chain. The planner and the monitor (niced)
    stay free: their work comes in bursts that any idle CPU should take."""
    if len(available) < 2 or name not in PRIORITY:
        return None
    last = max(available)
    return {last} if name in BUS_SIDE else available - {last}


def realtime(name: str) -> str:
    """Put the calling thread (and the threads it starts later) in SCHED_FIFO at the priority of `name`, on
    the CPUs ``cpus_for`` gives it; returns what was applied, for the start-up line. Where the OS refuses
    (no CAP_SYS_NICE, a container's limits) the thread stays in the normal class and the cell relies on
    niceness alone (planner +10, monitor +5 in supervisord and hrc demo): said, not hidden."""
    return f"{_fifo(name)}, {_pin(name)}"


def _fifo(name: str) -> str:
    priority = PRIORITY.get(name)
    if priority is None:
        return "normal scheduling"
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        return f"SCHED_FIFO {priority}"
    except (AttributeError, OSError) as exc:
        return f"normal scheduling (SCHED_FIFO {priority} refused: {getattr(exc, 'strerror', None) or exc})"


def _pin(name: str) -> str:
    if os.environ.get("HRC_PIN_CPUS", "1") == "0":
        return "any CPU (HRC_PIN_CPUS=0)"
    try:
        available = set(os.sched_getaffinity(0))
        cpus = cpus_for(name, available)
        if cpus is None:
            return "any CPU" + (" (one available)" if len(available) < 2 else "")
        os.sched_setaffinity(0, cpus)
        return f"CPU {','.join(map(str, sorted(cpus)))}"
    except (AttributeError, OSError) as exc:
        return f"any CPU (affinity refused: {getattr(exc, 'strerror', None) or exc})"


_PR_SET_NAME = 15


def name_os_thread(name: str | None = None) -> None:
    """Give the calling thread its name in the operating system too (Linux: prctl PR_SET_NAME, 15
    characters), so ``top -H``, py-spy and ``bench/cell_cpu.py`` tell the threads of a process apart
    (Python keeps its thread names to itself). Never the main thread: its name is the process's in ps and
    pgrep. Does nothing where the call is not available."""
    if threading.current_thread() is threading.main_thread():
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_NAME, (name or threading.current_thread().name).encode()[:15], 0, 0, 0)
    except (OSError, AttributeError):
        pass


_named = threading.local()          # per thread: whether it has its OS name yet


def name_callback_thread(name: str) -> None:
    """name_os_thread for a thread a library runs callbacks on (zenoh-python's, python-can's notifier):
    called at the top of the callback, it names the thread at its first call and costs an attribute look-up
    after that."""
    if not getattr(_named, "done", False):
        _named.done = True
        name_os_thread(name)


WAKE_LATE = 1e-4                    # s: a thread sleeping until a deadline wakes this long after it


def sleep_until(due: float, now: float) -> float:
    """How long (s) a thread sleeps to wake just after the monotonic time `due` (at once when it has passed):
    the loops that wake only when something can be due (tracker_ingest's dropout watch, the emulated drives'
    SYNC watchdog) instead of polling; each wake-up costs this machine a cold cache."""
    return max(due - now, 0.0) + WAKE_LATE
