"""What the ROS 2 bridge is on the ROS 2 graph, and what it lets in (pure).

The bridge is one ROS 2 node, ``hrc_bridge``: the endpoints below, each with its rmw_zenoh data key, liveliness
token, GID and sequence numbers (``BridgeNode``). What comes in from ROS 2 (a goal, people from a perception
node) passes ``Inbound``: a sample without its attachment, a buffer that is not the type, a message that is not
valid (or stale, or a skeleton partly seen), or one more than `max_rate` a second on its topic is refused and
counted by reason; what passes becomes the cell's own message and takes the cell's own checks (a goal the
planner's, people the tracker's)."""

from __future__ import annotations

from dataclasses import dataclass, field

from shared.core.errors import MessageError
from shared.ros2 import convert
from shared.ros2.graph import (
    LATCHED,
    PUBLISHER,
    SENSOR,
    SUBSCRIPTION,
    Qos,
    attachment,
    endpoint_token,
    gid,
    node_token,
    parse_attachment,
    topic_key,
)
from shared.ros2.types import deserialize
from shared.tracking.keypoints import ARM_KEYPOINTS, KEYPOINTS

NODE_NAME = "hrc_bridge"


@dataclass(frozen=True)
class Endpoint:
    topic: str
    msgtype: str
    kind: str                  # PUBLISHER or SUBSCRIPTION
    qos: Qos
    entity_id: int


ENDPOINTS = (
    Endpoint("/joint_states", convert.JOINT_STATE, PUBLISHER, SENSOR, 1),
    Endpoint("/tf", convert.TF, PUBLISHER, Qos(depth=100), 2),
    Endpoint("/robot_description", convert.STRING, PUBLISHER, LATCHED, 3),
    Endpoint("/hrc/people", convert.MARKERS, PUBLISHER, SENSOR, 4),
    Endpoint("/hrc/robot_capsules", convert.MARKERS, PUBLISHER, SENSOR, 5),
    Endpoint("/speed_scaling_factor", convert.FLOAT64, PUBLISHER, SENSOR, 6),
    Endpoint("/hrc/replan_request", convert.BOOL, PUBLISHER, SENSOR, 7),
    Endpoint("/diagnostics", convert.DIAGNOSTICS, PUBLISHER, SENSOR, 8),
    Endpoint("/hrc/perception/people", convert.MARKERS, SUBSCRIPTION, SENSOR, 9),
    Endpoint("/hrc/goal", convert.JOINT_STATE, SUBSCRIPTION, SENSOR, 10),
    Endpoint("/hrc/perception/keypoints", convert.POSES, SUBSCRIPTION, SENSOR, 11),
    Endpoint("/hrc/perception/arm_keypoints", convert.POSES, SUBSCRIPTION, SENSOR, 12),
    Endpoint("/tf_static", convert.TF, PUBLISHER, LATCHED, 13),
)
# the keypoint topics and the skeleton each carries per person (shared.tracking.keypoints, in that order)
KEYPOINT_TOPICS = {"/hrc/perception/keypoints": KEYPOINTS, "/hrc/perception/arm_keypoints": ARM_KEYPOINTS}
PEOPLE_TOPICS = ("/hrc/perception/people", *KEYPOINT_TOPICS)
BY_TOPIC = {e.topic: e for e in ENDPOINTS}


@dataclass
class BridgeNode:
    """The node on the ROS 2 graph of `domain`, for the Zenoh session `session_id` (its zid, hex)."""

    domain: int
    session_id: str
    node_id: int = 0
    sequence: dict[str, int] = field(default_factory=dict)

    def key(self, topic: str) -> str:
        e = BY_TOPIC[topic]
        return topic_key(self.domain, e.topic, e.msgtype)

    def node_token(self) -> str:
        return node_token(self.domain, self.session_id, self.node_id, NODE_NAME)

    def token(self, topic: str) -> str:
        e = BY_TOPIC[topic]
        return endpoint_token(self.domain, self.session_id, self.node_id, e.entity_id, e.kind, NODE_NAME, e.topic,
                              e.msgtype, e.qos)

    def tokens(self) -> list[str]:
        return [self.node_token()] + [self.token(e.topic) for e in ENDPOINTS]

    def attachment(self, topic: str, now_ns: int) -> bytes:
        """The next sample's attachment on `topic`: its sequence number (from 1), the time, the publisher's GID."""
        self.sequence[topic] = self.sequence.get(topic, 0) + 1
        return attachment(self.sequence[topic], now_ns, gid(self.token(topic)))


class Inbound:
    """Checks what ROS 2 sends the bridge; ``refused`` counts the refusals by reason."""

    def __init__(self, max_rate: float = 250.0) -> None:
        self.min_interval = 1.0 / max_rate
        self.last: dict[str, float] = {}
        self.refused: dict[str, int] = {}
        self.accepted = 0

    def _refuse(self, reason: str) -> None:
        self.refused[reason] = self.refused.get(reason, 0) + 1

    def take(self, topic: str, payload: bytes, att: bytes | None, now: float):
        """The message of a sample on `topic` (monotonic `now`, s), or None with the refusal counted."""
        try:
            parse_attachment(att)
        except MessageError:
            self._refuse("no attachment")
            return None
        if now - self.last.get(topic, -1e9) < self.min_interval:
            self._refuse("over the rate")
            return None
        try:
            message = deserialize(payload, BY_TOPIC[topic].msgtype)
        except MessageError:
            self._refuse("not the type")
            return None
        self.last[topic] = now
        return message

    def _checked(self, make, *args):
        """make(*args), or None with the refusal counted: the MessageError of a shared.ros2.convert reader,
        under its ``reason`` ('invalid' unless it says: 'stale', 'partly seen')."""
        try:
            return make(*args)
        except MessageError as exc:
            self._refuse(exc.reason)
            return None

    def convert(self, make, *args):
        """make(*args) of a reader (``_checked``), counted as accepted where it passes."""
        value = self._checked(make, *args)
        self.accepted += value is not None
        return value

    def people(self, topic: str, message, wall_ns: int):
        """(capsules, age in s) of a people message on one of PEOPLE_TOPICS (a MarkerArray of capsules, or a
        PoseArray of keypoints), the age from its header stamps (``convert.sample_age``), at wall time
        `wall_ns`; None, counted, for one that is refused."""
        keypoints = KEYPOINT_TOPICS.get(topic)
        stamps = [message.header.stamp] if keypoints else [m.header.stamp for m in message.markers]
        age = self._checked(convert.sample_age, stamps, wall_ns)
        if age is None:
            return None
        humans = (self.convert(convert.people_from_keypoints, message, keypoints) if keypoints
                  else self.convert(convert.people_from_markers, message))
        return None if humans is None else (humans, age)
