"""The cell's operator and witness, as used by `hrc demo` and the fault campaign (`hrc faults`):

* ``Recorder`` subscribes to every key of the cell and keeps what arrives (bad messages are counted);
* ``HumanFeed`` publishes a scripted or recorded human as raw tracker data at the source's own rate, stamped
  with the moments the samples show, and can misbehave the way a tracker does (fall silent, send NaN, let
  the person jump) for the fault campaign;
* ``Shuttle`` sends goals between q_s and q_g: the next goal when the robot has arrived, the same goal again
  when the robot is not following a trajectory for it (the planner refused it, or the scaler dropped it
  after a stop), and 'recover' to the driver while it is stopped. One ``step`` per call, no thread.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import msgpack
import numpy as np

from evidence.scenarios import Q_GOAL, Q_START
from shared.core.errors import MessageError
from shared.core.humans import HumanCapsules, standing
from shared.robot.poses import leg_fraction
from shared.safety.latency import DelayHistogram
from shared.tracking.tracker import OLDEST_SAMPLE, TrackerParameters
from shared.wire.convert import humans_to_msg
from shared.wire.keys import KeySpace
from shared.wire.messages import (
    DriveLagReport,
    DriverRequest,
    Goal,
    HumanRaw,
    HumanState,
    JointCommand,
    JointState,
    LatencyReport,
    MonitorReport,
    SafetyEvent,
    ScalerStatus,
    TrajectoryMsg,
    decode,
    encode,
)
from tools.report import Recording

HUMAN_RATE = 120.0          # Hz, raw tracker samples of a scripted human (a recorded one goes at its own rate)
ARRIVED = 0.01              # rad: the robot is at its goal
GOAL_RETRY = 1.0            # s without following a trajectory for the current goal: send it again
RECOVER_EVERY = 1.0         # s between recovery requests while the driver is stopped
LATE_RESOLUTION, LATE_LIMIT = 1e-4, 0.2    # s: the feed's lateness histogram, 0.1 ms bins up to 200 ms


class Recorder:
    """Subscribes to every key of the cell and keeps what arrives (bad messages are counted, not kept)."""

    def __init__(self, session, keys: KeySpace, rec: Recording) -> None:
        self.rec, self.lock, self.bad = rec, threading.Lock(), 0
        self.latest: dict[type, object] = {}
        self.finished = threading.Event()    # set by a scaler status that says its trajectory is finished
        self.on_message = None           # called with every message kept (the demo's live 3D view)
        table = [(keys.scaler_status, ScalerStatus, rec.statuses), (keys.command, JointCommand, rec.commands),
                 (keys.joint_state, JointState, rec.joint_states), (keys.human_state, HumanState, rec.human_states),
                 (keys.trajectory, TrajectoryMsg, rec.trajectories), (keys.safety_events, SafetyEvent, rec.events),
                 (keys.latency, LatencyReport, rec.latency), (keys.drive_lag, DriveLagReport, rec.drive_lag),
                 (keys.monitor, MonitorReport, rec.monitor)]
        self.subs = [session.declare_subscriber(key, self._keeper(kind, store)) for key, kind, store in table]

    def _keeper(self, kind, store: list):
        def on_sample(sample):
            try:
                msg = decode(sample.payload.to_bytes(), kind)
            except MessageError:
                with self.lock:
                    self.bad += 1
                return
            with self.lock:
                store.append(msg)
                self.latest[kind] = msg
            if kind is ScalerStatus and msg.status == "finished":
                self.finished.set()
            if self.on_message is not None:
                self.on_message(msg)
        return on_sample

    def get(self, kind):
        with self.lock:
            return self.latest.get(kind)

    def wait_finished(self, timeout: float) -> None:
        """Wait up to `timeout` (s), less where a scaler status comes saying that its trajectory is finished: an
        operator that only polls every `timeout` leaves the robot standing at its goal for half of it on average
        before the next goal goes out (measured in docs/measurements.md, session 66). A finish that comes while the
        operator is busy is taken by its next wait; the scaler says "finished" every period until a new trajectory
        comes, so none is missed for long."""
        self.finished.wait(timeout)
        self.finished.clear()

    def close(self) -> None:
        for sub in self.subs:
            sub.undeclare()


@dataclass
class FeedFault:
    """How the feed misbehaves: 'silent' (nothing is sent), 'nan' (every coordinate NaN), 'jump' (the person
    is shown `offset` (m) away from where they are; with `every` > 0 only in every every-th sample, a
    glitch). kind None: a healthy feed."""

    kind: str | None = None
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    every: int = 0


class FeedSchedule:
    """When a feed's samples are due, in seconds of the motion from its start (pure: no clock, no I/O). A
    recorded motion's own frame times (``times``, from 0: each frame once, when its tracker sent it, regular or
    not), and past its last frame on at `rate` (the last frame held, as ``RecordedMotion.at`` holds it); a
    script's, k / rate from 0. ``until`` (s): the last offset a finite feed sends (``hrc human replay`` ends
    with its file); None: on until stopped."""

    def __init__(self, rate: float, times: np.ndarray | None = None, until: float | None = None) -> None:
        if not rate > 0.0:
            raise ValueError(f"a feed's rate must be positive, not {rate}")
        self.rate, self.until = float(rate), until
        self.times = np.zeros(1) if times is None or len(times) == 0 else np.asarray(times, dtype=float)
        # samples in all: every offset up to `until` (None: unbounded)
        self.count = None if until is None else int(np.searchsorted(self._offsets_upto(until), until, side="right"))

    def _offsets_upto(self, horizon: float) -> np.ndarray:
        last = float(self.times[-1])
        extra = max(0, int(np.floor((horizon - last) * self.rate + 1e-9)))
        return np.concatenate([self.times, last + np.arange(1, extra + 1) / self.rate])

    def offset(self, k: int) -> float:
        """Sample k's offset (s from the motion's start)."""
        n = self.times.size
        return float(self.times[k]) if k < n else float(self.times[-1]) + (k - n + 1) / self.rate

    def newest(self, elapsed: float) -> int:
        """The last sample due by `elapsed` s of the motion (0 before any; the last one of a finite feed)."""
        n = self.times.size
        if elapsed <= self.times[-1]:
            k = int(np.searchsorted(self.times, elapsed, side="right")) - 1
        else:
            k = n - 1 + int(np.floor((elapsed - self.times[-1]) * self.rate + 1e-9))
        k = max(k, 0)
        return k if self.count is None else min(k, self.count - 1)

    def done(self, k: int) -> bool:
        """Sample k lies beyond a finite feed's end."""
        return self.count is not None and k >= self.count


