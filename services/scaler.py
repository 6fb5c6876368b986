"""scaler: the trajectory scaling layer as a service (a thin shell around shared.scaling.layer).

Each tick it takes the last trajectory, the human states received since the last tick (all of them: one that
held for less than a period counts too) and the last joint state received, runs
ScalingLayer.step, and publishes the joint command and its status. It ticks on every joint state (the
driver publishes one a SYNC, 100 Hz), falling back to 1.5 control periods without one (services.common.
run_synced): locked to the drives' clock, its path never runs ahead of the robot (on its own clock, a
SYNC cycle lost under load left the robot one period behind a command at full speed, for good, and
the braking that followed overshot the stop). Once per SYNC (``shared.scaling.sync_clock.SyncClock``, by
the state's SYNC number): a SYNC one drive did not answer is published a period late, just before the next
one, and a fallback tick has already stood in for it; ticking on both stepped the path a period ahead of
the drives for every frame a drive lost (a drive losing a tenth of its frames put a healthy joint 130 mrad
behind the commands at its velocity limit, and the catch-up overshot a stop towards a person). Rules of the shell:
* no trajectory yet, or none taken: it commands the measured position (hold), so the driver can enable;
* a new trajectory version is taken without a jump: a fresh plan (base_version -1) when the robot is at
  its start; a merged one when the follower has not passed its junction (it continues at the same s);
* with scaling.await_plan > 0 (0 shipped), a replan request raised while the robot crawls brings it to rest,
  where it awaits the plan (the status's stop_s says where; the core's rule, ``ScalingLayer._await``; not with
  --no-await);
* the tracking margin covers the drive lag the robot driver measures (its DriveLagReport, once a second,
  and the lag each joint state says to cover, every SYNC), where that is longer than the configured
  ssm.drive_lag (``SsmParameters.covering_lag``);
* human data that never came, is marked invalid, or is older than the configured bound stops the robot
  (the core's rule; the bound at a slow source's rate is shared.tracking.tracker.stale_bound); an invalid
  or malformed message counts as no message. No joint state for scaling.robot_timeout (counted from the
  newest one's stamp, or from its arrival where that is later: ``state_age``) stops it too, along its path
  (the core's rule, status stale_joint_state): the path is not run open loop for a robot that is not heard
  from, nor on states that waited in a queue;
* a tick more than ``GAP_PERIODS`` control periods after the last one (a SYNC passed without a command) is
  logged with how long the first joint state since the last tick had waited in this process and how long the
  last tick took (the report's ``scaler_silences``, ``tools.silences``, has only the stamps);
* while the driver reports that the robot is not following (stopped, enabling: JointState.enabled false)
  the trajectory is dropped and the measured position held: after a quick stop the robot stands off the
  path, the driver re-enables only on a command where the robot is, and the planner (which sees
  trajectory version -1 in the status) plans the next goal afresh from there.

    python -m services.scaler --connect tcp/127.0.0.1:7447 [--config deploy/cell.yaml]
"""

from __future__ import annotations

import sys
import threading
import time
from dataclasses import replace

import numpy as np

from services.common import ServiceShell, open_service, run_synced, serve, service_parser, setup_logging
from shared.core.humans import HumanCapsules
from shared.robot.model import default_robot
from shared.scaling.layer import ScalingInputs, ScalingLayer
from shared.scaling.sync_clock import GAP_PERIODS, SyncClock
from shared.tracking.tracker import stale_bound
from shared.wire.convert import humans_from_msg, status_from_step, trajectory_from_msg
from shared.wire.messages import (
    DriveLagReport,
    HumanState,
    JointCommand,
    JointState,
    TrajectoryMsg,
    encode,
)

START_TOLERANCE = 0.02     # rad: how close the robot must be to a fresh plan's start to take it


def merge_human_states(msgs: list[HumanState]) -> HumanCapsules | None:
    """The people of the newest state and of every valid state before it in msgs (oldest first), as one
    state (newest capsules first); None when the newest is an invalid track."""
    if not msgs[-1].valid:
        return humans_from_msg(msgs[-1])
    return HumanCapsules.union([humans_from_msg(m) for m in reversed(msgs) if m.valid])


def state_age(now: float, arrived: float, stamp: float) -> float:
    """s: how old the newest joint state is at `now`: since the driver published it (its stamp, on this host's
    monotonic clock) or since it reached this process (arrived), whichever is longer. States that waited in a
    queue are as old as their stamps say: after the scaler was held up 1.5 s (SIGSTOP), Zenoh delivered the
    states of that time at once, the oldest first, and the scaler, judging them fresh by their arrival, ran on
    along its old path on states from before the driver had stopped the robot. A stamp ahead of the arrival
    (not this host's clock) counts from the arrival."""
    return now - min(arrived, stamp)


