"""A run as a ROS 2 bag: ``recording.mcap`` (MCAP, ROS 2 profile, CDR messages with their ros2msg schemas,
zstd-compressed chunks) and ``metadata.yaml`` beside it, so that ``ros2 bag play FOLDER`` (rosbag2's mcap
storage), Foxglove and rosbags open a report folder as it is.

Topics (ROS 2 names and types, Jazzy): /robot_description (std_msgs/String, the URDF, once), /tf_static (the
base, fixed to the world frame, once), /joint_states (measured), /tf (every moving link from the world frame,
at each joint state), /hrc/people and /hrc/robot_capsules
(visualization_msgs/MarkerArray), /speed_scaling_factor (the scaling layer's alpha, std_msgs/Float64),
/hrc/safe_alpha, /hrc/separation, /hrc/margin (Float64), /hrc/replan_request (beta, std_msgs/Bool) and
/diagnostics (the safety events). Message times are the senders' stamps on the wall clock of the run
(`epoch_t0`: the epoch time of the recording's t0). The run's metadata (code version, the configuration's ISO
parameters) is an MCAP metadata record named "hrc"."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import numpy as np
import yaml

from shared.config import CellConfig
from shared.robot.model import URDF_PATH, RobotModel
from shared.ros2 import convert
from shared.ros2.bridge import BY_TOPIC
from shared.ros2.graph import SENSOR
from shared.ros2.types import DISTRO, msgdef, serialize, type_hash
from tools.report import Recording


def offered_qos(topic: str) -> list[dict]:
    """What a topic's publisher offers, as rosbag2 (format 9) writes it in metadata.yaml and in the MCAP
    channel's ``offered_qos_profiles`` (the ros2 profile requires it; ``ros2 bag play`` offers it again, so
    /robot_description replays transient local and a late rviz2 still gets the model): the bridge's own QoS
    of the topic (shared.ros2.bridge.ENDPOINTS), else a stream's (SENSOR); durations 0 (the system default),
    in rosbags' own dump of them."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
    from rosbags.rosbag2.metadata import dump_qos_v9

    endpoint = BY_TOPIC.get(topic)
    q = endpoint.qos if endpoint is not None else SENSOR
    default = QosTime(sec=0, nsec=0)
    return dump_qos_v9([Qos(QosHistory(q.history), q.depth, QosReliability(q.reliability), QosDurability(q.durability),
                            default, default, QosLiveliness.AUTOMATIC, default, False)])


class BagWriter:
    """MCAP with the ROS 2 profile: one schema per type, one channel per topic, counts for metadata.yaml."""

    def __init__(self, path: Path) -> None:
        from mcap.writer import CompressionType, Writer

        self.file = open(path, "wb")
        self.writer = Writer(self.file, compression=CompressionType.ZSTD)
        self.writer.start(profile="ros2", library="hrc-ssm")
        self.schemas: dict[str, int] = {}
        self.channels: dict[str, tuple[int, str]] = {}
        self.counts: dict[str, int] = {}
        self.first = self.last = None

    def write(self, topic: str, msgtype: str, message, t_ns: int) -> None:
        if msgtype not in self.schemas:
            self.schemas[msgtype] = self.writer.register_schema(msgtype, "ros2msg", msgdef(msgtype).encode())
        if topic not in self.channels:
            qos = yaml.safe_dump(offered_qos(topic), default_flow_style=False).strip()
            self.channels[topic] = (self.writer.register_channel(topic, "cdr", self.schemas[msgtype],
                                                                 {"offered_qos_profiles": qos}), msgtype)
            self.counts[topic] = 0
        self.writer.add_message(self.channels[topic][0], log_time=t_ns, data=serialize(message, msgtype),
                                publish_time=t_ns, sequence=self.counts[topic])
        self.counts[topic] += 1
        self.first = t_ns if self.first is None else min(self.first, t_ns)
        self.last = t_ns if self.last is None else max(self.last, t_ns)

    def close(self, metadata: dict[str, str]) -> dict:
        self.writer.add_metadata("hrc", metadata)
        self.writer.finish()
        self.file.close()
        return {"first": self.first or 0, "last": self.last or 0, "counts": dict(self.counts),
                "types": {t: m for t, (_, m) in self.channels.items()}}


