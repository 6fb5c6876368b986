"""The ROS 2 bridge as a process, seen by a ROS 2 peer written only from rmw_zenoh's design document: it finds
the bridge's topics by their liveliness tokens, subscribes to the data key a token names, and decodes
/joint_states to what the cell published, every sample with its 33-byte attachment and a rising sequence
number. Goals and people (capsules and skeletons) from ROS 2 reach the cell's keys; samples without an
attachment, garbage, a NaN capsule, a partly seen or stale skeleton and a flood are refused and counted, and the
bridge goes on."""

import os
import struct
import subprocess
import sys
import time

import numpy as np
import pytest

from shared.robot.model import default_robot
from shared.ros2 import convert, types
from shared.tracking.keypoints import ARM_KEYPOINTS, body_capsules
from shared.transport.zenoh_session import await_liveliness, open_session
from shared.wire.keys import KeySpace
from shared.wire.messages import Goal, HumanRaw, JointState, SafetyEvent, decode, encode
from tests.ros2.test_ros2_wire import pose_array
from tests.util import ROOT, free_port

ROBOT = default_robot()
DOMAIN = 7


@pytest.fixture(scope="module")
def bridge():
    port, keys = free_port(), KeySpace(f"test/ros2{os.getpid()}")
    proc = subprocess.Popen([sys.executable, "-m", "services.ros2_bridge", "--prefix", keys.prefix, "--domain",
                             str(DOMAIN), "--listen", f"tcp/127.0.0.1:{port}", "--log-level", "WARNING"], cwd=ROOT,
                            env=dict(os.environ, PYTHONPATH=str(ROOT)), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    session = open_session("peer", listen=[f"tcp/127.0.0.1:{free_port()}"], connect=[f"tcp/127.0.0.1:{port}"])
    try:
        assert await_liveliness(session, keys.alive("ros2_bridge"), 60.0), "the bridge did not come up"
        yield session, keys, proc
    finally:
        session.close()
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()


def ros2_topics(session) -> dict[str, dict]:
    """The graph as a ROS 2 tool builds it: every publisher token under @ros2_lv/<domain>/, split as the
    design document lays it out."""
    found = {}
    for reply in session.liveliness().get(f"@ros2_lv/{DOMAIN}/**", timeout=5.0):
        parts = str(reply.ok.key_expr).split("/")
        if len(parts) == 13 and parts[5] == "MP":
            topic = parts[9].replace("%", "/")
            found[topic] = {"node": parts[8], "type": parts[10], "hash": parts[11], "qos": parts[12]}
    return found


def test_a_ros_2_peer_finds_the_topics_and_reads_the_joint_states(bridge):
    session, keys, proc = bridge
    topics = ros2_topics(session)
    assert {"/joint_states", "/tf", "/tf_static", "/robot_description", "/speed_scaling_factor", "/hrc/people",
            "/diagnostics"} <= set(topics)
    js = topics["/joint_states"]
    assert js["node"] == "hrc_bridge" and js["type"] == "sensor_msgs::msg::dds_::JointState_"
    assert js["hash"] == types.type_hash(convert.JOINT_STATE) and topics["/robot_description"]["qos"].startswith(":1:")
    got = []
    key = f"{DOMAIN}/joint_states/{js['type']}/{js['hash']}"
    sub = session.declare_subscriber(key, lambda s: got.append((s.payload.to_bytes(),
                                                               None if s.attachment is None else s.attachment.to_bytes())))
    pub = session.declare_publisher(keys.joint_state)
    sent = [np.full(6, -0.5)]
    deadline = time.monotonic() + 10.0        # the new subscription reaches the bridge first: not counted
    while not got and time.monotonic() < deadline:
        pub.put(encode(JointState(q=sent[0], qd=np.zeros(6), drive_state="enabled", enabled=True, fault=False,
                                  stamp=time.monotonic())))
        time.sleep(0.05)
    time.sleep(0.1)
    got.clear()
    for k in range(40):
        q = np.full(6, 0.01 * k)
        sent.append(q)
        pub.put(encode(JointState(q=q, qd=np.zeros(6), drive_state="enabled", enabled=True, fault=False, seq=k,
                                  stamp=time.monotonic())))
        time.sleep(0.02)
    time.sleep(0.3)
    sub.undeclare()
    positions = [np.asarray(types.deserialize(payload, convert.JOINT_STATE).position) for payload, _ in got]
    assert len(got) == 40, f"{len(got)} of 40 joint states came through"      # every one, in order, also loaded
    assert all(np.allclose(p, q) for p, q in zip(positions, sent[1:]))
    attachments = [att for _, att in got]
    assert all(att is not None and len(att) == 33 and att[16] == 16 for att in attachments)
    sequence = [struct.unpack_from("<q", att)[0] for att in attachments]
    assert sequence == sorted(sequence) and len(set(sequence)) == len(sequence)
    assert len({att[17:] for att in attachments}) == 1                      # one publisher, one GID


def test_a_late_subscriber_gets_the_robot_description_and_static_frames_from_the_cache(bridge):
    """Transient local as rmw_zenoh does it: a subscriber that comes after the sample asks the publisher's cache."""
    import zenoh.ext

    session, keys, proc = bridge
    got = {}
    subs = []
    for topic, msgtype in (("robot_description", convert.STRING), ("tf_static", convert.TF)):
        key = f"{DOMAIN}/{topic}/{types.dds_type_name(msgtype)}/{types.type_hash(msgtype)}"
        subs.append(zenoh.ext.declare_advanced_subscriber(
            session, key, lambda s, t=topic, m=msgtype: got.setdefault(t, types.deserialize(s.payload.to_bytes(), m)),
            history=zenoh.ext.HistoryConfig(detect_late_publishers=True)))
    deadline = time.monotonic() + 3.0                   # well before the bridge sends them again (every 10 s)
    while len(got) < 2 and time.monotonic() < deadline:
        time.sleep(0.05)
    for sub in subs:
        sub.undeclare()
    assert '<robot name="prbt"' in got["robot_description"].data
    assert [t.child_frame_id for t in got["tf_static"].transforms] == ["prbt_base_link"]


def ros_put(session, topic: str, msgtype: str, payload: bytes, seq: int, attached: bool = True) -> None:
    key = f"{DOMAIN}/{topic.strip('/')}/{types.dds_type_name(msgtype)}/{types.type_hash(msgtype)}"
    attachment = struct.pack("<qqB", seq, time.time_ns(), 16) + bytes(16) if attached else None
    session.put(key, payload, attachment=attachment)


def test_goals_and_people_from_ros_2_reach_the_cell_and_bad_ones_are_refused(bridge):
    session, keys, proc = bridge
    goals, raws, events = [], [], []
    subs = [session.declare_subscriber(keys.goal, lambda s: goals.append(decode(s.payload.to_bytes(), Goal))),
            session.declare_subscriber(keys.human_raw, lambda s: raws.append(decode(s.payload.to_bytes(), HumanRaw))),
            session.declare_subscriber(keys.safety_events,
                                       lambda s: events.append(decode(s.payload.to_bytes(), SafetyEvent)))]
    time.sleep(0.5)
    q = np.array([0.1, -0.2, 0.3, 0.0, 0.4, 0.5])
    goal = types.serialize(convert.joint_state(ROBOT.joint_names, q, np.zeros(6), 0), convert.JOINT_STATE)
    ros_put(session, "/hrc/goal", convert.JOINT_STATE, goal, 1)
    ros_put(session, "/hrc/goal", convert.JOINT_STATE, goal, 2, attached=False)          # refused: no attachment
    seg = np.array([[[-1.0, 0.2, 0.9], [-1.0, 0.2, 1.5]]])
    people = types.serialize(convert.capsule_markers(seg, np.array([0.17]), "p", "world", 0, (1, 1, 1, 1)),
                             convert.MARKERS)
    ros_put(session, "/hrc/perception/people", convert.MARKERS, people, 1)
    time.sleep(0.05)
    ros_put(session, "/hrc/perception/people", convert.MARKERS, b"\x00\x01\x00\x00garbage", 2)   # not the type
    bad = types.deserialize(people, convert.MARKERS)
    bad.markers[1].scale.x = float("nan")
    time.sleep(0.05)
    ros_put(session, "/hrc/perception/people", convert.MARKERS, types.serialize(bad, convert.MARKERS), 3)  # invalid
    for k in range(200):                                                                  # a flood
        ros_put(session, "/hrc/perception/people", convert.MARKERS, people, 10 + k)
    reasons = ("no attachment", "not the type", "invalid", "over the rate")
    deadline = time.monotonic() + 5.0                # the bridge says its refusals once a second
    while time.monotonic() < deadline and not any(e.event == "ros2_refused" and all(why in e.text for why in reasons)
                                                  for e in events):
        time.sleep(0.1)
    for sub in subs:
        sub.undeclare()
    assert [g.name for g in goals] == ["ros2"] and np.allclose(goals[0].q, q)
    assert raws and np.allclose(raws[0].segments, seg) and all(r.source == "ros2" for r in raws)
    assert len(raws) < 150                                           # the flood was cut to the rate
    said = [e.text for e in events if e.event == "ros2_refused"]
    assert said and all(why in said[-1] for why in reasons)
    assert proc.poll() is None                                       # and it goes on


def test_skeletons_from_ros_2_reach_the_tracker_as_capsules_sampled_when_stamped(bridge):
    """An arm-only skeleton on /hrc/perception/arm_keypoints becomes the seven capsules of `hrc human
    from-keypoints` on the cell's raw key, its sample time its header stamp's moment; a skeleton with an unseen
    keypoint (a dropout) and one stamped a second ago (stale) are refused by reason, and nothing of them
    reaches the tracker."""
    session, keys, proc = bridge
    raws, events = [], []
    subs = [session.declare_subscriber(keys.human_raw, lambda s: raws.append(decode(s.payload.to_bytes(), HumanRaw))),
            session.declare_subscriber(keys.safety_events,
                                       lambda s: events.append(decode(s.payload.to_bytes(), SafetyEvent)))]
    time.sleep(0.5)
    points = [[-0.9, 0.2, 1.4], [-0.9, -0.2, 1.4], [-0.7, 0.25, 1.2], [-0.7, -0.25, 1.2], [-0.5, 0.2, 1.1],
              [-0.5, -0.2, 1.1]]
    topic = "/hrc/perception/arm_keypoints"
    sent = time.monotonic()
    ros_put(session, topic, convert.POSES, types.serialize(pose_array(points, t_ns=time.time_ns() - 80_000_000),
                                                           convert.POSES), 1)
    time.sleep(0.05)
    unseen = [*points[:5], [float("nan"), 0.0, 0.0]]
    ros_put(session, topic, convert.POSES, types.serialize(pose_array(unseen), convert.POSES), 2)
    time.sleep(0.05)
    ros_put(session, topic, convert.POSES, types.serialize(pose_array(points, t_ns=time.time_ns() - 1_000_000_000),
                                                           convert.POSES), 3)
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline and not any(e.event == "ros2_refused" and "partly seen" in e.text and
                                                  "stale" in e.text for e in events):
        time.sleep(0.1)
    for sub in subs:
        sub.undeclare()
    expected = body_capsules({k: np.array(p) for k, p in zip(ARM_KEYPOINTS, points)})
    assert len(raws) == 1, [r.segments.shape for r in raws]
    assert np.allclose(raws[0].segments, [[a, b] for _, a, b, _ in expected])
    assert np.allclose(raws[0].radii, [r for *_, r in expected])
    assert sent - 0.08 - 0.03 <= raws[0].sample_time <= sent - 0.08 + 0.03     # when stamped, not when it came
    assert any("partly seen" in e.text and "stale" in e.text for e in events if e.event == "ros2_refused")
    assert proc.poll() is None
