"""tracker_ingest: raw human poses in, the human state out (a thin shell around shared.tracking.tracker).

Every raw sample (<prefix>/human/raw, HumanRaw: capsules from motion capture at up to 240 Hz, a camera
skeleton tracker at 15-60 Hz, the CLI or a replay) is filtered and published at once as HumanState on
<prefix>/human/state, stamped with its capture time on the cell's clock (``capture_stamp``: the sample's own
time, or its arrival where that time is ahead of it; the scaler measures the data's age from it, so a camera's latency
counts; a sample captured more than 0.5 s ago is dropped as stale, and said so once a second) and the
source's measured sample interval (the velocity window and the dropout bound scale with it:
shared.tracking.tracker). A watch publishes an invalid state every 10 ms while no
sample has arrived within the dropout bound, so a silent tracker is announced, not only noticed. While
samples come it sleeps until the moment the bound would pass (``next_check``), not a hundred times a second:
a dropout is announced within a fraction of a millisecond of it, and the process is not woken for nothing.

    python -m services.tracker_ingest --connect tcp/127.0.0.1:7447
"""

from __future__ import annotations

import sys
import threading
import time

from services.common import ServiceShell, open_service, prepare_loop_thread, serve, service_parser, setup_logging
from shared.core.humans import HumanCapsules
from shared.scheduling import sleep_until
from shared.tracking.tracker import SOURCE_RATES, HumanTracker, TrackerParameters, capture_stamp, declarable
from shared.wire.convert import humans_to_msg
from shared.wire.messages import HumanRaw, HumanState, SafetyEvent, encode

INVALID_PERIOD = 0.01       # s: how often the invalid state is repeated while no sample comes
STALE_SAID_EVERY = 1.0      # s: how often dropped stale samples are said (a count since the last time)


def next_check(now: float, valid_until: float, period: float = INVALID_PERIOD) -> float:
    """How long the dropout watch sleeps (s): just past the moment the track turns invalid while it is valid
    (a sample that comes meanwhile moves that moment on, and the watch sleeps again), every period while it
    is invalid."""
    return sleep_until(valid_until, now) if now <= valid_until else period


class TrackerIngest:
    def __init__(self, shell: ServiceShell, tracker: HumanTracker) -> None:
        self.shell, self.tracker = shell, tracker
        self.lock = threading.Lock()
        self.seq = 0
        self.valid_before = False
        self.stale, self.stale_said = 0, -float("inf")      # stale samples dropped since last said, and when that was
        self.state_pub = shell.session.declare_publisher(shell.keys.human_state)
        self.event_pub = shell.session.declare_publisher(shell.keys.safety_events)
        shell.subscribe(shell.keys.human_raw, HumanRaw, self.on_raw)

    def _publish(self, msg: HumanState) -> None:
        self.seq += 1
        self.state_pub.put(encode(HumanState(segments=msg.segments, radii=msg.radii, velocities=msg.velocities,
                                             velocity_known=msg.velocity_known, valid=msg.valid,
                                             sample_stamp=msg.sample_stamp,
                                             sample_interval=self.tracker.interval, seq=self.seq,
                                             stamp=time.monotonic())))

    def on_raw(self, msg: HumanRaw) -> None:
        arrival = time.monotonic()
        captured = capture_stamp(msg.sample_time, arrival)
        if captured is None:
            self._drop_stale(msg, arrival)
            return
        with self.lock:
            humans = self.tracker.update(msg.segments, msg.radii, msg.sample_time, arrival)
            if humans is not None:
                self._publish(humans_to_msg(humans, True, captured))

    def _drop_stale(self, msg: HumanRaw, arrival: float) -> None:
        """A sample captured too long ago: not the person of now. Counted, and said at most once a second."""
        self.stale += 1
        if arrival - self.stale_said >= STALE_SAID_EVERY:
            self.shell.log.warning("%d human sample(s) from %r dropped as stale: the last captured %.3f s before it "
                                   "arrived (a sample's time is its capture on the cell's CLOCK_MONOTONIC)",
                                   self.stale, msg.source, arrival - msg.sample_time)
            self.stale, self.stale_said = 0, arrival

    def check(self, now: float) -> None:
        with self.lock:
            valid = self.tracker.valid(now)
            if not valid:
                self._publish(humans_to_msg(HumanCapsules.empty(), False, now))
            if valid != self.valid_before:
                self.valid_before = valid
                self.seq += 1
                text = "tracking resumed" if valid else "no human sample within the dropout bound"
                self.event_pub.put(encode(SafetyEvent(source="tracker_ingest", event="tracker_dropout" if not valid
                                                      else "tracker_ok", severity="stop" if not valid else "info",
                                                      text=text, seq=self.seq, stamp=now)))
                (self.shell.log.warning if not valid else self.shell.log.info)(text)

    def watch(self, stop: threading.Event) -> None:
        """check() at the moments next_check says, until stopped (set up as every loop thread,
        ``prepare_loop_thread``; the process hands the GIL over every 0.5 ms, ``serve``, so a sample's callback
        never waits 5 ms behind this thread)."""
        prepare_loop_thread()
        while not stop.is_set():
            now = time.monotonic()
            self.check(now)
            with self.lock:
                valid_until = self.tracker.valid_until
            stop.wait(next_check(time.monotonic(), valid_until))


def main(argv: list[str] | None = None) -> int:
    parser = service_parser("tracker_ingest", __doc__, config=False)
    parser.add_argument("--dropout", type=float, default=0.05, help="no sample for this long: invalid (s)")
    parser.add_argument("--window", type=float, default=0.04, help="velocity fit window (s)")
    parser.add_argument("--source-rate", type=float, default=None, metavar="HZ",
                        help="the source's nominal frame rate, where known (a 15 Hz camera: 15): its sample interval "
                             "until one is measured, so its second frame is not taken for a lost person")
    args = parser.parse_args(argv)
    setup_logging(args.log_level)
    if not (0 < args.dropout <= 1.0 and 0 < args.window <= 1.0):
        print("tracker_ingest: error: --dropout and --window must be in (0, 1] s", file=sys.stderr)
        return 2
    if args.source_rate is not None and not declarable(args.source_rate):
        print(f"tracker_ingest: error: --source-rate must be within [{SOURCE_RATES[0]:g}, {SOURCE_RATES[1]:g}] Hz",
              file=sys.stderr)
        return 2
    opened = open_service("tracker_ingest", args)
    if opened is None:
        return 2
    _, shell = opened
    HumanTracker.warm_up()           # compile before the first sample, not at it
    interval = 0.0 if args.source_rate is None else 1.0 / args.source_rate
    service = TrackerIngest(shell, HumanTracker(TrackerParameters(window=args.window, dropout=args.dropout,
                                                                  source_interval=interval)))
    declared = "" if args.source_rate is None else f", a source at {args.source_rate:g} Hz declared"
    return serve(shell, f"tracker_ingest: least-squares velocity over {args.window * 1000:.0f} ms, dropout "
                        f"{args.dropout * 1000:.0f} ms{declared}, keys {shell.keys.prefix}/",
                 service.watch)

if __name__ == "__main__":
    sys.exit(main())
