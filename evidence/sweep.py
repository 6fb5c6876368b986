"""One simulated scenario as a pure function of its description: the unit every benchmark and sweep runs.

``run_scenario(spec) -> record``: a ``ScenarioSpec`` (scenario kind, seed, simulated duration, strategy, the
configuration values that differ from the shipped ones, the full strategy's forecaster, the people's latency) in, a
flat record of plain numbers and strings out (shuttles, stopped and slowed seconds, violations, replans, compute), so that
records travel between processes and machines (pickle, Parquet) and compare field by field. Deterministic:
the same spec gives the same record on any machine and in any order (the simulation is seeded by the spec and
charges each path search a fixed time; only ``wall_s``, the compute it cost, varies). The ``Strategies`` a
spec needs (robot, collision model, planners: seconds to build) are built once per process and
configuration and kept.

Overrides are dotted keys of the cell configuration (``ssm.reaction_time``, ``scaling.alpha_min``), validated
as a configuration file is: a bad key or value is a ConfigError naming it.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field

from shared.config import CellConfig
from shared.core.errors import ConfigError

RECORD_FIELDS = ("kind", "seed", "duration", "strategy", "overrides", "forecaster", "latency", "shuttles",
                 "completed", "sim_s", "stopped_fraction", "slowed_fraction", "stopped_s", "slowed_s", "min_margin_m_s",
                 "violations", "command_exceedances", "replans", "replans_failed", "beta_requests", "wall_s")


@dataclass(frozen=True)
class ScenarioSpec:
    """One (scenario, strategy, configuration) to simulate. overrides: ((dotted key, value), ...), sorted;
    forecaster: ``module:attribute`` of the full strategy's forecast of the people (None: the default); latency
    (s): the people reach the cell that long after their capture (a camera pipeline's; ``Strategies.run``)."""

    kind: str
    seed: int
    duration: float
    strategy: str
    overrides: tuple[tuple[str, float], ...] = field(default=())
    forecaster: str | None = None
    latency: float = 0.0

    def __post_init__(self) -> None:
        from shared.tracking.tracker import OLDEST_SAMPLE

        if not (math.isfinite(self.latency) and 0.0 <= self.latency <= OLDEST_SAMPLE):
            raise ConfigError(f"latency: from 0 to {OLDEST_SAMPLE} s (a sample older is stale), got {self.latency!r}")

    def config_key(self) -> str:
        """The configuration this spec runs under, as one string (the records' ``overrides`` column)."""
        return json.dumps(dict(self.overrides), sort_keys=True)


def config_of(overrides: tuple[tuple[str, float], ...]) -> CellConfig:
    """The shipped configuration with these dotted-key values in place (validated: ConfigError naming a bad
    key or value)."""
    doc: dict[str, dict[str, float]] = {}
    for key, value in overrides:
        section, _, name = key.partition(".")
        if not name:
            raise ConfigError(f"override {key!r}: expected section.key, e.g. ssm.reaction_time")
        doc.setdefault(section, {})[name] = value
    return CellConfig.from_mapping(doc, "overrides")


_STRATEGIES: dict[tuple, object] = {}
KEPT = 4            # configurations whose Strategies a process keeps (a sweep's chunks come point by point)


def strategies_for(overrides: tuple[tuple[str, float], ...], forecaster: str | None):
    """This process's ``Strategies`` for a configuration, built on first use (the shipped scene); the KEPT
    most recently used are kept, so a worker of a long sweep does not grow with its grid."""
    key = (overrides, forecaster)
    if key in _STRATEGIES:
        _STRATEGIES[key] = _STRATEGIES.pop(key)          # most recently used last
    else:
        while len(_STRATEGIES) >= KEPT:
            _STRATEGIES.pop(next(iter(_STRATEGIES)))
        from evidence.strategies import Strategies
        from shared.planning.forecast import load_forecaster
        from shared.planning.scene import DEFAULT_SCENE, load_scene
        _STRATEGIES[key] = Strategies(config_of(overrides), scene=load_scene(DEFAULT_SCENE),
                                      forecaster=None if forecaster is None else load_forecaster(forecaster))
    return _STRATEGIES[key]


def run_scenario(spec: ScenarioSpec) -> dict:
    """Simulate one spec; its record (RECORD_FIELDS)."""
    started = time.perf_counter()
    s = strategies_for(spec.overrides, spec.forecaster).run(spec.strategy, spec.kind, spec.seed,
                                                            spec.duration, latency=spec.latency).summary()
    return {"kind": spec.kind, "seed": spec.seed, "duration": spec.duration, "strategy": spec.strategy,
            "overrides": spec.config_key(), "forecaster": spec.forecaster or "", "latency": spec.latency,
            "shuttles": float(s["shuttle_progress"]), "completed": int(s["shuttles_completed"]),
            "sim_s": float(s["duration_s"]), "stopped_fraction": float(s["stopped_fraction"]),
            "slowed_fraction": float(s["slowed_fraction"]),
            "stopped_s": float(s["stopped_fraction"] * s["duration_s"]),
            "slowed_s": float(s["slowed_fraction"] * s["duration_s"]),
            "min_margin_m_s": float("nan") if s["min_margin_m_s"] is None else float(s["min_margin_m_s"]),
            "violations": int(s["violations"]), "command_exceedances": int(s["command_exceedances"]),
            "replans": len(s["replans"]), "replans_failed": int(s["replans_failed"]),
            "beta_requests": int(s["beta_requests"]), "wall_s": time.perf_counter() - started}


class RunFailed(RuntimeError):
    """A run of a chunk raised: the message names the run (kind, seed, strategy, configuration) and the error, so
    that `hrc scenario` can take it apart; a plain string, so it crosses a process pool or Dask as it is."""


def run_chunk(specs: list[ScenarioSpec]) -> list[dict]:
    """The records of a chunk of specs, in order (the unit an executor schedules)."""
    records = []
    for spec in specs:
        try:
            records.append(run_scenario(spec))
        except Exception as exc:
            where = f"{spec.kind} seed {spec.seed}, {spec.duration:g} s, {spec.strategy}"
            where += f", {spec.config_key()}" if spec.overrides else ""
            where += f", {1e3 * spec.latency:g} ms late" if spec.latency else ""
            raise RunFailed(f"{where}: {type(exc).__name__}: {exc}") from exc
    return records
