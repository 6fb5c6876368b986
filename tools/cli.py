"""``hrc``: the command line of the HRC cell.

Thin: it parses arguments, calls the cores or the services, and prints. Bad arguments give a clear
message and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
from pathlib import Path

from shared.core.errors import ConfigError, HrcError
from tools.arguments import NAMED, build_parser

PAPER_CONFIG = Path(__file__).resolve().parents[1] / "deploy" / "cell-paper.yaml"   # the paper's formula
ROBOT_WAIT = 0.3        # s: how long `hrc goal` waits for a joint state to say whether the robot runs (100 Hz)


def _scene(path: Path | None):
    """The given scene file, else the shipped deploy/scene.yaml; a missing one is refused (ConfigError, naming it)."""
    from shared.planning.scene import DEFAULT_SCENE, load_scene

    return load_scene(path or DEFAULT_SCENE)


def cmd_demo(args: argparse.Namespace) -> int:
    human = None
    if args.paper_formula:
        if args.config is not None:
            raise UsageError("--paper-formula is a configuration (deploy/cell-paper.yaml): give it or --config")
        args.config = PAPER_CONFIG
    if args.human is not None:
        from shared.tracking.motion import RecordedMotion

        human = RecordedMotion.load(args.human)        # a bad file: ConfigError naming the frame, nothing starts
    if args.duration is None:
        args.duration = max(human.duration, 1.0) if human is not None else 24.0
    if not args.sim:
        return _demo_processes(args)
    return _demo_sim(args, human)


def _demo_processes(args: argparse.Namespace) -> int:
    from shared.config import load_config
    from shared.robot.model import default_robot
    from tools import demo
    from tools.launch import free_port

    if args.no_planner:
        raise UsageError("--no-planner needs --sim (the running cell always has its planner)")
    if args.scene is not None:
        raise UsageError("--scene needs --sim (the planner service reads deploy/scene.yaml)")
    config = load_config(args.config)              # a bad file is refused here, before anything starts
    server = None
    if args.view and args.view_fd is None:         # the viewer is served here, on this side of any namespace
        from tools.view import ViewServer

        _check_port("--view-port", args.view_port)
        server = ViewServer(free_port(), args.view_port)
        args.view_fd = server.write_fd
        print(f"hrc demo: watch it at {server.web_url} (listening on 127.0.0.1 only)", flush=True)
    try:
        fds = () if server is None else (server.write_fd,)
        argv = [sys.executable, "-m", "tools.cli", *args.argv] + ([] if server is None else
                                                                      ["--view-fd", str(server.write_fd)])
        try:
            code = demo.reexec_in_namespace(argv, fds)
        except RuntimeError as exc:
            print(f"hrc demo: error: {exc}", file=sys.stderr)
            return 1
        if code is not None:
            return code
        try:
            summary = demo.run(args.out, args.duration, args.phase_length, args.config, args.seed, args.no_beta,
                               args.quiet, default_robot(), config, args.human, args.view_fd, args.latency)
        except RuntimeError as exc:
            print(f"hrc demo: error: {exc}", file=sys.stderr)
            return 1
    finally:
        if server is not None:
            server.stop()
    from tools import silences, stalls
    from tools.report import plain_json, reaction_said, stale_said

    for line in (stalls.said(summary.get("machine") or {}), silences.said(summary.get("scaler_silences") or {}),
                 stale_said(summary.get("tracker") or {}), reaction_said(summary)):
        if line is not None:
            print(f"hrc demo: {line}")
    accepted = sum(1 for e in summary["replans"] if e["ok"])
    print(json.dumps({k: v for k, v in summary.items() if k not in ("replan_stall_ms", "replans")}
                     | {"replans_accepted": accepted, "replans_refused": len(summary["replans"]) - accepted,
                        "replan_stall_ms": {k: summary["replan_stall_ms"][k] for k in ("median", "max", "goal_blocked")}},
                     default=plain_json))
    print(f"hrc demo: report in {args.out}/ (summary.json, trace.csv, figures: {', '.join(summary['figures'])})")
    if summary["violations"] is None:
        print("hrc demo: error: no summary from the safety monitor", file=sys.stderr)
        return 1
    return 0 if summary["violations"] == 0 else 1


def _demo_sim(args: argparse.Namespace, human) -> int:
    if args.view:
        raise UsageError("--view needs the processes (without --sim); a --sim run is its summary only")
    from evidence.scenarios import Q_GOAL, Q_START, paper_phases
    from evidence.sim import run_shuttle
    from shared.config import load_config
    from shared.robot.model import default_robot

    config = load_config(args.config)
    robot = default_robot()
    if human is not None:           # a motion file reaches the layers through the cell's tracker, as on the processes
        from shared.tracking.tracked import TrackedMotion

        human = TrackedMotion(human)
    else:
        human = paper_phases(args.phase_length)
    replanner = None
    if not args.no_planner:
        from shared.planning.collision import CollisionModel
        from shared.planning.ompl_planner import JointPlanner, PlannerOptions
        from shared.planning.replanner import Replanner

        collision = CollisionModel(robot, _scene(args.scene), config.ssm.min_separation)
        from shared.planning.options import ReplanOptions

        # the planner service's seeds (services/planner.py): OMPL's and the path search's, so that --sim is the
        # processes' planning layer, not one that draws other random detours
        replanner = Replanner(collision, JointPlanner(collision, PlannerOptions(seed=args.seed)), config.ssm,
                              options=ReplanOptions(seed=args.seed or 0, **config.planning.replan_fields()),
                              scaling=config.scaling)
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
        scenario = f"the motion in {args.human}" if args.human else "the built-in scenario"
        print(f"hrc demo --sim: {layers} on {scenario} (in-process, simulated clock)")

    def replanned(event) -> None:
        if not args.quiet:
            state = "replanned" if event.ok else "replan refused"
            print(f"t={event.t:6.2f}s  {state} ({event.reason}) in {event.compute_ms:.0f} ms  {event.detail}",
                  flush=True)     # whole: a refusal's figures (both predicted times) come at its end

    # each path search charged the planner service's budget on the simulated clock, as the benchmarks charge it
    # (evidence.strategies): plans free of time made the simulation kinder than the cell where the robot replans often
    from shared.planning.path_search import CELL_BUDGET

    result = run_shuttle(robot, config, human, Q_START, Q_GOAL, args.duration, progress, replanner,
                         beta_replans=not args.no_beta, on_replan=replanned, charge_planning=CELL_BUDGET,
                         latency=args.latency)
    summary = result.summary()
    from tools.report import reaction_said, stale_said

    for line in (stale_said(summary["tracker"]), reaction_said(summary)):
        if line is not None:
            print(f"hrc demo --sim: {line}")
    if args.out is not None:
        from tools.mcap_record import recording_from_sim
        from tools.report import write_bag

        args.out.mkdir(parents=True, exist_ok=True)
        summary["ros2_bag"] = write_bag(args.out, robot, config, recording_from_sim(result, human))
        (args.out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps(summary))
    return 0 if summary["violations"] == 0 else 1


def _session(args: argparse.Namespace):
    from shared.transport.zenoh_session import open_session
    from shared.wire.keys import KeySpace
    from tools.cell import cell_endpoint

    if args.connect is None:
        args.connect = cell_endpoint(args.prefix)
    keys = KeySpace(args.prefix)
    return open_session("peer", connect=[args.connect]), keys


def cmd_up(args: argparse.Namespace) -> int:

    from tools.cell import choose_bus, run_dir, up
    from tools.programs import source_rate_args

    interface = args.interface or choose_bus()[0]
    if not 1024 <= args.port <= 65530:
        print(f"hrc up: error: --port must be in 1024..65530, got {args.port}", file=sys.stderr)
        return 2
    from shared.tracking.tracker import SOURCE_RATES, declarable

    if args.source_rate is not None and not declarable(args.source_rate):
        print(f"hrc up: error: --source-rate must be within [{SOURCE_RATES[0]:g}, {SOURCE_RATES[1]:g}] Hz, got "
              f"{args.source_rate}", file=sys.stderr)
        return 2
    try:
        pid = up(args.prefix, interface, args.port, ("ros2_bridge",) if args.ros2 else (),
                 source_rate_args(args.source_rate))
    except RuntimeError as exc:
        print(f"hrc up: error: {exc}", file=sys.stderr)
        return 1
    bridge = f"; ROS 2 bridge on tcp/127.0.0.1:{args.port + 5}" if args.ros2 else ""
    print(f"hrc up: cell {args.prefix} starting under supervisord (pid {pid}, CAN {interface}, Zenoh "
          f"tcp/127.0.0.1:{args.port}{bridge}); logs in {run_dir(args.prefix)}; `hrc status` to follow it")
    return 0


def cmd_down(args: argparse.Namespace) -> int:
    from tools.cell import down

    if not down(args.prefix):
        print(f"hrc down: no running cell {args.prefix}", file=sys.stderr)
        return 1
    print(f"hrc down: cell {args.prefix} stopped")
    return 0


@contextlib.contextmanager
def _client(args: argparse.Namespace, service: str | None = None):
    """The Zenoh session of one client command (`hrc goal`, `recover`, `human`, `status`): (session, keys), once
    `service` is reachable (None: at once); Unreachable when it is not within args.timeout. Closed however the
    command ends."""
    from shared.transport.zenoh_session import await_liveliness

    session, keys = _session(args)
    try:
        if service is not None and not await_liveliness(session, keys.alive(service), args.timeout):
            raise Unreachable(f"no {service} reachable at {args.connect} within {args.timeout:.0f} s")
        yield session, keys
    finally:
        session.close()


def cmd_goal(args: argparse.Namespace) -> int:
    import time

    import numpy as np
    import zenoh

    from shared.robot.model import default_robot
    from shared.wire.messages import Goal, JointState, encode

    lim = default_robot().limits

    def configuration(values: list[str], what: str) -> tuple[str, np.ndarray]:
        """(name, q) of six angles or a name on the command line; GoalArgumentError saying what is wrong."""
        if len(values) == 1 and values[0] in NAMED:
            name, q = values[0], np.array(NAMED[values[0]])
        elif len(values) == 6:
            try:
                q = np.array([float(v) for v in values])
            except ValueError:
                raise GoalArgumentError(f"{what}: joint angles must be numbers, got {' '.join(values)}") from None
            name = ""
        else:
            raise GoalArgumentError(f"{what}: give six joint angles (rad) or one of {', '.join(NAMED)}, "
                                    f"got {' '.join(values)}")
        if not np.all(np.isfinite(q)) or not lim.within(q):
            raise GoalArgumentError(f"{what} outside the joint limits "
                                    f"(+-{', '.join(f'{u:.3f}' for u in lim.upper)} rad)")
        return name, q

    name, q = configuration(args.q, "goal")
    then = np.zeros((0, 6)) if args.then is None else configuration(args.then, "--then")[1][None]
    with _client(args, "planner") as (session, keys):
        robot = session.declare_subscriber(keys.joint_state, zenoh.handlers.RingChannel(1))
        goal_id = args.id if args.id is not None else int(time.time() * 1000) % (2 ** 31)
        session.put(keys.goal, encode(Goal(goal_id=goal_id, name=name, q=q, then=then, stamp=time.monotonic())))
        state = _newest(robot, JointState, ROBOT_WAIT)
        robot.undeclare()
    print(f"hrc goal: sent goal {goal_id} {name or ''} {np.round(q, 4).tolist()}".replace("  ", " "))
    if state is None:
        print(f"hrc goal: no joint state from the robot driver within {ROBOT_WAIT:.1f} s: the goal is planned once "
              "the robot's position is known")
    elif not state.enabled:
        print(f"hrc goal: the robot is {state.drive_state}: the goal is planned again once it runs (`hrc status` "
              "says why it stopped; `hrc recover` once its cause is gone)")
    return 0


def _newest(subscriber, kind, wait: float):
    """The newest well-formed message of `kind` a ring subscriber holds within `wait` s (None: none came)."""
    import time

    from shared.core.errors import MessageError
    from shared.wire.messages import decode

    deadline = time.monotonic() + wait
    while time.monotonic() < deadline:
        sample = subscriber.try_recv()
        if sample is not None:
            try:
                return decode(sample.payload.to_bytes(), kind)
            except MessageError:
                pass
        time.sleep(0.01)
    return None


def cmd_recover(args: argparse.Namespace) -> int:
    import time

    from shared.wire.messages import DriverRequest, encode

    with _client(args, "robot_driver") as (session, keys):
        session.put(keys.driver_request, encode(DriverRequest(action="recover", source="hrc recover",
                                                              stamp=time.monotonic())))
    print("hrc recover: asked the robot driver to reset and re-enable the drives")
    return 0


def cmd_human(args: argparse.Namespace) -> int:

    import numpy as np


    if args.human_command == "replay":
        return _replay(args)
    if args.human_command == "from-keypoints":
        return _from_keypoints(args)
    if args.human_command != "inject":
        print("hrc human: error: choose what to do: 'hrc human inject ...', 'hrc human replay FILE' or "
              "'hrc human from-keypoints IN OUT'", file=sys.stderr)
        return 2
    a, b = np.array(args.a), np.array(args.b)
    velocity = np.zeros(3) if args.velocity is None else np.array(args.velocity)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b)) and np.all(np.isfinite(velocity))):
        print("hrc human inject: error: positions and velocity must be finite numbers", file=sys.stderr)
        return 2
    if args.velocity is not None and args.duration is None:
        print("hrc human inject: error: --velocity needs --duration", file=sys.stderr)
        return 2
    from tools.actors import MovingCapsule

    return _feed(args, "inject", MovingCapsule(a, b, args.radius, velocity), rate=args.rate,
                 until=0.0 if args.duration is None else args.duration)


def _feed(args: argparse.Namespace, what: str, human, rate: float | None = None, speed: float = 1.0,
          until: float | None = None, latency: float = 0.0) -> int:
    """Send `human` as raw tracker data once tracker_ingest is reachable (exit 1 if it is not), by the demo's own
    feed (tools.actors.HumanFeed: each sample at its time, a late one skipped, never a burst), in SCHED_FIFO
    below the safety chain where the machine allows it, as a camera outside the machine; then its figures."""
    import time

    from shared.scheduling import realtime
    from tools.actors import HumanFeed

    with _client(args, "tracker_ingest") as (session, keys):
        human.at(0.0)                                 # its first evaluation before SCHED_FIFO, not under it
        scheduling = realtime("human_feed")
        feed = HumanFeed(session, keys, human, time.monotonic(), source=f"hrc {what}", rate=rate, speed=speed,
                         until=until, latency=latency)
        print(f"hrc human {what}: sending at {feed.rate:.1f} Hz, {scheduling}", flush=True)
        try:
            feed.run()                                # this thread, to the motion's end
        except KeyboardInterrupt:
            feed.running = False
        figures = feed.figures()
    late = "" if figures["late_ms_max"] is None else \
        f", woke late p99 {figures['late_ms_p99']} ms, max {figures['late_ms_max']} ms"
    print(f"hrc human {what}: published {figures['sent']} pose(s), {figures['skipped']} skipped{late}"
          + ("" if feed.finished else " (stopped)"))
    return 0 if feed.finished else 130


def _from_keypoints(args: argparse.Namespace) -> int:
    import math

    from shared.tracking.keypoints import ASSEMBLY_RATE, UNITS, FrameTransform, convert

    if not all(math.isfinite(v) for v in (args.yaw, *args.translate)):
        print("hrc human from-keypoints: error: --yaw and --translate must be finite numbers", file=sys.stderr)
        return 2
    assembly = args.format == "assembly"
    if args.rate is not None and not assembly:
        print("hrc human from-keypoints: error: --rate is for --format assembly (a keypoints CSV has its times)",
              file=sys.stderr)
        return 2
    transform = FrameTransform(UNITS[args.units], args.y_up, math.radians(args.yaw), tuple(args.translate),
                               camera=args.camera or assembly)
    frames, dropouts = convert(args.input, args.output, transform, args.format,   # ConfigError: exit 2 (main)
                               args.rate or ASSEMBLY_RATE, every=args.every)
    print(f"hrc human from-keypoints: {frames} frames ({dropouts} dropouts) written to {args.output}")
    return 0


def _replay(args: argparse.Namespace) -> int:
    from shared.tracking.motion import RecordedMotion

    motion = RecordedMotion.load(args.file)      # ConfigError: a clear message and exit 2 (main)
    return _feed(args, "replay", motion, speed=args.speed, until=motion.duration,   # a dropout: silence
                 latency=args.latency)


def _check_port(name: str, port: int) -> None:
    if not 1024 <= port <= 65535:
        raise UsageError(f"{name} must be in 1024..65535, got {port}")


def cmd_view(args: argparse.Namespace) -> int:
    """Serve the viewer on loopback here and log into it from a subscriber (inside the cell's network
    namespace when it has one: the pipe between the two crosses it)."""
    import os
    import subprocess

    from tools.cell import reenter_argv
    from tools.view import ViewServer

    if args.pipe_fd is not None:
        return _view_log(args)
    if args.save is not None:               # logging to a file: here, or inside the cell's namespace
        inner = None if os.environ.get("HRC_IN_CELL") else reenter_argv(
            args.prefix, [sys.executable, "-m", "tools.cli", *args.argv])
        if inner is None:
            return _view_log(args)
        return subprocess.call(inner, env=dict(os.environ, HRC_IN_CELL="1"))
    _check_port("--web-port", args.web_port)
    _check_port("--grpc-port", args.grpc_port)
    server = ViewServer(args.grpc_port, args.web_port)
    argv = [sys.executable, "-m", "tools.cli", "view", "--pipe-fd", str(server.write_fd), "--prefix", args.prefix,
            "--timeout", str(args.timeout)] + (["--connect", args.connect] if args.connect else []) \
        + (["--duration", str(args.duration)] if args.duration else [])
    inner = reenter_argv(args.prefix, argv) or argv
    print(f"hrc view: open {server.web_url} (listening on 127.0.0.1 only); Ctrl-C to stop", flush=True)
    child = subprocess.Popen(inner, pass_fds=(server.write_fd,), env=dict(os.environ, HRC_IN_CELL="1"))
    try:
        return child.wait()
    except KeyboardInterrupt:
        child.terminate()
        child.wait()
        return 130
    finally:
        server.stop()


def _view_log(args: argparse.Namespace) -> int:
    """The logging end of `hrc view`: subscribe to the cell and log every message to the pipe or file."""
    import time

    from shared.config import CellConfig
    from shared.core.errors import MessageError
    from shared.robot.model import default_robot
    from shared.wire.messages import HumanState, JointCommand, JointState, ScalerStatus, TrajectoryMsg, decode
    from tools.view import CellLogger, pipe_stream

    if args.save is not None:
        from tools.view import no_analytics

        no_analytics()
        import rerun as rr

        stream = rr.RecordingStream("hrc-view")
        stream.save(str(args.save))
    else:
        stream = pipe_stream(args.pipe_fd)
    logger = CellLogger(stream, default_robot(), CellConfig().ssm, time.monotonic())
    counts = {"logged": 0, "bad": 0}

    def keep(kind):
        def on_sample(sample):
            try:
                msg = decode(sample.payload.to_bytes(), kind)
            except MessageError:
                counts["bad"] += 1
                return
            logger.dispatch(msg)
            counts["logged"] += 1
        return on_sample

    with _client(args) as (session, keys):
        subs = [session.declare_subscriber(key, keep(kind)) for key, kind in (
            (keys.joint_state, JointState), (keys.command, JointCommand), (keys.human_state, HumanState),
            (keys.scaler_status, ScalerStatus), (keys.trajectory, TrajectoryMsg))]
        started = time.monotonic()
        try:
            while args.duration is None or time.monotonic() - started < args.duration:
                time.sleep(0.1)
        except KeyboardInterrupt:
            pass
        finally:
            for sub in subs:
                sub.undeclare()
            stream.flush()
            stream.disconnect()
    print(f"hrc view: {counts['logged']} messages logged ({counts['bad']} malformed ignored)"
          + (f" to {args.save}" if args.save else ""))
    return 0


def people_said(state) -> str:
    """`hrc status`'s line on the people (the newest HumanState, or None): the track, the source's rate and the
    way from a sample's capture to the tracker's state (a camera's latency, which the data's age counts)."""
    if state is None:
        return "no human state"
    if not state.valid:
        return "track not valid (no sample within the stale bound): the robot is stopped"
    rate = f"{1.0 / state.sample_interval:.1f} Hz" if state.sample_interval > 0 else "rate not yet measured"
    return (f"{len(state.radii)} capsule(s), {rate}, {1e3 * max(state.stamp - state.sample_stamp, 0.0):.0f} ms from "
            "capture to the tracker")


def cmd_status(args: argparse.Namespace) -> int:
    import time

    from shared.core.errors import MessageError
    from shared.wire.keys import SERVICES
    from shared.wire.messages import DriveLagReport, HumanState, JointState, SafetyEvent, ScalerStatus, decode

    latest: dict = {}

    def keep(kind):
        def on_sample(sample):
            try:
                msg = decode(sample.payload.to_bytes(), kind)
            except MessageError:
                return
            if kind is SafetyEvent and msg.event != "monitor_summary":
                return
            latest[kind] = msg
        return on_sample

    with _client(args) as (session, keys):
        subs = [session.declare_subscriber(keys.joint_state, keep(JointState)),
                session.declare_subscriber(keys.scaler_status, keep(ScalerStatus)),
                session.declare_subscriber(keys.safety_events, keep(SafetyEvent)),
                session.declare_subscriber(keys.drive_lag, keep(DriveLagReport)),
                session.declare_subscriber(keys.human_state, keep(HumanState))]
        deadline = time.monotonic() + args.timeout      # until every report has come once (the monitor's is 1 Hz)
        while len(latest) < len(subs) and time.monotonic() < deadline:
            time.sleep(0.05)
        alive = sorted({str(r.ok.key_expr).rsplit("/", 1)[-1] for r in session.liveliness().get(keys.alive_all, timeout=1.0)
                        if r.ok is not None})
        print(f"cell {args.prefix} at {args.connect}")
        print("  services: " + ", ".join(f"{s} {'up' if s in alive else 'down'}" for s in SERVICES
                                         if s != "cli" and (s != "ros2_bridge" or s in alive)))
        js = latest.get(JointState)
        lag = latest.get(DriveLagReport)
        print(f"  robot:    {js.drive_state if js else 'no joint state'}"
              + (f", q = {[round(float(v), 3) for v in js.q]}" if js else ""))
        if lag is not None and lag.stopped_by:
            print(f"  stopped:  {lag.stopped_by}; `hrc recover` once its cause is gone")
        print("  drives:   " + (f"lag p99 {', '.join(f'{x * 1e3:.1f}' for x in lag.lag)} ms (bound "
                                 f"{lag.bound * 1e3:.0f} ms; 0 = not moving), following error max "
                                 f"{lag.following_error.max() * 1e3:.2f} mrad" if lag else "no drive report"))
        st = latest.get(ScalerStatus)
        print("  scaler:   " + (f"alpha {st.alpha:.2f} (safe {st.safe_alpha:.2f}), beta {int(st.beta)}, trajectory "
                                 f"{st.trajectory_version}, s {st.s:.2f}, {st.status}" if st else "no status"))
        print(f"  people:   {people_said(latest.get(HumanState))}")
        ev = latest.get(SafetyEvent)
        print(f"  monitor:  {ev.text if ev else 'no summary'}")
        for sub in subs:
            sub.undeclare()
    return 0


def cmd_certs(args: argparse.Namespace) -> int:
    from shared.transport.acl import IDENTITIES
    from shared.transport.pki import make_cell_pki

    if args.out.exists() and any(args.out.glob("*.pem")):
        raise CertsArgumentError(f"{args.out} already holds certificates; refusing to replace the cell CA")
    try:
        make_cell_pki(args.out, list(IDENTITIES), tuple(args.hosts))
    except OSError as exc:
        raise CertsArgumentError(f"cannot write to {args.out}: {exc.strerror}") from None
    print(f"hrc certs: CA and certificates for {', '.join(IDENTITIES)} in {args.out} (valid for "
          f"{', '.join(args.hosts)}); move ca-key.pem off the cell")
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    """A grid of configuration values (tools.grid) run by tools.sweep, each point's figures from the Parquet records."""
    from evidence.scenarios import SCENARIO_KINDS
    from evidence.summary import against_first, against_other, per_point
    from shared.safety.parameters import SsmParameters
    from tools import grid as grids
    from tools import sweep

    doc = grids.load_grid(args.grid) if args.grid is not None else {}
    values = dict(doc.get("set") or {})
    for text in args.values:
        key, numbers = grids.parse_values(text)
        values[key] = numbers
    split = lambda text: [x.strip() for x in str(text).split(",") if x.strip()]
    listed = lambda given, key, default: split(given) if given is not None else list(doc.get(key) or default)
    def number(given, key: str, default, kind):
        try:
            return given if given is not None else kind(doc.get(key, default))
        except (TypeError, ValueError):
            raise grids.GridError(f"{args.grid}: {key}: expected a number, got {doc.get(key)!r}") from None

    grid = grids.Grid(values=values, strategies=listed(args.strategies, "strategies", ["scale_only", "full"]),
                       kinds=listed(args.kinds, "kinds", sorted(SCENARIO_KINDS)),
                       scenarios=number(args.scenarios, "scenarios", 20, int),
                       duration=number(args.duration, "duration", 12.0, float),
                       seed=number(args.seed, "seed", 0, int), latency=number(args.latency, "latency", 0.0, float))
    grids.check_grid(grid)
    if args.workers < 1 or args.chunk < 1:
        raise UsageError("--workers and --chunk must be >= 1")
    other = None if args.against is None else sweep.read_sweep(args.against)     # a bad folder: before any run
    forecaster = _forecaster(args.forecaster if args.forecaster is not None else doc.get("forecaster"))
    try:
        specs = grid.specs(forecaster)
    except ConfigError as exc:                      # the grid file's latency (--latency is checked as it is read)
        raise grids.GridError(f"{args.grid}: {exc}") from None
    print(f"hrc sweep: {len(grid.points())} points x {grid.scenarios} scenarios x {len(grid.strategies)} strategies "
          f"= {len(specs)} runs into {args.out}" + (f" (full's forecaster {forecaster})" if forecaster else "")
          + (f", the people {1e3 * grid.latency:g} ms late" if grid.latency else ""), flush=True)
    done = sweep.run_sweep(specs, args.out, executor="dask" if args.dask else "local", workers=args.workers,
                           address=None if args.dask in (None, "local") else args.dask, chunk=args.chunk,
                           meta={"bench": "sweep", "code": sweep.code_version(Path(__file__).resolve().parents[1])})
    records = sweep.read_records(args.out)
    points, first = per_point(records, SsmParameters().horizon), against_first(records)
    against = None if other is None else {"folder": str(args.against), "points": against_other(records, other)}
    print("\n".join(grids.figure_lines(points, grid.strategies, first, against)))
    grids.write_summary(points, grid, args.out, first, against)
    print(f"{done.ran} chunks run, {done.skipped} already there, {len(done.failed)} failed, in {done.wall_s:.0f} s; "
          f"summary.json, sweep.csv, sweep-kinds.csv and plots in {args.out}")
    if done.failed:
        print(f"hrc sweep: chunks {done.failed} failed: rerun the same command to fill them in", file=sys.stderr)
        return 1
    return 0


