"""The paper's shuttle: the two poses (rad) the robot moves between in the experiment (the base joint turned by
+-90 degrees, the arm reaching out over the table). The simulation's scenarios, `hrc goal q_s` / `q_g` and the
emulator's start pose are these."""

from __future__ import annotations

import numpy as np

PAPER_START = np.array([1.57, -0.4, 1.17, 0.0, 1.57, 0.0])
PAPER_GOAL = np.array([-1.57, -0.4, 1.17, 0.0, 1.57, 0.0])
