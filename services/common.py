"""What every service shell shares: logging format, the Zenoh session, liveliness, decoding with a
clear (rate-limited) log on bad input, and a deadline-paced loop thread.

A service is a thin shell around a pure core: it decodes what arrives on its keys (a bad message is
dropped with a log line and the service goes on), calls the core, encodes and publishes.
"""

from __future__ import annotations

import argparse
import logging
import sys
import threading
import time
from pathlib import Path

import zenoh

from shared.core.errors import MessageError
from shared.scheduling import name_callback_thread, name_os_thread, realtime, thaw_heap
from shared.transport.pki import TlsIdentity
from shared.transport.zenoh_session import open_session
from shared.wire.keys import KeySpace
from shared.wire.messages import Message, decode

LOG_FORMAT = "%(asctime)s %(name)s %(levelname)s %(message)s"


def setup_logging(level: str) -> None:
    logging.basicConfig(level=level.upper(), format=LOG_FORMAT)


def add_zenoh_arguments(parser: argparse.ArgumentParser, default_listen: str | None = None) -> None:
    parser.add_argument("--prefix", default="hrc/cell1", help="key prefix of the cell (default hrc/cell1)")
    parser.add_argument("--listen", nargs="*", default=[default_listen] if default_listen else [],
                        help="Zenoh endpoints to listen on (tcp/127.0.0.1:PORT)")
    parser.add_argument("--connect", nargs="*", default=[], help="Zenoh endpoints to connect to")
    parser.add_argument("--mode", choices=("peer", "client"), default="peer",
                        help="Zenoh mode: peer (one host, meshed) or client (of a router)")
    parser.add_argument("--allow-remote", action="store_true",
                        help="allow non-loopback endpoints (the multi-host deployment through a router)")
    parser.add_argument("--tls-dir", type=Path, default=None, metavar="DIR",
                        help="mutual TLS with the cell's certificates in DIR (ca.pem, <service>.pem, "
                             "<service>-key.pem; made by `hrc certs`): use tls/ endpoints")
    parser.add_argument("--log-level", default="INFO")


