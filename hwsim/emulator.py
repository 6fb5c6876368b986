"""The PRBT emulator process: six CiA 402 drives (node ids 3 to 8) on a CAN bus.

Each node is a canopen LocalNode built from the drive's EDS (``shared/drives/prbt_drive.eds``: SDO server,
NMT slave, heartbeat producer from 0x1017, EMCY producer) around a pure ``hwsim.drive.Drive``. RPDO1
(controlword, setpoint) is applied on reception; every SYNC completes each drive's interpolation period
and sends TPDO1 (statusword, mode display), TPDO2 (position demand 0x6062, following error 0x60F4) and
TPDO3 (position, velocity actual), the values of the SYNC instant, packed with the mapping's layout
(shared.drives.pdo_layout); an SDO read of a reported value answers the drive's value at that moment; a timer
runs the SYNC watchdog between SYNCs. The following error window (0x6065, counts) and time-out (0x6066,
ms) are read and written over SDO. Every fault is announced by an EMCY with the error register (0x1001)
set; a frozen node sends the EMCYs of faults it entered while frozen when it is unfrozen. Fault injection
through SDO writes to 0x2F00 (any time):
:1 drop that many per mille of the node's frames (a SYNC it loses: its drive runs that period on its own clock,
holding the last setpoint; ``Drive.on_missed_sync``), :2 heartbeat off, :3 freeze the node (no PDO, no
heartbeat; SDO still answers so it can be unfrozen), :4 raise a drive fault.

    python -m hwsim --interface udp_multicast            # only inside a private network namespace
    python -m hwsim --interface socketcan --channel vcan0
"""

from __future__ import annotations

import argparse
import logging
import random
import signal
import sys
import threading
import time

import canopen
import numpy as np

from hwsim.drive import Drive, DriveLimits
from shared.drives.bus import BusError, describe, open_bus
from shared.drives.pdo_layout import PdoLayout, PdoLayoutError
from shared.drives.prbt import (
    COUNTS_PER_RAD,
    EDS_PATH,
    EMCY_DRIVE_FAULT,
    FAULT_INJECTION,
    INJECT_DRIVE_FAULT,
    INJECT_DROP,
    INJECT_FREEZE,
    INJECT_HEARTBEAT_OFF,
    NODE_IDS,
    PERIOD,
    error_register,
    to_counts,
)
from shared.robot.model import default_robot
from shared.robot.poses import PAPER_START
from shared.scheduling import freeze_heap, name_callback_thread, realtime, sleep_until

log = logging.getLogger("hwsim")
WATCHDOG_STEP = 0.005        # s: the braking step of a fault reaction on the drives' own clock (no SYNC)