def rosbag2_metadata(name: str, info: dict) -> dict:
    """metadata.yaml (rosbag2 format version 9) for one MCAP file `name`."""
    duration = int(info["last"] - info["first"])
    topics = [{"message_count": n, "topic_metadata": {
        "name": topic, "type": info["types"][topic], "serialization_format": "cdr",
        "offered_qos_profiles": offered_qos(topic),
        "type_description_hash": type_hash(info["types"][topic])}} for topic, n in info["counts"].items()]
    total = sum(info["counts"].values())
    return {"rosbag2_bagfile_information": {
        "version": 9, "storage_identifier": "mcap", "relative_file_paths": [name],
        "duration": {"nanoseconds": duration}, "starting_time": {"nanoseconds_since_epoch": int(info["first"])},
        "message_count": total, "topics_with_message_count": topics, "compression_format": "",
        "compression_mode": "", "files": [{"path": name, "starting_time": {"nanoseconds_since_epoch": int(info["first"])},
                                          "duration": {"nanoseconds": duration}, "message_count": total}],
        "custom_data": None, "ros_distro": DISTRO}}


def write_mcap(out: Path, robot: RobotModel, config: CellConfig, rec: Recording, epoch_t0: float,
               code: str = "unknown") -> Path:
    """``out/recording.mcap`` and ``out/metadata.yaml`` from a recording; the MCAP's path."""
    ns = lambda stamp: int(round((stamp - rec.t0 + epoch_t0) * 1e9))
    bag = BagWriter(out / "recording.mcap")
    bag.write("/robot_description", convert.STRING, convert.string(URDF_PATH.read_text()), ns(rec.t0))
    fixed = robot.link_poses(np.zeros(robot.nq), fixed=True)
    bag.write("/tf_static", convert.TF, convert.link_transforms(fixed, "world", ns(rec.t0)), ns(rec.t0))
    last_capsules = -np.inf
    for js in sorted(rec.joint_states, key=lambda m: m.stamp):
        t = ns(js.stamp)
        bag.write("/joint_states", convert.JOINT_STATE, convert.joint_state(robot.joint_names, js.q, js.qd, t), t)
        bag.write("/tf", convert.TF, convert.link_transforms(robot.link_poses(js.q, fixed=False), "world", t), t)
        if js.stamp - last_capsules >= convert.ROBOT_MARKER_PERIOD:
            last_capsules = js.stamp
            bag.write("/hrc/robot_capsules", convert.MARKERS, convert.robot_markers(robot, js.q, t), t)
    for hs in sorted(rec.human_states, key=lambda m: m.stamp):
        bag.write("/hrc/people", convert.MARKERS, convert.people_markers(hs, ns(hs.stamp)), ns(hs.stamp))
    for st in sorted(rec.statuses, key=lambda m: m.stamp):
        t = ns(st.stamp)
        bag.write("/speed_scaling_factor", convert.FLOAT64, convert.float64(st.alpha), t)
        bag.write("/hrc/safe_alpha", convert.FLOAT64, convert.float64(st.safe_alpha), t)
        bag.write("/hrc/replan_request", convert.BOOL, convert.boolean(st.beta), t)
        if st.min_separation is not None:
            bag.write("/hrc/separation", convert.FLOAT64, convert.float64(st.min_separation), t)
        if st.min_margin is not None:
            bag.write("/hrc/margin", convert.FLOAT64, convert.float64(st.min_margin), t)
    for ev in sorted(rec.events, key=lambda m: m.stamp):
        bag.write("/diagnostics", convert.DIAGNOSTICS, convert.diagnostics([ev], ns(ev.stamp)), ns(ev.stamp))
    info = bag.close({"code": code, "ros_distro": DISTRO, "ssm": json.dumps(asdict(config.ssm)),
                      "scaling": json.dumps(asdict(config.scaling)), "prefix": config.keys.prefix})
    (out / "metadata.yaml").write_text(yaml.safe_dump(rosbag2_metadata("recording.mcap", info), sort_keys=False))
    return out / "recording.mcap"