def schedule_of(human, rate: float | None = None, until: float | None = None) -> FeedSchedule:
    """The schedule a feed sends `human` at: a given `rate` (Hz) as a fixed rate from 0; else a recorded
    motion's own frame times (``times``) and its median rate past them; else HUMAN_RATE."""
    if rate is not None:
        return FeedSchedule(rate, until=until)
    return FeedSchedule(getattr(human, "rate", None) or HUMAN_RATE, getattr(human, "times", None), until)


# samples of a scripted run's first moment the feed sends before its start (``HumanFeed``'s lead_in, one sample
# interval apart): the people as they stand at the start, seen by the tracker before the robot's first goal, as a
# cell's tracker has seen them long before it (the velocity fit's min_samples: their velocity is known at t0, as the
# simulation of a script knows it). Without it `hrc demo` began with the person's velocity unknown for the fit's
# first samples, and the planning layer took its first leg for a person who may be moving (the fold, 2.50 s nominal,
# where the simulation took the line, 2.45 s).
LEAD_IN = TrackerParameters().min_samples


def lead_in_samples(rate: float, latency: float = 0.0, samples: int = LEAD_IN) -> int:
    """The lead-in's samples of a feed at `rate` (Hz) whose samples reach the cell `latency` s after their capture:
    `samples` captured by t0 - latency (what the cell has at t0), and as many more as the latency spans."""
    return samples + int(np.ceil(latency * rate - 1e-9))


