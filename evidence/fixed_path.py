"""The strongest simple baseline of the planning layer: one fixed path, chosen once, followed by the plain
scaling layer with no planner. The straight shuttle with the elbow (joint 3) folded over the middle of the
sweep, in parallel with the base: the folded arm's links reach less far from the base, so where people stand
at the table's edge every link is farther from them and slower, and the SSM lets the robot go faster. It costs
a little in an empty cell (a longer path); what it wins with people is what a planning layer must at least
match to earn its place (issue 38).

``FixedPath.leg(start, goal, version)`` is the timed leg (TOPP-RA through the fold's waypoints, checked free of
the static scene), made once per pair of ends and renumbered per leg; ``run_shuttle(leg_path=...)`` follows it.
"""

from __future__ import annotations

from shared.planning.postures import FoldedLegs


class FixedPath(FoldedLegs):
    """The folded legs of ``shared.planning.postures`` as a fixed path: ``leg(start, goal, version)`` for
    ``run_shuttle(leg_path=...)`` (raises TimingError where a leg cannot be timed)."""
