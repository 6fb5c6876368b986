"""Writes tests/data/ros2/references.json: CDR bytes and RIHS01 type hashes from real ROS 2, for the byte-exact
tests of shared.ros2 (there is no ROS 2 on the test machines). Run it with an interpreter that has the PyPI
ROS 2 wheels (Kilted, cp311; the message definitions used here are the same in Jazzy):

    python3 -m venv /tmp/rosvenv
    /tmp/rosvenv/bin/pip install ros-rclpy ros-rmw-fastrtps-cpp ros-sensor-msgs ros-std-msgs ros-geometry-msgs
    /tmp/rosvenv/bin/python tests/ros2/make_references.py /tmp/rosvenv

Each case is a message given as plain fields, serialised by rclpy.serialization (the rmw's own CDR), and each
type's hash as the wheel's type description file (share/<package>/msg/<Name>.json) states it."""

import json
import sys
from pathlib import Path

from geometry_msgs.msg import Pose, PoseArray
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, String

CASES = [
    ("sensor_msgs/msg/JointState", {"stamp_ns": 1_764_650_000_123_456_789, "frame_id": "",
                                    "name": [f"prbt_joint_{k}" for k in range(1, 7)],
                                    "position": [0.1, -0.2, 0.3, -0.4, 0.5, -0.6],
                                    "velocity": [0.0, 1.57, -1.57, 0.25, 0.0, 1e-9], "effort": []}),
    ("sensor_msgs/msg/JointState", {"stamp_ns": 0, "frame_id": "world", "name": [], "position": [], "velocity": [],
                                    "effort": []}),
    ("std_msgs/msg/Float64", {"data": 0.8125}),
    ("std_msgs/msg/Bool", {"data": True}),
    ("std_msgs/msg/String", {"data": "<robot name=\"prbt\"/>"}),
    ("std_msgs/msg/String", {"data": "abc"}),
    # inbound: a perception node's arm-only skeleton (ARM_KEYPOINTS' order), and one with an unseen wrist
    ("geometry_msgs/msg/PoseArray", {"stamp_ns": 1_764_650_000_500_000_000, "frame_id": "world", "positions": [
        [-0.9, 0.2, 1.4], [-0.9, -0.2, 1.4], [-0.7, 0.25, 1.2], [-0.7, -0.25, 1.2], [-0.5, 0.2, 1.1],
        [-0.5, -0.2, 1.1]]}),
    ("geometry_msgs/msg/PoseArray", {"stamp_ns": 0, "frame_id": "world", "positions": [
        [-0.9, 0.2, 1.4], [-0.9, -0.2, 1.4], [-0.7, 0.25, 1.2], [-0.7, -0.25, 1.2], [-0.5, 0.2, 1.1],
        [float("nan"), 0.0, 0.0]]}),
]


def build(msgtype: str, fields: dict):
    if msgtype == "sensor_msgs/msg/JointState":
        m = JointState()
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(fields["stamp_ns"], 1_000_000_000)
        m.header.frame_id = fields["frame_id"]
        m.name, m.position, m.velocity, m.effort = fields["name"], fields["position"], fields["velocity"], fields["effort"]
        return m
    if msgtype == "geometry_msgs/msg/PoseArray":
        m = PoseArray()
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(fields["stamp_ns"], 1_000_000_000)
        m.header.frame_id = fields["frame_id"]
        for x, y, z in fields["positions"]:
            pose = Pose()
            pose.position.x, pose.position.y, pose.position.z = x, y, z
            m.poses.append(pose)
        return m
    return {"std_msgs/msg/Float64": Float64, "std_msgs/msg/Bool": Bool, "std_msgs/msg/String": String}[msgtype](**fields)


def main() -> int:
    prefix = Path(sys.argv[1])
    out = {"source": "rclpy.serialization (ros-rclpy, rmw_fastrtps_cpp), PyPI ROS 2 wheels", "cases": [], "hashes": {}}
    for msgtype, fields in CASES:
        out["cases"].append({"type": msgtype, "fields": fields, "cdr": serialize_message(build(msgtype, fields)).hex()})
        package, _, name = msgtype.split("/")
        description = json.loads((prefix / "share" / package / "msg" / f"{name}.json").read_text())
        out["hashes"].update({h["type_name"]: h["hash_string"] for h in description["type_hashes"]})
    target = Path(__file__).resolve().parents[1] / "data" / "ros2" / "references.json"
    target.write_text(json.dumps(out, indent=1) + "\n")
    print(f"{len(out['cases'])} cases, {len(out['hashes'])} hashes -> {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
