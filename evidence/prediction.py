"""The best one prediction of a time can do when the outcome is spread (pure, numpy only).

A leg's executed time depends on what the people do during it. Where that is drawn as they go (a wanderer's next
stop), one prediction made at the leg's start meets a spread of outcomes, and some error is left whatever the
forecast: this module says how much. Its input is a leg's executed times over other futures the people could have
had (``evidence.scenarios.other_futures``); its answers are the prediction that has the most of them within a
relative error (``best_within``) and the one of least expected relative error (``least_relative_error``), each to
be judged against the leg's own future, which it never saw (``bench/calibration.py --futures``).
"""

from __future__ import annotations

import numpy as np


def _times(samples) -> np.ndarray:
    x = np.asarray(samples, dtype=float).ravel()
    if x.size == 0 or not np.all(np.isfinite(x)) or np.any(x <= 0.0):
        raise ValueError("samples: one or more finite positive times (s)")
    return x


def best_within(samples, tolerance: float) -> tuple[float, float]:
    """(p, share): the prediction p (s) with the most samples x (s, > 0) within `tolerance` of it in relative
    error, |p / x - 1| <= tolerance, and that share of them. x is within it exactly when x (1 - tolerance) <= p <=
    x (1 + tolerance); the most such intervals meet at the left end of one of them, so those are the candidates
    (the smallest of the best). tolerance in [0, 1)."""
    x = _times(samples)
    if not 0.0 <= tolerance < 1.0:
        raise ValueError("tolerance: a relative error in [0, 1)")
    low, high = x * (1.0 - tolerance), x * (1.0 + tolerance)
    counts = ((low[None, :] <= low[:, None]) & (low[:, None] <= high[None, :])).sum(axis=1)
    candidates = np.flatnonzero(counts == counts.max())
    best = int(candidates[np.argmin(low[candidates])])
    return float(low[best]), float(counts[best] / x.size)


def least_relative_error(samples) -> float:
    """The prediction p (s) of least mean |p / x - 1| over the samples x (s, > 0): sum |p - x| / x is least at the
    median of x weighted by 1 / x (the lower weighted median where two values tie)."""
    x = np.sort(_times(samples))
    weights = 1.0 / x
    cumulative = np.cumsum(weights)
    return float(x[int(np.searchsorted(cumulative, 0.5 * cumulative[-1]))])
