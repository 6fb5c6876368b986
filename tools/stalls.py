"""The machine's own stalls, witnessed beside the cell (`python -m tools.stalls`): a process in SCHED_FIFO 99, above
every process of the cell, that sleeps to a deadline every few milliseconds and keeps how late it woke.

On a slow day the cell's timing has hiccups (the robot driver misses SYNC answers, the scaler sends two commands
20 ms apart, the person feed wakes 75 ms late), and a report has to say whose they were. Nothing on the machine
delays a FIFO 99 process that does almost nothing by more than the kernel's own work (a millisecond or so, here),
but the machine itself: when the hypervisor takes a virtual CPU away (its steal time, /proc/stat), or the kernel
throttles real-time work (which the cell's own real-time load can cause), every process on that CPU stops, the
drives' emulator included. A stall with as much steal is the hypervisor's, one without is the kernel's; a lag the
cell reports with no stall here is not shown to be the machine's, though a CPU taken away for a few milliseconds
can cost a drive answer (the SYNC answers missed follow the run's steal time: docs/measurements.md, session
60). ``bench/stall_probe.py`` runs the same witness at several priorities at once, to tell which of the cell's
processes held the others off.

One witness per CPU, each pinned to its own (``pinned``, a child process each; the parent merges their logs): a
hypervisor that takes one virtual CPU away stops only what runs there, and a single witness that happened to be
on the other CPU woke on time. On this VM the driver missed SYNC answers in runs where one unpinned witness saw
no stall of 20 ms, and those runs had about twice the steal time of the others (docs/measurements.md, session 59).

The protocol with the parent (``tools.demo``): the process sets its scheduling, starts its witnesses, prints READY
and runs until SIGTERM, then writes its figures (``StallLog.figures`` of every CPU's log together, monotonic times;
``per_cpu``: each CPU's stalls and latest wake-up) as JSON to --stats.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import queue
import signal
import sys
import time
from pathlib import Path

from shared.safety.latency import DelayHistogram

READY = "stall_witness: ready"
PRIORITY = 99                 # SCHED_FIFO: above the whole cell (shared.scheduling.PRIORITY tops at 60)
PERIOD = 0.005                # s between wake-ups: 200 a second, well under 1 % of a core
THRESHOLD = 0.01              # s late: a stall listed: one SYNC period, as long as a stall need be to cost a
# drive answer (a missed answer is what makes the driver clamp its next command; a 19 ms stall went unlisted
# before the command_clamped it came with, at 20 ms: docs/measurements.md, session 60)
KEPT = 100                    # the longest stalls kept
STEAL_EVERY = 0.1             # s: how often the steal time is read, so that a stall's own steal can be told
RESOLUTION, LIMIT = 1e-4, 1.0  # s: the lateness histogram's bins and range


def last_cpu() -> int:
    """The CPU this process last ran on (/proc/self/stat's 39th field; -1 where it cannot be read): the one it
    woke on after a stall."""
    try:
        text = Path("/proc/self/stat").read_text()
        return int(text[text.rindex(")") + 2:].split()[36])
    except (OSError, ValueError, IndexError):
        return -1


def steal_ticks() -> dict[str, int]:
    """Each CPU's steal time so far (USER_HZ ticks, the 8th field of /proc/stat's cpuN lines; empty where there
    are none): the time the hypervisor ran something else while this virtual CPU had work."""
    try:
        lines = Path("/proc/stat").read_text().splitlines()
    except OSError:
        return {}
    rows = (line.split() for line in lines)
    return {f[0]: int(f[8]) for f in rows if len(f) > 8 and f[0].startswith("cpu") and f[0] != "cpu"}


def steal_seconds(before: dict[str, int], after: dict[str, int]) -> dict[str, float]:
    """Each CPU's steal time between two ``steal_ticks`` readings (s)."""
    hz = os.sysconf("SC_CLK_TCK")
    return {cpu: round((ticks - before.get(cpu, 0)) / hz, 3) for cpu, ticks in after.items()}


