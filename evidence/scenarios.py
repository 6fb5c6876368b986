"""Scripted humans: a simple body of capsules moved through keyframes.

A body is a torso, a head and one reaching arm (upper arm + forearm with the hand), placed by the torso's
floor position (x, y), a reach fraction in [0, 1] that swings the arm from hanging down to pointing at a
target, and a lean in [0, 1] that bends the upper body towards the target (shoulders up to 0.35 m
forward and 0.3 m lower), so that a person can put an arm across the robot's path. Keyframes are linearly
interpolated in time; end-point velocities are the exact derivative
of that motion (central difference over 1 ms), so a scripted human has "tracked" velocities.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

from shared.core.errors import ConfigError
from shared.core.humans import HumanCapsules
from shared.robot.poses import PAPER_GOAL, PAPER_START

TORSO_RADIUS, HEAD_RADIUS, UPPER_ARM_RADIUS, FOREARM_RADIUS = 0.17, 0.12, 0.06, 0.05
UPPER_ARM, FOREARM = 0.30, 0.35


@dataclass(frozen=True)
class Keyframe:
    """At time t (s): torso floor position (m), reach fraction, reach target (m, base frame), label."""

    t: float
    x: float
    y: float
    reach: float = 0.0
    target: tuple[float, float, float] = (0.0, 0.0, 0.5)
    phase: str = ""
    lean: float = 0.0


def body_segments(x: float, y: float, reach: float, target: np.ndarray, lean: float = 0.0
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Capsule end points (4, 2, 3) and radii (4,) of a standing human with one arm reaching.

    In plain floats (the same operations in the same order as numpy would do them on 3-vectors, so the
    same values to the last bit): a scripted human is posed three times a simulated cycle, where small numpy
    arrays are mostly per-call overhead."""
    x, y, reach, lean = float(x), float(y), float(reach), float(lean)
    gx, gy, gz = (float(v) for v in target)
    tx, ty = gx - x, gy - y
    m = max(math.sqrt(tx * tx + ty * ty), 1e-9)
    tx, ty = tx / m, ty / m
    nx, ny, nz = x + 0.35 * lean * tx, y + 0.35 * lean * ty, 1.45 - 0.3 * lean          # neck
    sx, sy, sz = nx + 0.0, ny + -0.2, nz + 0.0                                          # shoulder
    ax, ay, az = gx - sx, gy - sy, gz - sz
    norm = math.sqrt(ax * ax + ay * ay + az * az)
    if norm > 1e-9:
        ax, ay, az = ax / norm, ay / norm, az / norm
    else:
        ax, ay, az = 0.0, 0.0, -1.0                                                     # hanging down
    keep = 1.0 - reach
    dx, dy, dz = keep * 0.0 + reach * ax, keep * 0.0 + reach * ay, keep * -1.0 + reach * az
    m = max(math.sqrt(dx * dx + dy * dy + dz * dz), 1e-9)
    dx, dy, dz = dx / m, dy / m, dz / m
    ex, ey, ez = sx + UPPER_ARM * dx, sy + UPPER_ARM * dy, sz + UPPER_ARM * dz         # elbow
    hx, hy, hz = ex + FOREARM * dx, ey + FOREARM * dy, ez + FOREARM * dz               # hand
    head = (nx + 0.0, ny + 0.0, nz + 0.27)
    segments = np.array([
        [(x, y, 0.9), (nx, ny, nz)],                 # torso
        [head, head],                                # head (a sphere)
        [(sx, sy, sz), (ex, ey, ez)],                # upper arm
        [(ex, ey, ez), (hx, hy, hz)],                # forearm and hand
    ])
    return segments, np.array([TORSO_RADIUS, HEAD_RADIUS, UPPER_ARM_RADIUS, FOREARM_RADIUS])


