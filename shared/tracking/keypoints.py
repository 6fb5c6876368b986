"""From 3D body keypoints (motion capture, a skeleton tracker) to the capsules the cell works with (pure).

Input CSV, one row per keypoint per person per frame, rows of a frame together, frames in order of t:

    t,person,keypoint,x,y,z
    0.000,alice,head,120.0,-1050.0,1650.0
    0.000,alice,l_shoulder,...

Keypoints: head, l_shoulder, r_shoulder, l_elbow, r_elbow, l_hand, r_hand, l_hip, r_hip (others are
ignored). Each person becomes eight capsules: the torso (mid-hip to mid-shoulder), the head (a sphere),
each upper arm (shoulder to elbow), each forearm (elbow to hand) and each hand (a sphere). A skeleton of the
arms alone (shoulders, elbows, wrists as hands: what most camera trackers see of a person at a table)
becomes seven: the arms', and a torso assumed on the vertical through the mid-shoulder point from the hips
to the top of the head (``body_capsules``). The human-assembly recordings (RealSense + OpenPose, 18 numbers
a row) are read by ``read_assembly``.

Radii: the 95th percentiles of DIN 33402-2:2020-12 (body dimensions of adults in Germany), as SaRA takes
them for its capsule model of the human (Thumm et al., SaRA-shield, human_reach config): torso diameter
0.434 m, head 0.434 m (the torso's, an over-approximation), upper arm 0.200 m and forearm 0.132 m (the
standard gives no arm circumferences; the thigh and calf values over-approximate them), hand 0.206 m.
Every radius is half its diameter: the capsules enclose the tracked limbs of 95 % of adults.

The frame transform takes the input to the robot base frame: p_base = R_z(yaw) (S p) + translation, S
swapping a y-up capture volume to z-up where asked, or turning a camera's optical frame (facing the
person) so that the person faces +x, after scaling to metres. A person missing any of the
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
ARM_KEYPOINTS = ("l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_hand", "r_hand")
# An arm-only skeleton (a camera tracker that sees the upper limbs) gets a torso on the vertical through the
# mid-shoulder point, from an assumed hip height up to an assumed top of the head: DIN 33402-2 (adults,
# 50th percentiles) puts the shoulders about 0.5 m above the hip joints and the top of the head about 0.3 m
# above the shoulders. The torso's radius (0.217 m) encloses the head's.
HIP_BELOW_SHOULDER = 0.5     # m
HEAD_ABOVE_SHOULDER = 0.3    # m
# The human-assembly recordings (RealSense D415 + OpenPose): 18 numbers a row, in this order, metres in the
# camera's optical frame (x right, y down, z forward); the source gives no frame rate.
ASSEMBLY_KEYPOINTS = ("l_hand", "r_hand", "l_elbow", "r_elbow", "l_shoulder", "r_shoulder")
ASSEMBLY_RATE = 30.0         # Hz: the camera's usual depth-and-colour rate, the rate assumed where none is given
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
    camera: bool = False

    def apply(self, p: np.ndarray) -> np.ndarray:
        """p (..., 3) in the input's units and frame -> the robot base frame (m). With ``camera`` the input is a
        camera's optical frame (x right, y down, z forward) facing the person: it is turned so that the person
        faces +x, up is +z and their left is +y (x_base = -z, y_base = x, z_base = -y), before the yaw."""
        p = np.asarray(p, dtype=float) * self.scale
        if self.camera:
            p = np.stack([-p[..., 2], p[..., 0], -p[..., 1]], axis=-1)
        elif self.y_up:                                 # (x, y_up, z_toward) -> (x, -z, y)
            p = np.array([p[..., 0], -p[..., 2], p[..., 1]]).T if p.ndim > 1 else np.array([p[0], -p[2], p[1]])
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return p @ rot.T + np.asarray(self.translation)


def body_capsules(points: dict[str, np.ndarray]) -> list[tuple[str, np.ndarray, np.ndarray, float]]:
    """(name, a, b, radius) of one person's capsules (base frame, m): from the nine keypoints eight (torso,
    head, and each arm's upper arm, forearm and hand); from the six arm keypoints alone seven, the torso
    assumed on the vertical through the mid-shoulder point from the hips to the top of the head
    (HIP_BELOW_SHOULDER, HEAD_ABOVE_SHOULDER)."""
    mid_shoulder = (points["l_shoulder"] + points["r_shoulder"]) / 2
    if all(k in points for k in KEYPOINTS):
        mid_hip = (points["l_hip"] + points["r_hip"]) / 2
        out = [("torso", mid_hip, mid_shoulder, DIAMETER["torso"] / 2),
               ("head", points["head"], points["head"], DIAMETER["head"] / 2)]
    else:
        up = np.array([0.0, 0.0, 1.0])
        out = [("torso", mid_shoulder - HIP_BELOW_SHOULDER * up, mid_shoulder + HEAD_ABOVE_SHOULDER * up,
                DIAMETER["torso"] / 2)]
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


def read_assembly(text: str, name: str = "recording", rate: float = ASSEMBLY_RATE) -> list[tuple[float, dict]]:
    """Frames of the human-assembly format (one row a time step, 18 numbers: ASSEMBLY_KEYPOINTS' xyz), one
    person ('person'), at `rate` Hz from t = 0. A keypoint with a NaN (OpenPose did not find it) is left out,
    so its frame becomes a dropout; a row of another length, or a value that is no number, is refused
    naming the line."""
    if not (math.isfinite(rate) and rate > 0):
        raise ConfigError(f"{name}: the frame rate must be a positive number of Hz, got {rate!r}")
    frames = []
    for line_no, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        cells = line.split()
        if len(cells) != 3 * len(ASSEMBLY_KEYPOINTS):
            raise ConfigError(f"{name}: line {line_no}: expected {3 * len(ASSEMBLY_KEYPOINTS)} numbers (xyz of "
                              f"{', '.join(ASSEMBLY_KEYPOINTS)}), got {len(cells)}")
        values = np.empty(len(cells))
        for k, cell in enumerate(cells):
            try:
                values[k] = float(cell)
            except ValueError:
                raise ConfigError(f"{name}: line {line_no}: {cell!r} is not a number") from None
        body = {k: values[3 * i:3 * i + 3] for i, k in enumerate(ASSEMBLY_KEYPOINTS)
                if np.all(np.isfinite(values[3 * i:3 * i + 3]))}
        frames.append((len(frames) / rate, {"person": body}))
    if not frames:
        raise ConfigError(f"{name}: no frames")
    return frames


def to_motion(frames, transform: FrameTransform) -> tuple[dict, int]:
    """The motion document (schema hrc-human-motion/1) and how many frames became dropouts."""
    out, dropouts = [], 0
    for t, people in frames:
        entry: dict = {"t": t, "people": []}
        for person, body in people.items():
            wanted = KEYPOINTS if any(k in body for k in ("head", "l_hip", "r_hip")) else ARM_KEYPOINTS
            missing = [k for k in wanted if k not in body]
            if missing:                      # partly seen: the robot stops, never guesses
                entry = {"t": t, "dropout": True, "label": f"{person}: no {', '.join(missing)}"}
                dropouts += 1
                break
            points = {k: transform.apply(body[k]) for k in wanted}
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


def convert(src: Path, dst: Path, transform: FrameTransform, fmt: str = "keypoints",
            rate: float = ASSEMBLY_RATE, every: int = 1) -> tuple[int, int]:
    """Read keypoints from src (fmt 'keypoints': the CSV above; 'assembly': the human-assembly rows at
    `rate` Hz), write the motion to dst (.csv or .json by extension); (frames, dropouts). every: keep the first
    frame and every every-th after it, each at its own time: the same person as a tracker at 1/every the rate
    would see them (a 30 Hz recording, every 2: a 15 Hz camera), to measure the cell with a slower tracker."""
    if isinstance(every, bool) or not isinstance(every, int) or every < 1:
        raise ConfigError(f"every: expected a whole number >= 1, got {every!r}")
    try:
        text = Path(src).read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{src}: cannot read: {exc}") from None
    frames = read_assembly(text, str(src), rate) if fmt == "assembly" else read_keypoints(text, str(src))
    doc, dropouts = to_motion(frames[::every], transform)
    body = motion_csv(doc) if Path(dst).suffix.lower() == ".csv" else json.dumps(doc, indent=None)
    Path(dst).write_text(body)
    return len(doc["frames"]), dropouts
