"""The stop model both layers share: how fast the robot can be brought to rest along its path, and when it counts
as at rest.

The scaling layer brings the robot to rest for a plan from rest at STOP_DECELERATION of the joints' deceleration
(``ScalingLayer``); the planning layer puts such a plan's start where that stop ends (``shared.planning.replanner``).
Below REST_SPEED (rad/s, fastest joint) both count the robot as at rest.
"""

from __future__ import annotations

import numba
import numpy as np

# the fraction of the joints' deceleration (max_acceleration, 3.49 rad/s^2, inside the 6 rad/s^2 of the braking
# floor) a stop for a plan from rest uses
STOP_DECELERATION = 1.0
REST_SPEED = 0.02         # rad/s (fastest joint): below it the robot counts as at rest


@numba.njit(cache=True)
def path_deceleration(dq_ds, d2q_ds2, sdot, acceleration):
    """The largest path deceleration d (1/s^2) at which no joint's acceleration q'_j (-d) + q''_j sdot^2
    leaves +-a_j: min over the moving joints of (a_j + sign(q'_j) q''_j sdot^2) / |q'_j|, at least 0 (inf
    when no joint moves). The curvature term counts: where the nominal trajectory itself decelerates, less
    path deceleration is left to the drives."""
    best = np.inf
    for j in range(dq_ds.shape[0]):
        speed = abs(dq_ds[j])
        if speed > 1e-9:
            curvature = d2q_ds2[j] * sdot * sdot
            best = min(best, (acceleration[j] + (curvature if dq_ds[j] > 0 else -curvature)) / speed)
    return max(best, 0.0)


def stopping_time(velocity: np.ndarray, acceleration: np.ndarray) -> float:
    """Seconds a stop for a plan takes from joint velocity `velocity` (rad/s) at STOP_DECELERATION of the joints'
    deceleration `acceleration` (rad/s^2): the slowest joint's |v| / (STOP_DECELERATION a)."""
    return float(np.max(np.abs(velocity) / (STOP_DECELERATION * np.asarray(acceleration))))
