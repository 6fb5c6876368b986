"""The side-by-side figures of a set of simulated scenarios (pure): per strategy shuttles per minute, time
stopped and slowed, margins and violations; the ratios of pairs of strategies with their paired bootstrap
intervals (evidence.stats); the share of what the people cost that a strategy wins back. Computed from
records (evidence.sweep), so a summary is the same whether the records came from memory or from a sweep's
Parquet files.

``rows``: one per scenario, ``{"kind", "seed", strategy: {"shuttles", "completed", "duration_s",
"stopped_fraction", "slowed_fraction", "min_margin_m_s", "violations", "command_exceedances", "wall_s"}}``
(``wide_rows`` builds them from records).
"""

from __future__ import annotations

import json
import math

import numpy as np

from evidence.stats import SAME, PairedRatio, paired_ratio
from evidence.strategies import KNOWN


def wide_rows(records: list[dict]) -> list[dict]:
    """Records (one per scenario and strategy, of one configuration) as rows (one per scenario, every strategy
    in it), in the order the scenarios first appear."""
    rows: dict[tuple, dict] = {}
    for r in records:
        row = rows.setdefault((r["kind"], r["seed"]), {"kind": r["kind"], "seed": r["seed"]})
        margin = r["min_margin_m_s"]
        row[r["strategy"]] = {"shuttles": r["shuttles"], "completed": r["completed"], "duration_s": r["sim_s"],
                              "stopped_fraction": r["stopped_fraction"], "slowed_fraction": r["slowed_fraction"],
                              "min_margin_m_s": None if margin is None or math.isnan(margin) else margin,
                              "violations": r["violations"], "command_exceedances": r["command_exceedances"],
                              "wall_s": r["wall_s"]}
    return list(rows.values())


def aggregate(rows: list[dict], horizon: float) -> dict:
    """Per strategy (those the rows have): shuttles per minute, time stopped (a share, and seconds per scenario),
    time slowed (seconds per scenario below full speed while moving), the smallest margin (m),
    violations and command exceedances, wall time per scenario."""
    result = {}
    for strategy in columns(rows):
        runs = [r[strategy] for r in rows]
        minutes = sum(r["duration_s"] for r in runs) / 60.0
        margins = [r["min_margin_m_s"] for r in runs if r["min_margin_m_s"] is not None]
        result[strategy] = {
            "shuttles_per_min": round(sum(r["shuttles"] for r in runs) / minutes, 3) if minutes else 0.0,
            "stopped_fraction": round(float(np.mean([r["stopped_fraction"] for r in runs])), 4),
            # seconds per scenario stopped and slowed (below full speed, moving): where the time went
            "stopped_s": round(float(np.mean([r["stopped_fraction"] * r["duration_s"] for r in runs])), 3),
            "slowed_s": round(float(np.mean([r.get("slowed_fraction", 0.0) * r["duration_s"] for r in runs])), 3),
            "min_margin_m": round(min(margins) * horizon, 4) if margins else None,
            "violations": int(sum(r["violations"] for r in runs)),
            "command_exceedances": int(sum(r["command_exceedances"] for r in runs)),
            "wall_s_per_scenario": round(float(np.mean([r["wall_s"] for r in runs])), 3)}
    return result


PAIRS = (("full", "scale_only"), ("full", "zones"), ("foresight", "scale_only"), ("full", "foresight"),
         ("oracle", "scale_only"), ("full", "oracle"), ("scale_only", "scale_only_paper"), ("full", "full_paper"),
         ("full_paper", "zones"), ("fixed_path", "scale_only"), ("full", "fixed_path"),
         ("clairvoyant", "scale_only"), ("full", "clairvoyant"),
         # the planning layer under the paper's formula, against that formula's own baselines
         ("full_paper", "scale_only_paper"), ("fixed_path_paper", "scale_only_paper"),
         ("full_paper", "fixed_path_paper"))


def columns(rows: list[dict]) -> tuple[str, ...]:
    """The strategies (and bounds) these rows were run with, in the table's order."""
    return tuple(s for s in KNOWN if rows and s in rows[0])


def won_back(per_strategy: dict, empty: float, strategy: str = "full") -> float | None:
    """(full - scale_only) / (empty - scale_only) in shuttles per minute: the share of the throughput the
    people cost the scaling layer alone that the full architecture (or `strategy`) wins back (None where
    they cost it nothing)."""
    full, scale = per_strategy[strategy]["shuttles_per_min"], per_strategy["scale_only"]["shuttles_per_min"]
    lost = empty - scale
    return round((full - scale) / lost, 3) if lost > 1e-9 else None


def ratios(rows: list[dict]) -> dict:
    """Each pair of PAIRS: the ratio of shuttles and its paired bootstrap interval (evidence.stats) over
    these scenarios (every strategy runs each scenario equally long, so it is the shuttles-per-minute ratio),
    or, where there is none (the second strategy did nothing at all), the reason."""
    return {f"{a}/{b}": ratio_or_why([r[a]["shuttles"] for r in rows], [r[b]["shuttles"] for r in rows])
            for a, b in PAIRS if a in columns(rows) and b in columns(rows)}


def ratio_or_why(numerator: list[float], denominator: list[float]) -> PairedRatio | str:
    """The paired ratio of two lists of per-scenario shuttles with its bootstrap interval (``paired_ratio``, seeded:
    the same figures every time), or, where there is none (the denominator did nothing at all), the reason."""
    try:
        return paired_ratio(numerator, denominator, np.random.default_rng(0))
    except ValueError as exc:
        return f"no ratio: {exc}"


