"""The demo's person, in a process of its own (`python -m tools.feed`): what a camera and its skeleton tracker
are to a real cell, a separate sender the cell cannot slow down and that cannot slow the cell.

``hrc demo`` ran its ``tools.actors.HumanFeed`` as a thread beside its recorder, which decodes every message
the cell publishes under the same interpreter lock; on a loaded machine the feed then fell behind, and
tracker_ingest declared a dropout with the person in view. Here the same ``HumanFeed`` loop runs alone.

The protocol with the parent (``tools.demo.start_feed``): the child opens its Zenoh session, waits until
tracker_ingest is reachable, prints READY, and reads one line from stdin: the monotonic time t0 (s; one
clock for every process of the machine) the motion starts at. Where the people stand at the start it sends
that first moment for ``LEAD_IN`` sample intervals before t0 (``tools.actors``: the tracker has seen them before
the run, as in a cell; the parent gives a t0 at least ``lead_in_time`` ahead), then the motion from t0, until
SIGTERM (or stdin closed before a start), and writes ``{"rate_hz", "skipped", "sent", "late_ms_p99",
"late_ms_max"}`` as JSON to --stats on the way out.

It runs in SCHED_FIFO below the safety chain (``shared.scheduling.PRIORITY``), as the emulated drives do: it
stands for hardware outside the machine. In the normal class a busy planner, monitor and recorder held it off
the CPU for 50 ms or more now and then (an idle ``hrc demo``: 5 samples skipped, a 56 ms gap), and
tracker_ingest rightly declared the person lost.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
from pathlib import Path

from tools.arguments import sample_latency

READY = "human_feed: ready"


def arguments(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m tools.feed", description=__doc__.split("\n\n")[0])
    parser.add_argument("--connect", required=True, help="the cell's Zenoh endpoint (tcp/127.0.0.1:PORT)")
    parser.add_argument("--prefix", required=True, help="the cell's key prefix")
    parser.add_argument("--human", type=Path, default=None, help="a motion file (default: the paper's phases)")
    parser.add_argument("--phase-length", type=float, default=6.0, help="s per phase of the paper's phases")
    parser.add_argument("--source", default="hrc demo", help="the source named in every sample")
    parser.add_argument("--latency", type=sample_latency, default=0.0,
                        help="s each sample goes out after its capture, stamped with the capture (a camera's latency)")
    parser.add_argument("--stats", type=Path, required=True, help="where the feed's figures go at the end")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = arguments(argv)
    from evidence.scenarios import paper_phases
    from shared.core.errors import ConfigError
    from shared.scheduling import realtime
    from shared.tracking.motion import RecordedMotion
    from shared.transport.zenoh_session import await_liveliness, open_session
    from shared.wire.keys import KeySpace
    from tools.actors import LEAD_IN, HumanFeed
    from tools.launch import free_port

    try:
        human = RecordedMotion.load(args.human) if args.human is not None else paper_phases(args.phase_length)
        session = open_session("peer", listen=[f"tcp/127.0.0.1:{free_port()}"], connect=[args.connect])
    except ConfigError as exc:
        print(f"human_feed: error: {exc}", file=sys.stderr)
        return 2
    keys = KeySpace(args.prefix)
    try:
        if not await_liveliness(session, keys.alive("tracker_ingest"), 30.0):
            print("human_feed: error: tracker_ingest is not reachable", file=sys.stderr)
            return 1
        # everything that takes time before READY: the first sample is due at the t0 the parent sends, and
        # realtime()'s full collection alone took 60-70 ms (the cell stood without a person for that long)
        feed = HumanFeed(session, keys, human, 0.0, source=args.source, latency=args.latency, lead_in=LEAD_IN)
        signal.signal(signal.SIGTERM, lambda *_: setattr(feed, "running", False))
        human.at(0.0)                                 # its first evaluation before SCHED_FIFO, not under it
        scheduling = realtime("human_feed")
        print(READY, flush=True)
        line = sys.stdin.readline()
        if not line.strip():                          # the parent went away before the start
            return 0
        try:
            feed.t0 = float(line)
        except ValueError:
            print(f"human_feed: error: the start must be a monotonic time in s, not {line.strip()[:40]!r}",
                  file=sys.stderr)
            return 2
        print(f"human_feed: sending at {feed.rate:.1f} Hz, {scheduling}", flush=True)
        feed.run()                                    # this thread, until SIGTERM
        args.stats.write_text(json.dumps(feed.figures()))
        return 0
    finally:
        session.close()


if __name__ == "__main__":
    sys.exit(main())
