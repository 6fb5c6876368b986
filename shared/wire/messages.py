"""Wire messages: msgpack maps with a schema version, a sequence number and the sender's timestamp.

Every message is a frozen dataclass with a ``KIND`` and a field spec; one generic encoder and one
validating decoder serve them all. On the wire a message is a map

    {"kind": str, "v": SCHEMA_VERSION, "seq": int, "stamp": float, <fields>}

where float arrays travel as little-endian float64 bytes and bool arrays as uint8 bytes (compact, and
the decoder checks their size exactly), and ``stamp`` is the sender's CLOCK_MONOTONIC time in seconds
(``time.monotonic()``; one clock for all processes of one host). The decoder rejects anything that is not
exactly the schema: unknown kind or version, missing or extra fields, wrong types, wrong shapes,
non-finite numbers, oversized strings or arrays. It raises ``MessageError`` naming the field, so a service
can log it and go on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import ClassVar

import msgpack
import numpy as np

from shared.core.errors import MessageError

SCHEMA_VERSION = 1
MAX_MESSAGE_BYTES = 8 * 1024 * 1024
MAX_STRING = 4096
MAX_ROWS = 100_000          # first dimension of any variable-length array
DOF = 6


@dataclass(frozen=True)
class Spec:
    """How one field travels. kind: 'float', 'int', 'bool', 'str', 'farray', 'barray'.
    shape: array shape, -1 for the one variable (first) dimension. optional: None allowed (floats, ints)."""

    kind: str
    shape: tuple[int, ...] = ()
    optional: bool = False
    minimum: float | None = None


@dataclass(frozen=True)
class Message:
    """Base of every message: sequence number and sender monotonic timestamp (s)."""

    KIND: ClassVar[str] = ""
    SPEC: ClassVar[dict[str, Spec]] = {}
    seq: int = field(default=0, kw_only=True)
    stamp: float = field(default=0.0, kw_only=True)

    def check(self) -> None:
        """Cross-field checks of a decoded message (e.g. arrays that must agree in length)."""


F = Spec("float")
I = Spec("int", minimum=0)
B = Spec("bool")
S = Spec("str")
Q = Spec("farray", (DOF,))


@dataclass(frozen=True)
class HumanRaw(Message):
    """Raw human pose from a tracker: M capsules (end points in the robot base frame, m; radii, m), captured at
    sample_time (s, the cell's CLOCK_MONOTONIC: the data's age counts from it)."""

    KIND: ClassVar[str] = "human_raw"
    SPEC: ClassVar[dict[str, Spec]] = {"source": S, "sample_time": F, "segments": Spec("farray", (-1, 2, 3)),
                                       "radii": Spec("farray", (-1,), minimum=0.0)}
    source: str
    sample_time: float
    segments: np.ndarray
    radii: np.ndarray

    def check(self) -> None:
        _same_rows(self, "segments", "radii")


@dataclass(frozen=True)
class HumanState(Message):
    """Filtered human state: capsules, end-point velocities (m/s), whether each velocity is known,
    whether the track is valid, the monotonic time the underlying sample was captured (s; its arrival at the
    tracker where its own time is not earlier: ``shared.tracking.tracker.capture_stamp``), and the tracker's
    measured interval between samples (s; 0 while not known): the source's rate, from which the age at
    which the data counts as stale is derived (shared.tracking.tracker.stale_bound)."""

    KIND: ClassVar[str] = "human_state"
    SPEC: ClassVar[dict[str, Spec]] = {
        "segments": Spec("farray", (-1, 2, 3)), "radii": Spec("farray", (-1,), minimum=0.0),
        "velocities": Spec("farray", (-1, 2, 3)), "velocity_known": Spec("barray", (-1,)),
        "valid": B, "sample_stamp": F, "sample_interval": Spec("float", minimum=0.0)}
    segments: np.ndarray
    radii: np.ndarray
    velocities: np.ndarray
    velocity_known: np.ndarray
    valid: bool
    sample_stamp: float
    sample_interval: float = 0.0

    def check(self) -> None:
        _same_rows(self, "segments", "radii", "velocities", "velocity_known")


@dataclass(frozen=True)
class Goal(Message):
    """A goal configuration (rad) for the planner; name is informational ('' when none). then (K, 6): the goals
    that follow this one, in order, where the sender knows them (none by default): the planner prepares the
    next leg's plan while the robot is still on its way (``shared.planning.loop``)."""

    KIND: ClassVar[str] = "goal"
    SPEC: ClassVar[dict[str, Spec]] = {"goal_id": I, "name": S, "q": Q, "then": Spec("farray", (-1, DOF))}
    goal_id: int
    name: str
    q: np.ndarray
    then: np.ndarray = field(default_factory=lambda: np.zeros((0, DOF)))


