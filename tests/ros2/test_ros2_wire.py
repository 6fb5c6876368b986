"""ROS 2 on the wire, against byte-exact references (there is no ROS 2 here): CDR bytes as rclpy serialises
them (tests/data/ros2/references.json, made by tests/ros2/make_references.py from the PyPI ROS 2 wheels), type
hashes as the wheels' type descriptions state them, keys and liveliness tokens as ros2/rmw_zenoh's
docs/design.md shows them, and every other message read back by an independent CDR decoder (mcap-ros2-support)."""

import json
import struct

import numpy as np
import pytest
import xxhash

from shared.core.errors import MessageError
from shared.robot.model import default_robot
from shared.ros2 import convert, graph, types
from shared.tracking.keypoints import ARM_KEYPOINTS, KEYPOINTS, body_capsules
from tests.util import ROOT

REFERENCES = json.loads((ROOT / "tests" / "data" / "ros2" / "references.json").read_text())
ROBOT = default_robot()


def padding(msgtype: str, fields: dict) -> set[int]:
    """The byte positions of a CDR buffer that are alignment padding (their value is free: rclpy's leaves
    whatever was in memory), walked from the layout of the types in the references."""
    pad, at = set(), 4                                # after the encapsulation header; alignment is from there

    def align(n: int) -> None:
        nonlocal at
        while (at - 4) % n:
            pad.add(at)
            at += 1

    def u32() -> None:
        nonlocal at
        align(4)
        at += 4

    def text(s: str) -> None:
        nonlocal at
        u32()
        at += len(s.encode()) + 1

    def f64s(xs) -> None:
        nonlocal at
        u32()
        if xs:
            align(8)
        at += 8 * len(xs)

    if msgtype == "sensor_msgs/msg/JointState":
        u32(), u32(), text(fields["frame_id"])
        u32()
        for name in fields["name"]:
            text(name)
        for key in ("position", "velocity", "effort"):
            f64s(fields[key])
    elif msgtype == "std_msgs/msg/String":
        text(fields["data"])
    elif msgtype == convert.POSES:
        u32(), u32(), text(fields["frame_id"])
        u32()
        if fields["positions"]:
            align(8)
    return pad


def ours(msgtype: str, fields: dict):
    if msgtype == convert.JOINT_STATE:
        m = convert.joint_state(fields["name"], np.array(fields["position"]), np.array(fields["velocity"]),
                                fields["stamp_ns"])
        m.header.frame_id = fields["frame_id"]
        return m
    if msgtype == convert.POSES:
        return pose_array(fields["positions"], fields["frame_id"], fields["stamp_ns"])
    return types.msg_class(msgtype)(**fields)


def pose_array(positions, frame: str = "world", t_ns: int = 0):
    """A geometry_msgs/PoseArray of these positions (m), unrotated, as a perception node sends keypoints."""
    Pose, Point = types.msg_class("geometry_msgs/msg/Pose"), types.msg_class("geometry_msgs/msg/Point")
    upright = types.msg_class("geometry_msgs/msg/Quaternion")(x=0.0, y=0.0, z=0.0, w=1.0)
    return types.msg_class(convert.POSES)(header=convert.header(t_ns, frame), poses=[
        Pose(position=Point(x=float(x), y=float(y), z=float(z)), orientation=upright) for x, y, z in positions])


@pytest.mark.parametrize("case", REFERENCES["cases"], ids=lambda c: c["type"])
def test_cdr_bytes_are_rclpys_but_for_the_free_padding(case):
    mine = types.serialize(ours(case["type"], case["fields"]), case["type"])
    ref = bytes.fromhex(case["cdr"])
    assert mine[:4] == types.CDR_LE_HEADER and len(ref) >= len(mine)     # rclpy's buffer may run on past the end
    free = padding(case["type"], case["fields"])
    assert [i for i in range(len(mine)) if mine[i] != ref[i] and i not in free] == []


def test_type_hashes_are_the_ros_2_type_descriptions():
    for msgtype, rihs in REFERENCES["hashes"].items():
        assert types.type_hash(msgtype) == rihs, msgtype


def test_keys_and_tokens_are_rmw_zenohs():
    """The examples of rmw_zenoh's design document, rebuilt."""
    string_hash = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
    assert graph.topic_key(0, "/chatter", "std_msgs/msg/String") == f"0/chatter/std_msgs::msg::dds_::String_/{string_hash}"
    assert graph.topic_key(0, "/robot1/chatter", "std_msgs/msg/String").startswith("0/robot1/chatter/")
    assert graph.node_token(2, "aac3178e146ba6f1fc6e6a4085e77f21", 0, "listener") == \
        "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
    assert graph.endpoint_token(2, "aac3178e146ba6f1fc6e6a4085e77f21", 0, 10, graph.SUBSCRIPTION, "listener",
                                "/chatter", "std_msgs/msg/String", graph.Qos(depth=10)) == \
        f"@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MS/%/%/listener/%chatter/std_msgs::msg::dds_::String_/{string_hash}/::,10:,:,:,,"
    assert graph.endpoint_token(2, "8b20917502ee955ac4476e0266340d5c", 0, 10, graph.PUBLISHER, "talker", "/chatter",
                                "std_msgs/msg/String", graph.Qos(depth=7)).endswith("/MP/%/%/talker/%chatter/"
                                                                                    f"std_msgs::msg::dds_::String_/{string_hash}/::,7:,:,:,,")
    assert graph.LATCHED.keyexpr() == ":1:,1:,:,:,," and graph.Qos().keyexpr() == "::,:,:,:,,"
    assert graph.mangle("/hrc/goal") == "%hrc%goal" and graph.mangle("") == "%"
    with pytest.raises(ValueError):
        graph.endpoint_token(0, "z", 0, 1, "SS", "n", "/t", "std_msgs/msg/Bool", graph.SENSOR)


