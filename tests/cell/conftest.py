"""Every test in this folder starts a process, a private network namespace or a Zenoh session: marked ``cell``
here, by the folder, so that ``make check`` (``-m "not cell"``) is process-free by construction."""

from __future__ import annotations

from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent


def pytest_collection_modifyitems(config, items):
    for item in items:
        if HERE in Path(item.fspath).resolve().parents:
            item.add_marker(pytest.mark.cell)
