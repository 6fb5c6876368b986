"""robot_driver: the PRBT's six CiA 402 drives on CAN, commanded from Zenoh.

Thin shell around ``shared.drives.driver_core.DriverCore`` (what to command) and
``shared.drives.master.CanMaster`` (the CANopen master), on the services' common skeleton (services.common.serve):
* bring-up (CanMaster.bring_up, blocking, before the loop);
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
  (0x60F4, TPDO2, 10 Hz); every joint state carries the lag the scaler's tracking margin must cover now
  (``DriveLagMeter.covering``: the worst of the last second, a SYNC a drive did not answer a period more,
  so a drive that loses frames widens the margin within a few SYNCs); once a second the chains go out as
  a LatencyReport on <prefix>/diag/latency and the drive figures as a DriveLagReport on
  <prefix>/diag/drive_lag, with a warning event when the whole chain (sample -> frame p99 + drive lag p99)
  exceeds the configured T_r or the lag exceeds ssm.drive_lag;
* a command that comes more than 2.5 SYNC periods after the scaler sent it (its stamp) is logged with how late:
  beside a ``stale_command`` stop it tells a command on its way from a scaler that fell silent (the report's
  ``scaler_silences``, ``tools.silences``);
* Zenoh subscriptions (joint commands, stop / recover requests), liveliness token once the drives are up,
  SIGTERM. A malformed message is logged and dropped; the service goes on.

    python -m services.robot_driver --interface udp_multicast --listen tcp/127.0.0.1:7447
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
import threading
import time
from pathlib import Path

import canopen
import numpy as np

from services.common import ServiceShell, run_in_thread, run_paced, serve, service_parser, setup_logging
from shared.config import load_config
from shared.core.errors import HrcError
from shared.drives.bus import BusError, describe, open_bus
from shared.drives.cia402 import State
from shared.drives.driver_core import COMMAND_TIMEOUT, DriverCore, Event, Mode, warm_up
from shared.drives.master import CanMaster
from shared.drives.prbt import PERIOD
from shared.robot.model import default_robot
from shared.safety.latency import DriveLagMeter, LatencyCheck, LatencyMeter
from shared.scaling.sync_clock import GAP_PERIODS
from shared.wire.messages import DriveLagReport, DriverRequest, JointCommand, JointState, LatencyReport, SafetyEvent, encode

log = logging.getLogger("robot_driver")


class Driver:
    """Ties the master, the core and Zenoh together."""

    def __init__(self, master: CanMaster, core: DriverCore, shell: ServiceShell, period: float,
                 latency: LatencyMeter, drive_lag: DriveLagMeter) -> None:
        self.master, self.core, self.shell, self.period = master, core, shell, period
        self.latency, self.latency_lock = latency, threading.Lock()
        self.drive_lag, self.lag_lock = drive_lag, threading.Lock()   # the cycle feeds it, the CAN thread reads it
        self.drive_lag_pub = shell.session.declare_publisher(shell.keys.drive_lag)
        self._sent = None                  # (setpoints, their velocity) that went out with the last SYNC
        self.report_every = max(1, int(round(1.0 / period)))      # a latency report a second
        self.cycles = 0
        self.latency_pub = shell.session.declare_publisher(shell.keys.latency)
        self.core_lock = threading.Lock()
        self.state_pub = shell.session.declare_publisher(shell.keys.joint_state)
        self.event_pub = shell.session.declare_publisher(shell.keys.safety_events)
        self.seq = 0
        self.pub_lock = threading.Lock()
        self.publishing = True             # until the service stops (``stop_publishing``)
        self.last_output = None
        master.on_complete = self.publish_state
        shell.subscribe(shell.keys.command, JointCommand, self.on_command)
        shell.subscribe(shell.keys.driver_request, DriverRequest, self.on_request)

    def on_command(self, msg: JointCommand) -> None:
        late = time.monotonic() - msg.stamp
        if msg.stamp > 0.0 and late > GAP_PERIODS * self.period:     # a SYNC or more passed on its way
            log.warning("a command came %.1f ms after the scaler sent it", late * 1e3)
        with self.core_lock:          # (the time it is taken at: inside the lock, ordered with the SYNC cycle's)
            early = self.core.command(msg.q, time.monotonic(), msg.qd)
        if early is not None:           # on the bus now; the drives take the latest setpoint at the next SYNC
            self.master.send(None, early, sync=False)
            if msg.human_sample_stamp is not None:          # the end of a sample -> frame chain
                sent = time.monotonic()
                elapsed = sent - msg.human_sample_stamp
                tick = sent - msg.stamp if msg.stamp > 0.0 else elapsed     # the tick: the command's stamp
                with self.latency_lock:
                    self.latency.add(elapsed, elapsed - (msg.human_wait or 0.0), tick)

    def on_request(self, msg: DriverRequest) -> None:
        log.info("request %s from %s", msg.action, msg.source)
        with self.core_lock:
            self.core.request(msg.action)

    def _publish_event(self, event: Event | LatencyCheck) -> None:
        """A stop or warning of the core, or a verdict of the lag meters: both say event, severity, text, value."""
        self._publish(self.event_pub, SafetyEvent(source="robot_driver", event=event.event, severity=event.severity,
                                                  text=event.text, value=event.value))
        (log.warning if event.severity != "info" else log.info)("%s: %s", event.event, event.text)

    def cycle(self, now: float) -> None:
        """One SYNC period: the core decides, RPDO1 to every drive, then SYNC (paced by run_paced)."""
        feedback = self.master.feedback(now)
        with self.master.lock:
            answered, self.master.completed = self.master.completed, False
        positions = np.array([fb.position for fb in feedback])
        if not answered:       # a drive did not answer the last SYNC: publish what there is, never go silent
            with self.lag_lock:
                if self._sent is not None:
                    self.drive_lag.missed(self.period)
            self.publish_state(positions, np.array([fb.velocity for fb in feedback]))
        elif self._sent is not None:      # how far the joints are behind what went out with that SYNC
            with self.lag_lock:
                self.drive_lag.add(*self._sent, positions, self.master.following_errors())
        judged = self.master.answers_judged()
        with self.core_lock:
            out = self.core.cycle(now, feedback, answered, judged)
        self.master.send(out.controlwords, out.setpoints)
        self._sent = (out.setpoints, out.setpoint_velocity) if out.mode is Mode.RUNNING else None
        self.last_output = out
        for event in out.events:
            self._publish_event(event)
        self.cycles += 1
        if self.cycles % self.report_every == 0:
            self._report_latency()

    def _report_latency(self) -> None:
        """The chains measured since the last report, and a warning when their p99 exceeds T_r."""
        with self.lag_lock:
            lag, samples, following_error, missed = self.drive_lag.report()
        with self.core_lock:
            stopped_by = self.core.stopped_by
        self._publish(self.drive_lag_pub, DriveLagReport(source="robot_driver", lag=lag, samples=samples,
                                                         following_error=following_error, bound=self.drive_lag.bound,
                                                         stopped_by=stopped_by, missed=missed))
        with self.lag_lock:
            lag_verdict = self.drive_lag.check()
        if lag_verdict is not None:
            self._publish_event(lag_verdict)
        with self.latency_lock:
            sample_to_frame, processing, tick_to_frame = self.latency.drain()
            with self.lag_lock:
                worst = self.drive_lag.worst()
            verdict = self.latency.check(worst or 0.0)
        if sample_to_frame.size:
            self._publish(self.latency_pub, LatencyReport(source="robot_driver", sample_to_frame=sample_to_frame,
                                                          processing=processing, tick_to_frame=tick_to_frame,
                                                          sync_wait=self.latency.sync_wait))
        if verdict is not None:
            self._publish_event(verdict)

    def stop_publishing(self) -> None:
        """Nothing goes out from now on (the SYNC cycle has stopped; the shell's session closes next). The drives
        still answer until the bus closes, and a joint state published from the CAN thread into the closed
        session raised there: canopen logged 'ERROR session closed' at the stop of 46 runs in 54."""
        with self.pub_lock:
            self.publishing = False

    def _publish(self, publisher, message) -> None:
        """One message out with the next sequence number and the time now (none once stopped)."""
        with self.pub_lock:
            if not self.publishing:
                return
            self.seq += 1
            publisher.put(encode(dataclasses.replace(message, seq=self.seq, stamp=time.monotonic())))

    def publish_state(self, q: np.ndarray, qd: np.ndarray) -> None:
        """Every drive has answered this SYNC: the joint state goes out now (from the CAN thread)."""
        out = self.last_output
        if out is None or not np.all(np.isfinite(q)):
            return
        states = sorted({s.value for s in out.drive_states})
        with self.lag_lock:
            lag = self.drive_lag.covering()
        with self.master.lock:
            sync = self.master.syncs            # the SYNC answered (complete), or the one not answered (the cycle's)
        with self.pub_lock:
            if not self.publishing:
                return
            self.seq += 1
            self.state_pub.put(encode(JointState(
                q=q, qd=qd, drive_state=f"{out.mode.value}:{'/'.join(states)}", enabled=out.mode is Mode.RUNNING,
                fault=any(s is State.FAULT for s in out.drive_states), drive_lag=lag, sync=sync, seq=self.seq,
                stamp=time.monotonic())))


def run(args: argparse.Namespace) -> int:
    """Bring the drives up, then serve on the common skeleton: the SYNC cycle in a thread of its own, until
    SIGTERM; the drives are left pre-operational and the bus closed however it ends."""
    config = load_config(args.config)
    warm_up(default_robot().limits)         # the setpoint limiter compiled before the first SYNC, not at it
    bus = open_bus(args.interface, args.channel)
    print(f"robot_driver: CANopen master on {describe(args.interface, args.channel)}, SYNC every "
          f"{args.period * 1000:.1f} ms", flush=True)
    master = CanMaster(bus)
    try:
        master.bring_up()
        shell = ServiceShell("robot_driver", args)
        core = DriverCore(default_robot().limits, args.period, args.command_timeout)
        driver = Driver(master, core, shell, args.period, LatencyMeter(config.ssm.reaction_time, sync_wait=args.period),
                        DriveLagMeter(config.ssm.drive_lag))

        def cycle_until(stop: threading.Event) -> int:
            """The SYNC cycle in its own thread; 1 when it failed (the process ends, its supervisor restarts it)."""
            failed = run_in_thread("can-cycle", lambda stopped: run_paced(args.period, driver.cycle, stopped), stop)
            driver.stop_publishing()
            return 1 if failed is not None else 0

        nodes = ", ".join(f"node {i['node']} fw {i['firmware']!r}" for i in master.identity)
        return serve(shell, f"robot_driver: drives up, {nodes}", cycle_until)
    finally:
        master.shutdown()


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
        return run(args)
    except (BusError, HrcError) as exc:
        print(f"robot_driver: error: {exc}", file=sys.stderr)
        return 2
    except (canopen.SdoCommunicationError, canopen.nmt.NmtError) as exc:
        print(f"robot_driver: error: a drive did not answer: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
