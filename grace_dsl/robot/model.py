"""Serial robot arms on Pinocchio, with a tool frame in the project's gripper convention.

A :class:`Robot` is a Pinocchio model reduced to the arm's actuated joints (finger joints are
locked at a fixed opening), a TCP frame that is the gripper frame of DESIGN.md §6 (origin between
the fingertips, +z the approach, +y the closing direction) and the hand's description as a
:class:`~grace_dsl.runtime.gripper.Gripper`. Robot models come from the ``example-robot-data``
package on PyPI, installed with the project and never downloaded at run time.
"""

from __future__ import annotations

import importlib.metadata
import math
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.inputs import as_array, check_pose

FloatArray = np.ndarray
UR5_HOME = (0.0, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0.0)
PANDA_HOME = (0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4)
PANDA_OPEN = 0.08  # m between the Panda's fingers fully open (each finger joint 0-0.04 m)


class RobotModelError(ParameterError):
    """A robot description that cannot be loaded or does not name the frames it should."""


@dataclass(frozen=True, eq=False)
class Robot:
    """An arm: its kinematic model, joint limits, TCP frame, collision geometry and hand.

    ``model`` keeps only the joints that :func:`solve_ik` moves; a configuration ``q`` is a
    vector of ``model.nq`` joint values in radians (metres for prismatic joints).
    """

    name: str
    model: pin.Model
    collision: pin.GeometryModel
    tcp_frame: int
    gripper: Gripper
    home: FloatArray
    urdf: Path
    _local: threading.local = field(default_factory=threading.local, repr=False)

    # -- construction
    @staticmethod
    def from_urdf(
        path: str | Path,
        tcp: str | tuple[str, Any],
        gripper: Gripper | None = None,
        *,
        locked: Mapping[str, float] | None = None,
        home: Sequence[float] | None = None,
        package_dirs: Sequence[str | Path] = (),
        name: str | None = None,
    ) -> Robot:
        """Load an arm from a URDF.

        ``tcp`` is a frame name of the URDF, or ``(frame, T_offset)`` with a 4x4 offset from that
        frame to the gripper frame. ``locked`` fixes joints (a hand's fingers) at the given values.
        ``home`` defaults to the middle of every joint's range.
        """
        urdf = Path(path)
        if not urdf.is_file():
            raise RobotModelError(f"no URDF at {urdf}")
        dirs = [str(d) for d in package_dirs] or [str(urdf.parent.parent.parent)]
        full, collision = _parsed(str(urdf.resolve()), tuple(dirs))
        model, collision = _reduced(full, collision, locked or {})
        frame_name, offset = (tcp, np.eye(4)) if isinstance(tcp, str) else tcp
        tcp_frame = _add_tcp(model, frame_name, rigid_pose(offset, "the TCP offset"))
        q_home = _home(model, home)
        return Robot(
            name or urdf.stem,
            model,
            collision,
            tcp_frame,
            gripper or Gripper.panda(),
            q_home,
            urdf,
        )

    @staticmethod
    def panda(opening: float = PANDA_OPEN) -> Robot:
        """The Franka Emika Panda (example-robot-data), fingers open, TCP ``panda_hand_tcp``.

        ``panda_hand_tcp`` sits 103.4 mm along the hand's +z, between the fingertips; the hand's
        +z is the approach and its fingers slide along its y axis, so the frame is already the
        gripper frame of DESIGN.md §6. ``opening``: the gap between the fingers in metres (the
        collision geometry of a hand closed on a part; the kinematics do not change).
        """
        if not 0.0 <= opening <= PANDA_OPEN:
            raise ParameterError(
                f"the Panda's fingers open 0 to {PANDA_OPEN * 1e3:.0f} mm, not {opening * 1e3:g} mm"
            )
        urdf = robot_data_file("panda_description/urdf/panda.urdf")
        half = opening / 2
        return Robot.from_urdf(
            urdf,
            tcp="panda_hand_tcp",
            gripper=Gripper.panda(),
            locked={"panda_finger_joint1": half, "panda_finger_joint2": half},
            home=PANDA_HOME,
            package_dirs=[urdf.parents[4]],
            name="panda",
        )

    @staticmethod
    def ur5(tcp_offset: float = 0.15) -> Robot:
        """Universal Robots' UR5 (example-robot-data's ``ur5_gripper.urdf``) with a parallel hand
        of the Panda's finger geometry on its flange, fingertips ``tcp_offset`` metres out.

        The URDF carries no hand geometry, so the hand itself is not collision-checked; the arm
        is. ``tool0``'s +z points out of the flange: it is the approach, and +y the closing
        direction, as the gripper convention asks.
        """
        urdf = robot_data_file("ur_description/urdf/ur5_gripper.urdf")
        offset = np.eye(4)
        offset[2, 3] = tcp_offset
        return Robot.from_urdf(
            urdf,
            tcp=("tool0", offset),
            gripper=Gripper.panda(),
            home=UR5_HOME,
            package_dirs=[urdf.parents[4]],
            name="ur5",
        )

    # -- queries
    @property
    def nq(self) -> int:
        return int(self.model.nq)

    @property
    def lower(self) -> FloatArray:
        return _read_only(self.model.lowerPositionLimit)

    @property
    def upper(self) -> FloatArray:
        return _read_only(self.model.upperPositionLimit)

    @property
    def velocity_limit(self) -> FloatArray:
        return _read_only(self.model.velocityLimit)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(self.model.names[i] for i in range(1, self.model.njoints))

    def data(self) -> pin.Data:
        """This thread's Pinocchio workspace (Pinocchio's data is not safe to share)."""
        data = getattr(self._local, "data", None)
        if data is None:
            data = self._local.data = self.model.createData()
        return data

    def check_q(self, q: Any, *, within_limits: bool = True) -> FloatArray:
        """``q`` as a float vector of the right length, finite and (by default) within limits."""
        try:  # the runtime's reading of numbers: text, bytes and ragged lists are refused
            arr = np.array(as_array("q", q)).reshape(-1)
        except ParameterError:
            raise ParameterError(
                f"{self.name}: q must be {self.nq} numbers, not {_short(q)}"
            ) from None
        if arr.size != self.nq:
            raise ParameterError(f"{self.name}: q must have {self.nq} values, got {arr.size}")
        if not np.all(np.isfinite(arr)):
            raise ParameterError(f"{self.name}: q must be finite, got {arr.tolist()}")
        if within_limits:
            outside = np.flatnonzero((arr < self.lower - 1e-9) | (arr > self.upper + 1e-9))
            if outside.size:
                i = int(outside[0])
                raise ParameterError(
                    f"{self.name}: joint {self.joint_names[i]} = {arr[i]:.4f} is outside its "
                    f"limits [{self.lower[i]:.4f}, {self.upper[i]:.4f}]"
                )
        return arr

    def fk(self, q: Any) -> FloatArray:
        """The 4x4 world pose of the gripper frame at configuration ``q``."""
        q = self.check_q(q)
        data = self.data()
        pin.framesForwardKinematics(self.model, data, q)
        return np.array(data.oMf[self.tcp_frame].homogeneous)

    def jacobian(self, q: Any) -> FloatArray:
        """(6, nq): the gripper frame's linear and angular velocity in world axes per joint rate
        (Pinocchio's LOCAL_WORLD_ALIGNED: the origin's velocity, expressed in world axes)."""
        q = self.check_q(q)
        data = self.data()
        pin.computeJointJacobians(self.model, data, q)
        pin.updateFramePlacements(self.model, data)
        return np.array(
            pin.getFrameJacobian(self.model, data, self.tcp_frame, pin.LOCAL_WORLD_ALIGNED)
        )

    def random_q(self, rng: np.random.Generator) -> FloatArray:
        """A configuration drawn uniformly within the joint limits."""
        return rng.uniform(self.lower, self.upper)


