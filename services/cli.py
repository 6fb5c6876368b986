"""``hrc``: the command line of the HRC cell.

Thin: it parses arguments, calls the cores or the services, and prints. Bad arguments give a clear
message and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from shared.errors import HrcError

DESCRIPTION = """\
Safety-aware kinodynamic control of a Pilz PRBT next to people (ISO/TS 15066 speed and separation
monitoring). Subcommands:

  hrc demo        run the paper's experiment: the PRBT shuttles between two poses while a scripted
                  human goes through four phases (far, approaching, arm in the path, very close); the
                  scaling layer keeps every link below its ISO/TS 15066 speed limit and the planning
                  layer replans around the arm (--no-beta: without the replan requests, as in the
                  paper's ablation; --no-planner: scaling only).
Run 'hrc <command> --help' for the options of one command."""


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {text!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="hrc", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", metavar="<command>")
    demo = sub.add_parser("demo", help="run the paper's experiment on the built-in scenario",
                          description="Shuttle the PRBT between q_s and q_g next to a scripted human going "
                                      "through the paper's four phases, in-process on a simulated clock; "
                                      "print progress and a JSON summary (and write it with --out).")
    demo.add_argument("--duration", type=_positive_float, default=24.0, metavar="SECONDS",
                      help="simulated seconds to run (default 24: all four phases)")
    demo.add_argument("--phase-length", type=_positive_float, default=6.0, metavar="SECONDS",
                      help="length of each of the four human phases (default 6)")
    demo.add_argument("--config", type=Path, default=None, metavar="FILE",
                      help="cell configuration YAML (default: built-in, same as deploy/cell.yaml)")
    demo.add_argument("--scene", type=Path, default=None, metavar="FILE",
                      help="static cell (floor, table, fixtures) for the planner (default deploy/scene.yaml)")
    demo.add_argument("--no-beta", action="store_true",
                      help="do not replan when the scaling layer asks (alpha below alpha_min)")
    demo.add_argument("--no-planner", action="store_true", help="scaling layer only: straight shuttles")
    demo.add_argument("--seed", type=int, default=1, help="seed of the planner's random sampling (default 1)")
    demo.add_argument("--out", type=Path, default=None, metavar="DIR",
                      help="write summary.json into this folder")
    demo.add_argument("--quiet", action="store_true", help="print only the summary")
    return parser


DEFAULT_SCENE = Path(__file__).resolve().parents[1] / "deploy" / "scene.yaml"


def _scene(path: Path | None):
    """The given scene file, else the shipped deploy/scene.yaml, else a bare floor (said on stderr)."""
    from shared.scene import Scene, load_scene

    if path is not None:
        return load_scene(path)
    if DEFAULT_SCENE.exists():
        return load_scene(DEFAULT_SCENE)
    print(f"hrc: no {DEFAULT_SCENE}; planning with a bare floor at z = 0", file=sys.stderr)
    return Scene(floor_z=0.0)


def cmd_demo(args: argparse.Namespace) -> int:
    from shared.config import load_config
    from shared.robot_model import default_robot
    from shared.scenarios import Q_GOAL, Q_START, paper_phases
    from shared.sim import run_shuttle

    config = load_config(args.config)
    robot = default_robot()
    human = paper_phases(args.phase_length)
    replanner = None
    if not args.no_planner:
        from shared.collision import CollisionModel
        from shared.planner import JointPlanner, PlannerOptions
        from shared.replanning import Replanner

        collision = CollisionModel(robot, _scene(args.scene), config.ssm.min_separation)
        replanner = Replanner(collision, JointPlanner(collision, PlannerOptions(seed=args.seed)), config.ssm)
    every = max(1, int(round(0.5 / config.scaling.period)))
    count = [0]

    def progress(record) -> None:
        count[0] += 1
        if args.quiet or count[0] % every:
            return
        s = record.step
        sep = f"{s.min_separation:5.2f}" if s.min_separation != float("inf") else "  -  "
        print(f"t={record.t:6.2f}s  {record.phase:<20} alpha={s.alpha:4.2f} safe={s.safe_alpha:4.2f} "
              f"beta={int(s.beta)}  sep={sep} m  shuttles={record.shuttles}  cycle={s.compute_us:6.1f} us",
              flush=True)

    if not args.quiet:
        layers = "scaling layer only" if replanner is None else \
            "scaling + planning layers" + (" (no beta replans)" if args.no_beta else "")
        print(f"hrc demo: {layers} on the built-in scenario (in-process, simulated clock)")

    def replanned(event) -> None:
        if not args.quiet:
            state = "replanned" if event.ok else "replan refused"
            print(f"t={event.t:6.2f}s  {state} ({event.reason}) in {event.compute_ms:.0f} ms  {event.detail[:100]}",
                  flush=True)

    result = run_shuttle(robot, config, human, Q_START, Q_GOAL, args.duration, progress, replanner,
                         beta_replans=not args.no_beta, on_replan=replanned)
    summary = result.summary()
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps(summary))
    return 0 if summary["violations"] == 0 else 1


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    try:
        return {"demo": cmd_demo}[args.command](args)
    except HrcError as exc:
        print(f"hrc {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
