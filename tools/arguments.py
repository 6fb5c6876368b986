"""The ``hrc`` command line's arguments: one function per command, each adding its parser and options.

Kept apart from tools.cli (which runs the commands) so that each command's options read as one block."""

from __future__ import annotations

import argparse
from pathlib import Path

from shared.robot.poses import PAPER_GOAL, PAPER_START
from shared.transport.pki import DEFAULT_HOSTS

DESCRIPTION = """\
Safety-aware kinodynamic control of a Pilz PRBT next to people (ISO/TS 15066 speed and separation
monitoring). Subcommands:

  hrc demo        run the paper's experiment: the PRBT shuttles between two poses while a scripted
                  human goes through four phases (far, approaching, arm in the path, very close); the
                  scaling layer keeps every link below its ISO/TS 15066 speed limit and the planning
                  layer replans around the arm (--no-beta: without the replan requests, as in the
                  paper's ablation; --no-planner: scaling only).
  hrc up / hrc down              start / stop the whole cell (PRBT emulator and every service) under
                                 supervisord; without kernel CAN inside a private network namespace
  hrc goal Q1 .. Q6 | NAME      send a goal configuration (rad) or a named one (q_s, q_g, home) to
                                 the planner of a running cell (--then Q1 .. Q6 | NAME: the goal after
                                 it, whose plan the planner prepares while the robot is on its way)
  hrc human inject X Y Z ...     publish a human pose (a capsule) once, or moving at a velocity
  hrc human replay FILE          replay a recorded or scripted motion (CSV or JSON) at its own rate
  hrc status                     which services are alive, the robot, the scaler, the monitor
  hrc recover                    after a stop: ask the driver to reset and re-enable the drives
  hrc certs --out DIR            the cell CA and a certificate per service, for mutual TLS and the
                                 router's access control (several hosts; deploy/zenoh/secure-*.json5)
  hrc faults [--only F ..]       the fault campaign against a cell that is up: kill -9, SIGSTOP, CAN
                                 faults, tracker faults; stop times, violations, recovery (a table)
  hrc sweep --set KEY=V1,V2 ..   the strategies over many seeded scenarios in the simulation, per
                                 configuration value and kind, against the first value or another sweep
  hrc scenario KIND SEED         one of those scenarios taken apart: each strategy's arrivals, holds
                                 and planning decisions
The cell's commands reach it over Zenoh (--connect, default tcp/127.0.0.1:7447).
Run 'hrc <command> --help' for the options of one command."""

NAMED = {"q_s": PAPER_START.tolist(), "q_g": PAPER_GOAL.tolist(), "home": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]}


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {text!r}")
    return value


def sample_latency(text: str) -> float:
    """A source's latency (s) from capture to the cell: 0 up to OLDEST_SAMPLE (a sample older is stale)."""
    from shared.tracking.tracker import OLDEST_SAMPLE

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
    if not 0.0 <= value <= OLDEST_SAMPLE:
        raise argparse.ArgumentTypeError(f"expected 0 to {OLDEST_SAMPLE} s (a sample older than that is stale and "
                                         f"dropped), got {text!r}")
    return value


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return value


def cell_options(p: argparse.ArgumentParser) -> None:
    """The options of every command that talks to a running cell."""
    p.add_argument("--connect", default=None, metavar="ENDPOINT",
                   help="a Zenoh endpoint of the running cell (default: the port `hrc up` used, else "
                        "tcp/127.0.0.1:7447)")
    p.add_argument("--prefix", default="hrc/cell1", help="key prefix of the cell (default hrc/cell1)")
    p.add_argument("--timeout", type=_positive_float, default=3.0, metavar="SECONDS",
                   help="how long to wait for the cell (default 3)")



