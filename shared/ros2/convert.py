"""The cell's state as ROS 2 messages, and what ROS 2 may send the cell, checked (pure).

Out: the measured joints (sensor_msgs/JointState), every link's pose (tf2_msgs/TFMessage, from the base
frame), capsules as visualization_msgs/MarkerArray (a cylinder and two spheres each), the scaling factor and
the replan request (std_msgs/Float64, std_msgs/Bool), the safety events (diagnostic_msgs/DiagnosticArray).
In: a goal as a sensor_msgs/JointState (positions by joint name), people as a MarkerArray of CYLINDER
markers (one capsule each: its pose's z axis is the capsule's axis, scale.z its length between the centres
of the end spheres, scale.x its diameter; the marker's ns names the person), or body keypoints as a
geometry_msgs/PoseArray (every person seen in a frame, one after another, each the keypoints of
shared.tracking.keypoints in their order), turned into capsules by the code of ``hrc human from-keypoints``.
Bad input raises MessageError naming what is wrong (its ``reason`` says how it is counted). Times are ns since
the epoch."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from shared.core.errors import MessageError
from shared.core.geometry import capsule_frames
from shared.core.humans import HumanCapsules
from shared.ros2.types import msg_class
from shared.tracking.keypoints import body_capsules
from shared.tracking.tracker import OLDEST_SAMPLE

JOINT_STATE, TF, MARKERS = "sensor_msgs/msg/JointState", "tf2_msgs/msg/TFMessage", "visualization_msgs/msg/MarkerArray"
FLOAT64, BOOL, STRING = "std_msgs/msg/Float64", "std_msgs/msg/Bool", "std_msgs/msg/String"
DIAGNOSTICS = "diagnostic_msgs/msg/DiagnosticArray"
POSES = "geometry_msgs/msg/PoseArray"
CYLINDER, SPHERE = 3, 2                      # visualization_msgs/Marker types
ADD, DELETEALL = 0, 3
LEVELS = {"info": 0, "warning": 1, "stop": 2}     # diagnostic_msgs/DiagnosticStatus OK, WARN, ERROR
MAX_CAPSULES = 64
BASE_FRAMES = ("world", "")    # the frames people may come in: the robot base, the root of the bridge's /tf
CELL_SIZE = 10.0               # m: a keypoint farther than this from the robot base is not a person in the cell
PEOPLE_RGBA, ROBOT_RGBA = (1.0, 0.55, 0.1, 0.7), (0.2, 0.5, 1.0, 0.5)   # the view's colours of both kinds
ROBOT_MARKER_PERIOD = 0.05   # s between two robot capsule MarkerArrays (20 Hz), live and in a bag


def stamp(t_ns: int):
    return msg_class("builtin_interfaces/msg/Time")(sec=int(t_ns // 1_000_000_000), nanosec=int(t_ns % 1_000_000_000))


def header(t_ns: int, frame: str):
    return msg_class("std_msgs/msg/Header")(stamp=stamp(t_ns), frame_id=frame)


def joint_state(names: list[str], q: np.ndarray, qd: np.ndarray, t_ns: int):
    return msg_class(JOINT_STATE)(header=header(t_ns, ""), name=list(names), position=np.asarray(q, np.float64),
                                  velocity=np.asarray(qd, np.float64), effort=np.zeros(0, np.float64))


def _transform(translation: np.ndarray, rotation: np.ndarray):
    x, y, z, w = pin.Quaternion(rotation).coeffs().tolist()            # pinocchio's: (x, y, z, w)
    return msg_class("geometry_msgs/msg/Transform")(
        translation=msg_class("geometry_msgs/msg/Vector3")(x=float(translation[0]), y=float(translation[1]),
                                                           z=float(translation[2])),
        rotation=msg_class("geometry_msgs/msg/Quaternion")(x=x, y=y, z=z, w=w))


def link_transforms(frames: list[tuple[str, np.ndarray]], base: str, t_ns: int):
    """A TFMessage of (child frame, 4x4 pose in the base frame) pairs, each as base -> child."""
    stamped = msg_class("geometry_msgs/msg/TransformStamped")
    return msg_class(TF)(transforms=[stamped(header=header(t_ns, base), child_frame_id=name,
                                             transform=_transform(pose[:3, 3], pose[:3, :3]))
                                     for name, pose in frames])


def capsule_markers(segments: np.ndarray, radii: np.ndarray, ns: str, frame: str, t_ns: int,
                    rgba: tuple[float, float, float, float]):
    """Each capsule as a CYLINDER between its end centres and two SPHEREs at them (ids 3k, 3k+1, 3k+2); a
    DELETEALL first, so capsules that went away leave the view."""
    Marker, Pose = msg_class("visualization_msgs/msg/Marker"), msg_class("geometry_msgs/msg/Pose")
    Point, Quat = msg_class("geometry_msgs/msg/Point"), msg_class("geometry_msgs/msg/Quaternion")
    Vec, Color = msg_class("geometry_msgs/msg/Vector3"), msg_class("std_msgs/msg/ColorRGBA")
    Duration = msg_class("builtin_interfaces/msg/Duration")
    color = Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])
    # the parts every marker of the array has alike, made once (serialising only reads them)
    same = {"header": header(t_ns, frame), "ns": ns, "color": color, "lifetime": Duration(sec=0, nanosec=0),
            "frame_locked": False, "points": [], "colors": [], "texture_resource": "", "uv_coordinates": [],
            "texture": msg_class("sensor_msgs/msg/CompressedImage")(header=header(0, ""), format="",
                                                                    data=np.zeros(0, np.uint8)),
            "text": "", "mesh_resource": "", "mesh_use_embedded_materials": False,
            "mesh_file": msg_class("visualization_msgs/msg/MeshFile")(filename="", data=np.zeros(0, np.uint8))}
    upright = Quat(x=0.0, y=0.0, z=0.0, w=1.0)

    def marker(k: int, kind: int, centre: np.ndarray, rotation: tuple | None, scale: tuple[float, float, float],
               action: int = ADD):
        orientation = upright if rotation is None else Quat(*rotation)
        return Marker(id=k, type=kind, action=action, **same,
                      pose=Pose(position=Point(x=float(centre[0]), y=float(centre[1]), z=float(centre[2])),
                                orientation=orientation),
                      scale=Vec(x=scale[0], y=scale[1], z=scale[2]))

    markers = [marker(0, CYLINDER, np.zeros(3), None, (0.0, 0.0, 0.0), DELETEALL)]
    seg = np.asarray(segments, float).reshape(-1, 2, 3)
    _, quats, lengths = capsule_frames(seg)                # the 3D view's own poses: +z turned onto each axis
    for k, ((a, b), r) in enumerate(zip(seg, np.asarray(radii, float))):
        d = 2.0 * float(r)
        markers.append(marker(3 * k, CYLINDER, (a + b) / 2.0, tuple(quats[k].tolist()), (d, d, float(lengths[k]))))
        markers.append(marker(3 * k + 1, SPHERE, a, None, (d, d, d)))
        markers.append(marker(3 * k + 2, SPHERE, b, None, (d, d, d)))
    return msg_class(MARKERS)(markers=markers)


def people_markers(state, t_ns: int):
    """The tracked people of a HumanState as capsule markers in the world frame; an invalid track clears them."""
    if not state.valid:
        return capsule_markers(np.zeros((0, 2, 3)), np.zeros(0), "people", "world", t_ns, PEOPLE_RGBA)
    return capsule_markers(state.segments, state.radii, "people", "world", t_ns, PEOPLE_RGBA)


def robot_markers(robot, q: np.ndarray, t_ns: int):
    """The robot's safety capsules at configuration q as markers in the world frame."""
    return capsule_markers(robot.capsule_segments(q), robot.radii, "robot", "world", t_ns, ROBOT_RGBA)


