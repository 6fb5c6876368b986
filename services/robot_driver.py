"""robot_driver: the PRBT's six CiA 402 drives on CAN, commanded from Zenoh.

Thin shell around ``shared.drives.driver_core.DriverCore``:
* bring-up (canopen, blocking, before the loop): per node NMT reset communication and boot-up, heartbeat
  producer 100 ms (0x1017), identity (0x1018) and firmware (0x100A) over SDO, mode 7 (0x6060, checked on
  0x6061), interpolation period (0x60C2:1), following error window and time-out (0x6065, 0x6066, from
  shared.drives.prbt), the PDO layout written with canopen's PDO configuration
  (invalidate, map, transmission type, validate; TPDO2, the following error, every 10th SYNC), NMT start;
* a cycle thread at the SYNC period (default 10 ms; deadline sleeping, not asyncio's millisecond
  timers): the core's controlwords and setpoints go out as RPDO1 on every node, then SYNC; the drives'
  TPDOs come back and, as soon as every drive has answered the SYNC, the joint state is published on
  Zenoh (from the CAN thread, not a cycle later); every core event goes out as a SafetyEvent;
* a command that arrives while running goes on the bus at once (RPDO1 is synchronous: the drives take
  the latest setpoint at the next SYNC), clamped and rate-limited exactly as the cycle will, so a command
  waits for the SYNC inside the drive instead of in this process;
* every first command computed from a new human sample closes a latency chain (sample into
  tracker_ingest -> target frame on the bus, see shared.safety.latency), and every SYNC answer measures how far
  the joints run behind the setpoints sent (the drive lag) and reads the drives' following error
  (0x60F4, TPDO2, 10 Hz): once a second the chains go out as a LatencyReport on <prefix>/diag/latency and the
  drive figures as a DriveLagReport on <prefix>/diag/drive_lag, with a warning event when the whole
  chain (sample -> frame p99 + drive lag p99) exceeds the configured T_r or the lag exceeds ssm.drive_lag;
* asyncio main: Zenoh subscriptions (joint commands, stop / recover requests), liveliness token,
  SIGTERM. A malformed message is logged and dropped; the service goes on.

    python -m services.robot_driver --interface udp_multicast --listen tcp/127.0.0.1:7447
"""

from __future__ import annotations

import argparse
import asyncio
import dataclasses
import logging
import math
import signal
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import canopen
import numpy as np

from services.common import ServiceShell, run_paced, service_parser, setup_logging
from shared.config import load_config
from shared.core.errors import HrcError
from shared.drives.bus import BusError, describe, open_bus
from shared.drives.driver_core import COMMAND_TIMEOUT, DriverCore, Feedback, warm_up
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
from shared.robot.model import default_robot
from shared.safety.latency import DriveLagMeter, LatencyMeter
from shared.scheduling import name_callback_thread, realtime
from shared.wire.messages import DriveLagReport, DriverRequest, JointCommand, JointState, LatencyReport, SafetyEvent, encode

log = logging.getLogger("robot_driver")


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
            node.sdo[0x6060].raw = MODE_IP
            node.sdo[0x60C2][1].raw = 10
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
            node.nmt.send_command(0x82)
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
                self.network.sync.transmit()
                self._since_sync = {}

    def shutdown(self) -> None:
        for node in self.nodes:
            try:
                node.nmt.state = "PRE-OPERATIONAL"
            except Exception:                 # best effort on the way out
                pass
        self.network.disconnect()