def _add_demo(sub) -> None:
    """hrc demo: the paper's experiment, on the processes or in the simulation."""
    demo = sub.add_parser("demo", help="run the paper's experiment on the built-in scenario",
                          description="Shuttle the PRBT between q_s and q_g next to a scripted human going "
                                      "through the paper's four phases. By default on the real processes: the "
                                      "PRBT emulator on CAN (vcan0, else udp_multicast in a private network "
                                      "namespace made for it) and every service over Zenoh; progress while it "
                                      "runs, then a report folder (--out): summary.json, a per-cycle trace "
                                      "(format: docs/report-format.md) and the paper's figures as PNG. --sim: "
                                      "both layers in-process on a simulated clock instead (deterministic, fast).",
                          formatter_class=argparse.RawDescriptionHelpFormatter)
    demo.add_argument("--duration", type=_positive_float, default=None, metavar="SECONDS",
                      help="seconds to run (default: 24, all four phases; with --human, the motion's length)")
    demo.add_argument("--human", type=Path, default=None, metavar="FILE",
                      help="a recorded or scripted motion (CSV or JSON, several people, dropouts; format in "
                           "docs/human-motion.md) in place of the paper's phases")
    demo.add_argument("--phase-length", type=_positive_float, default=6.0, metavar="SECONDS",
                      help="length of each of the four human phases (default 6)")
    demo.add_argument("--latency", type=sample_latency, default=0.0, metavar="SECONDS",
                      help="the person feed's latency: each sample reaches the cell this long after its capture and "
                           "is stamped with it, as a camera pipeline delivers skeletons; with --sim, both layers "
                           "are given each person that late (default 0)")
    demo.add_argument("--config", type=Path, default=None, metavar="FILE",
                      help="cell configuration YAML (default: built-in, same as deploy/cell.yaml)")
    demo.add_argument("--paper-formula", action="store_true",
                      help="the paper's configuration (deploy/cell-paper.yaml): its SSM formula (a person's measured "
                           "speed held over T_r + T_s) in place of the shipped model of a person who may speed "
                           "up, and its planner (no folded posture)")
    demo.add_argument("--scene", type=Path, default=None, metavar="FILE",
                      help="static cell (floor, table, fixtures) for the planner (default deploy/scene.yaml)")
    demo.add_argument("--no-beta", action="store_true",
                      help="do not replan when the scaling layer asks (alpha below alpha_min): the paper's ablation")
    demo.add_argument("--sim", action="store_true",
                      help="in-process on a simulated clock (no processes, no CAN, no Zenoh)")
    demo.add_argument("--no-planner", action="store_true", help="with --sim: scaling layer only, straight shuttles")
    demo.add_argument("--seed", type=int, default=1, help="seed of the planner's random sampling (default 1)")
    demo.add_argument("--out", type=Path, default=Path("hrc-demo-report"), metavar="DIR",
                      help="report folder (default ./hrc-demo-report)")
    demo.add_argument("--quiet", action="store_true", help="print only the summary")
    demo.add_argument("--view", action="store_true",
                      help="watch it live in 3D (rerun's web viewer on 127.0.0.1, --view-port); every report "
                           "folder holds recording.rrd anyway")
    demo.add_argument("--view-port", type=int, default=9090, help="web viewer port with --view (default 9090)")
    demo.add_argument("--view-fd", type=int, default=None, help=argparse.SUPPRESS)


def _add_up_down(sub) -> None:
    """hrc up and hrc down: the cell under supervisord."""
    upp = sub.add_parser("up", help="start the cell under supervisord",
                         description="Start the PRBT emulator and every service under supervisord "
                                     "(deploy/supervisord.conf). Without kernel CAN the bus is udp_multicast "
                                     "inside a private network namespace; the other hrc commands enter it.")
    upp.add_argument("--interface", default=None, help="CAN interface (default: socketcan on vcan0 if present, "
                                                        "else udp_multicast in a namespace)")
    upp.add_argument("--port", type=int, default=7447, help="first of six loopback ports (default 7447)")
    upp.add_argument("--prefix", default="hrc/cell1")
    upp.add_argument("--source-rate", type=float, default=None, metavar="HZ",
                     help="the people tracker's frame rate, where known (a 15 Hz camera: 15): tracker_ingest takes it "
                          "as the sample interval until it has measured one")
    upp.add_argument("--ros2", action="store_true",
                     help="also run the ROS 2 bridge: the cell as ROS 2 topics over rmw_zenoh, goals and people from "
                          "ROS 2 (the configuration's ros2 section; docs/ros2.md)")
    downp = sub.add_parser("down", help="stop the cell", description="Stop supervisord and every service.")
    downp.add_argument("--prefix", default="hrc/cell1")


