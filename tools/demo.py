"""`hrc demo`: the paper's experiment on the real processes (the project's main job).

Starts the PRBT emulator and every service as child processes (tools.launch), on kernel CAN (vcan0)
where there is one, else on udp_multicast inside a private network namespace that it makes for itself
(it re-runs itself under `unshare -n`, or `-rn` when not root). Then, as the cell's operator and witness:
* a scripted human (evidence.scenarios.paper_phases, at 120 Hz), or a recorded motion (--human FILE: several
  people, dropouts; shared.tracking.motion, at its own rate), goes out as raw tracker data from a process of
  its own (tools.feed), as a camera's tracker would: the recorder's work here cannot delay it;
* goals shuttle the robot between q_s and q_g: the next goal when the robot has arrived, the same goal
  again when the robot is not following a plan for it (refused, or dropped after a stop); see
  tools.actors;
* everything the cell publishes is recorded; progress twice a second;
* a witness of the machine's own stalls (tools.stalls, SCHED_FIFO 99) runs beside it, so that the report says
  which of the cell's lag warnings came as the machine itself stopped (the summary's ``machine``);
* at the end, the report folder (tools.report; format in docs/report-format.md).
`--no-beta` runs the planner with replans on the scaling layer's request switched off.
"""

from __future__ import annotations

import json
import os
import subprocess
import time
from pathlib import Path

from evidence.scenarios import paper_phases
from shared.drives.bus import in_private_namespace
from shared.tracking.motion import RecordedMotion
from shared.transport.zenoh_session import open_session
from shared.wire.keys import KeySpace
from shared.wire.messages import JointState, ScalerStatus
from tools.actors import Recorder, Shuttle, lead_in_time, schedule_of
from tools.cell import choose_bus
from tools.feed import READY
from tools.launch import CellProcesses, LaunchError, free_port
from tools.programs import source_rate_args
from tools.report import Recording, write_report
from tools.stalls import READY as WITNESS_READY
from tools.stalls import in_run

PREFIX = "hrc/demo"
START_MARGIN = 0.02   # s: the feed's first lead-in sample is due this long after it is told the start
ENABLE_WAIT = 5.0     # s: the most the run waits for drives stopped at its start to be recovered (Shuttle.enable)


def reexec_in_namespace(argv: list[str], pass_fds: tuple[int, ...] = ()) -> int | None:
    """When udp_multicast is needed and this process is not in a private namespace: run argv in a new one
    and return its exit code; None when no re-run is needed. Raises RuntimeError when none can be made."""
    from tools.cell import in_new_namespace, namespace_reason

    if choose_bus()[0] != "udp_multicast" or in_private_namespace():
        return None
    reason = namespace_reason()
    if reason:
        raise RuntimeError(f"no kernel CAN (vcan0), and no private network namespace for udp_multicast ({reason}); "
                           "run 'hrc demo --sim' (in-process) instead")
    return subprocess.call(in_new_namespace(argv), pass_fds=pass_fds)


# --no-beta, the paper's ablation: the planner answers no replan request, so the scaler never stands to await one
NO_BETA_ARGS = {"planner": ["--no-beta"], "scaler": ["--no-await"]}


def service_args(no_beta: bool, rate: float | None) -> dict[str, list[str]]:
    """Each service's extra arguments for this run: the paper's ablation (--no-beta), and the person feed's frame
    rate declared to tracker_ingest (rate, Hz: a recorded motion's own; None: the scripted person, whose 120 Hz
    needs no declaring; a rate the service refuses not declared either: ``tools.programs.source_rate_args``), so
    a camera's second frame is not taken for a lost person."""
    return {**{name: list(extra) for name, extra in (NO_BETA_ARGS if no_beta else {}).items()},
            **source_rate_args(rate)}


def start_feed(cell: CellProcesses, human_file: Path | None, phase_length: float, stats: Path, latency: float = 0.0):
    """The person feed's process (tools.feed), connected and ready to start; its Popen. latency: s from each
    sample's capture to its sending."""
    motion = ["--human", str(human_file)] if human_file is not None else ["--phase-length", repr(phase_length)]
    return cell.spawn_helper("human_feed", ["tools.feed", "--connect", cell.endpoint, "--prefix", cell.prefix,
                                            "--stats", str(stats), "--latency", repr(latency), *motion], READY)


def start_witness(cell: CellProcesses, stats: Path):
    """The machine's stall witness (tools.stalls, SCHED_FIFO 99 above the whole cell), running; its Popen."""
    return cell.spawn_helper("stall_witness", ["tools.stalls", "--stats", str(stats)], WITNESS_READY)


def helper_figures(stats: Path, helper: str) -> dict:
    """What a helper process (the feed, the stall witness) wrote to `stats` at its end; {"error": ...} naming its
    log when it wrote nothing readable."""
    try:
        return json.loads(stats.read_text())
    except (OSError, ValueError) as exc:
        return {"error": f"the {helper} wrote no figures ({exc.__class__.__name__}); see logs/{stats.stem}.log"}


def machine_figures(stats: Path, t0: float, events) -> dict:
    """The stall witness's figures for the run that began at t0 (``tools.stalls.in_run``: its stalls from t0, and
    the cell's warnings that followed one); {"error": ...} when it wrote nothing."""
    figures = helper_figures(stats, "stall witness")
    return figures if "error" in figures else in_run(figures, t0, events)


def feed_figures(stats: Path) -> dict:
    """What the feed process wrote at its end: rate_hz, skipped, sent, late_ms_p99, late_ms_max, late_max_at_s
    (how late it woke for its samples, and when); {"error": ...} when it wrote nothing."""
    return helper_figures(stats, "feed")


