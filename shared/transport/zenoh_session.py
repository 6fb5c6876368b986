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
    import time

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if list(session.liveliness().get(key, timeout=0.3)):
            return True
        time.sleep(0.05)
    return False
