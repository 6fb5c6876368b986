"""Alg. 2 of the paper, its splice: the old trajectory kept unchanged up to a junction s_j, a new part from
there. Where the junction and the new part come from is the replanner's (shared.planning.replanner).
"""

from __future__ import annotations

import numpy as np

from shared.core.trajectory import Trajectory


def merge(old: Trajectory, s_junction: float, new_part: Trajectory, version: int) -> Trajectory:
    """The old trajectory's knots up to s_junction (exactly, plus the junction itself), then new_part
    shifted to start at s_junction. Continuity is the caller's: new_part must start at q(s_j), q'(s_j)."""
    keep = old.times < s_junction - 1e-3    # a knot closer than 1 ms would make a needle-thin interval; the
    # interval that replaces it, from exact values and tangents at both ends, is the same cubic
    q_j, dq_j, _ = old.sample(float(s_junction))
    times = np.concatenate([old.times[keep], [s_junction], s_junction + new_part.times[1:]])
    positions = np.vstack([old.positions[keep], q_j, new_part.positions[1:]])
    velocities = np.vstack([old.velocities[keep], dq_j, new_part.velocities[1:]])
    return Trajectory(times, positions, velocities, version)