def _add_goal_recover(sub) -> None:
    """hrc goal and hrc recover: an operator's requests to a running cell."""
    goal = sub.add_parser("goal", help="send a goal configuration to the planner",
                          description="Send a goal to the planner: six joint angles in rad, or one of "
                                      f"{', '.join(NAMED)}. Waits until the planner is reachable first.")
    goal.add_argument("q", nargs="+", metavar="Q", help="six joint angles (rad) or a name")
    goal.add_argument("--id", type=int, default=None, help="goal id (default: from the clock)")
    goal.add_argument("--then", nargs="+", metavar="Q", default=None,
                      help="the goal after this one, six joint angles (rad) or a name: the planner prepares its "
                           "plan while the robot is on its way, and the robot leaves at once when it is sent")
    cell_options(goal)
    recover = sub.add_parser("recover", help="ask the robot driver to reset and re-enable the drives",
                             description="After a stop (a stale command, a lost heartbeat, a drive fault, a "
                                         "restarted service) the driver holds the drives stopped until asked: "
                                         "this asks it to reset faults and enable again. It refuses while the "
                                         "cause is still there (see hrc status and the driver's events).")
    cell_options(recover)


def _add_human(sub) -> None:
    """hrc human inject / replay / from-keypoints: people for the tracker, and keypoints to capsules."""
    human = sub.add_parser("human", help="publish human poses to the tracker; convert keypoints to capsules")
    human_sub = human.add_subparsers(dest="human_command", metavar="<what>")
    inject = human_sub.add_parser("inject", help="one capsule, once or moving at a constant velocity",
                                  description="Publish a human capsule (end points A and B, radius) as raw tracker "
                                              "data, once, or moving at --velocity for --duration seconds at --rate Hz.")
    # a single-string metavar: argparse (3.11) fails on tuple metavars when it reports missing positionals
    inject.add_argument("a", nargs=3, type=float, metavar="A", help="capsule end A: x y z (m, base frame)")
    inject.add_argument("b", nargs=3, type=float, metavar="B", help="capsule end B: x y z (m)")
    inject.add_argument("--radius", type=_positive_float, default=0.06, help="capsule radius (m, default 0.06)")
    inject.add_argument("--velocity", type=float, nargs=3, default=None, metavar=("VX", "VY", "VZ"),
                        help="constant velocity (m/s) while --duration lasts")
    inject.add_argument("--duration", type=_positive_float, default=None, metavar="SECONDS")
    inject.add_argument("--rate", type=_positive_float, default=100.0, metavar="HZ")
    cell_options(inject)
    replay = human_sub.add_parser("replay", help="a recorded or scripted motion (CSV or JSON) at its own rate",
                                  description="Publish the frames of a motion file (docs/human-motion.md: "
                                              "CSV or JSON, several people, dropouts) as raw tracker data at "
                                              "their own times; nothing during a dropout frame.")
    replay.add_argument("file", type=Path, help="a .csv or .json motion file")
    replay.add_argument("--speed", type=_positive_float, default=1.0, help="playback speed factor (default 1)")
    replay.add_argument("--latency", type=sample_latency, default=0.0, metavar="SECONDS",
                        help="each frame reaches the cell this long after its capture, stamped with it (a camera's "
                             "latency, which the cell counts in the data's age; default 0)")
    cell_options(replay)
    fromkp = human_sub.add_parser("from-keypoints", help="3D body keypoints (CSV) to a motion file of capsules",
                                  description="Turn a CSV of 3D keypoints (t,person,keypoint,x,y,z: head, "
                                              "shoulders, elbows, hands, hips; or the arms alone: shoulders, "
                                              "elbows, hands) or a human-assembly recording (--format assembly) "
                                              "into a motion file of capsules (docs/human-motion.md), radii from "
                                              "DIN 33402-2's 95th percentiles. A person missing a keypoint makes "
                                              "a dropout frame.")
    fromkp.add_argument("input", type=Path, help="keypoints CSV, or a human-assembly recording")
    fromkp.add_argument("--format", choices=("keypoints", "assembly"), default="keypoints",
                        help="keypoints: the CSV above; assembly: 18 numbers a row (wrists, elbows, shoulders "
                             "xyz, m, a camera's optical frame), as the human-assembly recordings")
    fromkp.add_argument("--rate", type=_positive_float, default=None, metavar="HZ",
                        help="--format assembly: the recording's frame rate (default 30; the source gives none)")
    fromkp.add_argument("--camera", action="store_true",
                        help="the input is a camera's optical frame (x right, y down, z forward) facing the person: "
                             "turned so the person faces +x before --yaw (implied by --format assembly)")
    fromkp.add_argument("output", type=Path, help="motion file to write (.json or .csv)")
    fromkp.add_argument("--units", choices=("m", "cm", "mm"), default="m", help="input length unit (default m)")
    fromkp.add_argument("--y-up", action="store_true", help="the capture volume's vertical axis is y (else z)")
    fromkp.add_argument("--yaw", type=float, default=0.0, metavar="DEG",
                        help="rotation about the vertical axis into the robot base frame (degrees)")
    fromkp.add_argument("--translate", type=float, nargs=3, default=(0.0, 0.0, 0.0), metavar=("X", "Y", "Z"),
                        help="then this translation (m, robot base frame)")
    fromkp.add_argument("--every", type=_positive_int, default=1, metavar="N",
                        help="keep every N-th frame, at its own time: the same person as a tracker at 1/N the "
                             "rate sees them (a 30 Hz recording with --every 2: a 15 Hz camera; default 1)")


