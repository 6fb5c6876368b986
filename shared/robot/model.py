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

from shared.core.errors import ConfigError

ROBOT_DIR = Path(__file__).parent
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
        # The hot path walks the chain itself (compiled): every actuated joint must be a revolute joint
        # about its local z axis, which is what the URDF's <axis xyz="0 0 1"/> gives.
        kinds = {self.model.joints[k].shortname() for k in range(1, self.model.njoints)}
        if kinds != {"JointModelRZ"}:
            raise ConfigError(f"{urdf_path}: the kinematics need revolute joints about z, got {sorted(kinds)}")
        self._joint_placement = np.array([self.model.jointPlacements[k].homogeneous
                                          for k in range(self.model.njoints)])
        self._parent = np.array(list(self.model.parents), dtype=np.int64)
        self.link_reach = self._link_reach()
        self.joint_reach = self.link_reach.max(axis=0)
        self.reach_centre, self.reach_radius = self._reach()

    def _link_reach(self) -> np.ndarray:
        """(L, 6): for link i and joint k, a bound (m) on the distance from joint k's axis to any capsule
        end point of link i, valid in every configuration (0 where k does not move the link): the lengths
        of the joint offsets from k out to the link's joint plus the point's offset there (triangle
        inequality). A motion dq moves no point of link i by more than sum_k |dq_k| link_reach[i, k]."""
        reach = np.zeros((len(self.capsules), self.nq))
        offsets = np.linalg.norm(self._joint_placement[:, :3, 3], axis=1)
        for p, joint in enumerate(self._point_joint):
            chain = [int(j) for j in self.model.supports[int(joint)]][1:]        # actuated joints to the point
            for pos, k in enumerate(chain):
                lever = sum(offsets[j] for j in chain[pos + 1:]) + np.linalg.norm(self._point_local[p])
                reach[p // 2, k - 1] = max(reach[p // 2, k - 1], lever)
        return reach

    def _reach(self) -> tuple[np.ndarray, float]:
        """A sphere that holds the whole robot in every configuration: centred on the first joint's origin
        (base frame), its radius the largest distance of a capsule's surface from it (``link_reach`` bounds
        the distance of a moving link's points from there; a link fixed to the base is where it is)."""
        centre = self._joint_placement[1][:3, 3].copy()
        radius = 0.0
        for i, cap in enumerate(self.capsules):
            if self.moving_links[i]:
                bound = self.link_reach[i, 0]
            else:
                bound = max(float(np.linalg.norm(self._point_local[2 * i + e] - centre)) for e in range(2))
            radius = max(radius, bound + cap.radius)
        return centre, radius

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

    def link_poses(self, q: np.ndarray, fixed: bool | None = None) -> list[tuple[str, np.ndarray]]:
        """Every link's pose (4x4) in the world frame at configuration q, by link name (the URDF's bodies);
        fixed True: only the links fixed to the world (no joint moves them: the base; ROS 2's /tf_static),
        False: only the others (/tf)."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return [(f.name, self.data.oMf[k].homogeneous.copy()) for k, f in enumerate(self.model.frames)
                if f.type == pin.FrameType.BODY and f.name != "world"
                and (fixed is None or fixed == (f.parentJoint == 0))]

    def frame_position(self, q: np.ndarray, frame: str) -> np.ndarray:
        """Position (3,) of any named frame of the model at configuration q."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return self.data.oMf[self.model.getFrameId(frame)].translation.copy()

    def capsule_segments(self, q: np.ndarray) -> np.ndarray:
        """End points of every link capsule in the base frame, shape (L, 2, 3)."""
        world = chain_world(np.asarray(q, dtype=np.float64), self._joint_placement, self._parent)
        return place_points(world, self._point_local, self._point_joint).reshape(len(self.capsules), 2, 3)

    @property
    def ancestry(self) -> np.ndarray:
        """(P, nq): 1 where joint k moves end point p (the compiled Jacobians take it with ``chain``)."""
        return self._ancestry

    @property
    def chain(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The arrays the compiled kinematics take: joint placements, parents, end points, their joints."""
        return self._joint_placement, self._parent, self._point_local, self._point_joint

    def capsule_kinematics(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Capsule end points (L, 2, 3) and the linear Jacobians of those points (L, 2, 3, 6).

        One compiled pass along the chain (T_k = T_parent M_k Rz(q_k), the joint placements M_k taken from
        the pinocchio model) places every joint; a point p carried by the chain then has the geometric
        Jacobian column z_k x (p - o_k) for every joint k that moves it. pinocchio's own kinematics give
        the same numbers (tests/core/test_robot_model.py); this path skips its per-object Python overhead.
        """
        points, jac = _chain_points_and_jacobians(np.asarray(q, dtype=np.float64), self._joint_placement,
                                                  self._parent, self._point_local, self._point_joint,
                                                  self._ancestry)
        n = len(self.capsules)
        return points.reshape(n, 2, 3), jac.reshape(n, 2, 3, self.nq)

    def capsule_motion(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Capsule end points (L, 2, 3) and their linear velocities (L, 2, 3, m/s) at joint velocities qd
        (rad/s): the Jacobians applied without being formed (one compiled pass, where forming them and the
        product cost more than the kinematics). The scaling layer's cycle calls the same kernel inside its
        own compiled calls (``shared.scaling.problem``)."""
        points, velocities = chain_points_and_velocities(np.asarray(q, dtype=np.float64), np.asarray(qd, dtype=np.float64),
                                                         self._joint_placement, self._parent, self._point_local,
                                                         self._point_joint, self._ancestry)
        n = len(self.capsules)
        return points.reshape(n, 2, 3), velocities.reshape(n, 2, 3)

    def point_jacobian(self, q: np.ndarray, link: str, point_in_link: np.ndarray) -> np.ndarray:
        """Linear Jacobian (3, 6) of a point given in a link's frame: d(p)/dt = J q_dot."""
        frame = self.model.frames[self.model.getFrameId(link)]
        local = frame.placement.act(np.asarray(point_in_link, dtype=float))[None, :]
        ancestry = np.zeros((1, self.nq))
        for k in self.model.supports[frame.parentJoint][1:]:
            ancestry[0, k - 1] = 1.0
        _, jac = _chain_points_and_jacobians(np.asarray(q, dtype=np.float64), self._joint_placement, self._parent,
                                             local, np.array([frame.parentJoint]), ancestry)
        return jac[0]


@numba.njit(cache=True)
def chain_world(q, joint_placement, parent):
    """Base-frame placement (n, 4, 4) of every joint of a chain of revolute-z joints (index 0: base): world[k] =
    world[parent[k]] @ joint_placement[k] @ Rz(q[k - 1]), written out. Why not numpy's ``@``: compiled, it calls
    BLAS for each 4 x 4 product, and the two products a joint took 80 % of this function (1.27 us of the 1.56 us a
    robot's points and velocities took; the planning layer's time cost computes them at every sample of every
    candidate, docs/measurements.md, session 85). A rotation about z mixes only the first two columns."""
    n_joints = joint_placement.shape[0]
    world = np.zeros((n_joints, 4, 4))
    for r in range(4):
        world[0, r, r] = 1.0
    for k in range(1, n_joints):
        c, s = np.cos(q[k - 1]), np.sin(q[k - 1])
        a, b = world[parent[k]], joint_placement[k]
        for r in range(4):
            m0 = a[r, 0] * b[0, 0] + a[r, 1] * b[1, 0] + a[r, 2] * b[2, 0] + a[r, 3] * b[3, 0]
            m1 = a[r, 0] * b[0, 1] + a[r, 1] * b[1, 1] + a[r, 2] * b[2, 1] + a[r, 3] * b[3, 1]
            world[k, r, 0] = c * m0 + s * m1
            world[k, r, 1] = c * m1 - s * m0
            for col in range(2, 4):
                world[k, r, col] = a[r, 0] * b[0, col] + a[r, 1] * b[1, col] + a[r, 2] * b[2, col] + a[r, 3] * b[3, col]
    return world


@numba.njit(cache=True)
def place_points(world, local, joint):
    """Points (P, 3) given in the frame of their joint, in the base frame."""
    points = np.empty((local.shape[0], 3))
    for p in range(local.shape[0]):
        h = world[joint[p]]
        for r in range(3):
            points[p, r] = h[r, 0] * local[p, 0] + h[r, 1] * local[p, 1] + h[r, 2] * local[p, 2] + h[r, 3]
    return points


@numba.njit(cache=True)
def _chain_points_and_jacobians(q, joint_placement, parent, local, joint, ancestry):
    """Points (P, 3) given in their joint's frame, placed in the base frame, and their Jacobians (P, 3, n)."""
    world = chain_world(q, joint_placement, parent)
    points = place_points(world, local, joint)
    n_points, n_dof = local.shape[0], joint_placement.shape[0] - 1
    jac = np.zeros((n_points, 3, n_dof))
    for p in range(n_points):
        for k in range(n_dof):
            if ancestry[p, k] == 0.0:
                continue
            zx, zy, zz = world[k + 1, 0, 2], world[k + 1, 1, 2], world[k + 1, 2, 2]
            dx = points[p, 0] - world[k + 1, 0, 3]
            dy = points[p, 1] - world[k + 1, 1, 3]
            dz = points[p, 2] - world[k + 1, 2, 3]
            jac[p, 0, k] = zy * dz - zz * dy
            jac[p, 1, k] = zz * dx - zx * dz
            jac[p, 2, k] = zx * dy - zy * dx
    return points, jac


@numba.njit(cache=True)
def chain_points_and_velocities(q, qd, joint_placement, parent, local, joint, ancestry):
    """Points (P, 3) given in their joint's frame, placed in the base frame, and their velocities (P, 3) at
    joint velocities qd: the sum over the joints k that move a point p of qd_k z_k x (p - o_k), which is
    its Jacobian (``_chain_points_and_jacobians``) times qd."""
    world = chain_world(q, joint_placement, parent)
    points = place_points(world, local, joint)
    velocities = np.zeros((local.shape[0], 3))
    for p in range(local.shape[0]):
        for k in range(joint_placement.shape[0] - 1):
            rate = qd[k]
            if ancestry[p, k] == 0.0 or rate == 0.0:
                continue
            zx, zy, zz = world[k + 1, 0, 2], world[k + 1, 1, 2], world[k + 1, 2, 2]
            dx = points[p, 0] - world[k + 1, 0, 3]
            dy = points[p, 1] - world[k + 1, 1, 3]
            dz = points[p, 2] - world[k + 1, 2, 3]
            velocities[p, 0] += rate * (zy * dz - zz * dy)
            velocities[p, 1] += rate * (zz * dx - zx * dz)
            velocities[p, 2] += rate * (zx * dy - zy * dx)
    return points, velocities


@lru_cache(maxsize=1)
def default_robot() -> RobotModel:
    """The PRBT with the project's URDF and capsules (built once per process)."""
    return RobotModel()