def lead_in_time(rate: float, latency: float = 0.0, samples: int = LEAD_IN) -> float:
    """How long (s) before a run's start a feed at `rate` (Hz), `latency` s late, sends its first lead-in sample."""
    return lead_in_samples(rate, latency, samples) / rate - latency


class HumanFeed(threading.Thread):
    """Publishes a scripted or recorded human (anything with ``at(t) -> HumanCapsules | None``; None: the
    tracker sees nobody, nothing is sent) as raw tracker data, time measured from t0, the way a tracker
    does: on its ``FeedSchedule`` (a recorded motion's frames each sent once at their own times; HUMAN_RATE for
    a script; or `rate`), each sample stamped with the moment it shows (its capture time, not when it was
    sent), and a feed that fell behind skips to the newest sample due, as a camera drops frames, rather than
    sending the ones it missed in a burst (a burst looks to the tracker like a glitch). ``fault`` may be
    changed at any time (FeedFault). speed: the motion played that many times faster (``hrc human replay
    --speed``). until: the motion's last second to send (None: until ``running`` is cleared); ``finished``
    then says the feed ended by itself. latency (s): each sample goes out that long after its capture and is
    stamped with the capture, as a camera pipeline delivers its skeletons (RealSense and OpenPose: 50-150 ms);
    the cell counts it in the data's age (``shared.tracking.tracker.capture_stamp``).

    tracked=True stands in for the tracker instead (a cell without tracker_ingest): each sample goes out as a
    valid HumanState with the capsules' own velocities, on the key the scaler reads. lead_in: samples of the motion's
    first moment sent before t0, one interval apart, stamped then (``LEAD_IN``), where the people stand at the start
    (``standing``: every velocity known and below a walk), and as many more as the latency spans (so that lead_in of
    them have reached the cell by t0: ``leading``, ``lead_in_samples``); a lead-in sample the feed is late for by an
    interval is not sent. Sample k goes out with seq k + leading."""

    def __init__(self, session, keys: KeySpace, human, t0: float, source: str = "hrc demo",
                 rate: float | None = None, tracked: bool = False, speed: float = 1.0,
                 until: float | None = None, latency: float = 0.0, lead_in: int = 0) -> None:
        super().__init__(daemon=True, name="human-feed")
        if not 0.0 <= latency <= OLDEST_SAMPLE:
            raise ValueError(f"latency: from 0 to {OLDEST_SAMPLE} s (a sample older than that is stale), got {latency}")
        self.latency = float(latency)
        self.tracked = tracked
        self.pub = session.declare_publisher(keys.human_state if tracked else keys.human_raw)
        self.human, self.t0, self.source, self.running = human, t0, source, True
        self.schedule = schedule_of(human, rate, until)
        self.speed = float(speed)
        self.rate = self.schedule.rate * self.speed      # Hz on the wall clock
        self.leading = lead_in_samples(self.rate, self.latency, int(lead_in)) if lead_in > 0 else 0
        self.fault = FeedFault()
        self.skipped = 0                  # samples not sent because the feed was late for them
        self.sent = 0                     # samples put
        self.finished = False             # a finite feed sent its last sample
        self.last_sent = 0.0              # monotonic time (s) of the last sample put
        self.lateness = DelayHistogram(LATE_RESOLUTION, LATE_LIMIT)   # how late it woke for each sample (s)
        self.latest_at: float | None = None   # when (s after t0) the sample it woke latest for was due

    def lateness_figures(self) -> dict:
        """How late the feed woke for its samples, after their due times (ms: p99, max): a feed that the machine
        does not run in time looks, to the tracker, like a person lost from view (issue 41, item 6). A
        histogram, not a list: a replay may run for hours. late_max_at_s: when the latest one was due (s after t0),
        to set beside the report's events and the machine's stalls."""
        if self.lateness.total == 0:
            return {"late_ms_p99": None, "late_ms_max": None, "late_max_at_s": None}
        return {"late_ms_p99": round(1e3 * self.lateness.percentile(99), 1),
                "late_ms_max": round(1e3 * self.lateness.largest, 1),
                "late_max_at_s": None if self.latest_at is None else round(self.latest_at, 3)}

    def figures(self) -> dict:
        """What the feed did: its rate (Hz), samples sent and skipped, and how late it woke."""
        return {"rate_hz": round(self.rate, 3), "skipped": self.skipped, "sent": self.sent,
                "latency_ms": round(1e3 * self.latency, 1), **self.lateness_figures()}

    def run(self) -> None:
        self._lead()
        schedule, k = self.schedule, 0
        while self.running and not schedule.done(k):
            due = self.t0 + schedule.offset(k) / self.speed          # its capture; it goes out `latency` later
            time.sleep(max(0.0, due + self.latency - time.monotonic()))
            woke = time.monotonic()
            late = woke - due - self.latency
            if self.latest_at is None or late > self.lateness.largest:
                self.latest_at = due - self.t0
            self.lateness.add(late)                           # before a skip moves `due` on
            newest = schedule.newest((woke - self.latency - self.t0) * self.speed)
            if newest > k:                                    # late: the samples missed are gone
                self.skipped += newest - k
                k = newest
                due = self.t0 + schedule.offset(k) / self.speed
            self._send(k, due, self.human.at(schedule.offset(k)))
            k += 1
        self.finished = schedule.done(k)

    def _lead(self) -> None:
        """The lead-in: the motion's first moment, `lead_in` intervals before t0 on, each on time or not at all; only
        where the people stand at the start, so that they stood there before it is what the motion itself says (a
        walker's, or a recording's first frame, whose velocity nothing gives: none, the track starts at t0)."""
        first = self.human.at(0.0) if self.leading > 0 else None
        if first is None or not standing(first):
            return
        for i in range(self.leading, 0, -1):
            due = self.t0 - i / self.rate
            time.sleep(max(0.0, due + self.latency - time.monotonic()))
            if not self.running:
                return
            if time.monotonic() - due - self.latency < 1.0 / self.rate:
                self._send(-i, due, first)

    def _send(self, k: int, due: float, caps: HumanCapsules | None) -> None:
        """Sample k, due at `due` (monotonic s), as the fault in force makes it (nothing when silent or nobody)."""
        fault = self.fault
        if fault.kind == "silent" or caps is None:           # a fault, or a dropout in a recorded motion
            return
        shifted = fault.kind == "jump" and (fault.every <= 0 or k % fault.every == 0)
        segments = caps.segments + np.asarray(fault.offset) if shifted else caps.segments
        if self.tracked:
            shown = HumanCapsules(segments, caps.radii, caps.velocities, caps.velocity_known)
            payload = encode(humans_to_msg(shown, True, due, seq=k + self.leading, stamp=time.monotonic(),
                                           sample_interval=1.0 / self.rate))
        else:
            payload = encode(HumanRaw(source=self.source, sample_time=due, segments=segments, radii=caps.radii,
                                      seq=k + self.leading, stamp=time.monotonic()))
        self.pub.put(with_nan_segments(payload) if fault.kind == "nan" else payload)
        self.last_sent = time.monotonic()
        self.sent += 1


