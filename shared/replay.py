"""Recorded or scripted human motion for replay: frames of capsules at their own times (pure loader).

CSV (one row per capsule per frame; frames in order of t):

    t,ax,ay,az,bx,by,bz,radius
    0.00,-1.2,0.0,0.90,-1.2,0.0,1.45,0.17
    0.00,-1.0,-0.2,1.40,-0.8,-0.2,1.10,0.06
    0.02,...

JSON: {"schema": "hrc-human-replay/1", "frames": [{"t": 0.0, "capsules": [{"a": [x, y, z], "b": [x, y, z],
"radius": r}, ...]}, ...]}

Units: s, m (robot base frame). Times start anywhere, never decrease; numbers are finite; radii
positive; at most MAX_FRAMES frames. A malformed file raises ConfigError naming the line or frame and
the field.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from shared.errors import ConfigError

SCHEMA = "hrc-human-replay/1"
MAX_FRAMES = 1_000_000
CSV_FIELDS = ["t", "ax", "ay", "az", "bx", "by", "bz", "radius"]


@dataclass(frozen=True)
class ReplayFrame:
    t: float
    segments: np.ndarray       # (M, 2, 3)
    radii: np.ndarray          # (M,)


def _finite(value, where: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{where}: expected a number, got {value!r}") from None
    if isinstance(value, bool) or not math.isfinite(number):
        raise ConfigError(f"{where}: expected a finite number, got {value!r}")
    return number


def _frames_from_rows(rows: list[tuple[str, float, list[float], float]]) -> list[ReplayFrame]:
    frames: list[ReplayFrame] = []
    current_t, segs, radii = None, [], []
    for where, t, ab, r in rows:
        if r <= 0:
            raise ConfigError(f"{where}: radius must be positive, got {r}")
        if current_t is not None and t < current_t:
            raise ConfigError(f"{where}: t = {t} goes back in time (previous {current_t})")
        if current_t is not None and t != current_t:
            frames.append(ReplayFrame(current_t, np.array(segs).reshape(-1, 2, 3), np.array(radii)))
            segs, radii = [], []
        current_t = t
        segs.append(ab)
        radii.append(r)
        if len(frames) > MAX_FRAMES:
            raise ConfigError(f"{where}: more than {MAX_FRAMES} frames")
    if current_t is not None:
        frames.append(ReplayFrame(current_t, np.array(segs).reshape(-1, 2, 3), np.array(radii)))
    if not frames:
        raise ConfigError("replay: no frames")
    return frames


def parse_csv(text: str, name: str = "replay") -> list[ReplayFrame]:
    reader = csv.reader(io.StringIO(text))
    header = next(reader, None)
    if header is None or [h.strip() for h in header] != CSV_FIELDS:
        raise ConfigError(f"{name}: line 1: expected the header {','.join(CSV_FIELDS)}")
    rows = []
    for line, row in enumerate(reader, start=2):
        if not row or all(not cell.strip() for cell in row):
            continue
        where = f"{name}: line {line}"
        if len(row) != len(CSV_FIELDS):
            raise ConfigError(f"{where}: expected {len(CSV_FIELDS)} values, got {len(row)}")
        values = [_finite(v, f"{where}: {field}") for v, field in zip(row, CSV_FIELDS)]
        rows.append((where, values[0], values[1:7], values[7]))
    return _frames_from_rows(rows)


def parse_json(text: str, name: str = "replay") -> list[ReplayFrame]:
    try:
        doc = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as exc:
        raise ConfigError(f"{name}: not valid JSON: {exc}") from None
    if not isinstance(doc, dict) or doc.get("schema") != SCHEMA or not isinstance(doc.get("frames"), list):
        raise ConfigError(f"{name}: expected {{\"schema\": \"{SCHEMA}\", \"frames\": [...]}}")
    rows = []
    for i, frame in enumerate(doc["frames"]):
        where = f"{name}: frames[{i}]"
        if not isinstance(frame, dict) or not isinstance(frame.get("capsules"), list):
            raise ConfigError(f"{where}: expected {{\"t\": ..., \"capsules\": [...]}}")
        t = _finite(frame.get("t"), f"{where}.t")
        for j, cap in enumerate(frame["capsules"]):
            w = f"{where}.capsules[{j}]"
            if not isinstance(cap, dict):
                raise ConfigError(f"{w}: expected {{\"a\", \"b\", \"radius\"}}")
            ab = []
            for end in ("a", "b"):
                point = cap.get(end)
                if not isinstance(point, list) or len(point) != 3:
                    raise ConfigError(f"{w}.{end}: expected three numbers")
                ab += [_finite(v, f"{w}.{end}") for v in point]
            rows.append((w, t, ab, _finite(cap.get("radius"), f"{w}.radius")))
    return _frames_from_rows(rows)


def load_replay(path: str | Path) -> list[ReplayFrame]:
    """Read a .csv or .json replay file (by extension; anything else is tried as JSON, then CSV)."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read: {exc}") from None
    if path.suffix.lower() == ".csv":
        return parse_csv(text, str(path))
    return parse_json(text, str(path))