def _forecaster(spec: str | None) -> str | None:
    """A researcher's forecaster named ``module:attribute``, loaded once to refuse a bad name before anything runs
    (UsageError saying what is wrong); None: the planning layer's own."""
    if spec is None:
        return None
    from shared.planning.forecast import forecaster_problem

    if problem := forecaster_problem(str(spec)):
        raise UsageError(f"--forecaster: {problem}")
    return str(spec)


def cmd_scenario(args: argparse.Namespace) -> int:
    """One seeded scenario, each strategy's run taken apart (tools.scenario); the configuration checked as a
    sweep's point is, before anything runs."""
    from evidence.scenarios import make_scenario
    from evidence.sweep import config_of, strategies_for
    from tools import grid as grids
    from tools.scenario import people_lines, story_lines

    overrides = []
    for text in args.values:
        key, values = grids.parse_values(text)
        if len(values) != 1:
            raise UsageError(f"--set {text!r}: one value a key (a sweep's point), got {len(values)}")
        overrides.append((key, values[0]))
    point = tuple(sorted(overrides))
    strategies = [s.strip() for s in args.strategies.split(",") if s.strip()]
    grids.check_grid(grids.Grid(values={k: [v] for k, v in point}, strategies=strategies, kinds=[args.kind],
                                scenarios=1, duration=args.duration, seed=args.seed))
    runs = strategies_for(point, _forecaster(args.forecaster))
    alpha_min = config_of(point).scaling.alpha_min
    print(f"hrc scenario: {args.kind} seed {args.seed}, {args.duration:g} s, {grids.point_label(point)}"
          + (f", full's forecaster {args.forecaster}" if args.forecaster else "")
          + (f", the people {1e3 * args.latency:g} ms late" if args.latency else ""))
    print("\n".join(people_lines(make_scenario(args.kind, args.seed, args.duration))) or "people: scripted")
    for strategy in strategies:
        run = runs.run(strategy, args.kind, args.seed, args.duration, latency=args.latency)
        print("\n".join(story_lines(strategy, run, alpha_min)))
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    """hrc report FOLDER --mcap: the ROS 2 bag of an older report, from its trace files."""
    import json
    import time

    from shared.config import load_config
    from shared.robot.model import default_robot
    from tools.mcap_record import ReportError, recording_from_report, write_mcap

    if not args.mcap:
        raise UsageError("nothing to write: give --mcap")
    if not (args.folder / "trace.csv").is_file():
        raise UsageError(f"{args.folder}: not an hrc demo report folder (no trace.csv)")
    config = load_config(args.config)                     # a ConfigError is the CLI's clear error
    try:
        rec = recording_from_report(args.folder)
    except ReportError as exc:
        raise UsageError(str(exc)) from None
    summary = args.folder / "summary.json"
    ended = summary.stat().st_mtime if summary.exists() else time.time()
    try:
        ran = json.loads(summary.read_text()).get("human_acceleration_m_s2") if summary.exists() else None
    except (OSError, ValueError, AttributeError):
        ran = None
    if isinstance(ran, (int, float)) and ran != config.ssm.human_acceleration:
        print(f"hrc report: warning: the run had human_acceleration {ran} m/s^2 (summary.json), the configuration "
              f"{config.ssm.human_acceleration}: give the run's own with --config", file=sys.stderr)
    last = max([m.stamp for m in rec.statuses] or [0.0])
    path = write_mcap(args.folder, default_robot(), config, rec, epoch_t0=ended - last)
    print(f"hrc report: {path} ({path.stat().st_size / 1e6:.1f} MB, {len(rec.joint_states)} joint states) and "
          f"metadata.yaml: `ros2 bag play {args.folder}`")
    return 0