def test_the_gid_is_the_tokens_xxh3_128_and_every_attachment_33_bytes():
    token = graph.node_token(0, "ab", 0, "hrc_bridge")
    digest = xxhash.xxh3_128_digest(token.encode())                 # canonical: big-endian high, then low
    assert graph.gid(token) == digest[8:][::-1] + digest[:8][::-1]
    att = graph.attachment(7, 1_764_650_000_000_000_001, graph.gid(token))
    assert len(att) == 33 and att[16] == 16 and struct.unpack_from("<qq", att) == (7, 1_764_650_000_000_000_001)
    assert graph.parse_attachment(att) == (7, 1_764_650_000_000_000_001, graph.gid(token))
    for bad in (None, b"", att[:-1], att + b"\x00", att[:16] + b"\x08" + att[17:]):
        with pytest.raises(MessageError, match="attachment"):
            graph.parse_attachment(bad)


def decoded(msgtype: str, data: bytes):
    """The message as mcap-ros2-support's own CDR decoder reads it, from the type's .msg text."""
    from mcap_ros2._dynamic import generate_dynamic
    return generate_dynamic(msgtype, types.msgdef(msgtype))[msgtype](data)


def test_every_outgoing_message_reads_back_with_an_independent_decoder():
    q = np.array([0.1, -0.5, 0.7, 0.0, 1.2, -3.0])
    js = decoded(convert.JOINT_STATE, types.serialize(convert.joint_state(ROBOT.joint_names, q, -q, 1_500_000_000_250),
                                                      convert.JOINT_STATE))
    assert js.name == ROBOT.joint_names and np.allclose(js.position, q) and np.allclose(js.velocity, -q)
    assert (js.header.stamp.sec, js.header.stamp.nanosec) == (1500, 250)
    poses = ROBOT.link_poses(q)
    fixed, moving = ROBOT.link_poses(q, fixed=True), ROBOT.link_poses(q, fixed=False)
    assert [n for n, _ in fixed] == ["prbt_base_link"] and {n for n, _ in fixed + moving} == {n for n, _ in poses}
    assert np.allclose(fixed[0][1], ROBOT.link_poses(-q, fixed=True)[0][1])        # /tf_static: no joint moves it
    tf = decoded(convert.TF, types.serialize(convert.link_transforms(poses, "world", 5), convert.TF))
    flange = next(t for t in tf.transforms if t.child_frame_id == "prbt_flange")
    assert np.allclose([flange.transform.translation.x, flange.transform.translation.y, flange.transform.translation.z],
                       ROBOT.flange_pose(q).translation)
    rotation = ROBOT.flange_pose(q).rotation
    x, y, z, w = (flange.transform.rotation.x, flange.transform.rotation.y, flange.transform.rotation.z,
                  flange.transform.rotation.w)
    assert np.allclose(rotation[:, 2], [2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
    seg = ROBOT.capsule_segments(q)
    markers = decoded(convert.MARKERS, types.serialize(convert.capsule_markers(seg, ROBOT.radii, "robot", "world", 5,
                                                                               (1, 0, 0, 1)), convert.MARKERS))
    assert markers.markers[0].action == convert.DELETEALL and len(markers.markers) == 1 + 3 * len(seg)
    spheres = [m for m in markers.markers if m.type == convert.SPHERE]
    assert np.allclose([[m.pose.position.x, m.pose.position.y, m.pose.position.z] for m in spheres],
                       seg.reshape(-1, 3))
    for msgtype, message, value in ((convert.FLOAT64, convert.float64(0.25), 0.25),
                                    (convert.BOOL, convert.boolean(True), True),
                                    (convert.STRING, convert.string("prbt"), "prbt")):
        assert decoded(msgtype, types.serialize(message, msgtype)).data == value


def test_people_and_goals_from_ros_2_and_bad_ones_refused():
    seg = np.array([[[-1.0, 0.2, 0.9], [-1.0, 0.2, 1.5]], [[-0.8, 0.0, 1.2], [-0.4, 0.3, 1.2]]])
    radii = np.array([0.17, 0.05])
    wire = types.serialize(convert.capsule_markers(seg, radii, "person-1", "world", 0, (1, 1, 1, 1)), convert.MARKERS)
    people = convert.people_from_markers(types.deserialize(wire, convert.MARKERS))
    order = np.argsort(people.radii)[::-1]
    assert np.allclose(np.sort(people.segments[order], axis=1), np.sort(seg, axis=1), atol=1e-9)
    assert np.allclose(people.radii[order], radii) and not people.velocity_known.any()
    markers = types.deserialize(wire, convert.MARKERS)
    markers.markers[1].pose.position.x = float("nan")
    with pytest.raises(MessageError, match="finite"):
        convert.people_from_markers(markers)
    q = np.array([0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    goal = convert.joint_state(ROBOT.joint_names[::-1], q[::-1], np.zeros(6), 0)     # named, in another order
    assert np.allclose(convert.goal_positions(goal, ROBOT.joint_names), q)
    for names, positions in ((ROBOT.joint_names[:5], q[:5]), (["a"] * 6, q), (ROBOT.joint_names, q * np.nan),
                             ([], q[:3])):
        with pytest.raises(MessageError, match="goal"):
            convert.goal_positions(convert.joint_state(names, positions, np.zeros(len(positions)), 0), ROBOT.joint_names)


def test_a_buffer_that_is_not_the_type_is_a_clear_error():
    good = types.serialize(convert.joint_state(ROBOT.joint_names, np.zeros(6), np.zeros(6), 0), convert.JOINT_STATE)
    rng = np.random.default_rng(3)
    for bad in (b"", b"\x00\x01", b"\x01\x00\x00\x00" + good[4:], good[:-9], good[: len(good) // 2], good + bytes(16),
                bytes(rng.integers(0, 256, 300, dtype=np.uint8))):
        with pytest.raises(MessageError, match="sensor_msgs/msg/JointState"):
            types.deserialize(bad, convert.JOINT_STATE)
    assert types.deserialize(good, convert.JOINT_STATE).name == ROBOT.joint_names


def test_keypoints_from_ros_2_become_the_capsules_of_hrc_human_from_keypoints():
    """rclpy's own PoseArray bytes, read by the bridge's reader: each person's capsules are body_capsules' (the
    code of `hrc human from-keypoints`), an unseen keypoint is a dropout, bad arrays are refused by reason."""
    cases = [c for c in REFERENCES["cases"] if c["type"] == convert.POSES]
    arms = types.deserialize(bytes.fromhex(cases[0]["cdr"]), convert.POSES)
    people = convert.people_from_keypoints(arms, ARM_KEYPOINTS)
    points = {k: np.array(p) for k, p in zip(ARM_KEYPOINTS, cases[0]["fields"]["positions"])}
    expected = body_capsules(points)
    assert people.count == len(expected) == 7 and not people.velocity_known.any()
    assert np.allclose(people.segments, [[a, b] for _, a, b, _ in expected])
    assert np.allclose(people.radii, [r for *_, r in expected])
    with pytest.raises(MessageError, match="not seen") as seen:
        convert.people_from_keypoints(types.deserialize(bytes.fromhex(cases[1]["cdr"]), convert.POSES), ARM_KEYPOINTS)
    assert seen.value.reason == "partly seen"
    full = {k: np.array([-0.8, 0.0, 1.0]) + 0.1 * i for i, k in enumerate(KEYPOINTS)}
    two = convert.people_from_keypoints(pose_array([*full.values(), *[p + [0, 1.0, 0] for p in full.values()]]),
                                        KEYPOINTS)
    assert two.count == 16 and np.allclose(two.segments[:8], [[a, b] for _, a, b, _ in body_capsules(full)])
    assert convert.people_from_keypoints(pose_array([]), ARM_KEYPOINTS).count == 0      # nobody in view
    for positions, frame, match in ((list(full.values())[:7], "world", "whole people"),
                                    (list(points.values()), "camera_link", "frame"),
                                    ([[np.inf, 0, 0]] + list(points.values())[1:], "world", "infinite"),
                                    ([[50.0, 0, 0]] + list(points.values())[1:], "world", "farther"),
                                    (list(points.values()) * 10, "world", "more than")):
        with pytest.raises(MessageError, match=match) as refused:
            convert.people_from_keypoints(pose_array(positions, frame), ARM_KEYPOINTS)
        assert refused.value.reason == "invalid"


def test_a_samples_age_is_its_header_stamps():
    stamp = lambda t_ns: convert.stamp(t_ns)  # noqa: E731
    now = 1_764_650_000_000_000_000
    assert convert.sample_age([stamp(0)], now) == 0.0                      # unset: the arrival stands for it
    assert convert.sample_age([], now) == 0.0
    assert convert.sample_age([stamp(now - 40_000_000), stamp(now - 90_000_000)], now) == pytest.approx(0.04)
    assert convert.sample_age([stamp(now + 5_000_000_000)], now) == 0.0    # a clock ahead of this one
    with pytest.raises(MessageError, match="stamped") as stale:
        convert.sample_age([stamp(now - 600_000_000)], now)
    assert stale.value.reason == "stale"
