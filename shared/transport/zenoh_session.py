"""The one place that opens Zenoh sessions, so every session is built safe.

Multicast scouting is always off (it would send packets out of the machine's network interfaces);
endpoints are explicit and, unless allow_remote is set (the multi-host deployment, through a router on
the cell network), must be loopback: tcp/127.0.0.1:PORT or tcp/[::1]:PORT (tls/... the same). Peers do not
forward for each other, so either every peer listens on its own loopback port or all connect to one router.

With a TLS identity (shared.transport.pki) the links are mutual TLS: the session presents its certificate and checks
the other side's against the cell CA. A router may also be given an access-control section (shared.transport.acl).
"""

from __future__ import annotations

import json
import re
import socket
import threading
import time

import zenoh

from shared.core.errors import ConfigError
from shared.transport.pki import TlsIdentity

_LOOPBACK = re.compile(r"^(tcp|tls)/(127\.0\.0\.1|\[::1\]):\d{1,5}$")


def check_endpoints(endpoints: list[str], allow_remote: bool = False) -> list[str]:
    for e in endpoints:
        if not isinstance(e, str) or not e.startswith(("tcp/", "tls/")):
            raise ConfigError(f"zenoh endpoint {e!r}: expected tcp/HOST:PORT or tls/HOST:PORT")
        if not allow_remote and not _LOOPBACK.match(e):
            raise ConfigError(f"zenoh endpoint {e!r}: only loopback (tcp/127.0.0.1:PORT) is allowed here")
    return list(endpoints)


def _tls_section(tls: TlsIdentity) -> dict:
    """Mutual TLS with the cell CA: the same certificate when listening and when connecting."""
    return {"root_ca_certificate": str(tls.ca), "enable_mtls": True, "verify_name_on_connect": True,
            "listen_certificate": str(tls.certificate), "listen_private_key": str(tls.key),
            "connect_certificate": str(tls.certificate), "connect_private_key": str(tls.key)}


def make_config(mode: str = "peer", listen: list[str] = (), connect: list[str] = (),
                allow_remote: bool = False, tls: TlsIdentity | None = None,
                access_control: dict | None = None, timestamping: bool = False) -> zenoh.Config:
    """timestamping: every sample gets the session's HLC timestamp (zenoh-ext's advanced publisher needs it:
    the ROS 2 bridge's transient-local topics); off elsewhere."""
    if mode not in ("peer", "client", "router"):
        raise ConfigError(f"zenoh mode {mode!r}: expected peer, client or router")
    config = zenoh.Config()
    config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("scouting/gossip/enabled", "true" if mode == "peer" else "false")
    config.insert_json5("listen/endpoints", json.dumps(check_endpoints(list(listen), allow_remote)))
    config.insert_json5("connect/endpoints", json.dumps(check_endpoints(list(connect), allow_remote)))
    if tls is not None:
        config.insert_json5("transport/link/tls", json.dumps(_tls_section(tls)))
    if access_control is not None:
        config.insert_json5("access_control", json.dumps(access_control))
    if timestamping:
        config.insert_json5("timestamping/enabled", json.dumps({"router": True, "peer": True, "client": True}))
    return config


def open_session(mode: str = "peer", listen: list[str] = (), connect: list[str] = (),
                 allow_remote: bool = False, tls: TlsIdentity | None = None,
                 access_control: dict | None = None, timestamping: bool = False) -> zenoh.Session:
    """Open a Zenoh session with the safe config (see module docstring). A session that cannot be opened
    (a port in use, an unreadable certificate, no router to connect to) is a ConfigError saying why."""
    config = make_config(mode, listen, connect, allow_remote, tls, access_control, timestamping)
    try:
        return zenoh.open(config)
    except zenoh.ZError as exc:
        raise ConfigError(f"zenoh: cannot open a {mode} session (listen {list(listen)}, connect "
                          f"{list(connect)}): {str(exc).split(' at /')[0]}") from None


def await_liveliness(session: zenoh.Session, key: str, timeout: float) -> bool:
    """Wait until a liveliness token on key is visible to this session; False after timeout seconds.
    Peers do not forward, so a service's token is visible exactly when a one-off put would reach it."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if list(session.liveliness().get(key, timeout=0.3)):
            return True
        time.sleep(0.05)
    return False


WARM_SIZE = 32_768      # bytes: a message as large as the cell's largest (a trajectory: about 26 KB)
WARM_MESSAGES = 2       # delivered over a link: the second is the one Zenoh holds up
WARM_WAIT = 2.0         # s: the most the warm-up takes (the link's set-up included); then it gives up


def _ephemeral_port() -> int:
    """A loopback port from the kernel's ephemeral range, free now: never one a launcher hands out to the cell's
    services (``tools.launch.free_port`` keeps below that range), so a warm-up cannot take a service's port."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def warm_up_transport(size: int = WARM_SIZE, messages: int = WARM_MESSAGES, wait: float = WARM_WAIT) -> int:
    """Send `messages` messages of `size` bytes over a throwaway loopback link between two sessions of this process,
    then close both: how many were delivered (0 where the link could not be made in `wait` seconds; never raises).

    Why: in a process of eclipse-zenoh 1.10.2, the second message larger than about 4 KB that goes over any link
    blocks its ``put`` 10-40 ms and arrives 13-90 ms late, once (every earlier and later one: 0.1-2 ms). In the cell
    that was the planner's second trajectory, and the robot stood at its first goal 50-191 ms where it stands 10-52
    ms at every other. It is the process's, not the link's: after this, a new session's first large messages to
    another process go at once (``bench/transport.py``; docs/measurements.md, session 86). Call it before serving."""
    deadline = time.monotonic() + wait
    delivered = threading.Semaphore(0)
    count = 0
    sessions: list[zenoh.Session] = []
    try:
        port = _ephemeral_port()
        sessions.append(open_session("peer", listen=[f"tcp/127.0.0.1:{port}"]))
        sessions.append(open_session("peer", listen=[f"tcp/127.0.0.1:{_ephemeral_port()}"],
                                     connect=[f"tcp/127.0.0.1:{port}"]))
        subscriber = sessions[1].declare_subscriber("hrc/warm-up", lambda _sample: delivered.release())
        publisher = sessions[0].declare_publisher("hrc/warm-up")
        payload = bytes(size)
        while count < messages and time.monotonic() < deadline:
            publisher.put(payload)              # not delivered until the link and the subscriber are known: again
            if delivered.acquire(timeout=0.05):
                count += 1
                time.sleep(0.05)            # sent back to back, the second did not take the delay, and the next did
        subscriber.undeclare()
    except (ConfigError, zenoh.ZError, OSError):
        return count
    finally:
        for session in sessions:
            try:
                session.close()
            except zenoh.ZError:        # a throwaway session: nothing the service needs
                pass
    return count