def float64(value: float):
    return msg_class(FLOAT64)(data=float(value))


def boolean(value: bool):
    return msg_class(BOOL)(data=bool(value))


def string(text: str):
    return msg_class(STRING)(data=text)


def diagnostics(events: list, t_ns: int):
    """Safety events (source, event, severity, text, value) as one DiagnosticArray, a status each."""
    Status, KeyValue = msg_class("diagnostic_msgs/msg/DiagnosticStatus"), msg_class("diagnostic_msgs/msg/KeyValue")
    return msg_class(DIAGNOSTICS)(header=header(t_ns, ""), status=[
        Status(level=LEVELS.get(e.severity, 1), name=f"hrc/{e.source}", message=f"{e.event}: {e.text}"[:1000],
               hardware_id="prbt", values=[KeyValue(key="event", value=e.event),
                                           KeyValue(key="value", value="" if e.value is None else repr(e.value))])
        for e in events])


# ------------------------------------------------------------------------------------------------ inbound
def goal_positions(msg, joint_names: list[str]) -> np.ndarray:
    """A goal's six joint positions (rad) in the robot's joint order, from a JointState naming every joint
    once (or, without names, giving them in order); MessageError otherwise."""
    positions = np.asarray(msg.position, dtype=float)
    names = list(msg.name)
    if names:
        if sorted(names) != sorted(joint_names) or len(names) != len(positions):
            raise MessageError(f"goal: expected a position for each of {joint_names} by name, got names {names} "
                               f"and {len(positions)} positions")
        positions = positions[[names.index(n) for n in joint_names]]
    elif len(positions) != len(joint_names):
        raise MessageError(f"goal: expected {len(joint_names)} positions, got {len(positions)}")
    if not np.all(np.isfinite(positions)):
        raise MessageError("goal: a position is not a finite number")
    return positions