class EmulatedNode:
    """One drive on the bus: glue between canopen's LocalNode and the pure Drive."""

    def __init__(self, network: canopen.Network, node_id: int, limits: DriveLimits, position: float,
                 rng: random.Random) -> None:
        self.id = node_id
        self.drive = Drive(limits)
        self.drive.boot(position)
        self.node = canopen.LocalNode(node_id, canopen.import_od(str(EDS_PATH), node_id))
        network.add_node(self.node)
        # re-entrant, defensively: the node's own values bypass the write callbacks (_store), but an SDO
        # write from the bus runs them on the same thread that may already hold this lock
        self.lock = threading.RLock()
        self.rng = rng
        self.drop = 0.0
        self.frozen = False
        self._unannounced: list[int] = []              # EMCY codes of faults entered while frozen
        self.syncs = 0
        # CiA 301 transmission type of each TPDO (0x1800+n-1:2): 1-240 = every that many SYNCs
        self.every = {n: int(self.node.sdo[0x1800 + n - 1][2].raw) for n in (1, 2, 3)}
        self.node.sdo[0x607D][1].raw = to_counts(limits.lower)
        self.node.sdo[0x607D][2].raw = to_counts(limits.upper)
        self.node.sdo[0x6065].raw = to_counts(limits.following_window)
        self.node.sdo[0x6066].raw = int(round(limits.following_timeout * 1000))
        self.node.add_write_callback(self._on_sdo_write)
        self.node.add_read_callback(self._on_sdo_read)
        self.node.rpdo.read(from_od=True)
        self.node.tpdo.read(from_od=True)
        self.rpdo1 = PdoLayout.of(self.node.rpdo[1])
        self.tpdos = {n: PdoLayout.of(self.node.tpdo[n]) for n in (1, 2, 3)}
        self.node.rpdo[1].add_callback(self._on_rpdo1)
        network.subscribe(0, self._on_nmt)               # after the NMT slave's own handler
        self._boot()

    def _boot(self) -> None:
        """Boot-up message, then pre-operational (canopen's NMT slave starts the heartbeat on that)."""
        self.node.network.send_message(0x700 + self.id, [0])
        self.node.nmt.state = "PRE-OPERATIONAL"

    def _on_nmt(self, can_id: int, data: bytes, timestamp: float) -> None:
        """canopen's NMT slave sets INITIALISING on a reset and stops there: finish the reset."""
        if len(data) < 2 or data[1] not in (0, self.id) or data[0] not in (0x81, 0x82) or self.frozen:
            return
        if data[0] == 0x81:                              # reset node: the application restarts too
            with self.lock:
                self.drive.boot(self.drive.position)
                self.drive.mode = 0
        self._boot()

    def _lost(self) -> bool:
        return self.frozen or (self.drop > 0 and self.rng.random() < self.drop)

    def _on_rpdo1(self, pdo_map) -> None:
        if self._lost():
            return
        try:
            values = self.rpdo1.unpack(pdo_map.data)
        except PdoLayoutError as exc:                    # a frame of the wrong length: as a drive, ignore it
            log.warning("node %d: %s", self.id, exc)
            return
        with self.lock:
            if (0x6040, 0) in values:
                self._emcy(self.drive.on_controlword(int(values[(0x6040, 0)])))
            if (0x60C1, 1) in values:
                self.drive.on_setpoint(int(values[(0x60C1, 1)]))

    def _on_sdo_write(self, index: int, subindex: int, od, data: bytes) -> None:
        value = od.decode_raw(data)
        with self.lock:
            if index == 0x6040:
                self._emcy(self.drive.on_controlword(int(value)))
            elif index == 0x6060:
                self.drive.mode = int(value)
            elif index == 0x60C1 and subindex == 1:
                self.drive.on_setpoint(int(value))
            elif index == 0x6065:
                self.drive.limits.following_window = int(value) / COUNTS_PER_RAD
            elif index == 0x6066:
                self.drive.limits.following_timeout = int(value) / 1000.0
            elif index == FAULT_INJECTION:
                self._inject(subindex, int(value))
            elif 0x1800 <= index <= 0x1802 and subindex == 2:
                self.every[index - 0x1800 + 1] = int(value)

    def _inject(self, subindex: int, value: int) -> None:
        if subindex == INJECT_DROP:
            self.drop = min(max(value, 0), 1000) / 1000.0
        elif subindex == INJECT_HEARTBEAT_OFF:
            self.node.nmt.stop_heartbeat() if value else self.node.nmt.start_heartbeat(self.node.sdo[0x1017].raw)
        elif subindex == INJECT_FREEZE:
            self.frozen = bool(value)
            if value:
                self.node.nmt.stop_heartbeat()
            else:             # a hung node resumes: its SYNC watchdog restarts with the next SYNC
                self.drive.last_sync = None
                self.node.nmt.start_heartbeat(self.node.sdo[0x1017].raw)
                codes, self._unannounced = self._unannounced, []
                self._emcy(codes)                        # what it entered while hung, announced now
        elif subindex == INJECT_DRIVE_FAULT and value:
            self._emcy(self.drive.raise_fault(EMCY_DRIVE_FAULT))
        log.info("node %d: fault injection 0x2F00:%d = %d", self.id, subindex, value)

    def _emcy(self, codes: list[int]) -> None:
        """Announce each code with its error register (0 after a reset); a frozen node is silent and keeps
        them for when it resumes, so that no fault goes unannounced."""
        if self.frozen:
            self._unannounced += [c for c in codes if c]
            return
        for code in codes:
            register = error_register(code)
            self.node.emcy.send(code, register)
            self._store(0x1001, 0, register)
            log.warning("node %d: EMCY 0x%04X (%s)", self.id, code, self.drive.state.value)

    def _store(self, index: int, subindex: int, value: int) -> None:
        """Put one of the node's own values into its object dictionary, where SDO reads find it. Not through
        the SDO path: that would run the write callbacks, which are for writes that come from the bus."""
        obj = self.node.object_dictionary[index]
        obj = obj[subindex] if subindex else obj
        self.node.data_store.setdefault(index, {})[subindex] = obj.encode_raw(value)

    def _reported(self) -> dict[tuple[int, int], int]:
        """The drive's reported values (what the TPDOs carry and an SDO read of them answers)."""
        d = self.drive
        return {(0x6041, 0): d.statusword(), (0x6061, 0): d.mode, (0x6064, 0): to_counts(d.position),
                (0x606C, 0): to_counts(d.velocity_actual), (0x606B, 0): to_counts(d.velocity),
                (0x6062, 0): to_counts(d.position_demand), (0x60F4, 0): to_counts(d.following_error)}

    def _on_sdo_read(self, index: int, subindex: int, od) -> int | None:
        """An SDO read of a reported value answers the drive's value now (None: the object dictionary's)."""
        with self.lock:
            return self._reported().get((index, subindex))

    def on_sync(self, now: float) -> None:
        if self._lost():                  # a SYNC this node did not receive: its drive's own clock goes on
            if not self.frozen:
                with self.lock:
                    self.drive.on_missed_sync()
            return
        with self.lock:
            self._emcy(self.drive.on_sync(now))
            values = self._reported()
        self.syncs += 1
        if self.node.nmt.state != "OPERATIONAL":
            return
        for n, layout in self.tpdos.items():
            if 1 <= self.every[n] <= 240 and self.syncs % self.every[n]:
                continue
            for key in layout.keys:          # an object mapped that the drive does not report: as stored
                if key not in values:
                    values[key] = self.node.sdo[key[0]][key[1]].raw
            if not self._lost():
                self.node.network.send_message(layout.cob_id, layout.pack(values))

    def watchdog(self, now: float) -> None:
        if self.frozen:
            return
        with self.lock:
            self._emcy(self.drive.watchdog(now))


