"""Which SYNC each drive's answer belongs to: by when its frame reached the machine, not by when the driver got
round to reading it (pure: no bus, no clock of its own).

A SYNC's answer window runs from the moment it was sent to the moment the next one was. A drive answers a SYNC
within microseconds; a frame stamped in SYNC n's window (the interface's receive time: SocketCAN's and
python-can udp_multicast's kernel stamp, SO_TIMESTAMPNS, or the virtual bus's send time, all on the wall
clock) answers SYNC n, however late the driver's receive thread reads it. Frames are read in the order they
came, so a frame stamped in a later window closes every window before it: each is judged answered when every
drive's answer was stamped in it, else missed. A window still open JUDGE_AFTER periods after it closed is
judged by what was read by then (a receive thread that far behind is itself a lost answer: the positions it
would give are that old).

Why: the driver stops the drives when frames are being lost (``DriverCore``: 10 of the last 100 SYNCs not
answered). Counted by whether the answers had been read by the next SYNC, a driver whose receive thread is
starved for a few periods (a loaded machine, a cold start) read as a bus losing frames, and a late answer was
counted as the next SYNC's. Counted by the frames' own stamps, a lost frame is still a miss (it never comes),
a late-read one is not, and a late answer never completes a later SYNC's state.
"""

from __future__ import annotations

import math
from collections import deque

SYNCS_KEPT = 128          # the SYNCs whose send time is kept (1.28 s at 100 Hz): older stamps cannot be placed
JUDGE_AFTER = 10          # periods after a window closed by which it is judged, read or not


class AnswerWindows:
    """Answers per SYNC by their stamps. ``usable`` turns False for good at the first stamp that does not fit
    the SYNCs' clock (no stamp, another clock): the caller then falls back to counting by arrival."""

    def __init__(self, nodes: int, period: float) -> None:
        self.nodes, self.period = nodes, period
        self._sent: deque[tuple[int, float]] = deque(maxlen=SYNCS_KEPT)     # (SYNC number, wall time sent)
        self._answered: dict[int, set[int]] = {}       # SYNC number -> the nodes whose answer was stamped in it
        self._judged_to = 0                             # every SYNC up to this number is judged
        self._verdicts: list[bool] = []                 # judged since the last take(), in SYNC order
        self.usable = True

    def sync(self, number: int, wall: float) -> None:
        """SYNC `number` is about to go out (wall: time.time() just before it is sent). Windows that closed
        more than JUDGE_AFTER periods ago are judged by what was read."""
        if self._sent and number != self._sent[-1][0] + 1:      # a restarted count: nothing before it is judged
            self._sent.clear()
            self._answered.clear()
            self._judged_to = number - 1
        if not self._sent:
            self._judged_to = number - 1
        self._sent.append((number, wall))
        closed_by = wall - JUDGE_AFTER * self.period       # a window closes when the next SYNC is sent
        last = None
        for k in range(max(0, self._judged_to + 1 - self._sent[0][0]), len(self._sent) - 1):   # the unjudged ones
            n, closed = self._sent[k][0], self._sent[k + 1][1]
            if closed > closed_by:
                break
            last = n
        if last is not None:
            self._judge_to(last)

    def window(self, stamp: float | None) -> int | None:
        """The SYNC whose window holds `stamp` (the newest sent at or before it), or None where no kept SYNC's
        does (before the oldest kept; not a number; later than a second after the newest: another clock)."""
        if stamp is None or not math.isfinite(stamp) or not self._sent:
            return None
        if stamp < self._sent[0][1] or stamp > self._sent[-1][1] + 1.0:
            return None
        for number, wall in reversed(self._sent):
            if wall <= stamp:
                return number
        return None

    def answer(self, node: int, stamp: float | None) -> int | None:
        """A drive's answer, stamped `stamp`: the SYNC it answers, counted for it, every window before it
        judged; None where the stamp fits no window (``usable`` then turns False: the stamps cannot be
        trusted)."""
        number = self.window(stamp)
        if number is None:
            if self._sent and (stamp is None or not math.isfinite(stamp) or stamp > self._sent[-1][1] + 1.0
                               or stamp < self._sent[0][1] - 1.0):
                self.usable = False         # not the SYNCs' clock (a late frame from before the oldest is not that)
            return None
        if number > self._judged_to:
            self._answered.setdefault(number, set()).add(node)
        self._judge_to(number - 1)
        return number

    def _judge_to(self, last: int) -> None:
        while self._judged_to < last:
            self._judged_to += 1
            self._verdicts.append(len(self._answered.pop(self._judged_to, ())) == self.nodes)

    def take(self) -> list[bool]:
        """The SYNCs judged since the last call, in order: True where every drive's answer was stamped in
        its window."""
        out, self._verdicts = self._verdicts, []
        return out