@dataclass(frozen=True)
class TrajectoryMsg(Message):
    """A versioned nominal trajectory (cubic Hermite knots over nominal time, see shared.core.trajectory).

    junction: where on this trajectory the follower should continue (s, seconds of nominal time; 0 for a
    fresh plan). base_version: the trajectory this one was merged into (-1 for none). reason: why it was
    planned ('goal', 'horizon', 'beta', ...)."""

    KIND: ClassVar[str] = "trajectory"
    SPEC: ClassVar[dict[str, Spec]] = {
        "version": I, "goal_id": I, "base_version": Spec("int", minimum=-1), "reason": S,
        "junction": Spec("float", minimum=0.0), "times": Spec("farray", (-1,)),
        "positions": Spec("farray", (-1, DOF)), "velocities": Spec("farray", (-1, DOF))}
    version: int
    goal_id: int
    base_version: int
    reason: str
    junction: float
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray

    def check(self) -> None:
        _same_rows(self, "times", "positions", "velocities")
        t = self.times
        if t.shape[0] < 2 or abs(t[0]) > 1e-12 or np.any(np.diff(t) <= 0):
            raise MessageError("trajectory.times: need >= 2 knots, starting at 0, strictly increasing")
        if self.junction > t[-1] + 1e-9:
            raise MessageError("trajectory.junction: beyond the end of the trajectory")


@dataclass(frozen=True)
class JointCommand(Message):
    """The scaler's joint command for the driver: position (rad) and velocity (rad/s).

    For the end-to-end latency (a human sample's capture -> the target frame on CAN), the first command computed
    from a new human state carries that state's sample_stamp and how long it had been published by
    tracker_ingest when the tick took it (s: its way to the scaler and its wait for the tick): the driver subtracts
    the wait to get the processing time, and the command's stamp (its tick) to get the part T_r covers. Both are
    None on every other command."""

    KIND: ClassVar[str] = "joint_command"
    SPEC: ClassVar[dict[str, Spec]] = {"q": Q, "qd": Q, "trajectory_version": Spec("int", minimum=-1),
                                       "s": F, "human_sample_stamp": Spec("float", optional=True),
                                       "human_wait": Spec("float", optional=True, minimum=0.0)}
    q: np.ndarray
    qd: np.ndarray
    trajectory_version: int
    s: float
    human_sample_stamp: float | None = None
    human_wait: float | None = None


