"""Real people as scenarios: windows of the human-assembly recordings, placed in the cell.

The recordings (``../shared/data/human-assembly/``: RealSense + OpenPose, the arms of people assembling LEGO at
a table, 30 Hz) are what a real cell sees most of the time: a person at work beside the robot, moving their arms,
not walking. Each is read by the product's own reader (``shared.tracking.keypoints``: arm-only skeletons, a
torso down to an assumed hip height, DIN radii) and placed as ``hrc human from-keypoints FILE OUT --format
assembly --translate X 0 1.1`` places it (shoulders 1.35 m high, facing the robot across its sweep):

* table_edge, X = -0.05: shoulders at x = -0.90 m, hands about 0.77 m from the base, within 0.3-0.5 m of the
  links as they sweep past;
* step_back, X = -0.75: shoulders at x = -1.60 m;
* around: anywhere between those two distances, turned about the robot's base by up to a quarter turn either way
  (beside the sweep's ends at the extremes), facing the base; the seed draws where. Two placements across the
  sweep's middle say little about a person who works beside its start or its end, where the links pass them side
  on, or diagonally: this kind is the cell's safety and planning checked wherever a person may work.

Scenario kinds ``real_table_edge``, ``real_step_back`` and ``real_around`` (``evidence.scenarios.make_scenario``):
seed k is recording k mod n (the folder's ``*.txt`` in name order) from a start drawn from the seed within its
length, so the seeds cycle through every recording and a run of many seeds covers each at many moments. The people are
the recording's, frame by frame, as the cell's tracker passes them on (``shared.tracking.tracked``: velocities
fitted over its window, unknown at a track's start and after a change in the capsules seen, nobody once no frame
came for its dropout bound; a frame OpenPose lost a keypoint in is a dropout), as on the processes. The same seed
gives the same motion where the recordings are the same: the folder is ``HRC_RECORDINGS`` where set, else ``RECORDINGS``.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from evidence.scenarios import RECORDED_KINDS
from shared.core.errors import ConfigError
from shared.core.humans import HumanCapsules
from shared.tracking.keypoints import FrameTransform, read_assembly, to_motion
from shared.tracking.motion import RecordedMotion, parse_json
from shared.tracking.tracked import TrackedMotion

RECORDINGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "human-assembly"
HEIGHT = 1.1                                                 # m: --translate Z (shoulders 1.35 m high)


@dataclass(frozen=True)
class Placement:
    """Where a recording's person stands: as the camera saw them (turned to face +x), moved `x` m along the robot
    base's x axis and raised HEIGHT (shoulders at about x - 0.85 m on the x axis, facing the base), then turned
    `yaw` rad about the base's vertical axis (0: across the middle of the sweep, which turns from -y through -x to
    +y; +-pi/2: beside its ends). ``options`` are the ``hrc human from-keypoints`` options that place a file
    there, so the processes run the person the simulation ran."""

    x: float
    yaw: float = 0.0

    def transform(self) -> FrameTransform:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return FrameTransform(camera=True, yaw=self.yaw, translation=(self.x * c, self.x * s, HEIGHT))

    def options(self) -> list[str]:
        """--yaw (degrees) and --translate X Y Z of ``hrc human from-keypoints --format assembly``."""
        return ["--yaw", repr(math.degrees(self.yaw)), "--translate", *map(repr, self.transform().translation)]


PLACEMENTS = {"table_edge": Placement(-0.05), "step_back": Placement(-0.75)}
AROUND_X = (-0.75, -0.05)         # m: the around kind's x, from one step back to the table's edge
AROUND_YAW = 0.5 * math.pi        # rad: ... turned by up to this either way
AROUND = "around"


def around(seed: int) -> Placement:
    """The around kind's placement for `seed` (its own generator: the window's start is drawn as for the fixed
    placements), rounded to the millimetre and the milliradian (a file's options give the same person)."""
    rng = np.random.default_rng([seed, 1])
    x, yaw = rng.uniform(*AROUND_X), rng.uniform(-AROUND_YAW, AROUND_YAW)
    return Placement(round(float(x), 3), round(float(yaw), 3))


def recordings_folder() -> Path:
    """Where the recordings are read from: ``HRC_RECORDINGS`` where set, else ``RECORDINGS``."""
    return Path(os.environ.get("HRC_RECORDINGS") or RECORDINGS)


def recordings(folder: Path) -> list[Path]:
    """The folder's recordings (``*.txt``) in name order; ConfigError where there are none."""
    found = sorted(Path(folder).glob("*.txt")) if Path(folder).is_dir() else []
    if not found:
        raise ConfigError(f"no recordings (*.txt, the human-assembly format) in {folder}: the real-people scenario "
                          "kinds read them there; set HRC_RECORDINGS to such a folder")
    return found


def placement_named(placement: str | Placement) -> Placement:
    """A placement by its name in PLACEMENTS or as X:YAW (m, degrees: ``-0.15:60``), or the placement itself;
    ConfigError saying what is wrong with any other text."""
    if isinstance(placement, Placement):
        return placement
    if placement in PLACEMENTS:
        return PLACEMENTS[placement]
    x, colon, yaw = str(placement).partition(":")
    try:
        found = Placement(float(x), math.radians(float(yaw))) if colon else None
    except ValueError:
        found = None
    if found is None or not (math.isfinite(found.x) and math.isfinite(found.yaw)):
        raise ConfigError(f"unknown placement {placement!r}; known: {', '.join(PLACEMENTS)}, or X:YAW (m along the "
                          "base's x axis, degrees about its vertical axis, e.g. -0.15:60)")
    return found


@lru_cache(maxsize=64)
def placed_motion(recording: Path, placement: str | Placement) -> RecordedMotion:
    """One recording at a placement (by name or itself), as ``hrc human from-keypoints --format assembly`` with
    the placement's options writes it and ``hrc demo --human`` reads it (the same values: the motion document
    goes through the file format's own parser). Kept per process: a sweep runs every strategy on the same few
    recordings."""
    transform = placement_named(placement).transform()
    try:
        text = Path(recording).read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{recording}: cannot read: {exc}") from None
    doc, _ = to_motion(read_assembly(text, str(recording)), transform)
    return RecordedMotion(parse_json(json.dumps(doc), str(recording)))


@lru_cache(maxsize=64)
def tracked_motion(recording: Path, placement: str | Placement) -> TrackedMotion:
    """``placed_motion`` through the cell's tracker, the whole recording once (a window's tracker has been running
    before the window starts, as in a cell). Kept per process."""
    return TrackedMotion(placed_motion(recording, placement))


class RecordingWindow:
    """A recorded motion from `start` s on, as a scenario's people (``at(t)``, ``phase(t)``: t from the window's
    start; past the recording's end its last frame holds, as ``RecordedMotion.at`` holds it). motion: anything
    with the motion's ``at`` and ``phase`` (a ``TrackedMotion`` for the scenario kinds)."""

    def __init__(self, motion: RecordedMotion | TrackedMotion, start: float, name: str,
                 placement: Placement | None = None, recording: Path | None = None) -> None:
        self.motion, self.start, self.name, self.placement = motion, float(start), name, placement
        self.recording = recording          # the file the motion was read from, where it was one

    def at(self, t: float) -> HumanCapsules | None:
        return self.motion.at(self.start + t)

    def phase(self, t: float) -> str:
        return f"{self.name} at {self.start + t:.1f} s: {self.motion.phase(self.start + t)}"

    def captured(self, t: float) -> tuple[float, float]:
        """When the newest sample by t was captured (s, on the window's clock) and the source's interval (s), as
        ``TrackedMotion.captured`` (a motion without it: captured at every moment), so the simulation ages a
        window's samples as the scaler finds them."""
        captured = getattr(self.motion, "captured", None)
        if captured is None:
            return t, 0.0
        taken, interval = captured(self.start + t)
        return taken - self.start, interval


def recorded_scenario(kind: str, seed: int, duration: float) -> RecordingWindow:
    """The people of one real-people scenario: recording seed mod n at the kind's placement (the around kind's
    drawn from the seed, ``around``), from a start the seed draws within the recording's length (0 where it is
    shorter than `duration`)."""
    if kind not in RECORDED_KINDS:
        raise ValueError(f"unknown recorded scenario kind {kind!r}; known: {sorted(RECORDED_KINDS)}")
    files = recordings(recordings_folder())
    recording = files[seed % len(files)]
    named = RECORDED_KINDS[kind]
    placement = around(seed) if named == AROUND else placement_named(named)
    motion = tracked_motion(recording, placement)
    start = float(np.random.default_rng(seed).uniform(0.0, max(0.0, motion.duration - duration)))
    return RecordingWindow(motion, round(start, 3), recording.stem, placement, recording)