def by_point(records: list[dict]) -> dict[str, list[dict]]:
    """Records grouped by configuration (their ``overrides``, a JSON text), in the order the points first appear."""
    points: dict[str, list[dict]] = {}
    for r in records:
        points.setdefault(r["overrides"], []).append(r)
    return points


def per_point(records: list[dict], horizon: float) -> list[dict]:
    """A sweep's records grouped by configuration (``by_point``): for each, the point's values, every strategy's
    aggregate and the pairs' ratios with their intervals, over the scenarios every strategy of the point has run;
    and the same for each scenario kind alone (``kinds``: the goals of a comparison are per kind, and a kind
    where the planning layer gains hides one where it loses in the overall figure)."""
    out = []
    for key, of_point in by_point(records).items():
        strategies = sorted({r["strategy"] for r in of_point})
        rows = [row for row in wide_rows(of_point) if all(s in row for s in strategies)]
        out.append({"point": json.loads(key), "scenarios": len(rows), "strategies": aggregate(rows, horizon),
                    "ratios": ratios(rows), "kinds": per_kind(rows, horizon)})
    return out


def per_kind(rows: list[dict], horizon: float) -> dict[str, dict]:
    """The rows of each scenario kind alone, kinds in alphabetical order: ``{kind: {"scenarios", "strategies"
    (``aggregate``), "ratios" (``ratios``), "most_lost" (each pair's scenarios that lost most, ``extremes``)}}``."""
    out = {}
    for kind in sorted({row["kind"] for row in rows}):
        of_kind = [row for row in rows if row["kind"] == kind]
        lost = {f"{a}/{b}": extremes([(r[a]["shuttles"], r[b]["shuttles"], r["kind"], r["seed"]) for r in of_kind],
                                     lost=True)
                for a, b in PAIRS if a in columns(of_kind) and b in columns(of_kind)}
        out[kind] = {"scenarios": len(of_kind), "strategies": aggregate(of_kind, horizon), "ratios": ratios(of_kind),
                     "most_lost": lost}
    return out


MOST = 3        # the scenarios named for the largest losses and gains of a comparison


def compared(numerator: list[dict], denominator: list[dict]) -> list[dict]:
    """Each strategy's shuttles in `numerator`'s records over its shuttles in `denominator`'s, scenario by
    scenario (the same kind, seed and duration in both; the others are left out), per kind and over all of
    them: ``{"strategy", "kind" ("overall" for all), "scenarios", "ratio"}`` with the paired bootstrap
    interval and the scenarios better, worse and the same (``PairedRatio``), or, where there is none, the
    reason. Two configurations of one sweep, or one configuration run by two versions of the code: the
    same seeded scenarios, so each scenario is its own control."""
    index = {(r["strategy"], r["kind"], r["seed"], r["duration"]): r["shuttles"] for r in denominator}
    pairs: dict[tuple[str, str], list[tuple[float, float, str, int]]] = {}
    for r in numerator:
        other = index.get((r["strategy"], r["kind"], r["seed"], r["duration"]))
        if other is not None:
            pairs.setdefault((r["strategy"], r["kind"]), []).append((r["shuttles"], other, r["kind"], r["seed"]))
    out = []
    for strategy in sorted({s for s, _ in pairs}):
        kinds = sorted(k for s, k in pairs if s == strategy)
        groups = [(kind, pairs[(strategy, kind)]) for kind in kinds]
        if len(kinds) > 1:
            groups.append(("overall", [p for _, of_kind in groups for p in of_kind]))
        for kind, of_kind in groups:
            ratio = ratio_or_why([p[0] for p in of_kind], [p[1] for p in of_kind])
            out.append({"strategy": strategy, "kind": kind, "scenarios": len(of_kind), "ratio": ratio,
                        "most_lost": extremes(of_kind, lost=True), "most_gained": extremes(of_kind, lost=False)})
    return out


def extremes(pairs: list[tuple[float, float, str, int]], lost: bool, most: int = MOST) -> list[list]:
    """The `most` scenarios whose numerator fell furthest below (lost) or rose furthest above its denominator,
    ``[kind, seed, numerator, denominator]`` each, largest difference first; only those that differ by more than
    SAME shuttles. The scenarios to take apart first."""
    sign = -1.0 if lost else 1.0
    differing = [p for p in pairs if sign * (p[0] - p[1]) > SAME]
    differing.sort(key=lambda p: -sign * (p[0] - p[1]))
    return [[kind, int(seed), round(a, 3), round(b, 3)] for a, b, kind, seed in differing[:most]]


def against_first(records: list[dict]) -> list[dict]:
    """Every point of a sweep after the first against the first (``compared``): ``{"point", "of", "compared"}``,
    the two points' values and the ratios. The first point is the reference a grid is read against: the
    values as shipped, where a grid lists them first."""
    points = list(by_point(records).items())
    if len(points) < 2:
        return []
    first_key, first = points[0]
    return [{"point": json.loads(key), "of": json.loads(first_key), "compared": compared(of_point, first)}
            for key, of_point in points[1:]]


def against_other(records: list[dict], other: list[dict]) -> list[dict]:
    """Every point of a sweep against the same point (the same configuration values) of another sweep's
    records (``compared``): ``{"point", "compared"}``, for the points both have. The other sweep is typically
    the same grid run by other code (another commit, a worktree), so the ratio is what the code changed."""
    others = by_point(other)
    return [{"point": json.loads(key), "compared": compared(of_point, others[key])}
            for key, of_point in by_point(records).items() if key in others]
