"""The report of a multi-process run (`hrc demo`): what the cell published, turned into a trace, the
paper's figures and a summary. The format of every file is in docs/report-format.md.

The analysis (``analyse``) is pure: recorded messages in, numbers out. ``write_report`` writes the files.
Times are the senders' CLOCK_MONOTONIC stamps (one clock for the host), given relative to the run's start.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from shared.config import CellConfig
from shared.robot.model import RobotModel
from shared.safety.latency import reaction_chain
from shared.safety.monitor import HumanHistory, ReactionWindow, SafetyMonitor
from shared.wire.convert import humans_from_msg
from shared.wire.messages import (
    DriveLagReport,
    HumanState,
    JointCommand,
    JointState,
    LatencyReport,
    MonitorReport,
    SafetyEvent,
    ScalerStatus,
    TrajectoryMsg,
)
from tools.judge import Recount, recount
from tools.silences import scaler_silences, stale_stops
from tools.view import write_recording

MOVING_ALPHA = 0.01          # a stall ends once the robot moves on at more than this fraction of its speed


@dataclass
class Recording:
    """Every message of the cell, as received (each carries its sender's stamp)."""

    t0: float
    statuses: list[ScalerStatus] = field(default_factory=list)
    commands: list[JointCommand] = field(default_factory=list)
    joint_states: list[JointState] = field(default_factory=list)
    human_states: list[HumanState] = field(default_factory=list)
    trajectories: list[TrajectoryMsg] = field(default_factory=list)
    events: list[SafetyEvent] = field(default_factory=list)
    latency: list[LatencyReport] = field(default_factory=list)
    drive_lag: list[DriveLagReport] = field(default_factory=list)
    monitor: list[MonitorReport] = field(default_factory=list)
    shuttles: int = 0
    progress: float = 0.0        # shuttles plus the fraction of the current leg covered (the operator's, tools.actors)
    directed_s: float | None = None   # how long the shuttle was directed (hrc demo's --duration): what it counted over
    phase: Callable[[float], str] | None = None


def _percentiles(values: np.ndarray, *qs: float, scale: float = 1e3) -> dict:
    if values.size == 0:
        return {f"p{q:g}": None for q in qs}
    return {f"p{q:g}": round(float(np.percentile(values, q)) * scale, 3) for q in qs}


def replan_stalls(statuses: list[ScalerStatus], t0: float = 0.0) -> list[dict]:
    """For every replan request (beta rising): how long the robot stood or stayed on the old trajectory
    before it moved on (ms): until a newer trajectory version runs at alpha > MOVING_ALPHA, or until the
    request clears and the robot moves on the old one ('cleared'), or the run ends ('end of run')."""
    stalls = []
    k, n = 0, len(statuses)
    while k < n:
        if not statuses[k].beta or (k > 0 and statuses[k - 1].beta):
            k += 1
            continue
        start, version = statuses[k], statuses[k].trajectory_version
        end, how = None, "end of run"
        for later in statuses[k + 1:]:
            if later.trajectory_version > version and later.alpha > MOVING_ALPHA:
                end, how = later, "new trajectory"
                break
            if not later.beta and later.alpha > MOVING_ALPHA:
                end, how = later, "cleared"
                break
        last = end if end is not None else statuses[-1]
        stalls.append({"t": round(start.stamp - t0, 3), "stall_ms": round((last.stamp - start.stamp) * 1e3, 1),
                       "ended_by": how})
        k += 1
    return stalls


def goal_changeovers(statuses: list[ScalerStatus]) -> np.ndarray:
    """For every trajectory the scaler finished (its first 'finished' status): how long (s) until a newer trajectory
    version runs at alpha > MOVING_ALPHA; the robot stands at its goal meanwhile, while the operator sees the arrival,
    sends the next goal, the planner plans it and the scaler takes it. A finish the run ends on is not counted."""
    gaps = []
    k, n = 0, len(statuses)
    while k < n:
        if statuses[k].status != "finished":
            k += 1
            continue
        start, version = statuses[k], statuses[k].trajectory_version
        k += 1
        while k < n and not (statuses[k].trajectory_version > version and statuses[k].alpha > MOVING_ALPHA):
            k += 1
        if k < n:
            gaps.append(statuses[k].stamp - start.stamp)
    return np.array(gaps)


def mark_blocked_goals(stalls: list[dict], events: list[SafetyEvent], t0: float = 0.0) -> None:
    """Flag each stall in which the planner refused a replan because the goal itself was out of reach
    while the people stayed (shared.planning.blocked): a wait that no path could have shortened."""
    refusals = [e.stamp - t0 for e in events if e.source == "planner" and e.event == "replan_refused"
                and "the goal is blocked" in e.text]
    for stall in stalls:
        end = stall["t"] + stall["stall_ms"] / 1e3
        stall["goal_blocked"] = any(stall["t"] - 1e-6 <= t <= end + 1e-6 for t in refusals)


def monitor_series(robot: RobotModel, config: CellConfig, rec: Recording) -> dict[str, np.ndarray]:
    """At every measured joint state, with the human states of its moment (shared.safety.monitor.HumanHistory.
    pair_since, the monitor service's own pairing; a state measured before any human sample is not checked, as the
    service leaves it unchecked): separation, and the robot's approach speed against its ISO/TS 15066
    limit at the pair closest to its limit (the independent monitor's check, recomputed for the figures),
    and ``late_excess``: by how much (m/s) the measured approach speed exceeded the limit at a pair whose
    exceedance had lasted longer than T_r (0 where none had): the formula gives the robot T_r to react to
    a limit that falls below its speed, and nothing after that without braking; and ``violations``: the
    monitor's own rule (ReactionWindow) recounted over the trace, to hold the service's count against."""
    monitor = SafetyMonitor(robot, config.ssm)
    window = ReactionWindow(config.ssm.reaction_time, config.ssm.stopping_time)
    history = HumanHistory(span=np.inf)
    for msg in rec.human_states:
        history.add(msg.sample_stamp, humans_from_msg(msg))
    states = rec.joint_states
    before = [-np.inf] + [js.stamp for js in states[:-1]]
    results = monitor.check_batch(np.array([js.q for js in states]).reshape(-1, 6),
                                  np.array([js.qd for js in states]).reshape(-1, 6),
                                  [paired[1] if (paired := history.pair_since(js.stamp, after)) else None
                                   for js, after in zip(states, before)])
    rows, since = [], {}
    for js, r in zip(states, results):
        speeding = {(v.link, v.capsule): v.approach_speed - max(v.limit, 0.0) for v in r.violations
                    if v.kind == "speed"}
        since = {pair: since.get(pair, js.stamp) for pair in speeding}
        late = max((excess for pair, excess in speeding.items()
                    if js.stamp - since[pair] > config.ssm.reaction_time), default=0.0)
        counted = len(window.update(js.stamp, r))
        rows.append((js.stamp - rec.t0, r.min_separation, r.approach_speed, r.limit, r.min_margin, late, counted))
    arr = np.array(rows, dtype=float).reshape(-1, 7)
    return {"t": arr[:, 0], "separation": arr[:, 1], "approach": arr[:, 2], "limit": arr[:, 3], "margin": arr[:, 4],
            "late_excess": arr[:, 5], "violations": arr[:, 6]}


def monitor_summary(rec: Recording, series: dict[str, np.ndarray], violations: int | None,
                    judged: Recount) -> dict:
    """The monitor as it reported itself (checks, unchecked, how far behind), its count held against the
    recount over the trace with its own code (``violations_recounted``) and against the independent judge
    (tools.judge: another pairing, coal's geometry, its own reading of the reaction window), and a flag
    when any two disagree."""
    last = rec.monitor[-1] if rec.monitor else None
    recount = int(series["violations"].sum())
    return {"checks": None if last is None else last.checks, "unchecked": None if last is None else last.unchecked,
            "lag_ms": {"p99": None if last is None else round(last.lag_p99 * 1e3, 1),
                       "max": None if last is None else round(last.lag_max * 1e3, 1)},
            "violations_recounted": recount,
            "independent": {"violations": judged.violations, "exceedances": judged.exceedances,
                            "unchecked": judged.unchecked, "states": judged.states, "speedups": judged.speedups,
                            "speedups_unknown": judged.speedups_unknown,
                            "speedups_unknown_commanded": judged.speedups_unknown_commanded,
                            "speedup_at_s": [round(t - rec.t0, 3) for t in judged.speedup_stamps]},
            "disagrees": None if violations is None else len({violations, recount, judged.violations}) > 1}


def tracker_summary(rec: Recording) -> dict:
    """The people as tracker_ingest gave them: the source's measured sample interval (median, ms), the share
    of valid states with some velocity unknown and the longest such run (ms), the dropouts declared; each valid
    state's way from its sample's capture to its publication (ms, p50 and p99: a camera's latency and the
    tracker's hop, which the data's age counts), and the share of control cycles the scaler found the people's
    data stale (its age from the capture past the stale bound)."""
    valid = [m for m in rec.human_states if m.valid]
    capture = np.array([m.stamp - m.sample_stamp for m in valid])
    stale = np.array([s.status == "stale_human_data" for s in rec.statuses], dtype=bool)
    intervals = np.array([m.sample_interval for m in valid if m.sample_interval > 0])
    unknown = np.array([not np.all(m.velocity_known) for m in valid], dtype=bool)
    stamps = np.array([m.sample_stamp for m in valid])
    longest, start = 0.0, None
    for k, flag in enumerate(unknown):
        if flag and start is None:
            start = stamps[k]
        if not flag and start is not None:
            longest, start = max(longest, stamps[k] - start), None
    if start is not None:                                  # a run still open when the recording ends
        longest = max(longest, stamps[-1] - start)
    return {"states": len(valid),
            "sample_interval_ms": round(float(np.median(intervals)) * 1e3, 2) if intervals.size else None,
            "velocity_unknown_share": round(float(unknown.mean()), 4) if unknown.size else None,
            "velocity_unknown_longest_ms": round(longest * 1e3, 1),
            "dropouts": sum(1 for e in rec.events if e.source == "tracker_ingest" and e.event == "tracker_dropout"),
            "capture_to_state_ms": _percentiles(capture, 50, 99),
            "stale_share": round(float(stale.mean()), 4) if stale.size else None}


STALE_SAID = 0.01     # the share of control cycles with stale people data from which `hrc demo` says so


def stale_said(tracker: dict) -> str | None:
    """One line for the operator when the people's data was stale in STALE_SAID of the control cycles or more
    (None otherwise): a source's latency counts in the data's age, and the bounds that cover it are named."""
    share = tracker.get("stale_share")
    if share is None or share < STALE_SAID:
        return None
    latency = (tracker.get("capture_to_state_ms") or {}).get("p99")
    way = f" (from a sample's capture to the tracker's state: p99 {latency:.0f} ms)" if latency is not None else ""
    return (f"the people's data was stale in {100 * share:.0f} % of the control cycles{way}: its age counts from the "
            "capture, so a camera's latency counts; raise scaling.human_timeout to cover it (the layers count the "
            "person's travel over the age: docs/human-motion.md)")


def reaction_said(summary: dict) -> str | None:
    """One line for the operator when the measured reaction chain does not fit in T_r (the summary's
    ``reaction_time_covers_p99`` false; None otherwise): from the scaler's tick that took a sample to its frame on
    CAN (p99), the frame's wait for the SYNC and the joints' lag behind that, against ssm.reaction_time (the robot
    driver's ``reaction_time_exceeded`` by the same sum; the way from the capture to the tick is the data's age,
    counted on the person's side)."""
    if summary.get("reaction_time_covers_p99") is not False:
        return None
    chain = ((summary.get("latency") or {}).get("tick_to_frame_ms") or {}).get("p99") or 0.0
    lag = max((summary.get("drives") or {}).get("lag_p99_ms") or [0.0])
    sync = (summary.get("latency") or {}).get("sync_wait_ms") or 0.0
    return (f"the reaction chain, from the scaler's tick to its frame on CAN (p99 {chain:.0f} ms), the frame's wait "
            f"for the SYNC ({sync:.0f} ms) and the joints' {lag:.0f} ms behind that, is longer than T_r "
            f"({1e3 * summary['reaction_time_s']:.0f} ms): the SSM's distances assume a faster reaction; raise "
            "ssm.reaction_time to cover it")


def drive_summary(rec: Recording) -> dict:
    """The drives as the robot driver reported them: the worst per-joint lag p99 (ms) over the reports, the
    largest following error (rad), the SYNCs some drive did not answer in time (all, and the most in one
    report, about a second), and the drive faults announced (EMCY events)."""
    reports = rec.drive_lag
    lag = np.max([r.lag for r in reports], axis=0) if reports else None
    faults = [e.text for e in rec.events if e.source == "robot_driver" and e.event in ("emcy", "drive_fault")]
    return {"reports": len(reports), "lag_p99_ms": None if lag is None else [round(float(x) * 1e3, 2) for x in lag],
            "following_error_max_rad": None if not reports else round(float(max(r.following_error.max()
                                                                                   for r in reports)), 5),
            "drive_lag_bound_ms": None if not reports else round(reports[-1].bound * 1e3, 2),
            "missed_answers": sum(r.missed for r in reports),
            "missed_answers_most_in_a_report": max((r.missed for r in reports), default=0),
            "faults": faults}


def scaling_cycle(statuses: list[ScalerStatus]) -> dict:
    """The scaler's compute per control cycle as it ran in the cell (ScalerStatus.compute_us, us: the
    scaling layer's step, where the issue's 100 us goal is judged), over the cycles that solved for a speed,
    and how each was solved (see shared.scaling.problem.solve)."""
    solved = [s for s in statuses if s.status == "running"]
    compute = np.array([s.compute_us for s in solved])
    methods: dict[str, int] = {}
    for s in solved:
        method = s.method.split("+")[0]
        methods[method] = methods.get(method, 0) + 1
    return {"cycles": len(solved), "compute_us": _percentiles(compute, 50, 99, scale=1.0), "methods": methods}


def analyse(robot: RobotModel, config: CellConfig, rec: Recording) -> tuple[dict, dict]:
    """(summary, monitor series) of a recording. The violations are the monitor service's own count."""
    st = rec.statuses
    stamps = np.array([s.stamp for s in st])
    alpha = np.array([s.alpha for s in st])
    trace = float(stamps[-1] - stamps[0]) if len(st) > 1 else 0.0
    # the shuttles were counted while the shuttle was directed; the trace goes on a moment after it (the monitor's
    # last summary), and a rate over the trace's length would understate the run's by that moment
    duration = rec.directed_s if rec.directed_s is not None else trace
    series = monitor_series(robot, config, rec)
    finite = np.isfinite(series["margin"])
    horizon = config.ssm.horizon
    summaries = [e for e in rec.events if e.source == "safety_monitor" and e.event == "monitor_summary"]
    violation_events = [e for e in rec.events if e.source == "safety_monitor" and e.event == "ssm_violation"]
    violations = int(summaries[-1].value) if summaries else None
    stalls = replan_stalls(st, rec.t0)
    changeovers = goal_changeovers(st)
    mark_blocked_goals(stalls, rec.events, rec.t0)
    replans, goals = [], []
    for e in rec.events:
        if e.source != "planner" or not (e.event.startswith("trajectory_") or e.event == "replan_refused"):
            continue
        reason = e.event[len("trajectory_"):] if e.event.startswith("trajectory_") else e.text.split(":")[0]
        if reason == "goal":
            goals.append(e)
            continue
        t = e.stamp - rec.t0
        entry = {"t": round(t, 3), "reason": reason, "ok": e.event != "replan_refused",
                 "compute_ms": None if e.value is None else round(e.value, 1), "stall_ms": None,
                 "detail": e.text[:200]}
        if reason == "beta":
            before = [s for s in stalls if s["t"] <= t + 1e-6]
            if before:
                entry["stall_ms"] = before[-1]["stall_ms"]
        replans.append(entry)
    s2f = np.concatenate([r.sample_to_frame for r in rec.latency]) if rec.latency else np.zeros(0)
    proc = np.concatenate([r.processing for r in rec.latency]) if rec.latency else np.zeros(0)
    own = np.concatenate([r.tick_to_frame for r in rec.latency]) if rec.latency else np.zeros(0)
    # a frame's wait for the SYNC: the driver's period as it reported it (its --period), else the configuration's
    sync_wait = max((r.sync_wait for r in rec.latency), default=config.scaling.period)
    stall_values = np.array([s["stall_ms"] for s in stalls])
    p99 = float(np.percentile(own, 99)) if own.size else None
    tracker = tracker_summary(rec)
    drives = drive_summary(rec)
    lag = max(drives["lag_p99_ms"] or [0.0]) / 1e3           # the joints behind the frames (the worst joint's p99)
    summary = {
        "duration_s": round(duration, 3),
        "trace_s": round(trace, 3),
        "cycles_completed": len(st),
        "mean_cycle_s": round(float(np.diff(stamps).mean()), 6) if len(st) > 1 else None,
        "shuttles_completed": rec.shuttles,
        "shuttles_per_min": round(60.0 * rec.shuttles / duration, 2) if duration else 0.0,
        "shuttle_progress": round(max(rec.progress, rec.shuttles), 4),
        "mean_alpha": round(float(alpha.mean()), 4) if alpha.size else None,
        "stopped_fraction": round(float(np.mean(alpha < 1e-6)), 4) if alpha.size else None,
        "beta_requests": len(stalls),
        "replans": replans,
        "replan_compute_ms": _percentiles(np.array([r["compute_ms"] for r in replans if r["compute_ms"] is not None]),
                                          50, 95, scale=1.0),
        "goal_plans": {"count": len(goals), "prepared": sum("prepared on the way here" in e.text for e in goals),
                       "compute_ms": _percentiles(np.array([e.value for e in goals if e.value is not None]), 50, 95,
                                                  scale=1.0)},
        "goal_changeover_ms": {"legs": int(changeovers.size)} | _percentiles(changeovers, 50, 95)
        | {"max": round(float(changeovers.max()) * 1e3, 1) if changeovers.size else None},
        "replan_stall_ms": {"median": round(float(np.median(stall_values)), 1) if stall_values.size else None,
                            "max": round(float(stall_values.max()), 1) if stall_values.size else None,
                            "goal_blocked": sum(s["goal_blocked"] for s in stalls),
                            "episodes": stalls},
        "min_margin_m": round(float(series["margin"][finite].min()) * horizon, 4) if finite.any() else None,
        "min_margin_m_s": round(float(series["margin"][finite].min()), 4) if finite.any() else None,
        "min_separation_m": round(float(series["separation"][np.isfinite(series["separation"])].min()), 4)
        if np.isfinite(series["separation"]).any() else None,
        "violations": violations,
        "violation_events": [e.text for e in violation_events[:10]],
        "monitor": summaries[-1].text if summaries else "no monitor summary received",
        "latency": {"chains": int(s2f.size), "sample_to_frame_ms": _percentiles(s2f, 50, 99),
                    "processing_ms": _percentiles(proc, 50, 99), "tick_to_frame_ms": _percentiles(own, 50, 99),
                    "sync_wait_ms": round(1e3 * sync_wait, 3)},
        "scaling_cycle": scaling_cycle(st),
        "drives": drives,
        "scaler_silences": scaler_silences(stamps, np.array([s.compute_us for s in st]),
                                           np.array([j.stamp for j in rec.joint_states]), config.scaling.period,
                                           rec.t0)
        | {"stale_stops": stale_stops([(e.stamp, e.value) for e in rec.events if e.source == "robot_driver"
                                       and e.event == "stale_command" and e.value is not None],
                                      np.array([c.stamp for c in rec.commands]), rec.t0)},
        "monitor_check": monitor_summary(rec, series, violations,
                                         recount(robot, config, rec.joint_states, rec.human_states,
                                                 commands=rec.commands)),
        "tracker": tracker,
        "human_acceleration_m_s2": config.ssm.human_acceleration,
        "exceedances_after_reaction_time": int(np.count_nonzero(series["late_excess"] > 0)),
        "worst_late_excess_m_s": round(float(series["late_excess"].max()), 4) if series["late_excess"].size else 0.0,
        "reaction_time_s": config.ssm.reaction_time,
        "reaction_time_covers_p99": None if p99 is None
        else bool(reaction_chain(p99, sync_wait, lag) <= config.ssm.reaction_time),
        "events": sorted({f"{e.source}:{e.event}" for e in rec.events if e.severity != "info"}),
    }
    return summary, series


# ------------------------------------------------------------------------------------------- files
def _write_csv(path: Path, header: list[str], rows) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)


