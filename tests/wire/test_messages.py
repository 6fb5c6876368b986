"""Wire messages: decode(encode(x)) == x for every type; garbage never crashes a decoder."""

import math

import msgpack
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from shared.core.errors import MessageError
from shared.wire.messages import (
    MESSAGE_TYPES,
    SCHEMA_VERSION,
    DriverRequest,
    Goal,
    HumanState,
    JointCommand,
    SafetyEvent,
    TrajectoryMsg,
    decode,
    encode,
    message_fields,
)

finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


def _array(draw, shape, rows, minimum=None):
    full = tuple(rows if d == -1 else d for d in shape)
    lo = 0.0 if minimum is not None else -100.0
    return np.array(draw(st.lists(st.floats(lo, 100.0), min_size=int(np.prod(full)), max_size=int(np.prod(full))))
                    ).reshape(full)


@st.composite
def messages(draw, cls=None):
    cls = cls or draw(st.sampled_from(sorted(MESSAGE_TYPES.values(), key=lambda c: c.KIND)))
    rows = draw(st.integers(2 if cls is TrajectoryMsg else 0, 5))
    values = {}
    for name, spec in cls.SPEC.items():
        if spec.kind == "farray":
            values[name] = _array(draw, spec.shape, rows, spec.minimum)
        elif spec.kind == "barray":
            values[name] = np.array(draw(st.lists(st.booleans(), min_size=rows, max_size=rows)), dtype=bool)
        elif spec.kind == "float":
            values[name] = draw(st.none() | finite) if spec.optional else draw(finite)
            if spec.minimum is not None and values[name] is not None:
                values[name] = abs(values[name])
        elif spec.kind == "int":
            values[name] = draw(st.integers(int(spec.minimum or 0), 2 ** 40))
        elif spec.kind == "bool":
            values[name] = draw(st.booleans())
        else:
            values[name] = draw(st.text(max_size=40))
    if cls is TrajectoryMsg:
        values["times"] = np.concatenate([[0.0], np.cumsum(np.abs(values["times"][1:]) + 0.01)])
        values["junction"] = min(values["junction"], values["times"][-1])
    if cls is SafetyEvent:
        values["severity"] = draw(st.sampled_from(["info", "warning", "stop"]))
    if cls is DriverRequest:
        values["action"] = draw(st.sampled_from(["stop", "recover"]))
    return cls(**values, seq=draw(st.integers(0, 2 ** 40)), stamp=draw(finite))


def assert_same(a, b):
    assert type(a) is type(b)
    fa, fb = message_fields(a), message_fields(b)
    assert fa.keys() == fb.keys()
    for k in fa:
        if isinstance(fa[k], np.ndarray):
            assert fa[k].shape == fb[k].shape and np.array_equal(fa[k], fb[k]), k
        else:
            assert fa[k] == fb[k], k


@given(messages())
def test_roundtrip(msg):
    assert_same(decode(encode(msg)), msg)
    assert_same(decode(encode(msg), type(msg)), msg)


@given(st.binary(max_size=300))
def test_random_bytes_raise_only_message_error(data):
    try:
        decode(data)
    except MessageError:
        pass


@given(messages(), st.sampled_from(["drop", "retype", "extra", "version", "nan"]), st.data())
def test_mutated_messages_raise_only_message_error(msg, how, data):
    body = msgpack.unpackb(encode(msg), raw=False)
    name = data.draw(st.sampled_from(sorted(msg.SPEC)))
    if how == "drop":
        del body[name]
    elif how == "retype":
        body[name] = data.draw(st.one_of(st.text(max_size=5), st.lists(st.integers(), max_size=3),
                                         st.binary(max_size=7), st.booleans(), st.none(), st.integers()))
    elif how == "extra":
        body["surprise"] = 1
    elif how == "version":
        body["v"] = SCHEMA_VERSION + 1
    else:
        body[name] = math.nan
    try:
        decode(msgpack.packb(body, use_bin_type=True))
    except MessageError:
        return
    assert how == "retype"        # only a retype can land on another valid value by chance


def _goal(**over):
    base = dict(goal_id=1, name="home", q=np.zeros(6))
    base.update(over)
    return Goal(**base)


def test_errors_name_the_field():
    with pytest.raises(MessageError, match=r"goal\.q: .*NaN"):
        encode(_goal(q=np.array([0, 0, np.nan, 0, 0, 0])))
    with pytest.raises(MessageError, match=r"goal\.q"):
        encode(_goal(q=np.zeros(5)))
    with pytest.raises(MessageError, match=r"goal\.goal_id"):
        encode(_goal(goal_id=-3))
    body = msgpack.unpackb(encode(_goal()), raw=False)
    body["v"] = 99
    with pytest.raises(MessageError, match=r"goal\.v: unsupported schema version 99"):
        decode(msgpack.packb(body))
    with pytest.raises(MessageError, match=r"expected 'joint_command', got 'goal'"):
        decode(encode(_goal()), JointCommand)


def test_the_short_paths_decide_as_the_checked_ones():
    """decode's short path for valid fields gives way to the checked path, never a different answer: huge
    finite values are valid, an integer where a float is expected is still a float, and a boolean array
    holding a 2, a NaN and an infinity are still refused with their messages."""
    huge = _goal(q=np.full(6, 1.5e308))
    assert np.array_equal(decode(encode(huge)).q, huge.q)
    body = msgpack.unpackb(encode(_goal()), raw=False)
    body["stamp"] = 3
    assert decode(msgpack.packb(body)).stamp == 3.0 and isinstance(decode(msgpack.packb(body)).stamp, float)
    seg = np.zeros((2, 2, 3))
    state = msgpack.unpackb(encode(HumanState(segments=seg, radii=np.ones(2), velocities=seg,
                                              velocity_known=np.ones(2, bool), valid=True, sample_stamp=0.0)), raw=False)
    state["velocity_known"] = bytes([1, 2])
    with pytest.raises(MessageError, match=r"human_state\.velocity_known: boolean array holds a value other than 0 or 1"):
        decode(msgpack.packb(state, use_bin_type=True))
    for bad in (np.nan, np.inf, -np.inf):
        body = msgpack.unpackb(encode(_goal()), raw=False)
        body["q"] = np.array([0, 0, bad, 0, 0, 0], dtype="<f8").tobytes()
        with pytest.raises(MessageError, match=r"goal\.q: contains NaN or infinity"):
            decode(msgpack.packb(body, use_bin_type=True))


def test_cross_field_checks():
    seg = np.zeros((2, 2, 3))
    with pytest.raises(MessageError, match="same length"):
        encode(HumanState(segments=seg, radii=np.ones(3), velocities=seg, velocity_known=np.ones(2, bool),
                          valid=True, sample_stamp=0.0))
    with pytest.raises(MessageError, match="strictly increasing"):
        encode(TrajectoryMsg(version=1, goal_id=0, base_version=-1, reason="goal", junction=0.0,
                             times=np.array([0.0, 0.0]), positions=np.zeros((2, 6)), velocities=np.zeros((2, 6))))
    with pytest.raises(MessageError, match="severity"):
        encode(SafetyEvent(source="x", event="y", severity="panic", text=""))


def test_oversized_input_is_refused():
    with pytest.raises(MessageError, match="limit"):
        decode(b"\x00" * (9 * 1024 * 1024))