class ScriptedHuman:
    """A human following keyframes; ``at(t)`` gives the capsules and their velocities at time t."""

    def __init__(self, keyframes: list[Keyframe]) -> None:
        if not keyframes or any(b.t <= a.t for a, b in zip(keyframes, keyframes[1:])):
            raise ValueError("keyframes need strictly increasing times")
        self.keyframes = keyframes
        self._times = [k.t for k in keyframes]

    def _pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        ks = self.keyframes
        t = min(max(t, ks[0].t), ks[-1].t)
        i = max(0, min(len(ks) - 2, bisect.bisect_right(self._times, t) - 1)) if len(ks) > 1 else 0
        a = ks[i]
        b = ks[i + 1] if len(ks) > 1 else a
        w = 0.0 if b.t == a.t else (t - a.t) / (b.t - a.t)
        mix = lambda u, v: (1 - w) * u + w * v
        target = [mix(float(u), float(v)) for u, v in zip(a.target, b.target)]
        return body_segments(mix(a.x, b.x), mix(a.y, b.y), mix(a.reach, b.reach), target, mix(a.lean, b.lean))

    def phase(self, t: float) -> str:
        """The label of the last keyframe at or before t."""
        label = self.keyframes[0].phase
        for k in self.keyframes:
            if k.t <= t:
                label = k.phase or label
        return label

    def at(self, t: float) -> HumanCapsules:
        """The capsules at t (s) with the velocities (m/s) they move on with from t: the slope of the keyframes'
        segment after t (a forward difference). At a keyframe the script's speed changes at once, and a central
        difference there reported the mean of the two, e.g. a crossing walker at 0 s at half their 1.6 m/s."""
        seg, radii = self._pose(t)
        dt = 1e-3
        vel = (self._pose(t + dt)[0] - seg) / dt
        return HumanCapsules(seg, radii, vel, np.ones(radii.size, dtype=bool))


# The paper's experiment, seen from the robot: the shuttle sweeps the flange over the -x side of the base.
Q_START, Q_GOAL = PAPER_START, PAPER_GOAL
IN_PATH = (-0.45, 0.0, 0.55)


def paper_phases(period: float = 6.0) -> ScriptedHuman:
    """The four phases of the paper's experiment, each `period` seconds long.

    1 far away (full speed); 2 walking up to the cell and back (scaling down, then up again);
    3 leaning in with the forearm across the robot's path (the planner replans around it);
    4 very close, reaching into the path (alpha falls below alpha_min: beta, a replan); then leaving.
    """
    p = period
    return ScriptedHuman([
        Keyframe(0.0, -2.8, 0.0, 0.0, IN_PATH, "1 far away"),
        Keyframe(p, -2.8, 0.0, 0.0, IN_PATH, "2 approaching"),
        Keyframe(p + 0.45 * p, -1.05, 0.0, 0.0, IN_PATH, "2 approaching"),
        Keyframe(p + 0.55 * p, -1.05, 0.0, 0.0, IN_PATH, "2 moving away"),
        Keyframe(2 * p, -2.0, 0.0, 0.0, IN_PATH, "3 arm in the path"),
        Keyframe(2 * p + 0.3 * p, -1.2, 0.15, 1.0, IN_PATH, "3 arm in the path", lean=0.4),
        Keyframe(3 * p, -1.2, 0.15, 1.0, IN_PATH, "4 very close", lean=0.4),
        Keyframe(3 * p + 0.2 * p, -1.1, 0.0, 1.0, IN_PATH, "4 very close", lean=0.4),
        Keyframe(3.8 * p, -1.1, 0.0, 1.0, IN_PATH, "leaving", lean=0.4),
        Keyframe(4 * p, -2.8, 0.0, 0.0, IN_PATH, "leaving"),
    ])


class EmptyCell:
    """Nobody in the cell (tracked, so the scaling layer runs at full speed): the reference every strategy
    is held against, the most any of them can do in a scenario's time."""

    def at(self, t: float) -> HumanCapsules:
        return HumanCapsules.empty()

    def phase(self, t: float) -> str:
        return "empty cell"


# ------------------------------------------------------------------------------- seeded random scenarios
class Crowd:
    """Several scripted humans at once: their capsules together; the phase is the first one's."""

    def __init__(self, humans: list[ScriptedHuman]) -> None:
        self.humans = humans

    def at(self, t: float) -> HumanCapsules:
        parts = [h.at(t) for h in self.humans]
        return HumanCapsules(np.concatenate([p.segments for p in parts]), np.concatenate([p.radii for p in parts]),
                             np.concatenate([p.velocities for p in parts]),
                             np.concatenate([p.velocity_known for p in parts]))

    def phase(self, t: float) -> str:
        return self.humans[0].phase(t)


WALK_SPEED = 1.6             # m/s, ISO 13855's walking speed: no scripted walk is faster


