"""Takes docs/view.png: a run's recording.rrd in rerun's web viewer, served on loopback, photographed by a
headless Chromium at a moment of the run (--at: typed into the viewer's time field; default the end).
Tools beyond the project's own: Debian's chromium and the playwright package (`pip install playwright`;
it drives the system's Chromium and downloads nothing).

    .venv/bin/hrc demo --duration 16 --out /tmp/view-run
    .venv/bin/python docs/view_screenshot.py /tmp/view-run/recording.rrd docs/view.png --at 14.2
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tools.launch import free_port  # noqa: E402
from tools.view import no_analytics, rerun_binary  # noqa: E402

CHROMIUM_FLAGS = ["--no-sandbox", "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--no-first-run", "--disable-quic", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                  "--ignore-gpu-blocklist"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("recording", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--at", type=float, default=None, help="seconds into the run to show (default: the end)")
    parser.add_argument("--wait", type=float, default=30.0, help="seconds to let the viewer load (software GL)")
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    no_analytics()                        # the viewer started below inherits it
    grpc, web = free_port(), free_port()
    server = subprocess.Popen([rerun_binary(), "--serve-web", "--bind", "127.0.0.1", "--port", str(grpc),
                               "--web-viewer-port", str(web), str(args.recording)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(3.0)
        url = f"http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc}%2Fproxy"
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path="/usr/bin/chromium", headless=True, args=CHROMIUM_FLAGS)
            page = browser.new_page(viewport={"width": 1500, "height": 850})
            page.goto(url)
            time.sleep(args.wait)
            if args.at is not None:
                page.mouse.click(1420, 835)                       # the time panel's time field
                page.keyboard.press("Control+A")
                page.keyboard.type(f"+{args.at:.3f}s")
                page.keyboard.press("Enter")
                time.sleep(8.0)
            page.screenshot(path=str(args.out))
            browser.close()
    finally:
        server.terminate()
        try:
            server.wait(timeout=5)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()
    print(f"{args.out} taken from {args.recording}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
