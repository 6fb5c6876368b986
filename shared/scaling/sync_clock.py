"""Which joint states step the scaling layer's path: one tick per SYNC of the drives (pure).

The scaler's path advances one control period per tick, so it must tick exactly once per SYNC period, or
its commands run ahead of the drives (at the velocity limit a drive never makes that up). It ticks on each
joint state, and after 1.5 periods without one (``services.common.run_synced``: the loop goes on when the
driver is silent). A joint state carries the number of the SYNC whose period it ends (``JointState.sync``).
The clock remembers the SYNC the path last stepped for: a tick on a state steps for that state's SYNC, a
tick without a new state (the fallback) stands in for the next SYNC; a state for a SYNC already stepped
for (a late one, published after the fallback, or a second answer to the same SYNC) wakes no tick. A
state without a number (a source that does not count SYNCs) always does, and a number far below the last
one is a restarted driver, whose count starts again.
"""

from __future__ import annotations

RESTART_GAP = 50          # SYNCs: a state this far behind the clock comes from a driver that restarted
# control periods between two ticks: more, and at least one SYNC passed without a new command (a silence of the
# scaler: the scaler's log and the report's scaler_silences, tools.silences, name each)
GAP_PERIODS = 2.5


class SyncClock:
    def __init__(self) -> None:
        self.stepped: int | None = None         # the SYNC the path last stepped for
        self.newest: int | None = None          # the newest SYNC a joint state said it ended

    def arrived(self, sync: int | None) -> bool:
        """A joint state for SYNC `sync` (None: not counted) came; whether it should wake a tick."""
        if sync is None:
            return True
        if self.stepped is not None and sync < self.stepped - RESTART_GAP:      # a new driver counts anew
            self.stepped = self.newest = None
        if self.newest is None or sync > self.newest:
            self.newest = sync
        return self.stepped is None or sync > self.stepped

    def ticked(self) -> None:
        """The path steps now: for the newest SYNC a state announced, or (none newer) for the next one."""
        if self.newest is None:
            return
        if self.stepped is None or self.newest > self.stepped:
            self.stepped = self.newest
        else:
            self.stepped += 1