@dataclass(frozen=True)
class ScalerStatus(Message):
    """What the scaling layer did in one cycle (``shared.scaling.layer.ScalingStep``, and what the planner reads of
    it, ``shared.planning.inputs.ScalerReport``): stop_s, the s where it brings the robot to rest to await the
    replan it asked for (None: it does not wait); speed, the commanded joint speed (rad/s, fastest joint); held,
    that speed is the SSM's bound, not a ramp below it; pending, the version of a plan from rest it brings the
    robot to rest for (-1: none); received, the newest trajectory version it has decided on (followed, stopped
    for or refused; -1: none yet), so the planner knows when a trajectory it published is no longer on its way."""

    KIND: ClassVar[str] = "scaler_status"
    SPEC: ClassVar[dict[str, Spec]] = {
        "s": F, "alpha": F, "safe_alpha": F, "beta": B, "q_command": Q, "trajectory_version": Spec("int", minimum=-1),
        "status": S, "method": S, "min_separation": Spec("float", optional=True),
        "min_margin": Spec("float", optional=True), "compute_us": F, "stop_s": Spec("float", optional=True),
        "speed": Spec("float", minimum=0.0), "held": B, "pending": Spec("int", minimum=-1),
        "received": Spec("int", minimum=-1)}
    s: float
    alpha: float
    safe_alpha: float
    beta: bool
    q_command: np.ndarray
    trajectory_version: int
    status: str
    method: str
    min_separation: float | None
    min_margin: float | None
    compute_us: float
    stop_s: float | None = None
    speed: float = 0.0
    held: bool = False
    pending: int = -1
    received: int = -1


@dataclass(frozen=True)
class JointState(Message):
    """Measured joint state from the driver: position (rad), velocity (rad/s), drive state summary, and
    drive_lag (s): how far behind (or ahead of) their setpoints the joints have run over the last second, the
    worst joint, at least the configured ssm.drive_lag (``DriveLagMeter.covering``), which the scaler's
    tracking margin covers from the next tick; sync: the number of the SYNC whose period the state ends (the
    driver's count since it started), so that the scaler steps its path once per SYNC however the states
    come (a SYNC one drive did not answer is published late, its next one just after). Both None from a
    source that does not measure them."""

    KIND: ClassVar[str] = "joint_state"
    SPEC: ClassVar[dict[str, Spec]] = {"q": Q, "qd": Q, "drive_state": S, "enabled": B, "fault": B,
                                       "drive_lag": Spec("float", optional=True, minimum=0.0),
                                       "sync": Spec("int", optional=True, minimum=0)}
    q: np.ndarray
    qd: np.ndarray
    drive_state: str
    enabled: bool
    fault: bool
    drive_lag: float | None = None
    sync: int | None = None


@dataclass(frozen=True)
class SafetyEvent(Message):
    """Something safety-relevant happened. severity: 'info', 'warning' or 'stop'."""

    KIND: ClassVar[str] = "safety_event"
    SPEC: ClassVar[dict[str, Spec]] = {"source": S, "event": S, "severity": S, "text": S,
                                       "value": Spec("float", optional=True)}
    source: str
    event: str
    severity: str
    text: str
    value: float | None = None

    def check(self) -> None:
        if self.severity not in ("info", "warning", "stop"):
            raise MessageError(f"safety_event.severity: expected info, warning or stop, got {self.severity!r}")


@dataclass(frozen=True)
class DriverRequest(Message):
    """Ask the robot driver to 'stop' (quick stop all drives) or 'recover' (reset and re-enable, if safe)."""

    KIND: ClassVar[str] = "driver_request"
    SPEC: ClassVar[dict[str, Spec]] = {"action": S, "source": S}
    action: str
    source: str

    def check(self) -> None:
        if self.action not in ("stop", "recover"):
            raise MessageError(f"driver_request.action: expected stop or recover, got {self.action!r}")


@dataclass(frozen=True)
class LatencyReport(Message):
    """The robot driver's latency measurements since its last report (s): for each human sample that
    reached the bus, from its capture to its target frame on CAN, the part of that which was processing (the
    rest is the human state's way to the scaler and its wait for the tick), and from the scaler's tick that took
    it to the frame (tick_to_frame: the part T_r covers, whose p99 is checked against it; the rest is the data's
    age, counted on the person's side); sync_wait: the driver's SYNC period, a frame's wait for the SYNC the drives
    take it at, which T_r covers too (the driver's own ``--period``, not the cell configuration's)."""

    KIND: ClassVar[str] = "latency_report"
    SPEC: ClassVar[dict[str, Spec]] = {"source": S, "sample_to_frame": Spec("farray", (-1,), minimum=0.0),
                                       "processing": Spec("farray", (-1,)),
                                       "tick_to_frame": Spec("farray", (-1,), minimum=0.0),
                                       "sync_wait": Spec("float", minimum=0.0)}
    source: str
    sample_to_frame: np.ndarray
    processing: np.ndarray
    tick_to_frame: np.ndarray
    sync_wait: float

    def check(self) -> None:
        _same_rows(self, "sample_to_frame", "processing", "tick_to_frame")