def _add_view(sub) -> None:
    """hrc view: the running cell in 3D."""
    view = sub.add_parser("view", help="the running cell in 3D (rerun), served on loopback",
                          description="A live 3D view of a running cell with rerun: the robot's link capsules "
                                      "at the measured joint state and the commanded ghost, every person's "
                                      "capsules, the robot-human pair nearest its ISO/TS 15066 limit with its "
                                      "approach speed against the limit, alpha and beta over time, the planner's "
                                      "current and merged trajectories. A Zenoh subscriber of its own (a slow "
                                      "viewer slows nothing else); the web viewer listens on 127.0.0.1 only.")
    view.add_argument("--web-port", type=int, default=9090, help="web viewer port on 127.0.0.1 (default 9090)")
    view.add_argument("--grpc-port", type=int, default=9876, help="viewer's gRPC port on 127.0.0.1 (default 9876)")
    view.add_argument("--save", type=Path, default=None, metavar="FILE",
                      help="write the view to an .rrd file instead of serving it (open it later with `rerun FILE`)")
    view.add_argument("--duration", type=_positive_float, default=None, metavar="SECONDS",
                      help="stop after this long (default: until Ctrl-C)")
    view.add_argument("--pipe-fd", type=int, default=None, help=argparse.SUPPRESS)
    cell_options(view)


def _add_certs(sub) -> None:
    """hrc certs: the cell's TLS certificates."""
    certs = sub.add_parser("certs", help="make the cell's TLS certificates (multi-host, secured)",
                           description="Make the cell CA and one certificate per identity (every service, "
                                       "operator, router) for mutual TLS and the router's access control "
                                       "(deploy/zenoh/secure-router.json5). Copy to each host the CA and only "
                                       "its own key; keep ca-key.pem off the cell.")
    certs.add_argument("--out", type=Path, required=True, metavar="DIR", help="where to write the PEM files")
    certs.add_argument("--hosts", nargs="+", default=list(DEFAULT_HOSTS), metavar="HOST",
                       help="names and addresses the certificates are valid for (the router's; default loopback)")


