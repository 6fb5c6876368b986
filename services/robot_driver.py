"""robot_driver: the PRBT's six CiA 402 drives on CAN, commanded from Zenoh.

Thin shell around ``services.driver_core.DriverCore``:
* bring-up (canopen, blocking, before the loop): per node NMT reset communication and boot-up, heartbeat
  producer 100 ms (0x1017), identity (0x1018) and firmware (0x100A) over SDO, mode 7 (0x6060, checked on
  0x6061) and interpolation period (0x60C2:1), the PDO layout written with canopen's PDO configuration
  (invalidate, map, transmission type, validate), NMT start;
* a cycle thread at the SYNC period (default 10 ms; deadline sleeping, not asyncio's millisecond
  timers): the core's controlwords and setpoints go out as RPDO1 on every node, then SYNC; the drives'
  TPDOs come back and, as soon as every drive has answered the SYNC, the joint state is published on
  Zenoh (from the CAN thread, not a cycle later); every core event goes out as a SafetyEvent;
* a command that arrives while running goes on the bus at once (RPDO1 is synchronous: the drives take
  the latest setpoint at the next SYNC), clamped and rate-limited exactly as the cycle will, so a command
  waits for the SYNC inside the drive instead of in this process;
* asyncio main: Zenoh subscriptions (joint commands, stop / recover requests), liveliness token,
  SIGTERM. A malformed message is logged and dropped; the service goes on.

    python -m services.robot_driver --interface udp_multicast --listen tcp/127.0.0.1:7447
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import math
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass

import canopen
import numpy as np

from hwsim.drive import to_counts, to_rad
from hwsim.emulator import EDS_PATH, NODE_IDS
from services.driver_core import DriverCore, Feedback
from shared.canbus import BusError, describe, open_bus
from shared.errors import HrcError, MessageError
from shared.keys import KeySpace
from shared.messages import DriverRequest, JointCommand, JointState, SafetyEvent, decode, encode
from shared.robot_model import default_robot
from shared.zenoh_session import open_session

log = logging.getLogger("robot_driver")


@dataclass
class _NodeFeedback:
    statusword: int | None = None
    position: float = math.nan
    velocity: float = 0.0
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
        self._setpoint_vars = []
        self._fresh: set[int] = set()
        self.on_complete = None            # called (from the CAN thread) once every drive answered a SYNC
        self.completed = False             # set with each complete answer; the cycle clears it

    def bring_up(self, timeout: float = 10.0) -> None:
        for k, node in enumerate(self.nodes):
            self._reset_communication(node, timeout)
            node.sdo[0x1017].raw = 100
            ident = {"node": node.id, "vendor": node.sdo[0x1018][1].raw, "product": node.sdo[0x1018][2].raw,
                     "revision": node.sdo[0x1018][3].raw, "serial": node.sdo[0x1018][4].raw,
                     "firmware": node.sdo[0x100A].raw}
            self.identity.append(ident)
            node.sdo[0x6060].raw = 7
            node.sdo[0x60C2][1].raw = 10
            if node.sdo[0x6061].raw != 7:
                raise HrcError(f"node {node.id} did not take interpolated position mode")
            node.tpdo.read(from_od=True)
            node.rpdo.read(from_od=True)
            node.tpdo.save()
            node.rpdo.save()
            for n in (1, 3):
                node.tpdo[n].add_callback(lambda m, k=k: self._on_tpdo(k, m))
            node.nmt.add_heartbeat_callback(lambda state, k=k: self._on_heartbeat(k))
            node.emcy.add_callback(lambda entry, k=k: self._on_emcy(k, entry))
            rpdo = node.rpdo[1]
            self._setpoint_vars.append(({(v.index, v.subindex): v for v in rpdo}, rpdo))
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
            node.nmt.send_command(0x82)
            if not booted.wait(timeout):
                raise HrcError(f"node {node.id}: no boot-up within {timeout:.0f} s of a communication reset")
        finally:
            self.network.unsubscribe(0x700 + node.id, on_frame)

    def _on_tpdo(self, k: int, pdo_map) -> None:
        complete = False
        with self.lock:
            fb = self.feedback_raw[k]
            for v in pdo_map:
                if v.index == 0x6041:
                    fb.statusword = int(v.raw)
                elif v.index == 0x6064:
                    fb.position = to_rad(int(v.raw))
                    self._fresh.add(k)
                elif v.index == 0x606C:
                    fb.velocity = to_rad(int(v.raw))
            if len(self._fresh) == len(self.nodes):
                self._fresh.clear()
                complete = self.completed = True
                positions = np.array([f.position for f in self.feedback_raw])
                velocities = np.array([f.velocity for f in self.feedback_raw])
        if complete and self.on_complete is not None:
            self.on_complete(positions, velocities)

    def _on_heartbeat(self, k: int) -> None:
        with self.lock:
            self.feedback_raw[k].heartbeat = time.monotonic()

    def _on_emcy(self, k: int, entry) -> None:
        with self.lock:
            if entry.code:
                self.feedback_raw[k].emcy = entry.code
        log.warning("node %d EMCY 0x%04X", self.nodes[k].id, entry.code)

    def feedback(self, now: float) -> list[Feedback]:
        with self.lock:
            out = [Feedback(fb.statusword, fb.position, fb.velocity, now - fb.heartbeat, fb.emcy)
                   for fb in self.feedback_raw]
            for fb in self.feedback_raw:
                fb.emcy = None
        return out

    def send(self, controlwords: list[int] | None, setpoints: np.ndarray, sync: bool = True) -> None:
        """RPDO1 (controlword, IP setpoint) to every node, then SYNC. controlwords None: keep the last ones
        (an early setpoint between SYNCs; the drives take the latest at the next SYNC)."""
        with self.send_lock:
            for k, ((variables, rpdo), sp) in enumerate(zip(self._setpoint_vars, setpoints)):
                if controlwords is not None:
                    variables[(0x6040, 0)].raw = int(controlwords[k])
                if math.isfinite(sp):
                    variables[(0x60C1, 1)].raw = to_counts(float(sp))
                rpdo.transmit()
            if sync:
                self.network.sync.transmit()

    def shutdown(self) -> None:
        for node in self.nodes:
            try:
                node.nmt.state = "PRE-OPERATIONAL"
            except Exception:                 # best effort on the way out
                pass
        self.network.disconnect()


class Driver:
    """Ties the master, the core and Zenoh together."""

    def __init__(self, master: CanMaster, core: DriverCore, session, keys: KeySpace, period: float) -> None:
        self.master, self.core, self.session, self.keys, self.period = master, core, session, keys, period
        self.core_lock = threading.Lock()
        self.stop = threading.Event()
        self.state_pub = session.declare_publisher(keys.joint_state)
        self.event_pub = session.declare_publisher(keys.safety_events)
        self.seq = 0
        self.pub_lock = threading.Lock()
        self.last_output = None
        self.bad_messages = 0
        master.on_complete = self.publish_state

    def _decode(self, sample, kind):
        """The message in a Zenoh sample, or None after logging why it was dropped (the service goes on)."""
        try:
            return decode(sample.payload.to_bytes(), kind)
        except MessageError as exc:
            self.bad_messages += 1
            log.error("dropped a bad %s on %s: %s", kind.KIND, sample.key_expr, exc)
            return None

    def on_command(self, sample) -> None:
        msg = self._decode(sample, JointCommand)
        if msg is None:
            return
        with self.core_lock:
            early = self.core.command(msg.q, time.monotonic())
        if early is not None:           # on the bus now; the drives take the latest setpoint at the next SYNC
            self.master.send(None, early, sync=False)

    def on_request(self, sample) -> None:
        msg = self._decode(sample, DriverRequest)
        if msg is None:
            return
        log.info("request %s from %s", msg.action, msg.source)
        with self.core_lock:
            self.core.request(msg.action)

    def _publish_event(self, event) -> None:
        with self.pub_lock:
            self.seq += 1
            self.event_pub.put(encode(SafetyEvent(source="robot_driver", event=event.event, severity=event.severity,
                                                  text=event.text, seq=self.seq, stamp=time.monotonic())))
        (log.warning if event.severity != "info" else log.info)("%s: %s", event.event, event.text)

    def run_cycles(self) -> None:
        try:       # best effort: a real-time class for this thread where the OS permits it
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(50))
        except (AttributeError, OSError, PermissionError):
            pass
        deadline = time.monotonic()
        while not self.stop.is_set():
            deadline += self.period
            # sleep to the deadline (clock_nanosleep: tens of microseconds late); no spinning, which would
            # hold the GIL while a command or a drive's answer waits for it
            remaining = deadline - time.monotonic()
            if remaining > 0:
                time.sleep(remaining)
            now = time.monotonic()
            if now - deadline > self.period:          # overran (e.g. the process was stopped): resync
                deadline = now
            feedback = self.master.feedback(now)
            with self.master.lock:
                answered, self.master.completed = self.master.completed, False
            if not answered:       # a drive did not answer the last SYNC: publish what there is, never go silent
                self.publish_state(np.array([fb.position for fb in feedback]), np.array([fb.velocity for fb in feedback]))
            with self.core_lock:
                out = self.core.cycle(now, feedback)
            self.master.send(out.controlwords, out.setpoints)
            self.last_output = out
            for event in out.events:
                self._publish_event(event)

    def publish_state(self, q: np.ndarray, qd: np.ndarray) -> None:
        """Every drive has answered this SYNC: the joint state goes out now (from the CAN thread)."""
        out = self.last_output
        if out is None or not np.all(np.isfinite(q)):
            return
        states = sorted({s.value for s in out.drive_states})
        with self.pub_lock:
            self.seq += 1
            self.state_pub.put(encode(JointState(
                q=q, qd=qd, drive_state=f"{out.mode.value}:{'/'.join(states)}", enabled=out.mode.value == "running",
                fault=any(s.value == "fault" for s in out.drive_states), seq=self.seq, stamp=time.monotonic())))


async def serve(args: argparse.Namespace) -> int:
    keys = KeySpace(args.prefix)
    bus = open_bus(args.interface, args.channel)
    print(f"robot_driver: CANopen master on {describe(args.interface, args.channel)}, SYNC every "
          f"{args.period * 1000:.1f} ms", flush=True)
    master = CanMaster(bus)
    await asyncio.to_thread(master.bring_up)
    session = open_session("peer", listen=args.listen, connect=args.connect)
    core = DriverCore(default_robot().limits, args.period, args.command_timeout)
    driver = Driver(master, core, session, keys, args.period)
    subs = [session.declare_subscriber(keys.command, driver.on_command),
            session.declare_subscriber(keys.driver_request, driver.on_request)]
    token = session.liveliness().declare_token(keys.alive("robot_driver"))
    thread = threading.Thread(target=driver.run_cycles, name="can-cycle", daemon=True)
    thread.start()
    loop = asyncio.get_running_loop()
    stopped = asyncio.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, stopped.set)
    print("robot_driver: drives up, " + ", ".join(f"node {i['node']} fw {i['firmware']!r}" for i in master.identity),
          flush=True)
    await stopped.wait()
    driver.stop.set()
    thread.join(1.0)
    for sub in subs:
        sub.undeclare()
    token.undeclare()
    master.shutdown()
    session.close()
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="robot_driver", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--interface", default="udp_multicast")
    parser.add_argument("--channel", default=None)
    parser.add_argument("--prefix", default="hrc/cell1")
    parser.add_argument("--listen", nargs="*", default=["tcp/127.0.0.1:7447"])
    parser.add_argument("--connect", nargs="*", default=[])
    parser.add_argument("--period", type=float, default=0.01, help="SYNC period (s), default 0.01")
    parser.add_argument("--command-timeout", type=float, default=0.05,
                        help="a command older than this stops the drives (s), default 0.05")
    parser.add_argument("--log-level", default="INFO")
    args = parser.parse_args(argv)
    logging.basicConfig(level=args.log_level.upper(), format="%(asctime)s %(name)s %(levelname)s %(message)s")
    # Python hands the GIL over every 5 ms by default: a Zenoh or CAN callback thread could make the SYNC
    # thread wait that long. 0.5 ms keeps the SYNC within a fraction of a millisecond of its deadline.
    sys.setswitchinterval(0.0005)
    try:
        return asyncio.run(serve(args))
    except (BusError, HrcError) as exc:
        print(f"robot_driver: error: {exc}", file=sys.stderr)
        return 2
    except (canopen.SdoCommunicationError, canopen.nmt.NmtError) as exc:
        print(f"robot_driver: error: a drive did not answer: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