@dataclass(frozen=True)
class DriveLagReport(Message):
    """The robot driver's drive diagnostics since its last report, per joint: lag (s, p99 of how far the
    measured position ran behind the driver's own setpoints while the joint moved; 0 where it did not),
    samples (how many lag measurements), following_error (rad, the largest |0x60F4| the drive reported),
    bound (s, the configured ssm.drive_lag the lag is checked against), and stopped_by: why the driver
    holds the drives stopped ('' while it does not; the stop's own event is sent once, this every second,
    so `hrc status` can say it at any time), missed: how many SYNCs some drive did not answer within its
    period (lost frames, or a bus or host too slow)."""

    KIND: ClassVar[str] = "drive_lag"
    SPEC: ClassVar[dict[str, Spec]] = {"source": S, "lag": Q, "samples": Spec("farray", (DOF,), minimum=0.0),
                                       "following_error": Spec("farray", (DOF,), minimum=0.0),
                                       "bound": Spec("float", minimum=0.0), "stopped_by": S,
                                       "missed": Spec("int", minimum=0)}
    source: str
    lag: np.ndarray
    samples: np.ndarray
    following_error: np.ndarray
    bound: float
    stopped_by: str = ""
    missed: int = 0


@dataclass(frozen=True)
class MonitorReport(Message):
    """The safety monitor's running totals (since it started), once a second: joint states checked,
    violations, unchecked states (no human state of their moment, or reached too late), how far behind
    its checks ran over the run so far (lag_p99, lag_max, s: measurement -> checked), the smallest
    margin (m/s) and separation (m) seen (inf before any check: sent as a large number)."""

    KIND: ClassVar[str] = "monitor_report"
    SPEC: ClassVar[dict[str, Spec]] = {"checks": I, "violations": I, "unchecked": I,
                                       "lag_p99": Spec("float", minimum=0.0), "lag_max": Spec("float", minimum=0.0),
                                       "min_margin": F, "min_separation": F}
    checks: int
    violations: int
    unchecked: int
    lag_p99: float
    lag_max: float
    min_margin: float
    min_separation: float


MESSAGE_TYPES: dict[str, type[Message]] = {cls.KIND: cls for cls in (
    HumanRaw, HumanState, Goal, TrajectoryMsg, JointCommand, ScalerStatus, JointState, SafetyEvent, DriverRequest,
    LatencyReport, DriveLagReport, MonitorReport)}


def _same_rows(msg: Message, *names: str) -> None:
    rows = {name: getattr(msg, name).shape[0] for name in names}
    if len(set(rows.values())) > 1:
        raise MessageError(f"{msg.KIND}: {', '.join(names)} must have the same length, got {rows}")


# ---------------------------------------------------------------------------------------------- encode
def _encode_value(spec: Spec, value):
    if spec.kind == "farray":
        return np.ascontiguousarray(value, dtype="<f8").tobytes()
    if spec.kind == "barray":
        return np.ascontiguousarray(value, dtype=bool).astype(np.uint8).tobytes()
    if spec.kind == "float":
        return None if value is None else float(value)
    if spec.kind == "int":
        return None if value is None else int(value)
    if spec.kind == "bool":
        return bool(value)
    return str(value)


