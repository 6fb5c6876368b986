"""The udp_multicast bus's own-frame filter: echoes of this process's identifiers are dropped in the kernel: the tests
that start a process or a network namespace (the rest, in-process, are in
tests/drives/test_echo_filter.py)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

from tests.util import ROOT, require_namespace
from tools.cell import in_new_namespace

PROBE = textwrap.dedent("""
    import time, can
    from shared.drives.bus import open_bus
    a, b = open_bus("udp_multicast"), open_bus("udp_multicast")
    for i in (0x00, 0x7F, 0x80, 0x181, 0x7FF):
        a.send(can.Message(arbitration_id=i, data=b"a", is_extended_id=False))
    b.send(can.Message(arbitration_id=0x582, data=b"b", is_extended_id=False))
    b.send(can.Message(arbitration_id=0x181, data=b"b", is_extended_id=False))
    def drain(bus):
        got = []
        while (m := bus._bus.recv(0.2)) is not None:       # the raw socket, under the Python filter
            got.append(f"{m.arbitration_id:x}:{bytes(m.data).decode()}")
        return got
    print(a.in_kernel, b.in_kernel)
    print(" ".join(drain(a)))
    print(" ".join(drain(b)))
    a.shutdown(); b.shutdown()
""")


def test_own_identifiers_are_dropped_in_the_kernel_and_every_other_frame_arrives():
    require_namespace("OwnFrameFilter's Python side is covered below on the virtual bus")
    out = subprocess.run(in_new_namespace([sys.executable, "-c", PROBE]), capture_output=True, text=True,
                         cwd=ROOT, timeout=60)
    assert out.returncode == 0, out.stderr
    in_kernel, at_a, at_b = out.stdout.splitlines()
    assert in_kernel == "True True"
    assert at_a.split() == ["582:b"]       # its own five never reached its socket; b's 0x181 is one of its own ids
    assert at_b.split() == ["0:a", "7f:a", "80:a", "181:a", "7ff:a"]       # a's, and none of its own
