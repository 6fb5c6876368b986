"""Recorded or scripted human motion: frames of people made of named capsules, at their own times (pure).

The format (docs/human-motion.md has it in full, with examples). Units: s, m, robot base frame.

JSON, schema "hrc-human-motion/1":

    {"schema": "hrc-human-motion/1",
     "frames": [
       {"t": 0.0, "label": "walking in",
        "people": [{"id": "alice", "capsules": [{"name": "torso", "a": [x, y, z], "b": [x, y, z], "radius": r},
                                               ...]},
                   {"id": "bob", "capsules": [...]}]},
       {"t": 0.5, "dropout": true},          # the tracker saw nobody, though someone may be there
       {"t": 0.7, "people": []},             # the cell is empty
       ...]}

CSV, one row per capsule per frame, rows of a frame together, frames in order of t:

    t,person,capsule,ax,ay,az,bx,by,bz,radius
    0.00,alice,torso,-1.2,0.0,0.90,-1.2,0.0,1.45,0.17
    0.00,alice,forearm,-1.0,-0.2,1.40,-0.8,-0.2,1.10,0.06
    0.50,,dropout,,,,,,,
    0.70,,nobody,,,,,,,

A frame holds until the next one. Times start anywhere and increase from frame to frame; numbers are
finite, radii positive, a person's id and a capsule's name non-empty. The first replay format (schema
"hrc-human-replay/1"; CSV header t,ax,ay,az,bx,by,bz,radius: one anonymous person) is read too. A
malformed file raises ConfigError naming the line or frame and the field.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from shared.core.errors import ConfigError
from shared.core.humans import HumanCapsules

SCHEMA = "hrc-human-motion/1"
SCHEMA_V1 = "hrc-human-replay/1"
MAX_FRAMES = 1_000_000
CSV_FIELDS = ["t", "person", "capsule", "ax", "ay", "az", "bx", "by", "bz", "radius"]
CSV_FIELDS_V1 = ["t", "ax", "ay", "az", "bx", "by", "bz", "radius"]
DROPOUT, NOBODY = "dropout", "nobody"


@dataclass(frozen=True)
class ReplayFrame:
    """One frame: capsule end points (M, 2, 3) and radii (M,), each capsule's person and name; dropout:
    the tracker saw nobody (nothing is published while it holds); label: what happens (optional)."""

    t: float
    segments: np.ndarray
    radii: np.ndarray
    people: tuple[str, ...] = ()
    names: tuple[str, ...] = ()
    dropout: bool = False
    label: str = ""

    def capsules(self) -> HumanCapsules | None:
        """The frame as capsules (velocities unknown: a tracker measures them), None in a dropout."""
        if self.dropout:
            return None
        return HumanCapsules.from_arrays(self.segments, self.radii)


def finite(value, where: str) -> float:
    """value as a finite float, else ConfigError naming where."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{where}: expected a number, got {value!r}") from None
    if isinstance(value, bool) or not math.isfinite(number):
        raise ConfigError(f"{where}: expected a finite number, got {value!r}")
    return number


