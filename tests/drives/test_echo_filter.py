"""The udp_multicast bus's own-frame filter: echoes of this process's identifiers are dropped in the kernel
(shared.drives.echo_filter, a socket filter; shown in a namespace by tests/cell/test_echo_filter.py), and what
the kernel lets pass (a layout it does not know) is still dropped in Python (OwnFrameFilter)."""

from __future__ import annotations

import can

from shared.drives.bus import OwnFrameFilter
from shared.drives.echo_filter import MAX_IDS, echo_program


def test_what_the_kernel_lets_pass_is_still_dropped_in_python():
    bus = OwnFrameFilter(can.Bus(interface="virtual", channel="echo-test", receive_own_messages=True))
    try:
        bus.send(can.Message(arbitration_id=0x181, data=b"x", is_extended_id=False))
        assert bus.in_kernel is False         # the virtual bus has no socket: the kernel part gives way
        assert bus.recv(0.1) is None          # its own echo, dropped in Python
        other = can.Bus(interface="virtual", channel="echo-test")
        other.send(can.Message(arbitration_id=0x201, data=b"y", is_extended_id=False))
        msg = bus.recv(0.5)
        assert msg is not None and msg.arbitration_id == 0x201
        other.shutdown()
    finally:
        bus.shutdown()


def test_the_program_matches_at_most_max_ids_identifiers_and_always_ends_in_accept_then_drop():
    prog = echo_program(range(0x100, 0x100 + 3 * MAX_IDS))
    assert len(prog) < 256 + 40                # every jump offset fits its 8 bits
    assert prog[-2][-4:] == b"\xff\xff\xff\xff" and prog[-1][-4:] == b"\x00\x00\x00\x00"
    assert len(echo_program(range(5))) == len(echo_program([])) + 5
