"""Human tracking: raw capsule poses in, capsules with velocities and a validity flag out (pure).

Velocity filter: a least-squares line through the last `window` seconds of samples of each capsule end
point (a sliding-window linear regression). Why: it is unbiased for a constant velocity (an alpha-beta or
low-pass filter lags and so *under*-estimates an approaching hand, the unsafe direction), its noise
shrinks as the window grows (about 0.03 m/s for 1 mm marker noise at 240 Hz over 40 ms), and it needs no
tuning beyond the window. Robustness:
* a step faster than any human moves (max_speed) is a tracking glitch or a new person: the position is
  taken as it is (the person is where the tracker says now) but the velocity is marked unknown until
  the window has refilled, so the SSM uses the ISO 13855 approach speeds meanwhile (conservative); and
  until then the capsules of the sample before the step are reported too (velocity unknown): the person
  is where the tracker says now *or* where they just were, so a one-sample glitch away from the robot
  never lets it speed up towards where the person really is;
* a change in the number of capsules restarts the filter the same way;
* samples that arrive out of order (older than the last) are dropped;
* no sample for longer than dropout: the track is invalid (the scaler then stops the robot).
Times in seconds (the tracker's sample time for the fit, the arrival time for the dropout), m, m/s.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from shared.core.humans import HumanCapsules


@dataclass(frozen=True)
class TrackerParameters:
    window: float = 0.04
    min_samples: int = 4
    max_speed: float = 4.0
    dropout: float = 0.05


class HumanTracker:
    def __init__(self, params: TrackerParameters | None = None) -> None:
        self.params = params or TrackerParameters()
        self._samples: deque[tuple[float, np.ndarray]] = deque()
        self._radii = np.zeros(0)
        self._last_arrival = -np.inf
        self._trusted_from = np.inf          # sample time from which the window holds only clean samples
        self._ghost: tuple[np.ndarray, np.ndarray] | None = None   # (segments, radii) before the last step
        self.glitches = 0

    def update(self, segments: np.ndarray, radii: np.ndarray, sample_time: float, arrival: float) -> HumanCapsules | None:
        """Add one sample; the capsules with their velocities, or None when the sample was dropped."""
        seg = np.asarray(segments, dtype=float).reshape(-1, 2, 3)
        p = self.params
        if self._samples and sample_time <= self._samples[-1][0]:
            return None                                          # out of order or repeated
        if self._samples and seg.shape != self._samples[-1][1].shape:
            self._restart(sample_time)
        elif self._samples:
            t_last, last = self._samples[-1]
            step = np.linalg.norm(seg - last, axis=2).max() if seg.size else 0.0
            if step > p.max_speed * (sample_time - t_last) + 0.01:
                self.glitches += 1
                self._ghost = (last, self._radii)
                self._restart(sample_time)
        elif not self._samples:
            self._trusted_from = sample_time
        self._samples.append((sample_time, seg))
        self._radii = np.asarray(radii, dtype=float).reshape(-1)
        while self._samples and self._samples[0][0] < sample_time - p.window:
            self._samples.popleft()
        self._last_arrival = arrival
        return self._estimate(sample_time)

    def _restart(self, sample_time: float) -> None:
        self._samples.clear()
        self._trusted_from = sample_time

    def _estimate(self, sample_time: float) -> HumanCapsules:
        times = np.array([t for t, _ in self._samples])
        pts = np.stack([s for _, s in self._samples])                 # (K, M, 2, 3)
        m = pts.shape[1]
        enough = len(times) >= self.params.min_samples and times[0] >= self._trusted_from
        if not enough:
            seg, radii = pts[-1], self._radii
            if self._ghost is not None:
                seg, radii = np.concatenate([seg, self._ghost[0]]), np.concatenate([radii, self._ghost[1]])
            return HumanCapsules(seg, radii, np.zeros_like(seg), np.zeros(len(radii), dtype=bool))
        self._ghost = None
        dt = times - times.mean()
        slope = np.tensordot(dt, pts - pts.mean(axis=0), axes=(0, 0)) / float(dt @ dt)   # (M, 2, 3)
        # report the fitted position at the newest sample time (the fit's value, not the noisy sample)
        fitted = pts.mean(axis=0) + slope * (sample_time - times.mean())
        return HumanCapsules(fitted, self._radii, slope, np.ones(m, dtype=bool))

    def valid(self, now: float) -> bool:
        """False once no sample has arrived for longer than the dropout bound."""
        return now - self._last_arrival <= self.params.dropout

    @property
    def valid_until(self) -> float:
        """The arrival time after which the track is invalid unless a sample comes (-inf before any)."""
        return self._last_arrival + self.params.dropout
