"""Where the tracked people are predicted to be while the robot travels: the planning layer's forecast.

The SSM-aware time cost (``shared.planning.time_cost``) walks a path against the people *as they will be*
when the robot gets to each sample. What "as they will be" means is a forecaster's job, kept apart from
the cost so that a better prediction of human motion can replace the default without touching the cost:

* ``ConstantVelocity``: the default, in the cell and in the simulation: every body part moves on along
  its tracked velocity for the forecast's horizon, then stays there; a part slower than ``drift_speed``
  (``shared.core.humans.STANDING_SPEED``: someone shifting their stance) and a part of unknown velocity
  stay where they are;
* any object with ``forecast(humans, horizon) -> PeopleForecast`` (``evidence.foresight`` gives the
  simulation's scripted people their own future, the bound no prediction can beat). The benchmarks take
  one by name, ``module:attribute`` (``load_forecaster``), so a researcher's predictor is measured without
  editing the project: ``bench/forecast.py`` for how far it is off, ``bench/compare.py`` for what it wins.

A forecast is frames of the capsules' end points at evenly spaced times from now; between two frames a
capsule moves linearly (so two frames hold a constant-velocity forecast exactly), after the last it stays.
For choosing between plans only, never for a safety decision: the scaling layer and the monitor use the
people as tracked, with the standard's worst-case approach speeds. Pure: no I/O.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from shared.core.humans import STANDING_SPEED, HumanCapsules, end_speeds


@dataclass(frozen=True)
class PeopleForecast:
    """frames (F, M, 2, 3): the M capsules' end points (m, robot base frame) at times 0, step, 2 step, ...
    (s from now); velocities (F, M, 2, 3): their end-point velocities (m/s) from each frame on, what the SSM
    takes as the approach speed (where velocity_known of the tracked humans says they are known)."""

    frames: np.ndarray
    velocities: np.ndarray
    step: float

    def __post_init__(self) -> None:
        for name in ("frames", "velocities"):
            object.__setattr__(self, name, np.ascontiguousarray(getattr(self, name), dtype=np.float64))
        if self.frames.ndim != 4 or self.frames.shape[0] < 1 or self.frames.shape[2:] != (2, 3):
            raise ValueError(f"forecast frames must be (F >= 1, M, 2, 3), not {self.frames.shape}")
        if self.velocities.shape != self.frames.shape:
            raise ValueError("forecast velocities and frames disagree in shape")
        if not self.step > 0.0:
            raise ValueError(f"forecast step must be > 0 s, not {self.step}")

    @property
    def horizon(self) -> float:
        """Seconds from now to the last frame (0: the people held where they are)."""
        return (self.frames.shape[0] - 1) * self.step

    def at(self, shift: float) -> np.ndarray:
        """The capsules' end points (M, 2, 3) `shift` seconds from now: linear between frames, the last held
        after the horizon (what the time cost's kernel does at every step of its walk)."""
        where = min(max(shift, 0.0), self.horizon) / self.step
        i = min(int(where), self.frames.shape[0] - 1)
        following = min(i + 1, self.frames.shape[0] - 1)
        frac = where - i if following > i else 0.0
        return self.frames[i] + frac * (self.frames[following] - self.frames[i])

    @staticmethod
    def still(humans: HumanCapsules) -> "PeopleForecast":
        """The people held where they are now."""
        return PeopleForecast(humans.segments[None], humans.velocities[None], 1.0)


class Forecaster(Protocol):
    def forecast(self, humans: HumanCapsules, horizon: float) -> PeopleForecast:
        """The people's frames over the next `horizon` seconds (s), from the tracked `humans` of now."""


@dataclass(frozen=True)
class ConstantVelocity:
    """Each capsule moves on along its tracked velocity for the horizon, then stays; a capsule whose ends
    both move slower than drift_speed (m/s), or of unknown velocity, stays where it is."""

    drift_speed: float = STANDING_SPEED

    def forecast(self, humans: HumanCapsules, horizon: float) -> PeopleForecast:
        if horizon <= 0.0 or humans.count == 0:
            return PeopleForecast.still(humans)
        fastest_end = end_speeds(humans)
        drifts = humans.velocity_known & (fastest_end >= self.drift_speed)
        end = humans.segments + np.where(drifts[:, None, None], humans.velocities * horizon, 0.0)
        return PeopleForecast(np.stack([humans.segments, end]), np.stack([humans.velocities, humans.velocities]),
                              horizon)


@dataclass(frozen=True)
class DampedVelocity:
    """Each capsule slows down as it goes: displacement v tau (1 - e^(-t / tau)), velocity v e^(-t / tau)
    (tau = time_constant, s), in `frames` steps over the horizon; parts slower than drift_speed (m/s) or of
    unknown velocity stay. Not the planning layer's default: it is off less than ``ConstantVelocity`` 2 s
    ahead in every scenario kind of the simulation, and plans worse (docs/measurements.md, "How far the
    forecast is off"). A second reference for ``bench/forecast.py`` and ``bench/compare.py --forecaster``."""

    time_constant: float = 1.0
    drift_speed: float = STANDING_SPEED
    frames: int = 8

    def forecast(self, humans: HumanCapsules, horizon: float) -> PeopleForecast:
        if horizon <= 0.0 or humans.count == 0:
            return PeopleForecast.still(humans)
        fastest_end = end_speeds(humans)
        moving = np.where((humans.velocity_known & (fastest_end >= self.drift_speed))[:, None, None],
                          humans.velocities, 0.0)
        t = np.linspace(0.0, horizon, self.frames + 1)[:, None, None, None]
        fading = np.exp(-t / self.time_constant)
        return PeopleForecast(humans.segments[None] + self.time_constant * (1.0 - fading) * moving[None],
                              fading * humans.velocities[None], horizon / self.frames)


@dataclass(frozen=True)
class WalksOrStops:
    """People who may do one of two things (issue 38, item 6; after Faroni et al., RA-L 2022, time-optimal
    planning under an uncertain human state): walk on along their tracked velocity (``ConstantVelocity``),
    with weight walk_weight, or stop where they are now. ``hypotheses`` gives both; the time cost takes the
    expected time over them (``SsmTimeCost.stretched``); ``forecast`` (what everything else takes: the
    scaling layer's forward run, the reach along a trajectory) is the walk."""

    walk_weight: float = 0.5
    drift_speed: float = STANDING_SPEED

    def __post_init__(self) -> None:
        if not 0.0 <= self.walk_weight <= 1.0:
            raise ValueError(f"walk_weight must be within [0, 1], not {self.walk_weight}")

    def forecast(self, humans: HumanCapsules, horizon: float) -> PeopleForecast:
        return ConstantVelocity(self.drift_speed).forecast(humans, horizon)

    def hypotheses(self, humans: HumanCapsules, horizon: float) -> list[tuple[float, PeopleForecast]]:
        return [(self.walk_weight, self.forecast(humans, horizon)), (1.0 - self.walk_weight, PeopleForecast.still(humans))]


def forecaster_problem(spec: str) -> str | None:
    """What is wrong with a forecaster's name (``load_forecaster`` tried once), in words, or None: an entry point
    says so before anything runs."""
    try:
        load_forecaster(spec)
    except ValueError as exc:
        return str(exc)
    return None


def load_forecaster(spec: str) -> Forecaster:
    """The forecaster named `spec`, ``package.module:attribute``: an object with ``forecast``, or a class or
    factory called with no arguments that returns one. ValueError saying what is wrong otherwise (the
    benchmarks turn it into their usage error)."""
    module_name, _, attribute = spec.partition(":")
    if not module_name or not attribute:
        raise ValueError(f"a forecaster is named module:attribute (e.g. shared.planning.forecast:ConstantVelocity), "
                         f"not {spec!r}")
    try:
        found = getattr(importlib.import_module(module_name), attribute)
    except ImportError as exc:
        raise ValueError(f"forecaster {spec!r}: cannot import {module_name!r}: {exc}") from None
    except AttributeError:
        raise ValueError(f"forecaster {spec!r}: {module_name!r} has no {attribute!r}") from None
    made = found() if isinstance(found, type) or (callable(found) and not hasattr(found, "forecast")) else found
    if not callable(getattr(made, "forecast", None)):
        raise ValueError(f"forecaster {spec!r}: {type(made).__name__} has no forecast(humans, horizon) method")
    return made
