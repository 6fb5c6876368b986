"""The system's reaction latency, measured, and checked against the SSM's reaction time T_r (pure).

The ISO/TS 15066 formula assumes the robot reacts to a new human position within T_r. Here that reaction
is a chain: a sample is captured, enters tracker_ingest, the human state reaches the scaler, the scaler's next
tick computes a command from it, the driver puts the resulting target frame on the CAN bus (``LatencyMeter``:
every such chain, ``JointCommand.human_sample_stamp``, one clock, CLOCK_MONOTONIC, for all processes of the
host), and the joints then follow that setpoint some time behind it (``DriveLagMeter``: the lag of the
measured positions behind the driver's own setpoints). The part from the capture to the tick is the data's
age, which the scaling layer counts on the person's side (``shared.safety.ssm.aged_travel``: their travel over
it); T_r covers the rest, from the tick to the joints moving. When the p99 of that, tick -> frame, the frame's
wait for the SYNC that the drives take it at (a period at most) and SYNC -> motion, exceeds T_r, the configured
T_r is too small for this installation: a warning names the numbers, once per episode, and says so again when it
is back within. The drive lag is also checked on its own against the configured ``ssm.drive_lag`` that the
scaling layer's tracking margin is computed from.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LatencyCheck:
    """A change of verdict: event 'reaction_time_exceeded' / 'drive_lag_exceeded' (severity warning) or its
    '_ok' (info). value (s): the figure the text gives (the chain's or the worst joint's p99), as a driver
    event's (``shared.drives.driver_core.Event``): the robot driver publishes both the same way."""

    event: str
    severity: str
    text: str
    value: float


class Episode:
    """A verdict (a bound exceeded or not) that is reported only when it changes: once per episode."""

    def __init__(self) -> None:
        self.exceeded = False

    def verdict(self, exceeded: bool, value: float, warning: tuple[str, str],
                ok: tuple[str, str]) -> "LatencyCheck | None":
        """Take the current verdict; a LatencyCheck (warning: event and text, or ok: the same, info) when
        it differs from the last one, else None."""
        if exceeded == self.exceeded:
            return None
        self.exceeded = exceeded
        event, text = warning if exceeded else ok
        return LatencyCheck(event, "warning" if exceeded else "info", text, value)


def reaction_chain(tick_to_frame: float, sync_wait: float, motion_lag: float) -> float:
    """The part of the reaction T_r covers (s): from the tick that took a sample to its frame on CAN (its p99), the
    frame's wait for the SYNC the drives take it at, and the joints' lag behind that SYNC (the drive lag p99). The
    robot driver's ``reaction_time_exceeded`` and the report's ``reaction_time_covers_p99`` hold it against T_r."""
    return tick_to_frame + sync_wait + max(motion_lag, 0.0)


