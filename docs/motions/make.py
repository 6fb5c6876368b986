"""Makes the example motions in this folder: keypoints of people of our own making (20 Hz, in mm, as a
capture system writes them), turned into motion files by the project's own converter (shared.tracking.keypoints,
the same as `hrc human from-keypoints`). Run from the project root:

    .venv/bin/python docs/motions/make.py

one_person.json     a person walks up to 1.2 m, reaches towards the robot's path for 4 s, walks away
two_people.json     Alice crosses back and forth at 1.5 m; Bob walks up, stands at 1.0 m and reaches half-way in
reach_stays.json    a person walks up and keeps an arm in the robot's path to the end
dropout.json        a person at 1.3 m; the tracker loses everybody twice for 0.5 s, and sees only part of
                    the body (no right hand) for 1 s
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from shared.tracking.keypoints import FrameTransform, convert  # noqa: E402

HERE = Path(__file__).resolve().parent
RATE = 20.0                      # Hz
TARGET = np.array([-0.45, 0.0, 0.55])   # a point on the robot's shuttle (the paper's arm-in-the-path point)


def keypoints(x: float, y: float, reach: float) -> dict[str, np.ndarray]:
    """A standing person at floor position (x, y) facing the robot's base, the right arm swung from
    hanging (reach 0) to pointing at TARGET (reach 1) with the upper body leaning in as it reaches (the
    shoulders up to 0.3 m forward and 0.25 m lower); metres, robot base frame."""
    facing = -np.array([x, y]) / max(np.hypot(x, y), 1e-9)
    side = np.array([-facing[1], facing[0]])                 # the person's left
    lean_f, lean_z = 0.3 * reach, -0.25 * reach

    def at(forward: float, left: float, z: float, upper: bool = True) -> np.ndarray:
        f, dz = (forward + lean_f, z + lean_z) if upper else (forward, z)
        return np.array([x + f * facing[0] + left * side[0], y + f * facing[1] + left * side[1], dz])

    r_shoulder = at(0.0, -0.2, 1.45)
    aim = TARGET - r_shoulder
    aim /= np.linalg.norm(aim)
    arm = (1 - reach) * np.array([0.0, 0.0, -1.0]) + reach * aim
    arm /= np.linalg.norm(arm)
    return {"head": at(0.0, 0.0, 1.72), "l_shoulder": at(0.0, 0.2, 1.45), "r_shoulder": r_shoulder,
            "l_elbow": at(0.0, 0.25, 1.15), "l_hand": at(0.05, 0.25, 0.88), "r_elbow": r_shoulder + 0.30 * arm,
            "r_hand": r_shoulder + 0.65 * arm, "l_hip": at(0.0, 0.15, 0.95, False),
            "r_hip": at(0.0, -0.15, 0.95, False)}


def path(points: list[tuple[float, float, float, float]], t: float) -> tuple[float, float, float]:
    """(x, y, reach) at time t along keyframes (t, x, y, reach), linearly interpolated, held at the ends."""
    ts = [p[0] for p in points]
    return tuple(float(np.interp(t, ts, [p[k] for p in points])) for k in (1, 2, 3))


def write(name: str, people: dict[str, list], duration: float, drop=None, partial=lambda t: False) -> None:
    rows = ["t,person,keypoint,x,y,z"]
    for k in range(int(duration * RATE) + 1):
        t = round(k / RATE, 3)
        if drop is not None and drop(t):
            continue                                             # the tracker saw nobody at all
        for person, keys in people.items():
            for part, p in keypoints(*path(keys, t)).items():
                if partial(t) and part == "r_hand":
                    continue
                rows.append(f"{t},{person},{part},{p[0] * 1000:.1f},{p[1] * 1000:.1f},{p[2] * 1000:.1f}")
    source = HERE / f"{name}.keypoints.csv"
    source.write_text("\n".join(rows) + "\n")
    frames, dropouts = convert(source, HERE / f"{name}.json", FrameTransform(scale=1e-3))
    if drop is not None:
        _mark_dropouts(HERE / f"{name}.json", duration, drop)
    source.unlink()
    print(f"{name}.json: {frames} frames, {dropouts} with part of a body missing")


def _mark_dropouts(motion: Path, duration: float, drop) -> None:
    """Frames in which the tracker saw nobody are missing from the keypoints: write them as dropouts."""
    import json

    doc = json.loads(motion.read_text())
    frames = {f["t"]: f for f in doc["frames"]}
    for k in range(int(duration * RATE) + 1):
        t = round(k / RATE, 3)
        if drop(t):
            frames[t] = {"t": t, "dropout": True, "label": "tracker lost everybody"}
    doc["frames"] = [frames[t] for t in sorted(frames)]
    motion.write_text(json.dumps(doc))


def main() -> None:
    write("one_person", {"alice": [(0, -2.8, 0.3, 0), (4, -1.2, 0.2, 0), (6, -1.2, 0.2, 0), (7, -1.2, 0.2, 0.9),
                                   (11, -1.2, 0.2, 0.9), (12, -1.2, 0.2, 0), (16, -2.8, -0.4, 0), (24, -2.8, -0.4, 0)]},
          24.0)
    write("two_people", {"alice": [(0, -1.5, 2.4, 0), (3, -1.5, -2.4, 0), (6, -1.5, 2.4, 0), (9, -1.5, -2.4, 0),
                                    (12, -1.5, 2.4, 0), (15, -1.5, -2.4, 0), (18, -1.5, 2.4, 0), (21, -1.5, -2.4, 0),
                                    (24, -1.5, 2.4, 0)],
                         "bob": [(0, -3.0, -1.0, 0), (5, -0.9, -0.5, 0), (6, -0.9, -0.5, 0.6), (24, -0.9, -0.5, 0.6)]},
          24.0)
    write("reach_stays", {"carol": [(0, -2.8, 0.0, 0), (3, -1.05, 0.15, 0), (4, -1.05, 0.15, 1.0),
                                    (24, -1.05, 0.15, 1.0)]}, 24.0)
    write("dropout", {"dave": [(0, -1.3, 0.4, 0), (24, -1.3, 0.4, 0)]}, 24.0,
          drop=lambda t: 8.0 <= t < 8.5 or 15.0 <= t < 15.5, partial=lambda t: 19.0 <= t < 20.0)


if __name__ == "__main__":
    main()
