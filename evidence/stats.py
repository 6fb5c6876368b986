"""How sure a side-by-side figure is: paired bootstrap intervals for the ratio of two strategies.

Every strategy runs the same seeded scenarios, so the comparison is paired: scenario k of one strategy
meets the same people as scenario k of the other. The figure a user reads is a ratio of totals (shuttles
per minute of one strategy over another's, every scenario equally long), and much of the spread between
scenarios (a person who stands in the path for the whole run, or never comes near) is shared by both
strategies. Resampling whole scenarios, with both strategies' results together, keeps that pairing: the
interval says how far the ratio would move with another draw of scenarios of the same kind, not how much
the scenarios differ from each other.

Pure and vectorised: numpy only, the random stream is the caller's (the same seed, the same interval).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SAME = 0.01    # shuttles: two runs of one scenario closer than this count as a tie


@dataclass(frozen=True)
class PairedRatio:
    """ratio: sum(numerator) / sum(denominator) over the scenarios; low, high: the bootstrap interval at
    `level`; better / worse / same: scenarios in which the numerator's strategy did more, less or the same
    (within SAME shuttles)."""

    ratio: float
    low: float
    high: float
    level: float
    better: int
    worse: int
    same: int

    def interval_text(self) -> str:
        """The ratio and its interval, ``1.012 [1.003, 1.020]``."""
        return f"{self.ratio:.3f} [{self.low:.3f}, {self.high:.3f}]"

    def describe(self) -> str:
        return f"{self.interval_text()} (better in {self.better}, worse in {self.worse}, same in {self.same})"

    def as_list(self) -> list[float]:
        """[ratio, low, high], rounded, for a JSON line."""
        return [round(self.ratio, 4), round(self.low, 4), round(self.high, 4)]

    def as_dict(self) -> dict:
        """The ratio, its interval and the scenarios better, worse and the same, rounded, for a JSON document."""
        ratio, low, high = self.as_list()
        return {"ratio": ratio, "interval": [low, high], "better": self.better, "worse": self.worse, "same": self.same}


def paired_ratio(numerator, denominator, rng: np.random.Generator, resamples: int = 4000,
                 level: float = 0.95) -> PairedRatio:
    """The ratio of totals of two strategies' per-scenario results (shuttles, same scenarios in the same
    order) and its percentile bootstrap interval, resampling scenarios with both results together.
    Raises ValueError for empty or unequal inputs, non-finite or negative values, a zero denominator
    total, or a level outside (0, 1)."""
    a = np.asarray(numerator, dtype=float)
    b = np.asarray(denominator, dtype=float)
    if a.ndim != 1 or a.shape != b.shape or a.size == 0:
        raise ValueError(f"need two equally long, non-empty lists of per-scenario results, got shapes "
                         f"{a.shape} and {b.shape}")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))) or np.any(a < 0) or np.any(b < 0):
        raise ValueError("per-scenario results must be finite and non-negative")
    if b.sum() <= 0.0:
        raise ValueError("the denominator's strategy did nothing in any scenario: no ratio")
    if not 0.0 < level < 1.0 or resamples < 1:
        raise ValueError(f"level must be in (0, 1) and resamples >= 1, got {level!r} and {resamples!r}")
    picks = rng.integers(0, a.size, size=(resamples, a.size))
    num, den = a[picks].sum(axis=1), b[picks].sum(axis=1)
    ratios = num[den > 0.0] / den[den > 0.0]          # a draw of only idle scenarios has no ratio
    tail = 100.0 * (1.0 - level) / 2.0
    low, high = np.percentile(ratios, [tail, 100.0 - tail]) if ratios.size else (np.nan, np.nan)
    diff = a - b
    return PairedRatio(float(a.sum() / b.sum()), float(low), float(high), level,
                       int(np.sum(diff > SAME)), int(np.sum(diff < -SAME)), int(np.sum(np.abs(diff) <= SAME)))
