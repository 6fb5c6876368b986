"""The PRBT joint drive as both ends of the bus know it: node ids, units, EDS, EMCY codes, and the limits
of what the drive follows. The robot driver (CANopen master) and the emulator both read this one module,
so the driver's idea of a followable setpoint and the drive's are the same numbers.

Facts (``../shared/prbt/FACTS.md`` sections 3-4): node ids 3-8, interpolated position mode (7), SYNC and
interpolation period 10 ms, setpoints in 0x60C1:1 at 0.001 degree per count, heartbeat 100 ms.

Chosen here (Pilz publishes no drive parameters), with the reason:

* ``FOLLOWING_WINDOW`` (0x6065) = 0.05 rad and ``FOLLOWING_TIMEOUT`` (0x6066) = 50 ms. The PRBT's
  trajectory controller aborts a motion whose path deviates by more than 0.157 rad (its path tolerance).
  A drive that is stuck or runs away at the full 1.57 rad/s crosses the window and then the time-out in
  0.05 + 1.57 x 0.05 = 0.13 rad < 0.157 rad: the drive faults before the controller would have noticed.
  A drive that follows followable setpoints keeps its following error near zero (one count), so the
  window is 3000 times the error of ordinary work and never trips it.
* Followable setpoints: consecutive setpoints whose implied velocity stays within the joint's velocity
  limit (1.57 rad/s) and whose velocity changes stay within the drive's acceleration (6.0 rad/s^2, the
  most the PRBT's controller tolerates: ``monitor_acceleration``). The driver never sends anything else
  (``shared.drives.driver_core.follow_step``).
"""

from __future__ import annotations

import math
from pathlib import Path

EDS_PATH = Path(__file__).parent / "prbt_drive.eds"
NODE_IDS = (3, 4, 5, 6, 7, 8)
COUNTS_PER_RAD = 180.0 / math.pi * 1000.0       # 0.001 degree per count
PERIOD = 0.01                                    # s: SYNC and interpolation period (0x60C2 = 10 x 10^-3 s)
MODE_IP = 7                                      # interpolated position mode (0x6060)

FOLLOWING_WINDOW = 0.05                          # rad (0x6065, in counts on the bus)
FOLLOWING_TIMEOUT = 0.05                         # s (0x6066, in ms on the bus)
# TPDO2 (position demand 0x6062, following error 0x60F4) every this many SYNCs (its transmission type,
# 0x1801:2): the driver only reports the following error (the drive itself watches it against 0x6065),
# so 10 Hz is enough, and the bus carries 12.6 TPDOs a SYNC instead of 18: at 1 Mbit/s its load falls
# from about 25 % to about 19 % (the processes' CPU did not change measurably: a frame costs microseconds)
DIAGNOSTIC_EVERY = 10

# EMCY error codes (CiA 301 / CiA 402) the drive sends; 0x0000 announces a fault reset
EMCY_RESET = 0x0000
EMCY_FOLLOWING = 0x8611          # following error beyond 0x6065 for longer than 0x6066
EMCY_LIMIT = 0x8612              # setpoint outside the software position limits (0x607D)
EMCY_SYNC_TIMEOUT = 0x8100       # no SYNC (communication)
EMCY_RPDO_TIMEOUT = 0x8250       # no new setpoint while interpolating
EMCY_DRIVE_FAULT = 0x5000        # device hardware (an injected fault)
# the emulator's fault-injection object (hwsim, over SDO): sub-index 1 drops that many per mille of the node's
# frames, 2 turns its heartbeat off, 3 freezes the node (no PDO, no heartbeat; SDO still answers), 4 raises a
# drive fault (each lifted by writing 0)
FAULT_INJECTION = 0x2F00
INJECT_DROP, INJECT_HEARTBEAT_OFF, INJECT_FREEZE, INJECT_DRIVE_FAULT = 1, 2, 3, 4
ERROR_REGISTER_GENERIC = 0x01    # 0x1001 bit 0, set with every fault's EMCY
ERROR_REGISTER_BITS = {EMCY_FOLLOWING: 0x01, EMCY_LIMIT: 0x01, EMCY_SYNC_TIMEOUT: 0x11,
                       EMCY_RPDO_TIMEOUT: 0x11, EMCY_DRIVE_FAULT: 0x01}   # 0x10: communication error


EMCY_MEANING = {EMCY_FOLLOWING: "following error beyond its window", EMCY_LIMIT: "setpoint beyond the position limits",
                EMCY_SYNC_TIMEOUT: "no SYNC within the drive's time-out", EMCY_RPDO_TIMEOUT: "no new setpoint",
                EMCY_DRIVE_FAULT: "drive fault"}


def describe_emcy(code: int) -> str:
    """An EMCY code as an operator reads it: 'EMCY 0x8100 (no SYNC within the drive's time-out)'."""
    meaning = EMCY_MEANING.get(code)
    return f"EMCY 0x{code:04X}" + (f" ({meaning})" if meaning else "")


def error_register(code: int) -> int:
    """The error register (0x1001) that goes with an EMCY code: 0 after a reset, else bit 0 (generic) and
    the class bit the code belongs to (communication for a lost SYNC or setpoint)."""
    return 0 if code == EMCY_RESET else ERROR_REGISTER_BITS.get(code, ERROR_REGISTER_GENERIC)


def to_counts(rad: float) -> int:
    """rad -> drive position counts (0.001 degree)."""
    return int(round(rad * COUNTS_PER_RAD))


def to_rad(counts: int) -> float:
    """drive position counts (0.001 degree) -> rad."""
    return counts / COUNTS_PER_RAD