def next_watchdog(drives: list[Drive], now: float) -> float:
    """How long (s) the watchdog thread may sleep: until the first drive's SYNC time-out could pass (every
    SYNC moves it on, so a running bus wakes the thread once a time-out, not every few milliseconds: a
    wake-up costs this machine a cold cache), or its next braking step while a fault reaction brakes
    without SYNC; half a time-out when nothing is due (no SYNC yet, not powered)."""
    dues = [due for d in drives if (due := d.watchdog_due(WATCHDOG_STEP)) is not None]
    if not dues:
        return 0.5 * min((d.limits.sync_timeout for d in drives), default=PERIOD)
    return sleep_until(min(dues), now)


def build_limits(period: float) -> list[DriveLimits]:
    lim = default_robot().limits
    return [DriveLimits(float(lo), float(hi), float(v), float(a), period)
            for lo, hi, v, a in zip(lim.lower, lim.upper, lim.velocity, lim.monitor_acceleration)]


def run(interface: str, channel: str | None, start: np.ndarray, seed: int, stop: threading.Event) -> None:
    scheduling = realtime("hwsim")          # before the bus: canopen's receive thread inherits it
    bus = open_bus(interface, channel)
    network = canopen.Network(bus)
    network.connect()
    rng = random.Random(seed)
    nodes = [EmulatedNode(network, nid, lim, float(q), rng)
             for nid, lim, q in zip(NODE_IDS, build_limits(PERIOD), start)]

    def on_sync(can_id: int, data: bytes, timestamp: float) -> None:
        name_callback_thread("can-receive")          # canopen's receive thread, in top -H and the CPU bench
        for n in nodes:
            n.on_sync(time.monotonic())

    network.subscribe(0x80, on_sync)
    freeze_heap()                           # the drives and their object dictionaries are built: keep them frozen
    print(f"hwsim: PRBT emulator, nodes {NODE_IDS[0]}-{NODE_IDS[-1]} on {describe(interface, channel)}, {scheduling}",
          flush=True)
    try:
        while not stop.wait(next_watchdog([n.drive for n in nodes if not n.frozen], time.monotonic())):
            now = time.monotonic()
            for n in nodes:
                n.watchdog(now)
    finally:
        for n in nodes:
            n.node.nmt.stop_heartbeat()
        network.disconnect()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="hwsim", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--interface", default="udp_multicast", help="python-can interface (default udp_multicast)")
    parser.add_argument("--channel", default=None, help="channel (vcan0, can0, or a multicast group)")
    parser.add_argument("--start", type=float, nargs=6, default=PAPER_START.tolist(),
                        metavar="Q", help="joint positions at power-up (rad)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the frame-dropping fault injection")
    parser.add_argument("--log-level", default="WARNING")
    args = parser.parse_args(argv)
    logging.basicConfig(level=args.log_level.upper(), format="%(asctime)s hwsim %(levelname)s %(message)s")
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    try:
        run(args.interface, args.channel, np.array(args.start), args.seed, stop)
    except BusError as exc:
        print(f"hwsim: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