def _fmt(v) -> str:
    return f"{v:.6f}" if isinstance(v, float) else str(v)


def write_trace(out: Path, rec: Recording) -> None:
    """trace.csv (one row per control cycle), humans.csv, events.csv, latency.csv, trajectories.json."""
    commands = {c.seq: c for c in rec.commands}
    js = sorted(rec.joint_states, key=lambda m: m.stamp)
    js_stamps = np.array([m.stamp for m in js])
    j6 = lambda name: [f"{name}_{k}" for k in range(1, 7)]
    header = ["t", "seq", "trajectory_version", "s", "alpha", "safe_alpha", "beta", "status", "min_separation_m",
              *j6("q_cmd"), *j6("qd_cmd"), *j6("q_meas"), *j6("qd_meas"), "drive_state", "drive_lag_ms", "phase"]
    rows = []
    for st in rec.statuses:
        cmd = commands.get(st.seq)
        i = int(np.searchsorted(js_stamps, st.stamp, side="right")) - 1
        meas = js[i] if i >= 0 else None
        t = st.stamp - rec.t0
        rows.append([_fmt(t), st.seq, st.trajectory_version, _fmt(st.s), _fmt(st.alpha), _fmt(st.safe_alpha),
                     int(st.beta), st.status, "" if st.min_separation is None else _fmt(st.min_separation),
                     *map(_fmt, st.q_command.tolist()),
                     *(map(_fmt, cmd.qd.tolist()) if cmd else [""] * 6),
                     *(map(_fmt, meas.q.tolist()) if meas else [""] * 6),
                     *(map(_fmt, meas.qd.tolist()) if meas else [""] * 6),
                     meas.drive_state if meas else "",
                     f"{meas.drive_lag * 1e3:.1f}" if meas and meas.drive_lag is not None else "",
                     rec.phase(t) if rec.phase else ""])
    _write_csv(out / "trace.csv", header, rows)
    rows = []
    for h in rec.human_states:
        if not h.valid or h.radii.size == 0:        # the tracker's invalid (or empty) states: one row, no capsule
            rows.append([_fmt(h.stamp - rec.t0), h.seq, int(h.valid)] + [""] * 15)
            continue
        for j in range(h.radii.size):
            rows.append([_fmt(h.stamp - rec.t0), h.seq, int(h.valid), j, *map(_fmt, h.segments[j].ravel().tolist()),
                         _fmt(float(h.radii[j])), *map(_fmt, h.velocities[j].ravel().tolist()),
                         int(h.velocity_known[j])])
    _write_csv(out / "humans.csv", ["t", "seq", "valid", "capsule", "ax", "ay", "az", "bx", "by", "bz", "radius",
                                    "vax", "vay", "vaz", "vbx", "vby", "vbz", "velocity_known"], rows)
    _write_csv(out / "events.csv", ["t", "source", "event", "severity", "value", "text"],
               [[_fmt(e.stamp - rec.t0), e.source, e.event, e.severity, "" if e.value is None else _fmt(e.value),
                 e.text] for e in rec.events])
    _write_csv(out / "latency.csv", ["t", "sample_to_frame_ms", "processing_ms", "tick_to_frame_ms"],
               [[_fmt(r.stamp - rec.t0), f"{a * 1e3:.3f}", f"{b * 1e3:.3f}", f"{c * 1e3:.3f}"] for r in rec.latency
                for a, b, c in zip(r.sample_to_frame, r.processing, r.tick_to_frame)])
    (out / "trajectories.json").write_text(json.dumps([
        {"t": round(m.stamp - rec.t0, 4), "version": m.version, "base_version": m.base_version, "reason": m.reason,
         "goal_id": m.goal_id, "junction": m.junction, "times": m.times.tolist(), "positions": m.positions.tolist(),
         "velocities": m.velocities.tolist()} for m in rec.trajectories]))


