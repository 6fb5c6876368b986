"""Start the whole cell as child processes of one program (the thin launcher behind `hrc demo` and the
end-to-end benchmark; `hrc up` uses supervisord instead, for a cell that outlives the command).

The PRBT emulator first, then the robot driver, tracker_ingest, scaler, planner and safety monitor, each
`python -m ...` with its output in <run>/<name>.log. Each is a Zenoh peer listening on its own loopback
port and connecting to the driver's (peers do not forward; gossip meshes them). A service is up when its
liveliness token is visible, which it declares only once it is ready. Every child dies with the
launcher (PR_SET_PDEATHSIG) and is ended by PID in ``stop``.
"""

from __future__ import annotations

import ctypes
import os
import random
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from tools.programs import BY_NAME, SERVICES

ROOT = Path(__file__).resolve().parents[1]


class LaunchError(RuntimeError):
    """A process of the cell did not come up; the message holds the tail of its log."""


EPHEMERAL = Path("/proc/sys/net/ipv4/ip_local_port_range")
_GIVEN: set[int] = set()             # ports this process has handed out: never twice


def free_port() -> int:
    """A loopback TCP port free now, below the kernel's ephemeral range where it can (from the lower half of the
    ports under it), never one this process has handed out before. Why not the kernel's own choice (bind to 0): that
    is an ephemeral port, which the kernel may give a moment later to the local end of an outgoing connection (every
    service connects to the others), and a service that then listens on it fails with 'Address already in use'
    (the fault campaign's planner once failed for 12 s so, and the robot stood). Bound here without SO_REUSEADDR, so
    a port still in TIME_WAIT from an earlier run is passed over too."""
    try:
        low = int(EPHEMERAL.read_text().split()[0])
    except (OSError, ValueError, IndexError):
        low = 32768
    rng = random.SystemRandom()
    for _ in range(200 if low // 2 >= 1024 else 0):
        port = rng.randrange(low // 2, low)
        if port in _GIVEN:
            continue
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
        _GIVEN.add(port)
        return port
    with socket.socket() as s:          # no room below the range: the kernel's choice
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    _GIVEN.add(port)
    return port




def die_with_parent() -> None:
    """In a child before exec: the kernel sends it SIGKILL when its parent dies (PR_SET_PDEATHSIG)."""
    ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)     # PR_SET_PDEATHSIG


def stat_cpu_seconds(stat: Path) -> float:
    """User + system CPU time (s) from a /proc stat file (a process's or a thread's); OSError when it has
    gone, IndexError or ValueError when the file is not one."""
    fields = stat.read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@dataclass
class CellProcesses:
    """The emulator and the five services of one cell, as children of this process."""

    run: Path
    prefix: str
    interface: str
    channel: str | None = None
    config: Path | None = None
    planner_seed: int | None = None
    services: tuple[str, ...] = SERVICES
    extra_args: dict[str, list[str]] = field(default_factory=dict)     # per process, appended to its argv
    procs: dict[str, subprocess.Popen] = field(default_factory=dict)
    port: int = 0

    def __post_init__(self) -> None:
        self.run.mkdir(parents=True, exist_ok=True)
        self.port = self.port or free_port()

    @property
    def endpoint(self) -> str:
        """The Zenoh endpoint a client of the cell connects to (the driver's)."""
        return f"tcp/127.0.0.1:{self.port}"

    def _spawn(self, name: str, argv: list[str], niceness: int | None = None, stdin=None) -> subprocess.Popen:
        env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")
        log = open(self.run / f"{name}.log", "w")
        niceness = BY_NAME[name].niceness if niceness is None else niceness

        def prepare() -> None:
            die_with_parent()
            os.nice(niceness)
        self.procs[name] = subprocess.Popen([sys.executable, "-X", "faulthandler", "-m", *argv], cwd=ROOT, env=env,
                                            stdin=stdin, stdout=log, stderr=subprocess.STDOUT, preexec_fn=prepare)
        log.close()
        return self.procs[name]

    def spawn_helper(self, name: str, argv: list[str], ready: str, timeout: float = 40.0) -> subprocess.Popen:
        """Start a process beside the cell that is not one of its programs (the demo's person feed): `python -m
        argv`, its output in <run>/<name>.log, a pipe to its stdin; return once its output holds `ready`
        (LaunchError with its log's tail when it does not). It is ended first in ``stop``."""
        proc = self._spawn(name, argv, niceness=0, stdin=subprocess.PIPE)
        self._wait_line(name, ready, timeout)
        return proc

    def _tail(self, name: str, lines: int = 12) -> str:
        try:
            return "".join((self.run / f"{name}.log").read_text().splitlines(True)[-lines:])
        except OSError:
            return ""

    def _wait_line(self, name: str, text: str, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if text in (self.run / f"{name}.log").read_text():
                return
            if self.procs[name].poll() is not None:
                break
            time.sleep(0.05)
        raise LaunchError(f"{name} did not start (exit {self.procs[name].poll()}):\n{self._tail(name)}")

    def start(self, session, timeout: float = 90.0) -> None:
        """Start everything; return when every service's liveliness token is visible to `session`
        (a Zenoh session connected to ``endpoint``)."""
        from shared.transport.zenoh_session import await_liveliness
        from shared.wire.keys import KeySpace

        emulator = BY_NAME["hwsim"]
        self._spawn(emulator.name, emulator.argv(interface=self.interface, channel=self.channel))
        self._wait_line(emulator.name, emulator.ready, 30.0)
        for name in self.services:
            program = BY_NAME[name]
            extra = ["--log-level", "WARNING"]
            if name == "planner" and self.planner_seed is not None:
                extra += ["--seed", str(self.planner_seed)]
            listen = self.endpoint if program.hub else f"tcp/127.0.0.1:{free_port()}"
            self._spawn(name, program.argv(interface=self.interface, channel=self.channel, prefix=self.prefix,
                                           listen=listen, connect=self.endpoint, config=self.config,
                                           extra=extra + self.extra_args.get(name, [])))
        keys = KeySpace(self.prefix)
        deadline = time.monotonic() + timeout
        for name in self.services:
            while not await_liveliness(session, keys.alive(name), 0.5):
                dead = [n for n, p in self.procs.items() if p.poll() is not None]
                if dead:
                    raise LaunchError(f"{dead[0]} exited ({self.procs[dead[0]].returncode}):\n{self._tail(dead[0])}")
                if time.monotonic() > deadline:
                    raise LaunchError(f"{name} not up within {timeout:.0f} s:\n{self._tail(name)}")

    def cpu_seconds(self) -> dict[str, float]:
        """CPU time (user + system, s) each live child has used so far (/proc/<pid>/stat)."""
        out = {}
        for name, proc in self.procs.items():
            try:
                out[name] = round(stat_cpu_seconds(Path(f"/proc/{proc.pid}/stat")), 2)
            except (OSError, IndexError, ValueError):
                pass
        return out

    def thread_cpu_seconds(self) -> dict[str, dict[str, float]]:
        """Per live child, the CPU time (s) of its threads so far, by thread name (/proc/<pid>/task: the
        names the OS knows: zenoh's runtime threads, the ones the services name, 'python' for the rest;
        threads of the same name summed)."""
        out: dict[str, dict[str, float]] = {}
        for name, proc in self.procs.items():
            threads: dict[str, float] = {}
            for task in Path(f"/proc/{proc.pid}/task").glob("*"):
                try:
                    comm = (task / "comm").read_text().strip()
                    threads[comm] = threads.get(comm, 0.0) + stat_cpu_seconds(task / "stat")
                except (OSError, IndexError, ValueError):        # a thread that ended meanwhile
                    continue
            if threads:
                out[name] = threads
        return out

    def alive(self) -> dict[str, bool]:
        return {name: proc.poll() is None for name, proc in self.procs.items()}

    def stop(self, timeout: float = 5.0) -> dict[str, int | None]:
        """SIGTERM every child (helpers first, then the services, the emulator last), then SIGKILL what is left;
        exit codes."""
        programs = [*reversed(self.services), "hwsim"]
        for name in [*(n for n in self.procs if n not in programs), *programs]:
            proc = self.procs.get(name)
            if proc is not None and proc.poll() is None:
                proc.send_signal(signal.SIGCONT)
                proc.terminate()
        codes = {}
        for name, proc in self.procs.items():
            try:
                codes[name] = proc.wait(timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                codes[name] = proc.wait()
        return codes
