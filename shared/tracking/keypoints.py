"""From 3D body keypoints (motion capture, a skeleton tracker) to the capsules the cell works with (pure).

Input CSV, one row per keypoint per person per frame, rows of a frame together, frames in order of t:

    t,person,keypoint,x,y,z
    0.000,alice,head,120.0,-1050.0,1650.0
    0.000,alice,l_shoulder,...

Keypoints: head, l_shoulder, r_shoulder, l_elbow, r_elbow, l_hand, r_hand, l_hip, r_hip (others are
ignored). Each person becomes eight capsules: the torso (mid-hip to mid-shoulder), the head (a sphere),
each upper arm (shoulder to elbow), each forearm (elbow to hand) and each hand (a sphere).

Radii: the 95th percentiles of DIN 33402-2:2020-12 (body dimensions of adults in Germany), as SaRA takes
them for its capsule model of the human (Thumm et al., SaRA-shield, human_reach config): torso diameter
0.434 m, head 0.434 m (the torso's, an over-approximation), upper arm 0.200 m and forearm 0.132 m (the
standard gives no arm circumferences; the thigh and calf values over-approximate them), hand 0.206 m.
Every radius is half its diameter: the capsules enclose the tracked limbs of 95 % of adults.

The frame transform takes the input to the robot base frame: p_base = R_z(yaw) (S p) + translation, S
swapping a y-up capture volume to z-up where asked, after scaling to metres. A person missing any of the
keypoints in a frame makes that frame a dropout (the tracker did not see the whole body: the robot
stops, never guesses). A malformed file raises ConfigError naming the line and field.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from shared.core.errors import ConfigError
from shared.tracking.motion import CSV_FIELDS, SCHEMA, csv_rows, finite

KEYPOINTS = ("head", "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_hand", "r_hand", "l_hip", "r_hip")
DIAMETER = {"torso": 0.434, "head": 0.434, "upper_arm": 0.200, "forearm": 0.132, "hand": 0.206}   # m
INPUT_FIELDS = ["t", "person", "keypoint", "x", "y", "z"]
UNITS = {"m": 1.0, "mm": 1e-3, "cm": 1e-2}


@dataclass(frozen=True)
class FrameTransform:
    """Input to robot base frame: scale (to m), optional y-up -> z-up swap, yaw about z (rad), translation (m)."""

    scale: float = 1.0
    y_up: bool = False
    yaw: float = 0.0
    translation: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def apply(self, p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, dtype=float) * self.scale
        if self.y_up:                                   # (x, y_up, z_toward) -> (x, -z, y)
            p = np.array([p[..., 0], -p[..., 2], p[..., 1]]).T if p.ndim > 1 else np.array([p[0], -p[2], p[1]])
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return p @ rot.T + np.asarray(self.translation)


def body_capsules(points: dict[str, np.ndarray]) -> list[tuple[str, np.ndarray, np.ndarray, float]]:
    """(name, a, b, radius) of the eight capsules of one person from the nine keypoints (base frame, m)."""
    mid_hip = (points["l_hip"] + points["r_hip"]) / 2
    mid_shoulder = (points["l_shoulder"] + points["r_shoulder"]) / 2
    out = [("torso", mid_hip, mid_shoulder, DIAMETER["torso"] / 2),
           ("head", points["head"], points["head"], DIAMETER["head"] / 2)]
    for side in ("l", "r"):
        out += [(f"{side}_upper_arm", points[f"{side}_shoulder"], points[f"{side}_elbow"], DIAMETER["upper_arm"] / 2),
                (f"{side}_forearm", points[f"{side}_elbow"], points[f"{side}_hand"], DIAMETER["forearm"] / 2),
                (f"{side}_hand", points[f"{side}_hand"], points[f"{side}_hand"], DIAMETER["hand"] / 2)]
    return out


def read_keypoints(text: str, name: str = "keypoints") -> list[tuple[float, dict[str, dict[str, np.ndarray]]]]:
    """Frames (t, {person: {keypoint: xyz in the input's units and frame}}), in order of t."""
    _, rows = csv_rows(text, name, [INPUT_FIELDS])
    frames: list[tuple[float, dict[str, dict[str, np.ndarray]]]] = []
    for where, row in rows:
        t = finite(row[0], f"{where}: t")
        person, keypoint = row[1].strip(), row[2].strip()
        if not person:
            raise ConfigError(f"{where}: person: expected a name")
        if not keypoint:
            raise ConfigError(f"{where}: keypoint: expected a name")
        xyz = np.array([finite(v, f"{where}: {axis}") for v, axis in zip(row[3:], "xyz")])
        if frames and t < frames[-1][0]:
            raise ConfigError(f"{where}: t = {t} goes back in time (previous frame at {frames[-1][0]})")
        if not frames or t > frames[-1][0]:
            frames.append((t, {}))
        body = frames[-1][1].setdefault(person, {})
        if keypoint in body:
            raise ConfigError(f"{where}: keypoint {keypoint!r} of {person!r} twice in the frame at t = {t}")
        body[keypoint] = xyz
    if not frames:
        raise ConfigError(f"{name}: no frames")
    return frames


def to_motion(frames, transform: FrameTransform) -> tuple[dict, int]:
    """The motion document (schema hrc-human-motion/1) and how many frames became dropouts."""
    out, dropouts = [], 0
    for t, people in frames:
        entry: dict = {"t": t, "people": []}
        for person, body in people.items():
            missing = [k for k in KEYPOINTS if k not in body]
            if missing:
                entry = {"t": t, "dropout": True, "label": f"{person}: no {', '.join(missing)}"}
                dropouts += 1
                break
            points = {k: transform.apply(body[k]) for k in KEYPOINTS}
            entry["people"].append({"id": person, "capsules": [
                {"name": n, "a": [round(float(v), 5) for v in a], "b": [round(float(v), 5) for v in b],
                 "radius": r} for n, a, b, r in body_capsules(points)]})
        out.append(entry)
    return {"schema": SCHEMA, "frames": out}, dropouts


def motion_csv(doc: dict) -> str:
    """The same motion in the CSV format of shared.tracking.motion."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(CSV_FIELDS)
    for frame in doc["frames"]:
        if frame.get("dropout"):
            writer.writerow([frame["t"], "", "dropout"] + [""] * 7)
            continue
        if not frame["people"]:
            writer.writerow([frame["t"], "", "nobody"] + [""] * 7)
        for person in frame["people"]:
            for cap in person["capsules"]:
                writer.writerow([frame["t"], person["id"], cap["name"], *cap["a"], *cap["b"], cap["radius"]])
    return buf.getvalue()


def convert(src: Path, dst: Path, transform: FrameTransform) -> tuple[int, int]:
    """Read keypoints from src, write the motion to dst (.csv or .json by extension); (frames, dropouts)."""
    try:
        text = Path(src).read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{src}: cannot read: {exc}") from None
    doc, dropouts = to_motion(read_keypoints(text, str(src)), transform)
    body = motion_csv(doc) if Path(dst).suffix.lower() == ".csv" else json.dumps(doc, indent=None)
    Path(dst).write_text(body)
    return len(doc["frames"]), dropouts