class CertsArgumentError(HrcError):
    """hrc certs cannot write where it was asked to."""


def cmd_faults(args: argparse.Namespace) -> int:
    from shared.config import load_config
    from shared.robot.model import default_robot
    from tools import faults
    from tools.cell import cell_endpoint, cell_pid, run_dir

    names = args.only or list(faults.FAULT_NAMES)
    unknown = [n for n in names if n not in faults.FAULT_NAMES]
    if unknown:
        raise FaultArgumentError(f"unknown fault(s) {unknown}; known: {', '.join(faults.FAULT_NAMES)}")
    if cell_pid(args.prefix) is None:
        raise FaultArgumentError(f"no cell {args.prefix} is up under supervisord (start it with hrc up)")
    config = load_config(args.config)
    can_file = run_dir(args.prefix) / "cell.can"
    interface = can_file.read_text().strip() if can_file.exists() else "udp_multicast"
    channel = "vcan0" if interface == "socketcan" else None
    if args.connect is None:
        args.connect = cell_endpoint(args.prefix)
    verdicts = faults.run_campaign(args.prefix, args.connect, interface, channel, config, default_robot(), names,
                                   args.out, say=lambda text: print(text, flush=True), trace=args.trace)
    return 0 if all(v.ok for v in verdicts) else 1


