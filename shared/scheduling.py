"""Scheduling of the cell's processes: the safety chain first.

On a small machine (two cores here, seven Python processes) the threads that carry a human sample to the
drives must not wait behind a plan or the witness. Where the operating system allows it they run in
SCHED_FIFO, highest first: the driver's SYNC cycle, the emulated drives, the scaler, tracker_ingest (and, in
``hrc demo``, below them, the process that plays the person, as a camera would); below all of them the safety
monitor, the independent witness, which must keep up with the robot (``monitor_behind``) but never delays a
command. The planner stays in the normal class and is niced (+10: in deploy/supervisord.conf and in hrc demo's
launcher); the monitor is niced too (+5), for where the OS refuses SCHED_FIFO.

With HRC_PIN_CPUS=1 in the environment, on a machine with two or more CPUs, the driver, which paces the
drives' SYNC, gets the last CPU to itself and the emulated drives, the scaler and tracker_ingest share the
others (``cpus_for``); the planner and the monitor stay free for their bursts. That is the layout for a
cell whose last core is kept for the driver (isolcpus). It is off by default because on this 2-core VM
it did not pay: bench/can_loop.py, idle, three interleaved pairs: SYNC jitter max 0.64-0.67 ms pinned
against 3.9-7.5 ms free, command -> frame p99 1.08-1.47 against 1.30-1.42 ms, but the joint state reached
a Zenoh subscriber later (p99 1.41-1.53 against 0.84-0.89 ms); loaded, two pairs: jitter max 3.96 / 0.56
against 0.53 / 0.98 ms, command -> frame p99 1.03 / 2.30 against 1.02 / 1.04 ms; hrc demo loaded, two
pairs: processing p99 2.47 / 2.04 against 2.18 / 1.89 ms. Other layouts were worse: the driver and the
emulated drives on one CPU serialised the CAN exchange (command -> frame p99 up to 3 ms), and pinning the
planner too made a replan under load take 1.1 s.
"""

from __future__ import annotations

import ctypes
import gc
import logging
import os
import sys
import threading
import time

SWITCH_INTERVAL = 0.0005      # s: how often a real-time process hands the GIL over (Python's default is 5 ms)

# SCHED_FIFO priorities of the safety chain, highest first: the driver's SYNC cycle, the emulated drives,
# the scaler, tracker_ingest. The planner stays in the normal class (and niced): a slow plan must never
# delay a command.
# Below them, the demo's person feed (tools.feed): like the emulated drives it stands for hardware outside the
# machine (a camera and its skeleton tracker), which neither the chain nor a busy planner delays.
# Below everything of the chain, the safety monitor: in the normal class (nice 5) the planner's searches and
# the demo's recorder held it more than 0.1 s behind the robot (``monitor_behind`` in 2 of 24 real-people runs,
# docs/real-people.md); its checks (about 0.1 CPU) now wait for nothing but the chain and the feed.
PRIORITY = {"robot_driver": 60, "hwsim": 55, "scaler": 50, "tracker_ingest": 45, "human_feed": 40,
            "safety_monitor": 30}


OWN_CPU = "robot_driver"                             # the SYNC cycle: the last CPU is its own
SHARED_CPUS = ("hwsim", "scaler", "tracker_ingest")   # the rest of the chain: the other CPUs


def cpus_for(name: str, available: set[int]) -> set[int] | None:
    """The CPUs process `name` runs on (None: leave it where it is): with two CPUs or more, the last one
    for the driver and the others for the emulated drives, the scaler and tracker_ingest. The planner and
    the monitor stay free: their work comes in bursts that any idle CPU should take."""
    if len(available) < 2 or (name != OWN_CPU and name not in SHARED_CPUS):
        return None
    last = max(available)
    return {last} if name == OWN_CPU else available - {last}


def realtime(name: str) -> str:
    """Put every thread of the calling process (and the threads they start later) in SCHED_FIFO at the
    priority of `name` and, with HRC_PIN_CPUS=1, on the CPUs ``cpus_for`` gives it; returns what was
    applied, for the start-up line. Every thread, not only the caller: a safety-chain thread waiting for the
    GIL must not wait behind a thread of its own process (Zenoh's, canopen's) that a busy machine has
    preempted.

    Call it after the service's warm-up, never before: a SCHED_FIFO process that compiles its kernels into
    numba's empty cache runs CPU-bound for tens of seconds, and two of them (scaler, tracker_ingest) use up
    the real-time budget of a 2-core machine (sched_rt_runtime_us, 950 ms a second); the kernel then
    throttles every SCHED_FIFO thread for the rest of each second, the driver's SYNC cycle included, and the
    drives fault on their SYNC time-out before the cell is up (seen: docs/measurements.md).

    Where the OS refuses (no CAP_SYS_NICE, a container's limits) the threads stay in the normal class and
    the cell relies on niceness alone (planner +10, monitor +5 in supervisord and hrc demo): said, not
    hidden.

    First the heap is frozen (``freeze_heap``): a real-time loop must not stop for Python's full collection. And
    the GIL is handed over every SWITCH_INTERVAL, not Python's 5 ms: a thread that releases the GIL to send a frame
    can wait up to 5 ms to get it back where another thread of its process computes meanwhile. Until session 60
    the services set it in their loops and the emulated drives, which answer each SYNC with six frames, kept
    5 ms (no change in the SYNC answers they missed was measured: those follow the hypervisor's steal time,
    docs/measurements.md)."""
    freeze_heap()
    sys.setswitchinterval(SWITCH_INTERVAL)
    return f"{_fifo(name)}, {_pin(name)}"


