"""rmw_zenoh's graph on Zenoh (ros2/rmw_zenoh docs/design.md, Jazzy): how a ROS 2 publisher or subscription
appears, so that ROS 2 tools (ros2 topic list, rviz2, rosbag2) see and talk to the cell.

- Data key: ``<domain>/<fully qualified name without its leading slash>/<DDS type name>/<RIHS01 type hash>``.
- Liveliness token of each node and endpoint: ``@ros2_lv/<domain>/<session id>/<node id>/<entity id>/<kind>/
  <enclave>/<namespace>/<node name>[/<topic>/<type>/<hash>/<qos>]``, every name mangled ('/' -> '%', an
  empty one '%'); the graph of ROS 2 tools is built from these tokens.
- QoS in the token: ``rel:dur:hist,depth:deadline s,ns:lifespan s,ns:liveliness,lease s,ns``, each value left
  empty where it equals rmw_zenoh's default (reliable, volatile, keep last 42, durations infinite, automatic).
- GID: the XXH3-128 hash of the endpoint's token (low 64 bits, then high, little-endian).
- Attachment on every sample: sequence number (int64 LE), source timestamp (ns since the epoch, int64 LE),
  the GID's length (one byte, 16) and the GID: 33 bytes; a subscriber drops a sample without it."""

from __future__ import annotations

import struct
from dataclasses import dataclass

from shared.core.errors import MessageError
from shared.ros2.types import dds_type_name, type_hash

ADMIN_SPACE = "@ros2_lv"
NODE, PUBLISHER, SUBSCRIPTION = "NN", "MP", "MS"
ATTACHMENT_SIZE = 33

# rmw's enums (rmw/types.h)
RELIABLE, BEST_EFFORT = 1, 2
TRANSIENT_LOCAL, VOLATILE = 1, 2
KEEP_LAST, KEEP_ALL = 1, 2


@dataclass(frozen=True)
class Qos:
    """The QoS of an endpoint (rmw's enum values). The defaults are rmw_zenoh's own, written as empty."""

    reliability: int = RELIABLE
    durability: int = VOLATILE
    history: int = KEEP_LAST
    depth: int = 42

    def keyexpr(self) -> str:
        pick = lambda value, default: "" if value == default else str(value)
        return (f"{pick(self.reliability, RELIABLE)}:{pick(self.durability, VOLATILE)}:"
                f"{pick(self.history, KEEP_LAST)},{pick(self.depth, 42)}:,:,:,,")


SENSOR = Qos(depth=10)                       # a stream: reliable, volatile, the last 10
LATCHED = Qos(durability=TRANSIENT_LOCAL, depth=1)   # /robot_description, /tf_static: late joiners get it


def mangle(name: str) -> str:
    """'/' -> '%'; an empty name (or the root namespace) is '%' (a key chunk cannot be empty)."""
    return name.replace("/", "%") if name not in ("", "/") else "%"


def topic_key(domain: int, topic: str, msgtype: str) -> str:
    """The data key of a topic, e.g. ``0/joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_a13e...``."""
    return f"{domain}/{topic.strip('/')}/{dds_type_name(msgtype)}/{type_hash(msgtype)}"


def node_token(domain: int, session_id: str, node_id: int, name: str, namespace: str = "/",
               enclave: str = "/") -> str:
    return f"{ADMIN_SPACE}/{domain}/{session_id}/{node_id}/{node_id}/{NODE}/{mangle(enclave)}/{mangle(namespace)}/{name}"


def endpoint_token(domain: int, session_id: str, node_id: int, entity_id: int, kind: str, node: str, topic: str,
                   msgtype: str, qos: Qos, namespace: str = "/", enclave: str = "/") -> str:
    """The liveliness token of a publisher (MP) or subscription (MS) of `node` on `topic` (fully qualified)."""
    if kind not in (PUBLISHER, SUBSCRIPTION):
        raise ValueError(f"endpoint kind {kind!r}: expected {PUBLISHER} or {SUBSCRIPTION}")
    return (f"{ADMIN_SPACE}/{domain}/{session_id}/{node_id}/{entity_id}/{kind}/{mangle(enclave)}/{mangle(namespace)}/"
            f"{node}/{mangle(topic)}/{dds_type_name(msgtype)}/{type_hash(msgtype)}/{qos.keyexpr()}")


def gid(token: str) -> bytes:
    """The 16-byte GID rmw_zenoh gives the entity of this liveliness token."""
    import xxhash

    digest = xxhash.xxh3_128_intdigest(token.encode())
    return struct.pack("<QQ", digest & (2**64 - 1), digest >> 64)


def attachment(sequence: int, timestamp_ns: int, source_gid: bytes) -> bytes:
    if len(source_gid) != 16:
        raise ValueError(f"a GID is 16 bytes, got {len(source_gid)}")
    return struct.pack("<qqB", sequence, timestamp_ns, 16) + source_gid


def parse_attachment(data: bytes | None) -> tuple[int, int, bytes]:
    """(sequence number, source timestamp ns, GID) of a sample's attachment; MessageError when it has none or
    it is not one (rmw_zenoh drops such samples, and so does the bridge)."""
    if data is None or len(data) != ATTACHMENT_SIZE or data[16] != 16:
        raise MessageError(f"a ROS 2 sample needs its {ATTACHMENT_SIZE}-byte attachment, got "
                           f"{'none' if data is None else f'{len(data)} bytes'}")
    sequence, stamp = struct.unpack_from("<qq", data)
    return sequence, stamp, bytes(data[17:])
