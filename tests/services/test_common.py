"""The shared service skeleton: a loop thread that fails ends its service (``run_in_thread``; the robot driver
then exits 1 through ``serve``), so a supervisor restarts a service whose loop is gone instead of keeping a
process that no longer does its job. (``serve`` itself takes the process real-time and its signals: not
called in the test process.)"""

from __future__ import annotations

import threading

from services.common import run_in_thread


def test_a_loop_that_raises_stops_its_service_and_is_returned_and_logged(caplog):
    stop = threading.Event()
    seen: list[str] = []

    def loop(stopped: threading.Event) -> None:
        seen.append(threading.current_thread().name)
        raise AttributeError("no attribute 'value'")

    with caplog.at_level("CRITICAL", logger="can-cycle"):
        failed = run_in_thread("can-cycle", loop, stop)
    assert isinstance(failed, AttributeError) and stop.is_set() and seen == ["can-cycle"]
    (record,) = [r for r in caplog.records if r.name == "can-cycle"]
    assert "the can-cycle loop failed" in record.getMessage() and record.exc_info[0] is AttributeError


def test_a_loop_stopped_from_outside_returns_nothing():
    stop = threading.Event()
    started = threading.Event()

    def loop(stopped: threading.Event) -> None:
        started.set()
        stopped.wait()

    threading.Timer(0.05, lambda: started.wait(5.0) and stop.set()).start()
    assert run_in_thread("worker", loop, stop) is None and stop.is_set()