def _walk(points: list[tuple[float, float, float, float]], label: str, speed: float = WALK_SPEED,
          pause: float = 0.0) -> ScriptedHuman:
    """Keyframes through (x, y, reach, lean) points at `speed`, pausing `pause` s at each."""
    frames, t = [], 0.0
    for k, (x, y, reach, lean) in enumerate(points):
        if k:
            px, py = points[k - 1][:2]
            t += max(np.hypot(x - px, y - py) / speed, 0.3)
        frames.append(Keyframe(t, x, y, reach, IN_PATH, label, lean))
        if pause > 0:
            t += pause
            frames.append(Keyframe(t, x, y, reach, IN_PATH, label, lean))
    return ScriptedHuman(frames)


def crossing(rng: np.random.Generator, duration: float) -> ScriptedHuman:
    """A person crossing the workspace at 1.6 m/s, back and forth, 0.9 to 1.6 m from the robot's axis."""
    x = -float(rng.uniform(0.9, 1.6))
    side = float(rng.choice([-1.0, 1.0]))
    points = [(x, side * 2.5 * (-1) ** k, 0.0, 0.0) for k in range(int(duration / 3.0) + 2)]
    return _walk(points, "crossing at 1.6 m/s")


def standing_in_path(rng: np.random.Generator, duration: float) -> ScriptedHuman:
    """A person walking up and standing next to the path, reaching into it, the whole time."""
    x, y = -float(rng.uniform(0.95, 1.3)), float(rng.uniform(-0.5, 0.5))
    reach, lean = float(rng.uniform(0.4, 1.0)), float(rng.uniform(0.2, 0.8))
    arrive = float(np.hypot(x + 2.6, 0.0)) / 1.2
    label = "standing in the path"
    return ScriptedHuman([Keyframe(0.0, -2.6, y, 0.0, IN_PATH, label), Keyframe(arrive, x, y, reach, IN_PATH, label, lean),
                          Keyframe(arrive + duration, x, y, reach, IN_PATH, label, lean)])


def _stops(rng: np.random.Generator, duration: float) -> list[tuple[float, float, float, float]]:
    """A wanderer's stops (x, y, reach, lean): 0.8 to 2.5 m from the robot's axis on its working side, reaching
    towards the path (at random) from those within 1.4 m."""
    points = []
    for _ in range(int(duration / 1.5) + 2):
        r, angle = float(rng.uniform(0.8, 2.5)), float(rng.uniform(0.55 * np.pi, 1.45 * np.pi))
        reach = float(rng.uniform(0.0, 1.0)) if r < 1.4 else 0.0
        points.append((r * np.cos(angle), r * np.sin(angle), reach, 0.5 * reach))
    return points


def _wander(rng: np.random.Generator, duration: float) -> tuple[list[tuple[float, float, float, float]], float, float]:
    """A wanderer's stops, speed (m/s) and pause at each stop (s), drawn in this order."""
    points = _stops(rng, duration)
    return points, float(rng.uniform(0.6, WALK_SPEED)), float(rng.uniform(0, 1))


def random_walk(rng: np.random.Generator, duration: float) -> ScriptedHuman:
    """A person wandering around the robot's working side: random stops 0.8 to 2.5 m from its axis, at
    most 1.6 m/s, sometimes reaching towards the path."""
    points, speed, pause = _wander(rng, duration)
    return _walk(points, "random walk", speed=speed, pause=pause)


def two_humans(rng: np.random.Generator, duration: float) -> Crowd:
    """One crossing, one wandering."""
    return Crowd([crossing(rng, duration), random_walk(rng, duration)])


WANDERING_KINDS = ("random_walk", "two_humans")     # the kinds whose people's future is drawn as they go


def other_futures(kind: str, seed: int, duration: float, t0: float, rng: np.random.Generator, count: int) -> list:
    """`count` other futures of the wandering scenario (kind, seed) from t0 (s): the same people up to the end of
    the wanderer's present step (the stop they walk to or pause at at t0, and their pause there), then new stops
    drawn as the scenario draws its own (the same speed and pause; a crosser's walk, which repeats, as it is).
    Each is a future the scenario could have had, as likely as its own, given the past and more than a tracker
    sees (that stop, the walk's speed and pause): the spread of what a robot then does over them is the part of
    a prediction's error that no forecast of the people can take away (``bench/calibration.py --futures``)."""
    if kind not in WANDERING_KINDS:
        raise ValueError(f"no other futures for {kind!r}: its people's future is fixed by its start; "
                         f"wandering kinds: {', '.join(WANDERING_KINDS)}")
    drawn = np.random.default_rng(seed)
    crosser = crossing(drawn, duration) if kind == "two_humans" else None
    points, speed, pause = _wander(drawn, duration)
    own = _walk(points, "random walk", speed=speed, pause=pause).keyframes
    leaving = [frame.t for frame in (own[1::2] if pause > 0 else own)]      # s: when each stop is left
    present = next((k for k, t in enumerate(leaving) if t >= t0), len(points) - 1)
    futures = []
    for _ in range(count):
        walker = _walk(points[:present + 1] + _stops(rng, duration), "random walk", speed=speed, pause=pause)
        futures.append(walker if crosser is None else Crowd([crosser, walker]))
    return futures


