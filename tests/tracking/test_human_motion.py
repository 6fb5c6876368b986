"""Recorded human motion: the multi-person format (JSON and CSV, dropouts), keypoints to capsules, and
`hrc demo --human` running it (in-process here; on the processes in the note's runs)."""

import json
import math

import numpy as np
import pytest

from shared.core.errors import ConfigError
from shared.tracking.keypoints import DIAMETER, KEYPOINTS, FrameTransform, convert, read_keypoints, to_motion
from shared.tracking.motion import RecordedMotion, parse_csv, parse_json
from tools.cli import main

TORSO_A, TORSO_B = [-1.2, 0.0, 0.9], [-1.2, 0.0, 1.45]
DOC = {"schema": "hrc-human-motion/1", "frames": [
    {"t": 10.0, "label": "two people", "people": [
        {"id": "alice", "capsules": [{"name": "torso", "a": TORSO_A, "b": TORSO_B, "radius": 0.17},
                                     {"name": "forearm", "a": [-1.0, -0.2, 1.4], "b": [-0.8, -0.2, 1.1],
                                      "radius": 0.06}]},
        {"id": "bob", "capsules": [{"name": "torso", "a": [-2.0, 1.0, 0.9], "b": [-2.0, 1.0, 1.45], "radius": 0.17}]}]},
    {"t": 10.5, "dropout": True},
    {"t": 10.7, "people": []}]}
CSV = """t,person,capsule,ax,ay,az,bx,by,bz,radius
10.0,alice,torso,-1.2,0.0,0.9,-1.2,0.0,1.45,0.17
10.0,alice,forearm,-1.0,-0.2,1.4,-0.8,-0.2,1.1,0.06
10.0,bob,torso,-2.0,1.0,0.9,-2.0,1.0,1.45,0.17
10.5,,dropout,,,,,,,
10.7,,nobody,,,,,,,
"""


def test_both_formats_give_the_same_people_dropouts_and_empty_frames():
    a, b = parse_json(json.dumps(DOC)), parse_csv(CSV)
    for x, y in zip(a, b):
        assert x.t == y.t and x.dropout == y.dropout and x.people == y.people and x.names == y.names
        assert np.allclose(x.segments, y.segments) and np.allclose(x.radii, y.radii)
    assert a[0].people == ("alice", "alice", "bob") and a[0].names == ("torso", "forearm", "torso")
    assert a[1].dropout and a[2].segments.shape == (0, 2, 3) and not a[2].dropout


def test_a_recorded_motion_measures_velocities_from_frame_to_frame_like_a_tracker():
    doc = {"schema": "hrc-human-motion/1", "frames": [
        {"t": 0.0, "people": [{"id": "a", "capsules": [{"name": "torso", "a": [0, 0, 0], "b": [0, 0, 1], "radius": 0.2}]}]},
        {"t": 0.5, "people": [{"id": "a", "capsules": [{"name": "torso", "a": [0.5, 0, 0], "b": [0.5, 0, 1],
                                                        "radius": 0.2}]},
                              {"id": "b", "capsules": [{"name": "torso", "a": [2, 0, 0], "b": [2, 0, 1], "radius": 0.2}]}]}]}
    later = RecordedMotion(parse_json(json.dumps(doc))).at(0.6)
    assert np.allclose(later.velocities[0], [[1.0, 0, 0], [1.0, 0, 0]]) and later.velocity_known.tolist() == [True, False]


def test_a_recorded_motion_holds_each_frame_and_is_silent_in_a_dropout():
    motion = RecordedMotion(parse_json(json.dumps(DOC)))
    assert motion.duration == pytest.approx(0.7) and motion.people() == ["alice", "bob"]
    first = motion.at(0.2)
    assert first.count == 3 and np.allclose(first.segments[0], [TORSO_A, TORSO_B])
    assert not first.velocity_known.any()              # the first frame: no velocities yet (ISO speeds apply)
    assert motion.at(0.5) is None and motion.at(0.69) is None       # dropout: nothing is sent
    assert motion.at(0.7).count == 0 and motion.at(99.0).count == 0  # nobody, and held after the end
    assert motion.phase(0.0) == "two people" and motion.phase(0.6) == "tracker dropout"
    assert motion.phase(1.0) == "nobody"