def freeze_heap() -> None:
    """Collect once, then move every object there is into the collector's permanent generation (``gc.freeze``),
    so that its full collections no longer walk them. Why: a full collection walks every tracked object, 55 000
    to 68 000 in a service of the cell after its imports (more once running), and holds the GIL meanwhile:
    8-15 ms on this VM idle, longer on a slow day. In the driver or the emulated drives that is a SYNC answer
    missed and a command the drives cannot follow (``command_clamped``); in the scaler, a command a period late.
    Objects made later are still collected as usual; call it again once a process has built what it keeps
    (the emulator's drives). Measured: docs/measurements.md, session 59."""
    gc.collect()
    gc.freeze()
    watch_collections()


SLOW_COLLECTION = 0.005     # s: a collection this long is logged (half a SYNC period, with the GIL held)
_watch: dict[int, float] = {}


def _on_collection(phase: str, info: dict, clock=time.perf_counter, log=logging.getLogger("gc")) -> None:
    """gc callback: time each collection; log one longer than SLOW_COLLECTION. What it uses is bound when it is
    defined: a collection during the interpreter's shutdown finds no module to import."""
    generation = info.get("generation", -1)
    if phase == "start":
        _watch[generation] = clock()
        return
    began = _watch.pop(generation, None)
    took = clock() - began if began is not None else 0.0
    if took > SLOW_COLLECTION:
        log.warning("a collection of generation %d took %.1f ms with the GIL held (%d collected)", generation,
                    took * 1e3, info.get("collected", 0))


def watch_collections() -> None:
    """Log every collection of Python's garbage collector that takes longer than SLOW_COLLECTION, from now on, once
    per process: with the heap frozen they should be short; one that is not holds every thread of the process
    (a SYNC answer missed, a command late) and its log line says so."""
    if _on_collection not in gc.callbacks:
        gc.callbacks.append(_on_collection)


def thaw_heap() -> None:
    """Undo ``freeze_heap`` once a service has stopped: its objects collectable again, so that what it built is
    freed at exit (frozen, the planner's OMPL objects outlived the interpreter's last collection and OMPL's
    bindings reported them leaked in every run's planner.log), and the collections no longer watched (the exit's
    one walks the whole heap, holding nothing up)."""
    gc.unfreeze()
    if _on_collection in gc.callbacks:
        gc.callbacks.remove(_on_collection)


def _threads() -> list[int]:
    """The native ids of every thread of this process (Linux: /proc/self/task); [0] (the caller) elsewhere."""
    try:
        return sorted(int(tid) for tid in os.listdir("/proc/self/task"))
    except OSError:
        return [0]


def _every_thread(apply) -> None:
    """apply(tid) to every thread of the process, again while new ones appear (a thread that a thread not yet
    changed starts meanwhile inherits the old setting; one started later inherits the new one). A thread
    that ends meanwhile is passed over; any other refusal raises (OSError)."""
    done: set[int] = set()
    for _ in range(3):
        new = [tid for tid in _threads() if tid not in done]
        if not new:
            return
        for tid in new:
            try:
                apply(tid)
            except ProcessLookupError:              # a thread that ended meanwhile
                pass
            done.add(tid)


def _fifo(name: str) -> str:
    priority = PRIORITY.get(name)
    if priority is None:
        return "normal scheduling"
    try:
        _every_thread(lambda tid: os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(priority)))
        return f"SCHED_FIFO {priority}"
    except (AttributeError, OSError) as exc:
        return f"normal scheduling (SCHED_FIFO {priority} refused: {getattr(exc, 'strerror', None) or exc})"


def _pin(name: str) -> str:
    if os.environ.get("HRC_PIN_CPUS", "0") != "1":
        return "any CPU"
    try:
        available = set(os.sched_getaffinity(0))
        cpus = cpus_for(name, available)
        if cpus is None:
            return "any CPU" + (" (one available)" if len(available) < 2 else "")
        _every_thread(lambda tid: os.sched_setaffinity(tid, cpus))
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