class HeldHuman:
    """A person who is wherever they were last put (``capsules``; None: nobody in view), for a feed whose
    scenario moves them by hand."""

    def __init__(self, capsules: HumanCapsules | None = None) -> None:
        self.capsules = HumanCapsules.empty() if capsules is None else capsules

    def at(self, t: float) -> HumanCapsules | None:
        return self.capsules


class MovingCapsule:
    """`hrc human inject`'s person: one capsule A-B (m, base frame) of `radius` (m) moving at `velocity` (m/s)
    from t = 0."""

    def __init__(self, a, b, radius: float, velocity) -> None:
        self.a, self.b, self.velocity = (np.asarray(v, dtype=float) for v in (a, b, velocity))
        self.radii = np.array([float(radius)])

    def at(self, t: float) -> HumanCapsules:
        moved = np.array([[self.a + self.velocity * t, self.b + self.velocity * t]])
        return HumanCapsules(moved, self.radii, np.broadcast_to(self.velocity, moved.shape).copy(),
                             np.ones(1, dtype=bool))


def with_nan_segments(payload: bytes) -> bytes:
    """A HumanRaw on the wire with every coordinate NaN, as a broken tracker would send it (encode refuses)."""
    body = msgpack.unpackb(payload, raw=False)
    body["segments"] = np.full(len(body["segments"]) // 8, np.nan).tobytes()
    return msgpack.packb(body, use_bin_type=True)


class Shuttle:
    """Shuttles the robot between q_s and q_g through goals, and asks a stopped driver to recover."""

    def __init__(self, session, keys: KeySpace, recorder: Recorder, rec: Recording, say=lambda text: None,
                 source: str = "hrc demo") -> None:
        self.goal_pub = session.declare_publisher(keys.goal)
        self.req_pub = session.declare_publisher(keys.driver_request)
        self.recorder, self.rec, self.say, self.source = recorder, rec, say, source
        self.ends = [Q_START, Q_GOAL]
        self.leg, self.goal_id = 0, 0
        self.goal_sent = self.last_recover = -1e9
        self.recovering = True            # False: leave a stopped driver stopped (a fault is being watched)

    @property
    def target(self) -> np.ndarray:
        return self.ends[(self.leg + 1) % 2]

    def send_goal(self, now: float) -> None:
        self.goal_sent = now
        self.goal_pub.put(encode(Goal(goal_id=self.goal_id, name="q_g" if self.leg % 2 == 0 else "q_s",
                                      q=self.target, then=self.ends[self.leg % 2][None], seq=self.goal_id,
                                      stamp=now)))       # then: back again, the shuttle's next goal

    def start(self, now: float) -> None:
        self.goal_id = 1
        self.send_goal(now)

    def following_goal(self, status: ScalerStatus | None) -> bool:
        """The scaler follows a trajectory planned for the current goal."""
        if status is None or status.trajectory_version < 0:
            return False
        with self.recorder.lock:
            mine = {t.version for t in self.rec.trajectories[-20:] if t.goal_id == self.goal_id}
        return status.trajectory_version in mine

    def step(self, now: float) -> None:
        js, st = self.recorder.get(JointState), self.recorder.get(ScalerStatus)
        following = self.following_goal(st)
        if js is not None and st is not None and st.status == "finished" and following \
                and np.abs(js.q - self.target).max() < ARRIVED:
            self.rec.shuttles += 1
            self.leg += 1
            self.goal_id += 1
            self.send_goal(now)
        elif not following and now - self.goal_sent > GOAL_RETRY:
            self.send_goal(now)
        if js is not None:      # a shuttle's part done counts, as the simulation counts it (evidence.sim)
            self.rec.progress = self.rec.shuttles + leg_fraction(js.q, self.ends[self.leg % 2], self.target)
        self._ask_recovery(js, now)

    def _ask_recovery(self, js: JointState | None, now: float) -> None:
        """Ask a stopped driver to recover, at most every RECOVER_EVERY (unless this shuttle leaves it stopped)."""
        if self.recovering and js is not None and js.drive_state.startswith("stopped") \
                and now - self.last_recover > RECOVER_EVERY:
            self.last_recover = now
            self.recover(now)
            self.say(f"t={now - self.rec.t0:6.2f}s  robot stopped ({js.drive_state}): asking the driver to recover")

    def enable(self, wait: float, clock=time.monotonic, sleep=time.sleep) -> bool:
        """Before the run: where the drives are stopped (a fault at start-up, e.g. the drives' SYNC watchdog on a
        slow machine's start), ask the driver to recover them (``_ask_recovery``, as the run does) until they run or
        `wait` s have passed (False then; the run's own recovery goes on asking). Why: a first plan that comes while
        the drives still enable is dropped by the scaler, and the robot stood a goal retry (1 s) at the start
        (session 86)."""
        deadline = clock() + wait
        while (now := clock()) < deadline:
            js = self.recorder.get(JointState)
            if js is not None and js.drive_state.startswith("running"):
                return True
            self._ask_recovery(js, now)
            sleep(0.01)
        return False

    def recover(self, now: float) -> None:
        self.req_pub.put(encode(DriverRequest(action="recover", source=self.source, stamp=now)))
