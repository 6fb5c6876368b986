"""router: a Zenoh router process (PyPI has no zenohd; a zenoh-python session in router mode is one).

For a cell spread over several hosts, every service connects to it as a client. On one host it is
optional (the services mesh as peers). Multicast scouting is off; endpoints are loopback unless
--allow-remote (then the cell network's address, never a wildcard the guide forbids here).

    python -m services.router --listen tcp/127.0.0.1:7447
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading

from services.common import setup_logging
from shared.errors import HrcError
from shared.keys import KeySpace
from shared.zenoh_session import open_session


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="router", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--listen", nargs="+", default=["tcp/127.0.0.1:7447"])
    parser.add_argument("--prefix", default="hrc/cell1")
    parser.add_argument("--allow-remote", action="store_true", help="listen on a non-loopback address")
    parser.add_argument("--log-level", default="INFO")
    args = parser.parse_args(argv)
    setup_logging(args.log_level)
    try:
        session = open_session("router", listen=args.listen, allow_remote=args.allow_remote)
        token = session.liveliness().declare_token(KeySpace(args.prefix).alive("router"))
    except HrcError as exc:
        print(f"router: error: {exc}", file=sys.stderr)
        return 2
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    print(f"router: Zenoh router on {', '.join(args.listen)}", flush=True)
    stop.wait()
    token.undeclare()
    session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
