"""An independent recount of a recorded run's SSM violations (pure: recorded messages in, a count out).

The monitor service and the report's figures share one pairing (shared.safety.monitor.HumanHistory,
Backlog), one compiled check (``SafetyMonitor.check_batch``) and one rule (``ReactionWindow``). This judge
shares none of them, so that a mistake in one of those shows up as a disagreement in the report:

* its own timeline: the joint states and the human states merged by their stamps, each joint state judged
  against every human state in force during its period (the one in force when the period began and every
  one that began within it), each on its own, so that a person state shorter than a period counts (the
  capsules numbered newest state first, as the monitor numbers them);
* the geometry of coal (``SafetyMonitor.check``, the reference the batch check is tested against, one
  human state at a time), not the compiled closest points;
* its own code for the standard's reaction window: for each (link, human capsule), an episode begins at
  the first exceeding state and ends at the first compliant one; within it the robot has T_r to react,
  then must stay under the braking line from its fastest approach of those T_r down to zero over T_s
  (plus ``tolerance``), and the episode may not outlast T_r + T_s, T_s that of the episode's first state (the
  cell's model of T_s at the measured joint speeds, as the check took it).

A joint state with no human state of its moment (before the first, older than PAIR_AGE, an invalid track)
is unchecked, as the monitor has it, never a violation and never a pass.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from shared.config import CellConfig
from shared.robot.model import RobotModel
from shared.safety.monitor import SafetyMonitor
from shared.wire.convert import humans_from_msg
from shared.wire.messages import HumanState, JointCommand, JointState

PAIR_AGE = 0.1      # s: a person state older than this at a joint state is not the person of its moment
SPEEDUPS_KEPT = 10  # the speed-ups whose stamps a recount keeps
COMMAND_RISE = 1e-6  # rad/s: a command this much faster than the one before rose


@dataclass
class Recount:
    """violations: pairs judged late (not braking, not stopped) or too close; exceedances: pairs above the
    limit at all, the reaction window aside; unchecked: joint states with no person of their moment; states:
    joint states judged; speedups: pairs whose approach rose, within the first T_r of an episode, more than
    the tolerance above its speed at the episode's first state (the stricter reading of v_r T_r; not counted
    as violations: a robot braking at full deceleration along a curved path does it, see
    shared.safety.monitor.ReactionWindow); speedups_unknown: those towards a capsule whose velocity the tracker
    did not know at that moment (the robot must never speed up towards a person it cannot judge:
    ``shared.scaling.layer.unknown_within_reach``); speedups_unknown_commanded: of those, the ones where a command
    computed from that person state (``JointCommand.human_sample_stamp`` marks the first) up to the joint state was
    faster than the command before it: the cell, knowing the velocity unknown, sped up. The rest are the drives
    following commands made before the state came, the lag T_r covers. None where no commands were given
    (unchecked, not 0). speedup_stamps: the joint states' stamps (s) of the first SPEEDUPS_KEPT speed-ups, to find
    them in a trace."""

    violations: int = 0
    exceedances: int = 0
    unchecked: int = 0
    states: int = 0
    speedups: int = 0
    speedups_unknown: int = 0
    speedups_unknown_commanded: int | None = None
    speedup_stamps: list[float] = field(default_factory=list)


def _in_force(human_stamps: np.ndarray, start: float, end: float) -> range:
    """Indices of the human states in force during (start, end]: the newest at or before start, and every
    one stamped within."""
    first = int(np.searchsorted(human_stamps, start, side="right")) - 1
    last = int(np.searchsorted(human_stamps, end, side="right"))
    return range(max(first, 0), last) if last > 0 else range(0)


class CommandRises:
    """The scaler's commands in order (max joint speed, rad/s): which of them were faster than the one before, and
    the first computed from each person state (the one carrying its sample stamp)."""

    def __init__(self, commands: list[JointCommand]) -> None:
        ordered = sorted(commands, key=lambda c: c.stamp)
        self.stamps = np.array([c.stamp for c in ordered])
        speed = np.array([float(np.abs(c.qd).max()) for c in ordered])
        rose = np.concatenate([[False], speed[1:] > speed[:-1] + COMMAND_RISE]) if speed.size else np.zeros(0, bool)
        self.rises = np.concatenate([[0], np.cumsum(rose)])      # rises among the first k commands
        marked = [(c.human_sample_stamp, k) for k, c in enumerate(ordered) if c.human_sample_stamp is not None]
        self.marked_stamps = np.array([m[0] for m in marked])
        self.marked_index = np.array([m[1] for m in marked], dtype=int)

    def rose_since(self, sample_stamp: float, until: float) -> bool:
        """Whether a command computed from the person state captured at sample_stamp (or a newer one), up to the
        stamp `until`, was faster than the command before it."""
        k = int(np.searchsorted(self.marked_stamps, sample_stamp - 1e-9))
        if k >= self.marked_index.size:
            return False                       # no command was computed from it yet
        first = int(self.marked_index[k])
        last = int(np.searchsorted(self.stamps, until, side="right"))      # commands [first, last)
        # a plain bool: numpy's made the count numpy's int, which the report's JSON refused, and the run's summary was
        # lost wherever the judge found a speed-up towards an unknown velocity
        return bool(last > first and self.rises[last] - self.rises[first] > 0)


def recount(robot: RobotModel, config: CellConfig, joint_states: list[JointState], human_states: list[HumanState],
            tolerance: float = 0.01, commands: list[JointCommand] | None = None) -> Recount:
    """The recount over a run's joint states and human states (each list in any order); with the scaler's commands,
    which speed-ups towards an unknown velocity a command made them (``Recount.speedups_unknown_commanded``)."""
    ssm = config.ssm
    monitor = SafetyMonitor(robot, ssm)
    people = sorted(human_states, key=lambda m: m.sample_stamp)
    stamps = np.array([m.sample_stamp for m in people])
    states = sorted(joint_states, key=lambda m: m.stamp)
    out = Recount()
    rises = None if commands is None else CommandRises(commands)
    if rises is not None:
        out.speedups_unknown_commanded = 0
    episodes: dict[tuple[str, int], tuple[float, float, float]] = {}   # (link, capsule) -> (start, fastest in T_r, T_s)
    first: dict[tuple[str, int], float] = {}                          # (link, capsule) -> speed at the start
    previous = -np.inf
    for js in states:
        indices = _in_force(stamps, previous, js.stamp)
        previous = js.stamp
        if np.abs(js.qd).max() <= 1e-4:                  # at rest: nothing approaches, an episode ends
            episodes, first = {}, {}
            out.states += 1
            continue
        seen = [humans_from_msg(people[k]) for k in indices]
        if not seen or seen[-1] is None or js.stamp - stamps[indices[-1]] > PAIR_AGE:
            out.unchecked += 1
            continue
        out.states += 1
        worst: dict[tuple[str, int], float] = {}
        unknown: dict[tuple[str, int], float] = {}      # pairs whose capsule's velocity was unknown: its capture
        stop = float(monitor.stopping_times(js.qd))       # this state's T_s
        offset = 0
        # newest first: capsule numbers as the monitor's union
        for k, humans in zip(reversed(indices), reversed(seen)):
            if humans is None:
                continue
            for v in monitor.check(js.q, js.qd, humans).violations:
                if v.kind == "separation":
                    out.violations += 1
                    continue
                pair = (v.link, offset + v.capsule)
                worst[pair] = max(worst.get(pair, -np.inf), v.approach_speed)
                if not humans.velocity_known[v.capsule]:
                    unknown[pair] = float(stamps[k])
            offset += humans.count
        out.exceedances += len(worst)
        kept = {}
        first = {pair: first.get(pair, speed) for pair, speed in worst.items()}
        for pair, speed in worst.items():
            start, reference, braking = episodes.get(pair, (js.stamp, speed, stop))
            elapsed = js.stamp - start
            if elapsed <= ssm.reaction_time:          # reacting: the fastest approach of these T_r is the one
                kept[pair] = (start, max(reference, speed), braking)      # braking must start from
                if speed > first[pair] + tolerance:
                    out.speedups += 1
                    if pair in unknown:
                        out.speedups_unknown += 1
                        if rises is not None:
                            out.speedups_unknown_commanded += rises.rose_since(unknown[pair], js.stamp)
                    if len(out.speedup_stamps) < SPEEDUPS_KEPT:
                        out.speedup_stamps.append(js.stamp)
                continue
            kept[pair] = (start, reference, braking)
            allowed = reference * max(0.0, 1.0 - (elapsed - ssm.reaction_time) / braking)
            if elapsed > ssm.reaction_time + braking or speed > allowed + tolerance:
                out.violations += 1
        episodes = kept
    return out