def people_from_markers(msg) -> HumanCapsules:
    """The capsules of a MarkerArray of CYLINDER markers (other types and DELETE actions are skipped; no
    velocity is known, so the SSM takes the ISO 13855 speeds). MessageError for a non-finite or degenerate
    capsule, or too many."""
    segments, radii = [], []
    for m in msg.markers:
        if m.type != CYLINDER or m.action != ADD:
            continue
        p, o = m.pose.position, m.pose.orientation
        values = np.array([p.x, p.y, p.z, o.x, o.y, o.z, o.w, m.scale.x, m.scale.z], dtype=float)
        if not np.all(np.isfinite(values)):
            raise MessageError(f"people: marker {m.ns}/{m.id} has a value that is not a finite number")
        quat = values[3:7]
        norm = np.linalg.norm(quat)
        if not 0.5 < norm < 1.5 or not 0.0 < m.scale.x <= 2.0 or not 0.0 <= m.scale.z <= 3.0:
            raise MessageError(f"people: marker {m.ns}/{m.id}: orientation not a rotation or scale out of range "
                               f"(diameter {m.scale.x} m, length {m.scale.z} m)")
        x, y, z, w = quat / norm
        axis = np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
        centre = values[:3]
        half = axis * m.scale.z / 2.0
        segments.append([centre - half, centre + half])
        radii.append(m.scale.x / 2.0)
    if len(radii) > MAX_CAPSULES:
        raise MessageError(f"people: {len(radii)} capsules, more than {MAX_CAPSULES}")
    if not radii:
        return HumanCapsules.empty()
    seg = np.array(segments)
    return HumanCapsules.from_arrays(seg, np.array(radii), np.zeros_like(seg), np.zeros(len(radii), bool))


def sample_age(stamps, wall_ns: int) -> float:
    """How old (s) a sample is at wall time `wall_ns` by the newest of its header stamps (builtin_interfaces/Time,
    the sender's wall clock): the age of the capture, so that the tracker's velocities and the data's age
    count from it, not from the arrival. 0 for unset stamps (all zero) or a stamp ahead of this clock (a host
    whose clock runs ahead: the arrival stands for the capture); MessageError ("stale") past OLDEST_SAMPLE."""
    newest = max((int(t.sec) * 1_000_000_000 + int(t.nanosec) for t in stamps), default=0)
    if newest <= 0:
        return 0.0
    age = (wall_ns - newest) * 1e-9
    if age > OLDEST_SAMPLE:
        raise MessageError(f"people: stamped {age:.3f} s ago, more than {OLDEST_SAMPLE} s", "stale")
    return max(age, 0.0)


def people_from_keypoints(msg, keypoints: tuple[str, ...]) -> HumanCapsules:
    """The capsules of the people in a PoseArray of body keypoints: len(keypoints) poses a person, in the order
    of `keypoints` (shared.tracking.keypoints.KEYPOINTS, or ARM_KEYPOINTS for an arm-only skeleton), one
    person after another, positions in the robot base frame (m; orientations are not used), each person's
    capsules those of ``body_capsules`` (as ``hrc human from-keypoints`` makes them; no velocity: the tracker
    estimates it); an empty array is nobody in view. MessageError for another frame, a count that is not
    whole people, an infinite or far-off position, or too many capsules; and, counted as "partly seen", for
    a NaN position: a keypoint not seen makes the frame a dropout (nothing reaches the tracker, so it stops
    the robot once the data is stale, rather than guess where that limb is)."""
    frame = msg.header.frame_id
    if frame not in BASE_FRAMES:
        raise MessageError(f"keypoints: frame {frame!r}: send them in the robot base frame 'world' (the bridge has "
                      f"no transforms of other frames)")
    n = len(keypoints)
    points = np.array([[p.position.x, p.position.y, p.position.z] for p in msg.poses], dtype=float).reshape(-1, 3)
    if len(points) % n:
        raise MessageError(f"keypoints: {len(points)} poses are not whole people of {n} ({', '.join(keypoints)})")
    if np.isnan(points).any():
        raise MessageError("keypoints: a keypoint not seen (NaN): the frame is a dropout", "partly seen")
    if not np.all(np.isfinite(points)) or np.abs(points).max(initial=0.0) > CELL_SIZE:
        raise MessageError(f"keypoints: a position is infinite or farther than {CELL_SIZE} m from the robot base")
    capsules = [c for k in range(0, len(points), n)
                for c in body_capsules({name: points[k + i] for i, name in enumerate(keypoints)})]
    if len(capsules) > MAX_CAPSULES:
        raise MessageError(f"keypoints: {len(capsules)} capsules, more than {MAX_CAPSULES}")
    if not capsules:
        return HumanCapsules.empty()
    seg = np.array([[a, b] for _, a, b, _ in capsules])
    return HumanCapsules.from_arrays(seg, np.array([r for *_, r in capsules]), np.zeros_like(seg),
                                     np.zeros(len(capsules), bool))
