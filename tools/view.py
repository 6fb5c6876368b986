"""The cell in 3D with rerun: a live view of a running cell (`hrc view`), of a demo (`hrc demo --view`),
and the recording of every demo (`recording.rrd` in its report folder).

What is drawn, on one timeline `t` (seconds from the start):
* robot/measured: the link capsules at the measured joint state; robot/commanded: the commanded ghost;
* humans: every human capsule tracker_ingest publishes (orange; grey when the track is invalid);
* ssm/closest: the robot-human pair nearest its limit, a line between the closest points, with its
  approach speed and its ISO/TS 15066 limit (ssm/approach, ssm/limit, m/s) on the plots;
* scaling/alpha, scaling/safe_alpha, scaling/beta over time;
* planner/current: the flange path of the trajectory being followed, planner/merged: of each merged or
  replanned one as it arrives.

The viewer is never inside a control process: `hrc view` is a Zenoh subscriber of its own, the demo logs
from its operator process, a slow viewer slows nothing but itself. A live view is served on loopback
only: the rerun binary that ships with rerun-sdk is started with `--bind 127.0.0.1` (gRPC proxy and web
viewer), and the logger connects to it there. Messages are logged as they arrive; pure helpers
(shared.core.geometry.capsule_frames, closest_pair) do the geometry.
"""

from __future__ import annotations

import json
import subprocess
import threading
import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from shared.core.geometry import capsule_frames, capsule_pair_distances
from shared.robot.model import RobotModel
from shared.safety.parameters import SsmParameters
from shared.safety.ssm import pair_ssm
from shared.wire.messages import HumanState, JointCommand, JointState, ScalerStatus, TrajectoryMsg

ROBOT_COLOR, GHOST_COLOR = (70, 110, 200, 255), (150, 190, 255, 90)
_PRIVATE_CONFIG: Path | None = None


def no_analytics() -> Path:
    """rerun's SDK and viewer send anonymous usage analytics to the internet unless told not to: this
    cell sends nothing beyond loopback. A private rerun configuration with analytics disabled (the file
    `rerun analytics disable` writes) is used by this process (XDG_CONFIG_HOME and XDG_DATA_HOME, before rerun's
    first use) and by the viewers it starts, leaving the user's own configuration alone. Returns that
    directory."""
    global _PRIVATE_CONFIG
    if _PRIVATE_CONFIG is None:
        import os
        import tempfile

        home = Path(tempfile.gettempdir()) / f"hrc-rerun-{os.getuid()}"
        config = home / "rerun" / "analytics.json"
        if not config.exists():                     # the file `rerun analytics disable` writes
            config.parent.mkdir(parents=True, exist_ok=True)
            config.write_text(json.dumps({"analytics_enabled": False, "analytics_id": uuid.uuid4().hex,
                                          "metadata": {}, "config_file_path": str(config),
                                          "data_dir_path": str(home / "data" / "rerun" / "analytics")}))
        os.environ.update({"XDG_CONFIG_HOME": str(home), "XDG_DATA_HOME": str(home / "data")})
        _PRIVATE_CONFIG = home
    return _PRIVATE_CONFIG
HUMAN_COLOR, LOST_COLOR = (240, 140, 40, 255), (150, 150, 150, 160)


@dataclass(frozen=True)
class ClosestPair:
    """The robot-human capsule pair nearest its SSM limit: its axis points (m), approach speed and limit
    (m/s), surface separation (m)."""

    robot_point: np.ndarray
    human_point: np.ndarray
    approach: float
    limit: float
    separation: float


