"""A kernel socket filter that drops a udp_multicast bus's echoes of its own frames before Python sees them.

python-can's udp_multicast bus hands every frame sent on the group back to every socket on it, the
sender's own too. ``OwnFrameFilter`` drops those echoes, but only after the receiving thread has woken,
read the datagram, unpacked its msgpack and built a ``can.Message``: in the emulator, every frame it sends,
the larger share of its CAN receive thread's CPU. This module builds a classic BPF program
(``SO_ATTACH_FILTER``, no privilege needed) that reads the identifier where python-can's packing puts it
and drops the datagram in the kernel when it is one of this process's own identifiers.

Only an optimisation, never the rule: a datagram whose bytes are not laid out as expected (another
python-can version, an extended identifier) passes, and ``OwnFrameFilter`` still drops it in Python.

Layout (python-can ``pack_message``: a msgpack map of 11 entries, 'timestamp' then 'arbitration_id'):
payload[0] 0x8b, payload[1] 0xa9 + 'timestamp', payload[11] 0xcb + float64, payload[20] 0xae +
'arbitration_id', payload[35] the identifier (fixint; 0xcc + 1 byte; 0xcd + 2 bytes big-endian). A UDP
socket's filter sees the datagram from its UDP header on: the payload starts at byte 8.
"""

from __future__ import annotations

import ctypes
import socket
import struct
from collections.abc import Iterable

SO_ATTACH_FILTER = 26         # <asm-generic/socket.h>
MAX_IDS = 200                 # identifiers one program drops (jump offsets are 8 bit); more pass to Python

# classic BPF opcodes
_LDB, _LDH, _LDW = 0x30, 0x28, 0x20            # A = packet[k] (byte, half word, word; big-endian)
_JEQ, _JGE = 0x15, 0x35                        # if A == k / A >= k: skip jt else skip jf
_RET = 0x06
_ACCEPT, _DROP = 0xFFFFFFFF, 0

_UDP = 8                                       # the payload's offset behind the UDP header
_ARBI = int.from_bytes(b"arbi", "big")


def _insn(code: int, jt: int = 0, jf: int = 0, k: int = 0) -> bytes:
    return struct.pack("HBBI", code, jt, jf, k)


def echo_program(own_ids: Iterable[int]) -> list[bytes]:
    """The BPF instructions: drop a python-can udp_multicast datagram whose identifier is in own_ids,
    accept everything else (the first MAX_IDS identifiers below 0x10000 are matched)."""
    ids = sorted({int(i) for i in own_ids if 0 <= int(i) < 0x10000})[:MAX_IDS]
    header = [(_LDB, 0x8B, 0), (_LDB, 0xA9, 1), (_LDB, 0xCB, 11), (_LDB, 0xAE, 20), (_LDW, _ARBI, 21)]
    prog: list[tuple] = []
    # each header check: load, then jump to the final accept unless it matches
    for load, value, offset in header:
        prog.append(("ld", load, _UDP + offset))
        prog.append(("jne_accept", value))
    prog += [("ld", _LDB, _UDP + 35),             # the identifier's first byte
             ("jlt_fixint",),                     # < 0x80: it is the identifier (A already holds it)
             ("jeq_next", 0xCC, "one"), ("jeq_next", 0xCD, "two"), ("accept",),
             ("label", "one"), ("ld", _LDB, _UDP + 36), ("goto", "match"),
             ("label", "two"), ("ld", _LDH, _UDP + 36),
             ("label", "match")]
    prog += [("jeq_drop", i) for i in ids]
    prog += [("label", "accept"), ("accept",), ("label", "drop"), ("drop",)]
    return _assemble(prog)


def _assemble(prog: list[tuple]) -> list[bytes]:
    """Resolve the labels of the small assembly above into BPF instructions (jumps count forward)."""
    at: dict[str, int] = {}
    n = 0
    for op in prog:
        if op[0] == "label":
            at[op[1]] = n
        else:
            n += 1
    out, k = [], 0
    for op in prog:
        kind = op[0]
        if kind == "label":
            continue
        if kind == "ld":
            out.append(_insn(op[1], k=op[2]))
        elif kind == "jne_accept":
            out.append(_insn(_JEQ, 0, at["accept"] - k - 1, op[1]))
        elif kind == "jlt_fixint":
            out.append(_insn(_JGE, 0, at["match"] - k - 1, 0x80))
        elif kind == "jeq_next":
            out.append(_insn(_JEQ, at[op[2]] - k - 1, 0, op[1]))
        elif kind == "goto":
            out.append(_insn(0x05, k=at[op[1]] - k - 1))          # BPF_JMP | BPF_JA
        elif kind == "jeq_drop":
            out.append(_insn(_JEQ, at["drop"] - k - 1, 0, op[1]))
        elif kind == "accept":
            out.append(_insn(_RET, k=_ACCEPT))
        elif kind == "drop":
            out.append(_insn(_RET, k=_DROP))
        k += 1
    return out


def attach(fd: int, own_ids: Iterable[int]) -> None:
    """Attach (or replace) the echo filter on the socket with file descriptor fd. OSError when the
    kernel refuses it (the caller then goes on with the filter in Python alone)."""
    code = b"".join(echo_program(own_ids))
    buf = ctypes.create_string_buffer(code, len(code))
    fprog = struct.pack("HL", len(code) // 8, ctypes.addressof(buf))
    sock = socket.socket(fileno=socket.dup(fd))
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_ATTACH_FILTER, fprog)
    finally:
        sock.close()