def encode(msg: Message) -> bytes:
    """msgpack bytes of a message (validated on the way out too, so a bad message is never sent)."""
    body = {"kind": msg.KIND, "v": SCHEMA_VERSION, "seq": int(msg.seq), "stamp": float(msg.stamp)}
    for name, spec in msg.SPEC.items():
        body[name] = _encode_value(spec, getattr(msg, name))
    data = msgpack.packb(body, use_bin_type=True)
    decode(data, type(msg))        # the sender's own mistake is caught here, with the same message
    return data


# ---------------------------------------------------------------------------------------------- decode
def _decode_value(kind: str, name: str, spec: Spec, raw):
    """One field: the common, valid cases on a short path; anything else (and every error, with its
    message) on ``_decode_checked``."""
    what = spec.kind
    if what == "farray" or what == "barray":
        if type(raw) is bytes:
            itemsize = 8 if what == "farray" else 1
            fixed = _FIXED[spec.shape]
            if len(raw) % (itemsize * fixed) == 0:
                rows = len(raw) // (itemsize * fixed)
                if (-1 in spec.shape or rows == 1) and rows <= MAX_ROWS:
                    shape = tuple(rows if d == -1 else d for d in spec.shape)
                    if what == "farray":
                        arr = np.frombuffer(raw, dtype="<f8").reshape(shape).astype(np.float64)
                        if np.isfinite(arr).all() and (spec.minimum is None or not (arr < spec.minimum).any()):
                            return arr
                    else:
                        arr = np.frombuffer(raw, dtype=np.uint8)
                        if not arr.size or arr.max() <= 1:
                            return arr.reshape(shape).astype(bool)
    elif what == "float":
        if type(raw) is float and math.isfinite(raw) and (spec.minimum is None or raw >= spec.minimum):
            return raw
    elif what == "int":
        if type(raw) is int and raw < 2 ** 63 and (spec.minimum is None or raw >= spec.minimum):
            return raw
    elif what == "bool":
        if type(raw) is bool:
            return raw
    elif what == "str":
        if type(raw) is str and len(raw) <= MAX_STRING:
            return raw
    return _decode_checked(kind, name, spec, raw)


class _FixedRows(dict):
    """The product of a shape's fixed dimensions, computed once per shape."""

    def __missing__(self, shape: tuple[int, ...]) -> int:
        self[shape] = value = math.prod(d for d in shape if d != -1)
        return value


_FIXED = _FixedRows()


def _decode_checked(kind: str, name: str, spec: Spec, raw):
    """One field, every check spelled out with the message that names what is wrong."""
    where = f"{kind}.{name}"
    if spec.kind in ("farray", "barray"):
        if not isinstance(raw, (bytes, bytearray)):
            raise MessageError(f"{where}: expected a binary array, got {type(raw).__name__}")
        itemsize = 8 if spec.kind == "farray" else 1
        fixed = math.prod(d for d in spec.shape if d != -1)
        if len(raw) % (itemsize * fixed):
            raise MessageError(f"{where}: {len(raw)} bytes do not make whole rows of shape {spec.shape}")
        rows = len(raw) // (itemsize * fixed)
        if -1 not in spec.shape and rows != 1:
            raise MessageError(f"{where}: expected shape {spec.shape}, got {len(raw) // itemsize} values")
        if rows > MAX_ROWS:
            raise MessageError(f"{where}: {rows} rows is more than the limit {MAX_ROWS}")
        shape = tuple(rows if d == -1 else d for d in spec.shape)
        if spec.kind == "barray":
            arr = np.frombuffer(bytes(raw), dtype=np.uint8).reshape(shape)
            if np.any(arr > 1):
                raise MessageError(f"{where}: boolean array holds a value other than 0 or 1")
            return arr.astype(bool)
        arr = np.frombuffer(bytes(raw), dtype="<f8").reshape(shape).astype(np.float64)
        if not np.all(np.isfinite(arr)):
            raise MessageError(f"{where}: contains NaN or infinity")
        if spec.minimum is not None and np.any(arr < spec.minimum):
            raise MessageError(f"{where}: values below the minimum {spec.minimum}")
        return arr
    if spec.kind == "float":
        if raw is None and spec.optional:
            return None
        if isinstance(raw, bool) or not isinstance(raw, (int, float)):
            raise MessageError(f"{where}: expected a number, got {type(raw).__name__}")
        value = float(raw)
        if not math.isfinite(value):
            raise MessageError(f"{where}: expected a finite number, got {value}")
        if spec.minimum is not None and value < spec.minimum:
            raise MessageError(f"{where}: {value} is below the minimum {spec.minimum}")
        return value
    if spec.kind == "int":
        if raw is None and spec.optional:
            return None
        if isinstance(raw, bool) or not isinstance(raw, int):
            raise MessageError(f"{where}: expected an integer, got {type(raw).__name__}")
        if spec.minimum is not None and raw < spec.minimum:
            raise MessageError(f"{where}: {raw} is below the minimum {int(spec.minimum)}")
        if raw >= 2 ** 63:
            raise MessageError(f"{where}: {raw} is too large")
        return raw
    if spec.kind == "bool":
        if not isinstance(raw, bool):
            raise MessageError(f"{where}: expected true or false, got {type(raw).__name__}")
        return raw
    if not isinstance(raw, str):
        raise MessageError(f"{where}: expected a string, got {type(raw).__name__}")
    if len(raw) > MAX_STRING:
        raise MessageError(f"{where}: string longer than {MAX_STRING} characters")
    return raw


