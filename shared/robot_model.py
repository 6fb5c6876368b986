"""The PRBT robot model: kinematics (pinocchio), joint limits and the link capsules.

The URDF, the capsule file and the joint-limit file live in ``shared/robot/``. Every capsule end point
is registered as a pinocchio frame, so one kinematics pass gives all end points in the base frame; the
linear Jacobian of any point rigidly attached to a link follows from the joint axes and origins
(geometric Jacobian, J_v[:, k] = z_k x (p - o_k) for every joint k that moves the link).

Units: metres, radians, seconds. Positions are in the robot base frame (``world`` = ``prbt_base_link``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numba
import numpy as np
import pinocchio as pin
import yaml

from shared.errors import ConfigError

ROBOT_DIR = Path(__file__).parent / "robot"
URDF_PATH = ROBOT_DIR / "prbt.urdf"
CAPSULES_PATH = ROBOT_DIR / "prbt_capsules.yaml"
LIMITS_PATH = ROBOT_DIR / "prbt_joint_limits.yaml"


@dataclass(frozen=True)
class JointLimits:
    """Per-joint limits as arrays of shape (6,): position (rad), velocity (rad/s), acceleration (rad/s^2)."""

    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    monitor_acceleration: np.ndarray

    def within(self, q: np.ndarray, tolerance: float = 0.0) -> bool:
        """True when every joint of q is inside [lower - tol, upper + tol]."""
        q = np.asarray(q, dtype=float)
        return bool(np.all(q >= self.lower - tolerance) and np.all(q <= self.upper + tolerance))


@dataclass(frozen=True)
class LinkCapsule:
    """A capsule rigidly attached to a link: segment a-b in the link frame, and a radius."""

    link: str
    a: np.ndarray
    b: np.ndarray
    radius: float


def _vector3(raw, where: str) -> np.ndarray:
    v = np.asarray(raw, dtype=float) if isinstance(raw, (list, tuple)) else None
    if v is None or v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ConfigError(f"{where}: expected a list of 3 finite numbers, got {raw!r}")
    return v


def load_capsules(path: Path = CAPSULES_PATH) -> tuple[list[LinkCapsule], list[tuple[str, str]]]:
    """Read the capsule file: one capsule per link, and the enabled self-collision pairs."""
    try:
        doc = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f"{path}: cannot read capsule file: {exc}") from exc
    if not isinstance(doc, dict) or not isinstance(doc.get("capsules"), dict):
        raise ConfigError(f"{path}: expected a mapping with a 'capsules' mapping")
    capsules = []
    for link, spec in doc["capsules"].items():
        where = f"{path}: capsules.{link}"
        if not isinstance(spec, dict):
            raise ConfigError(f"{where}: expected a mapping with a, b, radius")
        radius = spec.get("radius")
        if not isinstance(radius, (int, float)) or not np.isfinite(radius) or radius <= 0:
            raise ConfigError(f"{where}.radius: expected a positive number, got {radius!r}")
        capsules.append(LinkCapsule(str(link), _vector3(spec.get("a"), f"{where}.a"),
                                    _vector3(spec.get("b"), f"{where}.b"), float(radius)))
    pairs = [tuple(p) for p in doc.get("self_collision_pairs", [])]
    return capsules, pairs


class RobotModel:
    """Kinematics of the PRBT and its capsules.

    Pure computation, no I/O after construction. Not thread-safe (it owns one pinocchio Data).
    """

    def __init__(self, urdf_path: Path = URDF_PATH, capsules_path: Path = CAPSULES_PATH,
                 limits_path: Path = LIMITS_PATH) -> None:
        self.model = pin.buildModelFromUrdf(str(urdf_path))
        self.nq = self.model.nq
        self.joint_names = [self.model.names[i] for i in range(1, self.model.njoints)]
        self.limits = self._load_limits(limits_path)
        self.capsules, self.self_collision_pairs = load_capsules(capsules_path)
        self.link_names = [c.link for c in self.capsules]
        self.radii = np.array([c.radius for c in self.capsules])
        # Every capsule end point, expressed in the frame of the joint that carries it.
        local, joint_of_point = [], []
        for cap in self.capsules:
            if not self.model.existFrame(cap.link):
                raise ConfigError(f"capsule for unknown link {cap.link!r}")
            link_frame = self.model.frames[self.model.getFrameId(cap.link)]
            for point in (cap.a, cap.b):
                local.append(link_frame.placement.act(point))
                joint_of_point.append(link_frame.parentJoint)
        self._point_local = np.array(local)                  # (P, 3) in the carrying joint's frame
        self._point_joint = np.array(joint_of_point)         # (P,) pinocchio joint index, 0 = fixed to base
        self.data = self.model.createData()
        # ancestry[p, k] = 1 when actuated joint k (0-based) moves end point p.
        self._ancestry = np.zeros((len(self._point_joint), self.nq))
        for p, joint in enumerate(self._point_joint):
            for k in self.model.supports[int(joint)][1:]:
                self._ancestry[p, k - 1] = 1.0
        self.moving_links = self._ancestry.reshape(len(self.capsules), 2, self.nq)[:, 0].any(axis=1)
        self.flange_frame = self.model.getFrameId("prbt_flange")

    def _load_limits(self, path: Path) -> JointLimits:
        try:
            doc = yaml.safe_load(Path(path).read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise ConfigError(f"{path}: cannot read joint limits: {exc}") from exc
        acc = np.asarray(doc.get("max_acceleration", []), dtype=float)
        mon = np.asarray(doc.get("monitor_acceleration", []), dtype=float)
        if acc.shape != (self.nq,) or mon.shape != (self.nq,) or np.any(acc <= 0) or np.any(mon <= 0):
            raise ConfigError(f"{path}: max_acceleration and monitor_acceleration need {self.nq} positive values")
        return JointLimits(lower=self.model.lowerPositionLimit.copy(), upper=self.model.upperPositionLimit.copy(),
                           velocity=self.model.velocityLimit.copy(), acceleration=acc, monitor_acceleration=mon)

    # ------------------------------------------------------------------ kinematics
    def flange_pose(self, q: np.ndarray) -> pin.SE3:
        """Pose of the flange (= tool0 = tcp with no tool) in the base frame."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return pin.SE3(self.data.oMf[self.flange_frame])

    def frame_position(self, q: np.ndarray, frame: str) -> np.ndarray:
        """Position (3,) of any named frame of the model at configuration q."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return self.data.oMf[self.model.getFrameId(frame)].translation.copy()

    def _joint_placements(self) -> np.ndarray:
        """Homogeneous placements (njoints, 4, 4) of every joint, universe first (identity)."""
        oMi = self.data.oMi
        return np.array([oMi[k].homogeneous for k in range(self.model.njoints)])

    def capsule_segments(self, q: np.ndarray) -> np.ndarray:
        """End points of every link capsule in the base frame, shape (L, 2, 3)."""
        return self.capsule_kinematics(q)[0]

    def capsule_kinematics(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Capsule end points (L, 2, 3) and the linear Jacobians of those points (L, 2, 3, 6).

        Uses the world-frame Jacobian of the whole chain: with the spatial velocity (v0, w) expressed at
        the base origin, a point p moves at v0 + w x p, so J_p = J_lin - skew(p) J_ang restricted to the
        joints that move p. One kinematics pass serves all 2L points.
        """
        pin.computeJointJacobians(self.model, self.data, np.asarray(q, dtype=float))
        n_points = self._point_local.shape[0]
        points = np.empty((n_points, 3))
        jac = np.empty((n_points, 3, self.nq))
        _points_and_jacobians(self._joint_placements(), self.data.J, self._point_local, self._point_joint,
                              self._ancestry, points, jac)
        n = len(self.capsules)
        return points.reshape(n, 2, 3), jac.reshape(n, 2, 3, self.nq)

    def point_jacobian(self, q: np.ndarray, link: str, point_in_link: np.ndarray) -> np.ndarray:
        """Linear Jacobian (3, 6) of a point given in a link's frame: d(p)/dt = J q_dot."""
        pin.computeJointJacobians(self.model, self.data, np.asarray(q, dtype=float))
        frame = self.model.frames[self.model.getFrameId(link)]
        local = frame.placement.act(np.asarray(point_in_link, dtype=float))[None, :]
        joint = np.array([frame.parentJoint])
        ancestry = np.zeros((1, self.nq))
        for k in self.model.supports[frame.parentJoint][1:]:
            ancestry[0, k - 1] = 1.0
        point, jac = np.empty((1, 3)), np.empty((1, 3, self.nq))
        _points_and_jacobians(self._joint_placements(), self.data.J, local, joint, ancestry, point, jac)
        return jac[0]


@numba.njit(cache=True)
def _points_and_jacobians(placements, world_jacobian, local, joint, ancestry, points, jac):
    """Place points (P, 3) given in their joint's frame, and their linear Jacobians (P, 3, n).

    J_p[:, k] = J_lin[:, k] + J_ang[:, k] x p for every joint k that moves p (world-frame Jacobian).
    """
    for p in range(local.shape[0]):
        h = placements[joint[p]]
        for r in range(3):
            points[p, r] = h[r, 0] * local[p, 0] + h[r, 1] * local[p, 1] + h[r, 2] * local[p, 2] + h[r, 3]
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        for k in range(world_jacobian.shape[1]):
            m = ancestry[p, k]
            wx, wy, wz = world_jacobian[3, k], world_jacobian[4, k], world_jacobian[5, k]
            jac[p, 0, k] = m * (world_jacobian[0, k] + wy * pz - wz * py)
            jac[p, 1, k] = m * (world_jacobian[1, k] + wz * px - wx * pz)
            jac[p, 2, k] = m * (world_jacobian[2, k] + wx * py - wy * px)


@lru_cache(maxsize=1)
def default_robot() -> RobotModel:
    """The PRBT with the project's URDF and capsules (built once per process)."""
    return RobotModel()
