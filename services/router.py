"""router: a Zenoh router process (PyPI has no zenohd; a zenoh-python session in router mode is one).

For a cell spread over several hosts, every service connects to it as a client. On one host it is
optional (the services mesh as peers). Multicast scouting is off; endpoints are loopback unless
--allow-remote (then the cell network's address).

Secured (deploy/zenoh/secure-router.json5 is the same as a file): --tls-dir makes every link mutual TLS
with the cell's certificates (shared.transport.pki; the router's own identity is 'router'), and --acl turns on the
access control of shared.transport.acl for --prefix: a publication is taken only from the identity allowed to
publish on that key (only the scaler commands the robot, only tracker_ingest publishes human states).

    python -m services.router --listen tcp/127.0.0.1:7447
    python -m services.router --listen tls/10.0.0.2:7447 --allow-remote --tls-dir /etc/hrc/tls --acl
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path

from services.common import setup_logging
from shared.core.errors import HrcError
from shared.transport.acl import access_control
from shared.transport.pki import TlsIdentity
from shared.transport.zenoh_session import open_session
from shared.wire.keys import KeySpace


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="router", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--listen", nargs="+", default=["tcp/127.0.0.1:7447"])
    parser.add_argument("--prefix", default="hrc/cell1")
    parser.add_argument("--allow-remote", action="store_true", help="listen on a non-loopback address")
    parser.add_argument("--tls-dir", type=Path, default=None, metavar="DIR",
                        help="mutual TLS with the cell's certificates in DIR (ca.pem, router.pem, router-key.pem)")
    parser.add_argument("--acl", action="store_true",
                        help="access control: each key takes publications only from its allowed identity "
                             "(needs --tls-dir: identities are certificate names)")
    parser.add_argument("--log-level", default="INFO")
    args = parser.parse_args(argv)
    setup_logging(args.log_level)
    if args.acl and args.tls_dir is None:
        print("router: error: --acl needs --tls-dir (sessions are identified by their certificates)", file=sys.stderr)
        return 2
    try:
        tls = TlsIdentity.from_dir(args.tls_dir, "router") if args.tls_dir else None
        session = open_session("router", listen=args.listen, allow_remote=args.allow_remote, tls=tls,
                               access_control=access_control(args.prefix) if args.acl else None)
        token = session.liveliness().declare_token(KeySpace(args.prefix).alive("router"))
    except HrcError as exc:
        print(f"router: error: {exc}", file=sys.stderr)
        return 2
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    print(f"router: Zenoh router on {', '.join(args.listen)}{', mutual TLS' if tls else ''}"
          f"{', access control for ' + args.prefix if args.acl else ''}", flush=True)
    stop.wait()
    token.undeclare()
    session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
