"""The tracked humans as the cores see them: capsules with end-point velocities.

A human body is a set of capsules (forearm, upper arm, torso, head ...). Each capsule carries the
velocity of both end points; a point in between moves at the linear interpolation (a rigid segment's
point velocities are affine along it), so the fastest approach of a capsule is at one of its ends.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# m/s: below it a tracked body part counts as standing: a person shifting their stance or leaning in, not going
# anywhere (people walk at 0.4 m/s and more). The planning layer's predictions neither move such a part on along
# its velocity (``shared.planning.time_cost``) nor count its person as moving (``shared.planning.presence.StillClock``),
# and a person standing still farther off makes no folded leg (``shared.planning.replanner``, ``still_gap``).
# At 0.1 m/s, the paper's phase 4 (a person stepping in at 0.13 m/s for 1.2 s, then standing in the path) had a
# goal planned while they stepped predicted 0.25 m further in, past the way round, and they stopped in its way.
STANDING_SPEED = 0.15


def end_speeds(humans: "HumanCapsules") -> np.ndarray:
    """Each capsule's faster end's speed (M,), m/s: what says whether it drifts, walks or stands."""
    return np.linalg.norm(humans.velocities, axis=2).max(axis=1)


def standing(humans: "HumanCapsules", speed: float = STANDING_SPEED) -> bool:
    """Every capsule's velocity known and below `speed` (m/s) at both ends (True for nobody)."""
    return humans.count == 0 or (bool(humans.velocity_known.all())
                                 and float(end_speeds(humans).max()) < speed)


@dataclass(frozen=True)
class HumanCapsules:
    """M human capsules in the robot base frame.

    segments: (M, 2, 3) end points (m). radii: (M,) (m).
    velocities: (M, 2, 3) end-point velocities (m/s); meaningful where velocity_known is True.
    velocity_known: (M,) False where the tracker could not estimate a velocity: the SSM math then uses
    the ISO 13855 approach speed instead.
    """

    segments: np.ndarray
    radii: np.ndarray
    velocities: np.ndarray
    velocity_known: np.ndarray

    def __post_init__(self) -> None:
        # the compiled kernels take these arrays as they are: make them contiguous float64 / bool once
        for name, dtype in (("segments", np.float64), ("radii", np.float64), ("velocities", np.float64),
                            ("velocity_known", np.bool_)):
            object.__setattr__(self, name, np.ascontiguousarray(getattr(self, name), dtype=dtype))

    @property
    def count(self) -> int:
        return int(self.radii.shape[0])

    @staticmethod
    def empty() -> "HumanCapsules":
        return HumanCapsules(np.zeros((0, 2, 3)), np.zeros(0), np.zeros((0, 2, 3)), np.zeros(0, dtype=bool))

    @staticmethod
    def union(states: "list[HumanCapsules]") -> "HumanCapsules":
        """Every capsule of several states as one state (the newest first): the people as they were at each of
        those moments. A consumer that runs at its own cadence (the scaler at 100 Hz, the monitor at each
        joint state) checks against all the states that arrived since its last step, so a state that held for
        less than one of its periods (an unknown velocity after a glitch, a person nearer for 8 ms) still
        counts, and counts the same way in the scaling layer, the monitor and the report."""
        if len(states) == 1:
            return states[0]
        if not states:
            return HumanCapsules.empty()
        return HumanCapsules(np.concatenate([h.segments for h in states]), np.concatenate([h.radii for h in states]),
                             np.concatenate([h.velocities for h in states]),
                             np.concatenate([h.velocity_known for h in states]))

    @staticmethod
    def from_arrays(segments, radii, velocities=None, velocity_known=None) -> "HumanCapsules":
        """Build from array-likes; missing velocities mean 'unknown' (worst-case approach speed)."""
        seg = np.asarray(segments, dtype=float).reshape(-1, 2, 3)
        rad = np.asarray(radii, dtype=float).reshape(-1)
        if velocities is None:
            vel = np.zeros_like(seg)
            known = np.zeros(seg.shape[0], dtype=bool)
        else:
            vel = np.asarray(velocities, dtype=float).reshape(-1, 2, 3)
            known = (np.ones(seg.shape[0], dtype=bool) if velocity_known is None
                     else np.asarray(velocity_known, dtype=bool).reshape(-1))
        if not (seg.shape[0] == rad.shape[0] == vel.shape[0] == known.shape[0]):
            raise ValueError("human capsule arrays disagree on the number of capsules")
        return HumanCapsules(seg, rad, vel, known)
