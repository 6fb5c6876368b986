"""Replay files: both formats, errors that name the place, and garbage never crashes the loader."""

import json

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from shared.core.errors import ConfigError
from shared.tracking.motion import load_replay, parse_csv, parse_json

CSV = """t,ax,ay,az,bx,by,bz,radius
0.00,-1.2,0.0,0.90,-1.2,0.0,1.45,0.17
0.00,-1.0,-0.2,1.40,-0.8,-0.2,1.10,0.06
0.02,-1.1,0.0,0.90,-1.1,0.0,1.45,0.17
"""


def test_csv_groups_rows_into_frames(tmp_path):
    path = tmp_path / "walk.csv"
    path.write_text(CSV)
    frames = load_replay(path)
    assert [f.t for f in frames] == [0.0, 0.02]
    assert frames[0].segments.shape == (2, 2, 3) and frames[1].segments.shape == (1, 2, 3)
    assert np.allclose(frames[0].radii, [0.17, 0.06])


def test_json_gives_the_same_frames(tmp_path):
    doc = {"schema": "hrc-human-replay/1", "frames": [
        {"t": 0.0, "capsules": [{"a": [-1.2, 0, 0.9], "b": [-1.2, 0, 1.45], "radius": 0.17},
                                {"a": [-1.0, -0.2, 1.4], "b": [-0.8, -0.2, 1.1], "radius": 0.06}]},
        {"t": 0.02, "capsules": [{"a": [-1.1, 0, 0.9], "b": [-1.1, 0, 1.45], "radius": 0.17}]}]}
    path = tmp_path / "walk.json"
    path.write_text(json.dumps(doc))
    a, b = load_replay(path), parse_csv(CSV)
    assert all(np.allclose(x.segments, y.segments) and x.t == y.t for x, y in zip(a, b))


@pytest.mark.parametrize("text, place", [
    ("t,ax\n", "line 1"),
    (CSV.replace("0.02,-1.1", "-0.5,-1.1"), "line 4: t = -0.5 goes back"),
    (CSV.replace("0.17\n0.00", "-0.17\n0.00"), "line 2: radius"),
    (CSV.replace("-1.2,0.0,0.90", "-1.2,nan,0.90"), "line 2: ay"),
    (CSV.replace("-1.2,0.0,0.90", "-1.2,zero,0.90"), "line 2: ay"),
    (CSV + "0.04,1,2\n", "line 5: expected 8 values"),
])
def test_bad_csv_names_the_line_and_field(text, place):
    with pytest.raises(ConfigError, match=place):
        parse_csv(text)


def test_bad_json_names_the_frame_and_field():
    with pytest.raises(ConfigError, match=r"frames\[0\]\.capsules\[0\]\.b"):
        parse_json(json.dumps({"schema": "hrc-human-replay/1",
                               "frames": [{"t": 0, "capsules": [{"a": [0, 0, 0], "b": [0, 0], "radius": 1}]}]}))
    with pytest.raises(ConfigError, match="schema"):
        parse_json("{}")


@given(st.text(max_size=300))
def test_garbage_text_raises_only_config_error(text):
    for parser in (parse_csv, parse_json):
        try:
            parser(text)
        except ConfigError:
            pass


def test_unreadable_file(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        load_replay(tmp_path / "none.csv")