def robot_data_file(relative: str) -> Path:
    """A file of the installed ``example-robot-data`` package (``robots/<relative>``)."""
    try:
        files = importlib.metadata.files("example-robot-data") or []
    except importlib.metadata.PackageNotFoundError:
        raise RobotModelError(
            "the example-robot-data package is not installed (pip install example-robot-data)"
        ) from None
    suffix = f"robots/{relative}"
    for entry in files:
        if str(entry).endswith(suffix):
            return Path(str(entry.locate()))
    raise RobotModelError(f"example-robot-data has no {suffix}")


@lru_cache(maxsize=4)
def _parsed(urdf: str, dirs: tuple[str, ...]) -> tuple[pin.Model, pin.GeometryModel]:
    """The URDF's model and collision geometry, parsed once per process (the meshes take most
    of a second to load; a hand closed to another width only locks its fingers elsewhere).
    Callers get copies or reduced models (``_reduced``), never these."""
    try:
        full, collision, _ = pin.buildModelsFromUrdf(urdf, package_dirs=list(dirs))
    except (RuntimeError, ValueError) as exc:
        raise RobotModelError(f"cannot load {urdf}: {exc}") from None
    return full, collision


def _reduced(
    full: pin.Model, collision: pin.GeometryModel, locked: Mapping[str, float]
) -> tuple[pin.Model, pin.GeometryModel]:
    q = pin.neutral(full)
    ids = []
    for joint, value in locked.items():
        if not full.existJointName(joint):
            raise RobotModelError(f"the model has no joint {joint!r} to lock")
        jid = full.getJointId(joint)
        q[full.joints[jid].idx_q] = value
        ids.append(jid)
    if not ids:  # copies: the parsed models are shared by every robot loaded from the file
        return pin.Model(full), collision.copy()
    model, (geom,) = pin.buildReducedModel(full, [collision], ids, q)
    return model, geom


def _add_tcp(model: pin.Model, frame_name: str, offset: FloatArray) -> int:
    if not model.existFrame(frame_name):
        names = sorted({f.name for f in model.frames})
        raise RobotModelError(f"the model has no frame {frame_name!r}; frames: {names}")
    parent = model.frames[model.getFrameId(frame_name)]
    placement = parent.placement * pin.SE3(offset[:3, :3], offset[:3, 3])
    frame = pin.Frame("grace_tcp", parent.parentJoint, placement, pin.FrameType.OP_FRAME)
    return int(model.addFrame(frame))


def _home(model: pin.Model, home: Sequence[float] | None) -> FloatArray:
    lo, hi = model.lowerPositionLimit, model.upperPositionLimit
    q = (lo + hi) / 2 if home is None else np.asarray(home, dtype=float)
    if q.shape != (model.nq,) or np.any(q < lo) or np.any(q > hi):
        raise RobotModelError(f"home must be {model.nq} values within the joint limits")
    return _read_only(q)


def rigid_pose(m: Any, what: str) -> FloatArray:
    """``m`` as a rigid 4x4 pose, checked like every pose of the runtime (``check_pose``: finite,
    orthonormal, no mirror, last row 0 0 0 1, numbers only); unlike an instance's pose it is
    required, so None is refused rather than read as the identity."""
    if m is None or isinstance(m, (str, bytes)):
        raise ParameterError(f"{what} must be a 4x4 matrix, not {_short(m)}")
    return check_pose(m, what)


def _read_only(a: Any) -> FloatArray:
    out = np.array(a, dtype=float)
    out.setflags(write=False)
    return out


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
