"""hrc sweep's grid: every combination of configuration values, with every strategy on the same seeded
scenarios; the grid read from the command line or a YAML file and checked before anything runs; the figures
of each point, overall and per kind, and its ratios against the first point and against another sweep, as lines,
summary.json, sweep.csv, sweep-kinds.csv and a plot per key (the runs themselves: tools.sweep)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from evidence.sweep import ScenarioSpec
from shared.core.errors import HrcError


@dataclass
class Grid:
    """A sweep: every combination of the values in `values` (dotted configuration keys), each with every
    strategy on the same `scenarios` seeded scenarios (kinds in turn, seeds from `seed`, `duration` s)."""

    values: dict[str, list[float | str]]
    strategies: list[str]
    kinds: list[str]
    scenarios: int
    duration: float
    seed: int = 0
    latency: float = 0.0        # s: every run's people that long after their capture (``ScenarioSpec.latency``)

    def points(self) -> list[tuple[tuple[str, float | str], ...]]:
        import itertools

        keys = sorted(self.values)
        return [tuple(zip(keys, combo)) for combo in itertools.product(*(self.values[k] for k in keys))]

    def specs(self, forecaster: str | None = None) -> list[ScenarioSpec]:
        """Point by point, scenario by scenario, every strategy: a chunk holds whole scenarios of one point."""
        return [ScenarioSpec(self.kinds[k % len(self.kinds)], self.seed + k, self.duration, strategy,
                             overrides=point, forecaster=forecaster, latency=self.latency)
                for point in self.points() for k in range(self.scenarios) for strategy in self.strategies]


class GridError(HrcError, ValueError):
    """A sweep's grid is not usable (a bad key, value, strategy or kind), with what is wrong."""


def _value(text: str) -> float | str:
    """A number where the text is one, else the word itself (a choice: ``planning.judge=cost,scaling``)."""
    try:
        return float(text)
    except ValueError:
        return text


def point_label(items) -> str:
    """``key=value, ...`` of a grid point's (key, value) pairs: numbers as %g, words as they are; a sweep of
    no keys has one point, the configuration as shipped."""
    items = list(items)
    if not items:
        return "as shipped"
    return ", ".join(f"{k}={v:g}" if not isinstance(v, str) else f"{k}={v}" for k, v in items)


def parse_values(text: str) -> tuple[str, list[float | str]]:
    """``ssm.reaction_time=0.1,0.15,0.2`` -> ("ssm.reaction_time", [0.1, 0.15, 0.2]); words stay words
    (``planning.judge=cost,scaling``); whether a key takes them, ``check_grid`` says."""
    key, sep, values = text.partition("=")
    words = [v.strip() for v in values.split(",")]
    if not sep or not key.strip() or not all(words):
        raise GridError(f"--set {text!r}: expected KEY=V1,V2,... (e.g. ssm.reaction_time=0.1,0.15)")
    return key.strip(), [_value(v) for v in words]


