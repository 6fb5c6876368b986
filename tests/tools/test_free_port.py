"""tools.launch.free_port: the loopback ports the cell's services listen on."""

import socket

from tools import launch


def test_a_port_is_free_below_the_ephemeral_range_and_never_handed_out_twice():
    """A port the kernel picks for bind(0) is ephemeral: it may become the local end of an outgoing connection
    before the service listens on it. So the ports come from below that range, each one once."""
    low = int(launch.EPHEMERAL.read_text().split()[0])
    ports = [launch.free_port() for _ in range(50)]
    assert len(set(ports)) == 50
    assert all(low // 2 <= p < low for p in ports)
    for port in ports[:5]:                                   # free: a listener binds it
        with socket.socket() as s:
            s.bind(("127.0.0.1", port))
            s.listen()


def test_a_port_in_use_is_passed_over(monkeypatch):
    """A port another socket holds is not handed out: the next free one is."""
    low = int(launch.EPHEMERAL.read_text().split()[0])
    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        taken = held.getsockname()[1]
        choices = iter([taken, taken, low // 2 + 7])         # the taken one twice, then another
        monkeypatch.setattr(launch.random.SystemRandom, "randrange", lambda self, a, b: next(choices))
        monkeypatch.setattr(launch, "_GIVEN", set())
        assert launch.free_port() == low // 2 + 7