PAPER_SPREAD = 0.05      # the paper's experiment as a distribution: each seed's phase period within +-5 %


def perturbed_paper(rng: np.random.Generator, duration: float) -> ScriptedHuman:
    """The paper's four phases over `duration` s, the phase period drawn within +-PAPER_SPREAD of duration / 4
    (the person's timing never repeats to the millisecond, and neither does the robot's; one fixed script
    measured many times would give a ratio with no interval). Later phases are cut off by the duration."""
    return paper_phases(duration / 4.0 * (1.0 + float(rng.uniform(-PAPER_SPREAD, PAPER_SPREAD))))


SCENARIO_KINDS = {"paper": perturbed_paper, "crossing": crossing,
                  "standing": standing_in_path, "two_humans": two_humans, "random_walk": random_walk}


# real people (evidence.recorded): windows of the human-assembly recordings at a placement; not among the defaults
# of the benchmarks, which run the scripted kinds unless asked
RECORDED_KINDS = {"real_step_back": "step_back", "real_table_edge": "table_edge",      # kind: its placement
                  "real_around": "around"}                                             # (around: drawn per seed)
KNOWN_KINDS = tuple(sorted(SCENARIO_KINDS)) + tuple(sorted(RECORDED_KINDS))


def kinds_problem(kinds, allow_none: bool = False) -> str | None:
    """What is wrong with the scenario kinds a benchmark was asked for, in words, or None: a kind not known, none
    at all (unless `allow_none`), or a real-people kind without recordings to read (saying where it looked). An
    entry point says so before it starts, not in every worker."""
    unknown = sorted(set(kinds) - set(KNOWN_KINDS))
    if unknown or not (kinds or allow_none):
        return f"unknown or none {unknown or list(kinds)}; known: {', '.join(KNOWN_KINDS)}"
    if any(k in RECORDED_KINDS for k in kinds):
        from evidence.recorded import recordings, recordings_folder

        try:
            recordings(recordings_folder())
        except ConfigError as exc:
            return str(exc)
    return None


def add_scenario_arguments(parser, kinds: str, seeds: int, seed: int) -> None:
    """A benchmark's seeded scenarios as command-line options (argparse): --kinds, --seeds (a kind), --seed (the
    first), --duration (s), --workers; ``scenario_arguments`` checks them."""
    parser.add_argument("--kinds", default=kinds, help="comma-separated scenario kinds")
    parser.add_argument("--seeds", type=int, default=seeds, help="scenarios a kind")
    parser.add_argument("--seed", type=int, default=seed, help="the first scenario seed")
    parser.add_argument("--duration", type=float, default=12.0, help="simulated seconds a scenario")
    parser.add_argument("--workers", type=int, default=2, help="local processes")


def scenario_arguments(parser, args) -> list[str]:
    """The kinds of ``add_scenario_arguments``' options, each checked: a usage error (exit 2) saying what is wrong
    with them, before anything runs."""
    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    if args.seeds < 1 or not args.duration > 0 or args.workers < 1:
        parser.error("--seeds, --workers >= 1; --duration > 0")
    if problem := kinds_problem(kinds):
        parser.error(f"--kinds: {problem}")
    return kinds


def make_scenario(kind: str, seed: int, duration: float):
    """The human(s) of one seeded scenario: the same (kind, seed, duration) gives the same motion (a recorded
    kind: with the same recordings, evidence.recorded)."""
    if kind in RECORDED_KINDS:
        from evidence.recorded import recorded_scenario

        return recorded_scenario(kind, seed, duration)
    if kind not in SCENARIO_KINDS:
        raise ValueError(f"unknown scenario kind {kind!r}; known: {list(KNOWN_KINDS)}")
    return SCENARIO_KINDS[kind](np.random.default_rng(seed), duration)