def run(out: Path, duration: float, phase_length: float, config_path: Path | None, seed: int, no_beta: bool,
        quiet: bool, robot, config, human_file: Path | None = None, view_fd: int | None = None,
        latency: float = 0.0) -> dict:
    """The experiment on the real processes; returns the summary (written to out/summary.json). human_file:
    a recorded motion (shared.tracking.motion.RecordedMotion) in place of the paper's phases; view_fd: a pipe to a
    served 3D viewer (tools.view.ViewServer) to log every message into as it arrives; latency: s from each of the
    person's samples' capture to the cell (a camera pipeline's)."""
    interface, channel = choose_bus()
    keys = KeySpace(PREFIX)
    human = RecordedMotion.load(human_file) if human_file is not None else paper_phases(phase_length)
    cell = CellProcesses(out / "logs", PREFIX, interface, channel, config_path, seed,
                         extra_args=service_args(no_beta, human.rate if human_file is not None else None))
    say = (lambda *a: None) if quiet else (lambda text: print(text, flush=True))
    say(f"hrc demo: starting the cell (emulator + 5 services, CAN {interface}{' ' + channel if channel else ''}, "
        f"Zenoh {cell.endpoint}); logs in {out / 'logs'}")
    session = open_session("peer", listen=[f"tcp/127.0.0.1:{free_port()}"], connect=[cell.endpoint])
    rec = Recording(t0=time.monotonic())
    recorder = None
    stats = out / "logs" / "human_feed.json"
    machine = out / "logs" / "stall_witness.json"
    try:
        started = time.monotonic()
        cell.start(session)
        start_witness(cell, machine)
        feed = start_feed(cell, human_file, phase_length, stats, latency)
        what = f"the motion in {human_file}" if human_file is not None else "the paper's four phases"
        say(f"hrc demo: all services up in {time.monotonic() - started:.1f} s; {duration:.0f} s of {what}"
            f"{' (no beta replans)' if no_beta else ''}")
        recorder = Recorder(session, keys, rec)
        rec.phase = human.phase
        shuttle = Shuttle(session, keys, recorder, rec, say)
        if not shuttle.enable(ENABLE_WAIT):
            say(f"hrc demo: the drives do not run after {ENABLE_WAIT:.0f} s; starting all the same (recovery goes on)")
        # the run starts once the feed's lead-in has shown the tracker the people as they stand at the start (each
        # sample reaching the cell `latency` after its capture)
        rec.t0 = time.monotonic() + lead_in_time(schedule_of(human).rate, latency) + START_MARGIN
        if view_fd is not None:
            from tools.view import CellLogger, pipe_stream

            recorder.on_message = CellLogger(pipe_stream(view_fd), robot, config.ssm, rec.t0).dispatch
        try:
            feed.stdin.write(f"{rec.t0!r}\n".encode())
            feed.stdin.close()
        except OSError:                                  # it ended after saying it was ready
            raise LaunchError(f"the person feed ended before its start (exit {feed.poll()}); "
                              f"see {out / 'logs' / 'human_feed.log'}") from None
        time.sleep(max(0.0, rec.t0 - time.monotonic()))   # the first goal at the start, not in the lead-in
        _direct(shuttle, recorder, rec, duration, say)
        # the monitor's last summary (once a second), the person still tracked: a feed stopped first would end
        # every run with a tracker dropout, a stopped robot and a second of states the monitor cannot check
        time.sleep(1.2)
        alive, cpu = cell.alive(), cell.cpu_seconds()
    except LaunchError as exc:
        raise RuntimeError(f"the cell did not start: {exc}") from None
    finally:
        if recorder is not None:
            recorder.close()
        codes = cell.stop()
        session.close()
    say(f"hrc demo: cell stopped (exit codes {codes}); writing the report to {out}")
    extra = {"mode": "processes", "can": interface, "services_alive_at_end": alive, "exit_codes": codes,
             "cpu_s": cpu, "cpus": os.cpu_count(),
             "bad_messages_seen": recorder.bad, "no_beta": no_beta,
             "human_feed": feed_figures(stats),
             "machine": machine_figures(machine, rec.t0, rec.events),
             "human": str(human_file or "built-in: the paper's four phases")}
    return write_report(out, robot, config, rec, extra)


def _direct(shuttle: Shuttle, recorder: Recorder, rec: Recording, duration: float, say) -> None:
    """Shuttle goals, recovery requests and progress until duration has passed."""
    shuttle.start(time.monotonic())
    seen_events = 0
    last_print = -1e9
    while (now := time.monotonic()) - rec.t0 < duration:
        with recorder.lock:
            new_events, seen_events = rec.events[seen_events:], len(rec.events)
        for e in new_events:
            if e.source == "planner" and e.event != "trajectory_goal" or e.severity != "info":
                say(f"t={e.stamp - rec.t0:6.2f}s  {e.source}: {e.event}: {e.text}")   # whole: its figures end it
        shuttle.step(now)
        if now - last_print >= 0.5:
            last_print = now
            js, st = recorder.get(JointState), recorder.get(ScalerStatus)
            t = now - rec.t0
            sep = f"{st.min_separation:5.2f}" if st is not None and st.min_separation is not None else "  -  "
            say(f"t={t:6.2f}s  {rec.phase(t):<18} alpha={st.alpha if st else 0:4.2f} beta={int(st.beta) if st else 0} "
                f"sep={sep} m  v{st.trajectory_version if st else '-'}  shuttles={rec.shuttles}  "
                f"robot={js.drive_state.split(':')[0] if js else '-'}")
        recorder.wait_finished(0.02)      # the next goal as soon as the robot has arrived
    rec.directed_s = duration          # the run's length: what the shuttles were counted over