def closest_pair(robot: RobotModel, q: np.ndarray, qd: np.ndarray, humans_segments: np.ndarray,
                 humans_radii: np.ndarray, velocities: np.ndarray, known: np.ndarray,
                 ssm: SsmParameters) -> ClosestPair | None:
    """The pair with the smallest margin (limit - approach) at joint state (q, qd); None with nobody."""
    from shared.core.humans import HumanCapsules

    if len(humans_radii) == 0:
        return None
    humans = HumanCapsules(np.asarray(humans_segments, float), np.asarray(humans_radii, float),
                           np.asarray(velocities, float), np.asarray(known, bool))
    points, velocities = robot.capsule_motion(q, qd)
    pairs = pair_ssm(points, robot.radii, velocities, humans, ssm, ssm.stop_of(qd, robot.limits.velocity))
    i, j = np.unravel_index(int(np.argmin(np.maximum(pairs.limit, 0.0) - pairs.robot_speed)), pairs.limit.shape)
    dist = capsule_pair_distances(points[i:i + 1], robot.radii[i:i + 1], humans.segments[j:j + 1],
                                  humans.radii[j:j + 1])
    return ClosestPair(dist.robot_point[0, 0], dist.human_point[0, 0], float(pairs.robot_speed[i, j]),
                       float(pairs.limit[i, j]), float(pairs.distance[i, j]))


def layout():
    """The view's layout: the cell in 3D on the left; alpha, safe alpha and beta, and the closest pair's
    approach speed against its limit, over time on the right."""
    import rerun.blueprint as rrb

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="world", name="cell"),
            rrb.Vertical(rrb.TimeSeriesView(origin="scaling", name="alpha, safe alpha, beta"),
                         rrb.TimeSeriesView(origin="ssm", name="closest pair: approach speed and limit (m/s)")),
            column_shares=[3, 2]),
        collapse_panels=True)


