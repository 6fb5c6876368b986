"""Every report's ROS 2 bag: recording.mcap read back with mcap-ros2-support gives the recording's values,
and rosbags opens the folder as a rosbag2 (metadata.yaml), with the types and counts of each topic."""

import json

import numpy as np
import pytest

from evidence.scenarios import Q_GOAL, Q_START
from shared.config import CellConfig
from shared.core.trajectory import straight_line_trajectory
from shared.robot.model import default_robot
from shared.wire.messages import HumanState, JointState, SafetyEvent, ScalerStatus
from tests.util import ROOT
from tools.mcap_record import write_mcap
from tools.report import Recording

ROBOT = default_robot()
EPOCH = 1_764_650_000.0


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    traj = straight_line_trajectory(Q_START, Q_GOAL, ROBOT.limits.velocity, ROBOT.limits.acceleration)
    rec = Recording(t0=100.0)
    for k in range(30):
        t = 100.0 + 0.01 * k
        q, qd, _ = traj.sample(0.01 * k)
        rec.joint_states.append(JointState(q=q, qd=qd, drive_state="enabled", enabled=True, fault=False, stamp=t))
        rec.statuses.append(ScalerStatus(s=0.01 * k, alpha=0.5 + 0.01 * k, safe_alpha=1.0, beta=k > 20,
                                         q_command=q, trajectory_version=1, status="running", method="piqp",
                                         min_separation=None if k == 0 else 0.4, min_margin=0.2, compute_us=50.0,
                                         stamp=t))
    rec.human_states += [HumanState(segments=np.array([[[-1.0, 0, 0.9], [-1.0, 0, 1.5]]]), radii=np.array([0.17]),
                                    velocities=np.zeros((1, 2, 3)), velocity_known=np.ones(1, bool), valid=True,
                                    sample_stamp=0.0, stamp=100.05),
                         HumanState(segments=np.zeros((0, 2, 3)), radii=np.zeros(0), velocities=np.zeros((0, 2, 3)),
                                    velocity_known=np.zeros(0, bool), valid=False, sample_stamp=0.0, stamp=100.2)]
    rec.events.append(SafetyEvent(source="scaler", event="stale_human_data", severity="stop", text="no human sample",
                                  stamp=100.21))
    write_mcap(out, ROBOT, CellConfig(), rec, epoch_t0=EPOCH, code="abc123")
    return out, rec


def test_the_mcap_reads_back_to_the_recordings_values(bag):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    out, rec = bag
    with open(out / "recording.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        by_topic: dict[str, list] = {}
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            by_topic.setdefault(channel.topic, []).append((message.log_time, decoded))
            assert schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        compressions = {c.compression for c in reader.get_summary().chunk_indexes}
    assert header.profile == "ros2" and compressions == {"zstd"}
    positions = np.array([d.position for _, d in by_topic["/joint_states"]])
    assert np.allclose(positions, [js.q for js in rec.joint_states])
    first = by_topic["/joint_states"][0][0]
    assert first == pytest.approx(EPOCH * 1e9, abs=1e3)                      # the run on the wall clock
    assert np.allclose([d.data for _, d in by_topic["/speed_scaling_factor"]], [s.alpha for s in rec.statuses])
    assert [d.data for _, d in by_topic["/hrc/replan_request"]] == [s.beta for s in rec.statuses]
    assert len(by_topic["/hrc/separation"]) == 29                             # not while there is none
    assert len(by_topic["/tf"]) == 30 and len(by_topic["/hrc/robot_capsules"]) == 6   # capsules at 20 Hz
    (fixed,) = [d for _, d in by_topic["/tf_static"]]
    moving = {t.child_frame_id for t in by_topic["/tf"][0][1].transforms}
    assert [t.child_frame_id for t in fixed.transforms] == ["prbt_base_link"] and "prbt_base_link" not in moving
    people = [d for _, d in by_topic["/hrc/people"]]
    assert len(people[0].markers) == 4 and len(people[1].markers) == 1       # a cylinder, two spheres; then cleared
    assert "prbt" in by_topic["/robot_description"][0][1].data
    (events,) = [d for _, d in by_topic["/diagnostics"]]
    assert events.status[0].level == 2 and "stale_human_data" in events.status[0].message
    assert metadata["hrc"]["code"] == "abc123" and "reaction_time" in metadata["hrc"]["ssm"]


def test_rosbags_opens_the_report_folder_as_a_rosbag2(bag):
    from rosbags.highlevel import AnyReader

    out, rec = bag
    with AnyReader([out]) as reader:
        topics = {c.topic: (c.msgtype, c.msgcount) for c in reader.connections}
        assert topics["/joint_states"] == ("sensor_msgs/msg/JointState", 30)
        assert topics["/hrc/people"] == ("visualization_msgs/msg/MarkerArray", 2)
        joint = [c for c in reader.connections if c.topic == "/joint_states"]
        q = [reader.deserialize(raw, c.msgtype).position for c, _, raw in reader.messages(connections=joint)]
        qos = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}
    assert np.allclose(q, [js.q for js in rec.joint_states])
    # each topic offers the bridge's QoS again when played: the URDF and the base frame transient local, the
    # streams reliable and volatile
    latched = ("/robot_description", "/tf_static")
    assert all(len(qos[t]) == 1 and qos[t][0].durability.name == "TRANSIENT_LOCAL" and qos[t][0].depth == 1
               for t in latched)
    assert all(len(q) == 1 and q[0].reliability.name == "RELIABLE" and q[0].durability.name == "VOLATILE"
               for topic, q in qos.items() if topic not in latched)