def _save(fig, path: Path, legends=()) -> str:
    """Legends on the given axes, layout, PNG, close; the file's name."""
    import matplotlib.pyplot as plt

    for ax in legends:
        ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path.name


def write_figures(out: Path, rec: Recording, series: dict, config: CellConfig) -> list[str]:
    """The paper's figures as PNG; returns their file names."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from shared.wire.convert import trajectory_from_msg

    names = []
    js = rec.joint_states
    t_js = np.array([m.stamp - rec.t0 for m in js])
    q = np.array([m.q for m in js]).reshape(-1, 6)
    qd = np.array([m.qd for m in js]).reshape(-1, 6)
    # nominal: each trajectory version at full speed, placed where the scaler first ran it
    first_seen: dict[int, tuple[float, float]] = {}
    for st in rec.statuses:
        first_seen.setdefault(st.trajectory_version, (st.stamp - rec.t0, st.s))
    fig, axes = plt.subplots(6, 2, figsize=(13, 12), sharex=True)
    for msg in rec.trajectories:
        if msg.version not in first_seen:
            continue
        t_v, s_v = first_seen[msg.version]
        traj = trajectory_from_msg(msg)
        tau = np.arange(s_v, traj.duration, 0.01)
        if tau.size == 0:
            continue
        pos, vel, _ = traj.sample(tau)
        for k in range(6):
            axes[k, 0].plot(t_v + tau - s_v, pos[:, k], "--", color="tab:gray", lw=0.8)
            axes[k, 1].plot(t_v + tau - s_v, vel[:, k], "--", color="tab:gray", lw=0.8)
    for k in range(6):
        axes[k, 0].plot(t_js, q[:, k], color="tab:blue", lw=1.0)
        axes[k, 1].plot(t_js, qd[:, k], color="tab:blue", lw=1.0)
        axes[k, 0].set_ylabel(f"q{k + 1} (rad)")
        axes[k, 1].set_ylabel(f"qd{k + 1} (rad/s)")
    axes[0, 0].set_title("joint positions: nominal (dashed, each trajectory at full speed) vs executed")
    axes[0, 1].set_title("joint velocities: nominal (dashed) vs executed (measured)")
    axes[-1, 0].set_xlabel("t (s)")
    axes[-1, 1].set_xlabel("t (s)")
    names.append(_save(fig, out / "joints.png"))

    hs = [h for h in rec.human_states if h.valid and h.radii.size]
    fig, axes = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    if hs:
        t_h = np.array([h.stamp - rec.t0 for h in hs])
        torso = np.array([h.segments[0].mean(axis=0) for h in hs])
        speed = np.array([np.linalg.norm(h.velocities, axis=2).max() for h in hs])
        for k, axis in enumerate("xyz"):
            axes[0].plot(t_h, torso[:, k], label=f"torso centre {axis}")
        axes[1].plot(t_h, speed, color="tab:red", label="fastest capsule end point")
    axes[0].set_ylabel("position (m)")
    axes[1].set_ylabel("speed (m/s)")
    axes[1].set_xlabel("t (s)")
    axes[0].set_title("human position and velocity (tracker_ingest output)")
    names.append(_save(fig, out / "human.png", legends=axes))

    t_s = np.array([s.stamp - rec.t0 for s in rec.statuses])
    fig, axes = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    axes[0].plot(t_s, [s.alpha for s in rec.statuses], label="alpha (commanded)")
    axes[0].plot(t_s, [s.safe_alpha for s in rec.statuses], lw=0.7, label="safe alpha")
    axes[0].axhline(config.scaling.alpha_min, color="tab:red", ls=":", label="alpha_min")
    axes[1].step(t_s, [int(s.beta) for s in rec.statuses], where="post", color="tab:purple", label="beta")
    for e in rec.events:
        if e.source == "planner" and e.event.startswith("trajectory_") and e.event != "trajectory_goal":
            for a in axes:
                a.axvline(e.stamp - rec.t0, color="tab:green", lw=0.6)
    axes[0].set_ylabel("alpha")
    axes[1].set_ylabel("beta")
    axes[1].set_xlabel("t (s); green lines: replans")
    axes[0].set_title("scaling factor and replan request")
    names.append(_save(fig, out / "scaling.png", legends=axes))

    fig, axes = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    lim = np.where(np.isfinite(series["limit"]), series["limit"], np.nan)
    axes[0].plot(series["t"], series["approach"], label="robot approach speed (pair closest to its limit)")
    axes[0].plot(series["t"], np.maximum(lim, 0.0), color="tab:red", label="ISO/TS 15066 limit v_r_max")
    axes[0].set_ylabel("m/s")
    axes[0].set_ylim(-0.5, 3.0)
    sep = np.where(np.isfinite(series["separation"]), series["separation"], np.nan)
    axes[1].plot(series["t"], sep, label="smallest separation robot-human")
    axes[1].axhline(config.ssm.min_separation, color="tab:red", ls=":", label="d_min")
    axes[1].set_ylabel("m")
    axes[1].set_xlabel("t (s)")
    axes[0].set_title("velocity towards the human against its ISO/TS 15066 limit (measured joint states)")
    names.append(_save(fig, out / "ssm.png", legends=axes))
    return names


def write_bag(out: Path, robot: RobotModel, config: CellConfig, rec: Recording) -> str:
    """recording.mcap and metadata.yaml (tools.mcap_record), the run placed on the wall clock as ending now."""
    import time

    from tools.mcap_record import write_mcap
    from tools.sweep import code_version

    stamps = [m.stamp for m in rec.joint_states + rec.statuses + rec.human_states] or [rec.t0]
    write_mcap(out, robot, config, rec, epoch_t0=time.time() - (max(stamps) - rec.t0),
               code=code_version(Path(__file__).resolve().parents[1]))
    return "recording.mcap"


def write_report(out: Path, robot: RobotModel, config: CellConfig, rec: Recording, extra: dict | None = None) -> dict:
    """Write the whole report folder; returns the summary (also in summary.json)."""
    out.mkdir(parents=True, exist_ok=True)
    summary, series = analyse(robot, config, rec)
    summary.update(extra or {})
    write_trace(out, rec)
    summary["figures"] = write_figures(out, rec, series, config)
    write_recording(out / "recording.rrd", robot, config.ssm, rec.joint_states + rec.commands + rec.human_states
                    + rec.statuses + rec.trajectories, rec.t0)
    summary["recording"] = "recording.rrd"
    summary["ros2_bag"] = write_bag(out, robot, config, rec)
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=plain_json) + "\n")
    return summary


def plain_json(value):
    """json's `default` for the summary: numpy's numbers and arrays as Python's (a count that became numpy's int once
    failed the report's JSON, and the run's summary was lost wherever the judge found a speed-up towards an unknown
    velocity); anything else still refused."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"Object of type {type(value).__name__} is not JSON serializable")
