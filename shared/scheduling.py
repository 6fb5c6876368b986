"""Scheduling of the cell's processes: the safety chain first.

On a small machine (two cores here, seven Python processes) the threads that carry a human sample to the
drives must not wait behind a plan or the witness. Where the operating system allows it they run in
SCHED_FIFO, highest first: the driver's SYNC cycle, the emulated drives, the scaler, tracker_ingest. The
planner and the safety monitor stay in the normal class and are niced (planner +10, monitor +5: in
deploy/supervisord.conf and in hrc demo's launcher).
"""

from __future__ import annotations

import os

# SCHED_FIFO priorities of the safety chain, highest first: the driver's SYNC cycle, the emulated drives,
# the scaler, tracker_ingest. The planner and the safety monitor stay in the normal class (and niced): a
# slow plan or a busy witness must never delay a command.
PRIORITY = {"robot_driver": 60, "hwsim": 55, "scaler": 50, "tracker_ingest": 45}


def realtime(name: str) -> str:
    """Put the calling thread (and the threads it starts later) in SCHED_FIFO at the priority of `name`;
    returns what was applied, for the start-up line. Where the OS refuses (no CAP_SYS_NICE, a container's
    limits) the thread stays in the normal class and the cell relies on niceness alone (planner +10,
    monitor +5 in supervisord and hrc demo): said, not hidden."""
    priority = PRIORITY.get(name)
    if priority is None:
        return "normal scheduling"
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        return f"SCHED_FIFO {priority}"
    except (AttributeError, OSError) as exc:
        return f"normal scheduling (SCHED_FIFO {priority} refused: {getattr(exc, 'strerror', None) or exc})"