def _add_faults(sub) -> None:
    """hrc faults: the fault campaign."""
    faults = sub.add_parser("faults", help="the fault campaign against a running cell (hrc up)",
                            description="As the cell's operator (goals, a scripted person, recovery), inject each "
                                        "fault while the robot moves: kill -9 and SIGSTOP of services, lost CAN "
                                        "frames, a stopped heartbeat, a silent or NaN tracker, a person who jumps. "
                                        "For each: time to stop against its bound, violations (the monitor's and "
                                        "against the true person), the service back, the task resumed. Prints a "
                                        "JSON line per fault and a table.")
    faults.add_argument("--only", nargs="+", default=None, metavar="FAULT",
                        help="these faults only (default: all, in order)")
    faults.add_argument("--out", type=Path, default=None, metavar="DIR", help="write faults.json and faults.md here")
    faults.add_argument("--trace", action="store_true", help="with --out: write the campaign's trace (every message, "
                        "trace/) even when every verdict holds (it is written whenever one fails)")
    faults.add_argument("--config", type=Path, default=None, metavar="FILE", help="the cell configuration the "
                        "services run with (default: built in)")
    cell_options(faults)


def _add_sweep(sub) -> None:
    """hrc sweep: a grid of configuration values over seeded scenarios, on a local pool or Dask."""
    sweep = sub.add_parser("sweep", help="throughput against configuration values, over many seeded scenarios",
                           description="Simulate every combination of the configuration values given (--set, or a "
                                       "grid file) with every strategy on the same seeded scenarios, on a local "
                                       "process pool or dask.distributed (--dask). Each chunk of scenarios is a "
                                       "Parquet file under --out/records as it finishes; running the same sweep "
                                       "again skips the chunks already there (resume after a crash or a lost "
                                       "worker). Without --set, one point: the configuration as shipped. Prints "
                                       "progress, one line per grid point and per kind, every point against the "
                                       "first (and, with --against, against another sweep), scenario by scenario; "
                                       "writes summary.json, sweep.csv, sweep-kinds.csv and one plot per key "
                                       "(docs/sweeps.md).")
    sweep.add_argument("--set", action="append", default=[], metavar="KEY=V1,V2,...", dest="values",
                       help="a configuration key and its values, e.g. ssm.reaction_time=0.1,0.15,0.2 (repeat for "
                            "a grid of several keys)")
    sweep.add_argument("--grid", type=Path, default=None, metavar="FILE",
                       help="a YAML grid: set: {KEY: [values]}, and optionally strategies, kinds, scenarios, "
                            "duration, seed (the options below override it)")
    sweep.add_argument("--strategies", default=None, help="comma-separated (default scale_only,full)")
    sweep.add_argument("--kinds", default=None, help="comma-separated scenario kinds, in turn (default: all)")
    sweep.add_argument("--scenarios", type=int, default=None, help="seeded scenarios per grid point (default 20)")
    sweep.add_argument("--duration", type=_positive_float, default=None, metavar="SECONDS",
                       help="simulated seconds per scenario (default 12)")
    sweep.add_argument("--seed", type=int, default=None, help="first scenario seed (default 0)")
    sweep.add_argument("--out", type=Path, default=Path("hrc-sweep"), metavar="DIR",
                       help="output folder (default ./hrc-sweep); the same folder resumes the same sweep")
    sweep.add_argument("--forecaster", default=None, metavar="MODULE:ATTRIBUTE",
                       help="the full strategy's forecast of the people: a researcher's forecaster object, class or "
                            "factory (shared.planning.forecast.load_forecaster; default: constant velocity)")
    sweep.add_argument("--latency", type=sample_latency, default=None, metavar="SECONDS",
                       help="the people reach the cell this long after their capture (a camera pipeline's), in every "
                            "run; the zones are sized for it (default 0, or the grid file's latency)")
    sweep.add_argument("--against", type=Path, default=None, metavar="DIR",
                       help="another sweep's folder (the same grid run by other code: a commit, a worktree): every "
                            "point's ratios against the same point there, scenario by scenario, per kind")
    sweep.add_argument("--workers", type=int, default=2, help="local processes (default 2)")
    sweep.add_argument("--chunk", type=int, default=8, help="runs per chunk, a Parquet file each (default 8)")
    sweep.add_argument("--dask", nargs="?", const="local", default=None, metavar="tcp://SCHEDULER:8786",
                       help="run on dask.distributed: this scheduler, or without an address a LocalCluster of "
                            "--workers processes")