def test_each_mcap_channel_states_its_offered_qos_as_the_ros2_profile_requires(bag):
    import yaml
    from mcap.reader import make_reader

    out, _ = bag
    with open(out / "recording.mcap", "rb") as f:
        channels = make_reader(f).get_summary().channels.values()
    profiles = {c.topic: yaml.safe_load(c.metadata["offered_qos_profiles"]) for c in channels}
    assert profiles["/robot_description"][0]["durability"] == "transient_local"
    assert profiles["/joint_states"][0] == {**profiles["/joint_states"][0], "history": "keep_last", "depth": 10,
                                            "reliability": "reliable", "durability": "volatile"}


def bag_metadata(folder) -> dict:
    """The MCAP metadata record "hrc" of a folder's recording.mcap."""
    from mcap.reader import make_reader

    with open(folder / "recording.mcap", "rb") as f:
        return {m.name: m.metadata for m in make_reader(f).iter_metadata()}["hrc"]


def test_the_ros2_bridge_is_in_the_supervised_cell_only_when_asked():
    from tools.programs import SERVICES, supervisord_conf

    assert "[program:ros2_bridge]" not in supervisord_conf() and "ros2_bridge" not in SERVICES
    conf = supervisord_conf(("ros2_bridge",))
    section = conf.split("[program:ros2_bridge]")[1]
    assert "-m services.ros2_bridge" in section and "%(ENV_HRC_PORT5)s" in section and "nice -n 10" in section


def test_an_older_report_folder_gets_its_bag_from_the_trace(bag, tmp_path):
    from tests.util import run_hrc
    from tools.mcap_record import ReportError, recording_from_report
    from tools.report import write_trace

    _, rec = bag
    rec.commands = []
    write_trace(tmp_path, rec)
    back = recording_from_report(tmp_path)
    assert len(back.statuses) == 30 and np.allclose([s.alpha for s in back.statuses], [s.alpha for s in rec.statuses])
    assert np.allclose([js.q for js in back.joint_states], [js.q for js in rec.joint_states], atol=1e-6)
    assert [h.valid for h in back.human_states] == [True, False] and back.events[0].event == "stale_human_data"
    done = run_hrc("report", str(tmp_path), "--mcap")
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "recording.mcap").stat().st_size > 0 and "rosbag2_bagfile_information" in \
        (tmp_path / "metadata.yaml").read_text()
    (tmp_path / "summary.json").write_text('{"human_acceleration_m_s2": 0.0}')       # a --paper-formula run
    warned = run_hrc("report", str(tmp_path), "--mcap")
    assert warned.returncode == 0 and "human_acceleration 0.0" in warned.stderr and "--config" in warned.stderr
    paper = run_hrc("report", str(tmp_path), "--mcap", "--config", str(ROOT / "deploy" / "cell-paper.yaml"))
    assert paper.returncode == 0 and "warning" not in paper.stderr
    assert json.loads(bag_metadata(tmp_path)["ssm"])["human_acceleration"] == 0.0
    assert run_hrc("report", str(tmp_path), "--mcap", "--config", str(tmp_path / "none.yaml")).returncode == 2
    lines = (tmp_path / "trace.csv").read_text().splitlines()
    (tmp_path / "trace.csv").write_text("\n".join(lines[:5] + ["0.5,x,1"] + lines[6:]) + "\n")
    with pytest.raises(ReportError, match="trace.csv line 6"):
        recording_from_report(tmp_path)
    refused = run_hrc("report", str(tmp_path), "--mcap")
    assert refused.returncode == 2 and "trace.csv line 6" in refused.stderr
    assert run_hrc("report", str(tmp_path / "nothing"), "--mcap").returncode == 2
    assert run_hrc("report", str(tmp_path)).returncode == 2                  # nothing asked