class StallLog:
    """How late a witness woke (a bounded histogram, for hours of it) and its stalls later than `threshold` s: the
    `kept` longest as (due, ms late, the CPU it woke on, the steal time in ms the hypervisor took from the most
    robbed CPU since shortly before it, -1 unknown). A stall as long as its steal is the hypervisor's; one with
    little steal is the machine's own kernel (a real-time task throttled, an interrupt storm). Pure: the caller
    reads the CPU and the steal."""

    def __init__(self, threshold: float = THRESHOLD, kept: int = KEPT) -> None:
        self.threshold, self.kept = threshold, kept
        self.late = DelayHistogram(RESOLUTION, LIMIT)
        self.stalls = 0
        self.longest: list[tuple[float, float, int, float]] = []

    def add(self, due: float, woke: float, cpu: int = -1, steal_ms: float = -1.0) -> bool:
        """One wake-up due at `due` that came at `woke` (s, one clock); True when it was a stall."""
        self.late.add(woke - due)
        if woke - due <= self.threshold:
            return False
        self.stalls += 1
        self.longest.append((due, woke - due, cpu, steal_ms))
        if len(self.longest) > 2 * self.kept:
            self.longest = sorted(self.longest, key=lambda s: -s[1])[:self.kept]
        return True

    def absorb(self, other: "StallLog") -> None:
        """Take another witness's log into this one (the same resolution and range): every wake-up and stall of
        both, the longest kept."""
        self.late.absorb(other.late)
        self.stalls += other.stalls
        self.longest = sorted(self.longest + other.longest, key=lambda s: -s[1])[:2 * self.kept]

    def figures(self, t0: float = 0.0) -> dict:
        """wakeups, late_ms_p99, late_ms_max, stalls (how many beyond the threshold), longest ([s after t0, ms late,
        cpu, steal ms], in time order)."""
        kept = sorted(sorted(self.longest, key=lambda s: -s[1])[:self.kept])
        empty = self.late.total == 0
        return {"wakeups": self.late.total, "threshold_ms": round(1e3 * self.threshold, 1),
                "late_ms_p99": None if empty else round(1e3 * self.late.percentile(99), 2),
                "late_ms_max": None if empty else round(1e3 * self.late.largest, 2), "stalls": self.stalls,
                "longest": [[round(due - t0, 3), round(1e3 * late, 2), cpu, round(steal, 1)]
                            for due, late, cpu, steal in kept]}


def fifo(priority: int) -> str:
    """This process in SCHED_FIFO `priority` (0: left in the normal class); what it got, in words."""
    if priority <= 0:
        return "normal class"
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        return f"SCHED_FIFO {priority}"
    except OSError as exc:
        return f"normal class (SCHED_FIFO {priority} refused: {exc.strerror})"


def witness(log: StallLog, period: float, running, start: float | None = None, until: float | None = None) -> None:
    """Wake every `period` s on the grid from `start` (monotonic s; default now) while running() and before
    `until`, each wake-up into `log`, a stall with the CPU it woke on and the steal since the last reading (taken
    every STEAL_EVERY s); deadlines missed meanwhile are gone, not made up in a burst."""
    start = time.monotonic() if start is None else start
    k = 0
    steal, read_at = steal_ticks(), start
    while running():
        due = start + k * period
        if until is not None and due > until:
            return
        time.sleep(max(0.0, due - time.monotonic()))
        woke = time.monotonic()
        if woke - due > log.threshold:
            now = steal_ticks()
            robbed = max(steal_seconds(steal, now).values(), default=-1e-3)
            log.add(due, woke, last_cpu(), 1e3 * robbed)
            steal, read_at = now, woke
        else:
            log.add(due, woke)
            if woke - read_at >= STEAL_EVERY:
                steal, read_at = steal_ticks(), woke
        k = max(k + 1, int((woke - start) / period) + 1)


AFTER_STALL = 0.5     # s: a warning this soon after a stall's end is listed as following it


def in_run(figures: dict, t0: float, events) -> dict:
    """The witness's figures (``main``'s, monotonic times) for a run that began at t0 (monotonic s): its stalls'
    times counted from t0, and ``after_stall``: the cell's warnings and stops (``SafetyEvent``s of another
    severity than info, as "source:event") that came during one of them or within AFTER_STALL s of its end. An
    event listed there may still be the cell's own; one not listed was not the machine's stopping."""
    stalls = [(stall[0] - t0, *stall[1:]) for stall in figures.get("longest", [])]
    after = sorted({f"{e.source}:{e.event}" for e in events if e.severity != "info"
                    and any(st[0] <= e.stamp - t0 <= st[0] + st[1] / 1e3 + AFTER_STALL for st in stalls)})
    return {**figures, "started": round(figures.get("started", t0) - t0, 3),
            "longest": [[round(st[0], 3), *st[1:]] for st in stalls], "after_stall": after}