class FaultArgumentError(HrcError):
    """hrc faults was asked for a fault it does not know, or there is no cell to inject into."""


class Unreachable(HrcError):
    """A client command found no service of the cell to talk to (exit 1)."""


class UsageError(HrcError):
    """An option that does not fit the chosen mode, or a value out of range."""


class GoalArgumentError(HrcError):
    """A goal given on the command line is not six finite angles within the limits, nor a known name."""


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)
    if args.command is None:
        parser.print_help()
        return 2
    if args.command in ("goal", "human", "status", "recover", "faults") and getattr(args, "prefix", None) \
            and not os.environ.get("HRC_IN_CELL"):
        from tools.cell import reenter_argv
        argv2 = reenter_argv(args.prefix, [sys.executable, "-m", "tools.cli", *(argv or sys.argv[1:])])
        if argv2 is not None:            # the cell runs in its own network namespace: run there
            os.execvpe(argv2[0], argv2, dict(os.environ, HRC_IN_CELL="1"))
    try:
        return {"demo": cmd_demo, "goal": cmd_goal, "human": cmd_human, "status": cmd_status, "up": cmd_up,
                "down": cmd_down, "recover": cmd_recover, "faults": cmd_faults,
                "certs": cmd_certs, "view": cmd_view, "sweep": cmd_sweep, "scenario": cmd_scenario,
                "report": cmd_report}[args.command](args)
    except Unreachable as exc:
        print(f"hrc {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except HrcError as exc:
        print(f"hrc {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:      # `hrc status | grep -q running`: the reader has what it wanted and left
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())     # nor a traceback at the interpreter's exit
        return 0


if __name__ == "__main__":
    sys.exit(main())
