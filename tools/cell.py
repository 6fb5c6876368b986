"""Starting and stopping a whole cell under supervisord (the thin shell behind `hrc up` and `hrc down`).

Where the kernel has no CAN the bus is udp_multicast, which may only run in a private network namespace:
`up` then starts supervisord under `unshare -n` (root) or `unshare -rn` (only lo, multicast on, a route
on lo) and writes the namespace's PID to <run>/cell.pid. Every other `hrc` command run outside it
re-enters that namespace with nsenter (`reenter_argv`), so it reaches the cell's loopback Zenoh. `down` ends
supervisord by that
PID, and supervisord stops every service cleanly.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

from shared.core.errors import HrcError
from tools.programs import supervisord_conf

ROOT = Path(__file__).resolve().parents[1]


NAMESPACE_SETUP = "ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo && exec \"$@\""


def choose_bus() -> tuple[str, str | None]:
    """(interface, channel) of the cell's CAN bus: kernel CAN when vcan0 exists, else udp_multicast (which
    needs a private network namespace)."""
    return ("socketcan", "vcan0") if os.path.exists("/sys/class/net/vcan0") else ("udp_multicast", None)


def unshare_flags() -> str:
    """-n for root (a network namespace alone: the processes keep the right to SCHED_FIFO, which a new user
    namespace takes away), else -rn (unprivileged: a user namespace too)."""
    return "-n" if os.geteuid() == 0 else "-rn"


def in_new_namespace(argv: list[str]) -> list[str]:
    """argv run in a new private network namespace (only lo, multicast on lo): the only place udp_multicast
    CAN may run."""
    return ["unshare", unshare_flags(), "sh", "-c", NAMESPACE_SETUP, "sh", *argv]


def namespace_reason() -> str | None:
    """Why no private network namespace can be made here, or None when one can."""
    if not shutil.which("unshare") or not shutil.which("ip"):
        return "unshare or ip (iproute2) is not installed"
    probe = subprocess.run(["unshare", unshare_flags(), "true"], capture_output=True, text=True)
    return None if probe.returncode == 0 else f"unshare {unshare_flags()} is not permitted here: {probe.stderr.strip()}"


def run_dir(prefix: str) -> Path:
    base = Path(os.environ.get("XDG_RUNTIME_DIR") or "/tmp")
    return base / f"hrc-{prefix.replace('/', '_')}"


def conf_path(prefix: str) -> Path:
    """supervisord's configuration of the cell, written by `up` from tools.programs."""
    return run_dir(prefix) / "supervisord.conf"


def cell_pid(prefix: str) -> int | None:
    try:
        pid = int((run_dir(prefix) / "cell.pid").read_text())
        os.kill(pid, 0)
        return pid
    except (OSError, ValueError):
        return None


def cell_endpoint(prefix: str) -> str:
    """The Zenoh endpoint of the cell `hrc up` started (its port in the run folder; 7447 without one)."""
    port_file = run_dir(prefix) / "cell.port"
    return f"tcp/127.0.0.1:{port_file.read_text().strip() if port_file.exists() else 7447}"


def up(prefix: str, interface: str, port: int, optional: tuple[str, ...] = (),
       extra: dict[str, list[str]] | None = None) -> int:
    """Start the cell (with the optional programs named: ros2_bridge; each program's extra arguments by name);
    returns the PID of supervisord (which is also the namespace holder)."""
    if cell_pid(prefix) is not None:
        raise RuntimeError(f"a cell with prefix {prefix} is already up (pid {cell_pid(prefix)})")
    run = run_dir(prefix)
    run.mkdir(parents=True, exist_ok=True)
    conf = conf_path(prefix)
    conf.write_text(supervisord_conf(optional, extra))
    env = dict(os.environ, HRC_RUN=str(run), HRC_PYTHON=sys.executable, HRC_CAN=interface, HRC_PREFIX=prefix,
               PYTHONPATH=str(ROOT), **{f"HRC_PORT{k if k else ''}": str(port + k) for k in range(6)})
    supervisord = [sys.executable, "-c", "from supervisor.supervisord import main; main()", "-c", str(conf)]
    argv = in_new_namespace(supervisord) if interface == "udp_multicast" else supervisord
    log = open(run / "up.log", "w")
    proc = subprocess.Popen(argv, env=env, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    (run / "cell.pid").write_text(str(proc.pid))
    (run / "cell.port").write_text(str(port))
    (run / "cell.can").write_text(interface)
    time.sleep(0.5)
    if proc.poll() is not None:
        raise RuntimeError(f"supervisord did not start; see {run / 'up.log'}")
    return proc.pid


def down(prefix: str, timeout: float = 20.0) -> bool:
    pid = cell_pid(prefix)
    if pid is None:
        return False
    os.kill(pid, signal.SIGTERM)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except OSError:
            break
        time.sleep(0.1)
    else:
        os.kill(pid, signal.SIGKILL)
    (run_dir(prefix) / "cell.pid").unlink(missing_ok=True)
    return True


def reenter_argv(prefix: str, argv: list[str]) -> list[str] | None:
    """The command line that runs argv inside the cell's namespace, or None when no re-entry is needed."""
    pid = cell_pid(prefix)
    if pid is None:
        return None
    try:
        if os.readlink(f"/proc/{pid}/ns/net") == os.readlink("/proc/self/ns/net"):
            return None
        own_user = os.readlink(f"/proc/{pid}/ns/user") == os.readlink("/proc/self/ns/user")
    except OSError:
        return None
    return ["nsenter", "--preserve-credentials", *([] if own_user else ["-U"]), "-n", "-t", str(pid), *argv]


def supervisor(prefix: str):
    """An XML-RPC proxy of the cell's supervisord (over its unix socket in the run folder)."""
    import xmlrpc.client

    from supervisor.xmlrpc import SupervisorTransport

    socket_path = run_dir(prefix) / "supervisor.sock"
    # the URL is a placeholder: the transport talks to the unix socket only
    return xmlrpc.client.ServerProxy("http://localhost", transport=SupervisorTransport(None, None,
                                                                                      f"unix://{socket_path}"))


class CellError(HrcError):
    """The cell's supervisord cannot be asked (not up, or it does not know the program)."""


def service_info(prefix: str, name: str) -> tuple[int, str]:
    """(pid, state name) of one program of the cell under supervisord (pid 0 when it is not running)."""
    import xmlrpc.client

    try:
        info = supervisor(prefix).supervisor.getProcessInfo(name)
    except (OSError, xmlrpc.client.Fault) as exc:
        raise CellError(f"supervisord of cell {prefix} cannot tell about {name}: {exc}") from None
    return int(info["pid"]), str(info["statename"])
