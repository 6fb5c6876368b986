"""Helpers the tests share: a free loopback port, and the private network namespace the multi-process
tests need (they skip, saying why and what covers the same behaviour, where it cannot be made)."""

from __future__ import annotations

import shutil
import socket
import subprocess

import pytest


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def namespace_reason() -> str | None:
    """Why no private network namespace can be made here, or None when one can."""
    if not shutil.which("unshare") or not shutil.which("ip"):
        return "unshare or ip (iproute2) is not installed"
    probe = subprocess.run(["unshare", "-rn", "true"], capture_output=True, text=True)
    return None if probe.returncode == 0 else f"unshare -rn is not permitted here: {probe.stderr.strip()}"


def require_namespace(covered_by: str) -> None:
    """Skip the calling test, printing why, when no private network namespace can be made."""
    reason = namespace_reason()
    if reason:
        print(f"SKIP: no private network namespace ({reason}); {covered_by}")
        pytest.skip(reason)
