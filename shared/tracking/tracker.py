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
Times in seconds (the tracker's sample time for the fit, the arrival time for the dropout; the capture time,
``capture_stamp``, for the data's age), m, m/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from shared.core.humans import HumanCapsules

STALE_INTERVALS = 2.5      # a source's data is stale after this many of its own sample intervals (at the least):
                           # one lost frame (a gap of two intervals, and some jitter) is not a lost person
STALE_CEILING = 0.1        # s: ... but never later than this by the source's rate alone
RATE_SAMPLES = 16          # intervals the measured sample interval is the median of
OLDEST_SAMPLE = 0.5        # s: a sample captured longer ago than this is stale, never the person of now


def stale_bound(configured: float, interval: float) -> float:
    """The age (s) past which human data counts as stale: the configured bound (50 ms: motion capture at
    120-240 Hz), or STALE_INTERVALS of the source's own measured sample interval where that is longer (a
    20-60 Hz camera tracker: a 30 Hz skeleton is 33 ms old just before the next one comes, and one frame
    late under load must not read as a lost person), at most STALE_CEILING: a slower source (or one that
    falls silent between samples) is stopped for as stale unless the cell configures a larger bound itself (the
    layers count the person's travel over the whole age, ``shared.safety.ssm.aged_travel``, so a larger bound
    costs speed, not safety). The tracker's dropout and the scaler's stale-data stop both use it."""
    return max(configured, min(STALE_INTERVALS * interval, STALE_CEILING))


def capture_stamp(sample_time: float, arrival: float, oldest: float = OLDEST_SAMPLE) -> float | None:
    """When a sample was captured, on the cell's clock (s): its sample_time (a source's capture time on the cell's
    CLOCK_MONOTONIC, as the ROS 2 bridge gives it from a camera frame's header and the tools' feeds from their
    schedule), so that the data's age counts the source's own latency: ISO/TS 15066's T_r runs from the detection
    of the person, and a camera pipeline's 50-150 ms from capture to skeleton is part of it. The arrival where the
    stamp is ahead of it (a clock that is not the cell's, or none: the arrival stands for the capture); None for a
    sample captured more than `oldest` s before it arrived (stale: it is dropped, never taken for the person of
    now). NaN counts as stale."""
    if sample_time > arrival:
        return arrival
    return sample_time if arrival - sample_time <= oldest else None


def mean_age(latency: float, interval: float) -> float:
    """The people's data's age (s) as the scaling layer counts it on average: the samples' way from capture to
    the cell (`latency`, s) and half the source's sample interval (`interval`, s; 0 for a person captured at every
    moment), since the age grows from the latency to the latency and an interval before the next sample. The
    planning layer counts it (``Replanner.take_delay``) to predict the scaler's speed on a path."""
    return max(0.0, latency) + 0.5 * max(0.0, interval)


SOURCE_RATES = (1.0, 1000.0)   # Hz: the rates a source may be declared at (tracker_ingest --source-rate, hrc up)


def declarable(rate: float) -> bool:
    """Whether `rate` (Hz) is a source rate that can be declared: within SOURCE_RATES (NaN is not)."""
    return SOURCE_RATES[0] <= rate <= SOURCE_RATES[1]


@dataclass(frozen=True)
class TrackerParameters:
    """window (s): the velocity fit's span, at the least; min_samples: the fit needs this many clean samples;
    at a source's rate the window stretches to hold them (``HumanTracker.window``). max_speed (m/s): a step
    faster than this between two samples is a glitch. dropout (s): no sample for this long (at the least:
    ``stale_bound``) and the track is invalid. source_interval (s): the source's nominal sample interval where it
    is declared (a camera's 1 / frame rate; 0: not declared), taken as the measured one until the first interval
    is measured: a 15 Hz camera's second frame comes 67 ms after its first, past the 50 ms a source of unknown
    rate gets, and its track would be declared lost at the start of every run with the person in view."""

    window: float = 0.04
    min_samples: int = 4
    max_speed: float = 4.0
    dropout: float = 0.05
    source_interval: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.source_interval) and self.source_interval >= 0.0):
            raise ValueError(f"source_interval must be a finite number of seconds >= 0, not {self.source_interval!r}")


@numba.njit(cache=True)
def _largest_step(seg, last):
    """The largest end-point displacement (m) between two (M, 2, 3) samples."""
    step = 0.0
    for i in range(seg.shape[0]):
        for e in range(2):
            d = 0.0
            for c in range(3):
                d += (seg[i, e, c] - last[i, e, c]) ** 2
            step = max(step, np.sqrt(d))
    return step


@numba.njit(cache=True)
def _line_fit(times, pts, sample_time):
    """Least-squares line through K samples (times (K,), points (K, M, 2, 3)) of every end-point coordinate:
    (its value at sample_time, its slope), each (M, 2, 3)."""
    k = times.shape[0]
    t_mean = 0.0
    for n in range(k):
        t_mean += times[n]
    t_mean /= k
    var = 0.0
    for n in range(k):
        var += (times[n] - t_mean) ** 2
    fitted, slope = np.empty(pts.shape[1:]), np.empty(pts.shape[1:])
    for i in range(pts.shape[1]):
        for e in range(2):
            for c in range(3):
                mean = 0.0
                for n in range(k):
                    mean += pts[n, i, e, c]
                mean /= k
                cov = 0.0
                for n in range(k):
                    cov += (times[n] - t_mean) * (pts[n, i, e, c] - mean)
                slope[i, e, c] = cov / var
                fitted[i, e, c] = mean + slope[i, e, c] * (sample_time - t_mean)
    return fitted, slope