class Driver:
    """Ties the master, the core and Zenoh together."""

    def __init__(self, master: CanMaster, core: DriverCore, shell: ServiceShell, period: float,
                 latency: LatencyMeter, drive_lag: DriveLagMeter) -> None:
        self.master, self.core, self.shell, self.period = master, core, shell, period
        self.latency, self.latency_lock = latency, threading.Lock()
        self.drive_lag = drive_lag
        self.drive_lag_pub = shell.session.declare_publisher(shell.keys.drive_lag)
        self._sent = None                  # (setpoints, their velocity) that went out with the last SYNC
        self.report_every = max(1, int(round(1.0 / period)))      # a latency report a second
        self.cycles = 0
        self.latency_pub = shell.session.declare_publisher(shell.keys.latency)
        self.core_lock = threading.Lock()
        self.stop = threading.Event()
        self.state_pub = shell.session.declare_publisher(shell.keys.joint_state)
        self.event_pub = shell.session.declare_publisher(shell.keys.safety_events)
        self.seq = 0
        self.pub_lock = threading.Lock()
        self.last_output = None
        master.on_complete = self.publish_state
        shell.subscribe(shell.keys.command, JointCommand, self.on_command)
        shell.subscribe(shell.keys.driver_request, DriverRequest, self.on_request)

    def on_command(self, msg: JointCommand) -> None:
        with self.core_lock:
            early = self.core.command(msg.q, time.monotonic(), msg.qd)
        if early is not None:           # on the bus now; the drives take the latest setpoint at the next SYNC
            self.master.send(None, early, sync=False)
            if msg.human_sample_stamp is not None:          # the end of a sample -> frame chain
                elapsed = time.monotonic() - msg.human_sample_stamp
                with self.latency_lock:
                    self.latency.add(elapsed, elapsed - (msg.human_wait or 0.0))

    def on_request(self, msg: DriverRequest) -> None:
        log.info("request %s from %s", msg.action, msg.source)
        with self.core_lock:
            self.core.request(msg.action)

    def _publish_event(self, event) -> None:
        self._publish(self.event_pub, SafetyEvent(source="robot_driver", event=event.event, severity=event.severity,
                                                  text=event.text))
        (log.warning if event.severity != "info" else log.info)("%s: %s", event.event, event.text)

    def cycle(self, now: float) -> None:
        """One SYNC period: the core decides, RPDO1 to every drive, then SYNC (paced by run_paced)."""
        feedback = self.master.feedback(now)
        with self.master.lock:
            answered, self.master.completed = self.master.completed, False
        positions = np.array([fb.position for fb in feedback])
        if not answered:       # a drive did not answer the last SYNC: publish what there is, never go silent
            self.publish_state(positions, np.array([fb.velocity for fb in feedback]))
        elif self._sent is not None:      # how far the joints are behind what went out with that SYNC
            self.drive_lag.add(*self._sent, positions, self.master.following_errors())
        with self.core_lock:
            out = self.core.cycle(now, feedback)
        self.master.send(out.controlwords, out.setpoints)
        self._sent = (out.setpoints, out.setpoint_velocity) if out.mode.value == "running" else None
        self.last_output = out
        for event in out.events:
            self._publish_event(event)
        self.cycles += 1
        if self.cycles % self.report_every == 0:
            self._report_latency()

    def _report_latency(self) -> None:
        """The chains measured since the last report, and a warning when their p99 exceeds T_r."""
        lag, samples, following_error = self.drive_lag.report()
        with self.core_lock:
            stopped_by = self.core.stopped_by
        self._publish(self.drive_lag_pub, DriveLagReport(source="robot_driver", lag=lag, samples=samples,
                                                         following_error=following_error, bound=self.drive_lag.bound,
                                                         stopped_by=stopped_by))
        lag_verdict = self.drive_lag.check()
        if lag_verdict is not None:
            self._publish_event(lag_verdict)
        with self.latency_lock:
            sample_to_frame, processing = self.latency.drain()
            verdict = self.latency.check(self.drive_lag.worst() or 0.0)
        if sample_to_frame.size:
            self._publish(self.latency_pub, LatencyReport(source="robot_driver", sample_to_frame=sample_to_frame,
                                                          processing=processing))
        if verdict is not None:
            self._publish_event(verdict)

    def _publish(self, publisher, message) -> None:
        """One message out with the next sequence number and the time now."""
        with self.pub_lock:
            self.seq += 1
            publisher.put(encode(dataclasses.replace(message, seq=self.seq, stamp=time.monotonic())))

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
    config = load_config(args.config)
    warm_up(default_robot().limits)         # the setpoint limiter compiled before the first SYNC, not at it
    scheduling = realtime("robot_driver")   # every thread of the process: the GIL holder runs at the cycle's priority
    bus = open_bus(args.interface, args.channel)
    print(f"robot_driver: CANopen master on {describe(args.interface, args.channel)}, SYNC every "
          f"{args.period * 1000:.1f} ms, {scheduling}", flush=True)
    master = CanMaster(bus)
    await asyncio.to_thread(master.bring_up)
    shell = ServiceShell("robot_driver", args)
    core = DriverCore(default_robot().limits, args.period, args.command_timeout)
    driver = Driver(master, core, shell, args.period, LatencyMeter(config.ssm.reaction_time),
                    DriveLagMeter(config.ssm.drive_lag))
    thread = threading.Thread(target=run_paced, args=(args.period, driver.cycle, driver.stop), name="can-cycle",
                              daemon=True)
    thread.start()
    loop = asyncio.get_running_loop()
    stopped = asyncio.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, stopped.set)
    shell.announce()
    print("robot_driver: drives up, " + ", ".join(f"node {i['node']} fw {i['firmware']!r}" for i in master.identity),
          flush=True)
    await stopped.wait()
    driver.stop.set()
    thread.join(1.0)
    master.shutdown()
    shell.close()
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = service_parser("robot_driver", __doc__, config=False, default_listen="tcp/127.0.0.1:7447")
    parser.add_argument("--interface", default="udp_multicast")
    parser.add_argument("--channel", default=None)
    parser.add_argument("--period", type=float, default=PERIOD, help="SYNC period (s), default %(default)s")
    parser.add_argument("--config", type=Path, default=None,
                        help="cell configuration YAML (its T_r and drive_lag are checked against the measured ones)")
    parser.add_argument("--command-timeout", type=float, default=COMMAND_TIMEOUT,
                        help="a command older than this stops the drives (s), default %(default)s")
    args = parser.parse_args(argv)
    setup_logging(args.log_level)
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