@pytest.mark.parametrize("frames, place", [
    ([{"t": 0, "people": [{"id": "", "capsules": []}]}], r"frames\[0\]\.people\[0\]\.id"),
    ([{"t": 0, "people": [{"id": "a", "capsules": [{"name": "x", "a": [0, 0, 0], "b": [0, 0, 0]}]}]}],
     r"frames\[0\]\.people\[0\]\.capsules\[0\]\.radius"),
    ([{"t": 0, "people": [{"id": "a", "capsules": [{"name": "x", "a": [0, 0, "up"], "b": [0, 0, 0],
                                                   "radius": 0.1}]}]}], r"capsules\[0\]\.a"),
    ([{"t": 0, "dropout": True, "people": [{"id": "a", "capsules": []}]}], r"frames\[0\]: a dropout frame"),
    ([{"t": 0, "people": []}, {"t": 0, "people": []}], r"frames\[1\]: t = 0.0 repeats"),
    ([{"t": 1, "people": []}, {"t": 0.5, "people": []}], r"frames\[1\]: t = 0.5 goes back"),
    ([{"t": 0, "dropout": "yes"}], r"frames\[0\]\.dropout"),
    ([{"t": 0}], r"frames\[0\]\.people: expected a list"),
])
def test_bad_motion_files_name_the_frame_and_the_field(frames, place):
    with pytest.raises(ConfigError, match=place):
        parse_json(json.dumps({"schema": "hrc-human-motion/1", "frames": frames}))


def test_bad_csv_rows_name_the_line_and_the_field():
    with pytest.raises(ConfigError, match="line 3: capsule"):
        parse_csv(CSV.replace("10.0,alice,forearm", "10.0,alice,"))
    with pytest.raises(ConfigError, match="line 5: a dropout row has no coordinates"):
        parse_csv(CSV.replace("10.5,,dropout,,,", "10.5,,dropout,1,,"))
    with pytest.raises(ConfigError, match="line 2: radius must be positive"):
        parse_csv(CSV.replace("1.45,0.17\n10.0,alice", "1.45,-0.17\n10.0,alice"))


def keypoint_rows(person: str, x0: float, t: float, skip: str = "") -> list[str]:
    """A person standing at (x0, 0) with the right arm stretched out along +x, in mm."""
    points = {"head": (x0, 0, 1.7), "l_shoulder": (x0, 0.2, 1.45), "r_shoulder": (x0, -0.2, 1.45),
              "l_elbow": (x0, 0.25, 1.15), "r_elbow": (x0 + 0.3, -0.2, 1.45), "l_hand": (x0, 0.25, 0.9),
              "r_hand": (x0 + 0.6, -0.2, 1.45), "l_hip": (x0, 0.15, 0.95), "r_hip": (x0, -0.15, 0.95),
              "nose": (x0 + 0.1, 0, 1.7)}                      # not one of ours: ignored
    return [f"{t},{person},{k},{p[0] * 1000},{p[1] * 1000},{p[2] * 1000}" for k, p in points.items() if k != skip]


def test_keypoints_become_eight_capsules_per_person_in_the_robot_frame(tmp_path):
    rows = ["t,person,keypoint,x,y,z"] + keypoint_rows("alice", 1.0, 0.0) + keypoint_rows("bob", 2.0, 0.0) \
        + keypoint_rows("alice", 1.0, 0.1, skip="r_hand") + keypoint_rows("bob", 2.0, 0.1)
    src = tmp_path / "kp.csv"
    src.write_text("\n".join(rows) + "\n")
    # mm in, rotated a quarter turn about z and shifted: x -> y, y -> -x, then +(-1, 0, 0)
    transform = FrameTransform(scale=1e-3, yaw=math.pi / 2, translation=(-1.0, 0.0, 0.0))
    frames, dropouts = convert(src, tmp_path / "motion.json", transform)
    assert (frames, dropouts) == (2, 1)
    motion = RecordedMotion.load(tmp_path / "motion.json")
    first = motion.frames[0]
    assert first.people.count("alice") == 8 and first.people.count("bob") == 8
    torso = first.segments[first.names.index("torso")]
    assert np.allclose(torso, [[-1.0, 1.0, 0.95], [-1.0, 1.0, 1.45]])           # hips and shoulders, moved
    reach = first.segments[first.names.index("r_forearm")]
    assert np.allclose(reach[1], [-1.0 + 0.2, 1.6, 1.45])                        # the hand, 0.6 m along +y now
    assert first.radii[first.names.index("head")] == pytest.approx(DIAMETER["head"] / 2)
    assert first.radii[first.names.index("r_forearm")] == pytest.approx(0.066)
    assert motion.frames[1].dropout and "alice: no r_hand" in motion.frames[1].label   # never a partial body
    # the CSV form of the same motion reads back to the same capsules
    convert(src, tmp_path / "motion.csv", transform)
    again = RecordedMotion.load(tmp_path / "motion.csv")
    assert np.allclose(again.frames[0].segments, first.segments, atol=1e-5)