def said(figures: dict) -> str | None:
    """One line for the operator when the witness saw the machine stall (None when it did not, or wrote nothing):
    how many stalls, the longest with the steal meanwhile, and the cell's warnings that followed them."""
    if not figures.get("stalls"):
        return None
    worst = max(figures.get("longest") or [[0.0, figures.get("late_ms_max") or 0.0, -1, -1.0]], key=lambda st: st[1])
    steal = f", {worst[3]:.0f} ms of it the hypervisor's steal" if len(worst) > 3 and worst[3] >= 0 else ""
    after = figures.get("after_stall") or []
    threshold = figures.get("threshold_ms", 1e3 * THRESHOLD)
    return (f"the machine itself stalled {figures['stalls']} time(s) beyond {threshold:.0f} ms "
            f"(the longest {worst[1]:.0f} ms at t={worst[0]:.2f} s{steal}); "
            + (f"during or just after them: {', '.join(after)}" if after else "no warning of the cell came with them"))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.stalls", description=__doc__.split("\n\n")[0])
    parser.add_argument("--stats", type=Path, required=True, help="where the figures go at the end (JSON)")
    parser.add_argument("--priority", type=int, default=PRIORITY, help="SCHED_FIFO priority (0: the normal class)")
    parser.add_argument("--period", type=float, default=PERIOD, help="s between wake-ups")
    parser.add_argument("--threshold", type=float, default=THRESHOLD, help="s late: a stall")
    args = parser.parse_args(argv)
    if not (0 <= args.priority <= 99 and args.period > 0 and args.threshold > 0):
        print("stall_witness: error: --priority in 0..99, --period and --threshold positive", file=sys.stderr)
        return 2
    running = [True]
    signal.signal(signal.SIGTERM, lambda *_: running.__setitem__(0, False))
    scheduling = fifo(args.priority)
    cpus = sorted(os.sched_getaffinity(0))
    context = multiprocessing.get_context("fork")
    stop, logs = context.Event(), context.Queue()
    children = [context.Process(target=pinned, args=(cpu, args.threshold, args.period, stop, logs), daemon=True)
                for cpu in cpus]
    steal0, started = steal_ticks(), time.monotonic()
    for child in children:
        child.start()
    print(f"{READY}: {scheduling}, every {1e3 * args.period:.0f} ms, one witness on each of CPUs "
          f"{','.join(map(str, cpus))}", flush=True)
    while running[0] and all(child.is_alive() for child in children):
        time.sleep(0.05)
    stop.set()
    log, per_cpu = StallLog(args.threshold), {}
    for _ in children:
        try:
            cpu, own = logs.get(timeout=5.0)
        except queue.Empty:               # a witness died without its log: said in the figures
            break
        log.absorb(own)
        per_cpu[str(cpu)] = {"stalls": own.stalls, "late_ms_max": round(1e3 * own.late.largest, 2)}
    for child in children:
        child.join(timeout=5.0)
    figures = {"scheduling": scheduling, "period_ms": round(1e3 * args.period, 2), "started": round(started, 3),
               **log.figures(), "per_cpu": per_cpu, "steal_s": steal_seconds(steal0, steal_ticks())}
    if len(per_cpu) < len(children):       # a witness that died: its CPU's stalls are not in the figures
        figures["unwitnessed_cpus"] = [cpu for cpu in map(str, cpus) if cpu not in per_cpu]
    args.stats.write_text(json.dumps(figures))
    return 0


def pinned(cpu: int, threshold: float, period: float, stop, logs) -> None:
    """One witness on CPU `cpu` alone (in the parent's scheduling, inherited) until `stop` is set, or its parent is
    gone (killed: a witness in SCHED_FIFO 99 must not outlive it); puts (cpu, its StallLog) on `logs`. SIGTERM is
    left to the parent: the witnesses end together when it sets `stop`."""
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    parent = os.getppid()
    os.sched_setaffinity(0, {cpu})
    log = StallLog(threshold)
    witness(log, period, lambda: not stop.is_set() and os.getppid() == parent)
    if os.getppid() == parent:          # nobody would read it: the put would block this process's exit for good
        logs.put((cpu, log))


if __name__ == "__main__":
    sys.exit(main())