def _add_scenario(sub) -> None:
    """hrc scenario: one seeded scenario of a sweep, each strategy's run taken apart."""
    scenario = sub.add_parser("scenario", help="one seeded scenario of a sweep taken apart, strategy by strategy",
                              description="Simulate one seeded scenario as hrc sweep does (the same figures to the "
                                          "digit) with each strategy, and print what each did: shuttles, time "
                                          "stopped and slowed, the arrivals at the goals, the spans held below "
                                          "alpha_min, and every planning decision with its reason (a replan taken "
                                          "or refused with both predicted times). For the seeds a sweep names as "
                                          "most lost (docs/sweeps.md).")
    scenario.add_argument("kind", help="the scenario kind (paper, crossing, standing, two_humans, random_walk, "
                                       "real_table_edge, real_step_back, real_around)")
    scenario.add_argument("seed", type=int, help="its seed, as the sweep names it")
    scenario.add_argument("--strategies", default="full,fixed_path", help="comma-separated (default full,fixed_path)")
    scenario.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="values",
                          help="a configuration value, as the sweep's point had it (repeat for several), e.g. "
                               "ssm.human_acceleration=0")
    scenario.add_argument("--duration", type=_positive_float, default=12.0, metavar="SECONDS",
                          help="simulated seconds (default 12, as hrc sweep)")
    scenario.add_argument("--forecaster", default=None, metavar="MODULE:ATTRIBUTE",
                          help="the full strategy's forecast of the people, as the sweep had it")
    scenario.add_argument("--latency", type=sample_latency, default=0.0, metavar="SECONDS",
                          help="the people this long after their capture, as the sweep had it (default 0)")


def _add_report(sub) -> None:
    """hrc report: more out of a report folder."""
    report = sub.add_parser("report", help="write more into an hrc demo report folder (a ROS 2 bag of an older run)",
                            description="Read an hrc demo report folder back (trace.csv, humans.csv, events.csv) and "
                                        "write what an older run lacks: --mcap, recording.mcap and metadata.yaml "
                                        "(a rosbag2 bag; docs/ros2.md).")
    report.add_argument("folder", type=Path, help="an hrc demo report folder")
    report.add_argument("--mcap", action="store_true", help="write recording.mcap and metadata.yaml")
    report.add_argument("--config", type=Path, default=None, metavar="FILE",
                        help="the cell configuration the run had, for the bag's metadata (default: the built-in "
                             "one; deploy/cell-paper.yaml for a run with --paper-formula)")


def _add_status(sub) -> None:
    """hrc status: what the running cell is doing."""
    status = sub.add_parser("status", help="what the running cell is doing",
                            description="Listen to the cell until each of its reports has come once (at most "
                                        "--timeout seconds) and report which services are alive, the robot's state, "
                                        "the scaler and the safety monitor.")
    cell_options(status)


def build_parser() -> argparse.ArgumentParser:
    """The whole command line: every command's parser under one top-level parser."""
    parser = argparse.ArgumentParser(prog="hrc", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", metavar="<command>")
    _add_demo(sub)
    _add_up_down(sub)
    _add_goal_recover(sub)
    _add_human(sub)
    _add_view(sub)
    _add_certs(sub)
    _add_faults(sub)
    _add_sweep(sub)
    _add_scenario(sub)
    _add_report(sub)
    _add_status(sub)
    return parser
