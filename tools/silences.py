"""The scaler's silences in a run of the cell (pure): where a SYNC of the drives passed without a new command, and
whose silence it was.

The scaler ticks once per SYNC, on the driver's joint state, or 1.5 periods without one (``services.common.
run_synced``); each tick publishes a command and a ``ScalerStatus`` stamped when the tick began. Two ticks more
than ``GAP_PERIODS`` control periods apart left a SYNC without a new command: the driver carries the last one a
period on, then brakes, and after its command timeout stops the robot (``stale_command``); a late command then
lies ahead of the braked setpoint (``command_clamped``). A stop with commands published meanwhile was a delay
between the two processes (``stale_stops``), not a silence. A silence is the scaler's own where the driver's
joint states kept coming meanwhile (the scaler had a state to tick on and did not: its last tick ran long, or its
process was held; its log says which), and the driver's too
where none came. The machine's part (a CPU stopped, the hypervisor's steal) is the stall witness's to say
(``tools.stalls``): a silence beside none of its stalls is a process of the cell not being run while a CPU was
free to the witness, which the chain's priorities (``shared.scheduling``) can do when one CPU is taken away and
the other runs the driver and the emulated drives.
"""

from __future__ import annotations

import numpy as np

from shared.scaling.sync_clock import GAP_PERIODS

LISTED = 10           # the longest silences listed


def scaler_silences(tick_stamps: np.ndarray, step_us: np.ndarray, state_stamps: np.ndarray, period: float,
                    t0: float) -> dict:
    """The scaler's silences: {"count", "longest": [[t (s from t0), ms without a tick, the scaling step's compute
    in the tick that began it (ms), the joint states the driver published meanwhile, the driver's own longest
    interval between states meanwhile (ms)], ...]} (the LISTED longest, longest first). tick_stamps: when each
    tick began (monotonic s, ScalerStatus.stamp, in order); step_us: each tick's step (ScalerStatus.compute_us);
    state_stamps: when the driver published each joint state (JointState.stamp)."""
    ticks = np.asarray(tick_stamps, dtype=float)
    step_us = np.asarray(step_us, dtype=float)
    if ticks.size != step_us.size:
        raise ValueError(f"{ticks.size} tick stamps but {step_us.size} step times")
    order = np.argsort(ticks, kind="stable")
    ticks, step_us = ticks[order], step_us[order]
    states = np.sort(np.asarray(state_stamps, dtype=float))
    gaps = np.diff(ticks)
    found = np.flatnonzero(gaps > GAP_PERIODS * period)
    rows = []
    for k in found:
        begin, end = ticks[k], ticks[k + 1]
        inside = states[(states > begin) & (states < end)]
        around = np.concatenate([[begin], inside, [end]])
        rows.append([round(float(begin - t0), 3), round(float(gaps[k]) * 1e3, 1), round(float(step_us[k]) / 1e3, 2),
                     int(inside.size), round(float(np.diff(around).max()) * 1e3, 1)])
    rows.sort(key=lambda row: -row[1])
    return {"count": len(rows), "longest": rows[:LISTED]}


def stale_stops(stops: list[tuple[float, float]], command_stamps: np.ndarray, t0: float) -> list[list]:
    """Each ``stale_command`` stop of the driver against the scaler's commands: [t (s from t0), ms without a
    command as the driver counted, the commands the scaler published meanwhile (stamped after the driver's last
    one came and at least a millisecond before the stop), the age at the stop of the first of them (ms)]. stops:
    (when the driver stopped, how long it had been without a command, s; its event's value), monotonic. None
    published: the scaler's silence (``scaler_silences``); some: they were on their way, or the driver did not
    take them (its own process held up), a delay between the two processes, not the scaler's."""
    stamps = np.sort(np.asarray(command_stamps, dtype=float))
    rows = []
    for t, without in stops:
        sent = stamps[(stamps > t - without) & (stamps < t - 1e-3)]
        rows.append([round(float(t - t0), 3), round(float(without) * 1e3, 1), int(sent.size),
                     round(float(t - sent[0]) * 1e3, 1) if sent.size else None])
    return rows


def said(silences: dict) -> str | None:
    """One line for the operator when the scaler fell silent (None when it did not)."""
    lines = []
    for t, without, sent, oldest in silences.get("stale_stops") or []:
        lines.append(f"the driver stopped at t={t:.2f} s without a command for {without:.0f} ms: " +
                     (f"the scaler had published {sent} meanwhile (the first {oldest:.0f} ms before), which had not "
                      "reached it" if sent else "the scaler had published none meanwhile"))
    if not silences.get("count"):
        return "; ".join(lines) or None
    t, gap, step, states, driver = silences["longest"][0]
    whose = (f"the driver published {states} joint state(s) meanwhile (at most {driver:.0f} ms apart) and the "
             f"scaler did not tick on them" if states else
             f"the driver published no joint state meanwhile either ({driver:.0f} ms)")
    return "; ".join([f"the scaler fell silent {silences['count']} time(s) for more than {GAP_PERIODS:g} control "
                      f"periods (the longest {gap:.0f} ms at t={t:.2f} s, after a {step:.1f} ms step: {whose})", *lines])