def test_a_y_up_capture_volume_is_turned_z_up():
    body = {k: np.array([0.0, 1.0, 0.0]) for k in KEYPOINTS}
    doc, _ = to_motion([(0.0, {"p": body})], FrameTransform(y_up=True))
    assert doc["frames"][0]["people"][0]["capsules"][0]["a"] == [0.0, 0.0, 1.0]


@pytest.mark.parametrize("text, place", [
    ("t,person,kp,x,y,z\n", "line 1"),
    ("t,person,keypoint,x,y,z\n0,a,head,1,2\n", "line 2: expected 6 values"),
    ("t,person,keypoint,x,y,z\n0,a,head,1,2,inf\n", "line 2: z"),
    ("t,person,keypoint,x,y,z\n0,,head,1,2,3\n", "line 2: person"),
    ("t,person,keypoint,x,y,z\n1,a,head,1,2,3\n0,a,head,1,2,3\n", "line 3: t = 0.0 goes back"),
    ("t,person,keypoint,x,y,z\n0,a,head,1,2,3\n0,a,head,1,2,3\n", "line 3: keypoint 'head' of 'a' twice"),
])
def test_bad_keypoint_files_name_the_line_and_the_field(text, place):
    with pytest.raises(ConfigError, match=place):
        read_keypoints(text)


def test_hrc_converts_keypoints_and_runs_the_demo_on_them(tmp_path, capsys):
    rows = ["t,person,keypoint,x,y,z"]
    for k in range(40):                                    # a person walking up to the robot's working side
        rows += keypoint_rows("alice", -2.4 + 0.035 * k, round(0.1 * k, 2))
    src = tmp_path / "walk.csv"
    src.write_text("\n".join(rows) + "\n")
    motion = tmp_path / "walk.json"
    assert main(["human", "from-keypoints", str(src), str(motion), "--units", "mm"]) == 0
    for bad_every in ("0", "2.5", "x"):                   # a tracker at 1/N the rate: N a whole number >= 1
        with pytest.raises(SystemExit) as exit_:
            main(["human", "from-keypoints", str(src), str(tmp_path / "every.json"), "--every", bad_every])
        assert exit_.value.code == 2 and "--every" in capsys.readouterr().err
    assert main(["human", "from-keypoints", str(src), str(tmp_path / "every.json"), "--units", "mm", "--every", "3"]) == 0
    assert len(json.loads((tmp_path / "every.json").read_text())["frames"]) == 14     # frames 0, 3, ..., 39
    out = tmp_path / "report"
    assert main(["demo", "--sim", "--human", str(motion), "--quiet", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["duration_s"] == pytest.approx(3.9, abs=0.02)      # the motion's own length
    assert summary["violations"] == 0 and summary["mean_alpha"] < 1.0  # she slowed it, safely
    from rosbags.highlevel import AnyReader  # and the run is a ROS 2 bag too

    with AnyReader([out]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        people = [c for c in reader.connections if c.topic == "/hrc/people"]
        shown = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=people)]
    assert summary["ros2_bag"] == "recording.mcap" and counts["/joint_states"] == summary["cycles"] == len(shown)
    assert max(len(m.markers) for m in shown) == 1 + 3 * 8           # her eight capsules, as markers
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"schema": "hrc-human-motion/1", "frames": [{"t": 0, "people": [{"id": "a"}]}]}))
    capsys.readouterr()
    assert main(["demo", "--human", str(bad), "--out", str(tmp_path / "never")]) == 2
    assert "frames[0].people[0]" in capsys.readouterr().err and not (tmp_path / "never").exists()
