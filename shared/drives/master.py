"""The CANopen master of the PRBT's six CiA 402 drives (python-canopen underneath): bring-up over NMT and SDO,
the PDO layout, one RPDO1 per drive and a SYNC per cycle, and the drives' TPDOs, heartbeats and EMCYs collected
as ``shared.drives.driver_core.Feedback``. No policy: what to command is the driver core's (``DriverCore``), and
the robot driver service (``services.robot_driver``) is the shell that ties both to Zenoh.

Bring-up, per node: NMT reset communication and boot-up, heartbeat producer 100 ms (0x1017), identity (0x1018)
and firmware (0x100A) over SDO, mode 7 (0x6060, checked on 0x6061), interpolation period (0x60C2:1), following
error window and time-out (0x6065, 0x6066, from shared.drives.prbt), the PDO layout written with canopen's PDO
configuration (invalidate, map, transmission type, validate; TPDO2, the following error, every 10th SYNC), NMT
start.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass

import canopen
import numpy as np

from shared.core.errors import HrcError
from shared.drives.answer_windows import AnswerWindows
from shared.drives.driver_core import Feedback
from shared.drives.pdo_layout import PdoLayout, PdoLayoutError
from shared.drives.prbt import (
    DIAGNOSTIC_EVERY,
    EDS_PATH,
    FOLLOWING_TIMEOUT,
    FOLLOWING_WINDOW,
    MODE_IP,
    NODE_IDS,
    PERIOD,
    describe_emcy,
    to_counts,
    to_rad,
)
from shared.scheduling import name_callback_thread

log = logging.getLogger("canopen_master")

NMT_RESET_COMMUNICATION = 0x82
HEARTBEAT_MS = 100
INTERPOLATION_PERIOD_MS = int(round(PERIOD * 1000))   # 0x60C2:1, with the index -3 (ms)


@dataclass
class _NodeFeedback:
    statusword: int | None = None
    position: float = math.nan
    velocity: float = 0.0
    following_error: float = 0.0
    heartbeat: float = -math.inf
    emcy: int | None = None


class CanMaster:
    """The CANopen master side: bring-up, per-cycle RPDO + SYNC, TPDO / heartbeat / EMCY collection."""

    def __init__(self, bus, node_ids=NODE_IDS) -> None:
        self.network = canopen.Network(bus)
        self.network.connect()
        self.nodes = []
        for nid in node_ids:
            node = canopen.RemoteNode(nid, canopen.import_od(str(EDS_PATH), nid))
            self.network.add_node(node)
            self.nodes.append(node)
        self.feedback_raw = [_NodeFeedback() for _ in node_ids]
        self.lock = threading.Lock()
        self.send_lock = threading.Lock()          # the cycle and early commands both write RPDO1
        self.identity: list[dict] = []
        self._rpdo1: list[PdoLayout] = []                 # per node, its RPDO1 layout
        self._rpdo1_values: list[dict] = []               # per node, the values its next RPDO1 carries
        self._fresh: set[int] = set()
        self._fresh_error = False          # a following error arrived since following_errors() last asked
        self._since_sync: dict[int, bytes] = {}       # node -> the RPDO1 data sent to it since the last SYNC
        self.on_complete = None            # called (from the CAN thread) once every drive answered the latest SYNC
        self.completed = False             # set with each complete answer; the cycle clears it
        self.syncs = 0                     # SYNCs sent so far: the latest one's number
        self.windows = AnswerWindows(len(node_ids), PERIOD)   # which SYNC each answer belongs to, by its stamp

    def bring_up(self, timeout: float = 10.0) -> None:
        for k, node in enumerate(self.nodes):
            self._reset_communication(node, timeout)
            node.sdo[0x1017].raw = HEARTBEAT_MS
            ident = {"node": node.id, "vendor": node.sdo[0x1018][1].raw, "product": node.sdo[0x1018][2].raw,
                     "revision": node.sdo[0x1018][3].raw, "serial": node.sdo[0x1018][4].raw,
                     "firmware": node.sdo[0x100A].raw}
            self.identity.append(ident)
            node.sdo[0x6060].raw = MODE_IP
            node.sdo[0x60C2][1].raw = INTERPOLATION_PERIOD_MS
            node.sdo[0x6065].raw = to_counts(FOLLOWING_WINDOW)
            node.sdo[0x6066].raw = int(round(FOLLOWING_TIMEOUT * 1000))
            if node.sdo[0x6061].raw != MODE_IP:
                raise HrcError(f"node {node.id} did not take interpolated position mode")
            node.tpdo.read(from_od=True)
            node.rpdo.read(from_od=True)
            node.tpdo[2].trans_type = DIAGNOSTIC_EVERY        # the following error at 10 Hz (prbt.DIAGNOSTIC_EVERY)
            node.tpdo.save()
            node.rpdo.save()
            for n in (1, 2, 3):
                layout = PdoLayout.of(node.tpdo[n])
                node.tpdo[n].add_callback(lambda m, k=k, layout=layout: self._on_tpdo(k, layout, m))
            node.nmt.add_heartbeat_callback(lambda state, k=k: self._on_heartbeat(k))
            node.emcy.add_callback(lambda entry, k=k: self._on_emcy(k, entry))
            self._rpdo1.append(PdoLayout.of(node.rpdo[1]))
            self._rpdo1_values.append({key: 0 for key in self._rpdo1[-1].keys})
            node.nmt.state = "OPERATIONAL"
            log.info("node %d up: %s", node.id, ident)
        for node in self.nodes:
            node.nmt.wait_for_heartbeat(2.0)

    def _reset_communication(self, node, timeout: float) -> None:
        """NMT reset communication, then wait for the boot-up. The listener is in place before the command:
        a drive answers within microseconds, before canopen's wait_for_bootup would start waiting."""
        booted = threading.Event()

        def on_frame(can_id: int, data: bytes, timestamp: float) -> None:
            if data[:1] == b"\x00":
                booted.set()

        self.network.subscribe(0x700 + node.id, on_frame)
        try:
            node.nmt.send_command(NMT_RESET_COMMUNICATION)
            if not booted.wait(timeout):
                raise HrcError(f"node {node.id}: no boot-up within {timeout:.0f} s of a communication reset")
        finally:
            self.network.unsubscribe(0x700 + node.id, on_frame)

    def _on_tpdo(self, k: int, layout: PdoLayout, pdo_map) -> None:
        name_callback_thread("can-receive")
        try:
            values = layout.unpack(pdo_map.data)
        except PdoLayoutError as exc:                  # a frame of the wrong length: no feedback from it
            log.warning("node %d: %s", self.nodes[k].id, exc)
            return
        complete = False
        with self.lock:
            fb = self.feedback_raw[k]
            for (index, _), value in values.items():
                if index == 0x6041:
                    fb.statusword = int(value)
                elif index == 0x6064:
                    fb.position = to_rad(int(value))
                    if not self._answered_before(k, getattr(pdo_map, "timestamp", None)):
                        self._fresh.add(k)
                elif index == 0x606C:
                    fb.velocity = to_rad(int(value))
                elif index == 0x60F4:
                    fb.following_error = to_rad(int(value))
                    self._fresh_error = True
            if len(self._fresh) == len(self.nodes):
                self._fresh.clear()
                complete = self.completed = True
                positions = np.array([f.position for f in self.feedback_raw])
                velocities = np.array([f.velocity for f in self.feedback_raw])
        if complete and self.on_complete is not None:
            self.on_complete(positions, velocities)

    def _answered_before(self, k: int, stamp: float | None) -> bool:
        """Node k's position answer, stamped `stamp`, answers a SYNC before the latest one (it was read late):
        counted for its own SYNC (``AnswerWindows``), never towards the latest one's state. Called with the lock."""
        if not self.windows.usable:
            return False
        number = self.windows.answer(k, stamp)
        return number is not None and number < self.syncs

    def answers_judged(self) -> list[bool] | None:
        """The SYNCs judged since the last call, in order: True where every drive's answer reached the machine
        within its period, however late it was read (``AnswerWindows``); None where the interface's stamps do
        not fit the SYNCs' clock (then only whether the answers had been read by the next SYNC can say)."""
        with self.lock:
            return self.windows.take() if self.windows.usable else None

    def _on_heartbeat(self, k: int) -> None:
        with self.lock:
            self.feedback_raw[k].heartbeat = time.monotonic()

    def _on_emcy(self, k: int, entry) -> None:
        with self.lock:
            if entry.code:
                self.feedback_raw[k].emcy = entry.code
        log.warning("node %d %s", self.nodes[k].id, describe_emcy(entry.code))

    def following_errors(self) -> np.ndarray | None:
        """The drives' last reported following errors (rad, 0x60F4), or None when none arrived since the
        last call (TPDO2 comes every DIAGNOSTIC_EVERY SYNCs: a value is counted once, not ten times)."""
        with self.lock:
            if not self._fresh_error:
                return None
            self._fresh_error = False
            return np.array([fb.following_error for fb in self.feedback_raw])

    def feedback(self, now: float) -> list[Feedback]:
        with self.lock:
            out = [Feedback(fb.statusword, fb.position, fb.velocity, now - fb.heartbeat, fb.emcy)
                   for fb in self.feedback_raw]
            for fb in self.feedback_raw:
                fb.emcy = None
        return out

    def send(self, controlwords: list[int] | None, setpoints: np.ndarray, sync: bool = True) -> None:
        """RPDO1 (controlword, IP setpoint) to every node, then SYNC. controlwords None: keep the last ones
        (an early setpoint between SYNCs; the drives take the latest at the next SYNC). A node that an early
        send has already given exactly this controlword and setpoint since the last SYNC is not sent it
        again: six frames a period fewer for every process on the bus."""
        with self.send_lock:
            for k, (layout, values, sp) in enumerate(zip(self._rpdo1, self._rpdo1_values, setpoints)):
                if controlwords is not None:
                    values[(0x6040, 0)] = int(controlwords[k])
                if math.isfinite(sp):
                    values[(0x60C1, 1)] = to_counts(float(sp))
                frame = layout.pack(values)
                if self._since_sync.get(k) == frame:
                    continue
                self.network.send_message(layout.cob_id, frame)
                self._since_sync[k] = frame
            if sync:
                with self.lock:         # the answers counted from here are this SYNC's: a drive that missed the
                    self._fresh.clear()     # last one does not complete it with the others' older positions
                    self.syncs += 1
                    self.windows.sync(self.syncs, time.time())     # its window opens before it goes out
                self.network.sync.transmit()
                self._since_sync = {}

    def shutdown(self) -> None:
        for node in self.nodes:
            try:
                node.nmt.state = "PRE-OPERATIONAL"
            except Exception:                 # best effort on the way out
                pass
        self.network.disconnect()
