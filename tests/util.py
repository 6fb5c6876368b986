"""Helpers the tests share: a free loopback port, and the private network namespace the multi-process
tests need (they skip, saying why and what covers the same behaviour, where it cannot be made)."""

from __future__ import annotations

import pytest

from tools.cell import namespace_reason
from tools.launch import free_port

__all__ = ["free_port", "namespace_reason", "require_namespace"]


def require_namespace(covered_by: str) -> None:
    """Skip the calling test, printing why, when no private network namespace can be made."""
    reason = namespace_reason()
    if reason:
        print(f"SKIP: no private network namespace ({reason}); {covered_by}")
        pytest.skip(reason)