class HumanTracker:
    """The filter of one tracked scene. The window's samples are kept in two arrays (times, points) used
    from ``_first`` to ``_end``: a sample is written at the end, old ones are left behind by moving
    ``_first``, and the window is moved to the front (doubling the arrays when it fills more than half)
    when the end is reached: a sample allocates nothing but at those moves, and the fit reads one
    contiguous slice."""

    def __init__(self, params: TrackerParameters | None = None) -> None:
        self.params = params or TrackerParameters()
        self._times = np.zeros(32)
        self._points = np.zeros((32, 0, 2, 3))
        self._first = self._end = 0
        self._radii = np.zeros(0)
        self._last_arrival = -np.inf
        self._last_time = -np.inf            # the sample time of the last sample taken
        self._trusted_from = np.inf          # sample time from which the window holds only clean samples
        self._ghost: tuple[np.ndarray, np.ndarray] | None = None   # (segments, radii) before the last step
        self._intervals = np.zeros(RATE_SAMPLES)                    # the last sample intervals (s), a ring
        self._interval_count = 0
        # s: the median of the last RATE_SAMPLES sample intervals (before the first: the declared one, 0 if none)
        self.interval = self.params.source_interval
        self.glitches = 0

    @staticmethod
    def warm_up() -> None:
        """Run the compiled kernels once on a scratch tracker, so that a service's first samples are not the
        ones that wait for them to compile (or load from numba's cache)."""
        scratch = HumanTracker()
        for k in range(4):
            scratch.update(np.full((1, 2, 3), 0.001 * k), np.array([0.05]), 0.01 * k, 0.01 * k)

    @property
    def samples(self) -> int:
        """How many samples the velocity window holds now."""
        return self._end - self._first

    def update(self, segments: np.ndarray, radii: np.ndarray, sample_time: float, arrival: float) -> HumanCapsules | None:
        """Add one sample; the capsules with their velocities, or None when the sample was dropped."""
        seg = np.ascontiguousarray(segments, dtype=np.float64).reshape(-1, 2, 3)
        p = self.params
        held = self._end > self._first
        if held and sample_time <= self._times[self._end - 1]:
            return None                                          # out of order or repeated
        if np.isfinite(self._last_time):
            self._measure_interval(sample_time - self._last_time)
        self._last_time = sample_time
        if seg.shape[0] != self._points.shape[1]:
            self._restart(sample_time, seg.shape[0])
        elif held:
            last = self._points[self._end - 1]
            step = _largest_step(seg, last) if seg.shape[0] else 0.0
            if step > p.max_speed * (sample_time - self._times[self._end - 1]) + 0.01:
                self.glitches += 1
                self._ghost = (last.copy(), self._radii)
                self._restart(sample_time, seg.shape[0])
        else:
            self._trusted_from = sample_time
        self._append(sample_time, seg)
        self._radii = np.asarray(radii, dtype=float).reshape(-1)
        times, window = self._times, self.window
        while times[self._first] < sample_time - window:
            self._first += 1
        self._last_arrival = arrival
        return self._estimate(sample_time)

    def _measure_interval(self, dt: float) -> None:
        self._intervals[self._interval_count % RATE_SAMPLES] = dt
        self._interval_count += 1
        self.interval = float(np.median(self._intervals[:min(self._interval_count, RATE_SAMPLES)]))

    @property
    def window(self) -> float:
        """The velocity fit's span (s): the configured window, stretched where the source's rate is too low
        for it to hold min_samples samples (a 30 Hz skeleton: 3.5 intervals, 117 ms, where 40 ms would never
        hold four and the velocity would stay unknown for good)."""
        return max(self.params.window, (self.params.min_samples - 0.5) * self.interval)

    @property
    def dropout(self) -> float:
        """No sample for this long (s) and the track is invalid: ``stale_bound`` of the configured dropout and
        the measured interval."""
        return stale_bound(self.params.dropout, self.interval)

    def _append(self, sample_time: float, seg: np.ndarray) -> None:
        if self._end == self._times.shape[0]:                    # move the window to the front
            held = self._end - self._first
            size = self._times.shape[0] * (2 if 2 * held > self._times.shape[0] else 1)
            times, points = np.zeros(size), np.zeros((size, *self._points.shape[1:]))
            times[:held], points[:held] = self._times[self._first:self._end], self._points[self._first:self._end]
            self._times, self._points, self._first, self._end = times, points, 0, held
        self._times[self._end] = sample_time
        self._points[self._end] = seg
        self._end += 1

    def _restart(self, sample_time: float, capsules: int) -> None:
        if capsules != self._points.shape[1]:
            self._points = np.zeros((self._times.shape[0], capsules, 2, 3))
        self._first = self._end = 0
        self._trusted_from = sample_time

    def _estimate(self, sample_time: float) -> HumanCapsules:
        times, pts = self._times[self._first:self._end], self._points[self._first:self._end]
        enough = times.shape[0] >= self.params.min_samples and times[0] >= self._trusted_from
        if not enough:
            seg, radii = pts[-1].copy(), self._radii
            if self._ghost is not None:
                seg, radii = np.concatenate([seg, self._ghost[0]]), np.concatenate([radii, self._ghost[1]])
            return HumanCapsules(seg, radii, np.zeros_like(seg), np.zeros(len(radii), dtype=bool))
        self._ghost = None
        # report the fitted position at the newest sample time (the fit's value, not the noisy sample)
        fitted, slope = _line_fit(times, pts, float(sample_time))
        return HumanCapsules(fitted, self._radii, slope, np.ones(pts.shape[1], dtype=bool))

    def valid(self, now: float) -> bool:
        """False once no sample has arrived for longer than the dropout bound."""
        return now - self._last_arrival <= self.dropout

    @property
    def valid_until(self) -> float:
        """The arrival time after which the track is invalid unless a sample comes (-inf before any)."""
        return self._last_arrival + self.dropout
