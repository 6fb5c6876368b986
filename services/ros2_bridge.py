"""ros2_bridge: the cell as ROS 2 topics (rmw_zenoh, Jazzy), and goals and people from ROS 2.

Out, every 10 ms on what is new: /joint_states (every measured joint state, stamped when measured) and /tf
(every moving link from the world frame, at the newest state; the base, fixed to it, on /tf_static, transient
local), /hrc/robot_capsules (20 Hz), /hrc/people (the tracked people, at most 30 Hz: a viewer's rate),
/speed_scaling_factor (alpha) and /hrc/replan_request (beta), /diagnostics (the safety events),
/robot_description (the URDF, transient local: zenoh-ext's advanced publisher keeps it for late subscribers,
as rmw_zenoh does; sent again every 10 s, with /tf_static). Each sample carries rmw_zenoh's attachment; the
node and every endpoint declare their liveliness tokens, so `ros2 topic list` and rviz2 see them
(shared.ros2.graph, shared.ros2.bridge).

In: /hrc/goal (sensor_msgs/JointState) becomes a Goal for the planner; /hrc/perception/people
(visualization_msgs/MarkerArray of CYLINDER capsules) and /hrc/perception/keypoints, .../arm_keypoints
(geometry_msgs/PoseArray of skeletons, made capsules by the code of `hrc human from-keypoints`) raw human data
for tracker_ingest, sampled when their header stamps say, which filters and checks it as any tracker's.
Refusals (no attachment, not the type, invalid, stale, partly seen, over the rate) are counted and
said once a second in an info event. The bridge is outside the safety chain: it only reads the cell's keys,
and what it sends in takes the cell's own checks; a slow or dead bridge stops nothing but itself.

    python -m services.ros2_bridge --prefix hrc/cell1 --domain 0 --connect tcp/127.0.0.1:7447
"""

from __future__ import annotations

import sys
import threading
import time

import numpy as np

from services.common import ServiceShell, open_service, run_paced, serve, service_parser, setup_logging
from shared.robot.model import URDF_PATH, RobotModel
from shared.ros2 import convert
from shared.ros2.bridge import ENDPOINTS, PEOPLE_TOPICS, BridgeNode, Inbound
from shared.ros2.graph import PUBLISHER, TRANSIENT_LOCAL
from shared.ros2.types import serialize
from shared.wire.messages import Goal, HumanRaw, HumanState, JointState, SafetyEvent, ScalerStatus, encode

PERIOD = 0.01
PEOPLE_PERIOD, DESCRIPTION_PERIOD, REPORT_PERIOD = 1.0 / 30.0, 10.0, 1.0