def service_parser(name: str, doc: str | None, config: bool = True,
                   default_listen: str | None = None) -> argparse.ArgumentParser:
    """The argument parser every service starts from: its docstring as the help, the Zenoh options and,
    with config, --config (the cell configuration YAML)."""
    parser = argparse.ArgumentParser(prog=name, description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_zenoh_arguments(parser, default_listen)
    if config:
        parser.add_argument("--config", type=Path, default=None, help="cell configuration YAML")
    return parser


class ServiceShell:
    """Session, keys, liveliness token and decoding for one named service.

    The liveliness token means "ready to serve": a service declares it with ``announce()`` only once it
    has warmed up and subscribed, so a client that waits for it never sends into a gap."""

    def __init__(self, name: str, args: argparse.Namespace) -> None:
        self.name = name
        self.log = logging.getLogger(name)
        self.keys = KeySpace(args.prefix)
        tls = TlsIdentity.from_dir(args.tls_dir, name) if getattr(args, "tls_dir", None) else None
        self.session = open_session(args.mode, listen=args.listen if args.mode == "peer" else [],
                                    connect=args.connect, allow_remote=args.allow_remote, tls=tls,
                                    timestamping=getattr(args, "timestamping", False))
        self.token = None
        self.bad_messages = 0
        self._last_bad_log = -1e9
        self._subscribers = []

    def decode(self, sample, kind: type[Message]) -> Message | None:
        """The message in a sample, or None after logging why it was dropped (at most one line a second,
        with a count, so a flood of garbage cannot flood the log)."""
        try:
            return decode(sample.payload.to_bytes(), kind)
        except MessageError as exc:
            self.bad_messages += 1
            now = time.monotonic()
            if now - self._last_bad_log >= 1.0:
                self._last_bad_log = now
                self.log.error("dropped a bad %s on %s (%d so far): %s", kind.KIND, sample.key_expr,
                               self.bad_messages, exc)
            return None

    def subscribe(self, key: str, kind: type[Message], handler) -> None:
        """Call handler(message) for every valid message on key (on zenoh-python's callback thread, named
        'zenoh-callback' in the OS at its first message)."""
        def on_sample(sample):
            name_callback_thread("zenoh-callback")
            msg = self.decode(sample, kind)
            if msg is not None:
                handler(msg)
        self._subscribers.append(self.session.declare_subscriber(key, on_sample))

    def latest(self, key: str, kind: type[Message]) -> "Latest":
        """The newest message on key, kept by Zenoh (see ``Latest``)."""
        latest = Latest(self, self.session.declare_subscriber(key, zenoh.handlers.RingChannel(1)), kind)
        self._subscribers.append(latest.subscriber)
        return latest

    def queue(self, key: str, kind: type[Message], capacity: int = 10_000) -> "Queue":
        """Every message on key, queued by Zenoh (see ``Queue``)."""
        queue = Queue(self, self.session.declare_subscriber(key, zenoh.handlers.FifoChannel(capacity)), kind)
        self._subscribers.append(queue.subscriber)
        return queue

    def announce(self) -> None:
        """Declare the liveliness token: from now on this service is up (call it last in the set-up)."""
        self.token = self.session.liveliness().declare_token(self.keys.alive(self.name))

    def close(self) -> None:
        for sub in self._subscribers:
            sub.undeclare()
        if self.token is not None:
            self.token.undeclare()
        self.session.close()


class _Inbox:
    """A subscriber whose samples Zenoh keeps until a reader with a cadence of its own takes them: no
    Python runs per message (a callback costs its thread a wake-up, the GIL and a decode)."""

    def __init__(self, shell: ServiceShell, subscriber, kind: type[Message]) -> None:
        self.shell, self.subscriber, self.kind = shell, subscriber, kind


class Latest(_Inbox):
    """The newest message on a key, kept by Zenoh in a ring of one. For inputs of which only the newest
    matters (the planner's people, joints and scaler status)."""

    def take(self) -> Message | None:
        """The newest valid message since the last take, else None (none came, or it was bad: logged)."""
        sample = self.subscriber.try_recv()
        return None if sample is None else self.shell.decode(sample, self.kind)


class Queue(_Inbox):
    """Every message on a key, queued by Zenoh (a FIFO) and taken in bulk. The capacity holds far more
    than a reader that keeps its cadence ever leaves (10 000: 100 s of 100 Hz joint states)."""

    def drain(self) -> list[Message]:
        """Every valid message since the last drain, oldest first (bad ones logged and counted)."""
        out = []
        while (sample := self.subscriber.try_recv()) is not None:
            msg = self.shell.decode(sample, self.kind)
            if msg is not None:
                out.append(msg)
        return out


def prepare_loop_thread() -> None:
    """What every loop thread of a service sets before it loops: the thread's name in the OS
    (``name_os_thread``; the main thread keeps the process's). The GIL is already handed over every 0.5 ms,
    so no callback thread waits 5 ms behind the loop (nor the loop behind a callback): ``serve`` took the
    process real-time first (``shared.scheduling.realtime`` sets the switch interval)."""
    name_os_thread()


def run_paced(period: float, tick, stop: threading.Event) -> None:
    """Call tick(now) every period: deadline sleeping (clock_nanosleep, tens of microseconds late), no
    spinning (that would hold the GIL while a callback waits); an overrun re-syncs instead of bursting.
    Python hands the GIL over every 5 ms by default, which would let any callback thread delay a tick that
    long: the process's scheduling, taken after its warm-up (``serve``: ``shared.scheduling.realtime``), sets
    the switch interval to 0.5 ms, and the thread runs in that scheduling. A thread of its own is named in the
    OS after its Python name (``prepare_loop_thread``)."""
    prepare_loop_thread()
    deadline = time.monotonic()
    while not stop.is_set():
        deadline += period
        remaining = deadline - time.monotonic()
        if remaining > 0:
            time.sleep(remaining)
        now = time.monotonic()
        if now - deadline > period:
            deadline = now
        tick(now)


def run_synced(period: float, tick, stop: threading.Event, ready: threading.Event) -> None:
    """Call tick(now) each time `ready` is set (by whoever feeds the loop: the scaler sets it on every joint
    state, one a SYNC), or after 1.5 periods without it (so the loop goes on when its feed stops). Locked
    to the robot's own clock, a loop never runs ahead of the drives: a SYNC that comes late delays its
    tick instead of leaving the robot a period behind the commands, which a trajectory at the velocity
    limit can never make up. Switch interval, scheduling and naming as run_paced."""
    prepare_loop_thread()
    while not stop.is_set():
        ready.wait(1.5 * period)
        ready.clear()
        tick(time.monotonic())


def run_in_thread(name: str, loop, stop: threading.Event) -> BaseException | None:
    """Run loop(stop) in a thread of its own, named `name`, until `stop` is set (by the service's signal handler,
    or by this when the loop ends); returns what the loop raised, None when it returned. A loop that raises
    sets `stop` with it: its service must then end (and be restarted by its supervisor), not live on without
    the loop. Why: the robot driver's SYNC cycle once raised in its thread while the process stayed up; the
    drives stopped for want of SYNC, and the supervisor saw a running driver that never moved the robot again."""
    failure: list[BaseException] = []

    def guarded() -> None:
        try:
            loop(stop)
        except BaseException as exc:          # whatever it was, the loop is gone: the service must go too
            failure.append(exc)
            logging.getLogger(name).critical("the %s loop failed; the service ends", name, exc_info=exc)
        finally:
            stop.set()

    thread = threading.Thread(target=guarded, name=name, daemon=True)
    thread.start()
    stop.wait()
    thread.join(1.0)
    return failure[0] if failure else None


def open_service(name: str, args: argparse.Namespace):
    """(cell config, shell) of a service, or None after printing a clear error (the caller exits 2). The
    process stays in the normal scheduling class here: it takes its own (``shared.scheduling.realtime``)
    in ``serve``, after its warm-up (a compile in SCHED_FIFO starves the driver's SYNC cycle)."""
    from shared.config import load_config
    from shared.core.errors import HrcError

    try:
        config = load_config(getattr(args, "config", None))
        return config, ServiceShell(name, args)
    except HrcError as exc:
        print(f"{name}: error: {exc}", file=sys.stderr)
        return None


def serve(shell: ServiceShell, ready: str, loop, on_stop=None) -> int:
    """Take the service's scheduling (every thread of the process, after its warm-up: see
    ``shared.scheduling.realtime``), stop on SIGTERM / SIGINT, announce the service (it is ready), print
    its ready line with the scheduling, run loop(stop) until stopped, close; returns the loop's exit code (0 when
    it returns none). on_stop() is called from the signal handler (e.g. to wake a worker)."""
    import signal

    scheduling = realtime(shell.name)
    stop = threading.Event()

    def handler(*_):
        stop.set()
        if on_stop is not None:
            on_stop()

    signal.signal(signal.SIGTERM, handler)
    signal.signal(signal.SIGINT, handler)
    try:
        shell.announce()
        print(f"{ready}, {scheduling}", flush=True)
        code = loop(stop)
    finally:
        shell.close()
        thaw_heap()
    return code or 0