class Scaler:
    def __init__(self, shell: ServiceShell, layer: ScalingLayer, arrival_clock=time.monotonic) -> None:
        """arrival_clock: what says when a joint state came (s, on the clock ticks are given on; a test's own).
        Not ``self.clock``: that is the SYNC clock the path steps on."""
        self.shell, self.layer, self.arrival_clock = shell, layer, arrival_clock
        self.lock = threading.Lock()
        self.humans = None                 # HumanCapsules, or None
        self.human_stamp = -np.inf         # monotonic time of the human sample
        self.human_published = -np.inf     # when tracker_ingest published its state (same host clock)
        self.human_interval = 0.0                         # s: the source's sample interval, as the tracker measured
        self.reported_stamp = None         # the sample whose latency chain the last command carried
        self.joint_q = None
        self.joint_arrived = -np.inf       # when the newest joint state reached this process (monotonic s) ...
        self.joint_stamp = -np.inf         # ... and when the driver published it (its stamp, the host's monotonic s)
        self.robot_following = False       # the driver runs and follows commands (JointState.enabled)
        self.joint_state_arrived = threading.Event()       # wakes the tick: one a SYNC
        self.woken_by: tuple[float, float] | None = None   # the first state due since the last tick: (came, stamp)
        self.last_tick: tuple[float, float] | None = None  # (when the last tick began, how long it took), s
        self.clock = SyncClock()
        self.pending: TrajectoryMsg | None = None
        self.version = -1
        self.received = -1                 # the newest trajectory version decided on (followed, stopped for, refused)
        self.seq = 0
        keys = shell.keys
        self.cmd_pub = shell.session.declare_publisher(keys.command)
        self.status_pub = shell.session.declare_publisher(keys.scaler_status)
        # the human states, queued by Zenoh and taken at each tick: no callback thread woken for each of
        # 120-240 samples a second; a tick checks against every one since the last (HumanCapsules.union)
        self.humans_in = shell.queue(keys.human_state, HumanState)
        # the robot driver's drive lag (once a second): the tracking margin covers the lag measured
        self.configured_ssm = layer.ssm
        self.lag_in = shell.latest(keys.drive_lag, DriveLagReport)
        self.reported_lag = 0.0            # s, the newest report's worst p99
        self.state_lag = 0.0               # s, the newest joint state's drive_lag (0: it gave none)
        self.covered_lag = 0.0             # s, the lag the layer's margin was last set for (0: as configured)
        shell.subscribe(keys.joint_state, JointState, self.on_joints)
        shell.subscribe(keys.trajectory, TrajectoryMsg, self.on_trajectory)

    @property
    def stale_after(self) -> float:
        """s: the people's data's age bound at the source's rate (``stale_bound`` of human_timeout and the
        newest state's interval)."""
        return stale_bound(self.layer.params.human_timeout, self.human_interval)

    def take_humans(self) -> None:
        """The human states since the last tick, if any came: the people of all of them at once
        (``merge_human_states``: a state shorter than a period counts too), aged by the newest (an invalid
        newest track counts as no people; a malformed message as no message: logged and counted by the shell)."""
        msgs = self.humans_in.drain()
        if msgs:
            newest = msgs[-1]
            self.humans = merge_human_states(msgs)
            self.human_stamp = newest.sample_stamp if newest.valid else -np.inf
            self.human_published = newest.stamp
            self.human_interval = newest.sample_interval

    def cover_drive_lag(self) -> None:
        """The scaling layer's margin for the drive lag measured: the configured drive_lag, the worst joint's
        p99 of the newest report (once a second) or the lag the newest joint state says to cover (the last
        second's worst, every SYNC: a drive that loses frames widens the margin within a few SYNCs, not a
        second later), the longest (``SsmParameters.covering_lag``)."""
        msg = self.lag_in.take()
        if msg is not None:
            self.reported_lag = float(np.max(msg.lag))
        with self.lock:
            lag = max(self.reported_lag, self.state_lag)
        if lag == self.covered_lag:          # as last tick: the margin stands (no new parameters each tick)
            return
        self.covered_lag = lag
        ssm = self.configured_ssm.covering_lag(lag)
        if (ssm is self.configured_ssm) != (self.layer.ssm is self.configured_ssm):
            self.shell.log.warning("tracking margin %.3f m/s for a drive lag of %.1f ms (configured %.1f ms)",
                                   ssm.tracking_margin, ssm.drive_lag * 1e3, self.configured_ssm.drive_lag * 1e3)
        self.layer.ssm = ssm

    def on_joints(self, msg: JointState) -> None:
        """The newest measured state; it wakes the tick when it ends a SYNC the path has not stepped for yet
        (``SyncClock``)."""
        with self.lock:
            self.joint_q = np.asarray(msg.q)
            self.joint_arrived = self.arrival_clock()
            self.joint_stamp = msg.stamp
            self.robot_following = msg.enabled
            self.state_lag = msg.drive_lag or 0.0
            due = self.clock.arrived(msg.sync)
            if due and self.woken_by is None:
                self.woken_by = (time.monotonic(), msg.stamp)
        if due:
            self.joint_state_arrived.set()

    def on_trajectory(self, msg: TrajectoryMsg) -> None:
        with self.lock:
            if msg.version > self.version:
                self.pending = msg

    def _take_pending(self) -> None:
        msg, self.pending = self.pending, None
        self.received = max(self.received, msg.version)
        fresh = msg.base_version == -1
        followed = self.layer.trajectory.version if self.layer.trajectory is not None else -1
        if not fresh and msg.base_version != followed:       # (not self.version: a plan it stops for is not followed yet)
            why = f"merged into version {msg.base_version}, not the followed {followed}"
        elif fresh and self.joint_q is None:
            why = "the robot's position is not known yet"
        else:
            why = self.layer.take(trajectory_from_msg(msg), fresh, msg.junction, self.joint_q, START_TOLERANCE)
        if why is not None:
            self.shell.log.warning("trajectory %d not taken: %s", msg.version, why)
            return
        self.version = msg.version
        self.shell.log.info("following trajectory %d (%s)", msg.version, msg.reason)

    def say_silence(self, now: float, woken_by: tuple[float, float] | None) -> None:
        """Log a tick that began more than GAP_PERIODS control periods after the last one (a SYNC passed
        without a command: ``tools.silences``), with what the report cannot see: how long the first joint state
        due since the last tick (woken_by: when it came, its stamp) had waited, how late it reached this process,
        and how long the last tick took."""
        if self.last_tick is None:
            return
        began, took = self.last_tick
        if now - began <= GAP_PERIODS * self.layer.params.period:
            return
        if woken_by is None:
            woke = "with no new joint state (the fallback)"
        else:
            woke = (f"with a joint state that had waited {(now - woken_by[0]) * 1e3:.1f} ms for it, "
                    f"{(woken_by[0] - woken_by[1]) * 1e3:.1f} ms after the driver published it")
        self.shell.log.warning("no tick for %.1f ms (the last took %.1f ms): woke %s", (now - began) * 1e3,
                               took * 1e3, woke)

    def tick(self, now: float) -> None:
        started = time.monotonic()
        with self.lock:
            woken_by, self.woken_by = self.woken_by, None
        self.say_silence(now, woken_by)
        self._tick(now)
        self.last_tick = (now, time.monotonic() - started)

    def _tick(self, now: float) -> None:
        self.cover_drive_lag()
        with self.lock:
            self.clock.ticked()
            self.take_humans()
            if self.pending is not None:
                self._take_pending()
            humans, age, q_meas = self.humans, now - self.human_stamp, self.joint_q
            robot_age = state_age(now, self.joint_arrived, self.joint_stamp)
            stamp, published, following = self.human_stamp, self.human_published, self.robot_following
        if q_meas is not None and (self.layer.trajectory is None or not following):
            if not following and self.layer.trajectory is not None and self.layer.trajectory.version != -1:
                self.shell.log.warning("the robot is not following (driver stopped or enabling): trajectory %d "
                                       "dropped, holding the measured position", self.layer.trajectory.version)
                with self.lock:         # any fresh plan from where the robot stands may follow, whatever its number
                    self.version = -1
            self.layer.hold(q_meas)
        if self.layer.trajectory is None:
            return
        step = self.layer.step(ScalingInputs(humans=humans, human_age=age if humans is not None else np.inf,
                                             stale_after=self.stale_after, robot_age=robot_age))
        if step.dropped is not None:
            self.shell.log.warning("trajectory dropped: %s", step.dropped)
            with self.lock:         # the planner numbers its next plan from the followed one: it may come with
                self.version = step.trajectory_version       # the dropped plan's number and is taken
        self.seq += 1
        fresh = np.isfinite(stamp) and stamp != self.reported_stamp      # first command from this sample
        if fresh:
            self.reported_stamp = stamp
        self.cmd_pub.put(encode(JointCommand(q=step.q_command, qd=step.qd_command,
                                             trajectory_version=step.trajectory_version, s=step.s,
                                             human_sample_stamp=stamp if fresh else None,
                                             human_wait=max(0.0, now - published) if fresh else None,
                                             seq=self.seq, stamp=now)))
        self.status_pub.put(encode(status_from_step(step, self.received, self.seq, now)))


def main(argv: list[str] | None = None) -> int:
    parser = service_parser("scaler", __doc__)
    parser.add_argument("--no-await", action="store_true",
                        help="never stand still awaiting a replan (the planner's --no-beta answers none)")
    args = parser.parse_args(argv)
    setup_logging(args.log_level)
    opened = open_service("scaler", args)
    if opened is None:
        return 2
    config, shell = opened
    scaling = replace(config.scaling, await_plan=0.0) if args.no_await else config.scaling
    layer = ScalingLayer(default_robot(), config.ssm, scaling)
    layer.warm_up()                  # compile before the first deadline, not at it
    scaler = Scaler(shell, layer)
    return serve(shell, f"scaler: {1 / config.scaling.period:.0f} Hz on the drives' SYNC, solver "
                        f"{config.scaling.solver}, keys {shell.keys.prefix}/",
                 lambda stop: run_synced(config.scaling.period, scaler.tick, stop, scaler.joint_state_arrived))


if __name__ == "__main__":
    sys.exit(main())
