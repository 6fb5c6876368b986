"""Every real recording through the cell, as a table (not a test: it prints figures; docs/real-people.md).

The human-assembly recordings (``../shared/data/human-assembly/``: RealSense + OpenPose, the arms of people
assembling LEGO at a table) are converted with the product's own reader (``hrc human from-keypoints FILE OUT
--format assembly --translate X 0 1.1``) at each placement, and run through ``hrc demo --human`` on the real
processes (every service over Zenoh, the emulated PRBT on CAN; the recording sent at its own 30 Hz), or in the
simulation with ``--sim``. One row per run, from the run's own summary.json (docs/report-format.md): shuttles per
minute (whole shuttles, and with the last leg's part counted), the stopped share, the share of control cycles with
the people's data stale, the violations counted by the
monitor, by the report's recount and by the independent judge (tools/judge.py), the states left unchecked, the
tracker's dropouts and unknown velocities, the independent judge's speed-ups within T_r, the worst joint's drive
lag p99, the machine's own stalls (the demo's FIFO 99 witness, ``tools.stalls``) and the events that were not info,
each marked "(machine)" where it came during or just after such a stall. Then the mean shuttles per minute and the
sums of violations per placement.
The last line is one JSON object: {"rows": [...], "means": {placement: {"shuttles_per_min": m, "progress_per_min":
p (the last leg's part counted: the processes and the simulation compare by it), "violations":
[monitor, recount, independent], "unchecked": n, "held": [recordings whose robot completed no shuttle]}}} (a count
is null where no run of the placement measured it: the simulation has no recount).

Placements (shoulders 1.35 m high, facing the robot across its sweep; ``evidence.recorded.Placement``):
* table_edge, X = -0.05: shoulders at x = -0.90 m, hands about 0.77 m from the base;
* step_back, X = -0.75: shoulders at x = -1.60 m;
* X:YAW, any other: moved X m along the base's x axis, then turned YAW degrees about the base (``-0.15:60``: near
  the table's edge, beside the end of the sweep the robot starts from; the real_around scenario kind draws these).

    python bench/real_people.py [--sim] [--paper-formula] [--placements table_edge,step_back,X:YAW]
                                [--recordings DIR] [--only NAME ...] [--out DIR] [--every N] [--latency S]

``--every 2`` keeps every second frame of each recording: the same people as a 15 Hz camera would see them
(``hrc human from-keypoints --every``), sent at that rate; the tracker's window and dropout bound follow it.
``--latency S`` has each frame reach the cell S after its capture, stamped with it (``hrc demo --latency``): a
camera pipeline's latency, which the cell counts in the data's age and the scaling layer in the person's travel
(with ``--sim`` both layers are given each frame that late, the judge the person of each moment).

Each processes run takes the recording's length plus about 15 s to start and stop the cell; the 24 runs of
both placements about 20 minutes on this 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from evidence.recorded import PLACEMENTS, RECORDINGS, placement_named  # noqa: E402  (the placements, one definition)
from shared.core.errors import ConfigError  # noqa: E402
from tools.arguments import sample_latency  # noqa: E402

HRC = [sys.executable, "-m", "tools.cli"]


def convert(recording: Path, placement: str, out: Path, every: int = 1) -> Path:
    """The recording as a motion file at the placement, every `every`-th frame kept (a tracker at 1/every the
    rate; the product's reader; raises CalledProcessError)."""
    motion = out / f"{recording.stem}-{placement.replace(':', '_')}{'' if every == 1 else f'-every{every}'}.json"
    subprocess.run(HRC + ["human", "from-keypoints", str(recording), str(motion), "--format", "assembly",
                          *placement_named(placement).options(), "--every", str(every)],
                   check=True, cwd=ROOT, capture_output=True, text=True)
    return motion


def run(motion: Path, report: Path, sim: bool, paper: bool, config: Path | None = None, latency: float = 0.0) -> dict:
    """One ``hrc demo --human`` run (with the cell configuration `config`, where given; the person's samples
    reaching the cell `latency` s after their capture); its summary.json, or {"error": ...} where the run gave
    none."""
    cmd = HRC + ["demo", "--human", str(motion), "--out", str(report), "--quiet"]
    cmd += ["--sim"] if sim else []
    cmd += ["--latency", repr(latency)] if latency else []
    cmd += ["--paper-formula"] if paper else []
    cmd += ["--config", str(config)] if config is not None else []
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    summary = report / "summary.json"
    if not summary.exists():
        return {"error": f"exit {done.returncode}: {(done.stderr or done.stdout).strip()[-300:]}"}
    return json.loads(summary.read_text())


def progress_per_min(summary: dict) -> float | None:
    """Shuttles per minute with the last leg's part counted (``shuttle_progress``, docs/report-format.md): whole
    shuttles over a half-minute run differ by a whole shuttle between a run that ends just short of a goal and one
    that ends just past it, so the processes and the simulation compare by this; None where a run has no progress."""
    progress, duration = summary.get("shuttle_progress"), summary.get("duration_s")
    return round(60.0 * progress / duration, 2) if progress is not None and duration else None


def row(recording: str, placement: str, summary: dict) -> dict:
    """The table's figures of one run (None where the run's mode does not measure them: the simulation has no
    recount, no tracker and no drives)."""
    check = summary.get("monitor_check") or {}
    independent = check.get("independent") or {}
    tracker = summary.get("tracker") or {}
    lags = (summary.get("drives") or {}).get("lag_p99_ms") or []     # per joint (report.py)
    machine = summary.get("machine") or {}
    silences = summary.get("scaler_silences") or {}
    return {"recording": recording, "placement": placement, "error": summary.get("error"),
            "shuttles_per_min": summary.get("shuttles_per_min"),
            "progress_per_min": progress_per_min(summary),
            "stopped": summary.get("stopped_fraction"),
            # the people's data stale (its age from the capture past the bound: a camera's latency counts)
            "stale_data": tracker.get("stale_share"),
            "violations": [summary.get("violations"), check.get("violations_recounted"), independent.get("violations")],
            "unchecked": check.get("unchecked"),
            "dropouts": tracker.get("dropouts"),
            "velocity_unknown": [tracker.get("velocity_unknown_share"), tracker.get("velocity_unknown_longest_ms")],
            # the judge's speed-ups within T_r, of them those towards a capsule whose velocity was unknown, and of
            # those the ones a command made (the rest: the drives following commands made before the person state)
            "speedups": [independent.get("speedups"), independent.get("speedups_unknown"),
                         independent.get("speedups_unknown_commanded")],
            "drive_lag_p99_ms": max(lags) if lags else None,
            "events": summary.get("events") or [],
            # the machine's own stalls (tools.stalls: how many beyond 10 ms, the longest), and the events after one
            "machine": [machine.get("stalls"), machine.get("late_ms_max")] if "stalls" in machine else [None, None],
            "after_stall": machine.get("after_stall") or [],
            # SYNCs the scaler let pass without a command (tools.silences: how many, the longest ms, the joint
            # states the driver published meanwhile)
            "scaler_silences": [silences["count"], *silences["longest"][0][1:4:2]] if silences.get("longest") else
            [silences.get("count"), None, None],
            # each stale_command stop: the commands the scaler had published meanwhile (tools.silences.stale_stops)
            "stale_stops": silences.get("stale_stops") or []}


def event_cell(r: dict) -> str:
    """The events of a run, each marked where it came with a stall of the machine, and a stale_command stop with the
    commands the scaler had sent meanwhile (none: its silence; some: they had not reached the driver)."""
    out = []
    for e in r["events"]:
        notes = ["machine"] if e in r["after_stall"] else []
        if e == "robot_driver:stale_command" and r["stale_stops"]:
            notes += [f"{sum(stop[2] for stop in r['stale_stops'])} commands sent meanwhile"]
        out.append(e + (f" ({', '.join(notes)})" if notes else ""))
    return ", ".join(out) or "-"


def _cell(value, share: bool = False) -> str:
    if value is None:
        return "-"
    if share:
        return f"{100.0 * value:.1f} %"
    if isinstance(value, float):
        return f"{value:.3g}"
    if isinstance(value, list):
        return " / ".join(_cell(v) for v in value)
    return str(value)


def _total(values) -> int | None:
    """The sum of the counts a run measured (None where no run measured it: the simulation's recounts)."""
    counted = [v for v in values if v is not None]
    return sum(counted) if counted else None


def means(rows: list[dict]) -> dict:
    """Per placement: the mean shuttles per minute, the violations summed per counter, the unchecked states, the
    judge's speed-ups summed per count (all, towards an unknown velocity, of those a command's), and the recordings
    whose robot completed no shuttle."""
    out = {}
    for placement in dict.fromkeys(r["placement"] for r in rows):
        mine = [r for r in rows if r["placement"] == placement and r["error"] is None]
        rates = [r["shuttles_per_min"] for r in mine]
        parts = [r["progress_per_min"] for r in mine if r["progress_per_min"] is not None]
        out[placement] = {
            "runs": len(mine), "failed": sum(r["placement"] == placement and r["error"] is not None for r in rows),
            "shuttles_per_min": round(sum(rates) / len(rates), 2) if rates else None,
            "progress_per_min": round(sum(parts) / len(parts), 2) if parts else None,
            "violations": [_total(r["violations"][k] for r in mine) for k in range(3)],
            "unchecked": _total(r["unchecked"] for r in mine),
            "speedups": [_total(r["speedups"][k] for r in mine) for k in range(3)],
            "held": [r["recording"] for r in mine if not r["shuttles_per_min"]]}
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sim", action="store_true", help="in the simulation (hrc demo --sim) instead of the processes")
    parser.add_argument("--paper-formula", action="store_true", help="the paper's configuration (deploy/cell-paper.yaml)")
    parser.add_argument("--config", type=Path, default=None,
                        help="another cell configuration (hrc demo --config), e.g. to compare a planning setting")
    parser.add_argument("--placements", default="table_edge,step_back",
                        help=f"comma-separated, of {', '.join(PLACEMENTS)} or X:YAW (m, degrees; default: the two; "
                             "--placements=-0.15:60 with the '=' where the list starts with a minus)")
    parser.add_argument("--recordings", type=Path, default=RECORDINGS, help="the folder of *.txt recordings")
    parser.add_argument("--only", nargs="*", default=None, help="recording names (without .txt) to run, not all")
    parser.add_argument("--out", type=Path, default=None, help="where each run's report goes (default: a temporary folder)")
    parser.add_argument("--every", type=int, default=1, metavar="N",
                        help="keep every N-th frame of each recording: the same people as a tracker at 1/N their "
                             "30 Hz sees them (2: a 15 Hz camera; hrc human from-keypoints --every)")
    parser.add_argument("--latency", type=sample_latency, default=0.0, metavar="SECONDS",
                        help="each sample reaches the cell this long after its capture, stamped with it (a camera "
                             "pipeline's latency; hrc demo --latency, in the simulation too)")
    args = parser.parse_args(argv)
    if args.every < 1:
        parser.error(f"--every: expected a whole number >= 1, got {args.every}")
    placements = [p.strip() for p in args.placements.split(",") if p.strip()]
    if not placements:
        parser.error(f"--placements: none; known: {', '.join(PLACEMENTS)}, or X:YAW")
    for placement in placements:
        try:
            placement_named(placement)
        except ConfigError as exc:
            parser.error(f"--placements: {exc}")
    recordings = sorted(args.recordings.glob("*.txt")) if args.recordings.is_dir() else []
    if args.only is not None:
        recordings = [r for r in recordings if r.stem in set(args.only)]
    if not recordings:
        parser.error(f"no recordings (*.txt) in {args.recordings}" + (f" named {args.only}" if args.only else ""))
    out = args.out or Path(tempfile.mkdtemp(prefix="real-people-"))
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    header = ["recording", "placement", "shuttles/min", "with the last leg's part", "stopped", "stale data",
              "violations (monitor / recount / independent)",
              "unchecked", "dropouts", "velocity unknown (share, longest ms)",
              "speed-ups (all, velocity unknown, of those a command's)",
              "drive lag p99 ms",
              "machine stalls > 10 ms (count, longest ms)", "scaler silences (count, longest ms, joint states in it)",
              "events (machine: during or just after a stall)"]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header), flush=True)
    for placement in placements:
        for recording in recordings:
            try:
                motion = convert(recording, placement, out, args.every)
            except subprocess.CalledProcessError as exc:
                r = row(recording.stem, placement, {"error": f"conversion: {exc.stderr.strip()[-300:]}"})
            else:
                report = motion.with_name(motion.stem + (f"-latency{round(args.latency * 1e3)}ms" if args.latency
                                                         else ""))
                r = row(recording.stem, placement, run(motion, report, args.sim, args.paper_formula, args.config,
                                                       args.latency))
            rows.append(r)
            cells = [r["recording"], r["placement"]] + ([f"error: {r['error']}"] if r["error"] else
                     [_cell(r["shuttles_per_min"]), _cell(r["progress_per_min"]), _cell(r["stopped"], share=True),
                      _cell(r["stale_data"], share=True)]
                     + [_cell(r[k]) for k in ("violations", "unchecked", "dropouts")]
                     + [f"{_cell(r['velocity_unknown'][0], share=True)}, {_cell(r['velocity_unknown'][1])}"]
                     + [", ".join(_cell(v) for v in r["speedups"]), _cell(r["drive_lag_p99_ms"])]
                     + [f"{_cell(r['machine'][0])}, {_cell(r['machine'][1])}"]
                     + [", ".join(_cell(v) for v in r["scaler_silences"])]
                     + [event_cell(r)])
            print("| " + " | ".join(cells) + " |", flush=True)
    summary = means(rows)
    for placement, m in summary.items():
        print(f"{placement}: {m['shuttles_per_min']} shuttles/min ({_cell(m['progress_per_min'])} with the last "
              f"leg's part) over {m['runs']} runs ({m['failed']} failed), "
              f"violations {_cell(m['violations'])}, unchecked {_cell(m['unchecked'])}, "
              f"speed-ups {', '.join(_cell(v) for v in m['speedups'])} (all, velocity unknown, a command's), "
              f"no shuttle done: {', '.join(m['held']) or 'none'}")
    print(f"reports in {out}")
    print(json.dumps({"rows": rows, "means": summary, "sim": args.sim, "paper_formula": args.paper_formula,
                      "every": args.every, "latency_s": args.latency,
                      "config": None if args.config is None else str(args.config)}))
    return 0 if all(r["error"] is None for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
