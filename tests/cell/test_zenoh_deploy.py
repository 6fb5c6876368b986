"""Zenoh deployment: the safe config, the shipped config files, and clients meeting through the router."""

import subprocess
import sys
import time

import pytest

from shared.core.errors import ConfigError
from shared.transport.zenoh_session import check_endpoints, open_session
from tests.util import ROOT, free_port


@pytest.mark.parametrize("endpoint", ["tcp/10.0.0.5:7447", "tcp/0.0.0.0:7447", "udp/127.0.0.1:7447",
                                      "tcp/[::]:7447", "tcp/example.com:7447"])
def test_only_loopback_unless_allowed(endpoint):
    with pytest.raises(ConfigError):
        check_endpoints([endpoint])


def test_shipped_configs_keep_multicast_scouting_off():
    import json

    import zenoh

    paths = sorted((ROOT / "deploy" / "zenoh").glob("*.json5"))
    assert len(paths) >= 4
    for path in paths:                     # parsed as zenoh parses them, whatever the JSON5 style
        config = zenoh.Config.from_file(str(path))
        assert json.loads(config.get_json("scouting/multicast/enabled")) is False, path
        for kind in ("listen", "connect"):          # as shipped, loopback only (the cell's address goes in there)
            endpoints = json.loads(config.get_json(f"{kind}/endpoints"))
            if isinstance(endpoints, dict):         # zenoh's per-mode form ({"router": [...], "peer": [...]})
                endpoints = [e for per_mode in endpoints.values() for e in per_mode or []]
            assert check_endpoints(endpoints) == endpoints, path


def test_two_clients_meet_through_the_router():
    port = free_port()
    router = subprocess.Popen([sys.executable, "-m", "services.router", "--listen", f"tcp/127.0.0.1:{port}",
                               "--prefix", "t/cell"], cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        assert "router: Zenoh router" in router.stdout.readline()
        a = open_session("client", connect=[f"tcp/127.0.0.1:{port}"])
        b = open_session("client", connect=[f"tcp/127.0.0.1:{port}"])
        got = []
        sub = b.declare_subscriber("t/cell/ping", lambda s: got.append(s.payload.to_bytes()))
        pub = a.declare_publisher("t/cell/ping")
        deadline = time.monotonic() + 5
        while not got and time.monotonic() < deadline:
            pub.put(b"hello")
            time.sleep(0.05)
        assert got and got[0] == b"hello"
        assert list(a.liveliness().get("t/cell/alive/router", timeout=2.0))     # the router announces itself
        sub.undeclare()
        a.close()
        b.close()
    finally:
        router.terminate()
        router.wait(5)


def test_the_transport_warm_up_delivers_its_messages_over_a_link_and_never_raises(monkeypatch):
    """warm_up_transport sends its large messages over a real loopback link of this process (each delivered, so
    the one Zenoh holds up has gone: bench/transport.py measures what that saves); where no link can be made it gives
    up in its time and says 0, for a service must start all the same."""
    from shared.transport import zenoh_session

    assert zenoh_session.warm_up_transport(size=8192, messages=2, wait=5.0) == 2

    def refused(*args, **kwargs):
        raise ConfigError("zenoh: cannot open a peer session (a port in use)")

    monkeypatch.setattr(zenoh_session, "open_session", refused)
    assert zenoh_session.warm_up_transport(wait=0.5) == 0