def _text(value, where: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(f"{where}: expected a non-empty name, got {value!r}")
    return value.strip()


@dataclass
class _Building:
    t: float
    where: str
    segs: list
    radii: list
    people: list
    names: list
    dropout: bool = False
    label: str = ""

    def frame(self) -> ReplayFrame:
        return ReplayFrame(self.t, np.array(self.segs, dtype=float).reshape(-1, 2, 3), np.array(self.radii, dtype=float),
                           tuple(self.people), tuple(self.names), self.dropout, self.label)


def _add(frames: list[_Building], where: str, t: float, same_frame_ok: bool) -> _Building:
    """The frame for time t: the current one when t equals its time (and rows may share it), else a new
    one after it. Raises ConfigError when t goes back."""
    if frames:
        last = frames[-1]
        if t < last.t:
            raise ConfigError(f"{where}: t = {t} goes back in time (previous frame at {last.t})")
        if t == last.t and not same_frame_ok:
            raise ConfigError(f"{where}: t = {t} repeats the previous frame's time")
        if t == last.t:
            return last
    if len(frames) >= MAX_FRAMES:
        raise ConfigError(f"{where}: more than {MAX_FRAMES} frames")
    frames.append(_Building(t, where, [], [], [], []))
    return frames[-1]


def _capsule(frame: _Building, where: str, ab: list[float], radius: float, person: str, name: str) -> None:
    if frame.dropout:
        raise ConfigError(f"{where}: a dropout frame holds no capsules")
    if radius <= 0:
        raise ConfigError(f"{where}: radius must be positive, got {radius}")
    frame.segs.append(ab)
    frame.radii.append(radius)
    frame.people.append(person)
    frame.names.append(name)


def _finish(frames: list[_Building], name: str) -> list[ReplayFrame]:
    if not frames:
        raise ConfigError(f"{name}: no frames")
    return [f.frame() for f in frames]


def csv_rows(text: str, name: str, headers: list[list[str]]) -> tuple[list[str], Iterator[tuple[str, list[str]]]]:
    """The header of a CSV text (one of `headers`, the first named in the error otherwise) and its
    non-blank rows, each with its place ('name: line N') and checked to hold as many values as the header
    (the motion files here, the keypoint files of shared.tracking.keypoints)."""
    reader = csv.reader(io.StringIO(text))
    header = next(reader, None)
    fields = [h.strip() for h in header] if header is not None else None
    if fields not in headers:
        raise ConfigError(f"{name}: line 1: expected the header {','.join(headers[0])}")

    def rows() -> Iterator[tuple[str, list[str]]]:
        for line, row in enumerate(reader, start=2):
            if not row or all(not cell.strip() for cell in row):
                continue
            where = f"{name}: line {line}"
            if len(row) != len(fields):
                raise ConfigError(f"{where}: expected {len(fields)} values, got {len(row)}")
            yield where, row
    return fields, rows()


def parse_csv(text: str, name: str = "replay") -> list[ReplayFrame]:
    fields, rows = csv_rows(text, name, [CSV_FIELDS, CSV_FIELDS_V1])
    v1 = fields == CSV_FIELDS_V1
    frames: list[_Building] = []
    for where, row in rows:
        t = finite(row[0], f"{where}: t")
        if v1:
            values = [finite(v, f"{where}: {field}") for v, field in zip(row[1:], fields[1:])]
            frame = _add(frames, where, t, True)
            _capsule(frame, where, values[:6], values[6], "person", f"capsule {len(frame.segs)}")
            continue
        person, capsule = row[1].strip(), row[2].strip()
        if not person and capsule in (DROPOUT, NOBODY):
            if any(cell.strip() for cell in row[3:]):
                raise ConfigError(f"{where}: a {capsule} row has no coordinates")
            frame = _add(frames, where, t, False)
            frame.dropout = capsule == DROPOUT
            continue
        person = _text(person, f"{where}: person")
        capsule = _text(capsule, f"{where}: capsule")
        values = [finite(v, f"{where}: {field}") for v, field in zip(row[3:], fields[3:])]
        _capsule(_add(frames, where, t, True), where, values[:6], values[6], person, capsule)
    return _finish(frames, name)


def _point(value, where: str) -> list[float]:
    if not isinstance(value, list) or len(value) != 3:
        raise ConfigError(f"{where}: expected three numbers")
    return [finite(v, where) for v in value]


def parse_json(text: str, name: str = "replay") -> list[ReplayFrame]:
    try:
        doc = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as exc:
        raise ConfigError(f"{name}: not valid JSON: {exc}") from None
    if not isinstance(doc, dict) or doc.get("schema") not in (SCHEMA, SCHEMA_V1) \
            or not isinstance(doc.get("frames"), list):
        raise ConfigError(f"{name}: expected {{\"schema\": \"{SCHEMA}\", \"frames\": [...]}}")
    v1 = doc["schema"] == SCHEMA_V1
    frames: list[_Building] = []
    for i, raw in enumerate(doc["frames"]):
        where = f"{name}: frames[{i}]"
        if not isinstance(raw, dict):
            raise ConfigError(f"{where}: expected an object with \"t\"")
        frame = _add(frames, where, finite(raw.get("t"), f"{where}.t"), False)
        label = raw.get("label", "")
        if not isinstance(label, str):
            raise ConfigError(f"{where}.label: expected text, got {label!r}")
        frame.label = label
        if v1:
            people = [{"id": "person", "capsules": raw.get("capsules")}]
        elif raw.get("dropout", False) is True:
            if raw.get("people"):
                raise ConfigError(f"{where}: a dropout frame holds no people")
            frame.dropout = True
            continue
        elif "dropout" in raw and raw["dropout"] is not False:
            raise ConfigError(f"{where}.dropout: expected true or false, got {raw['dropout']!r}")
        else:
            people = raw.get("people")
            if not isinstance(people, list):
                raise ConfigError(f"{where}.people: expected a list (empty: nobody in the cell)")
        for j, person in enumerate(people):
            pw = where if v1 else f"{where}.people[{j}]"
            if not isinstance(person, dict) or not isinstance(person.get("capsules"), list):
                raise ConfigError(f"{pw}: expected {{\"id\": ..., \"capsules\": [...]}}")
            pid = "person" if v1 else _text(person.get("id"), f"{pw}.id")
            for k, cap in enumerate(person["capsules"]):
                w = f"{pw}.capsules[{k}]"
                if not isinstance(cap, dict):
                    raise ConfigError(f"{w}: expected {{\"name\", \"a\", \"b\", \"radius\"}}")
                cname = f"capsule {k}" if v1 else _text(cap.get("name"), f"{w}.name")
                ab = _point(cap.get("a"), f"{w}.a") + _point(cap.get("b"), f"{w}.b")
                _capsule(frame, w, ab, finite(cap.get("radius"), f"{w}.radius"), pid, cname)
    return _finish(frames, name)


def load_replay(path: str | Path) -> list[ReplayFrame]:
    """Read a .csv or .json motion file (by extension; anything else is read as JSON)."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read: {exc}") from None
    if path.suffix.lower() == ".csv":
        return parse_csv(text, str(path))
    return parse_json(text, str(path))


class RecordedMotion:
    """A motion file as a human for the cell: ``at(t)`` the capsules of the frame holding at t seconds
    from the first frame (None in a dropout), ``phase(t)`` what is happening (the frame's label, else
    who is there), ``duration`` the time of the last frame."""

    def __init__(self, frames: list[ReplayFrame]) -> None:
        if not frames:
            raise ConfigError("a motion needs at least one frame")
        self.frames = frames
        self.t0 = frames[0].t
        self.times = np.array([f.t - self.t0 for f in frames])

    @classmethod
    def load(cls, path: str | Path) -> "RecordedMotion":
        return cls(load_replay(path))

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    @property
    def rate(self) -> float | None:
        """The source's frame rate (Hz): one over the median interval between frames; None for a single frame.
        A feed sends the motion at this rate (each frame once, as its tracker did)."""
        if self.times.size < 2:
            return None
        return 1.0 / float(np.median(np.diff(self.times)))

    def frame(self, t: float) -> ReplayFrame:
        k = int(np.searchsorted(self.times, t, side="right")) - 1
        return self.frames[max(0, k)]

    def at(self, t: float) -> HumanCapsules | None:
        """The frame holding at t, its velocities the change of each capsule (matched by person and name)
        since the frame before, as a tracker would measure them; unknown for a capsule that was not there
        (the ISO 13855 speeds then apply). None in a dropout."""
        k = max(0, int(np.searchsorted(self.times, t, side="right")) - 1)
        frame = self.frames[k]
        caps = frame.capsules()
        if caps is None or k == 0 or self.frames[k - 1].dropout or caps.count == 0:
            return caps
        before = self.frames[k - 1]
        index = {key: i for i, key in enumerate(zip(before.people, before.names))}
        dt = frame.t - before.t
        velocities = np.zeros_like(caps.segments)
        known = np.zeros(caps.count, dtype=bool)
        for i, key in enumerate(zip(frame.people, frame.names)):
            j = index.get(key)
            if j is not None:
                velocities[i] = (frame.segments[i] - before.segments[j]) / dt
                known[i] = True
        return HumanCapsules(caps.segments, caps.radii, velocities, known)

    def phase(self, t: float) -> str:
        f = self.frame(t)
        if f.label:
            return f.label
        if f.dropout:
            return "tracker dropout"
        people = sorted(set(f.people))
        return ", ".join(people) if people else "nobody"

    def people(self) -> list[str]:
        """Every person id in the motion, in order of appearance."""
        return list(dict.fromkeys(p for f in self.frames for p in f.people))
