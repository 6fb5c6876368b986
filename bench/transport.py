"""The first messages on a fresh Zenoh link (not a test: it prints figures).

Two Zenoh peers of the cell's own session configuration (``shared.transport.zenoh_session``: loopback, multicast
scouting off) on a fresh link, one publishing to the other: for each message size, `--puts` puts `--gap` s apart,
each with how long ``put`` blocked the caller and how long after the put the subscriber had it; each size on a new
pair of sessions. Why: on eclipse-zenoh 1.10.2 the second message larger than about 4 KB that a process sent over a
link blocked the publisher 10-16 ms and came 13-21 ms late, every other one 0.1-0.3 ms (once a process: a later
fresh link's are not); in the cell, the planner's second trajectory (26 KB) held the robot at its first goal 50-191
ms (docs/measurements.md, session 86). A Zenoh upgrade that changes this shows here. `--warm` runs the planner's own
start-up warm-up first (``warm_up_transport``): what it saves. Run sizes one at a time to see each size's first
link. Last line: one JSON object.

    python bench/transport.py [--sizes 2000,8000,26000] [--puts 5] [--gap 0.2] [--warm]
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from shared.transport.zenoh_session import open_session, warm_up_transport  # noqa: E402
from tools.launch import free_port  # noqa: E402

DELIVERY_WAIT = 1.0      # s: a message not delivered by then counts as lost (None)


def fresh_link(size: int, puts: int, gap: float) -> list[dict]:
    """`puts` messages of `size` bytes over a new link: per put, the ms it blocked and the ms until delivery."""
    port = free_port()
    publisher = open_session("peer", listen=[f"tcp/127.0.0.1:{port}"])
    subscriber = open_session("peer", listen=[f"tcp/127.0.0.1:{free_port()}"], connect=[f"tcp/127.0.0.1:{port}"])
    arrived: list[float] = []
    came = threading.Event()

    def on_sample(_sample) -> None:
        arrived.append(time.monotonic())
        came.set()

    sub = subscriber.declare_subscriber("bench/transport/data", on_sample)
    try:
        time.sleep(1.0)                       # the link up, the subscription known on both sides
        payload = b"x" * size
        pub = publisher.declare_publisher("bench/transport/data")
        rows = []
        for _ in range(puts):
            came.clear()
            before = len(arrived)
            sent = time.monotonic()
            pub.put(payload)
            blocked = time.monotonic() - sent
            came.wait(DELIVERY_WAIT)
            delivered = arrived[before] - sent if len(arrived) > before else None
            rows.append({"put_ms": round(blocked * 1e3, 2),
                         "delivered_ms": None if delivered is None else round(delivered * 1e3, 2)})
            time.sleep(gap)
        return rows
    finally:
        sub.undeclare()
        subscriber.close()
        publisher.close()


def said(delivered_ms: float | None) -> str:
    """A delivery time as printed: ms with one decimal, or 'lost'."""
    return "lost" if delivered_ms is None else f"{delivered_ms:.1f}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", default="2000,8000,26000", help="message sizes in bytes, comma-separated")
    parser.add_argument("--puts", type=int, default=5, help="puts per size (default 5)")
    parser.add_argument("--gap", type=float, default=0.2, help="s between puts (default 0.2)")
    parser.add_argument("--warm", action="store_true", help="the planner's transport warm-up first")
    args = parser.parse_args(argv)
    try:
        sizes = [int(s) for s in args.sizes.split(",") if s.strip()]
    except ValueError:
        parser.error(f"--sizes takes byte counts separated by commas, not {args.sizes!r}")
    if not sizes or min(sizes) < 1 or args.puts < 1 or not args.gap >= 0.0:
        parser.error("--sizes must be positive byte counts, --puts at least 1, --gap at least 0")
    import zenoh

    warmed = warm_up_transport() if args.warm else None
    results = {}
    for size in sizes:
        rows = fresh_link(size, args.puts, args.gap)
        results[str(size)] = rows
        shown = "  ".join(f"{r['put_ms']:.1f}/{said(r['delivered_ms'])}" for r in rows)
        print(f"{size:>7} B{' (process warmed)' if args.warm else ''}: put blocked / delivered after (ms): {shown}",
              flush=True)
    print(json.dumps({"bench": "transport", "zenoh": getattr(zenoh, "__version__", "?"), "warmed": warmed,
                      "gap_s": args.gap, "sizes": results}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