class Ros2Bridge:
    def __init__(self, shell: ServiceShell, robot: RobotModel, domain: int) -> None:
        self.shell, self.robot = shell, robot
        self.node = BridgeNode(domain, str(shell.session.zid()))
        self.inbound = Inbound()
        self.lock = threading.Lock()              # before the subscriptions: their callbacks take it
        self.goal_id = int(time.time() * 1000) % 2**31
        self.raw_seq = 0
        self.pubs = {e.topic: self._publisher(e) for e in ENDPOINTS if e.kind == PUBLISHER}
        # every joint state (a bag of /joint_states holds what the driver measured, 100 Hz, also when a tick
        # is late under load); /tf and the capsules from the newest only
        self.joints = shell.queue(shell.keys.joint_state, JointState, capacity=1000)
        self.people = shell.latest(shell.keys.human_state, HumanState)
        self.status = shell.latest(shell.keys.scaler_status, ScalerStatus)
        self.events = shell.queue(shell.keys.safety_events, SafetyEvent, capacity=1000)
        self.goal_pub = shell.session.declare_publisher(shell.keys.goal)
        self.raw_pub = shell.session.declare_publisher(shell.keys.human_raw)
        self.event_pub = shell.session.declare_publisher(shell.keys.safety_events)
        self.subs = [shell.session.declare_subscriber(self.node.key(topic), lambda s, t=topic: self.on_ros(t, s))
                     for topic in ("/hrc/goal", *PEOPLE_TOPICS)]
        self.tokens = [shell.session.liveliness().declare_token(t) for t in self.node.tokens()]
        self.urdf = URDF_PATH.read_text()
        self.last_js = self.last_people = self.last_status = -1.0
        self.last_capsules = self.last_description = self.last_report = -1e9
        self.reported = 0

    def _publisher(self, endpoint):
        """A Zenoh publisher on the endpoint's key; for TRANSIENT_LOCAL (/robot_description) zenoh-ext's advanced
        publisher with a cache of its depth, as rmw_zenoh makes it, so a late subscriber gets the last sample."""
        key = self.node.key(endpoint.topic)
        if endpoint.qos.durability != TRANSIENT_LOCAL:
            return self.shell.session.declare_publisher(key)
        import zenoh.ext

        return zenoh.ext.declare_advanced_publisher(self.shell.session, key,
                                                    cache=zenoh.ext.CacheConfig(max_samples=endpoint.qos.depth),
                                                    publisher_detection=True)

    def put(self, topic: str, message, msgtype: str) -> None:
        now_ns = time.time_ns()
        self.pubs[topic].put(serialize(message, msgtype), attachment=self.node.attachment(topic, now_ns))

    def tick(self, now: float) -> None:
        t_ns = time.time_ns()
        states = [js for js in self.joints.drain() if js.stamp > self.last_js]
        for js in states:          # each stamped when it was measured (the driver's clock is this host's monotonic one)
            measured_ns = t_ns - int(max(0.0, now - js.stamp) * 1e9)
            self.put("/joint_states", convert.joint_state(self.robot.joint_names, js.q, js.qd, measured_ns),
                     convert.JOINT_STATE)
        if states:
            js = states[-1]
            self.last_js = js.stamp
            self.put("/tf", convert.link_transforms(self.robot.link_poses(js.q, fixed=False), "world", t_ns),
                     convert.TF)
            if now - self.last_capsules >= convert.ROBOT_MARKER_PERIOD:
                self.last_capsules = now
                self.put("/hrc/robot_capsules", convert.robot_markers(self.robot, js.q, t_ns), convert.MARKERS)
        hs = self.people.take() if now - self.last_people >= PEOPLE_PERIOD else None
        if hs is not None:
            self.last_people = now
            self.put("/hrc/people", convert.people_markers(hs, t_ns), convert.MARKERS)
        st = self.status.take()
        if st is not None and st.stamp != self.last_status:
            self.last_status = st.stamp
            self.put("/speed_scaling_factor", convert.float64(st.alpha), convert.FLOAT64)
            self.put("/hrc/replan_request", convert.boolean(st.beta), convert.BOOL)
        events = self.events.drain()
        if events:
            self.put("/diagnostics", convert.diagnostics(events, t_ns), convert.DIAGNOSTICS)
        if now - self.last_description >= DESCRIPTION_PERIOD:
            self.last_description = now
            self.put("/robot_description", convert.string(self.urdf), convert.STRING)
            self.put("/tf_static", self.static_frames(t_ns), convert.TF)
        if now - self.last_report >= REPORT_PERIOD:
            self.last_report = now
            self.report(now)

    def static_frames(self, t_ns: int):
        """/tf_static: the links fixed to the world (the base), as robot_state_publisher sends them."""
        return convert.link_transforms(self.robot.link_poses(np.zeros(self.robot.nq), fixed=True), "world", t_ns)

    def report(self, now: float) -> None:
        with self.lock:
            refused = dict(self.inbound.refused)
        total = sum(refused.values())
        if total > self.reported:
            self.reported = total
            text = ", ".join(f"{n} {why}" for why, n in sorted(refused.items()))
            self.shell.log.warning("refused from ROS 2 so far: %s", text)
            self.event_pub.put(encode(SafetyEvent(source="ros2_bridge", event="ros2_refused", severity="info",
                                                  text=f"refused from ROS 2 so far: {text}", value=float(total),
                                                  stamp=now)))

    def on_ros(self, topic: str, sample) -> None:
        """A sample from ROS 2 (Zenoh's callback thread): checked, then sent into the cell as its own message."""
        now = time.monotonic()
        att = sample.attachment.to_bytes() if sample.attachment is not None else None
        with self.lock:
            message = self.inbound.take(topic, sample.payload.to_bytes(), att, now)
            if message is None:
                return
            if topic == "/hrc/goal":
                q = self.inbound.convert(convert.goal_positions, message, self.robot.joint_names)
                if q is None:
                    return
                if not self.robot.limits.within(q):
                    self.inbound._refuse("invalid")
                    return
                self.goal_id += 1
                self.goal_pub.put(encode(Goal(goal_id=self.goal_id, name="ros2", q=q, seq=self.goal_id, stamp=now)))
            else:
                taken = self.inbound.people(topic, message, time.time_ns())
                if taken is None:
                    return
                people, age = taken
                self.raw_seq += 1
                self.raw_pub.put(encode(HumanRaw(source="ros2", sample_time=now - age, segments=people.segments,
                                                 radii=people.radii, seq=self.raw_seq, stamp=now)))

    def safe_tick(self, now: float) -> None:
        """tick, its failure logged (at most once a second) and the bridge going on: it is a view of the
        cell, and nothing in the cell waits for it."""
        try:
            self.tick(now)
        except Exception as exc:                 # e.g. a message rosbags cannot serialise: that cycle is lost
            if now - getattr(self, "_last_error", -1e9) >= 1.0:
                self._last_error = now
                self.shell.log.error("a tick failed: %s: %s", type(exc).__name__, exc)

    def loop(self, stop: threading.Event) -> None:
        try:
            run_paced(PERIOD, self.safe_tick, stop)
        finally:
            self.close()            # before serve closes the session

    def close(self) -> None:
        for token in self.tokens:
            token.undeclare()
        for sub in self.subs:
            sub.undeclare()


def main(argv: list[str] | None = None) -> int:
    parser = service_parser("ros2_bridge", __doc__)
    parser.add_argument("--domain", type=int, default=None,
                        help="ROS_DOMAIN_ID of the ROS 2 graph (default: the configuration's ros2.domain_id, 0)")
    args = parser.parse_args(argv)
    setup_logging(args.log_level)
    if args.domain is not None and not 0 <= args.domain <= 232:
        print("ros2_bridge: error: --domain must be a ROS domain id, 0 to 232", file=sys.stderr)
        return 2
    from shared.config import load_config
    from shared.core.errors import ConfigError

    try:
        ros2 = load_config(args.config).ros2
    except ConfigError as exc:
        print(f"ros2_bridge: error: {exc}", file=sys.stderr)
        return 2
    if ros2.router:
        args.connect = [*args.connect, ros2.router]           # the ROS 2 host's router, besides the cell
    args.timestamping = True                # zenoh-ext's advanced publisher (transient local) needs it
    opened = open_service("ros2_bridge", args)
    if opened is None:
        return 2
    _, shell = opened
    domain = ros2.domain_id if args.domain is None else args.domain
    bridge = Ros2Bridge(shell, RobotModel(), domain)
    return serve(shell, f"ros2_bridge: ROS 2 domain {domain}, node hrc_bridge, session {bridge.node.session_id}, "
                        f"keys {shell.keys.prefix}/", bridge.loop)


if __name__ == "__main__":
    sys.exit(main())
