"""A goal that no motion within the SSM can reach while the people stay where they are (pure).

Inside a certain separation from a person the ISO/TS 15066 limit, less the scaling layer's tracking
margin, is zero or negative: there a robot link may not approach that person at all, only move away
(``shared.safety.ssm``). That separation, the *no-approach distance*, is

    d0 = v_h (T_s + T_r) + C + Z_d + Z_r + a_max T_s^2 / 2 + tracking_margin (T_s + T_r)

at the T_s of a robot that barely moves (``SsmParameters.min_stopping_time``: a link that approaches at all
may do so where a creeping robot may), the person's part by the cell's human model (0.32 m for a person
standing still under the paper's formula). The scaling layer bounds how fast a link
closes the distance to a capsule (the end-point speed it limits bounds the closest points' speed), so
while that person stays, the separation of a link from them cannot shrink below d0 or, where it already is
below, below what it is now. A goal at which some link would be closer to a person than both d0 and its
separation now is therefore out of reach until the person moves: every path, old or new, ends in a wait.
``goal_block`` says so, naming the link and the numbers; the planning loop adds it to the reason a replan
is refused (and a replan request is not searched for), and the demo's report to the stall it explains.
"Stay" is taken literally: a tracked person counts as standing where they are now (a walking one will be
somewhere else soon, and is not a reason to stop searching); a capsule the tracker has no velocity for
gets the ISO 13855 speed, as everywhere, so its d0 is larger.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from shared.core.humans import HumanCapsules
from shared.robot.model import RobotModel
from shared.safety.parameters import SsmParameters
from shared.safety.ssm import human_distance, pair_ssm

TOLERANCE = 1e-3   # m: a separation this much smaller counts as closer (a robot at its goal is not blocked)


@dataclass(frozen=True)
class GoalBlock:
    """Why a goal is out of reach: at the goal, `link` would be `at_goal` m from human capsule `capsule`,
    closer than the no-approach distance `no_approach` (m) and than its separation now, `now` (m)."""

    link: str
    capsule: int
    at_goal: float
    no_approach: float
    now: float

    def describe(self) -> str:
        return (f"the goal is blocked while the person stays: there {self.link} would be {self.at_goal:.2f} m "
                f"from human capsule {self.capsule}, inside the {self.no_approach:.2f} m at which the SSM "
                f"allows no approach (it is {self.now:.2f} m now)")


def goal_block(robot: RobotModel, ssm: SsmParameters, q_now: np.ndarray, q_goal: np.ndarray,
               humans: HumanCapsules | None) -> GoalBlock | None:
    """The pair that keeps q_goal out of reach from q_now while these people stay (the one the goal brings
    closest, relative to its no-approach distance), or None when no pair does (see the module docstring)."""
    if humans is None or humans.count == 0:
        return None
    still = np.zeros((len(robot.radii), 2, 3))
    staying = HumanCapsules(humans.segments, humans.radii, np.zeros_like(humans.velocities), humans.velocity_known)
    goal = pair_ssm(robot.capsule_segments(np.asarray(q_goal, dtype=float)), robot.radii, still, staying, ssm)
    now = pair_ssm(robot.capsule_segments(np.asarray(q_now, dtype=float)), robot.radii, still, staying, ssm)
    stop = ssm.min_stopping_time
    no_approach = human_distance(goal.human_speed, ssm, goal.distance, stop) + ssm.fixed_distance_at(stop) \
        + ssm.tracking_margin * (ssm.reaction_time + stop)
    blocked = (goal.distance < no_approach) & (goal.distance < now.distance - TOLERANCE)
    if not blocked.any():
        return None
    depth = np.where(blocked, no_approach - goal.distance, -np.inf)
    i, j = np.unravel_index(int(np.argmax(depth)), depth.shape)
    return GoalBlock(robot.link_names[i], int(j), float(goal.distance[i, j]), float(no_approach[i, j]),
                     float(now.distance[i, j]))
