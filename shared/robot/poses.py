"""The paper's shuttle: the two poses (rad) the robot moves between in the experiment (the base joint turned by
+-90 degrees, the arm reaching out over the table). The simulation's scenarios, `hrc goal q_s` / `q_g` and the
emulator's start pose are these; and how far along a leg between two poses a robot is (``leg_fraction``), so the
simulation and the processes count a shuttle's part done the same way."""

from __future__ import annotations

import numpy as np

PAPER_START = np.array([1.57, -0.4, 1.17, 0.0, 1.57, 0.0])
PAPER_GOAL = np.array([-1.57, -0.4, 1.17, 0.0, 1.57, 0.0])


def leg_fraction(q: np.ndarray, start: np.ndarray, goal: np.ndarray) -> float:
    """How much of a leg the robot has covered, by where it is: 1 - |q - goal| / |start - goal| (joint
    space, Euclidean), in [0, 1]. Geometric, so a replanned trajectory that starts anew from where the
    robot stands is credited with the way already made (a path parameter would restart at 0)."""
    span = float(np.linalg.norm(np.asarray(goal) - np.asarray(start)))
    if span <= 0.0:
        return 0.0
    return float(np.clip(1.0 - np.linalg.norm(np.asarray(q) - np.asarray(goal)) / span, 0.0, 1.0))
