"""Scheduling and naming of the cell's threads (shared.scheduling), and the per-thread CPU the CPU bench reads."""

from __future__ import annotations

import threading
from pathlib import Path

from shared.scheduling import cpus_for, name_callback_thread, name_os_thread


def os_name(native_id: int) -> str:
    return Path(f"/proc/self/task/{native_id}/comm").read_text().strip()


def test_a_thread_gets_its_name_in_the_os_and_the_main_thread_keeps_the_process_name():
    main_name = os_name(threading.main_thread().native_id)
    seen = {}

    def worker():
        name_os_thread()                              # its Python name
        seen["plain"] = os_name(threading.get_native_id())
        name_callback_thread("zenoh-callback")        # named at the first call ...
        name_callback_thread("something-else")        # ... and left alone after it
        seen["callback"] = os_name(threading.get_native_id())

    thread = threading.Thread(target=worker, name="can-cycle-with-a-long-name")
    thread.start()
    thread.join()
    assert seen == {"plain": "can-cycle-with-"[:15], "callback": "zenoh-callback"}
    name_os_thread("renamed")                         # the main thread: ps and pgrep know the process by it
    assert os_name(threading.main_thread().native_id) == main_name


def test_the_driver_gets_the_last_cpu_and_the_rest_of_the_chain_the_others():
    assert cpus_for("robot_driver", {0, 1}) == {1} and cpus_for("hwsim", {0, 1}) == {0}
    assert cpus_for("scaler", {0, 1}) == {0} and cpus_for("tracker_ingest", {0, 1, 2, 3}) == {0, 1, 2}
    assert cpus_for("planner", {0, 1}) is None and cpus_for("safety_monitor", {0, 1}) is None   # free for bursts
    assert cpus_for("robot_driver", {2, 5, 7}) == {7}
    assert cpus_for("scaler", {3}) is None                 # one CPU: nothing to place


def test_the_monitor_runs_in_sched_fifo_below_every_process_of_the_safety_chain_and_the_feed():
    # the witness must keep up with the robot (monitor_behind), but never take the CPU from a command
    from shared.scheduling import PRIORITY

    chain = {name: p for name, p in PRIORITY.items() if name != "safety_monitor"}
    assert set(chain) == {"robot_driver", "hwsim", "scaler", "tracker_ingest", "human_feed"}
    assert 0 < PRIORITY["safety_monitor"] < min(chain.values())
    assert "planner" not in PRIORITY                  # a search never preempts anything of the cell


FROZEN = """
import gc, weakref
from shared.scheduling import freeze_heap
kept = [[i] for i in range(200_000)]           # a large heap of tracked objects, as a service has after its imports
walked_before = sum(len(gc.get_objects(generation)) for generation in range(3))
freeze_heap()
walked_after = sum(len(gc.get_objects(generation)) for generation in range(3))   # what a full collection walks

class Node:
    pass
cycle = Node(); cycle.me = cycle; alive = weakref.ref(cycle); del cycle    # garbage made after the freeze
gc.collect()
print(gc.get_freeze_count() >= 200_000, alive() is None, walked_before > 200_000, walked_after < 1_000)
"""


def test_a_frozen_heap_is_not_walked_by_a_full_collection_and_new_garbage_is_still_collected():
    # in a process of its own: freezing this test process's heap would change every test after it
    import subprocess
    import sys

    from tests.util import ROOT
    out = subprocess.run([sys.executable, "-c", FROZEN], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True"] * 4, out.stdout


SLOW = """
import gc, logging
logging.basicConfig(level=logging.WARNING, format="%(name)s %(message)s")
import shared.scheduling as scheduling
scheduling.freeze_heap()
scheduling.freeze_heap()                        # twice (the emulator does): one watch
assert gc.callbacks.count(scheduling._on_collection) == 1
gc.collect()                                    # nothing to walk: not logged
scheduling.SLOW_COLLECTION = 0.0
gc.disable()                                    # no automatic collection meanwhile: only the one below
class Node:
    pass
for _ in range(50_000):
    n = Node(); n.me = n
gc.collect()                                    # 50 000 cycles of garbage: logged, as longer than 0 s
"""


def test_a_collection_longer_than_half_a_sync_period_is_logged_once_the_heap_is_frozen():
    import subprocess
    import sys

    from tests.util import ROOT
    out = subprocess.run([sys.executable, "-c", SLOW], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    lines = [line for line in out.stderr.splitlines() if line.startswith("gc a collection of generation 2 took")]
    assert len(lines) == 1 and "ms with the GIL held (" in lines[0], out.stderr
    assert int(lines[0].rsplit("(", 1)[1].split()[0]) >= 40_000           # the nodes of the cycles (at least)


SHUTDOWN = """
import gc
import shared.scheduling as scheduling
scheduling.freeze_heap()
scheduling.SLOW_COLLECTION = 0.0
class Node:
    def __del__(self):
        pass
keep = []
for _ in range(20_000):
    n = Node(); n.me = n; keep.append(n)
gc.set_threshold(1)                             # collections while the interpreter tears its modules down
"""


def test_the_collection_watch_does_not_fail_while_the_interpreter_shuts_down():
    """It once imported what it needed when called: at the shutdown of every process of the cell it raised
    ('import of time halted') and filled the end of each log with tracebacks."""
    import subprocess
    import sys

    from tests.util import ROOT
    out = subprocess.run([sys.executable, "-c", SHUTDOWN], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and "Traceback" not in out.stderr and "Exception ignored" not in out.stderr, \
        out.stderr[-2000:]


THAW = """
import gc, weakref
import shared.scheduling as scheduling
class Node:
    pass
cycle = Node(); cycle.me = cycle; alive = weakref.ref(cycle)
scheduling.freeze_heap()                        # the cycle built before the service ran: frozen
del cycle
gc.collect()
frozen_kept = alive() is not None
scheduling.thaw_heap()                          # the service has stopped
gc.collect()
print(frozen_kept, alive() is None, gc.get_freeze_count() == 0, scheduling._on_collection not in gc.callbacks)
"""


def test_a_stopped_service_thaws_its_heap_so_what_it_built_is_freed_and_no_longer_watched():
    """serve() thaws the heap when the loop ends: frozen, a cycle built before the run outlived the interpreter (the
    planner's OMPL objects, listed as leaked by OMPL's bindings at every exit)."""
    import subprocess
    import sys

    from tests.util import ROOT
    out = subprocess.run([sys.executable, "-c", THAW], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True"] * 4, out.stdout


REALTIME = """
import sys
from shared.scheduling import SWITCH_INTERVAL, realtime
before = sys.getswitchinterval()
said = realtime("name-of-no-service")          # no priority of its own: stays in the normal class
print(before, sys.getswitchinterval() == SWITCH_INTERVAL, SWITCH_INTERVAL <= 0.001, said.startswith("normal"))
"""


def test_a_real_time_process_hands_the_gil_over_every_half_millisecond_not_every_five():
    # a process that called only realtime() (the emulated drives) kept Python's 5 ms: a thread that releases the
    # GIL to send a frame can wait up to 5 ms to get it back behind one that computes
    import subprocess
    import sys

    from tests.util import ROOT
    out = subprocess.run([sys.executable, "-c", REALTIME], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["0.005", "True", "True", "True"], out.stdout
