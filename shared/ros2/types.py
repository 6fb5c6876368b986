"""ROS 2 message types, pinned to one distribution, Jazzy: their definitions, RIHS01 type hashes (REP-2016),
DDS type names and CDR bytes, all from rosbags' Jazzy type store (a well-kept pure-Python implementation of
rosidl's serialisation and type hashing, so no ROS install is needed).

``serialize`` writes the standard CDR encapsulation (little-endian, header ``00 01 00 00``); ``deserialize``
refuses a buffer that is not one of the type (short, wrong header, more than 3 trailing bytes), naming the type, with
MessageError, so bad input from a ROS 2 peer is a counted refusal and never a crash."""

from __future__ import annotations

from functools import lru_cache

from shared.core.errors import MessageError

DISTRO = "jazzy"
CDR_LE_HEADER = b"\x00\x01\x00\x00"


@lru_cache(maxsize=1)
def typestore():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def msg_class(msgtype: str):
    """The message class of ``pkg/msg/Name`` (a dataclass whose fields are the ROS 2 fields)."""
    return typestore().types[msgtype]


@lru_cache(maxsize=None)
def type_hash(msgtype: str) -> str:
    """``RIHS01_<sha256>`` of the type's description, as rosidl computes it."""
    return typestore().hash_rihs01(msgtype)


def dds_type_name(msgtype: str) -> str:
    """``sensor_msgs/msg/JointState`` -> ``sensor_msgs::msg::dds_::JointState_``, as rmw_zenoh's keys spell it."""
    package, kind, name = msgtype.split("/")
    return f"{package}::{kind}::dds_::{name}_"


@lru_cache(maxsize=None)
def msgdef(msgtype: str) -> str:
    """The concatenated ``.msg`` text of the type and every type it uses (MCAP's ros2msg schema)."""
    text, _ = typestore().generate_msgdef(msgtype, ros_version=2)
    return text


def serialize(message, msgtype: str) -> bytes:
    return bytes(typestore().serialize_cdr(message, msgtype))


def deserialize(data: bytes, msgtype: str):
    """The message in a CDR buffer, or MessageError naming the type and what is wrong."""
    if len(data) < 4 or data[:4] != CDR_LE_HEADER:
        raise MessageError(f"{msgtype}: not a little-endian CDR buffer (header {bytes(data[:4]).hex() or 'missing'})")
    try:                                  # rosbags also refuses a buffer longer than the message and its padding
        return typestore().deserialize_cdr(data, msgtype)
    except Exception as exc:              # rosbags raises assorted errors on a short or garbled buffer
        raise MessageError(f"{msgtype}: not a valid CDR buffer of this type ({type(exc).__name__}: {exc})") from None
