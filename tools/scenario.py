"""hrc scenario: one seeded scenario of a sweep taken apart, strategy by strategy: where a comparison names a
seed (``hrc sweep``'s "most lost"), what each strategy did in it. Each strategy's shuttles, the time stopped and
slowed, the arrivals at the goals, the spans held below alpha_min (where the scaling layer asks for a replan),
and every planning decision with its reason: a goal's plan, a replan taken or refused with both predicted times.
The runs are the sweep's own (``evidence.sweep.strategies_for``), so the figures are the sweep's to the digit."""

from __future__ import annotations

import math
import shlex

from evidence.sim import SimResult

GAP = 0.05      # s: spans held below alpha_min closer than this are one span


def held_spans(result: SimResult, alpha_min: float) -> list[tuple[float, float]]:
    """(start, end) in s of every span in which the scaling layer held the robot below alpha_min (a replan
    request's threshold), spans apart by less than GAP joined."""
    spans: list[list[float]] = []
    period = result.records[1].t - result.records[0].t if len(result.records) > 1 else 0.0
    for record in result.records:
        if record.step.alpha >= alpha_min:
            continue
        if spans and record.t - spans[-1][1] <= GAP:
            spans[-1][1] = record.t + period
        else:
            spans.append([record.t, record.t + period])
    return [(a, b) for a, b in spans]


def arrivals(result: SimResult) -> list[float]:
    """When each shuttle was completed (s): the records at which the count rose."""
    return [b.t for a, b in zip(result.records, result.records[1:]) if b.shuttles > a.shuttles]


def story_lines(strategy: str, result: SimResult, alpha_min: float) -> list[str]:
    """One strategy's run as lines: its figures, arrivals and holds, then each planning decision in time order."""
    summary = result.summary()
    duration = summary["duration_s"] or 1.0
    head = (f"{strategy}: {summary['shuttle_progress']:.2f} shuttles ({summary['shuttles_completed']} completed), "
            f"stopped {summary['stopped_fraction'] * duration:.2f} s, slowed {summary['slowed_fraction'] * duration:.2f} s,"
            f" {summary['violations']} violations")
    times = arrivals(result)
    lines = [head, "  arrivals at " + ", ".join(f"{t:.2f}" for t in times) + " s" if times else "  no arrival"]
    spans = held_spans(result, alpha_min)
    lines.append(f"  held below alpha_min {alpha_min:g}: " +
                 (", ".join(f"{a:.2f}-{b:.2f}" for a, b in spans) + " s" if spans else "never"))
    for event in sorted(result.goals + result.replans, key=lambda e: e.t):
        taken = "taken" if event.ok else "refused"
        lines.append(f"  {event.t:6.2f} s  {event.reason:<7} {taken:<8} {event.detail}".rstrip())
    return lines


def people_lines(window) -> list[str]:
    """Where a real-people scenario's person comes from and stands (a ``evidence.recorded.RecordingWindow``: the
    recording, the window's start in it, the placement), and the two commands that run that person on the
    processes (the whole recording, the window inside it); none for scripted people."""
    placement = getattr(window, "placement", None)
    if placement is None:
        return []
    convert = ["hrc", "human", "from-keypoints", str(window.recording), "person.json", "--format", "assembly",
               *placement.options()]
    return [f"people: {window.name} from {window.start:.2f} s of it, moved {placement.x:+.3f} m along x and turned "
            f"{math.degrees(placement.yaw):+.1f} deg about the base; on the processes (the whole recording):",
            "  " + shlex.join(convert), "  hrc demo --human person.json"]