def load_grid(path: Path) -> dict:
    """A grid file (YAML): ``set: {KEY: [values]}`` and optionally strategies, kinds, scenarios, duration, seed,
    forecaster."""
    import yaml

    try:
        doc = yaml.safe_load(path.read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise GridError(f"{path}: cannot read the grid: {exc}") from None
    known = {"set", "strategies", "kinds", "scenarios", "duration", "seed", "forecaster", "latency"}
    if not isinstance(doc, dict) or set(map(str, doc)) - known:
        raise GridError(f"{path}: expected a mapping with some of {sorted(known)}")
    values = doc.get("set") or {}
    if not isinstance(values, dict) or not all(isinstance(v, list) and v for v in values.values()):
        raise GridError(f"{path}: set: expected a mapping of keys to non-empty lists of numbers or words")
    return doc


def check_grid(grid: Grid) -> None:
    """Every point a valid configuration, every strategy and kind known (GridError naming what is not)."""
    import math

    from evidence.scenarios import kinds_problem
    from evidence.strategies import KNOWN
    from evidence.sweep import config_of
    from shared.core.errors import ConfigError

    if not grid.strategies or set(grid.strategies) - set(KNOWN):
        raise GridError(f"strategies: unknown or none {sorted(set(grid.strategies) - set(KNOWN))}; known: "
                        f"{', '.join(KNOWN)}")
    if problem := kinds_problem(grid.kinds):
        raise GridError(f"kinds: {problem}")
    if grid.scenarios < 1 or not (grid.duration > 0 and math.isfinite(grid.duration)):
        raise GridError("scenarios must be >= 1 and duration a positive number of seconds")
    for key, values in grid.values.items():
        if not all(isinstance(v, (int, float, str)) and not isinstance(v, bool) for v in values):
            raise GridError(f"{key}: the values must be numbers or words, got {values}")
        if len({type(v) is str for v in values}) > 1:
            raise GridError(f"{key}: the values must be all numbers or all words, got {values}")
    for point in grid.points():
        try:
            config_of(point)
        except ConfigError as exc:
            raise GridError(str(exc)) from None


def plot_sweep(points: list[dict], grid: Grid, out: Path) -> list[Path]:
    """One plot per swept key: shuttles per minute of every strategy against the key's values (a line for each
    combination of the other keys' values)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    for key in sorted(grid.values):
        fig, ax = plt.subplots(figsize=(7, 4.5))
        others = sorted({tuple((k, v) for k, v in sorted(p["point"].items()) if k != key) for p in points})
        for strategy in grid.strategies:
            for rest in others:
                line = sorted((p["point"][key], p["strategies"][strategy]["shuttles_per_min"]) for p in points
                              if tuple((k, v) for k, v in sorted(p["point"].items()) if k != key) == rest
                              and strategy in p["strategies"])
                label = strategy + ("" if not rest else f" ({point_label(rest)})")
                ax.plot([x for x, _ in line], [y for _, y in line], "o-", label=label)
        ax.set_xlabel(key)
        ax.set_ylabel("shuttles per minute")
        ax.set_title(f"{grid.scenarios} scenarios a point ({', '.join(grid.kinds)}), {grid.duration:g} s each")
        ax.legend(fontsize=8)
        fig.tight_layout()
        path = out / f"sweep-{key}.png"
        fig.savefig(path, dpi=80)
        plt.close(fig)
        written.append(path)
    return written


def ratio_text(ratio) -> str:
    """A ratio as a line says it (``PairedRatio.describe``: the ratio, its interval, the scenarios better, worse and
    the same), or why there is none."""
    return ratio if isinstance(ratio, str) else ratio.describe()


def seeds_text(scenarios: list[list]) -> str:
    """``evidence.summary.extremes``' scenarios as a line names them: ``seed 9396 3.47 against 4.54, ...``."""
    return ", ".join(f"seed {seed} {a:.2f} against {b:.2f}" for _, seed, a, b in scenarios)


def kind_lines(point: dict, strategies: list[str]) -> list[str]:
    """A point's figures kind by kind (``evidence.summary.per_point``): where the planning layer gains and where it
    loses, which the overall figure sums away, and each pair's scenarios that lost most (the seeds to take apart
    first). Nothing for a sweep of one kind."""
    if len(point["kinds"]) < 2:
        return []
    lines = []
    for kind, of_kind in point["kinds"].items():
        figures = "  ".join(f"{s} {of_kind['strategies'][s]['shuttles_per_min']:.2f}/min" for s in strategies
                            if s in of_kind["strategies"])
        pairs = "  ".join(f"{pair} {ratio_text(r)}" for pair, r in of_kind["ratios"].items())
        lines.append(f"  {kind} ({of_kind['scenarios']}): {figures}  {pairs}".rstrip())
        for pair, lost in of_kind["most_lost"].items():
            if lost:
                lines.append(f"    {pair} most lost: {seeds_text(lost)}")
    return lines


def compared_lines(comparisons: list[dict]) -> list[str]:
    """``evidence.summary.compared``'s ratios, a line each: strategy, kind, ratio, interval and counts; under each
    kind's line the scenarios that lost and gained most (seed: numerator against denominator)."""
    lines = []
    for c in comparisons:
        lines.append(f"  {c['strategy']} {c['kind']} ({c['scenarios']}): {ratio_text(c['ratio'])}")
        if c["kind"] == "overall":
            continue
        for label in ("most_lost", "most_gained"):
            if c[label]:
                lines.append(f"    {label.replace('_', ' ')}: {seeds_text(c[label])}")
    return lines


def figure_lines(points: list[dict], strategies: list[str], first: list[dict], against: dict | None) -> list[str]:
    """What hrc sweep prints when it is done: a line per point (each strategy's shuttles per minute and
    violations, the pairs' ratios), then its kinds (``kind_lines``); every point against the first
    (``evidence.summary.against_first``); every point against the same point of another sweep (`against`:
    ``{"folder", "points"}``, ``evidence.summary.against_other``)."""
    lines = []
    for p in points:
        figures = "  ".join(f"{s} {p['strategies'][s]['shuttles_per_min']:.2f}/min (viol {p['strategies'][s]['violations']})"
                            for s in strategies if s in p["strategies"])
        pairs = "  ".join(f"{pair} {r.interval_text()}" for pair, r in p["ratios"].items() if not isinstance(r, str))
        lines.append(f"{point_label(sorted(p['point'].items()))}: {figures}  {pairs}")
        lines += kind_lines(p, strategies)
    for f in first:          # named by the values that differ (the others are the same in both)
        differ = sorted(k for k in set(f["point"]) | set(f["of"]) if f["point"].get(k) != f["of"].get(k))
        name = lambda values: point_label([(k, values[k]) for k in differ if k in values])
        lines.append(f"{name(f['point'])} against {name(f['of'])}:")
        lines += compared_lines(f["compared"])
    if against is not None:
        for a in against["points"]:
            lines.append(f"{point_label(sorted(a['point'].items()))} against the same point in {against['folder']}:")
            lines += compared_lines(a["compared"]) or ["  no scenario in common (kinds, seeds, duration)"]
        if not against["points"]:
            lines.append(f"hrc sweep: {against['folder']} has none of these points (configuration values) to compare "
                         f"with")
    return lines


def _comparisons_json(comparisons: list[dict]) -> list[dict]:
    return [{**c, "ratio": c["ratio"] if isinstance(c["ratio"], str) else c["ratio"].as_dict()} for c in comparisons]


def write_summary(points: list[dict], grid: Grid, out: Path, first: list[dict] | None = None,
                  against: dict | None = None) -> None:
    """summary.json (every point's figures and ratios with their intervals, overall and per kind; each point
    against the first, `first` (``evidence.summary.against_first``); and against another sweep's records,
    `against`: ``{"folder", "points": [{"point", "compared"}]}``), sweep.csv (a row per point and strategy),
    sweep-kinds.csv (a row per point, kind and strategy) and the plots."""
    import csv

    out.mkdir(parents=True, exist_ok=True)
    lists = lambda ratios: {k: (r if isinstance(r, str) else r.as_list()) for k, r in ratios.items()}
    doc = {"grid": {"set": grid.values, "strategies": grid.strategies, "kinds": grid.kinds,
                    "scenarios": grid.scenarios, "duration": grid.duration, "seed": grid.seed,
                    "latency": grid.latency},
           "points": [{**p, "ratios": lists(p["ratios"]),
                       "kinds": {k: {**v, "ratios": lists(v["ratios"])} for k, v in p["kinds"].items()}}
                      for p in points],
           "against_first": [{**f, "compared": _comparisons_json(f["compared"])} for f in first or []]}
    if against is not None:
        doc["against"] = {"folder": against["folder"],
                          "points": [{**a, "compared": _comparisons_json(a["compared"])} for a in against["points"]]}
    (out / "summary.json").write_text(json.dumps(doc, indent=1))
    keys = sorted(grid.values)
    columns = ["strategy", "scenarios", "shuttles_per_min", "stopped_s", "slowed_s", "violations"]
    with open(out / "sweep.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(keys + columns)
        for p in points:
            for strategy, a in p["strategies"].items():
                writer.writerow([p["point"].get(k) for k in keys] + [strategy, p["scenarios"], a["shuttles_per_min"],
                                                                      a["stopped_s"], a["slowed_s"], a["violations"]])
    with open(out / "sweep-kinds.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(keys + ["kind"] + columns)
        for p in points:
            for kind, of_kind in p["kinds"].items():
                for strategy, a in of_kind["strategies"].items():
                    writer.writerow([p["point"].get(k) for k in keys] + [kind, strategy, of_kind["scenarios"],
                                                                          a["shuttles_per_min"], a["stopped_s"],
                                                                          a["slowed_s"], a["violations"]])
    plot_sweep(points, grid, out)