def recording_from_sim(result, human) -> Recording:
    """An in-process run (``evidence.sim.run_shuttle``'s SimResult; `human` its scenario, ``at(t)``) as a
    Recording on its simulated clock, t0 = 0: the commanded joints stand for the measured ones (the simulated
    robot follows its commands), the scaling layer's step each cycle, the scenario's people at each cycle
    (None: a dropout, an invalid track), and each replan as an info event."""
    from shared.core.humans import HumanCapsules
    from shared.wire.convert import humans_to_msg, status_from_step
    from shared.wire.messages import JointState, SafetyEvent

    rec = Recording(t0=0.0)
    for r in result.records:
        s = r.step
        rec.joint_states.append(JointState(q=s.q_command, qd=s.qd_command, drive_state="simulated", enabled=True,
                                           fault=False, stamp=r.t))
        rec.statuses.append(status_from_step(s, stamp=r.t))
        people = human.at(r.t)
        rec.human_states.append(humans_to_msg(HumanCapsules.empty() if people is None else people, people is not None,
                                              r.t, stamp=r.t))
    rec.events += [SafetyEvent(source="planner", event="replanned" if e.ok else "replan_refused", severity="info",
                               text=f"{e.reason}: {e.detail}"[:500], value=e.compute_ms, stamp=e.t)
                   for e in result.replans]
    return rec


class ReportError(ValueError):
    """A report folder that cannot be read back (a missing file, a row that is not a trace row), saying where."""


def _rows(path: Path) -> list[dict[str, str]]:
    import csv

    try:
        with open(path, newline="") as f:
            return list(csv.DictReader(f))
    except OSError as exc:
        raise ReportError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except (csv.Error, UnicodeDecodeError) as exc:
        raise ReportError(f"{path}: not a CSV trace: {exc}") from None


def recording_from_report(folder: Path) -> Recording:
    """The joint states, scaler statuses, people and events of an `hrc demo` report folder (trace.csv,
    humans.csv, events.csv; docs/report-format.md), t0 = 0, as a Recording to write a bag from."""
    from shared.wire.messages import HumanState, JointState, SafetyEvent, ScalerStatus

    rec = Recording(t0=0.0)
    num = lambda row, key: float(row[key]) if row.get(key, "") != "" else None
    j6 = lambda row, name: np.array([float(row[f"{name}_{k}"]) for k in range(1, 7)])
    where = "trace.csv"
    try:
        for n, row in enumerate(_rows(folder / "trace.csv"), start=2):
            where = f"trace.csv line {n}"
            t = float(row["t"])
            rec.statuses.append(ScalerStatus(s=float(row["s"]), alpha=float(row["alpha"]),
                                             safe_alpha=float(row["safe_alpha"]), beta=row["beta"] == "1",
                                             q_command=j6(row, "q_cmd"), trajectory_version=int(row["trajectory_version"]),
                                             status=row["status"], method="", min_separation=num(row, "min_separation_m"),
                                             min_margin=None, compute_us=0.0, stamp=t))
            if row.get("q_meas_1", "") != "":
                rec.joint_states.append(JointState(q=j6(row, "q_meas"), qd=j6(row, "qd_meas"),
                                                   drive_state=row["drive_state"] or "unknown", enabled=True,
                                                   fault=False, stamp=t,
                                                   drive_lag=None if (lag := num(row, "drive_lag_ms")) is None
                                                   else lag / 1e3))
        people: dict[tuple[str, str], list[dict]] = {}
        for n, row in enumerate(_rows(folder / "humans.csv"), start=2):
            where = f"humans.csv line {n}"
            people.setdefault((row["t"], row["seq"]), []).append(row)
        for (t, _), rows in people.items():
            where = f"humans.csv at t={t}"
            capsules = [r for r in rows if r["valid"] == "1" and r["capsule"] != ""]
            seg = np.array([[[float(r[k]) for k in ("ax", "ay", "az")], [float(r[k]) for k in ("bx", "by", "bz")]]
                            for r in capsules]).reshape(-1, 2, 3)
            rec.human_states.append(HumanState(segments=seg, radii=np.array([float(r["radius"]) for r in capsules]),
                                               velocities=np.zeros_like(seg), velocity_known=np.zeros(len(capsules), bool),
                                               valid=bool(capsules), sample_stamp=float(t), stamp=float(t)))
        for n, row in enumerate(_rows(folder / "events.csv"), start=2):
            where = f"events.csv line {n}"
            rec.events.append(SafetyEvent(source=row["source"], event=row["event"], severity=row["severity"],
                                          text=row["text"], value=num(row, "value"), stamp=float(row["t"])))
    except (KeyError, ValueError, TypeError) as exc:
        if isinstance(exc, ReportError):
            raise
        raise ReportError(f"{folder}: {where}: not a trace row ({type(exc).__name__}: {exc})") from None
    return rec