_HEADER = {"seq": Spec("int", minimum=0), "stamp": Spec("float")}
_SPECS: dict[type, tuple[dict[str, Spec], frozenset[str]]] = {}


def _specs(cls: type[Message]) -> tuple[dict[str, Spec], frozenset[str]]:
    """(every field's spec, header first; every key a message of cls has), computed once per class."""
    if cls not in _SPECS:
        specs = {**_HEADER, **cls.SPEC}
        _SPECS[cls] = specs, frozenset(specs) | {"kind", "v"}
    return _SPECS[cls]


def decode(data: bytes, expected: type[Message] | None = None) -> Message:
    """Decode and validate one message; raise MessageError naming what is wrong."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise MessageError(f"message: expected bytes, got {type(data).__name__}")
    if len(data) > MAX_MESSAGE_BYTES:
        raise MessageError(f"message: {len(data)} bytes is more than the limit {MAX_MESSAGE_BYTES}")
    try:
        body = msgpack.unpackb(bytes(data), raw=False, strict_map_key=True)
    except Exception as exc:         # msgpack raises several unrelated types on garbage
        raise MessageError(f"message: not valid msgpack ({type(exc).__name__}: {exc})") from None
    if not isinstance(body, dict):
        raise MessageError(f"message: expected a map, got {type(body).__name__}")
    kind = body.get("kind")
    cls = MESSAGE_TYPES.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise MessageError(f"message.kind: unknown message kind {kind!r}")
    if expected is not None and cls is not expected:
        raise MessageError(f"message.kind: expected {expected.KIND!r}, got {kind!r}")
    if body.get("v") != SCHEMA_VERSION or isinstance(body.get("v"), bool):
        raise MessageError(f"{kind}.v: unsupported schema version {body.get('v')!r} (this build speaks {SCHEMA_VERSION})")
    specs, names = _specs(cls)
    if len(body) != len(names) or not names.issuperset(body):
        missing = sorted(n for n in names if n not in body)
        extra = sorted(map(str, set(body) - names))
        if missing:
            raise MessageError(f"{kind}: missing field(s) {missing}")
        raise MessageError(f"{kind}: unknown field(s) {extra}")
    values = {name: _decode_value(kind, name, spec, body[name]) for name, spec in specs.items()}
    msg = cls(**values)
    msg.check()
    return msg


def message_fields(msg: Message) -> dict:
    """Every field of a message by name (header included), for comparisons and logging."""
    return {f.name: getattr(msg, f.name) for f in fields(msg)}