class LatencyMeter:
    """Rolling window of the chains' latencies in seconds (from the capture to the frame, its processing part,
    and from the tick that computed the command to the frame), and the T_r verdict."""

    def __init__(self, reaction_time: float, window: int = 2000, min_samples: int = 100,
                 sync_wait: float = 0.0) -> None:
        if not reaction_time > 0:
            raise ValueError(f"reaction_time must be positive, got {reaction_time}")
        if not sync_wait >= 0:
            raise ValueError(f"sync_wait must be >= 0, got {sync_wait}")
        self.reaction_time = reaction_time
        self.sync_wait = sync_wait            # s: a frame's wait for the SYNC that the drives take it at (a period)
        self.min_samples = min_samples
        self._window: deque[float] = deque(maxlen=window)
        self._pending: list[tuple[float, float, float]] = []
        self.episode = Episode()

    def add(self, sample_to_frame: float, processing: float, tick_to_frame: float) -> None:
        """One chain: from the sample's capture to its frame, the processing part of that, and from the scaler's
        tick that took the sample to the frame (s): the part of the reaction T_r covers (the rest is the data's
        age at the tick, counted on the person's side). Non-finite or negative latencies (a clock mix-up) are not
        data and are ignored."""
        if not all(np.isfinite(x) and x >= 0.0 for x in (sample_to_frame, tick_to_frame)) \
                or not np.isfinite(processing):
            return
        self._window.append(tick_to_frame)
        self._pending.append((sample_to_frame, processing, tick_to_frame))

    def drain(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The (sample_to_frame, processing, tick_to_frame) latencies added since the last drain, for a report."""
        pending, self._pending = self._pending, []
        arr = np.array(pending, dtype=float).reshape(-1, 3)
        return arr[:, 0], arr[:, 1], arr[:, 2]

    def p99(self) -> float | None:
        """p99 of tick_to_frame over the window, or None before min_samples chains."""
        if len(self._window) < self.min_samples:
            return None
        return float(np.percentile(np.fromiter(self._window, float), 99))

    def check(self, motion_lag: float = 0.0) -> LatencyCheck | None:
        """A LatencyCheck when the verdict (tick -> frame p99 + the wait for the SYNC + motion_lag > T_r, or not)
        changes, else None. motion_lag (s): how far the joints run behind the SYNC that took the frame (the drive
        lag p99)."""
        p99 = self.p99()
        if p99 is None:
            return None
        chain = reaction_chain(p99, self.sync_wait, motion_lag)
        parts = (f"tick -> frame p99 {p99 * 1e3:.1f} ms + the wait for the SYNC {self.sync_wait * 1e3:.0f} ms + "
                 f"drive lag {motion_lag * 1e3:.1f} ms")
        return self.episode.verdict(
            chain > self.reaction_time, chain,
            ("reaction_time_exceeded", f"measured reaction chain {chain * 1e3:.1f} ms ({parts}) exceeds the configured "
                                       f"T_r {self.reaction_time * 1e3:.0f} ms: the SSM distances assume a faster "
                                       f"system; raise ssm.reaction_time in the cell configuration"),
            ("reaction_time_ok", f"reaction chain {chain * 1e3:.1f} ms ({parts}) is within T_r "
                                 f"{self.reaction_time * 1e3:.0f} ms again"))


class DriveLagMeter:
    """How far the measured joints run behind the driver's own setpoints, per joint (pure).

    Fed once per SYNC with the setpoint that went out with the previous SYNC, its velocity, the positions
    the drives reported at that SYNC, and the drives' own following error (0x60F4). The lag in time of a
    joint moving at |velocity| >= min_speed is (setpoint - measured) / velocity: an interpolated position
    drive that reaches each setpoint at the next SYNC is exactly one period behind. Slower joints give no
    lag sample (the ratio is noise there) but their following error counts. ``report`` drains the window's
    figures; ``check`` compares the p99 with the configured bound, a verdict per change (as LatencyMeter).

    ``covering`` is the lag the scaling layer's tracking margin must cover now, at once rather than a report
    a second later: a drive that loses frames falls behind its setpoints (a lost SYNC), or overshoots them
    (a lost setpoint while braking makes the next one twice as far, which a linear interpolator runs at twice
    the speed), or its position is a period old (a lost answer, ``missed``); within a few SYNCs of the
    first lost frame. The worst joint's |lag| of every SYNC (ahead counts as behind: either way the measured
    speed is not the commanded one), held for `hold` SYNCs, since a link that loses one frame loses more.
    """

    def __init__(self, bound: float, dof: int = 6, min_speed: float = 0.2, window: int = 1000,
                 min_samples: int = 50, hold: int = 100) -> None:
        if not bound > 0:
            raise ValueError(f"drive lag bound must be positive, got {bound}")
        self.bound, self.min_speed, self.min_samples = bound, min_speed, min_samples
        self._recent: deque[float] = deque(maxlen=hold)      # the worst joint's |lag| (s) of each recent SYNC
        self._lags = [deque(maxlen=window) for _ in range(dof)]
        self._pending_lag = [[] for _ in range(dof)]
        self._pending_error = np.zeros(dof)
        self._pending_missed = 0
        self.episode = Episode()

    def add(self, setpoint: np.ndarray, velocity: np.ndarray, measured: np.ndarray,
            following_error: np.ndarray | None = None) -> None:
        """One SYNC's answer: rad, rad/s, rad, rad (non-finite values are not data and are skipped)."""
        setpoint, velocity, measured = (np.asarray(a, dtype=float) for a in (setpoint, velocity, measured))
        with np.errstate(divide="ignore", invalid="ignore"):
            lag = (setpoint - measured) / velocity
        moving = np.flatnonzero((np.abs(velocity) >= self.min_speed) & np.isfinite(lag))
        for j in moving:
            self._lags[j].append(float(lag[j]))
            self._pending_lag[j].append(float(lag[j]))
        self._recent.append(float(np.max(np.abs(lag[moving]))) if moving.size else 0.0)
        if following_error is not None:
            err = np.abs(np.asarray(following_error, dtype=float))
            self._pending_error = np.fmax(self._pending_error, np.where(np.isfinite(err), err, 0.0))

    def missed(self, period: float) -> None:
        """A SYNC that some drive did not answer: the position published for it is a period (s) older than
        the others' and than its setpoint, on top of the lag it had (at least the bound)."""
        self._recent.append(max(self._recent[-1] if self._recent else 0.0, self.bound) + period)
        self._pending_missed += 1

    def covering(self) -> float:
        """The lag (s) the tracking margin must cover now: the bound, or the worst joint's |lag| of any of
        the last `hold` SYNCs (a missed answer counted as ``missed`` says) where that is longer."""
        return max(self.bound, max(self._recent, default=0.0))

    def p99(self) -> np.ndarray:
        """Per joint p99 lag (s) over the window; NaN for a joint with fewer than min_samples."""
        return np.array([np.percentile(np.fromiter(w, float), 99) if len(w) >= self.min_samples else np.nan
                         for w in self._lags])

    def worst(self) -> float | None:
        """The largest per-joint p99 lag (s), or None before any joint has min_samples."""
        p99 = self.p99()
        return float(np.nanmax(p99)) if np.any(np.isfinite(p99)) else None

    def report(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """Since the last report: per joint lag p99 (s, 0 where not measured), how many lag samples, the
        largest |following error| the drives reported (rad), and how many SYNCs some drive did not answer
        within its period (``missed``)."""
        count = np.array([len(p) for p in self._pending_lag], dtype=float)
        lag = np.array([np.percentile(p, 99) if p else 0.0 for p in self._pending_lag])
        error = self._pending_error.copy()
        missed, self._pending_missed = self._pending_missed, 0
        self._pending_lag = [[] for _ in self._pending_lag]
        self._pending_error[:] = 0.0
        return lag, count, error, missed

    def check(self) -> LatencyCheck | None:
        """A LatencyCheck when the verdict (worst joint's p99 lag > bound, or not) changes, else None."""
        worst = self.worst()
        if worst is None:
            return None
        return self.episode.verdict(
            worst > self.bound, worst,
            ("drive_lag_exceeded", f"the joints run {worst * 1e3:.1f} ms (p99) behind their setpoints, more than the "
                                   f"configured ssm.drive_lag {self.bound * 1e3:.0f} ms that the scaling layer's "
                                   f"tracking margin assumes: raise it, or find why the drives fall behind"),
            ("drive_lag_ok", f"drive lag p99 {worst * 1e3:.1f} ms is within ssm.drive_lag {self.bound * 1e3:.0f} ms "
                             f"again"))


class DelayHistogram:
    """Delays (s) over a whole run in fixed bins, so a percentile costs the same after an hour as after a
    second (the monitor reports its lag p99 every second; a list of every lag grew with the run). Bins
    of `resolution` s up to `limit` s; a delay beyond the limit counts in the last bin, and the largest
    delay is kept exactly."""

    def __init__(self, resolution: float = 0.0005, limit: float = 10.0) -> None:
        if not (resolution > 0 and limit > resolution):
            raise ValueError(f"need 0 < resolution < limit, got {resolution} and {limit}")
        self.resolution = resolution
        self.counts = np.zeros(int(np.ceil(limit / resolution)) + 1, dtype=np.int64)
        self.largest = 0.0
        self.total = 0

    def add(self, delay: float) -> None:
        delay = max(0.0, float(delay))
        self.counts[min(int(delay / self.resolution), self.counts.size - 1)] += 1
        self.largest = max(self.largest, delay)
        self.total += 1

    def absorb(self, other: "DelayHistogram") -> None:
        """Add another histogram's delays to this one (the same bins: resolution and limit), as if each had been
        added here."""
        if other.resolution != self.resolution or other.counts.size != self.counts.size:
            raise ValueError("histograms with other bins cannot be merged")
        self.counts += other.counts
        self.total += other.total
        self.largest = max(self.largest, other.largest)

    def percentile(self, q: float) -> float:
        """The q-th percentile (0-100), to one bin (its upper edge; never above the largest delay); 0 when
        empty."""
        if self.total == 0:
            return 0.0
        rank = int(np.ceil(q / 100.0 * self.total))
        k = int(np.searchsorted(np.cumsum(self.counts), max(rank, 1)))
        if k >= self.counts.size - 1:                 # beyond the range: the largest is all there is to say
            return self.largest
        return min((k + 1) * self.resolution, self.largest)
