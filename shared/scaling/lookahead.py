"""Where a stop begun now leads (pure, compiled): whether a command can still be braked along its path without a
link approaching a person faster than the SSM allows on the way.

The scaling layer's rows see the robot's state now, and its command check the state one period on. Near a person,
inside the no-approach distance (there the ISO limit is at most 0: a link may not approach at all), a link may
still pass at full speed while it does not approach. Where the path then turns towards that person, a stop at the
drives' limit from full speed takes 0.26 s, and the turn makes the link approach all the way; so does a person who
walks past the link, turning the line between them. Random walk seed 4196, the fold as a new goal's leg: the flange
passed 0.46 m from a person walking at 1.2 m/s at 1.57 rad/s, then approached at 5 mm/s rising to 48 mm/s while
braking, above the monitor's braking envelope (a violation). A stop run ahead against the people standing where
they are missed it; against them moved on along their tracked velocities it slows the robot before.

``stop_stays_safe`` runs the stop the layer itself would command from a candidate command: ``braking_floor``'s
deceleration along the path, every period. It checks every `every`-th state of that stop with the bound of the
SSM rows (``motion_alpha_bound``). The layer lowers alpha until the stop is safe (``ScalingLayer._stop_checked``),
so the robot slows before such a turn instead of braking into it.
"""

from __future__ import annotations

import numba

from shared.core.trajectory import _hermite_one
from shared.scaling.problem import motion_alpha_bound
from shared.scaling.stopping import path_deceleration

MAX_STEPS = 100     # periods a stop may take (1 s at 100 Hz; from full speed it takes 26); longer is not safe


@numba.njit(cache=True)
def stop_stays_safe(times, positions, velocities, s, sdot, period, acceleration, offset, every, velocity_limit,
                    placement, parent, local, joint, ancestry, radii, human_seg, human_rad, human_vel, human_known,
                    horizon, fixed, near_d, v_near, v_far, a_h, lead, stop_full, stop_min, reaction, a_stop, static,
                    margin):
    """Whether the stop that starts at path parameter s with path speed sdot (the command's) keeps every checked
    state within the SSM rows' bound: each period, the path speed falls by the drives' deceleration
    (``path_deceleration`` with `acceleration`, rad/s^2), s moves on by it, and every `every`-th state
    (q(s) + offset, q'(s) at that path speed) is checked against the people where their tracked velocities take
    them by then (one of unknown velocity stays where it is). False where one exceeds the bound, or where the stop
    would take more than MAX_STEPS periods (each state at its own stopping time: the bound of sdot, ``motion_alpha_bound``,
    at q'(s)). times, positions, velocities: the trajectory's knots; the rest: ``motion_alpha_bound``'s."""
    end = times[-1]
    q, dq, ddq = _hermite_one(times, positions, velocities, s)
    for k in range(1, MAX_STEPS + 1):
        sdot = max(0.0, sdot - path_deceleration(dq, ddq, sdot, acceleration) * period)
        s = min(s + sdot * period, end)
        if sdot <= 0.0 or s >= end:
            return True
        q, dq, ddq = _hermite_one(times, positions, velocities, s)     # once a period: the check's and the next step's
        if k % every == 0:
            moved = human_seg.copy()            # the people moved on along their tracked velocities meanwhile
            for m in range(human_seg.shape[0]):
                if human_known[m]:
                    moved[m] += human_vel[m] * (k * period)
            bound = motion_alpha_bound(q + offset, dq, velocity_limit, placement, parent, local, joint, ancestry,
                                       radii, moved, human_rad, human_vel, human_known, horizon, fixed, near_d,
                                       v_near, v_far, a_h, lead, stop_full, stop_min, reaction, a_stop, static, margin)
            if sdot > bound * (1.0 + 1e-9) + 1e-12:
                return False
    return False