class CellLogger:
    """Logs the cell's messages to a rerun RecordingStream, time from t0 (the senders' monotonic stamps)."""

    def __init__(self, stream, robot: RobotModel, ssm: SsmParameters, t0: float) -> None:
        no_analytics()
        import rerun as rr

        self.rr, self.stream, self.robot, self.ssm, self.t0 = rr, stream, robot, ssm, t0
        self.lock = threading.Lock()
        self.humans: HumanState | None = None
        self.followed = -1
        self.trajectories: dict[int, TrajectoryMsg] = {}
        stream.send_blueprint(layout())
        stream.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)

    def _at(self, stamp: float) -> None:
        self.stream.set_time("t", duration=max(0.0, stamp - self.t0))

    def _capsules(self, path: str, segments: np.ndarray, radii: np.ndarray, color, ghost: bool = False) -> None:
        rr = self.rr
        start, quat, length = capsule_frames(segments)
        self.stream.log(path, rr.Capsules3D(lengths=length, radii=radii, translations=start, quaternions=quat,
                                            colors=[color] * len(radii),
                                            fill_mode=rr.components.FillMode.MajorWireframe if ghost else None))

    def _flange_path(self, msg: TrajectoryMsg) -> np.ndarray:
        q = msg.positions[:: max(1, len(msg.positions) // 100)]
        return np.array([self.robot.capsule_segments(qk)[-1, 1] for qk in q])

    def dispatch(self, msg) -> None:
        """Log any message of the cell (others are ignored)."""
        handler = {JointState: self.joint_state, JointCommand: self.command, HumanState: self.human_state,
                   ScalerStatus: self.status, TrajectoryMsg: self.trajectory}.get(type(msg))
        if handler is not None:
            with self.lock:
                self._at(msg.stamp)
                handler(msg)

    def joint_state(self, msg: JointState) -> None:
        self._capsules("world/robot/measured", self.robot.capsule_segments(msg.q), self.robot.radii, ROBOT_COLOR)
        hs = self.humans
        pair = None if hs is None or not hs.valid else closest_pair(
            self.robot, msg.q, msg.qd, hs.segments, hs.radii, hs.velocities, hs.velocity_known, self.ssm)
        if pair is None:
            self.stream.log("world/ssm/closest", self.rr.Clear(recursive=False))
            return
        self.stream.log("world/ssm/closest", self.rr.LineStrips3D([[pair.robot_point, pair.human_point]],
                                                                  colors=[(220, 30, 30)], radii=[0.005],
                                                                  labels=[f"{pair.separation:.2f} m"]))
        self.stream.log("ssm/approach", self.rr.Scalars([pair.approach]))
        self.stream.log("ssm/limit", self.rr.Scalars([max(pair.limit, 0.0)]))

    def command(self, msg: JointCommand) -> None:
        self._capsules("world/robot/commanded", self.robot.capsule_segments(msg.q), self.robot.radii, GHOST_COLOR,
                       ghost=True)

    def human_state(self, msg: HumanState) -> None:
        self.humans = msg
        if msg.radii.size == 0:
            self.stream.log("world/humans", self.rr.Clear(recursive=False))
            return
        self._capsules("world/humans", msg.segments, msg.radii, HUMAN_COLOR if msg.valid else LOST_COLOR)

    def status(self, msg: ScalerStatus) -> None:
        rr = self.rr
        self.stream.log("scaling/alpha", rr.Scalars([msg.alpha]))
        self.stream.log("scaling/safe_alpha", rr.Scalars([msg.safe_alpha]))
        self.stream.log("scaling/beta", rr.Scalars([float(msg.beta)]))
        if msg.trajectory_version != self.followed and msg.trajectory_version in self.trajectories:
            self.followed = msg.trajectory_version
            path = self._flange_path(self.trajectories[msg.trajectory_version])
            self.stream.log("world/planner/current", rr.LineStrips3D([path], colors=[(40, 160, 60)], radii=[0.004]))

    def trajectory(self, msg: TrajectoryMsg) -> None:
        self.trajectories[msg.version] = msg
        if len(self.trajectories) > 50:
            self.trajectories.pop(min(self.trajectories))
        if msg.reason != "goal":
            self.stream.log("world/planner/merged", self.rr.LineStrips3D(
                [self._flange_path(msg)], colors=[(160, 60, 200)], radii=[0.004],
                labels=[f"v{msg.version} {msg.reason}"]))


def write_recording(path: Path, robot: RobotModel, ssm: SsmParameters, messages, t0: float) -> int:
    """Every message (any order; sorted by stamp here) into an .rrd file; returns how many were logged."""
    no_analytics()
    import rerun as rr

    stream = rr.RecordingStream("hrc", recording_id=f"hrc-{path.parent.name}")
    stream.save(str(path))
    logger = CellLogger(stream, robot, ssm, t0)
    count = 0
    for msg in sorted(messages, key=lambda m: m.stamp):
        logger.dispatch(msg)
        count += 1
    stream.flush()
    stream.disconnect()
    return count


def rerun_binary() -> str:
    """The rerun viewer executable that ships with rerun-sdk (the binary itself: the `rerun` script on the
    PATH is a Python wrapper that starts it as a child, which would outlive a terminated wrapper)."""
    try:
        import rerun_cli
    except ImportError:
        raise RuntimeError("the rerun viewer is not installed (pip install rerun-sdk)") from None
    binary = Path(rerun_cli.__file__).with_name("rerun")
    if not binary.exists():
        raise RuntimeError(f"the rerun viewer binary is missing: {binary}")
    return str(binary)


class ViewServer:
    """The rerun viewer served on loopback only (`--bind 127.0.0.1`: its gRPC proxy and its web viewer),
    fed through a pipe: whoever logs writes the recording stream to ``write_fd`` (a child process, even one
    in the cell's private network namespace, inherits it; no network hop is needed)."""

    def __init__(self, grpc_port: int, web_port: int) -> None:
        import os

        self.grpc_port, self.web_port = grpc_port, web_port
        no_analytics()                              # the viewer inherits the private configuration
        read_fd, self.write_fd = os.pipe()
        self.process = subprocess.Popen([rerun_binary(), "--serve-web", "--bind", "127.0.0.1", "--port",
                                         str(grpc_port), "--web-viewer-port", str(web_port), "-"],
                                        stdin=read_fd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(read_fd)

    @property
    def web_url(self) -> str:
        return f"http://127.0.0.1:{self.web_port}/?url=rerun%2Bhttp://127.0.0.1:{self.grpc_port}/proxy"

    def stop(self) -> None:
        import os

        try:
            os.close(self.write_fd)
        except OSError:
            pass
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=3)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()


def pipe_stream(fd: int, name: str = "hrc-live"):
    """A rerun RecordingStream written into a pipe to a ViewServer (fd inherited or our own)."""
    no_analytics()
    import rerun as rr

    stream = rr.RecordingStream(name)
    stream.set_sinks(rr.FileSink(f"/proc/self/fd/{fd}"))
    return stream
