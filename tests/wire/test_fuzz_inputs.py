"""Bad input everywhere: every file loader fuzzed with hypothesis (structured YAML/JSON documents near the
real schema, and raw text and bytes), and every CLI command given bad arguments. A loader either
returns a valid object or raises the project's ConfigError naming what is wrong; the CLI exits non-zero
with a message, never a traceback."""

import json
import tempfile
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from shared.config import load_config
from shared.core.errors import ConfigError
from shared.planning.scene import load_scene
from shared.tracking.motion import load_replay, parse_csv, parse_json
from tests.util import run_hrc

scalars = st.none() | st.booleans() | st.integers(-10 ** 6, 10 ** 6) | st.floats(allow_nan=True) | st.text(max_size=12)
values = st.recursive(scalars, lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=10), inner,
                                                                                             max_size=4), max_leaves=20)
KEYS = {"config": ["cell", "ssm", "scaling", "reaction_time", "stopping_time", "period", "alpha_min", "solver",
                   "min_separation", "human_timeout", "planning", "patience", "posture_gap", "judge", "ros2"],
        "scene": ["floor_z", "boxes", "capsules", "name", "center", "size", "a", "b", "radius"],
        "replay": ["frames", "t", "capsules", "a", "b", "radius"]}


def near_schema(kind):
    """Documents shaped like the real ones (known keys, nested), with arbitrary values."""
    key = st.sampled_from(KEYS[kind]) | st.text(max_size=8)
    leaf = values | st.lists(st.floats(allow_nan=True), min_size=0, max_size=4)
    return st.recursive(leaf, lambda inner: st.dictionaries(key, inner, max_size=5) | st.lists(inner, max_size=3),
                        max_leaves=25)


def _loads(loader, payload: bytes, suffix: str):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"input{suffix}"
        path.write_bytes(payload)
        try:
            loader(path)
        except ConfigError as exc:
            assert str(exc)                                   # a message that says something


FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@FUZZ
@given(near_schema("config"))
def test_config_loader_takes_any_document(doc):
    _loads(load_config, yaml.safe_dump(doc).encode(), ".yaml")


@FUZZ
@given(near_schema("scene"))
def test_scene_loader_takes_any_document(doc):
    _loads(load_scene, yaml.safe_dump(doc).encode(), ".yaml")


@FUZZ
@given(near_schema("replay"))
def test_replay_json_loader_takes_any_document(doc):
    _loads(load_replay, json.dumps(doc).encode(), ".json")


@FUZZ
@given(st.lists(st.lists(st.text(alphabet="0123456789.,-eE naNinf", max_size=10), max_size=12), max_size=6))
def test_replay_csv_loader_takes_any_table(rows):
    text = "\n".join(",".join(r) for r in rows)
    for parse in (parse_csv, parse_json):
        try:
            parse(text)
        except ConfigError:
            pass


@FUZZ
@given(st.lists(st.lists(st.text(alphabet="0123456789.-eE naNinf", max_size=10), max_size=20), max_size=6))
def test_the_camera_skeleton_readers_take_any_table(rows):
    """The human-assembly rows and a keypoints CSV: a motion or ConfigError, whatever the numbers (a NaN is a
    keypoint not seen, a dropout frame), never another exception."""
    from shared.tracking.keypoints import FrameTransform, read_assembly, read_keypoints, to_motion

    for reader, sep in ((read_assembly, " "), (read_keypoints, ",")):
        try:
            to_motion(reader("\n".join(sep.join(r) for r in rows), "fuzz"), FrameTransform(camera=True))
        except ConfigError:
            pass


coordinate = st.floats(allow_nan=True, allow_infinity=True) | st.floats(-3.0, 3.0)


@FUZZ
@given(st.lists(st.tuples(coordinate, coordinate, coordinate), max_size=40), st.sampled_from(["world", "", "camera"]),
       st.integers(0, 2 ** 31), st.booleans())
def test_skeletons_from_ros_2_are_capsules_or_a_counted_refusal(positions, frame, stamp_s, arms):
    """Any PoseArray on a keypoint topic: the people's capsules, or a MessageError with the reason it is counted
    under; any header stamp: an age, or a refusal as stale. Nothing else escapes the bridge's readers."""
    from shared.core.errors import MessageError
    from shared.ros2 import convert
    from shared.tracking.keypoints import ARM_KEYPOINTS, KEYPOINTS
    from tests.ros2.test_ros2_wire import pose_array

    message = pose_array([list(p) for p in positions], frame, stamp_s * 1_000_000_000)
    try:
        people = convert.people_from_keypoints(message, ARM_KEYPOINTS if arms else KEYPOINTS)
        assert np.all(np.isfinite(people.segments)) and np.all(people.radii > 0)
    except MessageError as exc:
        assert str(exc) and exc.reason in ("invalid", "partly seen")
    try:
        assert convert.sample_age([message.header.stamp], 1_764_650_000_000_000_000) >= 0.0
    except MessageError as exc:
        assert exc.reason == "stale"


@FUZZ
@given(st.binary(max_size=200), st.sampled_from([(load_config, ".yaml"), (load_scene, ".yaml"),
                                                 (load_replay, ".json"), (load_replay, ".csv")]))
def test_every_loader_takes_raw_bytes(payload, loader_suffix):
    loader, suffix = loader_suffix
    _loads(loader, payload, suffix)


@pytest.mark.parametrize("args", [
    ["goal"], ["goal", "1", "2"], ["goal", "a", "b", "c", "d", "e", "f"], ["goal", "9", "0", "0", "0", "0", "0"],
    ["goal", "nowhere"], ["goal", "q_g", "--timeout", "-1"], ["goal", "q_g", "--prefix", "bad/*/prefix"],
    ["human"], ["human", "inject"], ["human", "inject", "0", "0", "0", "0", "0", "nan"],
    ["human", "inject", "0", "0", "0", "0", "0", "1", "--velocity", "1", "0", "0"],
    ["human", "inject", "0", "0", "0", "0", "0", "1", "--radius", "0"],
    ["human", "replay", "/nonexistent.csv"], ["status", "--timeout", "zero"], ["status", "--connect", "tcp/8.8.8.8:7447"],
    ["up", "--port", "80"], ["down", "--prefix", "no/such/cell"], ["recover", "--timeout", "inf"],
    ["demo", "--phase-length", "0"], ["demo", "--seed", "x"], ["demo", "--scene", "/nonexistent.yaml", "--sim"],
    ["certs"], ["certs", "--out", "/proc/no/such/dir"], ["certs", "--out", "/nonexistent-hrc-certs", "--hosts", ""],
    ["faults", "--only", "unplug"], ["faults", "--timeout", "0"], ["faults", "--prefix", "bad/*/prefix"],
    ["--bogus"], [],
])
def test_every_command_refuses_bad_arguments_clearly(args):
    out = run_hrc(*args)                     # in-process: an escaping exception fails here
    assert out.returncode != 0, (args, out.stdout)
    assert "Traceback" not in out.stderr, (args, out.stderr)
    assert out.stderr.strip() or out.stdout.strip(), args
